#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/mesh/cdt.hpp>
#include <mgcloth/mesh/pattern.hpp>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_mesh_face_base_2.h>
#include <CGAL/Delaunay_mesh_size_criteria_2.h>
#include <CGAL/Delaunay_mesh_vertex_base_2.h>
#include <CGAL/Delaunay_mesher_no_edge_refinement_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>

namespace mgcloth::mesh {

namespace {

/// CGAL's shape criterion B = sin^2 of the smallest angle allowed: 0.125 is 20.7 degrees, the bound for which
/// Delaunay refinement provably terminates (as in generators.cpp).
constexpr double kShapeBound = 0.125;
/// Longest triangle edge allowed by the size criterion, in resolutions: refinement to a bound S leaves edges of
/// about S / kSizeFactor on average, so this makes the mean edge about the resolution.
constexpr double kSizeFactor = 1.4;
/// Segments per curved edge for the resolution-independent checks (outline shape, lengths use a finer table).
constexpr int kCheckSegments = 64;
/// Arc-length table of a Bezier edge: uniform parameter steps.
constexpr int kTableSegments = 1024;

std::string quoted(const std::string& s) { return Json(s).dump(); }

/// One outline edge as a parametric curve, t in [0, 1]; arcs are parametrized by angle, i.e. by arc length.
class EdgePath {
 public:
  EdgePath(const Vec2& p0, const Vec2& p1, const PatternCurve& c) : m_p0(p0), m_p1(p1), m_curve(c) {
    if (c.type == PatternCurve::Type::circle) {
      const double chord = (p1 - p0).norm(), d = 0.5 * chord;
      const double r = std::max(c.radius, d);
      const Vec2 dir = (p1 - p0) / chord, left(-dir.y(), dir.x());
      const Vec2 bulge = c.right ? Vec2(-left) : left;
      const double h = std::sqrt(std::max(0.0, r * r - d * d));
      m_center = 0.5 * (p0 + p1) + (c.large ? h : -h) * bulge;
      m_radius = r;
      const double small = 2.0 * std::asin(std::min(1.0, d / r));
      m_sweep = (c.large ? 2.0 * std::numbers::pi - small : small) * (c.right ? 1.0 : -1.0);
      m_start = std::atan2(p0.y() - m_center.y(), p0.x() - m_center.x());
    }
  }

  Vec2 at(double t) const {
    if (t <= 0.0) return m_p0;
    if (t >= 1.0) return m_p1;
    const double s = 1.0 - t;
    switch (m_curve.type) {
      case PatternCurve::Type::straight: return s * m_p0 + t * m_p1;
      case PatternCurve::Type::quadratic: return s * s * m_p0 + 2.0 * s * t * m_curve.control[0] + t * t * m_p1;
      case PatternCurve::Type::cubic:
        return s * s * s * m_p0 + 3.0 * s * s * t * m_curve.control[0] + 3.0 * s * t * t * m_curve.control[1] +
               t * t * t * m_p1;
      case PatternCurve::Type::circle: {
        const double a = m_start + t * m_sweep;
        return m_center + m_radius * Vec2(std::cos(a), std::sin(a));
      }
    }
    return m_p0;
  }

  bool is_bezier() const {
    return m_curve.type == PatternCurve::Type::quadratic || m_curve.type == PatternCurve::Type::cubic;
  }
  bool is_straight() const { return m_curve.type == PatternCurve::Type::straight; }

  double length() const {
    if (is_straight()) return (m_p1 - m_p0).norm();
    if (!is_bezier()) return m_radius * std::abs(m_sweep);
    return table().back();
  }

  /// n + 1 points at equal arc-length steps, the first m_p0 and the last m_p1 exactly.
  std::vector<Vec2> sample(Index n) const {
    std::vector<Vec2> out(n + 1);
    if (!is_bezier()) {
      for (Index k = 0; k <= n; ++k) out[k] = at(static_cast<double>(k) / n);
    } else {
      const std::vector<double> cum = table();
      const double total = cum.back();
      std::size_t j = 0;
      for (Index k = 0; k <= n; ++k) {
        const double s = total * k / n;
        while (j + 1 < cum.size() - 1 && cum[j + 1] < s) ++j;
        const double seg = cum[j + 1] - cum[j];
        const double f = seg > 0.0 ? std::clamp((s - cum[j]) / seg, 0.0, 1.0) : 0.0;
        out[k] = at((static_cast<double>(j) + f) / kTableSegments);
      }
    }
    out.front() = m_p0;
    out.back() = m_p1;
    return out;
  }

  /// m + 1 points at equal parameter steps (for shape checks).
  std::vector<Vec2> polyline(int m) const {
    if (is_straight()) return {m_p0, m_p1};
    std::vector<Vec2> out(m + 1);
    for (int k = 0; k <= m; ++k) out[k] = at(static_cast<double>(k) / m);
    out.front() = m_p0;
    out.back() = m_p1;
    return out;
  }

 private:
  /// Cumulative chord length over kTableSegments uniform parameter steps (relative error ~1e-7 for smooth
  /// Beziers: the chord sum's error falls with the square of the step).
  std::vector<double> table() const {
    std::vector<double> cum(kTableSegments + 1, 0.0);
    Vec2 prev = m_p0;
    for (int k = 1; k <= kTableSegments; ++k) {
      const Vec2 p = at(static_cast<double>(k) / kTableSegments);
      cum[k] = cum[k - 1] + (p - prev).norm();
      prev = p;
    }
    return cum;
  }

  Vec2 m_p0, m_p1;
  PatternCurve m_curve;
  Vec2 m_center = Vec2::Zero();
  double m_radius = 0.0, m_sweep = 0.0, m_start = 0.0;
};

const PatternCurve& curve_of(const PatternPanel& panel, Index e) {
  static const PatternCurve straight;
  return panel.edges.empty() ? straight : panel.edges[e];
}

EdgePath edge_path(const PatternPanel& panel, Index e) {
  const Index n = static_cast<Index>(panel.vertices.size());
  return EdgePath(panel.vertices[e], panel.vertices[(e + 1) % n], curve_of(panel, e));
}

double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

double signed_area(const std::vector<Vec2>& loop) {
  double a = 0.0;
  for (std::size_t i = 0; i < loop.size(); ++i) a += 0.5 * cross(loop[i], loop[(i + 1) % loop.size()]);
  return a;
}

/// Whether closed segments [a0, a1] and [b0, b1] have a point in common.
bool segments_meet(const Vec2& a0, const Vec2& a1, const Vec2& b0, const Vec2& b1) {
  const double d1 = cross(a1 - a0, b0 - a0), d2 = cross(a1 - a0, b1 - a0);
  const double d3 = cross(b1 - b0, a0 - b0), d4 = cross(b1 - b0, a1 - b0);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  auto on = [](const Vec2& p, const Vec2& q, const Vec2& r, double d) {  // r on segment pq, given collinear
    return d == 0.0 && std::min(p.x(), q.x()) <= r.x() && r.x() <= std::max(p.x(), q.x()) &&
           std::min(p.y(), q.y()) <= r.y() && r.y() <= std::max(p.y(), q.y());
  };
  return on(a0, a1, b0, d1) || on(a0, a1, b1, d2) || on(b0, b1, a0, d3) || on(b0, b1, a1, d4);
}

/// A closed polyline's first pair of segments that meet other than at their shared end (neighbours also when they
/// fold back onto each other); segment i runs from loop[i] to loop[i+1]. {-1, -1} when simple.
std::pair<Index, Index> self_intersection(const std::vector<Vec2>& loop) {
  const Index n = static_cast<Index>(loop.size());
  std::vector<Index> order(n);
  std::iota(order.begin(), order.end(), 0);
  auto lo = [&](Index i) { return std::min(loop[i].x(), loop[(i + 1) % n].x()); };
  auto hi = [&](Index i) { return std::max(loop[i].x(), loop[(i + 1) % n].x()); };
  std::sort(order.begin(), order.end(), [&](Index a, Index b) { return lo(a) < lo(b); });
  std::pair<Index, Index> found{-1, -1};
  for (std::size_t ia = 0; ia < order.size(); ++ia) {
    const Index i = order[ia];
    const Vec2 &a0 = loop[i], &a1 = loop[(i + 1) % n];
    for (std::size_t ib = ia + 1; ib < order.size() && lo(order[ib]) <= hi(i); ++ib) {
      const Index j = order[ib];
      const Vec2 &b0 = loop[j], &b1 = loop[(j + 1) % n];
      bool meet;
      if ((i + 1) % n == j || (j + 1) % n == i) {
        // Neighbours share a point; they are bad only when they run back over each other.
        const Vec2 shared = (i + 1) % n == j ? a1 : b1;
        const Vec2 pa = (i + 1) % n == j ? a0 : a1, pb = (i + 1) % n == j ? b1 : b0;
        meet = n <= 2 || (cross(pa - shared, pb - shared) == 0.0 && (pa - shared).dot(pb - shared) > 0.0);
      } else {
        meet = segments_meet(a0, a1, b0, b1);
      }
      if (meet) {
        const std::pair<Index, Index> p{std::min(i, j), std::max(i, j)};
        if (found.first < 0 || p < found) found = p;
      }
    }
  }
  return found;
}

void check_name(const std::string& source, const std::string& n) {
  const auto bad = [&](const std::string& why) {
    throw_input_error("{}: panel {}: the name {} (1 to 64 bytes; no control characters, no , \" / \\)", source,
                      quoted(n), why);
  };
  if (n.empty()) bad("is empty");
  if (n.size() > 64) bad(fmt::format("is {} bytes long", n.size()));
  for (const char c : n) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) bad(fmt::format("contains the control character 0x{:02x}", u));
    if (c == ',' || c == '"' || c == '/' || c == '\\') bad(fmt::format("contains '{}'", c));
  }
}

/// The outline of a panel as a closed polyline, each edge cut into the given number of pieces (by parameter
/// for the shape check, by arc length for meshing); edge e starts at index start[e].
struct Outline {
  std::vector<Vec2> points;
  std::vector<Index> start;
};

Outline check_outline(const PatternPanel& panel) {
  Outline o;
  for (Index e = 0; e < static_cast<Index>(panel.vertices.size()); ++e) {
    o.start.push_back(static_cast<Index>(o.points.size()));
    const std::vector<Vec2> pts = edge_path(panel, e).polyline(kCheckSegments);
    o.points.insert(o.points.end(), pts.begin(), pts.end() - 1);
  }
  return o;
}

Index edge_of_segment(const Outline& o, Index segment) {
  return static_cast<Index>(std::upper_bound(o.start.begin(), o.start.end(), segment) - o.start.begin()) - 1;
}

Mat3 rotation_matrix(const Vec3& degrees) {
  const Vec3 r = degrees * (std::numbers::pi / 180.0);
  return (Eigen::AngleAxisd(r.z(), Vec3::UnitZ()) * Eigen::AngleAxisd(r.y(), Vec3::UnitY()) *
          Eigen::AngleAxisd(r.x(), Vec3::UnitX()))
      .toRotationMatrix();
}

// ------------------------------------------------------------------------------------------------- parsing ---

StitchEnd parse_end(JsonReader r) {
  StitchEnd end;
  end.panel = r.required_string("panel");
  if (!r.has("edge")) r.fail("edge", "missing required field");
  end.edge = r.integer("edge", 0, 0);
  r.finish();
  return end;
}

PatternCurve parse_curve(JsonReader c) {
  PatternCurve curve;
  const std::string type = c.required_string("type");
  auto required_vec2 = [&](const std::string& key) {
    if (!c.has(key)) c.fail(key, "missing required field");
    return c.vec2(key, Vec2::Zero());
  };
  if (type == "quadratic") {
    curve.type = PatternCurve::Type::quadratic;
    curve.control = {required_vec2("control")};
  } else if (type == "cubic") {
    curve.type = PatternCurve::Type::cubic;
    if (!c.has("control")) c.fail("control", "missing required field");
    curve.control = c.vec2s("control");
    if (curve.control.size() != 2)
      c.fail("control", fmt::format("a cubic curve needs two control points [[x1, y1], [x2, y2]], got {}",
                                    curve.control.size()));
  } else if (type == "circle") {
    curve.type = PatternCurve::Type::circle;
    curve.radius = c.required_number("radius", kMinMaterialEdge);
    curve.large = c.boolean("large", false);
    curve.right = c.boolean("right", false);
  } else {
    c.fail("type", fmt::format("unknown curve type {} (expected one of: quadratic, cubic, circle)", quoted(type)));
  }
  c.finish();
  return curve;
}

PatternPanel parse_panel(const std::string& name, JsonReader r) {
  PatternPanel panel;
  panel.name = name;
  check_name(r.file(), name);
  if (!r.has("vertices")) r.fail("vertices", "missing required field");
  panel.vertices = r.vec2s("vertices");
  if (panel.vertices.size() < 3)
    r.fail("vertices", fmt::format("a panel's outline needs at least 3 vertices, got {}", panel.vertices.size()));
  if (r.has("edges")) {
    std::vector<JsonReader> edges = r.objects("edges");
    if (edges.size() != panel.vertices.size())
      r.fail("edges", fmt::format("expected one entry per outline edge ({}, as many as vertices), got {}",
                                  panel.vertices.size(), edges.size()));
    for (JsonReader& e : edges) {
      if (auto c = e.optional_object("curve")) panel.edges.push_back(parse_curve(*c));
      else panel.edges.emplace_back();
      e.finish();
    }
  }
  if (auto p = r.optional_object("placement")) {
    panel.translation = p->vec3("translation", Vec3::Zero());
    panel.rotation_deg = p->vec3("rotation_deg", Vec3::Zero());
    p->finish();
  }
  if (auto w = r.optional_object("wrap")) {
    PatternWrap wrap;
    wrap.radius = w->required_number("radius", kMinMaterialEdge);
    wrap.axis_x = w->number("axis_x", 0.0);
    w->finish();
    panel.wrap = wrap;
  }
  r.finish();
  return panel;
}

}  // namespace

double pattern_edge_length(const PatternPanel& panel, Index edge) { return edge_path(panel, edge).length(); }

SewingPattern parse_pattern(const Json& json, const std::string& label) {
  SewingPattern pattern;
  pattern.source = label;
  JsonReader top(json, label);
  const Json& panels = top.raw("panels");
  if (!panels.is_object())
    top.fail("panels", fmt::format("expected an object mapping panel names to panels, got {}", panels.type_name()));
  if (panels.empty()) top.fail("panels", "a pattern needs at least one panel");
  for (auto it = panels.begin(); it != panels.end(); ++it)  // nlohmann::json objects iterate in key order
    pattern.panels.push_back(parse_panel(it.key(), JsonReader(it.value(), label, "panels." + it.key())));
  if (top.has("stitches")) {
    const Json& stitches = top.raw("stitches");
    if (!stitches.is_array()) top.fail("stitches", fmt::format("expected an array, got {}", stitches.type_name()));
    for (std::size_t k = 0; k < stitches.size(); ++k) {
      const std::string path = fmt::format("stitches[{}]", k);
      const Json& s = stitches[k];
      PatternStitch stitch;
      const Json* ends = &s;
      std::string ends_path = path;
      std::optional<JsonReader> obj;
      if (s.is_object()) {
        obj.emplace(s, label, path);
        ends = &obj->raw("edges");
        ends_path = path + ".edges";
        stitch.same_direction = obj->boolean("same_direction", false);
        obj->finish();
      }
      if (!ends->is_array() || ends->size() != 2)
        throw_input_error("{}: {}: a stitch is a pair of edges [{{\"panel\": ..., \"edge\": i}}, {{...}}] or "
                          "{{\"edges\": [...], \"same_direction\": false}}, got {}",
                          label, ends_path, ends->dump());
      stitch.a = parse_end(JsonReader((*ends)[0], label, ends_path + "[0]"));
      stitch.b = parse_end(JsonReader((*ends)[1], label, ends_path + "[1]"));
      pattern.stitches.push_back(stitch);
    }
  }
  top.finish();
  check_pattern(pattern);
  return pattern;
}

SewingPattern read_pattern(const std::filesystem::path& path) {
  return parse_pattern(load_json(path.string()), path.string());
}

void check_pattern(const SewingPattern& pattern, bool warn) {
  const std::string& src = pattern.source;
  if (pattern.panels.empty()) throw_input_error("{}: a pattern needs at least one panel", src);
  std::map<std::string, Index> index;
  for (Index p = 0; p < static_cast<Index>(pattern.panels.size()); ++p) {
    const PatternPanel& panel = pattern.panels[p];
    check_name(src, panel.name);
    if (!index.emplace(panel.name, p).second) throw_input_error("{}: panel {} is defined twice", src, quoted(panel.name));
    const std::string where = fmt::format("{}: panel {}", src, quoted(panel.name));
    const Index n = static_cast<Index>(panel.vertices.size());
    if (n < 3) throw_input_error("{}: a panel's outline needs at least 3 vertices, got {}", where, n);
    if (!panel.edges.empty() && static_cast<Index>(panel.edges.size()) != n)
      throw_input_error("{}: {} edges for {} vertices (one per outline edge expected)", where, panel.edges.size(), n);
    for (Index i = 0; i < n; ++i)
      if (!panel.vertices[i].allFinite()) throw_input_error("{}: vertex {} is not finite", where, i);
    if (!panel.translation.allFinite() || !panel.rotation_deg.allFinite())
      throw_input_error("{}: placement is not finite", where);
    for (Index e = 0; e < n; ++e) {
      const Vec2 p0 = panel.vertices[e], p1 = panel.vertices[(e + 1) % n];
      const PatternCurve& c = curve_of(panel, e);
      const double chord = (p1 - p0).norm();
      if (!(chord >= kMinMaterialEdge))
        throw_input_error("{} edge {}: zero length (vertices {} and {} coincide)", where, e, e, (e + 1) % n);
      const std::size_t need = c.type == PatternCurve::Type::quadratic ? 1 : c.type == PatternCurve::Type::cubic ? 2 : 0;
      if (c.control.size() != need)
        throw_input_error("{} edge {}: the curve needs {} control point(s), got {}", where, e, need, c.control.size());
      for (const Vec2& q : c.control)
        if (!q.allFinite()) throw_input_error("{} edge {}: control point is not finite", where, e);
      if (c.type == PatternCurve::Type::circle) {
        if (!std::isfinite(c.radius) || !(c.radius > 0.0))
          throw_input_error("{} edge {}: circle radius must be positive and finite, got {}", where, e, c.radius);
        if (c.radius < 0.5 * chord * (1.0 - 1e-9))
          throw_input_error("{} edge {}: circle radius {} is shorter than half the chord ({}); no arc joins the two "
                            "vertices",
                            where, e, c.radius, 0.5 * chord);
      }
    }
    const Outline o = check_outline(panel);
    const auto [s0, s1] = self_intersection(o.points);
    if (s0 >= 0)
      throw_input_error("{}: the outline intersects itself: edge {} meets edge {}", where, edge_of_segment(o, s0),
                        edge_of_segment(o, s1));
    const double area = signed_area(o.points);
    if (!(area > 0.0))
      throw_input_error("{}: the outline is {} (signed area {} m^2); list its vertices counter-clockwise", where,
                        area < 0.0 ? "clockwise" : "degenerate", area);
    if (panel.wrap) {
      const PatternWrap& w = *panel.wrap;
      if (!std::isfinite(w.radius) || !(w.radius > 0.0) || !std::isfinite(w.axis_x))
        throw_input_error("{}: wrap needs a positive finite radius and a finite axis_x", where);
      double reach = 0.0;
      for (const Vec2& q : o.points) reach = std::max(reach, std::abs(q.x() - w.axis_x));
      if (reach > std::numbers::pi * w.radius)
        throw_input_error("{}: the panel reaches {} m from the wrap axis (x = {}), more than half the circumference "
                          "(pi x radius = {} m) of its wrap cylinder: it would overlap itself",
                          where, reach, w.axis_x, std::numbers::pi * w.radius);
    }
  }
  std::map<std::pair<Index, Index>, std::size_t> used;
  for (std::size_t k = 0; k < pattern.stitches.size(); ++k) {
    const PatternStitch& s = pattern.stitches[k];
    std::array<std::pair<Index, Index>, 2> ends;
    for (int side = 0; side < 2; ++side) {
      const StitchEnd& end = side == 0 ? s.a : s.b;
      const auto it = index.find(end.panel);
      if (it == index.end()) {
        std::vector<std::string> names;
        for (const auto& [name, p] : index) names.push_back(quoted(name));
        throw_input_error("{}: stitches[{}]: unknown panel {} (panels: {})", src, k, quoted(end.panel),
                          fmt::join(names, ", "));
      }
      const Index n = static_cast<Index>(pattern.panels[it->second].vertices.size());
      if (end.edge < 0 || end.edge >= n)
        throw_input_error("{}: stitches[{}]: panel {} edge {} is out of range (the panel has edges 0 to {})", src, k,
                          quoted(end.panel), end.edge, n - 1);
      ends[side] = {it->second, end.edge};
    }
    if (ends[0] == ends[1])
      throw_input_error("{}: stitches[{}]: panel {} edge {} is stitched to itself", src, k, quoted(s.a.panel),
                        s.a.edge);
    for (int side = 0; side < 2; ++side) {
      const auto [it, fresh] = used.emplace(ends[side], k);
      if (!fresh)
        throw_input_error("{}: stitches[{}]: panel {} edge {} is already stitched in stitches[{}]", src, k,
                          quoted(pattern.panels[ends[side].first].name), ends[side].second, it->second);
    }
    const double la = pattern_edge_length(pattern.panels[ends[0].first], ends[0].second);
    const double lb = pattern_edge_length(pattern.panels[ends[1].first], ends[1].second);
    const double diff = std::abs(la - lb) / std::max(la, lb);
    const std::string what = fmt::format("{}: stitches[{}]: panel {} edge {} is {:.4f} m long, panel {} edge {} is {:.4f} m",
                                         src, k, quoted(s.a.panel), s.a.edge, la, quoted(s.b.panel), s.b.edge, lb);
    if (diff > 0.1) throw_input_error("{}: they differ by {:.1f}%, more than the 10% allowed", what, 100.0 * diff);
    if (warn && diff > 0.01) logger().warn("{}: they differ by {:.1f}% (eased in by the seam)", what, 100.0 * diff);
  }
}

// ---------------------------------------------------------------------------------------------- meshing ---

namespace {

using cdt::Cdt;
using cdt::FaceBase;
using cdt::Kernel;
using cdt::VertexBase;
using Criteria = CGAL::Delaunay_mesh_size_criteria_2<Cdt>;
using Mesher = CGAL::Delaunay_mesher_no_edge_refinement_2<Cdt, Criteria>;

struct PanelMesh {
  std::vector<Vec2> u;  ///< outline samples first
  std::vector<Tri> tris;
};

/// CDT of the closed outline (its points numbered 0..n-1), refined without touching the outline.
PanelMesh mesh_panel(const std::string& where, const std::vector<Vec2>& outline, double resolution) {
  const Index n = static_cast<Index>(outline.size());
  Cdt cdt;
  std::vector<std::pair<Kernel::Point_2, Index>> points(n);
  for (Index i = 0; i < n; ++i) points[i] = {{outline[i].x(), outline[i].y()}, i};
  cdt.insert(points.begin(), points.end());
  std::vector<Cdt::Vertex_handle> handle(n);
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) handle[v->info()] = v;
  for (Index i = 0; i < n; ++i)
    if (handle[i] == Cdt::Vertex_handle() || handle[i]->info() != i)
      throw_input_error("{}: two outline samples coincide at ({}, {})", where, outline[i].x(), outline[i].y());
  for (Index i = 0; i < n; ++i) cdt.insert_constraint(handle[i], handle[(i + 1) % n]);
  if (static_cast<Index>(cdt.number_of_vertices()) != n)
    throw_input_error("{}: the sampled outline crosses itself (a constraint intersection added a vertex)", where);
  Mesher mesher(cdt, Criteria(kShapeBound, kSizeFactor * resolution));
  mesher.refine_mesh();  // no seeds: the domain is the inside of the outline

  PanelMesh m;
  m.u = outline;
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
    if (v->info() < 0 || v->info() >= n || handle[v->info()] != Cdt::Vertex_handle(v)) {  // inserted by the mesher
      v->info() = static_cast<Index>(m.u.size());
      m.u.emplace_back(v->point().x(), v->point().y());
    }
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    if (f->is_in_domain()) m.tris.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
  // Constrained edges stay edges of the triangulation, so the outline's vertex count is what was sampled; check.
  std::vector<char> used(m.u.size(), 0);
  for (const Tri& t : m.tris)
    for (Index v : t) used[v] = 1;
  if (std::find(used.begin(), used.end(), 0) != used.end())
    throw_error("{}: the triangulation left a vertex unused (outline {} samples, {} vertices)", where, n, m.u.size());
  return m;
}

Vec3 place(const PatternPanel& panel, const Mat3& rotation, const Vec2& u) {
  Vec3 p(u.x(), u.y(), 0.0);
  if (panel.wrap) {
    const double r = panel.wrap->radius, x0 = panel.wrap->axis_x, a = (u.x() - x0) / r;
    p = Vec3(x0 + r * std::sin(a), u.y(), r * std::cos(a) - r);
  }
  return rotation * p + panel.translation;
}

struct UnionFind {
  std::vector<Index> parent;
  explicit UnionFind(Index n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  Index find(Index i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  }
  void join(Index a, Index b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);  // the root is the smallest member
  }
};

}  // namespace

PatternMesh triangulate_pattern(const SewingPattern& pattern, double resolution) {
  const std::string& src = pattern.source;
  if (!std::isfinite(resolution) || !(resolution >= kMinMaterialEdge))
    throw_input_error("{}: resolution must be finite and at least {} m, got {}", src, kMinMaterialEdge, resolution);
  check_pattern(pattern, /*warn=*/false);
  const Index np = static_cast<Index>(pattern.panels.size());
  std::map<std::string, Index> index;
  for (Index p = 0; p < np; ++p) index[pattern.panels[p].name] = p;

  // Sample counts: round(L / h) per edge, the larger of the two on stitched edges.
  double estimate = 0.0;
  std::vector<std::vector<Index>> count(np);
  std::vector<std::vector<double>> length(np);
  for (Index p = 0; p < np; ++p) {
    const PatternPanel& panel = pattern.panels[p];
    const Index ne = static_cast<Index>(panel.vertices.size());
    for (Index e = 0; e < ne; ++e) {
      const double l = pattern_edge_length(panel, e);
      length[p].push_back(l);
      count[p].push_back(static_cast<Index>(std::max(1.0, std::min(std::round(l / resolution), 1e9))));
      estimate += l / resolution;
    }
    estimate += 2.0 / std::sqrt(3.0) * signed_area(check_outline(panel).points) / (resolution * resolution);
  }
  if (estimate > kMaxPatternVertices)
    throw_input_error("{}: resolution {} m would make about {:.0f} vertices, more than {}", src, resolution, estimate,
                      kMaxPatternVertices);
  for (const PatternStitch& s : pattern.stitches) {
    Index& ca = count[index[s.a.panel]][s.a.edge];
    Index& cb = count[index[s.b.panel]][s.b.edge];
    ca = cb = std::max(ca, cb);
  }

  return building([&] { return fmt::format("the pattern mesh of {} at resolution {} m", src, resolution); }, [&] {
    PatternMesh out;
    TriMesh& mesh = out.mesh;
    std::vector<PanelMesh> parts(np);
    std::vector<std::vector<Index>> edge_start(np);
    Index total = 0;
    for (Index p = 0; p < np; ++p) {
      const PatternPanel& panel = pattern.panels[p];
      const std::string where = fmt::format("{}: panel {}", src, quoted(panel.name));
      Outline o;
      for (Index e = 0; e < static_cast<Index>(panel.vertices.size()); ++e) {
        o.start.push_back(static_cast<Index>(o.points.size()));
        const std::vector<Vec2> pts = edge_path(panel, e).sample(count[p][e]);
        o.points.insert(o.points.end(), pts.begin(), pts.end() - 1);
      }
      const auto [s0, s1] = self_intersection(o.points);
      if (s0 >= 0)
        throw_input_error("{}: at resolution {} m the sampled outline intersects itself (edge {} meets edge {}); use "
                          "a finer resolution",
                          where, resolution, edge_of_segment(o, s0), edge_of_segment(o, s1));
      if (!(signed_area(o.points) > 0.0))
        throw_input_error("{}: at resolution {} m the sampled outline is not counter-clockwise; use a finer "
                          "resolution",
                          where, resolution);
      parts[p] = mesh_panel(where, o.points, resolution);
      edge_start[p] = o.start;
      out.panel_names.push_back(panel.name);
      out.panel_vertex_offset.push_back(total);
      total += static_cast<Index>(parts[p].u.size());
    }
    out.panel_vertex_offset.push_back(total);

    mesh.u.resize(2, total);
    mesh.x.resize(3, total);
    for (Index p = 0; p < np; ++p) {
      const PatternPanel& panel = pattern.panels[p];
      const Mat3 rotation = rotation_matrix(panel.rotation_deg);
      const Index off = out.panel_vertex_offset[p];
      for (std::size_t i = 0; i < parts[p].u.size(); ++i) {
        mesh.u.col(off + static_cast<Index>(i)) = parts[p].u[i];
        mesh.x.col(off + static_cast<Index>(i)) = place(panel, rotation, parts[p].u[i]);
      }
      for (const Tri& t : parts[p].tris) {
        mesh.tris.push_back({t[0] + off, t[1] + off, t[2] + off});
        out.panel_of_triangle.push_back(p);
      }
      const Index ne = static_cast<Index>(panel.vertices.size());
      const Index nb = edge_start[p].empty() ? 0 : edge_start[p].back() + count[p].back();
      out.edge_vertices.emplace_back(ne);
      for (Index e = 0; e < ne; ++e)
        for (Index k = 0; k <= count[p][e]; ++k)
          out.edge_vertices[p][e].push_back(off + (edge_start[p][e] + k) % nb);
    }

    UnionFind sewn(total);
    for (const PatternStitch& s : pattern.stitches) {
      const std::vector<Index>& a = out.edge_vertices[index[s.a.panel]][s.a.edge];
      const std::vector<Index>& b = out.edge_vertices[index[s.b.panel]][s.b.edge];
      const std::size_t n = a.size();  // == b.size()
      out.stitch_pairs.emplace_back();
      for (std::size_t k = 0; k < n; ++k) {
        const Index vb = b[s.same_direction ? k : n - 1 - k];
        out.stitch_pairs.back().push_back({a[k], vb});
        sewn.join(a[k], vb);
      }
    }
    mesh.source_vertex.resize(total);
    for (Index i = 0; i < total; ++i) mesh.source_vertex[i] = sewn.find(i);
    return out;
  });
}

}  // namespace mgcloth::mesh
