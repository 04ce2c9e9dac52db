#pragma once

namespace mgcloth {

/// SIGINT and SIGTERM set a flag instead of ending the process, so that a long run stops at a safe point and keeps
/// its results (a second signal ends the process at once). Solvers whose Stop is `interruptible` end their solve at
/// the next iteration with status "interrupted".
void install_interrupt_handler();
/// Whether a signal arrived since the handler was installed (or set_interrupted(true)).
bool interrupted();
/// Sets or clears the flag (tests; a caller that wants its solves to stop).
void set_interrupted(bool on);

}  // namespace mgcloth
