#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/limit_surface.hpp>

#include <opensubdiv/bfr/refinerSurfaceFactory.h>
#include <opensubdiv/bfr/surface.h>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <map>

namespace mgcloth::mesh {

namespace Bfr = OpenSubdiv::Bfr;

Vec3 LimitStencil::apply(const Mat3X& q, int d) const {
  Vec3 s = Vec3::Zero();
  for (Index k = 0; k < size(); ++k) s += w(k, d) * q.col(points[k]);
  return s;
}

Vec2 LimitStencil::apply(const Mat2X& u, int d) const {
  Vec2 s = Vec2::Zero();
  for (Index k = 0; k < size(); ++k) s += w(k, d) * u.col(points[k]);
  return s;
}

struct LimitSurface::Impl {
  TopologyRefinerPtr refiner;
  std::unique_ptr<Bfr::RefinerSurfaceFactory<>> factory;
  std::vector<std::unique_ptr<Bfr::Surface<double>>> surfaces;  // per face; null for ghost faces
};

LimitSurface::LimitSurface(const QuadMesh& mesh, int approx_level) : m_mesh(mesh), m(std::make_unique<Impl>()) {
  m->refiner = make_topology_refiner(mesh);
  Bfr::SurfaceFactory::Options options;
  options.SetApproxLevelSmooth(approx_level);
  m->factory = std::make_unique<Bfr::RefinerSurfaceFactory<>>(*m->refiner, options);
  m->surfaces.resize(mesh.quads.size());
  for (Index f = 0; f < mesh.num_faces(); ++f) {
    if (mesh.is_ghost_face(f)) continue;
    auto surface = std::make_unique<Bfr::Surface<double>>();
    if (!m->factory->InitVertexSurface(f, surface.get()) || !surface->IsValid())
      throw_input_error("quad {}: OpenSubdiv cannot build its limit surface (no valid neighbourhood)", f);
    m->surfaces[f] = std::move(surface);
    m_real_faces.push_back(f);
  }
  if (m_real_faces.empty()) throw_input_error("the control mesh has no real (non-ghost) quad");
}

LimitSurface::~LimitSurface() = default;
LimitSurface::LimitSurface(LimitSurface&&) noexcept = default;
LimitSurface& LimitSurface::operator=(LimitSurface&&) noexcept = default;

bool LimitSurface::is_regular(Index face) const {
  return m->surfaces[face] && m->surfaces[face]->IsRegular();
}

void LimitSurface::stencil(Index face, double s, double t, LimitStencil& out) const {
  const auto* surface = m->surfaces.at(static_cast<size_t>(face)).get();
  if (!surface) throw_error("LimitSurface::stencil: face {} is a ghost face", face);
  const int n = surface->GetNumControlPoints();
  out.points.resize(n);
  surface->GetControlPointIndices(out.points.data());
  out.w.resize(n, 6);
  const double uv[2] = {s, t};
  surface->EvaluateStencil(uv, out.w.col(0).data(), out.w.col(1).data(), out.w.col(2).data(), out.w.col(3).data(),
                           out.w.col(4).data(), out.w.col(5).data());
}

bool LimitSurface::locate(const Vec2& u, Index& face, double& s, double& t) const {
  std::vector<std::pair<double, Index>> order;
  for (Index f : m_real_faces) {
    Vec2 c = Vec2::Zero();
    double r = 0.0;
    for (Index v : m_mesh.quads[f]) c += 0.25 * m_mesh.u.col(v);
    for (Index v : m_mesh.quads[f]) r = std::max(r, (m_mesh.u.col(v) - c).norm());
    const double d = (u - c).norm();
    if (d <= 1.5 * r) order.emplace_back(d, f);
  }
  std::sort(order.begin(), order.end());
  LimitStencil st;
  constexpr double kTol = 1e-9;
  for (const auto& [dist, f] : order) {
    Vec2 p(0.5, 0.5);
    bool inside = false;
    for (int it = 0; it < 30; ++it) {
      stencil(f, p.x(), p.y(), st);
      const Vec2 r = st.apply(m_mesh.u, 0) - u;
      Mat2 J;
      J.col(0) = st.apply(m_mesh.u, 1);
      J.col(1) = st.apply(m_mesh.u, 2);
      if (std::abs(J.determinant()) < 1e-300) break;
      const Vec2 dp = J.lu().solve(r);
      p -= dp;
      p = p.cwiseMax(-0.5).cwiseMin(1.5);
      if (dp.norm() < 1e-13) {
        inside = p.minCoeff() >= -kTol && p.maxCoeff() <= 1.0 + kTol;
        break;
      }
    }
    if (inside) {
      face = f;
      s = std::clamp(p.x(), 0.0, 1.0);
      t = std::clamp(p.y(), 0.0, 1.0);
      return true;
    }
  }
  return false;
}

Mat3X LimitSurface::Tessellation::positions(const Mat3X& q) const {
  Mat3X x(3, static_cast<Index>(offsets.size()) - 1);
  for (Index i = 0; i + 1 < static_cast<Index>(offsets.size()); ++i) {
    Vec3 p = Vec3::Zero();
    for (Index k = offsets[i]; k < offsets[i + 1]; ++k) p += weights[k] * q.col(indices[k]);
    x.col(i) = p;
  }
  return x;
}

LimitSurface::Tessellation LimitSurface::tessellate(int r) const {
  if (r < 1) throw_input_error("limit surface tessellation needs at least 1 sample per face side (got {})", r);
  Tessellation out;
  std::vector<Vec2> us;
  // Points shared along face edges are merged by their limit material coordinate.
  double scale = 0.0;
  for (Index v = 0; v < m_mesh.num_vertices(); ++v) scale = std::max(scale, m_mesh.u.col(v).cwiseAbs().maxCoeff());
  const double quantum = std::max(scale, 1e-30) * 1e-9;
  std::map<std::pair<long long, long long>, Index> ids;
  LimitStencil st;
  std::vector<Index> grid(static_cast<size_t>((r + 1) * (r + 1)));
  for (Index f : m_real_faces) {
    for (int j = 0; j <= r; ++j)
      for (int i = 0; i <= r; ++i) {
        stencil(f, static_cast<double>(i) / r, static_cast<double>(j) / r, st);
        const Vec2 u = st.apply(m_mesh.u, 0);
        const std::pair<long long, long long> key{std::llround(u.x() / quantum), std::llround(u.y() / quantum)};
        auto [it, fresh] = ids.try_emplace(key, static_cast<Index>(us.size()));
        if (fresh) {
          us.push_back(u);
          for (Index k = 0; k < st.size(); ++k) {
            if (st.w(k, 0) == 0.0) continue;
            out.indices.push_back(st.points[k]);
            out.weights.push_back(st.w(k, 0));
          }
          out.offsets.push_back(static_cast<Index>(out.indices.size()));
        }
        grid[static_cast<size_t>(j * (r + 1) + i)] = it->second;
      }
    for (int j = 0; j < r; ++j)
      for (int i = 0; i < r; ++i) {
        const Index a = grid[j * (r + 1) + i], b = grid[j * (r + 1) + i + 1], c = grid[(j + 1) * (r + 1) + i + 1],
                    d = grid[(j + 1) * (r + 1) + i];
        out.mesh.tris.push_back({a, b, c});
        out.mesh.tris.push_back({a, c, d});
      }
  }
  out.mesh.u.resize(2, static_cast<Index>(us.size()));
  for (size_t k = 0; k < us.size(); ++k) out.mesh.u.col(static_cast<Index>(k)) = us[k];
  out.mesh.x = out.positions(m_mesh.x);
  return out;
}

}  // namespace mgcloth::mesh
