#pragma once
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace mgcloth {

using Index = int;
using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat2 = Eigen::Matrix2d;
using Mat3 = Eigen::Matrix3d;
using VecX = Eigen::VectorXd;
using MatX = Eigen::MatrixXd;
/// Vertex positions as 3 x N columns; maps onto a VecX of length 3N (xyz interleaved) without a copy.
using Mat3X = Eigen::Matrix3Xd;
using Mat2X = Eigen::Matrix2Xd;
using Tri = std::array<Index, 3>;

inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// Vertex i of a stacked 3N vector.
inline auto vertex(VecX& x, Index i) { return x.segment<3>(3 * i); }
inline auto vertex(const VecX& x, Index i) { return x.segment<3>(3 * i); }

inline Eigen::Map<Mat3X> as_columns(VecX& x) { return {x.data(), 3, x.size() / 3}; }
inline Eigen::Map<const Mat3X> as_columns(const VecX& x) { return {x.data(), 3, x.size() / 3}; }
inline Eigen::Map<const VecX> as_stacked(const Mat3X& p) { return {p.data(), p.size()}; }

}  // namespace mgcloth
