#pragma once
#include <chrono>

namespace mgcloth {

class Timer {
 public:
  Timer() : m_start(std::chrono::steady_clock::now()) {}
  void reset() { m_start = std::chrono::steady_clock::now(); }
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
  }
  double ms() const { return 1e3 * seconds(); }

 private:
  std::chrono::steady_clock::time_point m_start;
};

}  // namespace mgcloth
