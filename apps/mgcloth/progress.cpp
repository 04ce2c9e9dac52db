#include "progress.hpp"

#include <fmt/format.h>

#include <cstdio>
#include <unistd.h>

namespace mgcloth::cli {

namespace {
std::string duration(double s) {
  if (s < 60) return fmt::format("{:.0f}s", s);
  if (s < 3600) return fmt::format("{}m{:02d}s", static_cast<int>(s) / 60, static_cast<int>(s) % 60);
  return fmt::format("{}h{:02d}m", static_cast<int>(s) / 3600, (static_cast<int>(s) % 3600) / 60);
}
}  // namespace

Progress::Progress(int total, int done, bool quiet)
    : m_total(total), m_start(done), m_quiet(quiet), m_tty(::isatty(STDERR_FILENO) != 0) {}

void Progress::message(const std::string& line) {
  if (m_quiet) return;
  if (m_bar_drawn) std::fputs("\r\033[K", stderr);
  std::fprintf(stderr, "%s\n", line.c_str());
  m_bar_drawn = false;
}

void Progress::update(int done, double frame_seconds, int iterations, double energy) {
  if (m_quiet) return;
  const double elapsed = m_timer.seconds();
  const int since = done - m_start;
  const double eta = since > 0 ? elapsed / since * (m_total - done) : 0.0;
  if (m_tty) {
    constexpr int kWidth = 30;
    const int filled = m_total > 0 ? kWidth * done / m_total : kWidth;
    std::string bar(filled, '#');
    bar.resize(kWidth, '.');
    std::fprintf(stderr, "\r\033[K[%s] %d/%d frames  %.2fs/frame  %d it  ETA %s", bar.c_str(), done, m_total,
                 frame_seconds, iterations, duration(eta).c_str());
    std::fflush(stderr);
    m_bar_drawn = true;
  } else {
    std::fprintf(stderr, "frame %d/%d  %.3f s  %d iterations  energy %.6g  elapsed %s  eta %s\n", done, m_total,
                 frame_seconds, iterations, energy, duration(elapsed).c_str(), duration(eta).c_str());
  }
}

void Progress::finish() {
  if (m_quiet) return;
  if (m_bar_drawn) std::fputs("\n", stderr);
  m_bar_drawn = false;
}

}  // namespace mgcloth::cli
