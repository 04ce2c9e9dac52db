#pragma once
// The device pipeline of the nonlinear FMG (Wang 2018 §3-4), written once over an execution backend B (the CUDA
// backend, or the host backend that runs the same kernels on the CPU): B::for_each(n, f) runs f(i) for i < n,
// B::sum(n, f) reduces, B::Buffer<T> holds device memory. Kernels are MGCLOTH_HOST_DEVICE lambdas that capture raw
// pointers by value, never `this` (a host pointer on the device). Every vector is xyz-interleaved in the level's
// device numbering (layout.hpp), every matrix a BSR of row-major 3x3 blocks.
#include <mgcloth/core/backtracking.hpp>
#include <mgcloth/core/interrupt.hpp>
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
    for (auto* v : {&m_x, &m_g, &m_r, &m_d, &m_Ad, &m_p, &m_Ap, &m_s_vec, &m_As, &m_trial, &m_g_trial, &m_y})
      v->resize(n3);
    const Level& C = m_levels.back();
    m_coarse_dense_n = 3 * C.n;
    if (m_s.coarse_solve == "device") {
      m_dense.resize(static_cast<size_t>(m_coarse_dense_n) * static_cast<size_t>(m_coarse_dense_n));
      m_cholesky = std::make_unique<typename B::DenseCholesky>();
    } else {
      m_coarse_host = m_layout.levels.back().pattern;
    }
    m_beta = 1.0;
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

  double energy(const double* x) const {
    const PointTerms P = point_terms();
    const ObjectiveLayout& O = m_layout.objective;
    return B::sum(m_n, MGCLOTH_LAMBDA(Index i) { return point_element(P, i, x + 3 * i, nullptr, nullptr); }) +
           element_energy(triangles(), O.tris.size(), x) + element_energy(hinges(), O.hinges.size(), x) +
           isometric_energy(x);
  }

  void gradient(const double* x, double* g) const {
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
  Index project(double* x) const {
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
      m_trial.upload(xd);  // free between solves
    }
    const PointTerms P = point_terms();
    double *x = m_x.data(), *v = m_g_trial.data();
    const double* x0 = m_trial.data();
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
    m_x.download(buf);
    from_device_order(m_layout, buf, x_host);
    m_g_trial.download(buf);
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
    B::synchronize();
    Timer t;
    f();
    B::synchronize();
    slot += t.ms();
  }
  struct Profile {
    double smoothing = 0.0, coarse = 0.0, transfer = 0.0, smoother_bytes = 0.0;
  };

  // ---- The nonlinear FMG (Wang 2018 §4.2, solvers::NonlinearFMG with its default schedule) ---------------------

  Outcome minimize(const physics::Objective& objective, const std::vector<const linalg::StencilTable*>& prolongations,
                   bool do_project, VecX& x_host, const Limits& stop, bool want_trace) override;

 private:
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
  Buf<double> m_x, m_g, m_r, m_d, m_Ad, m_p, m_Ap, m_s_vec, m_As, m_trial, m_g_trial;
  Index m_coarse_dense_n = 0;
  Buf<double> m_dense;
  std::unique_ptr<typename B::DenseCholesky> m_cholesky;
  linalg::BlockMatrix3 m_coarse_host;
  linalg::CholmodSolver m_coarse_solver;
  double m_rows_active = 0.0, m_rows_total = 0.0;
  double m_beta = 1.0;  ///< accepted step / model step of the last direction, to start the next line search (§4.2.3)
  std::vector<double> m_restore_radii;  ///< restore_smoother_radii() for the next minimize(), after build()
  Profile m_prof;
  SpgemmComparison m_spgemm;
  typename B::Graph m_vcycle_graph;
};

template <class B>
Outcome Pipeline<B>::minimize(const physics::Objective& objective,
                              const std::vector<const linalg::StencilTable*>& prolongations, bool do_project,
                              VecX& x_host, const Limits& stop, bool want_trace) {
  Timer timer;
  struct Phases {
    double setup = 0, assembly = 0, galerkin = 0, linear = 0, line_search = 0, gradient = 0, model = 0;
  } ms;
  // The device layout (colorings, Galerkin maps, scatter slots) follows the objective's pattern: rebuilt when the
  // terms' stencils changed it. (Within a solve the device assembles with the stencils of the solve's start.)
  objective.update_stencils(x_host);
  if (m_objective != &objective || m_prolongations != prolongations || m_pattern_version != objective.pattern_version()) {
    Timer t;
    build(objective, prolongations);
    ms.setup = t.ms();
  }
  if (!m_restore_radii.empty()) {
    if (m_restore_radii.size() != m_levels.size())
      fail_input("fmg-cuda: a solver state for " + std::to_string(m_restore_radii.size()) + " levels, the hierarchy has " +
                 std::to_string(m_levels.size()));
    for (size_t l = 0; l < m_levels.size(); ++l) m_levels[l].rho = m_restore_radii[l];
    m_restore_radii.clear();
  }
  if (x_host.size() != 3 * m_n)
    fail("fmg-cuda: the start point has " + std::to_string(x_host.size()) + " entries, the objective " +
         std::to_string(3 * m_n) + " dofs");
  upload_step(objective);
  m_rows_active = m_rows_total = 0.0;
  m_prof = Profile{};
  const Index n3 = 3 * m_n;
  {
    std::vector<double> xd;
    to_device_order(m_layout, x_host, xd);
    m_x.upload(xd);
  }
  double *x = m_x.data(), *g = m_g.data(), *r = m_r.data(), *d = m_d.data(), *Ad = m_Ad.data(), *p = m_p.data(),
         *Ap = m_Ap.data(), *sv = m_s_vec.data(), *As = m_As.data(), *trial = m_trial.data(),
         *g_trial = m_g_trial.data();
  Level& top = m_levels[0];
  long directions = 0, rejected = 0, energy_evals = 0, matrix_updates = 0, graph_launches = 0, fallbacks = 0;
  // Graphs hold only device work: not with the host coarse solve (copies), the adaptive mask (reductions) or the
  // profile's synchronizations.
  const bool use_graphs = m_s.graphs && m_s.coarse_solve == "device" && !(m_s.adaptive_threshold > 0.0) && !m_s.profile;
  const auto timed = [&](double& slot, auto&& f) {
    Timer t;
    f();
    B::synchronize();
    slot += t.ms();
  };
  const auto evaluate = [&](const double* y) {
    double v = 0.0;
    timed(ms.line_search, [&] { v = energy(y); });
    ++energy_evals;
    return v;
  };
  double e = energy(x);
  double gnorm = 0.0;
  const auto refresh_gradient = [&] {
    timed(ms.gradient, [&] {
      gradient(x, g);
      B::for_each(n3, MGCLOTH_LAMBDA(Index i) { r[i] = -g[i]; });
      gnorm = std::sqrt(dot(g, g, n3));
    });
  };
  refresh_gradient();
  Outcome out;
  const auto check = [&](int iteration) {
    if (!std::isfinite(e) || !std::isfinite(gnorm))
      fail_solve("fmg-cuda: the solve diverged at iteration " + std::to_string(iteration) + " (energy " + sci(e) +
                 ", |g| " + sci(gnorm) + ")");
  };
  check(0);
  out.initial_grad_norm = gnorm;
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);
  out.target = target;
  if (want_trace) out.trace.push_back({0, e, gnorm, timer.ms(), 0.0});

  bool have_s = false, as_stale = false;
  const auto update_matrix = [&] {
    timed(ms.assembly, [&] { hessian(x); });
    timed(ms.galerkin, [&] { update_hierarchy(); });
    if (m_s.compare_spgemm && !m_spgemm.done) compare_spgemm();
    as_stale = true;
    m_beta = 1.0;  // a fresh model is trusted again
    ++matrix_updates;
  };
  // After x changed: projection, then the new residual (and the energy when the projection moved x).
  const auto refresh = [&](bool energy_known, double e_new) {
    const Index moved = do_project ? project(x) : 0;
    e = energy_known && moved == 0 ? e_new : evaluate(x);
    refresh_gradient();
  };
  double last_alpha = 0.0;
  const auto direction = [&]() -> bool {
    ++directions;
    // One linear V-cycle of the Galerkin hierarchy from c = 0 on the residual (Theorem 4.2: an SPD operator, so
    // c·r > 0 and c is a descent direction).
    timed(ms.linear, [&] {
      const auto vcycle = [&] {
        copy(r, top.b.data(), n3);
        fill(top.x.data(), 0.0, n3);
        cycle(0, true);
        copy(top.x.data(), d, n3);
      };
      // The V-cycle is the same sequence of launches on the same buffers every time (2 × colors per sweep on every
      // level): captured once as a graph and replayed, it costs one launch. Its kernels read the matrices, not
      // copies of them, so a new matrix needs no new graph.
      if (use_graphs) {
        if (!m_vcycle_graph.ready() && !m_vcycle_graph.failed) B::capture(m_vcycle_graph, vcycle);
        if (m_vcycle_graph.ready()) {
          B::launch(m_vcycle_graph);
          ++graph_launches;
          return;
        }
      }
      vcycle();
    });
    const double cr = dot(d, r, n3);
    if (!(cr > 0.0)) {
      ++rejected;
      return false;
    }
    const double slope = -cr;
    double dAd = 0.0;
    timed(ms.model, [&] {
      multiply(top, d, Ad);
      dAd = dot(d, Ad, n3);
    });
    const double model_alpha = dAd > 0.0 ? cr / dAd : 1.0;
    double p_slope = model_alpha * slope;
    B::for_each(n3, MGCLOTH_LAMBDA(Index i) {
      p[i] = model_alpha * d[i];
      Ap[i] = model_alpha * Ad[i];
    });
    if (m_s.momentum && have_s) {
      // The model minimized over span{d, s} (s the previous step), as in solvers::NonlinearFMG.
      timed(ms.model, [&] {
        if (as_stale) {
          multiply(top, sv, As);
          as_stale = false;
        }
        const double sAs = dot(sv, As, n3), dAs = dot(d, As, n3), sr = dot(sv, r, n3);
        const double det = dAd * sAs - dAs * dAs;
        if (dAd > 0.0 && sAs > 0.0 && det > 1e-10 * dAd * sAs) {
          const double a = (cr * sAs - sr * dAs) / det, b = (dAd * sr - dAs * cr) / det;
          B::for_each(n3, MGCLOTH_LAMBDA(Index i) {
            p[i] = a * d[i] + b * sv[i];
            Ap[i] = a * Ad[i] + b * As[i];
          });
          p_slope = -(a * cr + b * sr);
        }
      });
    }
    // Where the predicted decrease is below the energy's round-off, the gradient norm decides.
    const auto accept_by_gradient = [&]() -> bool {
      add_scaled(x, 1.0, p, trial, n3);
      double gt = 0.0;
      timed(ms.gradient, [&] {
        gradient(trial, g_trial);
        gt = std::sqrt(dot(g_trial, g_trial, n3));
      });
      if (!(gt < gnorm)) return false;
      copy(p, sv, n3);
      copy(Ap, As, n3);
      have_s = true;
      copy(trial, x, n3);
      last_alpha = 1.0;
      refresh(false, 0.0);
      return true;
    };
    const bool in_round_off = -p_slope < 1e-13 * std::max(1.0, std::abs(e));
    if (in_round_off) {
      if (accept_by_gradient()) return true;
      ++rejected;
      return false;
    }
    // Backtracking from the model step scaled by what was needed last time (§4.2.3), with safeguarded quadratic
    // interpolation; trial points are made feasible first (§4.5).
    double alpha = m_beta, et = 0.0;
    bool ok = false;
    int tries = 0;
    for (; tries < m_s.max_line_search_steps; ++tries) {
      add_scaled(x, alpha, p, trial, n3);
      if (do_project) project(trial);
      et = evaluate(trial);
      if (std::isfinite(et) && et <= e + m_s.armijo * alpha * p_slope) {
        ok = true;
        break;
      }
      alpha = backtracking_step(alpha, et, e, p_slope, m_s.shrink);
    }
    if (!ok) {
      m_beta = std::max(1e-3, 0.5 * m_beta);
      if (-p_slope < 1e-9 * std::max(1.0, std::abs(e)) && accept_by_gradient()) return true;
      ++rejected;
      return false;
    }
    m_beta = std::min(1.0, tries == 0 ? 2.0 * alpha : alpha);
    const double a = alpha;
    B::for_each(n3, MGCLOTH_LAMBDA(Index i) {
      sv[i] = a * p[i];
      As[i] = a * Ap[i];
      x[i] = trial[i];
    });
    have_s = true;
    last_alpha = alpha;
    refresh(true, et);
    return true;
  };

  // solvers::steepest_descent_fallback on the device: along r = −g from the step that minimizes the model along it
  // (a secant guess from the gradient at a small probe where the model has no curvature there), backtracking; the
  // accepted point is projected as after any step.
  const auto steepest_descent = [&]() -> bool {
    const double gg = dot(g, g, n3);
    if (!(gg > 0.0)) return false;
    double alpha = 0.0;
    multiply(top, r, Ad);
    const double dAd = dot(r, Ad, n3);
    if (dAd > 0.0) alpha = gg / dAd;
    if (!(alpha > 0.0)) {
      const double probe = 1e-6 / std::sqrt(gg);
      add_scaled(x, probe, r, trial, n3);
      timed(ms.gradient, [&] { gradient(trial, g_trial); });
      const double curvature = B::sum(n3, MGCLOTH_LAMBDA(Index i) { return (g_trial[i] - g[i]) * r[i]; }) / probe;
      alpha = curvature > 0.0 ? gg / curvature : probe;
    }
    for (int tries = 0; tries < 60; ++tries, alpha *= 0.5) {
      add_scaled(x, alpha, r, trial, n3);
      const double et = evaluate(trial);
      if (std::isfinite(et) && et <= e - 1e-4 * alpha * gg) {
        if (!(et < e)) return false;
        copy(trial, x, n3);
        refresh(true, et);
        return std::isfinite(gnorm);
      }
    }
    return false;
  };

  out.status = "max_iters";
  int k = 0;
  bool done = false, force_update = false;
  const bool per_solve = m_s.matrix_update == 2;
  for (; k < stop.max_iters && !done; ++k) {
    if (gnorm <= target) {
      out.status = "converged";
      break;
    }
    if (timer.seconds() > stop.max_seconds) {
      out.status = "time_limit";
      break;
    }
    if (stop.interruptible && interrupted()) {
      out.status = "interrupted";
      break;
    }
    if (!per_solve || k == 0 || force_update) update_matrix();
    const bool fresh_matrix = !per_solve || k == 0 || force_update;
    force_update = false;
    const bool moved = direction();
    check(k + 1);
    if (gnorm <= target) {
      out.status = "converged";
      done = true;
    } else if (timer.seconds() > stop.max_seconds) {
      out.status = "time_limit";
      done = true;
    } else if (stop.interruptible && interrupted()) {
      out.status = "interrupted";
      done = true;
    }
    if (want_trace) out.trace.push_back({k + 1, e, gnorm, timer.ms(), last_alpha});
    if (!moved && !done) {
      // No direction decreased the energy (as in solvers::NonlinearFMG): a matrix too stale to help (retry with a
      // fresh one), the limiting accuracy (round-off), or a model that misleads (steepest descent, then the model's
      // Newton step).
      if (!fresh_matrix) {
        force_update = true;
        continue;
      }
      // The floor is measured on the host objective at x: a few gradients, paid only by a solve that is stuck.
      VecX x_now;
      {
        std::vector<double> xd;
        m_x.download(xd);
        from_device_order(m_layout, xd, x_now);
      }
      double floor = 0.0;
      if (physics::at_roundoff_floor(objective, x_now, gnorm, &floor)) {
        out.status = "stagnated";
        ++k;
        break;
      }
      if (steepest_descent()) {
        have_s = false;
        m_beta = 1.0;
        ++fallbacks;
        force_update = true;
        check(k + 1);
        continue;
      }
      // The Newton step of the model, solved by V-cycles to a residual of 1e-3. Where even its predicted decrease is
      // below the round-off of the energy sum, the energy cannot tell better from worse: the step is judged by the
      // gradient norm, and if that fails too the solve has stagnated.
      {
        double* c = top.x.data();
        timed(ms.linear, [&] {
          copy(r, top.b.data(), n3);
          fill(c, 0.0, n3);
          for (int it = 0; it < 30; ++it) {
            cycle(0, it == 0);
            residual(top, r, c, d);
            if (std::sqrt(dot(d, d, n3)) <= 1e-3 * gnorm) break;
          }
        });
        const double predicted = 0.5 * dot(c, r, n3);
        double magnitude = 0.0;
        for (const auto& [name, value] : objective.term_values(x_now)) magnitude += std::abs(value);
        const bool below_noise = !(predicted > 1e-13 * magnitude);
        add_scaled(x, 1.0, c, trial, n3);
        if (do_project) project(trial);
        const double et = evaluate(trial);
        double gt = 0.0;
        timed(ms.gradient, [&] {
          gradient(trial, g_trial);
          gt = std::sqrt(dot(g_trial, g_trial, n3));
        });
        if (std::isfinite(et) && (et < e || (below_noise && gt < gnorm))) {
          B::for_each(n3, MGCLOTH_LAMBDA(Index i) {
            x[i] = trial[i];
            g[i] = g_trial[i];
            r[i] = -g_trial[i];
          });
          e = et;
          gnorm = gt;
          have_s = false;
          ++fallbacks;
          force_update = true;
          check(k + 1);
          continue;
        }
        if (below_noise) {
          out.status = "stagnated";
          ++k;
          break;
        }
      }
      if (gnorm <= 1e-3 * out.initial_grad_norm) {
        out.status = "stalled";
        ++k;
        break;
      }
      fail_solve("fmg-cuda: no search direction decreased the energy in cycle " + std::to_string(k + 1) + " (|g| = " +
                 sci(gnorm) + ", relative " + sci(gnorm / out.initial_grad_norm) + ", " +
                 (floor > 0.0 ? sci(gnorm / floor, 1) : std::string("?")) +
                 "x the gradient's round-off floor); tried: a fresh Hessian, the V-cycle's correction, a "
                 "steepest-descent step, the model's Newton step");
    }
  }
  {
    std::vector<double> xd;
    m_x.download(xd);
    from_device_order(m_layout, xd, x_host);
  }
  out.iterations = k;
  out.energy = e;
  out.grad_norm = gnorm;
  if (gnorm <= target) out.status = "converged";
  out.wall_ms = timer.ms();
  const double relax = m_rows_total > 0.0 ? 1.0 - m_rows_active / m_rows_total : 0.0;
  out.counters = {{"directions", static_cast<double>(directions)},
                  {"rejected_directions", static_cast<double>(rejected)},
                  {"energy_evals", static_cast<double>(energy_evals)},
                  {"matrix_updates", static_cast<double>(matrix_updates)},
                  {"fallbacks", static_cast<double>(fallbacks)},
                  {"skipped_fraction", relax},
                  {"setup_ms", ms.setup},
                  {"assembly_ms", ms.assembly},
                  {"galerkin_ms", ms.galerkin},
                  {"linear_ms", ms.linear},
                  {"line_search_ms", ms.line_search},
                  {"gradient_ms", ms.gradient},
                  {"model_ms", ms.model},
                  {"levels", static_cast<double>(m_levels.size())},
                  {"graph_launches", static_cast<double>(graph_launches)}};
  if (m_spgemm.available) {
    out.counters.push_back({"spgemm_gather_ms", m_spgemm.gather_ms});
    out.counters.push_back({"spgemm_reference_ms", m_spgemm.reference_ms});
    out.counters.push_back({"spgemm_max_rel_diff", m_spgemm.max_rel_diff});
  }
  if (m_s.profile) {
    out.counters.push_back({"smoothing_ms", m_prof.smoothing});
    out.counters.push_back({"coarse_ms", m_prof.coarse});
    out.counters.push_back({"transfer_ms", m_prof.transfer});
    out.counters.push_back({"smoother_gbytes", m_prof.smoother_bytes * 1e-9});
    out.counters.push_back({"smoother_gb_per_s", m_prof.smoothing > 0.0 ? m_prof.smoother_bytes * 1e-6 / m_prof.smoothing : 0.0});
  }
  return out;
}

}  // namespace mgcloth::cuda
