#include <mgcloth/core/interrupt.hpp>

#include <atomic>
#include <csignal>

namespace mgcloth {

namespace {
std::atomic<bool> g_interrupted{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void on_interrupt(int sig) {
  g_interrupted.store(true);
  std::signal(sig, SIG_DFL);  // a second Ctrl-C ends a run that does not reach its next check
}
}  // namespace

void install_interrupt_handler() {
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
}

bool interrupted() { return g_interrupted.load(); }

void set_interrupted(bool on) { g_interrupted.store(on); }

}  // namespace mgcloth
