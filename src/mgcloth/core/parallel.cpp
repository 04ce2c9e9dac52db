#include <mgcloth/core/parallel.hpp>

#include <dlfcn.h>

namespace mgcloth {
int num_threads() { return omp_get_max_threads(); }
void set_num_threads(int n) {
  if (n <= 0) return;
  omp_set_num_threads(n);
  // CHOLMOD's supernodal factorization runs in the BLAS, whose own thread pool (OpenBLAS starts one thread per core)
  // ignores OpenMP's setting: with --threads 1 next to another job its threads spin and wait on the busy core
  // (about a fifth of a level-6 shell solve's CPU time, measured with perf). The BLAS is whatever libblas.so.3 the
  // system chose, so its thread control is looked up, not linked.
  // CHOLMOD's own OpenMP loops ask for 4 threads by a num_threads clause (its compile-time default), which
  // omp_set_num_threads does not override; with dynamic adjustment libgomp may give them fewer where the cores
  // are busy, which is all a single-threaded run can ask for.
  // Set both ways: a program that goes back from 1 thread to more (a benchmark over thread counts, a Python
  // session) would otherwise keep dynamic adjustment, under which libgomp gives a loop one thread whenever the load
  // average says the cores are busy.
  omp_set_dynamic(n == 1 ? 1 : 0);
  using SetThreads = void (*)(int);
  if (auto* set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(n);
}
}  // namespace mgcloth
