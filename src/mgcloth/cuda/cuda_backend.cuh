#pragma once
// The CUDA execution backend of the device pipeline (pipeline.hpp): buffers in device memory, for_each as a kernel
// launch of the pipeline's __host__ __device__ lambda, sum as a deterministic two-pass block reduction (fixed grid,
// fixed tree order), and the coarsest level's dense Cholesky by cuSOLVER (loaded at run time, so that the binary
// needs nothing of CUDA but the driver: the runtime is linked statically).
#include <cuda_runtime.h>

#include <mgcloth/core/types.hpp>
#include <mgcloth/cuda/layout.hpp>

#include <algorithm>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace mgcloth::cuda {

/// Throws mgcloth::Error naming `what` when e is not cudaSuccess.
void check_cuda(cudaError_t e, const char* what);

template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept : m_p(std::exchange(o.m_p, nullptr)), m_n(std::exchange(o.m_n, 0)) {}
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    std::swap(m_p, o.m_p);
    std::swap(m_n, o.m_n);
    return *this;
  }
  ~DeviceBuffer() {
    if (m_p) cudaFree(m_p);
  }
  /// n zeroed elements.
  void resize(size_t n) {
    allocate(n);
    if (n) check_cuda(cudaMemset(m_p, 0, n * sizeof(T)), "cudaMemset");
  }
  size_t size() const { return m_n; }
  T* data() { return m_p; }
  const T* data() const { return m_p; }
  void upload(const std::vector<T>& src) { upload(src.data(), src.size()); }
  void upload(const T* src, size_t n) {
    allocate(n);
    if (n) check_cuda(cudaMemcpy(m_p, src, n * sizeof(T), cudaMemcpyHostToDevice), "cudaMemcpy to the device");
  }
  void download(std::vector<T>& dst) const {
    dst.resize(m_n);
    download(dst.data(), m_n);
  }
  void download(T* dst, size_t n) const {
    if (n) check_cuda(cudaMemcpy(dst, m_p, n * sizeof(T), cudaMemcpyDeviceToHost), "cudaMemcpy to the host");
  }

 private:
  void allocate(size_t n) {
    if (n == m_n) return;
    if (m_p) cudaFree(m_p);
    m_p = nullptr;
    m_n = n;
    if (n) check_cuda(cudaMalloc(&m_p, n * sizeof(T)), "cudaMalloc");
  }
  T* m_p = nullptr;
  size_t m_n = 0;
};

constexpr int kThreads = 256;
constexpr int kMaxReduceBlocks = 1024;

template <class F>
__global__ void for_each_kernel(Index n, F f) {
  const Index i = static_cast<Index>(blockIdx.x) * kThreads + static_cast<Index>(threadIdx.x);
  if (i < n) f(i);
}

__device__ inline void block_reduce(double* s) {
  for (int w = kThreads / 2; w > 0; w /= 2) {
    if (static_cast<int>(threadIdx.x) < w) s[threadIdx.x] += s[threadIdx.x + w];
    __syncthreads();
  }
}

template <class F>
__global__ void sum_kernel(Index n, F f, double* partial) {
  __shared__ double s[kThreads];
  double acc = 0.0;
  const Index stride = static_cast<Index>(gridDim.x) * kThreads;
  for (Index i = static_cast<Index>(blockIdx.x) * kThreads + static_cast<Index>(threadIdx.x); i < n; i += stride) acc += f(i);
  s[threadIdx.x] = acc;
  __syncthreads();
  block_reduce(s);
  if (threadIdx.x == 0) partial[blockIdx.x] = s[0];
}

__global__ void final_sum_kernel(const double* partial, int m, double* out);

/// The stream every kernel runs on: created once, blocking with respect to the legacy default stream, so that the
/// buffers' synchronous copies (cudaMemcpy) stay ordered with the kernels; kernels on it can be captured as graphs.
cudaStream_t pipeline_stream();

/// A captured sequence of kernels (a CUDA graph), instantiated once and replayed.
class CudaGraph {
 public:
  CudaGraph() = default;
  CudaGraph(const CudaGraph&) = delete;
  CudaGraph& operator=(const CudaGraph&) = delete;
  ~CudaGraph() { reset(); }
  bool ready() const { return exec != nullptr; }
  void reset() {
    if (exec) cudaGraphExecDestroy(exec);
    exec = nullptr;
    failed = false;
  }
  cudaGraphExec_t exec = nullptr;
  bool failed = false;  ///< the capture failed once (something in it cannot be captured): run without a graph
};

/// Scratch of the reductions (device partial sums, pinned result), allocated once per process.
double* reduce_partials();
double* reduce_result_device();
double* reduce_result_host();

struct CudaBackend {
  template <class T>
  using Buffer = DeviceBuffer<T>;
  static const char* name() { return "cuda"; }
  static std::string device_name();

  template <class F>
  static void for_each(Index n, F f) {
    if (n <= 0) return;
    for_each_kernel<<<(n + kThreads - 1) / kThreads, kThreads, 0, pipeline_stream()>>>(n, f);
    check_cuda(cudaGetLastError(), "kernel launch");
  }
  template <class F>
  static double sum(Index n, F f) {
    if (n <= 0) return 0.0;
    const int blocks = static_cast<int>(std::min<Index>(kMaxReduceBlocks, (n + kThreads - 1) / kThreads));
    cudaStream_t s = pipeline_stream();
    sum_kernel<<<blocks, kThreads, 0, s>>>(n, f, reduce_partials());
    check_cuda(cudaGetLastError(), "reduction launch");
    final_sum_kernel<<<1, kThreads, 0, s>>>(reduce_partials(), blocks, reduce_result_device());
    check_cuda(cudaMemcpyAsync(reduce_result_host(), reduce_result_device(), sizeof(double), cudaMemcpyDeviceToHost, s),
               "reduction result");
    check_cuda(cudaStreamSynchronize(s), "reduction result");
    return *reduce_result_host();
  }
  static void synchronize() { check_cuda(cudaStreamSynchronize(pipeline_stream()), "cudaStreamSynchronize"); }

  using Graph = CudaGraph;
  /// Stream capture of body's kernels into g (none runs); false, with g.failed, when the capture or instantiation
  /// failed (something in body cannot be captured): the caller then runs body directly.
  static bool capture(Graph& g, const std::function<void()>& body);
  static void launch(const Graph& g) { check_cuda(cudaGraphLaunch(g.exec, pipeline_stream()), "cudaGraphLaunch"); }

  /// The reference for FmgSettings::compare_spgemm: C = Pt (A P) by cuSPARSE's SpGEMM (generic API, loaded at run
  /// time like cuSOLVER) on the device, the mean time of `repeats` runs (work estimation, compute and copy of both
  /// products, the buffers of the warm-up reused) into ms. False where cuSPARSE cannot be loaded.
  static bool spgemm_rap(const ScalarCsr& A, const ScalarCsr& P, const ScalarCsr& Pt, int repeats, ScalarCsr& C,
                         double& ms);

  /// Dense Cholesky of an N x N column-major SPD matrix in device memory: cuSOLVER potrf/potrs where the library
  /// can be loaded, else the factor is computed on the host (and each solve goes through it).
  class DenseCholesky {
   public:
    DenseCholesky();
    ~DenseCholesky();
    DenseCholesky(const DenseCholesky&) = delete;
    DenseCholesky& operator=(const DenseCholesky&) = delete;
    bool factorize(const double* A, Index N);
    void solve(const double* b, double* x);
    bool on_device() const;

   private:
    struct Impl;
    Impl* m_impl;
  };
};

}  // namespace mgcloth::cuda
