#include <mgcloth/physics/shell_kinematics.hpp>

#include <Eigen/Geometry>

namespace mgcloth::physics {

namespace {
Mat3 cross_matrix(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}
// Slots of z: x 0, a1 3, a2 6, x,11 9, x,12 12, x,22 15; s rows 3, 4, 5 (b11, b22, b12) use x,11, x,22, x,12.
constexpr int kA1 = 3, kA2 = 6;
constexpr int kCurvatureSlot[3] = {9, 15, 12};
}  // namespace

bool shell_fundamental_forms(const Vec18& z, Eigen::Matrix<double, 6, 1>& s, ShellJacobian* J) {
  const Vec3 a1 = z.segment<3>(kA1), a2 = z.segment<3>(kA2);
  const Vec3 m = a1.cross(a2);
  const double l = m.norm();
  if (!(l > 0.0)) return false;
  const Vec3 n = m / l;
  s[0] = a1.dot(a1);
  s[1] = a2.dot(a2);
  s[2] = a1.dot(a2);
  for (int r = 0; r < 3; ++r) s[3 + r] = z.segment<3>(kCurvatureSlot[r]).dot(n);
  if (!J) return true;
  J->setZero();
  J->block<1, 3>(0, kA1) = 2.0 * a1.transpose();
  J->block<1, 3>(1, kA2) = 2.0 * a2.transpose();
  J->block<1, 3>(2, kA1) = a2.transpose();
  J->block<1, 3>(2, kA2) = a1.transpose();
  for (int r = 0; r < 3; ++r) {
    const Vec3 x = z.segment<3>(kCurvatureSlot[r]);
    // g(m) = x · m / |m|: ∇g = (I − n nᵀ) x / |m|; δm = δa1 × a2 = a1 × δa2.
    const Vec3 v = (x - x.dot(n) * n) / l;
    J->block<1, 3>(3 + r, kCurvatureSlot[r]) = n.transpose();
    J->block<1, 3>(3 + r, kA1) = a2.cross(v).transpose();
    J->block<1, 3>(3 + r, kA2) = v.cross(a1).transpose();
  }
  return true;
}

void add_fundamental_form_curvature(const Vec18& z, const Eigen::Matrix<double, 6, 1>& lambda, Mat18& Hz) {
  const Vec3 a1 = z.segment<3>(kA1), a2 = z.segment<3>(kA2);
  const Vec3 m = a1.cross(a2);
  const double l = m.norm();
  const Vec3 n = m / l;
  const Mat3 I = Mat3::Identity();
  Hz.block<3, 3>(kA1, kA1) += 2.0 * lambda[0] * I;
  Hz.block<3, 3>(kA2, kA2) += 2.0 * lambda[1] * I;
  Hz.block<3, 3>(kA1, kA2) += lambda[2] * I;
  Hz.block<3, 3>(kA2, kA1) += lambda[2] * I;
  const Mat3 dm1 = -cross_matrix(a2), dm2 = cross_matrix(a1);  // ∂m/∂a1, ∂m/∂a2
  const Mat3 P = (I - n * n.transpose()) / l;                  // ∂n/∂m
  for (int r = 0; r < 3; ++r) {
    const double w = lambda[3 + r];
    if (w == 0.0) continue;
    const int xs = kCurvatureSlot[r];
    const Vec3 x = z.segment<3>(xs);
    const double xn = x.dot(n);
    const Vec3 v = P * x;
    // ∇²g = (−x nᵀ − n xᵀ − (x·n) I + 3 (x·n) n nᵀ) / |m|²
    const Mat3 Hg = (-x * n.transpose() - n * x.transpose() - xn * I + 3.0 * xn * n * n.transpose()) / (l * l);
    const Mat3 X1 = w * P * dm1, X2 = w * P * dm2;
    Hz.block<3, 3>(xs, kA1) += X1;
    Hz.block<3, 3>(kA1, xs) += X1.transpose();
    Hz.block<3, 3>(xs, kA2) += X2;
    Hz.block<3, 3>(kA2, xs) += X2.transpose();
    Hz.block<3, 3>(kA1, kA1) += w * dm1.transpose() * Hg * dm1;
    Hz.block<3, 3>(kA2, kA2) += w * dm2.transpose() * Hg * dm2;
    // The bilinear part of m = a1 × a2: ∂²(v·m)/∂a1∂a2 = −[v]×.
    const Mat3 X12 = w * (dm1.transpose() * Hg * dm2 - cross_matrix(v));
    Hz.block<3, 3>(kA1, kA2) += X12;
    Hz.block<3, 3>(kA2, kA1) += X12.transpose();
  }
}

}  // namespace mgcloth::physics
