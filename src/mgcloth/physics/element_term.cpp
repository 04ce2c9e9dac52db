#include <mgcloth/physics/element_term.hpp>

#include <bit>

namespace mgcloth::physics {

namespace {

ElementColors color_chunks(const std::vector<Index>& flat, int arity, Index num_vertices, Index chunk) {
  constexpr int kMaxColors = 63;
  const Index m = static_cast<Index>(flat.size()) / arity;
  const Index chunks = (m + chunk - 1) / chunk;
  std::vector<std::uint64_t> used(num_vertices, 0);
  std::vector<std::vector<Index>> by_color;  // chunk indices per color
  std::vector<Index> serial;
  for (Index k = 0; k < chunks; ++k) {
    const Index begin = k * chunk, end = std::min(m, begin + chunk);
    std::uint64_t busy = 0;
    for (Index i = begin * arity; i < end * arity; ++i) busy |= used[flat[i]];
    const int c = std::countr_one(busy);
    if (c >= kMaxColors) {
      serial.push_back(k);
      continue;
    }
    if (c >= static_cast<int>(by_color.size())) by_color.resize(c + 1);
    by_color[c].push_back(k);
    for (Index i = begin * arity; i < end * arity; ++i) used[flat[i]] |= std::uint64_t{1} << c;
  }
  // The serial chunks must still not run concurrently: each becomes a color of its own.
  for (Index k : serial) by_color.push_back({k});
  ElementColors out;
  out.chunk_size = chunk;
  out.elements.reserve(m);
  out.chunk_offsets.push_back(0);
  out.color_offsets.push_back(0);
  for (const auto& color : by_color) {
    for (Index k : color) {
      for (Index e = k * chunk; e < std::min(m, (k + 1) * chunk); ++e) out.elements.push_back(e);
      out.chunk_offsets.push_back(static_cast<Index>(out.elements.size()));
    }
    out.color_offsets.push_back(static_cast<Index>(out.chunk_offsets.size()) - 1);
  }
  return out;
}

}  // namespace

ElementColors color_elements(const std::vector<Index>& flat, int arity, Index num_vertices, Index chunk) {
  if (chunk > 0) return color_chunks(flat, arity, num_vertices, chunk);
  constexpr Index kChunk = 64;
  constexpr Index kMaxChunkColors = 16;
  ElementColors chunked = color_chunks(flat, arity, num_vertices, kChunk);
  if (chunked.num_colors() <= kMaxChunkColors) return chunked;
  return color_chunks(flat, arity, num_vertices, 1);
}

}  // namespace mgcloth::physics
