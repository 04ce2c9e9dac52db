#pragma once
#include <fmt/format.h>
#include <stdexcept>
#include <string>

namespace mgcloth {

/// Every failure the library reports: the message names the file, JSON path or element it concerns.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
/// Bad user input: a scene, a mesh, a parameter.
class InputError : public Error {
 public:
  using Error::Error;
};
/// A solve that cannot continue: NaN energy, a failed line search, a factorization that keeps failing.
class SolveError : public Error {
 public:
  using Error::Error;
};

template <class E = Error, class... Args>
[[noreturn]] void throw_error(fmt::format_string<Args...> format, Args&&... args) {
  throw E(fmt::format(format, std::forward<Args>(args)...));
}
template <class... Args>
[[noreturn]] void throw_input_error(fmt::format_string<Args...> format, Args&&... args) {
  throw InputError(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace mgcloth
