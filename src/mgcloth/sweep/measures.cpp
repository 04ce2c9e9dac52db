#include <mgcloth/sim/simulator.hpp>
#include <mgcloth/sweep/measures.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace mgcloth::sweep {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const std::vector<std::string> kTypes{"probe", "energy", "kinetic_energy", "drape_coefficient", "bending_length"};

bodies::ClothBody& find_cloth(const Measure& m, const sim::Simulator& sim) {
  for (bodies::ClothBody* c : sim.cloths())
    if (c->name() == m.cloth) return *c;
  std::vector<std::string> names;
  for (bodies::ClothBody* c : sim.cloths()) names.push_back(fmt::format("\"{}\"", c->name()));
  throw InputError(fmt::format("measure \"{}\": the scene has no cloth \"{}\" (cloths: {})", m.name, m.cloth,
                               names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", "))));
}

std::vector<bodies::ClothBody*> cloths_of(const Measure& m, const sim::Simulator& sim) {
  if (!m.cloth.empty()) return {&find_cloth(m, sim)};
  return sim.cloths();
}

Vec3 vertex(const VecX& x, Index i) { return x.segment<3>(3 * i); }

/// Mean world position of the vertices whose material coordinate along `axis` is within `tol` of `at`.
Vec3 mean_at(const bodies::ClothBody& c, int axis, double at, double tol, Index& count) {
  Vec3 sum = Vec3::Zero();
  count = 0;
  for (Index i = 0; i < c.mesh().num_vertices(); ++i)
    if (std::abs(c.mesh().u(axis, i) - at) <= tol) {
      sum += vertex(c.x(), i);
      ++count;
    }
  return count > 0 ? Vec3(sum / static_cast<double>(count)) : Vec3::Constant(kNaN);
}

}  // namespace

std::vector<std::string> Measure::columns() const {
  if (type == "probe") return {name + "_x", name + "_y", name + "_z"};
  return {name};
}

Measure parse_measure(JsonReader& r) {
  Measure m;
  m.name = r.name("name", "");
  if (m.name.empty()) r.fail("name", "missing required field");
  m.type = r.choice("type", "", kTypes);
  if (m.type.empty()) r.fail("type", fmt::format("missing required field (one of {})", fmt::join(kTypes, ", ")));
  const bool needs_cloth = m.type != "energy" && m.type != "kinetic_energy";
  m.cloth = r.has("cloth") || needs_cloth ? r.name("cloth", "") : "";
  if (needs_cloth && m.cloth.empty()) r.fail("cloth", "missing required field");
  if (m.type == "probe") {
    if (r.has("vertex") == r.has("uv")) r.fail("vertex", "give exactly one of \"vertex\" (an index) and \"uv\"");
    if (r.has("vertex")) m.vertex = r.integer("vertex", 0, 0);
    if (r.has("uv")) m.uv = r.vec2("uv", Vec2::Zero());
  } else if (m.type == "drape_coefficient") {
    m.support_radius = r.required_number("support_radius", 0.0);
    if (!(m.support_radius > 0.0)) r.fail("support_radius", "must be > 0");
    m.raster = r.integer("raster", m.raster, 64, 16384);
  } else if (m.type == "bending_length") {
    m.clamp = r.required_number("clamp");
    m.axis = r.choice("axis", "u", {"u", "v"}) == "u" ? 0 : 1;
  }
  r.finish();
  return m;
}

Json to_json(const Measure& m) {
  Json j{{"name", m.name}, {"type", m.type}};
  if (!m.cloth.empty()) j["cloth"] = m.cloth;
  if (m.type == "probe") {
    if (m.vertex >= 0) j["vertex"] = m.vertex;
    else j["uv"] = vec_json(m.uv);
  } else if (m.type == "drape_coefficient") {
    j["support_radius"] = m.support_radius;
    j["raster"] = m.raster;
  } else if (m.type == "bending_length") {
    j["clamp"] = m.clamp;
    j["axis"] = m.axis == 0 ? "u" : "v";
  }
  return j;
}

double shadow_area(const Mat3X& x, const std::vector<Tri>& tris, const Vec3& down, int raster) {
  if (tris.empty() || raster < 1) return 0.0;
  const Vec3 n = down.normalized();
  const Vec3 e1 = n.unitOrthogonal();
  const Vec3 e2 = n.cross(e1);
  Mat2X p(2, x.cols());
  for (Index i = 0; i < x.cols(); ++i) p.col(i) = Vec2(e1.dot(x.col(i)), e2.dot(x.col(i)));
  const Vec2 lo = p.rowwise().minCoeff(), hi = p.rowwise().maxCoeff();
  const double cell = std::max(hi.x() - lo.x(), hi.y() - lo.y()) / raster;
  if (!(cell > 0.0)) return 0.0;
  const int nx = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / cell)));
  const int ny = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / cell)));
  std::vector<char> covered(static_cast<size_t>(nx) * ny, 0);
  for (const Tri& t : tris) {
    const Vec2 a = p.col(t[0]), b = p.col(t[1]), c = p.col(t[2]);
    const double area2 = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (area2 == 0.0) continue;  // seen edge-on: it casts no area
    const Vec2 tlo = a.cwiseMin(b).cwiseMin(c), thi = a.cwiseMax(b).cwiseMax(c);
    const int i0 = std::max(0, static_cast<int>(std::floor((tlo.x() - lo.x()) / cell - 0.5)));
    const int i1 = std::min(nx - 1, static_cast<int>(std::ceil((thi.x() - lo.x()) / cell - 0.5)));
    const int j0 = std::max(0, static_cast<int>(std::floor((tlo.y() - lo.y()) / cell - 0.5)));
    const int j1 = std::min(ny - 1, static_cast<int>(std::ceil((thi.y() - lo.y()) / cell - 0.5)));
    const auto edge = [](const Vec2& p0, const Vec2& p1, const Vec2& q) {
      return (p1 - p0).x() * (q - p0).y() - (p1 - p0).y() * (q - p0).x();
    };
    const double s = area2 > 0.0 ? 1.0 : -1.0;
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const Vec2 q = lo + cell * Vec2(i + 0.5, j + 0.5);
        if (s * edge(a, b, q) >= 0.0 && s * edge(b, c, q) >= 0.0 && s * edge(c, a, q) >= 0.0)
          covered[static_cast<size_t>(j) * nx + i] = 1;
      }
  }
  const auto cells = std::count(covered.begin(), covered.end(), char{1});
  return static_cast<double>(cells) * cell * cell;
}

double drape_coefficient(double shadow, double flat_area, double support_radius) {
  const double support = kPi * support_radius * support_radius;
  return (shadow - support) / (flat_area - support);
}

double peirce_bending_length(double length, double theta) {
  if (!(theta > 0.0 && theta < 0.5 * kPi)) return kNaN;
  // Peirce 1930, "The handle of cloth as a measurable quantity", eq. for the cantilever: c³ = l³ cos(θ/2) / (8 tan θ).
  return length * std::cbrt(std::cos(0.5 * theta) / (8.0 * std::tan(theta)));
}

std::vector<double> evaluate(const Measure& m, const sim::Simulator& sim) {
  const Vec3 down = sim.scene().gravity.squaredNorm() > 0.0 ? Vec3(sim.scene().gravity.normalized()) : Vec3(0, 0, -1);
  if (m.type == "probe") {
    const bodies::ClothBody& c = find_cloth(m, sim);
    Index v = m.vertex;
    if (v < 0) {
      (c.mesh().u.colwise() - m.uv).colwise().squaredNorm().minCoeff(&v);
    } else if (v >= c.mesh().num_vertices()) {
      throw InputError(fmt::format("measure \"{}\": vertex {} out of range (cloth \"{}\" has {} vertices)", m.name, v,
                                   c.name(), c.mesh().num_vertices()));
    }
    const Vec3 p = vertex(c.x(), v);
    return {p.x(), p.y(), p.z()};
  }
  if (m.type == "kinetic_energy") {
    double e = 0.0;
    for (const bodies::ClothBody* c : cloths_of(m, sim))
      for (Index i = 0; i < c->mesh().num_vertices(); ++i) e += 0.5 * c->mass()[i] * vertex(c->v(), i).squaredNorm();
    return {e};
  }
  if (m.type == "energy") {
    if (sim.step_count() == 0) return {kNaN};  // no step has set up the objectives yet
    double e = 0.0;
    for (bodies::ClothBody* c : cloths_of(m, sim))
      for (const auto& [name, value] : c->objective().term_values(c->x()))
        if (name != "inertia" && name != "cloth_friction") e += value;  // the step's, not the state's
    return {e};
  }
  const bodies::ClothBody& c = find_cloth(m, sim);
  const mesh::TriMesh& mesh = c.mesh();
  const double scale = c.material_scale();
  if (m.type == "drape_coefficient") {
    Mat3X x(3, mesh.num_vertices());
    for (Index i = 0; i < mesh.num_vertices(); ++i) x.col(i) = vertex(c.x(), i);
    const double flat = mesh.total_material_area() * scale * scale;
    return {drape_coefficient(shadow_area(x, mesh.tris, down, m.raster), flat, m.support_radius)};
  }
  // bending_length: the chord from the clamp's edge to the free end, whose material coordinate is the largest.
  const double tol = 0.5 * mesh::mean_material_edge_length(mesh);
  const double tip_at = mesh.u.row(m.axis).maxCoeff();
  Index at_clamp = 0, at_tip = 0;
  const Vec3 base = mean_at(c, m.axis, m.clamp, tol, at_clamp);
  const Vec3 tip = mean_at(c, m.axis, tip_at, tol, at_tip);
  if (at_clamp == 0)
    throw InputError(fmt::format("measure \"{}\": no vertex of cloth \"{}\" lies at clamp {} (its {} coordinates run "
                                 "{} to {})", m.name, c.name(), m.clamp, m.axis == 0 ? "u" : "v",
                                 mesh.u.row(m.axis).minCoeff(), tip_at));
  const Vec3 chord = tip - base;
  const double drop = chord.dot(down);
  const double across = (chord - drop * down).norm();
  return {peirce_bending_length((tip_at - m.clamp) * scale, std::atan2(drop, across))};
}

}  // namespace mgcloth::sweep
