# Debian's libhypre-dev (2.26 on Debian 12) ships no CMake package; locate header and library directly and define
# mgcloth::hypre. Debian builds hypre with MPI: its headers include <mpi.h> and every call needs MPI initialized
# (linalg/hypre_amg.cpp does that lazily), so the target carries MPI as well. We only need MPI's C API; the C++
# target is used because this project does not enable the C language, with the deprecated C++ bindings skipped.
find_path(HYPRE_INCLUDE_DIR HYPRE_parcsr_ls.h PATH_SUFFIXES hypre REQUIRED)
find_library(HYPRE_LIBRARY HYPRE REQUIRED)
file(STRINGS ${HYPRE_INCLUDE_DIR}/HYPRE_config.h _hypre_version_line REGEX "^#define HYPRE_RELEASE_VERSION ")
string(REGEX MATCH "[0-9]+\\.[0-9]+\\.[0-9]+" HYPRE_VERSION "${_hypre_version_line}")
if(HYPRE_VERSION VERSION_LESS 2.20)
  message(FATAL_ERROR "hypre ${HYPRE_VERSION} found at ${HYPRE_INCLUDE_DIR}; mgcloth needs 2.20 or newer")
endif()
file(STRINGS ${HYPRE_INCLUDE_DIR}/HYPRE_config.h _hypre_sequential REGEX "^#define HYPRE_SEQUENTIAL")

add_library(mgcloth::hypre INTERFACE IMPORTED)
target_include_directories(mgcloth::hypre INTERFACE ${HYPRE_INCLUDE_DIR})
target_link_libraries(mgcloth::hypre INTERFACE ${HYPRE_LIBRARY})
if(NOT _hypre_sequential)
  set(MPI_CXX_SKIP_MPICXX ON)
  find_package(MPI REQUIRED COMPONENTS CXX)
  target_link_libraries(mgcloth::hypre INTERFACE MPI::MPI_CXX)
endif()
message(STATUS "Found hypre ${HYPRE_VERSION}: ${HYPRE_LIBRARY}")
