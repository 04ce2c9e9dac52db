// Scene files (cloth and shell scenes): JSON text -> parse_json -> parse_scene, as `mgcloth run` reads them.
// Bad input must end in InputError; any other exception, a crash, a leak or UB is a finding. A scene that parses
// must also parse again from its resolved form (to_json), which `mgcloth run` writes as scene.resolved.json.
#include <mgcloth/core/json.hpp>
#include <mgcloth/sim/scene.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mgcloth;
  // Mesh paths are only resolved against it, never opened, by the parser.
  static const std::filesystem::path base = "/nonexistent/fuzz";
  const std::string text(reinterpret_cast<const char*>(data), size);
  sim::Scene scene;
  try {
    scene = sim::parse_scene(parse_json(text, "fuzz.json"), "fuzz.json", base);
  } catch (const InputError&) {
    return 0;
  }
  try {
    (void)sim::parse_scene(sim::to_json(scene), "fuzz.resolved.json", base);
  } catch (const InputError& e) {
    std::fprintf(stderr, "a scene that parses has a resolved form that does not: %s\n", e.what());
    std::abort();
  }
  return 0;
}
