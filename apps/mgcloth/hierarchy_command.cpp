// `mgcloth hierarchy`: builds the nested triangle-mesh hierarchy of a mesh or of a scene's cloths (Wang 2018,
// App. B) and shows it: every level as OBJ (world and material space), a picture of the levels side by side in
// material space, and a table of level sizes and of the colors the multi-color Gauss-Seidel smoother needs. A
// scene's shells show their subdivision levels (Kopaničáková 2019 §5.2): control points and faces per level, and
// the control meshes side by side.
#include "commands.hpp"
#include "raster.hpp"

#include <mgcloth/bodies/shell_body.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/json.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/sim/scene.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <unordered_set>

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

struct HierarchyOptions {
  std::string input;
  std::string out;
  std::string cloth;
  std::string body;
  double material_scale = 1.0;
  hierarchy::HierarchyParams params;
  long long seed = 1;  ///< signed, so that a negative seed is an error rather than a wrapped-around number
  int png_size = 512;
  CLI::Option* material_scale_option = nullptr;
  CLI::Option* cloth_option = nullptr;
  CLI::Option* body_option = nullptr;
} g_hier;

/// One body to show, as the simulator builds it. A cloth (bodies::ClothBody): its mesh (placed in the world), its
/// pinned vertices and the Hessian pattern of its per-step objective, coarsened here. A shell (bodies::ShellBody):
/// its subdivision hierarchy at the scene's level.
struct Subject {
  std::string name;
  std::string source;  ///< for messages: the file (and body)
  fs::path dir;        ///< where its outputs go
  std::unique_ptr<bodies::Body> body;
};

struct LevelRow {
  Index vertices = 0, triangles = 0, boundary_loops = 0, colors = 0;
};

/// One subdivision level of a shell: its control mesh's points and quads, ghost ones (the layer around open
/// boundaries, §5.2.1) included in the totals.
struct ShellLevelRow {
  Index control_points = 0, ghost_points = 0, faces = 0, ghost_faces = 0;
};

std::string lower_extension(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

void check_options() {
  const auto& p = g_hier.params;
  if (!(p.ratio > 1.0) || !std::isfinite(p.ratio)) throw_input_error("--ratio: must be greater than 1 (got {})", p.ratio);
  if (p.min_coarse_vertices < 3) throw_input_error("--min-coarse: must be at least 3 (got {})", p.min_coarse_vertices);
  if (p.max_coarse_vertices < p.min_coarse_vertices)
    throw_input_error("--max-coarse: must be at least --min-coarse (got {} < {})", p.max_coarse_vertices,
                      p.min_coarse_vertices);
  if (g_hier.seed < 0) throw_input_error("--seed: must be non-negative (got {})", g_hier.seed);
  g_hier.params.seed = static_cast<std::uint64_t>(g_hier.seed);
  if (g_hier.png_size < 64 || g_hier.png_size > 4096)
    throw_input_error("--png-size: must be within [64, 4096] pixels (got {})", g_hier.png_size);
  if (!(g_hier.material_scale > 0.0) || !std::isfinite(g_hier.material_scale))
    throw_input_error("--material-scale: must be a positive number of metres per UV unit (got {})", g_hier.material_scale);
  if (fs::exists(g_hier.out) && !fs::is_directory(g_hier.out))
    throw_input_error("--out: {} exists and is not a folder", g_hier.out);
}

std::unique_ptr<bodies::ClothBody> build_body(const sim::ClothSpec& spec, const std::vector<geometry::Obstacle>& obstacles,
                                              const sim::Scene& scene) {
  bodies::ClothEnvironment env = sim::cloth_environment(scene);
  env.obstacles = obstacles;
  return std::make_unique<bodies::ClothBody>(spec, env);
}

/// An OBJ is one cloth with the defaults of a scene cloth (cotton, no pins), written straight into --out.
std::vector<Subject> subjects_from_obj(const fs::path& file) {
  for (const CLI::Option* o : {g_hier.cloth_option, g_hier.body_option})
    if (o->count() > 0)
      throw_input_error("{}: only applies to a scene (.json) input, not to the mesh {}", o->get_name(), file.string());
  sim::ClothSpec spec;
  spec.name = file.stem().string();
  spec.mesh.file = file.string();
  spec.mesh.material_scale = g_hier.material_scale;
  spec.material = sim::material_preset(spec.preset);
  std::vector<Subject> out;
  const sim::Scene defaults;
  out.push_back({spec.name, file.string(), g_hier.out, build_body(spec, {}, defaults)});
  return out;
}

/// Names that are folders under --out: no path separators, not "." or "..".
void check_folder_name(const sim::Scene& scene, const std::string& kind, const std::string& name) {
  if (name.empty() || name == "." || name == ".." || name.find_first_of("/\\") != std::string::npos)
    throw_input_error("{}: {} name \"{}\" cannot be used as a folder name under --out", scene.file, kind, name);
}

/// The scene's bodies that --cloth or --body select (every cloth and shell when neither is given); InputError
/// listing the names when none is.
void select_bodies(const sim::Scene& scene, std::vector<const sim::ClothSpec*>& cloths,
                   std::vector<const bodies::ShellSpec*>& shells) {
  const bool by_cloth = !g_hier.cloth.empty(), by_body = !g_hier.body.empty();
  for (const auto& c : scene.cloths)
    if ((!by_cloth && !by_body) || (by_cloth && c.name == g_hier.cloth) || (by_body && c.name == g_hier.body))
      cloths.push_back(&c);
  for (const auto& sh : scene.shells)
    if (!by_cloth && (!by_body || sh.name == g_hier.body)) shells.push_back(&sh);
  if (!cloths.empty() || !shells.empty()) return;
  std::vector<std::string> cloth_names, body_names;
  for (const auto& c : scene.cloths) cloth_names.push_back(fmt::format("\"{}\"", c.name));
  body_names = cloth_names;
  for (const auto& sh : scene.shells) body_names.push_back(fmt::format("\"{}\"", sh.name));
  if (body_names.empty()) throw_input_error("{}: the scene has no cloths or shells", scene.file);
  if (by_cloth) {
    if (cloth_names.empty()) throw_input_error("{}: the scene has no cloths", scene.file);
    throw_input_error("--cloth: no cloth named \"{}\" in {} (cloths: {})", g_hier.cloth, scene.file,
                      fmt::join(cloth_names, ", "));
  }
  throw_input_error("--body: no cloth or shell named \"{}\" in {} (bodies: {})", g_hier.body, scene.file,
                    fmt::join(body_names, ", "));
}

/// A scene gives one subject per selected cloth and shell, each written into --out/<body name>/.
std::vector<Subject> subjects_from_scene(const fs::path& file) {
  if (g_hier.material_scale_option->count() > 0)
    throw_input_error("--material-scale: only applies to a mesh (.obj) input; a scene sets mesh.material_scale per cloth ({})",
                      file.string());
  const sim::Scene scene = sim::load_scene(file);
  std::vector<const sim::ClothSpec*> selected;
  std::vector<const bodies::ShellSpec*> shells;
  select_bodies(scene, selected, shells);
  // Obstacles only add diagonal (per-vertex) contact blocks to the Hessian, but build them as the simulator does so
  // that the cloth's objective is exactly the simulated one.
  std::vector<geometry::Obstacle> obstacles;
  for (size_t i = 0; i < scene.obstacles.size(); ++i) {
    try {
      obstacles.push_back(scene.obstacles[i].build());
    } catch (const InputError& e) {
      throw_input_error("{}: obstacles[{}] (\"{}\"): {}", scene.file, i, scene.obstacles[i].name, e.what());
    }
  }
  std::vector<Subject> out;
  for (const sim::ClothSpec* c : selected) {
    check_folder_name(scene, "cloth", c->name);
    const auto index = static_cast<size_t>(c - scene.cloths.data());
    try {
      out.push_back({c->name, fmt::format("{} (cloth \"{}\")", scene.file, c->name), fs::path(g_hier.out) / c->name,
                     build_body(*c, obstacles, scene)});
    } catch (const InputError& e) {
      throw_input_error("{}: cloths[{}] (\"{}\"): {}", scene.file, index, c->name, e.what());
    }
  }
  for (const bodies::ShellSpec* sh : shells) {
    check_folder_name(scene, "shell", sh->name);
    const auto index = static_cast<size_t>(sh - scene.shells.data());
    try {
      out.push_back({sh->name, fmt::format("{} (shell \"{}\")", scene.file, sh->name), fs::path(g_hier.out) / sh->name,
                     std::make_unique<bodies::ShellBody>(*sh, scene.gravity, scene.file)});
    } catch (const InputError& e) {
      throw_input_error("{}: shells[{}] (\"{}\"): {}", scene.file, index, sh->name, e.what());
    }
  }
  return out;
}

std::vector<Subject> load_subjects() {
  const fs::path file = g_hier.input;
  if (!fs::exists(file)) throw_input_error("{}: no such file", file.string());
  if (fs::is_directory(file)) throw_input_error("{}: is a folder, not a file", file.string());
  const std::string ext = lower_extension(file);
  if (ext != ".obj" && ext != ".json")
    throw_input_error("{}: unknown input type \"{}\" (expected a mesh .obj or a scene .json)", file.string(), ext);
  return ext == ".obj" ? subjects_from_obj(file) : subjects_from_scene(file);
}

/// Level 0: the pattern of the cloth's Newton Hessian (membrane triangles, bending hinges, pins, contact).
/// Coarser levels: the Galerkin pattern of P_lᵀ A_l P_l (Wang 2018, §3.1), which is what the multigrid smoother
/// colors on those levels.
std::vector<Index> level_colors(const physics::Objective& objective, const hierarchy::TriangleHierarchy& h) {
  std::vector<Index> colors;
  linalg::BlockMatrix3 pattern = objective.hessian_pattern();
  for (Index l = 0; l < h.num_levels(); ++l) {
    colors.push_back(static_cast<Index>(linalg::color_rows(pattern).size()));
    if (l + 1 == h.num_levels()) break;
    const linalg::StencilTable& P = h.prolongation(l);
    const linalg::GalerkinProduct rap(pattern, P);
    pattern = rap.coarse_pattern();
  }
  return colors;
}

/// Panels side by side, one per level, all at one scale in material space (from the bounding box of `u`, every
/// level's material coordinates), each as tall as that box needs plus a label row on top.
struct PanelLayout {
  int panel = 0, font = 1, label_height = 0, content = 0;
  Vec2 lo, size;
  double scale = 0.0, thin = 1.0, thick = 2.5, dot = 2.5;

  PanelLayout(const Mat2X& u, int panel_width) : panel(panel_width) {
    font = std::max(1, panel / 200);
    label_height = 9 * font;
    lo = u.rowwise().minCoeff();
    size = (u.rowwise().maxCoeff() - lo).cwiseMax(1e-300);
    const double margin = std::max(8.0, panel / 32.0);
    scale = std::min((panel - 2 * margin) / size.x(), (panel - 2 * margin) / size.y());
    content = std::min(panel, static_cast<int>(std::ceil(scale * size.y() + 2 * margin)));
    const double scale_px = panel / 512.0;
    thin = std::clamp(scale_px, 0.75, 2.0);
    thick = 2.5 * thin;
    dot = std::max(2.5, 3.5 * scale_px);
  }
  Image image(Index levels) const { return Image(static_cast<int>(levels) * panel, content + label_height, Rgb{255, 255, 255}); }
  /// Pixel coordinates of material point p on panel l (material v up, image y down).
  double px(Index l, const Vec2& p) const { return l * panel + 0.5 * (panel - scale * size.x()) + scale * (p.x() - lo.x()); }
  double py(const Vec2& p) const { return label_height + 0.5 * (content + scale * size.y()) - scale * (p.y() - lo.y()); }
  /// The first (longest) label that fits the panel, and the divider to the previous panel.
  void label(Image& img, Index l, const std::vector<std::string>& labels) const {
    for (const std::string& text : labels)
      if (Image::text_width(text, font) + 4 * font <= panel) {
        img.draw_text(static_cast<int>(l * panel) + 2 * font, 2 * font, text, font, Rgb{0, 0, 0});
        break;
      }
    if (l > 0) img.fill_rect(static_cast<int>(l * panel), 0, static_cast<int>(l * panel) + 1, img.height(), Rgb{200, 200, 200});
  }
};

/// The levels side by side in material space: triangle edges dark, boundary edges thick and blue, kept (pinned)
/// vertices as red dots, each panel labelled with its level and size.
Image draw_levels(const hierarchy::TriangleHierarchy& h, const std::vector<mesh::Topology>& topologies,
                  const std::unordered_set<Index>& keep, int panel) {
  const Rgb edge{80, 80, 80}, boundary{30, 90, 200}, pin{220, 40, 40};
  const Index n = h.num_levels();
  // One scale for all panels, from the finest level's material bounding box.
  const PanelLayout layout(h.level(0).mesh.u, panel);
  Image img = layout.image(n);
  for (Index l = 0; l < n; ++l) {
    const mesh::TriMesh& m = h.level(l).mesh;
    const mesh::Topology& topo = topologies[l];
    const auto px = [&](Index v) { return layout.px(l, m.u.col(v)); };
    const auto py = [&](Index v) { return layout.py(m.u.col(v)); };
    for (Index e = 0; e < topo.num_edges(); ++e)
      if (topo.edge_tris[e][1] >= 0) {
        const auto [a, b] = topo.edges[e];
        img.draw_line(px(a), py(a), px(b), py(b), layout.thin, edge);
      }
    for (Index e = 0; e < topo.num_edges(); ++e)
      if (topo.edge_tris[e][1] < 0) {
        const auto [a, b] = topo.edges[e];
        img.draw_line(px(a), py(a), px(b), py(b), layout.thick, boundary);
      }
    for (Index v = 0; v < m.num_vertices(); ++v)
      if (keep.count(h.level(l).to_finest[v]) > 0) img.fill_circle(px(v), py(v), layout.dot, pin);
    layout.label(img, l, {fmt::format("LEVEL {}: {} VERTICES, {} TRIANGLES", l, m.num_vertices(), m.num_triangles()),
                          fmt::format("LEVEL {}: {} V, {} T", l, m.num_vertices(), m.num_triangles()),
                          fmt::format("L{}: {} V", l, m.num_vertices()), fmt::format("L{}", l)});
  }
  return img;
}

/// A shell's control meshes side by side in material space, finest first: edges of real faces dark, of ghost
/// faces light, the real region's boundary thick and blue; each panel labelled with its level and size.
Image draw_shell_levels(const std::vector<const mesh::QuadMesh*>& meshes, int panel) {
  const Rgb edge{80, 80, 80}, ghost{185, 185, 185}, boundary{30, 90, 200};
  const Index n = static_cast<Index>(meshes.size());
  // One scale for all panels, from every level's points: the ghost layer of a coarser level reaches farther.
  Index points = 0;
  for (const auto* m : meshes) points += m->num_vertices();
  Mat2X all(2, points);
  for (Index k = 0, at = 0; k < n; at += meshes[k]->num_vertices(), ++k)
    all.middleCols(at, meshes[k]->num_vertices()) = meshes[k]->u;
  const PanelLayout layout(all, panel);
  Image img = layout.image(n);
  for (Index l = 0; l < n; ++l) {
    const mesh::QuadMesh& m = *meshes[l];
    const auto line = [&](Index f, int k, double width, Rgb c) {
      const Vec2 a = m.u.col(m.quads[f][k]), b = m.u.col(m.quads[f][(k + 1) % 4]);
      img.draw_line(layout.px(l, a), layout.py(a), layout.px(l, b), layout.py(b), width, c);
    };
    for (const bool real : {false, true})  // real edges over ghost ones
      for (Index f = 0; f < m.num_faces(); ++f)
        if (m.is_ghost_face(f) != real)
          for (int k = 0; k < 4; ++k) line(f, k, layout.thin, real ? edge : ghost);
    for (const auto& [f, k] : mesh::real_boundary_edges(m)) line(f, k, layout.thick, boundary);
    layout.label(img, l, {fmt::format("LEVEL {}: {} POINTS, {} FACES", l, m.num_vertices(), m.num_faces()),
                          fmt::format("LEVEL {}: {} P, {} F", l, m.num_vertices(), m.num_faces()),
                          fmt::format("L{}: {} P", l, m.num_vertices()), fmt::format("L{}", l)});
  }
  return img;
}

/// Removes level files of an earlier run that had more levels, so the folder describes one hierarchy.
void remove_stale_levels(const fs::path& dir, Index num_levels) {
  static const std::regex name(R"(level(\d+)(_material)?\.obj)");
  for (const auto& entry : fs::directory_iterator(dir)) {
    std::smatch match;
    const std::string file = entry.path().filename().string();
    if (entry.is_regular_file() && std::regex_match(file, match, name) && std::stol(match[1].str()) >= num_levels)
      fs::remove(entry.path());
  }
}

void process_cloth(const Subject& s, bodies::ClothBody& body) {
  hierarchy::HierarchyParams params = g_hier.params;
  params.keep = body.pinned_vertices();
  std::sort(params.keep.begin(), params.keep.end());
  params.keep.erase(std::unique(params.keep.begin(), params.keep.end()), params.keep.end());

  Timer timer;
  hierarchy::TriangleHierarchy h;
  try {
    h = hierarchy::build_triangle_hierarchy(body.mesh(), params);
  } catch (const Error& e) {
    throw_error("{}: {}", s.source, e.what());
  }
  const double build_seconds = timer.seconds();

  std::vector<mesh::Topology> topologies;
  std::vector<LevelRow> rows;
  const std::vector<Index> colors = level_colors(body.objective(), h);
  for (Index l = 0; l < h.num_levels(); ++l) {
    const mesh::TriMesh& m = h.level(l).mesh;
    topologies.push_back(mesh::build_topology(m, fmt::format("{} level {}", s.source, l)));
    rows.push_back({m.num_vertices(), m.num_triangles(), static_cast<Index>(topologies.back().boundary_loops.size()), colors[l]});
  }

  fs::create_directories(s.dir);
  const double ms = body.material_scale();
  Json levels = Json::array();
  for (Index l = 0; l < h.num_levels(); ++l) {
    const mesh::TriMesh& m = h.level(l).mesh;
    const std::string world = fmt::format("level{}.obj", l), material = fmt::format("level{}_material.obj", l);
    mesh::write_obj(s.dir / world, m, m.x, ms);
    Mat3X flat = Mat3X::Zero(3, m.num_vertices());
    flat.topRows<2>() = m.u;
    mesh::write_obj(s.dir / material, m, flat, ms);
    levels.push_back({{"level", l}, {"vertices", rows[l].vertices}, {"triangles", rows[l].triangles},
                      {"boundary_loops", rows[l].boundary_loops}, {"colors", rows[l].colors}, {"obj", world},
                      {"material_obj", material}});
  }
  remove_stale_levels(s.dir, h.num_levels());
  const std::unordered_set<Index> keep(params.keep.begin(), params.keep.end());
  draw_levels(h, topologies, keep, g_hier.png_size).write_png(s.dir / "levels.png");

  const Json report = {
      {"input", g_hier.input},
      {"cloth", s.name},
      {"material_scale", ms},
      {"params",
       {{"ratio", params.ratio},
        {"min_coarse_vertices", params.min_coarse_vertices},
        {"max_coarse_vertices", params.max_coarse_vertices},
        {"seed", params.seed},
        {"corner_angle_deg", params.corner_angle_deg}}},
      {"kept_vertices", params.keep},
      {"build_seconds", build_seconds},
      {"colors_of", "level 0: the Newton Hessian's block pattern; level l > 0: the Galerkin pattern P^T A P"},
      {"levels", levels},
      {"png", "levels.png"}};
  write_file_atomic(s.dir / "hierarchy.json", report.dump(2) + "\n");

  std::string table = fmt::format("{}: {} levels built in {:.3f} s (ratio {:g}, coarse vertices {}-{}, seed {}, {} kept)\n",
                                  s.source, h.num_levels(), build_seconds, params.ratio, params.min_coarse_vertices,
                                  params.max_coarse_vertices, params.seed, params.keep.size());
  table += fmt::format("{:>6} {:>9} {:>10} {:>15} {:>7}\n", "level", "vertices", "triangles", "boundary loops", "colors");
  for (Index l = 0; l < h.num_levels(); ++l)
    table += fmt::format("{:>6} {:>9} {:>10} {:>15} {:>7}\n", l, rows[l].vertices, rows[l].triangles,
                         rows[l].boundary_loops, rows[l].colors);
  table += fmt::format("wrote {}: level0.obj..level{}.obj, level*_material.obj, levels.png, hierarchy.json\n",
                       s.dir.string(), h.num_levels() - 1);
  std::fputs(table.c_str(), stdout);
  std::fflush(stdout);
}

/// A shell's levels are the control meshes of its Catmull-Clark hierarchy (Kopaničáková 2019 §5.2), as many as the
/// scene's shells[].level: nothing is coarsened here, so --ratio, --min-coarse, --max-coarse and --seed do not
/// apply. Points per level come from the body's hierarchy as a solver sees it (finest first), faces from its
/// control meshes.
void process_shell(const Subject& s, bodies::ShellBody& body) {
  const hierarchy::Hierarchy h = body.solver_hierarchy(/*rediscretized=*/false);
  const Index n = static_cast<Index>(h.num_levels());
  std::vector<const mesh::QuadMesh*> meshes;  // finest first, as h
  std::vector<ShellLevelRow> rows;
  for (Index l = 0; l < n; ++l) {
    const mesh::QuadMesh& m = body.hierarchy().mesh(static_cast<int>(n - 1 - l));
    if (m.num_vertices() != h.levels[static_cast<size_t>(l)].num_points)
      throw_error("{}: level {} has {} control points, its solver level {}", s.source, l, m.num_vertices(),
                  h.levels[static_cast<size_t>(l)].num_points);
    Index ghost_faces = 0;
    for (Index f = 0; f < m.num_faces(); ++f) ghost_faces += m.is_ghost_face(f) ? 1 : 0;
    meshes.push_back(&m);
    rows.push_back({h.levels[static_cast<size_t>(l)].num_points, m.num_vertices() - m.num_real_vertices(),
                    m.num_faces(), ghost_faces});
  }

  fs::create_directories(s.dir);
  Json levels = Json::array();
  for (Index l = 0; l < n; ++l) {
    const ShellLevelRow& r = rows[static_cast<size_t>(l)];
    levels.push_back({{"level", l}, {"subdivision_level", n - l}, {"control_points", r.control_points},
                      {"ghost_points", r.ghost_points}, {"faces", r.faces}, {"ghost_faces", r.ghost_faces},
                      {"dofs", 3 * r.control_points}});
  }
  remove_stale_levels(s.dir, 0);  // a cloth of this name may have left its level OBJs here
  draw_shell_levels(meshes, g_hier.png_size).write_png(s.dir / "levels.png");
  const Json report = {{"input", g_hier.input},
                       {"shell", s.name},
                       {"kind", body.kind()},
                       {"levels_of", "the Catmull-Clark control meshes, finest first; subdivision_level is the "
                                     "paper's numbering (1: the coarsest)"},
                       {"levels", levels},
                       {"png", "levels.png"}};
  write_file_atomic(s.dir / "hierarchy.json", report.dump(2) + "\n");

  std::string table = fmt::format("{}: {} subdivision levels ({}, shells[].level {})\n", s.source, n, body.size_text(),
                                  body.spec().level);
  table += fmt::format("{:>6} {:>11} {:>15} {:>13} {:>6} {:>12}\n", "level", "subdivision", "control points",
                       "ghost points", "faces", "ghost faces");
  for (Index l = 0; l < n; ++l) {
    const ShellLevelRow& r = rows[static_cast<size_t>(l)];
    table += fmt::format("{:>6} {:>11} {:>15} {:>13} {:>6} {:>12}\n", l, n - l, r.control_points, r.ghost_points,
                         r.faces, r.ghost_faces);
  }
  table += fmt::format("wrote {}: levels.png, hierarchy.json\n", s.dir.string());
  std::fputs(table.c_str(), stdout);
  std::fflush(stdout);
}

void process(Subject& s) {
  if (auto* cloth = dynamic_cast<bodies::ClothBody*>(s.body.get())) return process_cloth(s, *cloth);
  if (auto* shell = dynamic_cast<bodies::ShellBody*>(s.body.get())) return process_shell(s, *shell);
  throw_error("{}: a {} has no hierarchy to show", s.source, s.body->kind());
}

}  // namespace

void add_hierarchy_command(CLI::App& app) {
  const hierarchy::HierarchyParams defaults;
  auto* cmd = app.add_subcommand("hierarchy", "Build and show the multilevel hierarchy of a mesh or of a scene's cloths and shells");
  cmd->add_option("input", g_hier.input, "Mesh (.obj) or scene (.json)")->required();
  cmd->add_option("--out,-o", g_hier.out, "Output folder (created if missing)")->required();
  g_hier.cloth_option = cmd->add_option("--cloth", g_hier.cloth, "Scene input: only this cloth (default: every cloth and shell)");
  g_hier.body_option = cmd->add_option("--body", g_hier.body, "Scene input: only this cloth or shell, by name")->excludes(g_hier.cloth_option);
  g_hier.material_scale_option =
      cmd->add_option("--material-scale", g_hier.material_scale, "OBJ input: metres per UV unit (default 1)");
  cmd->add_option("--ratio", g_hier.params.ratio, "Target vertex-count reduction per level")->default_val(defaults.ratio);
  cmd->add_option("--min-coarse", g_hier.params.min_coarse_vertices, "A level is never coarsened below about this many vertices")
      ->default_val(defaults.min_coarse_vertices);
  cmd->add_option("--max-coarse", g_hier.params.max_coarse_vertices, "Coarsening stops at a level with at most this many vertices")
      ->default_val(defaults.max_coarse_vertices);
  cmd->add_option("--seed", g_hier.seed, "Seed of the interior sampling order")->default_val(defaults.seed);
  cmd->add_option("--png-size", g_hier.png_size, "Width of each level's panel in levels.png, pixels")->default_val(512);
}

int run_hierarchy_command() {
  check_options();
  std::vector<Subject> subjects = load_subjects();
  for (Subject& s : subjects) process(s);
  return 0;
}

}  // namespace mgcloth::cli
