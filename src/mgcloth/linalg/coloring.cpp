#include <mgcloth/linalg/coloring.hpp>

namespace mgcloth::linalg {

std::vector<std::vector<Index>> color_rows(const BlockMatrix3& A) {
  const Index n = A.rows();
  std::vector<Index> color(n, -1);
  std::vector<Index> stamp;  // stamp[c] == r: color c is taken by a neighbour of row r
  std::vector<std::vector<Index>> groups;
  const auto& off = A.row_offsets();
  const auto& cols = A.col_indices();
  for (Index r = 0; r < n; ++r) {
    for (Index k = off[r]; k < off[r + 1]; ++k) {
      const Index c = color[cols[k]];
      if (c >= 0) stamp[c] = r;
    }
    Index c = 0;
    while (c < static_cast<Index>(stamp.size()) && stamp[c] == r) ++c;
    if (c == static_cast<Index>(stamp.size())) {
      stamp.push_back(-1);
      groups.emplace_back();
    }
    color[r] = c;
    groups[c].push_back(r);
  }
  return groups;
}

}  // namespace mgcloth::linalg
