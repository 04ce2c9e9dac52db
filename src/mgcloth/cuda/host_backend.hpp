#pragma once
// The execution backend of the device pipeline on the CPU: the same kernels (MGCLOTH_HOST_DEVICE lambdas over an
// index range) run as OpenMP loops over std::vector buffers. It makes the whole GPU pipeline testable on machines
// without a GPU, against the CPU solvers (tests/cuda/); the CUDA backend (cuda_backend.cuh) launches the same
// lambdas as kernels.
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/cuda/layout.hpp>

#include <Eigen/SparseCore>

#include <Eigen/Cholesky>
#include <functional>
#include <string>
#include <vector>

namespace mgcloth::cuda {

/// The host backend's CUDA graph: while a capture is recording, launches are recorded instead of run (as stream
/// capture does on the GPU), so that a replay runs the same kernels with the arguments frozen at capture: the host
/// tests check that the pipeline captures nothing that changes between replays. Host copies and reductions cannot
/// be captured (they need the device's results on the host): they fail the capture, as on the GPU.
struct HostGraph {
  std::vector<std::function<void()>> ops;
  bool failed = false;
  bool ready() const { return !failed && !ops.empty(); }
  void reset() {
    ops.clear();
    failed = false;
  }
  static HostGraph*& recording() {
    static thread_local HostGraph* g = nullptr;
    return g;
  }
};

template <class T>
class HostBuffer {
 public:
  void resize(size_t n) { m_v.assign(n, T{}); }
  size_t size() const { return m_v.size(); }
  T* data() { return m_v.data(); }
  const T* data() const { return m_v.data(); }
  void upload(const std::vector<T>& src) {
    uncapturable();
    m_v = src;
  }
  void upload(const T* src, size_t n) {
    uncapturable();
    m_v.assign(src, src + n);
  }
  void download(std::vector<T>& dst) const {
    uncapturable();
    dst = m_v;
  }
  void download(T* dst, size_t n) const {
    uncapturable();
    std::copy(m_v.begin(), m_v.begin() + static_cast<std::ptrdiff_t>(n), dst);
  }

 private:
  static void uncapturable() {
    if (HostGraph* g = HostGraph::recording()) g->failed = true;
  }
  std::vector<T> m_v;
};

struct HostBackend {
  template <class T>
  using Buffer = HostBuffer<T>;
  static const char* name() { return "host"; }
  /// f(i) for i in [0, n); iterations must be independent (they run in parallel).
  template <class F>
  static void for_each(Index n, F f) {
    if (HostGraph* g = HostGraph::recording()) {
      g->ops.push_back([n, f] { parallel_for(n, f); });
      return;
    }
    parallel_for(n, f);
  }
  /// Σ f(i), deterministic (fixed chunking).
  template <class F>
  static double sum(Index n, F f) {
    if (HostGraph* g = HostGraph::recording()) {
      g->failed = true;
      return 0.0;
    }
    return parallel_sum(n, f);
  }

  using Graph = HostGraph;
  /// Records body's launches into g (nothing runs); false when body did something a graph cannot hold.
  template <class F>
  static bool capture(Graph& g, F&& body) {
    g.reset();
    HostGraph::recording() = &g;
    try {
      body();
    } catch (...) {
      HostGraph::recording() = nullptr;
      g.reset();
      g.failed = true;
      return false;
    }
    HostGraph::recording() = nullptr;
    if (g.failed) g.ops.clear();
    return !g.failed;
  }
  static void launch(const Graph& g) {
    for (const auto& op : g.ops) op();
  }
  static void synchronize() {}
  static std::string device_name() { return "host (CPU emulation of the device pipeline)"; }

  /// The reference for FmgSettings::compare_spgemm: C = Pt (A P) by Eigen's sparse products, the mean time of
  /// `repeats` runs after a warm-up into ms.
  static bool spgemm_rap(const ScalarCsr& A, const ScalarCsr& P, const ScalarCsr& Pt, int repeats, ScalarCsr& C,
                         double& ms) {
    using Sp = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;
    const auto map = [](const ScalarCsr& m) {
      return Eigen::Map<const Sp>(m.rows, m.cols, static_cast<int>(m.values.size()), m.offsets.data(),
                                  m.indices.data(), m.values.data());
    };
    Sp result = map(Pt) * Sp(map(A) * map(P));
    Timer t;
    for (int r = 0; r < repeats; ++r) result = map(Pt) * Sp(map(A) * map(P));
    ms = t.ms() / repeats;
    result.makeCompressed();
    C.rows = static_cast<int>(result.rows());
    C.cols = static_cast<int>(result.cols());
    C.offsets.assign(result.outerIndexPtr(), result.outerIndexPtr() + result.rows() + 1);
    C.indices.assign(result.innerIndexPtr(), result.innerIndexPtr() + result.nonZeros());
    C.values.assign(result.valuePtr(), result.valuePtr() + result.nonZeros());
    return true;
  }

  /// Dense Cholesky of an N x N column-major SPD matrix in place (the CUDA backend's cuSOLVER potrf/potrs).
  class DenseCholesky {
   public:
    bool factorize(const double* A, Index N) {
      m_llt.compute(Eigen::Map<const Eigen::MatrixXd>(A, N, N));
      return m_llt.info() == Eigen::Success;
    }
    void solve(const double* b, double* x) const {
      if (HostGraph* g = HostGraph::recording()) {
        g->ops.push_back([this, b, x] { solve(b, x); });
        return;
      }
      const Index N = m_llt.rows();
      Eigen::Map<Eigen::VectorXd>(x, N) = m_llt.solve(Eigen::Map<const Eigen::VectorXd>(b, N));
    }

   private:
    Eigen::LLT<Eigen::MatrixXd> m_llt;
  };
};

}  // namespace mgcloth::cuda
