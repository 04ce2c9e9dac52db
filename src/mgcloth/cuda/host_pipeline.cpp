// The device pipeline instantiated for the host backend, and the factory of both backends.
#include <mgcloth/core/error.hpp>
#include <mgcloth/cuda/host_backend.hpp>
#include <mgcloth/cuda/pipeline.hpp>

namespace mgcloth::cuda {

template class Pipeline<HostBackend>;

#if defined(MGCLOTH_HAVE_CUDA)
// cuda_pipeline.cu
std::unique_ptr<DeviceFmg> make_cuda_fmg(const FmgSettings& settings);
bool probe_cuda(std::string* why);
#endif

bool cuda_compiled() {
#if defined(MGCLOTH_HAVE_CUDA)
  return true;
#else
  return false;
#endif
}

bool cuda_available(std::string* why) {
#if defined(MGCLOTH_HAVE_CUDA)
  return probe_cuda(why);
#else
  if (why) *why = "this build of mgcloth has no CUDA backend (CMake found no nvcc, or MGCLOTH_CUDA=OFF)";
  return false;
#endif
}

std::unique_ptr<DeviceFmg> make_device_fmg(Backend backend, const FmgSettings& settings) {
  if (backend == Backend::Host) return std::make_unique<Pipeline<HostBackend>>(settings);
  std::string why;
  if (!cuda_available(&why)) throw Error(fmt::format("fmg-cuda: no GPU to run on: {}", why));
#if defined(MGCLOTH_HAVE_CUDA)
  return make_cuda_fmg(settings);
#else
  return nullptr;
#endif
}

}  // namespace mgcloth::cuda
