#include <mgcloth/core/error.hpp>
#include <mgcloth/cuda/layout.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/physics/bending.hpp>

namespace mgcloth::cuda {
namespace {

/// Rows grouped by color: perm (device row → row) and the color ranges.
void order_by_color(const linalg::BlockMatrix3& pattern, std::vector<Index>& perm, std::vector<Index>& color_offsets) {
  const auto colors = linalg::color_rows(pattern);
  perm.clear();
  color_offsets.assign(1, 0);
  for (const auto& c : colors) {
    perm.insert(perm.end(), c.begin(), c.end());
    color_offsets.push_back(static_cast<Index>(perm.size()));
  }
  if (static_cast<Index>(perm.size()) != pattern.rows()) throw_error("device layout: the coloring misses rows");
}

std::vector<Index> inverse(const std::vector<Index>& perm) {
  std::vector<Index> inv(perm.size());
  for (size_t r = 0; r < perm.size(); ++r) inv[static_cast<size_t>(perm[r])] = static_cast<Index>(r);
  return inv;
}

linalg::BlockMatrix3 renumbered(const linalg::BlockMatrix3& A, const std::vector<Index>& inv) {
  std::vector<std::pair<Index, Index>> pairs;
  pairs.reserve(static_cast<size_t>(A.num_blocks()));
  for (Index r = 0; r < A.rows(); ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k)
      pairs.emplace_back(inv[static_cast<size_t>(r)], inv[static_cast<size_t>(A.col_indices()[k])]);
  return linalg::BlockMatrix3(A.rows(), std::move(pairs));
}

template <int K>
ElementGroup group_elements(const std::vector<std::array<Index, K>>& elements, const std::vector<Index>& inv,
                            const linalg::BlockMatrix3& pattern) {
  ElementGroup g;
  g.arity = K;
  const Index ne = static_cast<Index>(elements.size());
  std::vector<Index> flat(static_cast<size_t>(ne) * K);
  for (Index e = 0; e < ne; ++e)
    for (int a = 0; a < K; ++a) flat[static_cast<size_t>(e) * K + a] = inv[static_cast<size_t>(elements[e][a])];
  // One element per chunk: each color is then a set of elements with pairwise disjoint vertices.
  const physics::ElementColors colors = physics::color_elements(flat, K, pattern.rows(), 1);
  g.color_offsets.assign(1, 0);
  for (Index c = 0; c < colors.num_colors(); ++c) {
    for (Index k = colors.color_offsets[c]; k < colors.color_offsets[c + 1]; ++k)
      for (Index i = colors.chunk_offsets[k]; i < colors.chunk_offsets[k + 1]; ++i) {
        const Index e = colors.elements[i];
        g.source.push_back(e);
        for (int a = 0; a < K; ++a) g.vertices.push_back(flat[static_cast<size_t>(e) * K + a]);
      }
    g.color_offsets.push_back(static_cast<Index>(g.source.size()));
  }
  g.slots.resize(g.vertices.size() * K);
  for (size_t e = 0; e < g.source.size(); ++e)
    for (int a = 0; a < K; ++a)
      for (int b = 0; b < K; ++b)
        g.slots[(e * K + a) * K + b] = pattern.find(g.vertices[e * K + a], g.vertices[e * K + b]);
  return g;
}

}  // namespace

Layout build_layout(const physics::Objective& objective, const std::vector<const linalg::StencilTable*>& prolongations) {
  Layout L;
  L.levels.resize(prolongations.size() + 1);
  linalg::BlockMatrix3 original = objective.hessian_pattern();  // this level's pattern in the problem's numbering
  {
    LevelLayout& top = L.levels[0];
    top.n = original.rows();
    order_by_color(original, top.perm, top.color_offsets);
    top.pattern = renumbered(original, inverse(top.perm));
  }
  for (size_t l = 0; l < prolongations.size(); ++l) {
    const linalg::StencilTable& P = *prolongations[l];
    LevelLayout& fine = L.levels[l];
    LevelLayout& coarse = L.levels[l + 1];
    if (P.num_rows != fine.n)
      throw_error("device layout: level {} has {} vertices but its prolongation expects {}", l, fine.n, P.num_rows);
    // The coarse pattern (in the problem's numbering) decides the coarse coloring, hence the coarse device numbering.
    const linalg::GalerkinProduct symbolic(original, P);
    original = symbolic.coarse_pattern();
    coarse.n = P.num_cols;
    order_by_color(original, coarse.perm, coarse.color_offsets);
    const std::vector<Index> inv_c = inverse(coarse.perm);
    linalg::StencilTable Pd;
    Pd.num_rows = P.num_rows;
    Pd.num_cols = P.num_cols;
    Pd.offsets.assign(1, 0);
    for (Index r = 0; r < fine.n; ++r) {
      const Index i = fine.perm[static_cast<size_t>(r)];
      for (Index k = P.offsets[i]; k < P.offsets[i + 1]; ++k) {
        Pd.indices.push_back(inv_c[static_cast<size_t>(P.indices[k])]);
        Pd.weights.push_back(P.weights[k]);
      }
      Pd.offsets.push_back(static_cast<Index>(Pd.indices.size()));
    }
    Pd.build_transpose();
    fine.P = {Pd.offsets, Pd.indices, Pd.weights};
    fine.Pt = {Pd.t_offsets, Pd.t_indices, Pd.t_weights};
    const linalg::GalerkinProduct rap(fine.pattern, Pd);
    coarse.pattern = rap.coarse_pattern();
    fine.rap_offsets = rap.term_offsets();
    for (const auto& t : rap.terms()) {
      fine.rap_blocks.push_back(t.fine_block);
      fine.rap_weights.push_back(t.weight);
    }
  }

  ObjectiveLayout& O = L.objective;
  const LevelLayout& top = L.levels[0];
  O.n = top.n;
  const std::vector<Index> inv = inverse(top.perm);
  // Every term describes itself (physics::Term::describe_device); the layout only renumbers and colors.
  physics::DeviceObjective d;
  d.n = O.n;
  for (const auto& term : objective.terms())
    if (!term->describe_device(d))
      throw InputError(fmt::format(
          "fmg-cuda: the objective's term \"{}\" has no device implementation (the GPU pipeline takes inertia, gravity, "
          "the StVK membrane, every bending model, pins and the cubic obstacle penalty; use \"fmg\")",
          term->name()));
  if (!d.inertia) throw InputError("fmg-cuda: the objective has no inertia term");
  const auto by_device_row = [&](const std::vector<double>& v) {
    std::vector<double> out(static_cast<size_t>(O.n));
    for (Index r = 0; r < O.n; ++r) out[static_cast<size_t>(r)] = v[static_cast<size_t>(top.perm[static_cast<size_t>(r)])];
    return out;
  };
  O.mass = by_device_row(d.mass);
  if (d.gravity) {
    if (by_device_row(d.gravity_mass) != O.mass)
      throw InputError("fmg-cuda: gravity and inertia use different masses, which the device pipeline does not support");
    for (int k = 0; k < 3; ++k) O.gravity[k] = d.g[k];
    O.has_gravity = true;
  }
  if (d.membrane) {
    O.tris = group_elements<3>(d.triangles, inv, top.pattern);
    O.mu = d.mu;
    O.lambda = d.lambda;
    for (Index e : O.tris.source) {
      const auto& m = d.dm_inv[static_cast<size_t>(e)];
      O.tri_dm_inv.insert(O.tri_dm_inv.end(), m.begin(), m.end());
      O.tri_at.push_back(d.area_thickness[static_cast<size_t>(e)]);
    }
  }
  using Bending = physics::DeviceObjective::Bending;
  if (d.bending == Bending::Hinge || d.bending == Bending::Quadratic) {
    O.quadratic_bending = d.bending == Bending::Quadratic;
    O.hinges = group_elements<4>(d.hinges, inv, top.pattern);
    for (Index e : O.hinges.source) {
      O.hinge_c.push_back(d.hinge_c[static_cast<size_t>(e)]);
      if (O.quadratic_bending) {
        const auto& K = d.hinge_k[static_cast<size_t>(e)];
        O.hinge_k.insert(O.hinge_k.end(), K.begin(), K.end());
      }
    }
  } else if (d.bending == Bending::Isometric) {
    O.isometric_bending = true;
    const auto& K = *d.bend_matrix;
    O.bend_offsets.assign(1, 0);
    for (Index r = 0; r < O.n; ++r) {
      const Index i = top.perm[static_cast<size_t>(r)];
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(K, i); it; ++it) {
        const Index c = inv[static_cast<size_t>(it.col())];
        O.bend_cols.push_back(c);
        O.bend_values.push_back(it.value());
        O.bend_slots.push_back(top.pattern.find(r, c));
        if (O.bend_slots.back() < 0) throw_error("device layout: bending entry ({}, {}) outside the Hessian pattern", i, it.col());
      }
      O.bend_offsets.push_back(static_cast<Index>(O.bend_cols.size()));
    }
    const physics::TriangleCurvature& S = *d.curvature;
    O.curv_offsets = S.offsets;
    for (size_t k = 0; k < S.vertices.size(); ++k) {
      O.curv_vertices.push_back(inv[static_cast<size_t>(S.vertices[k])]);
      O.curv_weights.insert(O.curv_weights.end(), {S.weights[k][0], S.weights[k][1], S.weights[k][2]});
    }
    for (double a : S.area) O.curv_kb_area.push_back(d.bend_stiffness * a);
  }
  // Pins grouped by vertex (several pins may share one), each remembering its index for its target per step.
  std::vector<std::vector<Index>> by_vertex(static_cast<size_t>(O.n));
  for (size_t p = 0; p < d.pin_vertex.size(); ++p)
    by_vertex[static_cast<size_t>(inv[static_cast<size_t>(d.pin_vertex[p])])].push_back(static_cast<Index>(p));
  O.pin_offsets.assign(1, 0);
  for (const auto& list : by_vertex) {
    for (Index p : list) {
      O.pin_source.push_back(p);
      O.pin_k.push_back(d.pin_k[static_cast<size_t>(p)]);
    }
    O.pin_offsets.push_back(static_cast<Index>(O.pin_source.size()));
  }
  if (d.contact) {
    O.thickness = d.thickness;
    O.contact_k = by_device_row(d.contact_k);
  }
  return L;
}

StepData step_data(const physics::Objective& objective, const Layout& layout) {
  physics::DeviceStep d;
  for (const auto& term : objective.terms()) term->describe_device_step(d);
  StepData s;
  to_device_order(layout, d.y, s.y);
  s.inv_h2 = d.inv_h2;
  for (Index p : layout.objective.pin_source) {
    const Vec3& target = d.pin_targets[static_cast<size_t>(p)];
    s.targets.insert(s.targets.end(), {target.x(), target.y(), target.z()});
  }
  s.obstacles = std::move(d.obstacles);
  return s;
}

void to_device_order(const Layout& layout, const VecX& x, std::vector<double>& out) {
  const auto& perm = layout.levels[0].perm;
  out.resize(3 * perm.size());
  for (size_t r = 0; r < perm.size(); ++r)
    for (int k = 0; k < 3; ++k) out[3 * r + k] = x[3 * perm[r] + k];
}

void from_device_order(const Layout& layout, const std::vector<double>& in, VecX& x) {
  const auto& perm = layout.levels[0].perm;
  x.resize(static_cast<Index>(3 * perm.size()));
  for (size_t r = 0; r < perm.size(); ++r)
    for (int k = 0; k < 3; ++k) x[3 * perm[r] + k] = in[3 * r + k];
}

ScalarCsr expand_blocks(const linalg::BlockMatrix3& pattern, const std::vector<double>& blocks) {
  ScalarCsr m;
  const Index n = pattern.rows();
  m.rows = m.cols = static_cast<int>(3 * n);
  m.offsets.assign(1, 0);
  const auto& off = pattern.row_offsets();
  const auto& cols = pattern.col_indices();
  for (Index r = 0; r < n; ++r)
    for (int i = 0; i < 3; ++i) {
      for (Index k = off[static_cast<size_t>(r)]; k < off[static_cast<size_t>(r) + 1]; ++k)
        for (int j = 0; j < 3; ++j) {
          m.indices.push_back(static_cast<int>(3 * cols[static_cast<size_t>(k)] + j));
          m.values.push_back(blocks[9 * static_cast<size_t>(k) + 3 * i + j]);
        }
      m.offsets.push_back(static_cast<int>(m.indices.size()));
    }
  return m;
}

ScalarCsr expand_table(const CsrTable& table, Index cols) {
  ScalarCsr m;
  const size_t rows = table.offsets.size() - 1;
  m.rows = static_cast<int>(3 * rows);
  m.cols = static_cast<int>(3 * cols);
  m.offsets.assign(1, 0);
  for (size_t r = 0; r < rows; ++r)
    for (int i = 0; i < 3; ++i) {
      for (Index k = table.offsets[r]; k < table.offsets[r + 1]; ++k) {
        m.indices.push_back(static_cast<int>(3 * table.indices[static_cast<size_t>(k)] + i));
        m.values.push_back(table.weights[static_cast<size_t>(k)]);
      }
      m.offsets.push_back(static_cast<int>(m.indices.size()));
    }
  return m;
}

double relative_difference(const ScalarCsr& C, const linalg::BlockMatrix3& pattern, const std::vector<double>& blocks) {
  double scale = 0.0, diff = 0.0;
  for (double v : blocks) scale = std::max(scale, std::abs(v));
  for (int i = 0; i < C.rows; ++i)
    for (int k = C.offsets[static_cast<size_t>(i)]; k < C.offsets[static_cast<size_t>(i) + 1]; ++k) {
      const int j = C.indices[static_cast<size_t>(k)];
      const Index b = pattern.find(i / 3, j / 3);
      const double ours = b < 0 ? 0.0 : blocks[9 * static_cast<size_t>(b) + 3 * static_cast<size_t>(i % 3) + static_cast<size_t>(j % 3)];
      diff = std::max(diff, std::abs(C.values[static_cast<size_t>(k)] - ours));
    }
  return scale > 0.0 ? diff / scale : diff;
}

}  // namespace mgcloth::cuda
