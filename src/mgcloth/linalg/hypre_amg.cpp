#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/hypre_amg.hpp>

#include <HYPRE.h>
#include <HYPRE_parcsr_ls.h>
#include <_hypre_parcsr_mv.h>
#include <mpi.h>

#include <cstdlib>
#include <limits>
#include <string>

#if defined(__SANITIZE_ADDRESS__)
#define MGCLOTH_LSAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MGCLOTH_LSAN 1
#endif
#endif
#ifdef MGCLOTH_LSAN
#include <sanitizer/lsan_interface.h>
#endif

namespace mgcloth::linalg {
namespace {

/// Debian's hypre is built with MPI: every hypre call needs MPI initialized. A program that never started MPI gets
/// a singleton process here, on the first HypreAmg, finalized at exit; a program that started MPI keeps owning it.
/// Static-local: destroyed after every HypreAmg that was constructed after it, so no hypre object outlives MPI.
class HypreRuntime {
 public:
  static void ensure() { static HypreRuntime runtime; }

 private:
  HypreRuntime() {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) {
      EnvOverride env;
      if (!launched_by_mpi()) set_singleton_environment(env);
      int provided = 0;
#ifdef MGCLOTH_LSAN
      // Open MPI keeps allocations from its initialization that it never frees (nothing of ours; a
      // MGCLOTH_SANITIZE build would report them as leaks in every test that uses hypre).
      __lsan::ScopedDisabler open_mpi_keeps_these;
#endif
      if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS)
        throw_error("hypre: MPI_Init_thread failed");
      m_owns_mpi = true;
    }
    HYPRE_Init();
  }
  ~HypreRuntime() {
    HYPRE_Finalize();
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (m_owns_mpi && !finalized) MPI_Finalize();
  }

  /// Sets environment variables the user has not set for the duration of MPI_Init, then removes them again (the
  /// program's child processes must not inherit them).
  struct EnvOverride {
    std::vector<std::string> added;
    void set(const char* name, const char* value) {
      if (std::getenv(name)) return;  // the user's choice wins
      setenv(name, value, 0);
      added.emplace_back(name);
    }
    ~EnvOverride() {
      for (const auto& name : added) unsetenv(name.c_str());
    }
  };

  /// Open MPI's singleton start-up (a program not launched by mpirun) forks a helper daemon and probes network
  /// transports: 0.6-0.7 s per process, measured. We only ever talk over MPI_COMM_SELF, so when not under a
  /// launcher, ask for an isolated singleton with the in-process transport only (0.1 s). Other MPIs ignore these.
  static bool launched_by_mpi() {
    return std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK");
  }
  static void set_singleton_environment(EnvOverride& env) {
    env.set("OMPI_MCA_ess_singleton_isolated", "1");
    env.set("OMPI_MCA_pml", "ob1");
    env.set("OMPI_MCA_btl", "self");
  }

  bool m_owns_mpi = false;
};

/// Throws SolveError with hypre's description when `code` carries a real error (convergence warnings are not).
void check(HYPRE_Int code, const char* what) {
  if (code == 0) return;
  const bool fatal =
      HYPRE_CheckError(code, HYPRE_ERROR_GENERIC) || HYPRE_CheckError(code, HYPRE_ERROR_MEMORY) ||
      HYPRE_CheckError(code, HYPRE_ERROR_ARG);
  char description[256] = {0};
  HYPRE_DescribeError(code, description);
  HYPRE_ClearAllErrors();
  if (fatal) throw_error<SolveError>("hypre: {} failed: {}", what, description);
}

int relax_type(HypreAmgParams::Smoother s, bool down) {
  using S = HypreAmgParams::Smoother;
  switch (s) {
    case S::ForwardBackwardGS: return down ? 13 : 14;
    case S::SymmetricGS: return 6;
    case S::L1SymmetricGS: return 8;
    case S::L1Jacobi: return 18;
  }
  return 6;
}

}  // namespace

struct HypreAmg::Impl {
  hypre_ParCSRMatrix* A = nullptr;
  hypre_ParVector* b = nullptr;
  hypre_ParVector* x = nullptr;
  HYPRE_Solver amg = nullptr;
  // Pattern that A holds, so that new values for the same pattern only rewrite A's value array.
  std::vector<Index> offsets, cols;

  ~Impl() {
    release_solver();
    release_matrix();
  }
  void release_solver() {
    if (amg) HYPRE_BoomerAMGDestroy(amg);
    amg = nullptr;
  }
  void release_matrix() {
    if (A) hypre_ParCSRMatrixDestroy(A);
    if (b) hypre_ParVectorDestroy(b);
    if (x) hypre_ParVectorDestroy(x);
    A = nullptr, b = nullptr, x = nullptr;
    offsets.clear(), cols.clear();
  }

  /// hypre's ParCSR form written directly (hypre's IJ interface searches every entry it inserts and took as long
  /// as the AMG setup): one process, so everything lives in the "diag" CSR part. Scalar row 3r+a lists the
  /// diagonal entry first (hypre's smoothers read it there), then columns 3c+d of every block (r, c) in order.
  void build(const BlockMatrix3& M) {
    const bool same_pattern = A && offsets == M.row_offsets() && cols == M.col_indices();
    if (!same_pattern) allocate(M);
    forget_transposes();
    hypre_CSRMatrix* diag = hypre_ParCSRMatrixDiag(A);
    const HYPRE_Int* I = hypre_CSRMatrixI(diag);
    HYPRE_Int* J = hypre_CSRMatrixJ(diag);
    HYPRE_Complex* V = hypre_CSRMatrixData(diag);
    parallel_for(M.rows(), [&](Index r) {
      const Index kd = M.diagonal(r);
      for (int a = 0; a < 3; ++a) {
        HYPRE_Int out = I[3 * r + a];
        J[out] = 3 * r + a;
        V[out++] = M.block(kd)(a, a);
        for (Index k = offsets[r]; k < offsets[r + 1]; ++k)
          for (int c = 0; c < 3; ++c) {
            if (k == kd && c == a) continue;
            J[out] = 3 * cols[k] + c;
            V[out++] = M.block(k)(a, c);
          }
      }
    });
  }

  /// Transposes hypre may have cached on A for the old values.
  void forget_transposes() {
    for (hypre_CSRMatrix** t : {&hypre_ParCSRMatrixDiagT(A), &hypre_ParCSRMatrixOffdT(A)}) {
      if (*t) hypre_CSRMatrixDestroy(*t);
      *t = nullptr;
    }
  }

  void allocate(const BlockMatrix3& M) {
    release_matrix();
    const Index n = M.rows();
    if (9.0 * M.num_blocks() > static_cast<double>(std::numeric_limits<HYPRE_Int>::max()))
      throw_error<SolveError>("BoomerAMG: {} scalar entries overflow hypre's 32-bit indices", 9.0 * M.num_blocks());
    offsets = M.row_offsets();
    cols = M.col_indices();
    const HYPRE_BigInt N = 3 * static_cast<HYPRE_BigInt>(n);
    HYPRE_BigInt starts[2] = {0, N};
    A = hypre_ParCSRMatrixCreate(MPI_COMM_SELF, N, N, starts, starts, 0, 9 * M.num_blocks(), 0);
    hypre_ParCSRMatrixInitialize(A);
    HYPRE_Int* I = hypre_CSRMatrixI(hypre_ParCSRMatrixDiag(A));
    parallel_for(n, [&](Index r) {
      for (int a = 0; a < 3; ++a) I[3 * r + a] = 9 * offsets[r] + 3 * (offsets[r + 1] - offsets[r]) * a;
    });
    I[N] = 9 * M.num_blocks();
    hypre_ParCSRMatrixSetNumNonzeros(A);
    hypre_ParCSRMatrixSetDNumNonzeros(A);
    hypre_MatvecCommPkgCreate(A);
    b = hypre_ParVectorCreate(MPI_COMM_SELF, N, starts);
    x = hypre_ParVectorCreate(MPI_COMM_SELF, N, starts);
    hypre_ParVectorInitialize(b);
    hypre_ParVectorInitialize(x);
  }

  double* data(hypre_ParVector* v) const { return hypre_VectorData(hypre_ParVectorLocalVector(v)); }

  void configure(const HypreAmgParams& p) {
    check(HYPRE_BoomerAMGCreate(&amg), "BoomerAMGCreate");
    // As a preconditioner: one V-cycle, no convergence test (hypre then skips the residual norms).
    HYPRE_BoomerAMGSetMaxIter(amg, 1);
    HYPRE_BoomerAMGSetTol(amg, 0.0);
    HYPRE_BoomerAMGSetPrintLevel(amg, p.print_level);
    // Systems AMG: without SetDofFunc hypre maps unknown i to function i mod 3, which is our xyz interleaving.
    HYPRE_BoomerAMGSetNumFunctions(amg, 3);
    HYPRE_BoomerAMGSetNodal(amg, p.nodal);
    HYPRE_BoomerAMGSetStrongThreshold(amg, p.strong_threshold);
    HYPRE_BoomerAMGSetCoarsenType(amg, static_cast<int>(p.coarsening));
    HYPRE_BoomerAMGSetAggNumLevels(amg, p.aggressive_levels);
    HYPRE_BoomerAMGSetInterpType(amg, p.interp_type);
    HYPRE_BoomerAMGSetPMaxElmts(amg, p.p_max_elements);
    HYPRE_BoomerAMGSetMaxLevels(amg, p.max_levels);
    // Lexicographic order: C/F-ordered relaxation would make the down and up legs non-adjoint.
    HYPRE_BoomerAMGSetRelaxOrder(amg, 0);
    HYPRE_BoomerAMGSetCycleRelaxType(amg, relax_type(p.smoother, true), 1);
    HYPRE_BoomerAMGSetCycleRelaxType(amg, relax_type(p.smoother, false), 2);
    HYPRE_BoomerAMGSetCycleRelaxType(amg, 9, 3);  // Gaussian elimination on the coarsest level
    HYPRE_BoomerAMGSetCycleNumSweeps(amg, p.sweeps, 1);
    HYPRE_BoomerAMGSetCycleNumSweeps(amg, p.sweeps, 2);
    HYPRE_BoomerAMGSetCycleNumSweeps(amg, 1, 3);
  }
};

HypreAmg::HypreAmg(HypreAmgParams params) : m_params(params) {
  if (params.nodal < 0 || params.nodal == 5 || params.nodal > 6)
    throw_input_error("HypreAmg: nodal must be 0 (unknown-based) or a block norm 1-4 or 6, not {}", params.nodal);
  if (!(params.strong_threshold > 0.0 && params.strong_threshold < 1.0))
    throw_input_error("HypreAmg: strong_threshold must lie in (0, 1), not {}", params.strong_threshold);
  if (params.sweeps < 1 || params.max_levels < 1 || params.aggressive_levels < 0 || params.p_max_elements < 0)
    throw_input_error("HypreAmg: sweeps and max_levels must be >= 1, aggressive_levels and p_max_elements >= 0");
  HypreRuntime::ensure();
  m = std::make_unique<Impl>();
}

HypreAmg::~HypreAmg() = default;

void HypreAmg::set_matrix(const BlockMatrix3& A) {
  const Index n = A.rows();
  if (n == 0) throw_error("BoomerAMG: empty matrix");
  for (Index r = 0; r < n; ++r)
    for (int a = 0; a < 3; ++a)
      if (!(A.block(A.diagonal(r))(a, a) > 0.0))
        throw_error<SolveError>("BoomerAMG: diagonal entry {} of block row {} is {} (the matrix must be SPD)", a, r,
                                A.block(A.diagonal(r))(a, a));
  Timer timer;
  m->release_solver();
  m->build(A);
  m_copy_seconds = timer.seconds();
  timer.reset();
  m->configure(m_params);
  try {
    check(HYPRE_BoomerAMGSetup(m->amg, m->A, m->b, m->x), "BoomerAMGSetup");
  } catch (...) {
    m->release_solver();
    throw;
  }
  m_setup_seconds = timer.seconds();
}

void HypreAmg::apply(const VecX& r, VecX& z) const {
  if (!m->amg) throw_error("HypreAmg::apply called before set_matrix");
  const auto N = static_cast<Index>(hypre_ParVectorGlobalSize(m->b));
  if (r.size() != N) throw_error("HypreAmg: vector of size {} for a matrix with {} rows", r.size(), N);
  VecX::Map(m->data(m->b), N) = r;
  VecX::Map(m->data(m->x), N).setZero();
  check(HYPRE_BoomerAMGSolve(m->amg, m->A, m->b, m->x), "BoomerAMGSolve");
  z = VecX::Map(m->data(m->x), N);
}

}  // namespace mgcloth::linalg
