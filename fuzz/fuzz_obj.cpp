// OBJ meshes through every reader that takes them from users: read_obj as `mgcloth run` (checked) and
// `mgcloth info` (unchecked) call it, and read_quad_obj for shell control meshes. The readers take a path, so
// the input goes to a per-process file first. Bad input must end in InputError; a crash, a leak, UB or any other
// exception is a finding.
#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace {
struct InputFile {
  std::filesystem::path path;
  InputFile() {
    const std::filesystem::path dir =
        std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
    path = dir / ("mgcloth_fuzz_obj_" + std::to_string(::getpid()) + ".obj");
  }
  ~InputFile() {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
};
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mgcloth;
  static const InputFile file;
  const std::filesystem::path& path = file.path;
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    (void)mesh::read_obj(path, 1.0, true);
  } catch (const InputError&) {
  }
  try {
    (void)mesh::read_obj(path, 1.0, false);
  } catch (const InputError&) {
  }
  try {
    (void)mesh::read_quad_obj(path, 1.0, true);
  } catch (const InputError&) {
  }
  return 0;
}
