#pragma once
#include <mgcloth/core/timer.hpp>

#include <algorithm>
#include <functional>

namespace mgcloth::bench {

/// Best of `repeat` runs, in ms (the first run is a warm-up of caches and thread pool).
inline double best_ms(int repeat, const std::function<void()>& f) {
  f();
  double best = 1e300;
  for (int r = 0; r < repeat; ++r) {
    Timer t;
    f();
    best = std::min(best, t.ms());
  }
  return best;
}

}  // namespace mgcloth::bench
