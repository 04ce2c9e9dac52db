#pragma once
#include <mgcloth/core/timer.hpp>

#include <string>

namespace mgcloth::cli {

/// Progress on stderr: a bar with ETA on a terminal, one line per frame otherwise (logs, CI), nothing when quiet.
class Progress {
 public:
  Progress(int total, int done, bool quiet);
  void update(int done, double frame_seconds, int iterations, double energy);
  void message(const std::string& line);
  void finish();

 private:
  int m_total, m_start;
  bool m_quiet, m_tty, m_bar_drawn = false;
  Timer m_timer;
};

}  // namespace mgcloth::cli
