#pragma once
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/psd.hpp>
#include <mgcloth/physics/term.hpp>

namespace mgcloth::physics {

/// Elements grouped for race-free parallel assembly: chunks of consecutive elements, colored so that no two chunks
/// of one color share a vertex. A thread assembles whole chunks, so one color writes every vertex and every block
/// from one thread only. Chunks rather than single elements: one color's chunks then cover a fraction of the
/// mesh and touch that fraction of the matrix, where an element-wise coloring touches every row of the matrix in
/// every color and its assembly is memory-bound (the whole Hessian 2.4x slower at 120K vertices, bench/RESULTS.md).
struct ElementColors {
  std::vector<Index> elements;       ///< every element once, grouped by color, then by chunk
  std::vector<Index> chunk_offsets;  ///< chunk k is elements[chunk_offsets[k], chunk_offsets[k + 1])
  std::vector<Index> color_offsets;  ///< color c is chunks [color_offsets[c], color_offsets[c + 1])
  Index num_colors() const { return static_cast<Index>(color_offsets.size()) - 1; }
  Index chunk_size = 0;              ///< elements per chunk (the last chunk may be shorter)
};

/// Greedy coloring of chunks of `chunk` consecutive elements in element order (deterministic; the summation order
/// per block is fixed by color, then element order within the one chunk that writes it, so results are bitwise
/// reproducible whatever the thread count). Chunks that find no free color among the first 63 go to one-chunk
/// colors of their own. With chunk = 0 the size is chosen: chunks of 64 when that needs at most 16 colors (a mesh
/// whose element order is spatially coherent), single elements otherwise.
ElementColors color_elements(const std::vector<Index>& flat_vertices, int arity, Index num_vertices, Index chunk = 0);

/// f(e) for every element, color by color, each chunk of a color on one thread in element order: the race-free
/// and bitwise deterministic loop of every assembler.
template <class F>
void for_each_colored(const ElementColors& colors, F&& f) {
  for (Index c = 0; c < colors.num_colors(); ++c) {
    const Index first = colors.color_offsets[c];
    parallel_for(colors.color_offsets[c + 1] - first, [&](Index k) {
      for (Index i = colors.chunk_offsets[first + k]; i < colors.chunk_offsets[first + k + 1]; ++i) f(colors.elements[i]);
    }, 2);
  }
}

/// The shared parallel assembler: a term with elements of K vertices implements element(), the value, gradient
/// and Hessian of one element from its K local positions; value/gradient/Hessian assembly is written once here.
template <int K>
class ElementTerm : public Term {
 public:
  static constexpr int N = 3 * K;
  using Local = Eigen::Matrix<double, N, 1>;
  using LocalHessian = Eigen::Matrix<double, N, N>;
  using Element = std::array<Index, K>;

  Index num_elements() const { return static_cast<Index>(m_elements.size()); }
  const std::vector<Element>& elements() const { return m_elements; }

  /// Energy of element e; fills g and H when they are non-null.
  virtual double element(Index e, const Local& xe, Local* g, LocalHessian* H) const = 0;
  /// A positive semi-definite approximation of element e's Hessian: by default the exact Hessian with its negative
  /// eigenvalues clamped. Terms with a closed-form PSD part override it: an eigendecomposition per element costs
  /// 10-35x the exact Hessian and would dominate every solver's assembly (bench/RESULTS.md, mgcloth_bench_assembly).
  virtual void element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const {
    Local g;
    element(e, xe, &g, &H);
    project_psd(H);
  }

  Local gather(const VecX& x, Index e) const {
    Local xe;
    for (int a = 0; a < K; ++a) xe.template segment<3>(3 * a) = x.template segment<3>(3 * m_elements[e][a]);
    return xe;
  }

  double value(const VecX& x) const override {
    return parallel_sum(num_elements(), [&](Index e) { return element(e, gather(x, e), nullptr, nullptr); });
  }

  void add_gradient(const VecX& x, VecX& g) const override {
    for_each_colored([&](Index e) {
      Local ge = Local::Zero();
      element(e, gather(x, e), &ge, nullptr);
      for (int a = 0; a < K; ++a) g.template segment<3>(3 * m_elements[e][a]) += ge.template segment<3>(3 * a);
    });
  }

  /// One colored pass for both; each element's energy is kept and summed afterwards in value()'s order, so the
  /// result is value()'s to the bit.
  double value_and_gradient(const VecX& x, VecX& g) const override {
    std::vector<double> energy(static_cast<size_t>(num_elements()));
    for_each_colored([&](Index e) {
      Local ge = Local::Zero();
      energy[static_cast<size_t>(e)] = element(e, gather(x, e), &ge, nullptr);
      for (int a = 0; a < K; ++a) g.template segment<3>(3 * m_elements[e][a]) += ge.template segment<3>(3 * a);
    });
    return parallel_sum(num_elements(), [&](Index e) { return energy[static_cast<size_t>(e)]; });
  }

  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project) const override {
    for_each_colored([&](Index e) {
        LocalHessian He = LocalHessian::Zero();
        if (project) {
          element_psd_hessian(e, gather(x, e), He);
        } else {
          Local ge;
          element(e, gather(x, e), &ge, &He);
        }
        // A point term away from its obstacle adds nothing: skipping it spares touching the diagonal block, a cache
        // miss per vertex in a matrix of a few hundred MB.
        if constexpr (K == 1)
          if (He.isZero(0.0)) return;
        const Index* slots = &m_block_slots[static_cast<size_t>(e) * K * K];
        for (int a = 0; a < K; ++a)
          for (int b = 0; b < K; ++b) H.block(slots[a * K + b]) += He.template block<3, 3>(3 * a, 3 * b);
    });
  }

  const ElementColors& colors() const { return m_colors; }

  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override {
    for (const auto& el : m_elements)
      for (int a = 0; a < K; ++a)
        for (int b = 0; b < K; ++b)
          if (el[a] <= el[b]) pairs.emplace_back(el[a], el[b]);
  }

  void bind(const linalg::BlockMatrix3& pattern) override {
    m_block_slots.resize(m_elements.size() * K * K);
    for (size_t e = 0; e < m_elements.size(); ++e)
      for (int a = 0; a < K; ++a)
        for (int b = 0; b < K; ++b) m_block_slots[e * K * K + a * K + b] = pattern.find(m_elements[e][a], m_elements[e][b]);
  }

 protected:
  /// Sets the stencils (once); colors them for the race-free parallel assembly.
  void set_elements(std::vector<Element> elements, Index num_vertices) {
    m_elements = std::move(elements);
    std::vector<Index> flat(m_elements.size() * K);
    for (size_t e = 0; e < m_elements.size(); ++e)
      for (int a = 0; a < K; ++a) flat[e * K + a] = m_elements[e][a];
    m_colors = color_elements(flat, K, num_vertices);
  }

 private:
  template <class F>
  void for_each_colored(F&& f) const {
    physics::for_each_colored(m_colors, std::forward<F>(f));
  }

  std::vector<Element> m_elements;
  ElementColors m_colors;
  std::vector<Index> m_block_slots;
};

}  // namespace mgcloth::physics
