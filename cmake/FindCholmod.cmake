# Debian's SuiteSparse 5 ships no CMake package for CHOLMOD; locate header and libraries directly.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig REQUIRED)
add_library(mgcloth::cholmod INTERFACE IMPORTED)
target_include_directories(mgcloth::cholmod INTERFACE ${CHOLMOD_INCLUDE_DIR})
target_link_libraries(mgcloth::cholmod INTERFACE ${CHOLMOD_LIBRARY} ${SUITESPARSECONFIG_LIBRARY})
