#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>

#include <cholmod.h>
#include <omp.h>

namespace mgcloth::linalg {

struct CholmodSolver::Impl {
  cholmod_common common;
  cholmod_sparse* A = nullptr;
  cholmod_factor* L = nullptr;
  // Pattern this analysis belongs to, and for every stored lower-triangle scalar entry, the position of its value
  // inside the flattened BSR blocks (9 doubles per block, column-major).
  std::vector<Index> offsets, cols;
  std::vector<std::int64_t> source;
  std::vector<std::int64_t> diagonal_slots;

  Impl() {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
    common.supernodal = CHOLMOD_SUPERNODAL;
  }
  ~Impl() {
    if (L) cholmod_free_factor(&L, &common);
    if (A) cholmod_free_sparse(&A, &common);
    cholmod_finish(&common);
  }

  void build_structure(const BlockMatrix3& M) {
    if (L) cholmod_free_factor(&L, &common);
    if (A) cholmod_free_sparse(&A, &common);
    offsets = M.row_offsets();
    cols = M.col_indices();
    const Index n = M.rows();
    // Lower triangle of the scalar matrix in CSC: column j = 3C + c holds rows 3R + r >= j. By symmetry
    // A(3R+r, 3C+c) = block(C, R)(c, r), and block row C lists the R >= C in ascending order.
    std::vector<std::int64_t> colptr(3 * n + 1, 0);
    std::vector<std::int64_t> rowind;
    source.clear();
    diagonal_slots.assign(3 * n, 0);
    for (Index C = 0; C < n; ++C) {
      for (int c = 0; c < 3; ++c) {
        for (Index k = offsets[C]; k < offsets[C + 1]; ++k) {
          const Index R = cols[k];
          if (R < C) continue;
          for (int r = (R == C ? c : 0); r < 3; ++r) {
            if (R == C && r == c) diagonal_slots[3 * C + c] = static_cast<std::int64_t>(rowind.size());
            rowind.push_back(3 * R + r);
            source.push_back(9 * static_cast<std::int64_t>(k) + c + 3 * r);
          }
        }
        colptr[3 * C + c + 1] = static_cast<std::int64_t>(rowind.size());
      }
    }
    A = cholmod_allocate_sparse(3 * n, 3 * n, rowind.size(), /*sorted*/ 1, /*packed*/ 1, /*stype lower*/ -1,
                                CHOLMOD_REAL, &common);
    if (!A) throw_error("CHOLMOD: cannot allocate a {}x{} matrix with {} entries", 3 * n, 3 * n, rowind.size());
    // Debian's CHOLMOD uses int indices for the plain (non-_l) interface.
    auto* p = static_cast<int*>(A->p);
    auto* i = static_cast<int*>(A->i);
    for (size_t k = 0; k < colptr.size(); ++k) p[k] = static_cast<int>(colptr[k]);
    for (size_t k = 0; k < rowind.size(); ++k) i[k] = static_cast<int>(rowind[k]);
  }
};

CholmodSolver::CholmodSolver() : m(std::make_unique<Impl>()) {}
CholmodSolver::~CholmodSolver() = default;

bool CholmodSolver::factorize(const BlockMatrix3& M, double shift) {
  const bool new_pattern = !m->A || m->offsets != M.row_offsets() || m->cols != M.col_indices();
  if (new_pattern) m->build_structure(M);
  const double* src = M.blocks().empty() ? nullptr : M.blocks().front().data();
  auto* val = static_cast<double*>(m->A->x);
  const auto nnz = static_cast<Index>(m->source.size());
  parallel_for(nnz, [&](Index k) { val[k] = src[m->source[k]]; }, 8192);
  if (shift != 0.0)
    for (auto slot : m->diagonal_slots) val[slot] += shift;
  if (new_pattern) {
    m->L = cholmod_analyze(m->A, &m->common);
    if (!m->L) throw_error("CHOLMOD: symbolic analysis failed (status {})", m->common.status);
    ++m_analyses;
  }
  // The supernodal factorization makes thousands of small BLAS calls; OpenMP-threaded BLAS forks for each and
  // the fork/join cost dominates (measured 6x slower with 2 threads than with 1 on a 30K-dof cloth).
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const int ok = cholmod_factorize(m->A, m->L, &m->common);
  omp_set_num_threads(threads);
  if (!ok || m->common.status == CHOLMOD_NOT_POSDEF) return false;
  if (m->common.status < CHOLMOD_OK) throw_error("CHOLMOD: factorization failed (status {})", m->common.status);
  return m->L->minor == m->L->n;
}

void CholmodSolver::solve(const VecX& b, VecX& x) const {
  if (!m->L) throw_error("CholmodSolver::solve called before factorize");
  cholmod_dense* B = cholmod_allocate_dense(b.size(), 1, b.size(), CHOLMOD_REAL, &m->common);
  std::copy(b.data(), b.data() + b.size(), static_cast<double*>(B->x));
  // The triangular solves call BLAS per supernode too: one thread, for the reason given in factorize().
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  cholmod_dense* X = cholmod_solve(CHOLMOD_A, m->L, B, &m->common);
  omp_set_num_threads(threads);
  if (!X) {
    cholmod_free_dense(&B, &m->common);
    throw_error("CHOLMOD: solve failed (status {})", m->common.status);
  }
  x.resize(b.size());
  std::copy(static_cast<double*>(X->x), static_cast<double*>(X->x) + b.size(), x.data());
  cholmod_free_dense(&X, &m->common);
  cholmod_free_dense(&B, &m->common);
}

}  // namespace mgcloth::linalg
