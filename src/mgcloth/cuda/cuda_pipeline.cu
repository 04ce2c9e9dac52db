// The device pipeline instantiated for the CUDA backend.
#include <mgcloth/cuda/cuda_backend.cuh>
#include <mgcloth/cuda/pipeline.hpp>

#include <cusolverDn.h>
#include <cusparse.h>
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

namespace {
// cuSPARSE, loaded at run time: the generic SpGEMM entry points (their types from the header, nothing linked).
struct Cusparse {
  decltype(&cusparseCreate) create = nullptr;
  decltype(&cusparseSetStream) set_stream = nullptr;
  decltype(&cusparseCreateCsr) create_csr = nullptr;
  decltype(&cusparseDestroySpMat) destroy_mat = nullptr;
  decltype(&cusparseSpGEMM_createDescr) create_descr = nullptr;
  decltype(&cusparseSpGEMM_destroyDescr) destroy_descr = nullptr;
  decltype(&cusparseSpGEMM_workEstimation) work_estimation = nullptr;
  decltype(&cusparseSpGEMM_compute) compute = nullptr;
  decltype(&cusparseSpGEMM_copy) copy = nullptr;
  decltype(&cusparseSpMatGetSize) get_size = nullptr;
  decltype(&cusparseCsrSetPointers) set_pointers = nullptr;
  cusparseHandle_t handle = nullptr;

  Cusparse() {
    void* lib = nullptr;
    for (const char* name : {"libcusparse.so.12", "libcusparse.so.13", "libcusparse.so"}) {
      lib = dlopen(name, RTLD_NOW | RTLD_LOCAL);
      if (lib) break;
    }
    if (!lib) return;
    const auto load = [lib](auto& f, const char* symbol) { f = reinterpret_cast<std::decay_t<decltype(f)>>(dlsym(lib, symbol)); };
    load(create, "cusparseCreate");
    load(set_stream, "cusparseSetStream");
    load(create_csr, "cusparseCreateCsr");
    load(destroy_mat, "cusparseDestroySpMat");
    load(create_descr, "cusparseSpGEMM_createDescr");
    load(destroy_descr, "cusparseSpGEMM_destroyDescr");
    load(work_estimation, "cusparseSpGEMM_workEstimation");
    load(compute, "cusparseSpGEMM_compute");
    load(copy, "cusparseSpGEMM_copy");
    load(get_size, "cusparseSpMatGetSize");
    load(set_pointers, "cusparseCsrSetPointers");
    if (!create || !set_stream || !create_csr || !destroy_mat || !create_descr || !destroy_descr || !work_estimation ||
        !compute || !copy || !get_size || !set_pointers || create(&handle) != CUSPARSE_STATUS_SUCCESS ||
        set_stream(handle, pipeline_stream()) != CUSPARSE_STATUS_SUCCESS)
      handle = nullptr;  // the library stays loaded: the process may ask again
  }
  static Cusparse& get() {
    static Cusparse* c = new Cusparse();  // never freed, as the reduction scratch
    return *c;
  }
  void check(cusparseStatus_t st, const char* what) const {
    if (st != CUSPARSE_STATUS_SUCCESS) fail(std::string("fmg-cuda: ") + what + " failed (cuSPARSE status " + std::to_string(static_cast<int>(st)) + ")");
  }
};

/// A scalar CSR matrix in device memory with its cuSPARSE descriptor.
struct DeviceCsr {
  int rows = 0, cols = 0;
  DeviceBuffer<int> offsets, indices;
  DeviceBuffer<double> values;
  cusparseSpMatDescr_t mat = nullptr;
  void describe(const Cusparse& cs, long nnz) {
    if (mat) cs.destroy_mat(mat);
    cs.check(cs.create_csr(&mat, rows, cols, nnz, offsets.data(), nnz ? indices.data() : nullptr,
                           nnz ? values.data() : nullptr, CUSPARSE_INDEX_32I, CUSPARSE_INDEX_32I,
                           CUSPARSE_INDEX_BASE_ZERO, CUDA_R_64F),
             "cusparseCreateCsr");
  }
  void upload(const Cusparse& cs, const ScalarCsr& m) {
    rows = m.rows;
    cols = m.cols;
    offsets.upload(m.offsets);
    indices.upload(m.indices);
    values.upload(m.values);
    describe(cs, static_cast<long>(m.values.size()));
  }
  ~DeviceCsr() {
    if (mat) Cusparse::get().destroy_mat(mat);
  }
};

/// C = A B by cusparseSpGEMM (work estimation, compute, copy), the buffers kept in `work` between calls.
struct SpgemmProduct {
  DeviceBuffer<char> buffer1, buffer2;
  void run(const Cusparse& cs, DeviceCsr& A, DeviceCsr& B, DeviceCsr& C) {
    const double one = 1.0, zero = 0.0;
    const auto op = CUSPARSE_OPERATION_NON_TRANSPOSE;
    const auto alg = CUSPARSE_SPGEMM_DEFAULT;
    if (C.rows != A.rows || C.cols != B.cols || !C.mat) {
      C.rows = A.rows;
      C.cols = B.cols;
      C.offsets.resize(static_cast<size_t>(A.rows) + 1);
      C.describe(cs, 0);
    }
    cusparseSpGEMMDescr_t d = nullptr;
    cs.check(cs.create_descr(&d), "cusparseSpGEMM_createDescr");
    size_t size1 = 0, size2 = 0;
    cs.check(cs.work_estimation(cs.handle, op, op, &one, A.mat, B.mat, &zero, C.mat, CUDA_R_64F, alg, d, &size1, nullptr),
             "cusparseSpGEMM_workEstimation");
    if (buffer1.size() < size1) buffer1.resize(size1);
    cs.check(cs.work_estimation(cs.handle, op, op, &one, A.mat, B.mat, &zero, C.mat, CUDA_R_64F, alg, d, &size1,
                                buffer1.data()),
             "cusparseSpGEMM_workEstimation");
    cs.check(cs.compute(cs.handle, op, op, &one, A.mat, B.mat, &zero, C.mat, CUDA_R_64F, alg, d, &size2, nullptr),
             "cusparseSpGEMM_compute");
    if (buffer2.size() < size2) buffer2.resize(size2);
    cs.check(cs.compute(cs.handle, op, op, &one, A.mat, B.mat, &zero, C.mat, CUDA_R_64F, alg, d, &size2, buffer2.data()),
             "cusparseSpGEMM_compute");
    int64_t rows = 0, cols = 0, nnz = 0;
    cs.check(cs.get_size(C.mat, &rows, &cols, &nnz), "cusparseSpMatGetSize");
    if (C.indices.size() < static_cast<size_t>(nnz)) {
      C.indices.resize(static_cast<size_t>(nnz));
      C.values.resize(static_cast<size_t>(nnz));
    }
    cs.check(cs.set_pointers(C.mat, C.offsets.data(), C.indices.data(), C.values.data()), "cusparseCsrSetPointers");
    cs.check(cs.copy(cs.handle, op, op, &one, A.mat, B.mat, &zero, C.mat, CUDA_R_64F, alg, d), "cusparseSpGEMM_copy");
    cs.check(cs.destroy_descr(d), "cusparseSpGEMM_destroyDescr");
  }
};
}  // namespace

bool CudaBackend::spgemm_rap(const ScalarCsr& A, const ScalarCsr& P, const ScalarCsr& Pt, int repeats, ScalarCsr& C,
                             double& ms) {
  const Cusparse& cs = Cusparse::get();
  if (!cs.handle) return false;
  DeviceCsr a, p, pt, ap, rap;
  a.upload(cs, A);
  p.upload(cs, P);
  pt.upload(cs, Pt);
  SpgemmProduct first, second;
  const auto product = [&] {
    first.run(cs, a, p, ap);
    second.run(cs, pt, ap, rap);
  };
  product();  // warm-up: sizes the buffers
  synchronize();
  Timer t;
  for (int r = 0; r < repeats; ++r) product();
  synchronize();
  ms = t.ms() / repeats;
  int64_t rows = 0, cols = 0, nnz = 0;
  cs.check(cs.get_size(rap.mat, &rows, &cols, &nnz), "cusparseSpMatGetSize");
  C.rows = static_cast<int>(rows);
  C.cols = static_cast<int>(cols);
  C.offsets.resize(static_cast<size_t>(rows) + 1);
  C.indices.resize(static_cast<size_t>(nnz));
  C.values.resize(static_cast<size_t>(nnz));
  rap.offsets.download(C.offsets.data(), C.offsets.size());
  rap.indices.download(C.indices.data(), C.indices.size());
  rap.values.download(C.values.data(), C.values.size());
  return true;
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
