#include <mgcloth/physics/element_term.hpp>

#include <bit>

namespace mgcloth::physics {

std::vector<std::vector<Index>> color_elements(const std::vector<Index>& flat, int arity, Index num_vertices) {
  constexpr int kMaxColors = 63;
  const Index m = static_cast<Index>(flat.size()) / arity;
  std::vector<std::uint64_t> used(num_vertices, 0);
  std::vector<std::vector<Index>> colors;
  std::vector<Index> serial;
  for (Index e = 0; e < m; ++e) {
    std::uint64_t busy = 0;
    for (int a = 0; a < arity; ++a) busy |= used[flat[e * arity + a]];
    const int c = std::countr_one(busy);
    if (c >= kMaxColors) {
      serial.push_back(e);
      continue;
    }
    if (c >= static_cast<int>(colors.size())) colors.resize(c + 1);
    colors[c].push_back(e);
    for (int a = 0; a < arity; ++a) used[flat[e * arity + a]] |= std::uint64_t{1} << c;
  }
  // The serial group must still not be split across threads: run it as one-element "colors".
  for (Index e : serial) colors.push_back({e});
  return colors;
}

}  // namespace mgcloth::physics
