#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/hierarchy/reverse_subdivision.hpp>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>

namespace mgcloth::hierarchy {

namespace {

using EdgeKey = std::pair<Index, Index>;
EdgeKey undirected(Index a, Index b) { return a < b ? EdgeKey{a, b} : EdgeKey{b, a}; }

/// A weight and the sum of the magnitudes that were added into it: substituting rows cancels entries, and an entry
/// below rounding of its contributions is a zero, not a tiny weight.
struct Term {
  double w = 0.0;
  double magnitude = 0.0;
};
/// A row of Q under construction: fine point -> weight.
using Row = std::map<Index, Term>;

void add(Row& row, Index fine, double w) {
  Term& t = row[fine];
  t.w += w;
  t.magnitude += std::abs(w);
}

void add(Row& row, const Row& other, double s) {
  for (const auto& [i, o] : other) {
    Term& t = row[i];
    t.w += s * o.w;
    t.magnitude += std::abs(s) * o.magnitude;
  }
}

void drop_cancelled(Row& row) {
  std::erase_if(row, [](const auto& entry) {
    return std::abs(entry.second.w) <= 16.0 * std::numeric_limits<double>::epsilon() * entry.second.magnitude;
  });
}

struct CoarseTopology {
  std::map<EdgeKey, std::vector<Index>> edge_faces;
  std::vector<std::vector<Index>> neighbours, faces;

  bool interior(Index v) const {
    return std::all_of(neighbours[v].begin(), neighbours[v].end(),
                       [&](Index w) { return edge_faces.at(undirected(v, w)).size() == 2; });
  }
  std::vector<Index> boundary_neighbours(Index v) const {
    std::vector<Index> out;
    for (Index w : neighbours[v])
      if (edge_faces.at(undirected(v, w)).size() == 1) out.push_back(w);
    return out;
  }
};

CoarseTopology connect(const mesh::QuadMesh& m) {
  CoarseTopology t;
  t.neighbours.resize(static_cast<size_t>(m.num_vertices()));
  t.faces.resize(static_cast<size_t>(m.num_vertices()));
  for (Index f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 4; ++k) {
      const Index a = m.quads[f][k], b = m.quads[f][(k + 1) % 4];
      auto& fs = t.edge_faces[undirected(a, b)];
      if (fs.empty()) {
        t.neighbours[a].push_back(b);
        t.neighbours[b].push_back(a);
      }
      fs.push_back(f);
      t.faces[a].push_back(f);
    }
  return t;
}

/// The fine points subdivide() kept, found by how they were made; -1 where the point was dropped with the outer
/// ghost layer (§5.2.1).
struct FinePoints {
  std::vector<Index> of_vertex, of_face;
  std::map<EdgeKey, Index> of_edge;

  Index vertex(Index v) const { return of_vertex[v]; }
  Index face(Index f) const { return of_face[f]; }
  Index edge(Index a, Index b) const {
    const auto it = of_edge.find(undirected(a, b));
    return it == of_edge.end() ? -1 : it->second;
  }
};

FinePoints index_fine_points(const mesh::QuadMesh& coarse, const SubdivisionStep& step) {
  FinePoints p;
  p.of_vertex.assign(static_cast<size_t>(coarse.num_vertices()), -1);
  p.of_face.assign(static_cast<size_t>(coarse.num_faces()), -1);
  for (Index i = 0; i < static_cast<Index>(step.kind.size()); ++i) {
    const auto [a, b] = step.parent[i];
    if (step.kind[i] == 0) p.of_vertex.at(static_cast<size_t>(a)) = i;
    if (step.kind[i] == 1) p.of_edge[undirected(a, b)] = i;
    if (step.kind[i] == 2) p.of_face.at(static_cast<size_t>(a)) = i;
  }
  return p;
}

/// Eq. (5.19) with (5.21): v = c1 v' + c2 sum e' + c3 sum f' over the fine one-ring of an interior point of
/// valence n != 3; nothing when part of that ring was dropped.
std::optional<Row> interior_rule(Index v, const CoarseTopology& t, const FinePoints& fine) {
  const double n = static_cast<double>(t.neighbours[v].size());
  if (n == 3.0 || fine.vertex(v) < 0) return std::nullopt;
  Row row;
  add(row, fine.vertex(v), n / (n - 3.0));
  for (Index w : t.neighbours[v]) {
    const Index e = fine.edge(v, w);
    if (e < 0) return std::nullopt;
    add(row, e, -4.0 / (n * (n - 3.0)));
  }
  for (Index f : t.faces[v]) {
    if (fine.face(f) < 0) return std::nullopt;
    add(row, fine.face(f), 1.0 / (n * (n - 3.0)));
  }
  return row;
}

/// (A.2) with (A.1) substituted, v' = v / 2 + (e'_a + e'_b) / 4, solved for v.
std::optional<Row> boundary_rule(Index v, const std::vector<Index>& boundary_nbrs, const FinePoints& fine) {
  if (boundary_nbrs.size() != 2 || fine.vertex(v) < 0) return std::nullopt;
  const Index ea = fine.edge(v, boundary_nbrs[0]), eb = fine.edge(v, boundary_nbrs[1]);
  if (ea < 0 || eb < 0) return std::nullopt;
  Row row;
  add(row, fine.vertex(v), 2.0);
  add(row, ea, -0.5);
  add(row, eb, -0.5);
  return row;
}

struct Candidate {
  Row row;
  ReverseRule rule;
};

bool shorter(const Row& row, const std::optional<Row>& best) { return !best || row.size() < best->size(); }

/// (B.2), v = 4 e' - w - f'_1 - f'_2, through the shortest usable interior edge to a reconstructed neighbour w.
std::optional<Row> edge_rule(Index v, const CoarseTopology& t, const FinePoints& fine, const std::vector<Row>& rows,
                             const std::vector<char>& done) {
  std::optional<Row> best;
  for (Index w : t.neighbours[v]) {
    const std::vector<Index>& fs = t.edge_faces.at(undirected(v, w));
    const Index e = fine.edge(v, w);
    if (!done[w] || fs.size() != 2 || e < 0 || fine.face(fs[0]) < 0 || fine.face(fs[1]) < 0) continue;
    Row row;
    add(row, e, 4.0);
    add(row, fine.face(fs[0]), -1.0);
    add(row, fine.face(fs[1]), -1.0);
    add(row, rows[w], -1.0);
    drop_cancelled(row);
    if (shorter(row, best)) best = std::move(row);
  }
  return best;
}

/// (B.4) with N = 4, v = 4 f' - (the face's other corners), through the shortest usable face.
std::optional<Row> face_rule(Index v, const mesh::QuadMesh& coarse, const CoarseTopology& t, const FinePoints& fine,
                             const std::vector<Row>& rows, const std::vector<char>& done) {
  std::optional<Row> best;
  for (Index f : t.faces[v]) {
    const mesh::Quad& q = coarse.quads[f];
    const bool others_done = std::all_of(q.begin(), q.end(), [&](Index u) { return u == v || done[u]; });
    if (fine.face(f) < 0 || !others_done) continue;
    Row row;
    add(row, fine.face(f), 4.0);
    for (Index u : q)
      if (u != v) add(row, rows[u], -1.0);
    drop_cancelled(row);
    if (shorter(row, best)) best = std::move(row);
  }
  return best;
}

[[noreturn]] void throw_unreached(Index v, const CoarseTopology& t, const FinePoints& fine) {
  const bool interior = t.interior(v);
  std::string why;
  if (interior && t.neighbours[v].size() == 3 && fine.vertex(v) >= 0)
    why = "it is an interior point of valence 3, where eq. (5.20) is singular, and none of its neighbours could be "
          "reconstructed first to use the edge rule (B.2) of App. C (adjacent valence-3 points only?)";
  else
    why = "its fine one-ring was dropped with the outer ghost layer and no reconstructed neighbour reaches it by the "
          "edge rule (B.2) or the face rule (B.4)";
  throw_error("reverse subdivision: no rule reconstructs coarse point {}: {}; use the least-squares projection "
              "(eq. 5.18) instead", v, why);
}

}  // namespace

linalg::StencilTable reverse_subdivision(const mesh::QuadMesh& coarse, const SubdivisionStep& step,
                                    ReverseRuleCounts* rule_counts) {
  const Index nc = coarse.num_vertices(), nf = step.fine.num_vertices();
  if (step.subdivision.num_cols != nc || step.subdivision.num_rows != nf ||
      static_cast<Index>(step.kind.size()) != nf || static_cast<Index>(step.parent.size()) != nf)
    throw_error("reverse subdivision: the step ({} coarse, {} fine points, {} kinds) was not made from this mesh "
                "({} points)", step.subdivision.num_cols, nf, step.kind.size(), nc);
  const CoarseTopology t = connect(coarse);
  const FinePoints fine = index_fine_points(coarse, step);
  std::vector<Row> rows(static_cast<size_t>(nc));
  std::vector<char> done(static_cast<size_t>(nc), 0);
  std::vector<ReverseRule> rule(static_cast<size_t>(nc), ReverseRule::kCount);

  for (Index v = 0; v < nc; ++v) {
    const std::vector<Index> boundary_nbrs = t.boundary_neighbours(v);
    std::optional<Row> row = boundary_nbrs.empty() ? interior_rule(v, t, fine) : boundary_rule(v, boundary_nbrs, fine);
    if (!row) continue;
    rows[v] = std::move(*row);
    done[v] = 1;
    if (boundary_nbrs.empty())
      rule[v] = t.neighbours[v].size() == 4 ? ReverseRule::kOrdinary : ReverseRule::kExtraordinary;
    else
      rule[v] = t.faces[v].size() == 1 ? ReverseRule::kCorner : ReverseRule::kBoundary;
  }
  // The rest in waves, each from the points of earlier waves only, so rows substitute as few levels as possible.
  for (;;) {
    std::vector<std::pair<Index, Candidate>> wave;
    for (Index v = 0; v < nc; ++v) {
      if (done[v]) continue;
      if (std::optional<Row> row = edge_rule(v, t, fine, rows, done)) {
        const bool valence3 = t.neighbours[v].size() == 3 && t.interior(v);
        wave.emplace_back(v, Candidate{std::move(*row), valence3 ? ReverseRule::kValence3 : ReverseRule::kGhost});
      } else if (std::optional<Row> row = face_rule(v, coarse, t, fine, rows, done)) {
        wave.emplace_back(v, Candidate{std::move(*row), ReverseRule::kCornerGhost});
      }
    }
    if (wave.empty()) break;
    for (auto& [v, c] : wave) {
      rows[v] = std::move(c.row);
      rule[v] = c.rule;
      done[v] = 1;
    }
  }

  linalg::StencilTable Q;
  Q.num_rows = nc;
  Q.num_cols = nf;
  Q.offsets.assign(1, 0);
  for (Index v = 0; v < nc; ++v) {
    if (!done[v]) throw_unreached(v, t, fine);
    drop_cancelled(rows[v]);
    for (const auto& [i, term] : rows[v]) {
      Q.indices.push_back(i);
      Q.weights.push_back(term.w);
    }
    Q.offsets.push_back(static_cast<Index>(Q.indices.size()));
  }
  if (rule_counts) {
    rule_counts->fill(0);
    for (ReverseRule r : rule) ++(*rule_counts)[static_cast<size_t>(r)];
  }
  return Q;
}

struct LeastSquaresProjection::Impl {
  Eigen::SparseMatrix<double> S;
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt;
};

LeastSquaresProjection::LeastSquaresProjection(const linalg::StencilTable& S)
    : m_impl(std::make_unique<Impl>()), m_num_coarse(S.num_cols), m_num_fine(S.num_rows) {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(S.indices.size());
  for (Index i = 0; i < S.num_rows; ++i)
    for (Index k = S.offsets[i]; k < S.offsets[i + 1]; ++k) entries.emplace_back(i, S.indices[k], S.weights[k]);
  m_impl->S.resize(S.num_rows, S.num_cols);
  m_impl->S.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SparseMatrix<double> StS = m_impl->S.transpose() * m_impl->S;
  m_impl->llt.compute(StS);
  // Rounding can leave a tiny positive pivot where SᵀS is singular (on the cube, q = ±1 alternating has S q = 0),
  // so a pivot far below the diagonal's scale counts as a failure too.
  bool singular = m_impl->llt.info() != Eigen::Success;
  if (!singular && S.num_cols > 0) {
    const VecX pivots = m_impl->llt.matrixL().nestedExpression().diagonal();
    singular = pivots.cwiseAbs2().minCoeff() < 1e-12 * StS.diagonal().maxCoeff();
  }
  if (singular)
    throw_error("least-squares projection: SᵀS ({0} x {0}) is singular, the subdivision matrix is not injective "
                "(no projection with P S = I exists)", S.num_cols);
}

LeastSquaresProjection::~LeastSquaresProjection() = default;
LeastSquaresProjection::LeastSquaresProjection(LeastSquaresProjection&&) noexcept = default;
LeastSquaresProjection& LeastSquaresProjection::operator=(LeastSquaresProjection&&) noexcept = default;

void LeastSquaresProjection::apply(const VecX& fine3, VecX& coarse3) const {
  if (fine3.size() != 3 * static_cast<Eigen::Index>(m_num_fine))
    throw_error("LeastSquaresProjection::apply: fine vector has {} entries, expected {}", fine3.size(),
                3 * m_num_fine);
  // Eq. (5.18) for x, y and z at once: columns of the n x 3 right-hand side SᵀF.
  const MatX rhs = m_impl->S.transpose() * as_columns(fine3).transpose();
  const MatX q = m_impl->llt.solve(rhs);
  coarse3.resize(3 * static_cast<Eigen::Index>(m_num_coarse));
  as_columns(coarse3) = q.transpose();
}

Index LeastSquaresProjection::factor_nonzeros() const {
  return static_cast<Index>(m_impl->llt.matrixL().nestedExpression().nonZeros());
}

std::size_t LeastSquaresProjection::memory_bytes() const {
  using StorageIndex = Eigen::SparseMatrix<double>::StorageIndex;
  const auto& L = m_impl->llt.matrixL().nestedExpression();
  const auto n = static_cast<std::size_t>(m_num_coarse);
  return static_cast<std::size_t>(L.nonZeros()) * (sizeof(double) + sizeof(StorageIndex)) +
         static_cast<std::size_t>(L.outerSize() + 1) * sizeof(StorageIndex) + 2 * n * sizeof(StorageIndex);
}

}  // namespace mgcloth::hierarchy
