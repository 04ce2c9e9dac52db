// The device pipeline instantiated for the CUDA backend.
#include <mgcloth/cuda/cuda_backend.cuh>
#include <mgcloth/cuda/pipeline.hpp>

#include <cusolverDn.h>
#include <dlfcn.h>

#include <Eigen/Cholesky>

namespace mgcloth::cuda {

void check_cuda(cudaError_t e, const char* what) {
  if (e != cudaSuccess) fail(std::string("fmg-cuda: ") + what + " failed: " + cudaGetErrorString(e));
}

__global__ void final_sum_kernel(const double* partial, int m, double* out) {
  __shared__ double s[kThreads];
  double acc = 0.0;
  for (int i = static_cast<int>(threadIdx.x); i < m; i += kThreads) acc += partial[i];
  s[threadIdx.x] = acc;
  __syncthreads();
  block_reduce(s);
  if (threadIdx.x == 0) *out = s[0];
}

namespace {
struct Scratch {
  double* partials = nullptr;
  double* result = nullptr;
  double* host = nullptr;
  Scratch() {
    check_cuda(cudaMalloc(&partials, kMaxReduceBlocks * sizeof(double)), "cudaMalloc (reduction)");
    check_cuda(cudaMalloc(&result, sizeof(double)), "cudaMalloc (reduction)");
    check_cuda(cudaMallocHost(&host, sizeof(double)), "cudaMallocHost (reduction)");
  }
};
// Never freed: the process's CUDA context outlives every pipeline, and freeing at static destruction would race
// the runtime's own teardown.
Scratch& scratch() {
  static Scratch* s = new Scratch();
  return *s;
}
}  // namespace

cudaStream_t pipeline_stream() {
  static cudaStream_t s = [] {
    cudaStream_t created = nullptr;
    check_cuda(cudaStreamCreate(&created), "cudaStreamCreate");
    return created;
  }();
  return s;
}

bool CudaBackend::capture(Graph& g, const std::function<void()>& body) {
  g.reset();
  cudaStream_t s = pipeline_stream();
  const auto give_up = [&] {
    cudaGraph_t partial = nullptr;
    cudaStreamCaptureStatus status;
    if (cudaStreamIsCapturing(s, &status) == cudaSuccess && status != cudaStreamCaptureStatusNone) {
      cudaStreamEndCapture(s, &partial);
      if (partial) cudaGraphDestroy(partial);
    }
    (void)cudaGetLastError();
    g.failed = true;
    return false;
  };
  if (cudaStreamBeginCapture(s, cudaStreamCaptureModeThreadLocal) != cudaSuccess) return give_up();
  try {
    body();
  } catch (const std::exception&) {
    return give_up();
  }
  cudaGraph_t graph = nullptr;
  if (cudaStreamEndCapture(s, &graph) != cudaSuccess || !graph) return give_up();
  const cudaError_t e = cudaGraphInstantiate(&g.exec, graph, 0);
  cudaGraphDestroy(graph);
  if (e != cudaSuccess) {
    g.exec = nullptr;
    return give_up();
  }
  return true;
}

double* reduce_partials() { return scratch().partials; }
double* reduce_result_device() { return scratch().result; }
double* reduce_result_host() { return scratch().host; }

std::string CudaBackend::device_name() {
  int dev = 0;
  cudaDeviceProp prop{};
  if (cudaGetDevice(&dev) != cudaSuccess || cudaGetDeviceProperties(&prop, dev) != cudaSuccess) return "cuda";
  return std::string(prop.name) + " (sm_" + std::to_string(prop.major) + std::to_string(prop.minor) + ", " +
         std::to_string(prop.multiProcessorCount) + " SMs, " +
         std::to_string(static_cast<long>(prop.totalGlobalMem >> 30)) + " GiB)";
}

// cuSOLVER, loaded at run time: the potrf/potrs entry points of its dense API.
struct CudaBackend::DenseCholesky::Impl {
  using Create = cusolverStatus_t (*)(cusolverDnHandle_t*);
  using Destroy = cusolverStatus_t (*)(cusolverDnHandle_t);
  using BufferSize = cusolverStatus_t (*)(cusolverDnHandle_t, cublasFillMode_t, int, double*, int, int*);
  using Potrf = cusolverStatus_t (*)(cusolverDnHandle_t, cublasFillMode_t, int, double*, int, double*, int, int*);
  using Potrs = cusolverStatus_t (*)(cusolverDnHandle_t, cublasFillMode_t, int, int, const double*, int, double*, int, int*);
  using SetStream = cusolverStatus_t (*)(cusolverDnHandle_t, cudaStream_t);
  void* lib = nullptr;
  cusolverDnHandle_t handle = nullptr;
  Create create = nullptr;
  Destroy destroy = nullptr;
  BufferSize buffer_size = nullptr;
  Potrf potrf = nullptr;
  Potrs potrs = nullptr;
  DeviceBuffer<double> factor, work;
  DeviceBuffer<int> info;
  int N = 0;
  // Host fallback.
  Eigen::LLT<Eigen::MatrixXd> llt;
  std::vector<double> hb;

  Impl() {
    for (const char* name : {"libcusolver.so.12", "libcusolver.so.11", "libcusolver.so"}) {
      lib = dlopen(name, RTLD_NOW | RTLD_LOCAL);
      if (lib) break;
    }
    if (!lib) return;
    create = reinterpret_cast<Create>(dlsym(lib, "cusolverDnCreate"));
    destroy = reinterpret_cast<Destroy>(dlsym(lib, "cusolverDnDestroy"));
    buffer_size = reinterpret_cast<BufferSize>(dlsym(lib, "cusolverDnDpotrf_bufferSize"));
    potrf = reinterpret_cast<Potrf>(dlsym(lib, "cusolverDnDpotrf"));
    potrs = reinterpret_cast<Potrs>(dlsym(lib, "cusolverDnDpotrs"));
    const auto set_stream = reinterpret_cast<SetStream>(dlsym(lib, "cusolverDnSetStream"));
    // On the pipeline's stream, so that the coarse solve is ordered with the kernels and captured with them.
    if (!create || !destroy || !buffer_size || !potrf || !potrs || !set_stream || create(&handle) != CUSOLVER_STATUS_SUCCESS ||
        set_stream(handle, pipeline_stream()) != CUSOLVER_STATUS_SUCCESS) {
      handle = nullptr;
      dlclose(lib);
      lib = nullptr;
    }
  }
  ~Impl() {
    if (handle) destroy(handle);
  }
};

CudaBackend::DenseCholesky::DenseCholesky() : m_impl(new Impl()) {}
CudaBackend::DenseCholesky::~DenseCholesky() { delete m_impl; }
bool CudaBackend::DenseCholesky::on_device() const { return m_impl->handle != nullptr; }

bool CudaBackend::DenseCholesky::factorize(const double* A, Index N) {
  Impl& m = *m_impl;
  m.N = N;
  if (!m.handle) {
    std::vector<double> host(static_cast<size_t>(N) * static_cast<size_t>(N));
    check_cuda(cudaMemcpy(host.data(), A, host.size() * sizeof(double), cudaMemcpyDeviceToHost), "coarse matrix download");
    m.llt.compute(Eigen::Map<const Eigen::MatrixXd>(host.data(), N, N));
    return m.llt.info() == Eigen::Success;
  }
  m.factor.resize(static_cast<size_t>(N) * static_cast<size_t>(N));
  check_cuda(cudaMemcpyAsync(m.factor.data(), A, m.factor.size() * sizeof(double), cudaMemcpyDeviceToDevice,
                             pipeline_stream()), "coarse copy");
  int lwork = 0;
  if (m.buffer_size(m.handle, CUBLAS_FILL_MODE_LOWER, N, m.factor.data(), N, &lwork) != CUSOLVER_STATUS_SUCCESS)
    fail("fmg-cuda: cusolverDnDpotrf_bufferSize failed");
  if (m.work.size() < static_cast<size_t>(lwork)) m.work.resize(static_cast<size_t>(lwork));
  if (m.info.size() == 0) m.info.resize(1);
  if (m.potrf(m.handle, CUBLAS_FILL_MODE_LOWER, N, m.factor.data(), N, m.work.data(), lwork, m.info.data()) !=
      CUSOLVER_STATUS_SUCCESS)
    fail("fmg-cuda: cusolverDnDpotrf failed");
  int info = 0;
  m.info.download(&info, 1);
  return info == 0;
}

void CudaBackend::DenseCholesky::solve(const double* b, double* x) {
  Impl& m = *m_impl;
  const size_t N = static_cast<size_t>(m.N);
  if (!m.handle) {
    m.hb.resize(N);
    check_cuda(cudaMemcpy(m.hb.data(), b, N * sizeof(double), cudaMemcpyDeviceToHost), "coarse rhs download");
    const Eigen::VectorXd sol = m.llt.solve(Eigen::Map<const Eigen::VectorXd>(m.hb.data(), m.N));
    check_cuda(cudaMemcpy(x, sol.data(), N * sizeof(double), cudaMemcpyHostToDevice), "coarse solution upload");
    return;
  }
  if (x != b)
    check_cuda(cudaMemcpyAsync(x, b, N * sizeof(double), cudaMemcpyDeviceToDevice, pipeline_stream()), "coarse rhs copy");
  if (m.potrs(m.handle, CUBLAS_FILL_MODE_LOWER, m.N, 1, m.factor.data(), m.N, x, m.N, m.info.data()) !=
      CUSOLVER_STATUS_SUCCESS)
    fail("fmg-cuda: cusolverDnDpotrs failed");
}

template class Pipeline<CudaBackend>;

std::unique_ptr<DeviceFmg> make_cuda_fmg(const FmgSettings& settings) {
  return std::make_unique<Pipeline<CudaBackend>>(settings);
}

bool probe_cuda(std::string* why) {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    if (why) *why = std::string("the CUDA runtime found no usable device (") + cudaGetErrorString(e) + ")";
    return false;
  }
  if (count == 0) {
    if (why) *why = "no CUDA device on this machine";
    return false;
  }
  return true;
}

}  // namespace mgcloth::cuda
