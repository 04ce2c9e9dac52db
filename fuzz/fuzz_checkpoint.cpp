// checkpoint.bin as `mgcloth run --resume` reads it: decode_checkpoint on the raw bytes, and again with the last 8
// bytes replaced by the checksum of the rest, so that inputs get past the checksum to the sizes behind it. Bad
// input must end in InputError; a crash, a leak, UB or any other exception is a finding. What decodes must
// encode back to the same bytes.
#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/checkpoint.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {
void decode(const std::string& bytes) {
  using namespace mgcloth;
  sim::Checkpoint c;
  try {
    c = sim::decode_checkpoint(bytes, "fuzz.bin");
  } catch (const InputError&) {
    return;
  }
  if (sim::encode_checkpoint(c) != bytes) {
    std::fprintf(stderr, "a decoded checkpoint does not encode back to its bytes\n");
    std::abort();
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string bytes(reinterpret_cast<const char*>(data), size);
  decode(bytes);
  if (bytes.size() >= sizeof(std::uint64_t)) {
    const std::size_t body = bytes.size() - sizeof(std::uint64_t);
    const std::uint64_t sum = mgcloth::sim::fnv1a(std::string_view(bytes).substr(0, body));
    std::memcpy(bytes.data() + body, &sum, sizeof sum);
    decode(bytes);
  }
  return 0;
}
