#pragma once
#include <mgcloth/core/error.hpp>

#include <new>

namespace mgcloth {

/// Memory ran out; the message says what was being built and how large it was (a bare std::bad_alloc says neither).
class OutOfMemory : public Error {
 public:
  using Error::Error;
};

/// Runs `build`; a std::bad_alloc in it becomes OutOfMemory("out of memory building " + what()), e.g. what() = "the
/// multigrid hierarchy of cloth \"flag\" (5000000 vertices)", and an OutOfMemory from a nested builder gets
/// "what(): " put before it, so that the message names every enclosing thing being built.
template <class What, class Build>
decltype(auto) building(What&& what, Build&& build) {
  try {
    return build();
  } catch (const std::bad_alloc&) {
    throw OutOfMemory(fmt::format("out of memory building {}", what()));
  } catch (const OutOfMemory& e) {
    throw OutOfMemory(fmt::format("{}: {}", what(), e.what()));
  }
}

}  // namespace mgcloth
