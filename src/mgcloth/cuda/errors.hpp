#pragma once
// Error reporting for code that nvcc compiles (pipeline.hpp, *.cu): fmt's compile-time format checks do not build
// there, so messages are plain strings and the exceptions (core/error.hpp) are thrown from a C++ translation unit.
#include <string>

namespace mgcloth::cuda {

[[noreturn]] void fail(const std::string& message);        ///< mgcloth::Error
[[noreturn]] void fail_input(const std::string& message);  ///< mgcloth::InputError
[[noreturn]] void fail_solve(const std::string& message);  ///< mgcloth::SolveError
/// v in scientific notation with `digits` significant digits after the point ("1.234e-03").
std::string sci(double v, int digits = 3);

}  // namespace mgcloth::cuda
