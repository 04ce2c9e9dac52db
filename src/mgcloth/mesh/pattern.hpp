#pragma once
#include <mgcloth/core/json.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

/// Sewing patterns: garments as flat panels with curved outlines, placed in 3D and sewn along stitched edge
/// pairs (in the spirit of GarmentCode's JSON patterns), and their triangulation into one stitched TriMesh.
///
/// # Pattern file (JSON, metres, degrees)
///
/// ```json
/// {
///   "panels": {
///     "front": {
///       "vertices": [[-0.36, 0], [0.36, 0], [0.215, 0.52], [-0.215, 0.52]],
///       "edges": [
///         {},
///         {"curve": {"type": "cubic", "control": [[0.30, 0.25], [0.27, 0.50]]}},
///         {"curve": {"type": "quadratic", "control": [0, 0.535]}},
///         {"curve": {"type": "circle", "radius": 0.8, "large": false, "right": true}}
///       ],
///       "placement": {"translation": [0.25, 0, 0.48], "rotation_deg": [90, 0, 90]},
///       "wrap": {"radius": 0.25, "axis_x": 0}
///     },
///     "back": { ... }
///   },
///   "stitches": [
///     [{"panel": "front", "edge": 1}, {"panel": "back", "edge": 3}],
///     {"edges": [{"panel": "front", "edge": 3}, {"panel": "back", "edge": 1}], "same_direction": false}
///   ]
/// }
/// ```
///
/// Top level: "panels" (required object, at least one panel) and "stitches" (optional array). Every object is read
/// strictly: an unknown key, a wrong type, a non-finite number or a value out of range is an InputError naming the
/// file and the JSON path ("skirt.json: panels.front.edges[2].curve.radius: must be >= 1e-07, got 0"); an explicit
/// null counts as absent.
///
/// ## Panels
/// "panels" maps each panel's name to its description. A name is 1 to 64 bytes without control characters or any
/// of , " / \ (names go into logs and CSV columns). JSON objects are unordered; panels are numbered in the order of
/// their names (byte-wise), which is the order of SewingPattern::panels and of the mesh's vertices.
/// - "vertices" (required): the outline's corners [x, y] in the panel's own 2D plane, metres, at least 3, listed
///   COUNTER-CLOCKWISE. The panel's 2D coordinates become the material (rest) coordinates u of its vertices; each
///   panel is its own chart, so panels may overlap in 2D. A clockwise outline is an error (it is not silently
///   reversed, since that would renumber the edges the stitches refer to); so is a self-intersecting or
///   self-touching one (checked on the curves, not only on the corners). Holes are not supported.
/// - "edges" (optional): one object per outline edge; edge i runs from vertex i to vertex i+1 (the last from the
///   last vertex back to vertex 0). When given, it must have exactly as many entries as "vertices". An entry is
///   {} for a straight edge or {"curve": {...}}; a missing "edges" makes every edge straight. Curve types:
///   - "quadratic": "control": [x, y], a quadratic Bezier from vertex i through the pull of the control point to
///     vertex i+1;
///   - "cubic": "control": [[x1, y1], [x2, y2]], a cubic Bezier, the first control point next to vertex i;
///   - "circle": "radius": r > 0 and the SVG arc flags "large" (default false: the shorter of the two arcs, at most
///     a half circle; true: the longer one) and "right" (default false: the arc bulges to the LEFT of the
///     direction from vertex i to vertex i+1, which for a counter-clockwise outline is into the panel, a concave
///     edge; true: it bulges to the right, outwards, a convex edge). r must be at least half the chord (a radius
///     short of it by at most 1e-9 relative is taken as exactly half: a half circle).
///   Control points are absolute coordinates in the panel's 2D plane (not relative to the edge as in GarmentCode).
/// - "placement" (optional): where the panel starts in 3D. The panel's point (x, y) is first taken as (x, y, 0)
///   (or wrapped, below), then rotated and translated: p -> R p + t, with "translation" t (default [0, 0, 0]) and
///   "rotation_deg" [rx, ry, rz] (default [0, 0, 0]), R = Rz(rz) Ry(ry) Rx(rx), the convention of the scene files'
///   transforms. The panel's front side is its local +z (its outline is counter-clockwise seen from there), so
///   for a panel in front of a body facing +x (z up), "rotation_deg": [90, 0, 90] maps local x to world +y, local
///   y to world +z and the front side to +x; [90, 0, -90] faces -x (a back panel).
/// - "wrap" (optional): bends the panel, before placement, around a cylinder parallel to the panel's local y
///   axis: "radius" r > 0 (required) and "axis_x" x0 (default 0). The point (x, y) goes to
///   (x0 + r sin((x - x0)/r), y, r cos((x - x0)/r) - r): the line x = x0 stays where it was, the rest curves back
///   to local -z, around the axis at (x0, *, -r), the front side outwards. A cylinder is developable, so wrapping
///   keeps lengths measured along the surface (the panel starts unstretched; a straight 3D chord between two
///   mesh vertices is shorter than its 2D length by a factor sin(a/2r)/(a/2r) for a horizontal distance a). The
///   panel must fit around the cylinder: every |x - x0| <= pi r.
///
/// ## Stitches
/// "stitches" lists the seams, each sewing one edge to another: either the pair
/// [{"panel": name, "edge": i}, {"panel": name, "edge": j}] or the object {"edges": [end, end],
/// "same_direction": false}. "edge" is the outline edge index (0 .. number of vertices - 1). The two edges may be
/// on the same panel (a dart, a tube from one panel) but must differ; no edge may be in two stitches.
/// Direction: by default the edges run OPPOSITE ways: the start of the first edge (its vertex i) is sewn to the
/// end of the second (its vertex j+1). That is the usual case: two panels laid face to face, or sewn side by side
/// with both fronts outwards, traverse their shared seam in opposite directions in their counter-clockwise
/// outlines. "same_direction": true sews start to start and end to end.
/// Stitched edges should have the same length: the pattern's 2D arc lengths differing by more than 1% of the
/// longer one is logged as a warning (ease), by more than 10% it is an InputError naming both edges.
///
/// # Triangulation (triangulate_pattern)
/// - Each edge is sampled by arc length into n = max(1, round(L / resolution)) equal pieces; the two edges of a
///   stitch both get the larger of their two counts, so sample k of one is sewn to sample k (same direction) or
///   n - k (opposite) of the other. Sample points lie on the curve; a curved edge is thus replaced by its chords.
/// - Each panel is triangulated by CGAL's constrained Delaunay triangulation with its sampled outline as
///   constraints, then refined by Delaunay_mesher_no_edge_refinement_2 with Delaunay_mesh_size_criteria_2: shape
///   bound 0.125 (sin^2 of the smallest angle, 20.7 degrees, the bound for which refinement provably terminates,
///   as for make_rectangle) and longest triangle edge 1.4 x resolution (so edges are about `resolution`
///   on average). This mesher never inserts points on constrained edges (a point that would encroach on the
///   outline is not inserted), so the outline keeps exactly the sampled vertices and stitched edges keep equal
///   counts; the price is that a triangle next to the outline may stay below 20.7 degrees where the outline is
///   sharply curved or has a sharp corner.
/// - The TriMesh: u = the panel's 2D coordinates, x = its placed (and wrapped) 3D position, triangles counter-
///   clockwise in u. Vertices are numbered panel by panel (panels in name order), within a panel the outline
///   samples first (from vertex 0, counter-clockwise), then the interior. source_vertex: vertices sewn together
///   (transitively: a corner that ends two stitched edges joins both seams) share the smallest index among them,
///   every other vertex has its own index, so Topology::stitch_groups (find_stitch_groups) are the seam points.
///
/// Errors (InputError; messages "<file>: panel "<name>" edge <i>: ..." or "<file>: stitches[<k>]: ..."): fewer
/// than 3 vertices, a zero-length edge, a curve whose circle radius is shorter than half the chord, a clockwise,
/// zero-area, self-intersecting or self-touching outline (on the exact curves, and again on the sampled outline at
/// the requested resolution, which can cut across a deep curve: then use a finer resolution), a panel too wide
/// for its wrap cylinder, a stitch naming an unknown panel or an edge out of range, an edge stitched to itself
/// or twice, stitched lengths differing by more than 10%, a resolution that is not finite and positive, below
/// kMinMaterialEdge, or so fine that the mesh would exceed kMaxPatternVertices.
namespace mgcloth::mesh {

/// The largest vertex count triangulate_pattern makes (estimated from the panel areas before meshing).
inline constexpr Index kMaxPatternVertices = 5'000'000;

struct PatternCurve {
  enum class Type { straight, quadratic, cubic, circle };
  Type type = Type::straight;
  std::vector<Vec2> control;  ///< quadratic: 1 point; cubic: 2; otherwise empty
  double radius = 0.0;        ///< circle
  bool large = false;         ///< circle: the longer arc
  bool right = false;         ///< circle: bulges to the right of the edge's direction (outwards for a CCW outline)
};

struct PatternWrap {
  double radius = 1.0;
  double axis_x = 0.0;
};

struct PatternPanel {
  std::string name;
  std::vector<Vec2> vertices;        ///< counter-clockwise outline
  std::vector<PatternCurve> edges;   ///< one per outline edge (edge i: vertex i -> i+1), or empty (all straight)
  Vec3 translation = Vec3::Zero();
  Vec3 rotation_deg = Vec3::Zero();  ///< R = Rz Ry Rx
  std::optional<PatternWrap> wrap;
};

struct StitchEnd {
  std::string panel;
  Index edge = 0;
};

struct PatternStitch {
  StitchEnd a, b;
  bool same_direction = false;  ///< default: a's start is sewn to b's end
};

struct SewingPattern {
  std::string source;  ///< file name or label, for messages
  std::vector<PatternPanel> panels;
  std::vector<PatternStitch> stitches;
};

/// Reads and checks (check_pattern) a pattern file; errors name the file and the JSON path or panel/edge.
SewingPattern read_pattern(const std::filesystem::path& path);
/// The same from parsed JSON; `label` stands for the file in messages.
SewingPattern parse_pattern(const Json& json, const std::string& label);
/// Every check that does not depend on the resolution (see the list above); read_pattern and parse_pattern call
/// it, triangulate_pattern calls it again (a pattern may also be built in code) with `warn` false, so the
/// length warnings (1% to 10%) are logged once, when reading.
void check_pattern(const SewingPattern& pattern, bool warn = true);

/// The 2D arc length of a panel's edge (as sampled for the length checks: Bezier curves to ~1e-7 relative).
double pattern_edge_length(const PatternPanel& panel, Index edge);

struct PatternMesh {
  TriMesh mesh;
  std::vector<Index> panel_of_triangle;
  std::vector<std::string> panel_names;
  /// Panel p's vertices are [panel_vertex_offset[p], panel_vertex_offset[p + 1]).
  std::vector<Index> panel_vertex_offset;
  /// edge_vertices[p][e]: the vertices along panel p's edge e, from its vertex e to vertex e+1 (both included).
  std::vector<std::vector<std::vector<Index>>> edge_vertices;
  /// For each stitch (in pattern order): the sewn vertex pairs (vertex of end a, vertex of end b), from a's start.
  std::vector<std::vector<std::pair<Index, Index>>> stitch_pairs;
};

/// Triangulates every panel at about `resolution` metres (see the header comment) and sews the stitches.
PatternMesh triangulate_pattern(const SewingPattern& pattern, double resolution);

}  // namespace mgcloth::mesh
