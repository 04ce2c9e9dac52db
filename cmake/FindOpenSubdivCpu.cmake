# Debian's libosd-dev CMake package lists static archives it does not ship (find_package fails on a fresh
# install); locate the header and the shared CPU library directly.
find_path(OPENSUBDIV_INCLUDE_DIR opensubdiv/far/topologyRefiner.h REQUIRED)
find_library(OPENSUBDIV_CPU_LIBRARY osdCPU REQUIRED)
add_library(mgcloth::opensubdiv INTERFACE IMPORTED)
target_include_directories(mgcloth::opensubdiv INTERFACE ${OPENSUBDIV_INCLUDE_DIR})
target_link_libraries(mgcloth::opensubdiv INTERFACE ${OPENSUBDIV_CPU_LIBRARY})
