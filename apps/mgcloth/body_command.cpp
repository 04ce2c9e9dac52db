#include "commands.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/geometry/mannequin.hpp>
#include <mgcloth/sim/gltf_export.hpp>
#include <mgcloth/sim/gltf_skin.hpp>

#include <fmt/format.h>
#include <fmt/os.h>

#include <cmath>
#include <filesystem>
#include <system_error>

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

struct BodyOptions {
  std::string out;
  geometry::MannequinParams body;
  geometry::WalkParams walk;
  double seconds = 5.0;
  double fps = 30.0;
  bool in_place = false;
  std::vector<std::string> formats{"obj", "glb"};
} g_body;

void write_obj_frame(const fs::path& path, const Mat3X& x, const std::vector<Tri>& tris) {
  write_file_atomic(path, [&](std::ostream& os) {
    os << "# mgcloth body: the generated mannequin\n";
    for (Index v = 0; v < x.cols(); ++v) os << fmt::format("v {:.6f} {:.6f} {:.6f}\n", x(0, v), x(1, v), x(2, v));
    for (const auto& t : tris) os << fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  });
}

}  // namespace

void add_body_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "body", "Write the generated walking mannequin as OBJ frames (body_0000.obj, ...) and a skinned, animated glb");
  auto& o = g_body;
  cmd->add_option("--out", o.out, "Output folder (created)")->required();
  const auto in = [](double lo, double hi) {
    return requires_number([lo, hi](double v) { return v >= lo && v <= hi; }, fmt::format("in [{}, {}]", lo, hi));
  };
  cmd->add_option("--height", o.body.height, "Sole to crown, m (1.2 to 2.2)")->check(in(1.2, 2.2))->capture_default_str();
  cmd->add_option("--build", o.body.build, "Girth factor of every limb and the torso (0.7 to 1.5)")
      ->check(in(0.7, 1.5))
      ->capture_default_str();
  cmd->add_option("--resolution", o.body.resolution, "Edge length of the surface, m (0.003 to 0.05)")
      ->check(in(0.003, 0.05))
      ->capture_default_str();
  cmd->add_option("--arm-abduction", o.body.arm_abduction, "Arms away from the vertical in the bind pose, degrees")
      ->check(in(5, 60))
      ->capture_default_str();
  cmd->add_option("--period", o.walk.period, "Gait cycle (two steps), s (0.5 to 3)")->check(in(0.5, 3))->capture_default_str();
  cmd->add_option("--stand", o.walk.stand, "Standing still before the first step, s")->check(in(0, 1e4))->capture_default_str();
  cmd->add_option("--ramp", o.walk.ramp, "The walk blends in over this long, s")->check(in(0, 1e4))->capture_default_str();
  cmd->add_option("--arm-swing", o.walk.arm_swing, "Arm swing, scaled (0 to 3)")->check(in(0, 3))->capture_default_str();
  cmd->add_flag("--in-place", o.in_place, "Walk on the spot (a treadmill)");
  cmd->add_option("--seconds", o.seconds, "Length of the animation, s")->check(in(0, 1e4))->capture_default_str();
  cmd->add_option("--fps", o.fps, "OBJ frames per second")->check(in(1e-3, 1000))->capture_default_str();
  cmd->add_option("--format", o.formats, "obj, glb or both")
      ->check(CLI::IsMember({"obj", "glb"}))
      ->delimiter(',')
      ->capture_default_str();
}

int run_body_command() {
  auto& o = g_body;
  const fs::path dir(o.out);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw_error("{}: cannot create the folder ({})", dir.string(), ec.message());
  o.walk.forward = !o.in_place;
  o.walk.duration = o.seconds;
  const Timer timer;
  geometry::MannequinInfo info;
  const geometry::SkinnedMesh skin = geometry::make_mannequin(o.body, o.walk, &info);
  const bool obj = std::find(o.formats.begin(), o.formats.end(), "obj") != o.formats.end();
  const bool glb = std::find(o.formats.begin(), o.formats.end(), "glb") != o.formats.end();
  size_t frames = 0;
  if (obj) {
    const auto n = static_cast<size_t>(std::floor(o.seconds * o.fps + 1e-9)) + 1;
    for (size_t k = 0; k < n; ++k) {
      write_obj_frame(dir / fmt::format("body_{:04d}.obj", k), skin.at(static_cast<double>(k) / o.fps), skin.tris);
    }
    frames = n;
  }
  if (glb) {
    if (!sim::glb_available()) throw_error("{}: this build has no glTF support (tinygltf was not found)", (dir / "body.glb").string());
    sim::SkinWriteOptions opt;
    opt.material = "body";
    sim::write_skinned_glb(dir / "body.glb", skin, opt);
  }
  fmt::print("body: {} vertices, {} triangles, {:.3f} m tall, volume {:.4f} m³; walks at {:.2f} m/s, stride {:.2f} m\n",
             skin.num_vertices(), skin.tris.size(), skin.at(0.0).row(2).maxCoeff(), info.volume, info.speed, info.stride);
  if (obj) {
    fmt::print("wrote {} OBJ frames at {} fps: {}; in a scene: {{\"mesh\": \"{}\", \"mesh_rate\": {}}}\n", frames, o.fps,
               (dir / "body_%04d.obj").string(), (dir / "body_%04d.obj").string(), o.fps);
  }
  if (glb) fmt::print("wrote {} (skinned, {} joints, {:.2f} s of animation)\n", (dir / "body.glb").string(), skin.num_joints(), skin.duration());
  fmt::print("in {:.2f} s\n", timer.seconds());
  return 0;
}

}  // namespace mgcloth::cli
