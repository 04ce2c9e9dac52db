#pragma once
#include <mgcloth/core/types.hpp>

#include <omp.h>

namespace mgcloth {

/// Runs f(i) for i in [0, n) on the OpenMP thread pool; small ranges run serially to avoid fork cost.
template <class F>
void parallel_for(Index n, F&& f, Index serial_below = 256) {
  if (n < serial_below || omp_get_max_threads() == 1) {
    for (Index i = 0; i < n; ++i) f(i);
    return;
  }
#pragma omp parallel for schedule(static)
  for (Index i = 0; i < n; ++i) f(i);
}

/// Deterministic parallel sum: fixed chunking, chunk sums added in order, so results do not depend on timing.
template <class F>
double parallel_sum(Index n, F&& f) {
  constexpr Index kChunk = 1024;
  const Index chunks = (n + kChunk - 1) / kChunk;
  std::vector<double> partial(chunks, 0.0);
  parallel_for(
      chunks,
      [&](Index c) {
        double s = 0.0;
        const Index end = std::min(n, (c + 1) * kChunk);
        for (Index i = c * kChunk; i < end; ++i) s += f(i);
        partial[c] = s;
      },
      2);
  double total = 0.0;
  for (double s : partial) total += s;
  return total;
}

int num_threads();
void set_num_threads(int n);

}  // namespace mgcloth
