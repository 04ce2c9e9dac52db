#include <mgcloth/core/error.hpp>
#include <mgcloth/cuda/errors.hpp>

namespace mgcloth::cuda {

void fail(const std::string& message) { throw Error(message); }
void fail_input(const std::string& message) { throw InputError(message); }
void fail_solve(const std::string& message) { throw SolveError(message); }
std::string sci(double v, int digits) { return fmt::format("{:.{}e}", v, digits); }

}  // namespace mgcloth::cuda
