#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/pcg.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::linalg {
namespace {
constexpr Index kChunk = 4096;
/// Below this many chunks the vector operations run serially: they take microseconds, less than waking threads.
constexpr Index kParallelChunks = 16;

/// f(begin, length) over fixed chunks of [0, n) in parallel; returns the chunk results summed in chunk order.
template <class F>
double chunked_sum(Index n, F&& f) {
  const Index chunks = (n + kChunk - 1) / kChunk;
  std::vector<double> partial(chunks, 0.0);
  parallel_for(
      chunks, [&](Index c) { partial[c] = f(c * kChunk, std::min(kChunk, n - c * kChunk)); }, kParallelChunks);
  double total = 0.0;
  for (double s : partial) total += s;
  return total;
}

double dot(const VecX& a, const VecX& b) {
  return chunked_sum(static_cast<Index>(a.size()), [&](Index i, Index m) { return a.segment(i, m).dot(b.segment(i, m)); });
}
}  // namespace

int pcg(const BlockMatrix3& A, const VecX& b, VecX& x, const Preconditioner& M, double rel_tol, int max_iters) {
  const auto n = static_cast<Index>(b.size());
  VecX r, z, p, Ap;
  A.multiply(x, Ap);
  r.resize(n);
  const double target = rel_tol * std::sqrt(dot(b, b));
  double rr = chunked_sum(n, [&](Index i, Index m) {
    r.segment(i, m) = b.segment(i, m) - Ap.segment(i, m);
    return r.segment(i, m).squaredNorm();
  });
  if (std::sqrt(rr) <= target) return 0;
  M(r, z);
  p = z;
  double rz = dot(r, z);
  for (int k = 1; k <= max_iters; ++k) {
    A.multiply(p, Ap);
    const double pAp = dot(p, Ap);
    if (!(pAp > 0.0)) throw_error<SolveError>("PCG: matrix not positive definite (pᵀAp = {})", pAp);
    const double alpha = rz / pAp;
    rr = chunked_sum(n, [&](Index i, Index m) {
      x.segment(i, m) += alpha * p.segment(i, m);
      r.segment(i, m) -= alpha * Ap.segment(i, m);
      return r.segment(i, m).squaredNorm();
    });
    if (std::sqrt(rr) <= target) return k;
    M(r, z);
    const double rz_new = dot(r, z);
    const double beta = rz_new / rz;
    parallel_for(
        (n + kChunk - 1) / kChunk,
        [&](Index c) {
          const Index i = c * kChunk, m = std::min(kChunk, n - i);
          p.segment(i, m) = z.segment(i, m) + beta * p.segment(i, m);
        },
        kParallelChunks);
    rz = rz_new;
  }
  return max_iters;
}

}  // namespace mgcloth::linalg
