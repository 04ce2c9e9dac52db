#pragma once
// The device pipeline of the nonlinear FMG (Wang 2018 §3-4), written once over an execution backend B (the CUDA
// backend, or the host backend that runs the same kernels on the CPU): B::for_each(n, f) runs f(i) for i < n,
// B::sum(n, f) reduces, B::Buffer<T> holds device memory. Kernels are MGCLOTH_HOST_DEVICE lambdas that capture raw
// pointers by value, never `this` (a host pointer on the device). Every vector is xyz-interleaved in the level's
// device numbering (layout.hpp), every matrix a BSR of row-major 3x3 blocks.
#include <mgcloth/core/timer.hpp>
#include <mgcloth/cuda/device_fmg.hpp>
#include <mgcloth/cuda/errors.hpp>
#include <mgcloth/cuda/layout.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/physics/element_kernels.hpp>

#include <cmath>
#include <memory>
#include <random>

#define MGCLOTH_LAMBDA [=] MGCLOTH_HOST_DEVICE

namespace mgcloth::cuda {

template <class B>
class Pipeline final : public DeviceFmg {
 public:
  template <class T>
  using Buf = typename B::template Buffer<T>;

  explicit Pipeline(FmgSettings settings) : m_s(std::move(settings)) {
    if (m_s.coarse_solve == "auto") m_s.coarse_solve = "device";
    if (m_s.coarse_solve != "device" && m_s.coarse_solve != "host")
      fail_input("fmg-cuda: coarse_solve must be \"device\", \"host\" or \"auto\" (got \"" + m_s.coarse_solve + "\")");
  }
  std::string device() const override { return B::device_name(); }
  std::vector<double> smoother_radii() const override {
    std::vector<double> out;
    for (const Level& L : m_levels) out.push_back(L.rho);
    return out;
  }
  void restore_smoother_radii(std::vector<double> radii) override {
    for (Level& L : m_levels) L.rho = 0.0;
    m_restore_radii = std::move(radii);
  }

  // ---- Set-up --------------------------------------------------------------------------------------------------

  struct Level {
    Index n = 0, nb = 0;
    Buf<Index> row_offsets, cols, diag;
    Buf<double> blocks, inv_diag;
    std::vector<Index> color_offsets;
    Buf<Index> p_off, p_idx, pt_off, pt_idx, rap_off, rap_blk;
    Buf<double> p_w, pt_w, rap_w;
    Buf<double> b, x, r, prev, cur;  ///< V-cycle vectors
    Buf<unsigned char> mask;
    double rho = 0.0;                ///< Chebyshev: spectral radius of one symmetric sweep (estimated once)
  };

  void build(const physics::Objective& objective, const std::vector<const linalg::StencilTable*>& prolongations) {
    m_layout = build_layout(objective, prolongations);
    m_objective = &objective;
    m_prolongations = prolongations;
    m_pattern_version = objective.pattern_version();
    const ObjectiveLayout& O = m_layout.objective;
    m_n = O.n;
    m_levels.clear();
    m_levels.resize(m_layout.levels.size());
    for (size_t l = 0; l < m_levels.size(); ++l) {
      const LevelLayout& src = m_layout.levels[l];
      Level& L = m_levels[l];
      L.n = src.n;
      L.nb = src.pattern.num_blocks();
      L.row_offsets.upload(src.pattern.row_offsets());
      L.cols.upload(src.pattern.col_indices());
      std::vector<Index> diag(static_cast<size_t>(L.n));
      for (Index r = 0; r < L.n; ++r) diag[static_cast<size_t>(r)] = src.pattern.diagonal(r);
      L.diag.upload(diag);
      L.blocks.resize(9 * static_cast<size_t>(L.nb));
      L.inv_diag.resize(9 * static_cast<size_t>(L.n));
      L.color_offsets = src.color_offsets;
      for (auto* v : {&L.b, &L.x, &L.r, &L.prev, &L.cur}) v->resize(3 * static_cast<size_t>(L.n));
      L.mask.resize(static_cast<size_t>(L.n));
      if (l + 1 < m_levels.size()) {
        L.p_off.upload(src.P.offsets);
        L.p_idx.upload(src.P.indices);
        L.p_w.upload(src.P.weights);
        L.pt_off.upload(src.Pt.offsets);
        L.pt_idx.upload(src.Pt.indices);
        L.pt_w.upload(src.Pt.weights);
        L.rap_off.upload(src.rap_offsets);
        L.rap_blk.upload(src.rap_blocks);
        L.rap_w.upload(src.rap_weights);
      }
    }
    m_mass.upload(O.mass);
    m_tri_v.upload(O.tris.vertices);
    m_tri_slots.upload(O.tris.slots);
    m_tri_dm.upload(O.tri_dm_inv);
    m_tri_at.upload(O.tri_at);
    m_hinge_v.upload(O.hinges.vertices);
    m_hinge_slots.upload(O.hinges.slots);
    m_hinge_c.upload(O.hinge_c);
    m_hinge_k.upload(O.hinge_k);
    m_bend_off.upload(O.bend_offsets);
    m_bend_cols.upload(O.bend_cols);
    m_bend_slots.upload(O.bend_slots);
    m_bend_val.upload(O.bend_values);
    m_curv_off.upload(O.curv_offsets);
    m_curv_v.upload(O.curv_vertices);
    m_curv_w.upload(O.curv_weights);
    m_curv_ka.upload(O.curv_kb_area);
    m_pin_off.upload(O.pin_offsets);
    m_pin_k.upload(O.pin_k);
    m_contact_k.upload(O.contact_k);
    const size_t n3 = 3 * static_cast<size_t>(m_n);
    for (auto& v : m_vec) v.resize(n3);
    for (auto* v : {&m_y, &m_step_start, &m_velocity}) v->resize(n3);
    const Level& C = m_levels.back();
    m_coarse_dense_n = 3 * C.n;
    if (m_s.coarse_solve == "device") {
      m_dense.resize(static_cast<size_t>(m_coarse_dense_n) * static_cast<size_t>(m_coarse_dense_n));
      m_cholesky = std::make_unique<typename B::DenseCholesky>();
    } else {
      m_coarse_host = m_layout.levels.back().pattern;
    }
    m_vcycle_graph.reset();
    m_spgemm = SpgemmComparison{};
  }

  const std::vector<Level>& levels() const { return m_levels; }
  const Layout& layout() const { return m_layout; }

  /// Per step: the prediction, pin targets and obstacle poses.
  void upload_step(const physics::Objective& objective) {
    const StepData s = step_data(objective, m_layout);
    m_y.upload(s.y);
    m_inv_h2 = s.inv_h2;
    m_pin_targets.upload(s.targets);
    m_obstacles.upload(s.obstacles);
    m_num_obstacles = static_cast<Index>(s.obstacles.size());
  }

  // ---- The objective (Wang 2018 eq. 2) -------------------------------------------------------------------------

  /// A view of the point terms (inertia, gravity, pins, contact) that kernels capture by value.
  struct PointTerms {
    const double *mass, *y, *pin_k, *targets, *contact_k;
    const Index* pin_off;
    const hd::ObstacleData* obstacles;
    Index num_obstacles;
    double inv_h2, thickness, g0, g1, g2;
    bool gravity, contact;
  };
  PointTerms point_terms() const {
    const ObjectiveLayout& O = m_layout.objective;
    return {m_mass.data(), m_y.data(), m_pin_k.data(), m_pin_targets.data(), m_contact_k.data(), m_pin_off.data(),
            m_obstacles.data(), m_num_obstacles, m_inv_h2, O.thickness, O.gravity[0], O.gravity[1], O.gravity[2],
            O.has_gravity, !O.contact_k.empty()};
  }

  /// Energy, gradient (g3) and PSD diagonal block (H9) of vertex i's point terms; g3/H9 are added to.
  MGCLOTH_HOST_DEVICE static double point_element(const PointTerms& P, Index i, const double* xi, double* g3, double* H9) {
    double local_g[3], local_H[9];
    double e = hd::point_spring(xi, P.y + 3 * i, P.mass[i] * P.inv_h2, g3 ? local_g : nullptr, H9 ? local_H : nullptr);
    if (g3)
      for (int k = 0; k < 3; ++k) g3[k] += local_g[k];
    if (H9)
      for (int k = 0; k < 9; ++k) H9[k] += local_H[k];
    if (P.gravity) {
      e -= P.mass[i] * (P.g0 * xi[0] + P.g1 * xi[1] + P.g2 * xi[2]);
      if (g3) {
        g3[0] -= P.mass[i] * P.g0;
        g3[1] -= P.mass[i] * P.g1;
        g3[2] -= P.mass[i] * P.g2;
      }
    }
    for (Index p = P.pin_off[i]; p < P.pin_off[i + 1]; ++p) {
      e += hd::point_spring(xi, P.targets + 3 * p, P.pin_k[p], g3 ? local_g : nullptr, H9 ? local_H : nullptr);
      if (g3)
        for (int k = 0; k < 3; ++k) g3[k] += local_g[k];
      if (H9)
        for (int k = 0; k < 9; ++k) H9[k] += local_H[k];
    }
    if (P.contact)
      for (Index o = 0; o < P.num_obstacles; ++o) e += hd::contact_psd(P.obstacles[o], xi, P.contact_k[i], P.thickness, g3, H9);
    return e;
  }

  /// The membrane's and the bending's elements as views that kernels capture by value: stencils, block slots and
  /// rest data; operator() evaluates one element from its gathered positions (hd:: element math).
  struct TriangleView {
    static constexpr int K = 3;
    const Index *v, *slots;
    const double *dm, *at;
    double mu, lambda;
    MGCLOTH_HOST_DEVICE double operator()(Index t, const double* xe, double* g, double* H) const {
      return hd::stvk_triangle(xe, dm + 4 * t, at[t], mu, lambda, g, H, /*clamp_stress=*/H != nullptr);
    }
  };
  struct HingeView {
    static constexpr int K = 4;
    const Index *v, *slots;
    const double *c, *k;
    bool quadratic;
    MGCLOTH_HOST_DEVICE double operator()(Index h, const double* xe, double* g, double* H) const {
      return quadratic ? hd::quadratic_bending(xe, k + 4 * h, c[h], g, H) : hd::hinge_bending_psd(xe, c[h], g, H);
    }
  };
  TriangleView triangles() const {
    const ObjectiveLayout& O = m_layout.objective;
    return {m_tri_v.data(), m_tri_slots.data(), m_tri_dm.data(), m_tri_at.data(), O.mu, O.lambda};
  }
  HingeView hinges() const {
    return {m_hinge_v.data(), m_hinge_slots.data(), m_hinge_c.data(), m_hinge_k.data(), m_layout.objective.quadratic_bending};
  }
  /// The consistent quadratic bending (physics::IsometricBending): the scalar matrix K by rows and the triangles'
  /// curvature weights.
  struct IsometricView {
    const Index *off, *cols, *slots, *curv_off, *curv_v;
    const double *val, *curv_w, *curv_ka;
    Index rows, triangles;
  };
  IsometricView isometric() const {
    const ObjectiveLayout& O = m_layout.objective;
    if (!O.isometric_bending) return {nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, 0, 0};
    return {m_bend_off.data(), m_bend_cols.data(), m_bend_slots.data(), m_curv_off.data(), m_curv_v.data(),
            m_bend_val.data(), m_curv_w.data(),    m_curv_ka.data(),    O.n,               static_cast<Index>(O.curv_kb_area.size())};
  }
  /// k_b/2 A_T |D²x|² summed over triangles, as a sum of squares (zero to round-off squared on a planar state).
  double isometric_energy(const double* x) const {
    const IsometricView I = isometric();
    return B::sum(I.triangles, MGCLOTH_LAMBDA(Index t) {
      double D[9] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};  // D[3c + s]: component s of coordinate c
      for (Index k = I.curv_off[t]; k < I.curv_off[t + 1]; ++k)
        for (int c = 0; c < 3; ++c)
          for (int q = 0; q < 3; ++q) D[3 * c + q] += I.curv_w[3 * k + q] * x[3 * I.curv_v[k] + c];
      double sq = 0.0;
      for (int c = 0; c < 3; ++c) sq += D[3 * c] * D[3 * c] + 2.0 * D[3 * c + 1] * D[3 * c + 1] + D[3 * c + 2] * D[3 * c + 2];
      return 0.5 * I.curv_ka[t] * sq;
    });
  }
  /// g += (K ⊗ I₃) x, one row per thread.
  void isometric_gradient(const double* x, double* g) const {
    const IsometricView I = isometric();
    B::for_each(I.triangles > 0 ? I.rows : 0, MGCLOTH_LAMBDA(Index i) {
      double Kx[3] = {0.0, 0.0, 0.0};
      for (Index k = I.off[i]; k < I.off[i + 1]; ++k)
        for (int c = 0; c < 3; ++c) Kx[c] += I.val[k] * x[3 * I.cols[k] + c];
      for (int c = 0; c < 3; ++c) g[3 * i + c] += Kx[c];
    });
  }
  /// A += K ⊗ I₃ (constant and positive semi-definite: nothing to project); each entry owns its block.
  void isometric_hessian(double* A) const {
    const IsometricView I = isometric();
    B::for_each(I.triangles > 0 ? I.rows : 0, MGCLOTH_LAMBDA(Index i) {
      for (Index k = I.off[i]; k < I.off[i + 1]; ++k) {
        double* blk = A + 9 * I.slots[k];
        blk[0] += I.val[k];
        blk[4] += I.val[k];
        blk[8] += I.val[k];
      }
    });
  }

  template <int K>
  MGCLOTH_HOST_DEVICE static void gather(const double* x, const Index* v, double* xe) {
    for (int a = 0; a < K; ++a)
      for (int k = 0; k < 3; ++k) xe[3 * a + k] = x[3 * v[a] + k];
  }

  template <class View>
  double element_energy(const View& E, Index count, const double* x) const {
    return B::sum(count, MGCLOTH_LAMBDA(Index e) {
      double xe[3 * View::K];
      gather<View::K>(x, E.v + View::K * e, xe);
      return E(e, xe, nullptr, nullptr);
    });
  }
  /// One launch per element color: no two elements of a color share a vertex, so the additions do not race.
  template <class View>
  void element_gradient(const View& E, const std::vector<Index>& colors, const double* x, double* g) const {
    for (size_t c = 0; c + 1 < colors.size(); ++c) {
      const Index first = colors[c];
      B::for_each(colors[c + 1] - first, MGCLOTH_LAMBDA(Index i) {
        constexpr int K = View::K;
        const Index e = first + i;
        double xe[3 * K], ge[3 * K];
        gather<K>(x, E.v + K * e, xe);
        E(e, xe, ge, nullptr);
        for (int a = 0; a < K; ++a)
          for (int k = 0; k < 3; ++k) g[3 * E.v[K * e + a] + k] += ge[3 * a + k];
      });
    }
  }
  template <class View>
  void element_hessian(const View& E, const std::vector<Index>& colors, const double* x, double* A) const {
    for (size_t c = 0; c + 1 < colors.size(); ++c) {
      const Index first = colors[c];
      B::for_each(colors[c + 1] - first, MGCLOTH_LAMBDA(Index i) {
        constexpr int K = View::K, N = 3 * K;
        const Index e = first + i;
        double xe[N], He[N * N];
        gather<K>(x, E.v + K * e, xe);
        E(e, xe, nullptr, He);
        for (int a = 0; a < K; ++a)
          for (int b = 0; b < K; ++b) {
            double* blk = A + 9 * E.slots[K * K * e + K * a + b];
            for (int r = 0; r < 3; ++r)
              for (int q = 0; q < 3; ++q) blk[3 * r + q] += He[(3 * a + r) * N + 3 * b + q];
          }
      });
    }
  }

  double energy_at(const double* x) const {
    const PointTerms P = point_terms();
    const ObjectiveLayout& O = m_layout.objective;
    return B::sum(m_n, MGCLOTH_LAMBDA(Index i) { return point_element(P, i, x + 3 * i, nullptr, nullptr); }) +
           element_energy(triangles(), O.tris.size(), x) + element_energy(hinges(), O.hinges.size(), x) +
           isometric_energy(x);
  }

  void gradient_at(const double* x, double* g) const {
    const PointTerms P = point_terms();
    B::for_each(m_n, MGCLOTH_LAMBDA(Index i) {
      double gi[3] = {0.0, 0.0, 0.0};
      point_element(P, i, x + 3 * i, gi, nullptr);
      for (int k = 0; k < 3; ++k) g[3 * i + k] = gi[k];
    });
    const ObjectiveLayout& O = m_layout.objective;
    element_gradient(triangles(), O.tris.color_offsets, x, g);
    element_gradient(hinges(), O.hinges.color_offsets, x, g);
    isometric_gradient(x, g);
  }

  /// The PSD-projected Hessian into level 0's blocks (the fixed pattern; element colors again keep it race-free).
  void hessian(const double* x) {
    Level& L = m_levels[0];
    double* A = L.blocks.data();
    B::for_each(9 * L.nb, MGCLOTH_LAMBDA(Index k) { A[k] = 0.0; });
    const PointTerms P = point_terms();
    const Index* ds = L.diag.data();  // level 0's diagonal blocks
    B::for_each(m_n, MGCLOTH_LAMBDA(Index i) { point_element(P, i, x + 3 * i, nullptr, A + 9 * ds[i]); });
    const ObjectiveLayout& O = m_layout.objective;
    element_hessian(triangles(), O.tris.color_offsets, x, A);
    element_hessian(hinges(), O.hinges.color_offsets, x, A);
    isometric_hessian(A);
  }

  /// Moves vertices inside obstacles onto their surfaces (§4.5); returns how many moved.
  Index project_at(double* x) const {
    if (m_num_obstacles == 0) return 0;
    const hd::ObstacleData* obs = m_obstacles.data();
    const int no = static_cast<int>(m_num_obstacles);
    return static_cast<Index>(
        B::sum(m_n, MGCLOTH_LAMBDA(Index i) { return hd::project_vertex(obs, no, x + 3 * i) > 0.0 ? 1.0 : 0.0; }));
  }

  void finish_step(const VecX& x_old, double h, VecX& x_host, VecX& v_host) override {
    if (!m_objective) fail("fmg-cuda: finish_step() before minimize()");
    if (x_old.size() != 3 * m_n || !(h > 0.0))
      fail("fmg-cuda: finish_step() needs the step's start (" + std::to_string(3 * m_n) + " entries) and h > 0");
    {
      std::vector<double> xd;
      to_device_order(m_layout, x_old, xd);
      m_step_start.upload(xd);
    }
    const PointTerms P = point_terms();
    double *x = m_vec[0].data(), *v = m_velocity.data();
    const double* x0 = m_step_start.data();
    const int no = static_cast<int>(m_num_obstacles);
    // One pass per vertex: projection, velocity, then each obstacle's friction filter, as on the CPU
    // (physics::project_out_of_obstacles, physics::apply_friction) with the cubic penalty's normal force.
    B::for_each(m_n, MGCLOTH_LAMBDA(Index i) {
      double* xi = x + 3 * i;
      double* vi = v + 3 * i;
      const double pushed = P.contact ? hd::project_vertex(P.obstacles, no, xi) : 0.0;
      for (int k = 0; k < 3; ++k) vi[k] = (xi[k] - x0[3 * i + k]) / h;
      if (!P.contact) return;
      for (int o = 0; o < no; ++o) {
        hd::V3 normal;
        const double gap = hd::contact_gap(P.obstacles[o], xi, P.thickness, normal);
        if (gap <= 0.0) continue;
        const double force = hd::contact_normal_force(P.contact_k[i], gap, P.thickness);
        const double dvn = h * force / P.mass[i] + pushed / h;
        hd::filter_velocity(vi, hd::point_velocity(P.obstacles[o], hd::load3(xi)), normal, dvn,
                            P.obstacles[o].friction);
      }
    });
    std::vector<double> buf;
    m_vec[0].download(buf);
    from_device_order(m_layout, buf, x_host);
    m_velocity.download(buf);
    from_device_order(m_layout, buf, v_host);
  }

  // ---- Linear algebra ------------------------------------------------------------------------------------------

  double dot(const double* a, const double* b, Index n3) const {
    return B::sum(n3, MGCLOTH_LAMBDA(Index i) { return a[i] * b[i]; });
  }
  void copy(const double* a, double* b, Index n3) const {
    B::for_each(n3, MGCLOTH_LAMBDA(Index i) { b[i] = a[i]; });
  }
  void fill(double* a, double v, Index n3) const {
    B::for_each(n3, MGCLOTH_LAMBDA(Index i) { a[i] = v; });
  }
  /// y = a·x + b·y
  void axpby(double a, const double* x, double b, double* y, Index n3) const {
    B::for_each(n3, MGCLOTH_LAMBDA(Index i) { y[i] = a * x[i] + b * y[i]; });
  }
  /// z = x + a·y
  void add_scaled(const double* x, double a, const double* y, double* z, Index n3) const {
    B::for_each(n3, MGCLOTH_LAMBDA(Index i) { z[i] = x[i] + a * y[i]; });
  }

  /// y = A_l x.
  void multiply(const Level& L, const double* x, double* y) const {
    const Index *off = L.row_offsets.data(), *cols = L.cols.data();
    const double* A = L.blocks.data();
    B::for_each(L.n, MGCLOTH_LAMBDA(Index r) {
      double s[3] = {0.0, 0.0, 0.0};
      for (Index k = off[r]; k < off[r + 1]; ++k) {
        const double* a = A + 9 * k;
        const double* xc = x + 3 * cols[k];
        for (int i = 0; i < 3; ++i) s[i] += a[3 * i] * xc[0] + a[3 * i + 1] * xc[1] + a[3 * i + 2] * xc[2];
      }
      for (int i = 0; i < 3; ++i) y[3 * r + i] = s[i];
    });
  }
  /// r = b − A_l x.
  void residual(const Level& L, const double* b, const double* x, double* r) const {
    multiply(L, x, r);
    axpby(1.0, b, -1.0, r, 3 * L.n);
  }

  /// One pass over the colors of level L (forward or backward), rows of a color relaxed in parallel; rows whose mask
  /// entry is 0 are skipped (adaptive smoothing).
  void sweep(const Level& L, const double* b, double* x, bool forward, const unsigned char* mask) const {
    const Index *off = L.row_offsets.data(), *cols = L.cols.data();
    const double *A = L.blocks.data(), *D = L.inv_diag.data();
    const Index nc = static_cast<Index>(L.color_offsets.size()) - 1;
    for (Index i = 0; i < nc; ++i) {
      const Index c = forward ? i : nc - 1 - i;
      const Index first = L.color_offsets[c];
      B::for_each(L.color_offsets[c + 1] - first, MGCLOTH_LAMBDA(Index k) {
        const Index r = first + k;
        if (mask && !mask[r]) return;
        double s[3] = {b[3 * r], b[3 * r + 1], b[3 * r + 2]};
        for (Index q = off[r]; q < off[r + 1]; ++q) {
          const Index col = cols[q];
          if (col == r) continue;
          const double* a = A + 9 * q;
          const double* xc = x + 3 * col;
          for (int j = 0; j < 3; ++j) s[j] -= a[3 * j] * xc[0] + a[3 * j + 1] * xc[1] + a[3 * j + 2] * xc[2];
        }
        const double* d = D + 9 * r;
        for (int j = 0; j < 3; ++j) x[3 * r + j] = d[3 * j] * s[0] + d[3 * j + 1] * s[1] + d[3 * j + 2] * s[2];
      });
    }
  }
  void symmetric_sweeps(const Level& L, const double* b, double* x, int sweeps, const unsigned char* mask) const {
    for (int s = 0; s < sweeps; ++s) {
      sweep(L, b, x, true, mask);
      sweep(L, b, x, false, mask);
    }
  }
  /// Chebyshev semi-iterative acceleration of the symmetric sweeps (Wang 2015; linalg::chebyshev_gauss_seidel).
  void smooth(Level& L, const double* b, double* x, int iterations, const unsigned char* mask) {
    if (!(m_s.chebyshev && L.rho > 0.0)) {
      symmetric_sweeps(L, b, x, iterations, mask);
      return;
    }
    const Index n3 = 3 * L.n;
    double *previous = L.prev.data(), *current = L.cur.data();
    copy(x, previous, n3);
    double omega = 1.0;
    const double rho = L.rho;
    for (int k = 1; k <= iterations; ++k) {
      copy(x, current, n3);
      symmetric_sweeps(L, b, x, 1, mask);
      omega = k == 1 ? 1.0 : k == 2 ? 2.0 / (2.0 - rho * rho) : 4.0 / (4.0 - rho * rho * omega);
      if (k > 1) {
        const double w = omega;
        B::for_each(n3, MGCLOTH_LAMBDA(Index i) { x[i] = w * (x[i] - previous[i]) + previous[i]; });
      }
      std::swap(previous, current);
    }
  }

  /// New level-0 values: Galerkin products A_{l+1} = Pᵀ A_l P (one gather per coarse block over the symbolic map),
  /// inverted diagonal blocks, Chebyshev estimates (first matrix only), the coarsest factorization.
  void galerkin(size_t l) {
    Level &F = m_levels[l], &C = m_levels[l + 1];
    const Index *off = F.rap_off.data(), *blk = F.rap_blk.data();
    const double *w = F.rap_w.data(), *Af = F.blocks.data();
    double* Ac = C.blocks.data();
    B::for_each(C.nb, MGCLOTH_LAMBDA(Index k) {
      double s[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
      for (Index t = off[k]; t < off[k + 1]; ++t) {
        const double* a = Af + 9 * blk[t];
        for (int q = 0; q < 9; ++q) s[q] += w[t] * a[q];
      }
      for (int q = 0; q < 9; ++q) Ac[9 * k + q] = s[q];
    });
  }

  /// FmgSettings::compare_spgemm, on the current matrices (after update_hierarchy()).
  struct SpgemmComparison {
    bool done = false, available = false;
    double gather_ms = 0.0, reference_ms = 0.0, max_rel_diff = 0.0;
  };
  const SpgemmComparison& compare_spgemm() {
    constexpr int kRepeats = 10;  // after one warm-up run each
    m_spgemm = SpgemmComparison{};
    m_spgemm.done = m_spgemm.available = true;
    for (size_t l = 0; l + 1 < m_levels.size(); ++l) {
      galerkin(l);
      B::synchronize();
      Timer t;
      for (int r = 0; r < kRepeats; ++r) galerkin(l);
      B::synchronize();
      m_spgemm.gather_ms += t.ms() / kRepeats;
      std::vector<double> fine, coarse;
      m_levels[l].blocks.download(fine);
      m_levels[l + 1].blocks.download(coarse);
      const LevelLayout &F = m_layout.levels[l], &C = m_layout.levels[l + 1];
      const ScalarCsr A = expand_blocks(F.pattern, fine), P = expand_table(F.P, C.n), Pt = expand_table(F.Pt, F.n);
      ScalarCsr rap;
      double ms = 0.0;
      if (!B::spgemm_rap(A, P, Pt, kRepeats, rap, ms)) {
        m_spgemm.available = false;
        return m_spgemm;
      }
      m_spgemm.reference_ms += ms;
      m_spgemm.max_rel_diff = std::max(m_spgemm.max_rel_diff, relative_difference(rap, C.pattern, coarse));
    }
    return m_spgemm;
  }

  void update_hierarchy() {
    for (size_t l = 0; l + 1 < m_levels.size(); ++l) galerkin(l);
    for (size_t l = 0; l + 1 < m_levels.size(); ++l) {
      Level& L = m_levels[l];
      const Index* diag = L.diag.data();
      const double* A = L.blocks.data();
      double* D = L.inv_diag.data();
      const double singular = B::sum(L.n, MGCLOTH_LAMBDA(Index r) { return hd::invert3(A + 9 * diag[r], D + 9 * r) ? 0.0 : 1.0; });
      if (singular > 0.0) fail_solve("fmg-cuda: a 3x3 diagonal block of the Gauss-Seidel smoother is singular");
      if (m_s.chebyshev && L.rho == 0.0) L.rho = estimate_rho(L);
    }
    factorize_coarsest();
  }

  /// ρ of one symmetric sweep from 30 sweeps on A e = 0 from a random start (linalg::estimate_gauss_seidel_rho).
  double estimate_rho(Level& L) {
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> e0(3 * static_cast<size_t>(L.n));
    for (double& v : e0) v = u(rng);
    L.x.upload(e0);
    const Index n3 = 3 * L.n;
    fill(L.b.data(), 0.0, n3);
    constexpr int sweeps = 30;
    double start = 0.0;
    for (int s = 0; s < sweeps; ++s) {
      if (s == sweeps / 2) start = std::sqrt(dot(L.x.data(), L.x.data(), n3));
      symmetric_sweeps(L, L.b.data(), L.x.data(), 1, nullptr);
    }
    if (start == 0.0) return 0.0;
    return std::min(0.9999, std::pow(std::sqrt(dot(L.x.data(), L.x.data(), n3)) / start, 1.0 / (sweeps - sweeps / 2)));
  }

  void factorize_coarsest() {
    Level& C = m_levels.back();
    if (m_s.coarse_solve == "device") {
      // Dense Cholesky of the coarsest Galerkin matrix (3·n_c ≤ a few thousand rows), column-major.
      const Index N = m_coarse_dense_n;
      double* M = m_dense.data();
      const Index *off = C.row_offsets.data(), *cols = C.cols.data();
      const double* A = C.blocks.data();
      B::for_each(N * N, MGCLOTH_LAMBDA(Index k) { M[k] = 0.0; });
      B::for_each(C.n, MGCLOTH_LAMBDA(Index r) {
        for (Index q = off[r]; q < off[r + 1]; ++q)
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) M[(3 * cols[q] + j) * N + 3 * r + i] = A[9 * q + 3 * i + j];
      });
      if (!m_cholesky->factorize(M, N)) fail_solve("fmg-cuda: the coarsest Galerkin matrix is not positive definite");
      return;
    }
    std::vector<double> blocks;
    C.blocks.download(blocks);
    for (Index k = 0; k < C.nb; ++k)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m_coarse_host.block(k)(i, j) = blocks[9 * static_cast<size_t>(k) + 3 * i + j];
    if (!m_coarse_solver.factorize(m_coarse_host))
      fail_solve("fmg-cuda: the coarsest Galerkin matrix is not positive definite");
  }

  void coarse_solve(Level& C, const double* b, double* x) {
    if (m_s.coarse_solve == "device") {
      m_cholesky->solve(b, x);
      return;
    }
    // CHOLMOD on the host: the right-hand side (the level's buffer C.b) down, the solution (into C.x) up.
    if (b != C.b.data() || x != C.x.data()) fail("fmg-cuda: the host coarse solve takes the level's own buffers");
    std::vector<double> hb(3 * static_cast<size_t>(C.n));
    C.b.download(hb);
    const VecX rhs = Eigen::Map<const VecX>(hb.data(), static_cast<Index>(hb.size()));
    VecX sol;
    m_coarse_solver.solve(rhs, sol);
    C.x.upload(sol.data(), static_cast<size_t>(sol.size()));
  }

  /// Adaptive smoothing mask of level L from a residual (Wang 2018 §4.3): rows below threshold × RMS are skipped.
  const unsigned char* adaptive_mask(Level& L, const double* res) {
    if (!(m_s.adaptive_threshold > 0.0)) return nullptr;
    const Index n3 = 3 * L.n;
    const double rms = std::sqrt(dot(res, res, n3) / static_cast<double>(std::max<Index>(1, L.n)));
    const double t2 = (m_s.adaptive_threshold * rms) * (m_s.adaptive_threshold * rms);
    unsigned char* mask = L.mask.data();
    const double active = B::sum(L.n, MGCLOTH_LAMBDA(Index r) {
      const double s = res[3 * r] * res[3 * r] + res[3 * r + 1] * res[3 * r + 1] + res[3 * r + 2] * res[3 * r + 2];
      mask[r] = s >= t2 ? 1 : 0;
      return s >= t2 ? 1.0 : 0.0;
    });
    m_rows_active += active;
    m_rows_total += static_cast<double>(L.n);
    return mask;
  }

  /// One V-cycle on level l for A_l x = b with b, x the level's buffers L.b, L.x (LinearMultigrid::cycle).
  void cycle(size_t l, bool x_zero) {
    Level& L = m_levels[l];
    if (l + 1 == m_levels.size()) {
      coarse_solve(L, L.b.data(), L.x.data());
      return;
    }
    Level& C = m_levels[l + 1];
    double *b = L.b.data(), *x = L.x.data(), *r = L.r.data();
    const unsigned char* mask = nullptr;
    if (m_s.adaptive_threshold > 0.0) {
      if (!x_zero) residual(L, b, x, r);
      mask = adaptive_mask(L, x_zero ? b : r);
    }
    profiled(m_prof.smoothing, [&] { smooth(L, b, x, m_s.pre_smooth, mask); });
    m_prof.smoother_bytes += sweep_bytes(L) * 2.0 * m_s.pre_smooth;
    Timer transfer;
    residual(L, b, x, r);
    // Restriction rc = Pᵀ r into the coarse level's right-hand side.
    {
      const Index *off = L.pt_off.data(), *idx = L.pt_idx.data();
      const double* w = L.pt_w.data();
      double* rc = C.b.data();
      B::for_each(C.n, MGCLOTH_LAMBDA(Index c) {
        double s[3] = {0.0, 0.0, 0.0};
        for (Index k = off[c]; k < off[c + 1]; ++k)
          for (int j = 0; j < 3; ++j) s[j] += w[k] * r[3 * idx[k] + j];
        for (int j = 0; j < 3; ++j) rc[3 * c + j] = s[j];
      });
    }
    fill(C.x.data(), 0.0, 3 * C.n);
    if (m_s.profile) {
      B::synchronize();
      m_prof.transfer += transfer.ms();
    }
    if (l + 2 == m_levels.size()) profiled(m_prof.coarse, [&] { cycle(l + 1, true); });
    else cycle(l + 1, true);
    transfer.reset();
    // Prolongation of the coarse correction, added to x.
    {
      const Index *off = L.p_off.data(), *idx = L.p_idx.data();
      const double* w = L.p_w.data();
      const double* ec = C.x.data();
      B::for_each(L.n, MGCLOTH_LAMBDA(Index f) {
        for (Index k = off[f]; k < off[f + 1]; ++k)
          for (int j = 0; j < 3; ++j) x[3 * f + j] += w[k] * ec[3 * idx[k] + j];
      });
    }
    if (m_s.profile) {
      B::synchronize();
      m_prof.transfer += transfer.ms();
    }
    if (m_s.adaptive_threshold > 0.0) {
      residual(L, b, x, r);
      mask = adaptive_mask(L, r);
    }
    profiled(m_prof.smoothing, [&] { smooth(L, b, x, m_s.post_smooth, mask); });
    m_prof.smoother_bytes += sweep_bytes(L) * 2.0 * m_s.post_smooth;
  }

  /// The least memory traffic of one forward (or backward) Gauss-Seidel pass over level L: every block, column
  /// index and row offset read once, b, the inverse diagonal and x's own row read and x written once, and the
  /// neighbours' x once per block (an upper bound on what caches save, so the bandwidth derived from it is a
  /// lower bound of the achieved one).
  static double sweep_bytes(const Level& L) {
    const double nb = static_cast<double>(L.nb), n = static_cast<double>(L.n);
    return nb * (72.0 + 4.0 + 24.0) + n * (8.0 + 24.0 + 72.0 + 24.0 + 24.0);
  }
  /// With settings.profile: f's time (after a device synchronization) into slot.
  template <class F>
  void profiled(double& slot, F&& f) {
    if (!m_s.profile) {
      f();
      return;
    }
    B::synchronize();  // only this part's own work in the time
    timed(slot, f);
  }
  struct Profile {
    double smoothing = 0.0, coarse = 0.0, transfer = 0.0, smoother_bytes = 0.0;
  };

  // ---- The backend of solvers::FmgCycle (the cycle itself is the CPU solver's) ---------------------------------

  bool begin(const physics::Objective& objective, const std::vector<const linalg::StencilTable*>& prolongations,
             const VecX& x_host) override {
    m_ms = Phases{};
    // The device layout (colorings, Galerkin maps, scatter slots) follows the objective's pattern: rebuilt when the
    // terms' stencils changed it. (Within a solve the device assembles with the stencils of the solve's start.)
    objective.update_stencils(x_host);
    bool rebuilt = false;
    if (m_objective != &objective || m_prolongations != prolongations || m_pattern_version != objective.pattern_version()) {
      Timer t;
      build(objective, prolongations);
      m_ms.setup = t.ms();
      rebuilt = true;
    }
    if (!m_restore_radii.empty()) {
      if (m_restore_radii.size() != m_levels.size())
        fail_input("fmg-cuda: a solver state for " + std::to_string(m_restore_radii.size()) +
                   " levels, the hierarchy has " + std::to_string(m_levels.size()));
      for (size_t l = 0; l < m_levels.size(); ++l) m_levels[l].rho = m_restore_radii[l];
      m_restore_radii.clear();
    }
    if (x_host.size() != 3 * m_n)
      fail("fmg-cuda: the start point has " + std::to_string(x_host.size()) + " entries, the objective " +
           std::to_string(3 * m_n) + " dofs");
    upload_step(objective);
    m_rows_active = m_rows_total = 0.0;
    m_prof = Profile{};
    m_graph_launches = 0;
    std::vector<double> xd;
    to_device_order(m_layout, x_host, xd);
    m_vec[0].upload(xd);
    return rebuilt;
  }
  void download(int v, VecX& x) const override {
    std::vector<double> xd;
    m_vec[slot(v)].download(xd);
    from_device_order(m_layout, xd, x);
  }

  double energy(int v) override { return energy_at(vec(v)); }
  void gradient(int v, int g) override { gradient_at(vec(v), vec(g)); }
  Index project(int v) override { return project_at(vec(v)); }
  double dot(int a, int b) override { return dot(vec(a), vec(b), 3 * m_n); }
  void combine(int out, double a, int u, double b, int w) override {
    double *o = vec(out), *x = vec(u), *y = vec(w);
    B::for_each(3 * m_n, MGCLOTH_LAMBDA(Index i) { o[i] = a * x[i] + b * y[i]; });
  }
  void scale(int out, double a, int u) override {
    double *o = vec(out), *x = vec(u);
    B::for_each(3 * m_n, MGCLOTH_LAMBDA(Index i) { o[i] = a * x[i]; });
  }
  void weight(int out, double omega, int u, int prev) override {
    double *o = vec(out), *x = vec(u), *q = vec(prev);
    B::for_each(3 * m_n, MGCLOTH_LAMBDA(Index i) { o[i] = omega * (x[i] - q[i]) + q[i]; });
  }
  void copy(int to, int from) override { copy(vec(from), vec(to), 3 * m_n); }
  void update_matrix(int v) override {
    timed(m_ms.assembly, [&] { hessian(vec(v)); });
    timed(m_ms.galerkin, [&] { update_hierarchy(); });
    if (m_s.compare_spgemm && !m_spgemm.done) compare_spgemm();
  }
  void multiply(int in, int out) override { multiply(m_levels[0], vec(in), vec(out)); }
  double vcycle(int rv, int dv) override {
    const Index n3 = 3 * m_n;
    Level& top = m_levels[0];
    double *r = vec(rv), *d = vec(dv);
    // Graphs hold only device work: not with the host coarse solve (copies), the adaptive mask (reductions) or the
    // profile's synchronizations.
    const bool use_graphs = m_s.graphs && m_s.coarse_solve == "device" && !(m_s.adaptive_threshold > 0.0) && !m_s.profile;
    timed(m_ms.linear, [&] {
      const auto run = [&] {
        copy(r, top.b.data(), n3);
        fill(top.x.data(), 0.0, n3);
        cycle(0, true);
        copy(top.x.data(), d, n3);
      };
      // The V-cycle is the same sequence of launches on the same buffers every time (2 × colors per sweep on every
      // level): captured once as a graph and replayed, it costs one launch. Its kernels read the matrices, not
      // copies of them, so a new matrix needs no new graph; other vectors do.
      if (use_graphs) {
        if (m_graph_vectors != std::make_pair(rv, dv)) {
          m_vcycle_graph.reset();
          m_graph_vectors = {rv, dv};
        }
        if (!m_vcycle_graph.ready() && !m_vcycle_graph.failed) B::capture(m_vcycle_graph, run);
        if (m_vcycle_graph.ready()) {
          B::launch(m_vcycle_graph);
          ++m_graph_launches;
          return;
        }
      }
      run();
    });
    return dot(d, r, n3);
  }
  void newton_step(int rv, int cv, double tol) override {
    const Index n3 = 3 * m_n;
    Level& top = m_levels[0];
    timed(m_ms.linear, [&] {
      copy(vec(rv), top.b.data(), n3);
      fill(top.x.data(), 0.0, n3);
      for (int it = 0; it < 30; ++it) {
        cycle(0, it == 0);
        residual(top, top.b.data(), top.x.data(), top.r.data());
        if (std::sqrt(dot(top.r.data(), top.r.data(), n3)) <= tol) break;
      }
      copy(top.x.data(), vec(cv), n3);
    });
  }
  void synchronize() override { B::synchronize(); }
  std::vector<std::pair<std::string, double>> counters() const override {
    const double relax = m_rows_total > 0.0 ? 1.0 - m_rows_active / m_rows_total : 0.0;
    std::vector<std::pair<std::string, double>> out{{"skipped_fraction", relax},
                                                    {"setup_ms", m_ms.setup},
                                                    {"assembly_ms", m_ms.assembly},
                                                    {"galerkin_ms", m_ms.galerkin},
                                                    {"linear_ms", m_ms.linear},
                                                    {"levels", static_cast<double>(m_levels.size())},
                                                    {"graph_launches", static_cast<double>(m_graph_launches)}};
    if (m_spgemm.available) {
      out.push_back({"spgemm_gather_ms", m_spgemm.gather_ms});
      out.push_back({"spgemm_reference_ms", m_spgemm.reference_ms});
      out.push_back({"spgemm_max_rel_diff", m_spgemm.max_rel_diff});
    }
    if (m_s.profile) {
      out.push_back({"smoothing_ms", m_prof.smoothing});
      out.push_back({"coarse_ms", m_prof.coarse});
      out.push_back({"transfer_ms", m_prof.transfer});
      out.push_back({"smoother_gbytes", m_prof.smoother_bytes * 1e-9});
      out.push_back({"smoother_gb_per_s", m_prof.smoothing > 0.0 ? m_prof.smoother_bytes * 1e-6 / m_prof.smoothing : 0.0});
    }
    return out;
  }

 private:
  static size_t slot(int v) {
    if (v < 0 || v >= kVectors) fail("fmg-cuda: no vector " + std::to_string(v));
    return static_cast<size_t>(v);
  }
  double* vec(int v) { return m_vec[slot(v)].data(); }
  template <class F>
  void timed(double& ms, F&& f) {
    Timer t;
    f();
    B::synchronize();
    ms += t.ms();
  }
  struct Phases {
    double setup = 0, assembly = 0, galerkin = 0, linear = 0;
  };

  FmgSettings m_s;
  Layout m_layout;
  const physics::Objective* m_objective = nullptr;
  std::vector<const linalg::StencilTable*> m_prolongations;
  long m_pattern_version = -1;  ///< the objective's pattern the layout was built for
  Index m_n = 0;
  std::vector<Level> m_levels;
  Buf<double> m_mass, m_tri_dm, m_tri_at, m_hinge_c, m_hinge_k, m_pin_k, m_contact_k, m_y, m_pin_targets;
  Buf<Index> m_tri_v, m_tri_slots, m_hinge_v, m_hinge_slots, m_pin_off;
  Buf<Index> m_bend_off, m_bend_cols, m_bend_slots, m_curv_off, m_curv_v;
  Buf<double> m_bend_val, m_curv_w, m_curv_ka;
  Buf<hd::ObstacleData> m_obstacles;
  Index m_num_obstacles = 0;
  double m_inv_h2 = 0.0;
  Buf<double> m_vec[kVectors];
  Buf<double> m_step_start, m_velocity;  ///< finish_step's x_old and v
  Index m_coarse_dense_n = 0;
  Buf<double> m_dense;
  std::unique_ptr<typename B::DenseCholesky> m_cholesky;
  linalg::BlockMatrix3 m_coarse_host;
  linalg::CholmodSolver m_coarse_solver;
  double m_rows_active = 0.0, m_rows_total = 0.0;
  std::vector<double> m_restore_radii;  ///< restore_smoother_radii() for the next solve, after build()
  Phases m_ms;
  long m_graph_launches = 0;
  Profile m_prof;
  SpgemmComparison m_spgemm;
  typename B::Graph m_vcycle_graph;
  std::pair<int, int> m_graph_vectors{-1, -1};  ///< the residual and correction vectors the graph was captured for
};

}  // namespace mgcloth::cuda
