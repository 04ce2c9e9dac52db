#pragma once
// Functions marked MGCLOTH_HOST_DEVICE compile for the CPU and, under nvcc, for the GPU: the element math that the
// CPU terms and the CUDA kernels share (ARCHITECTURE.md). They take plain arrays, never Eigen types, so that the
// device code needs nothing but this header.
#include <cmath>

#if defined(__CUDACC__)
#define MGCLOTH_HOST_DEVICE __host__ __device__
#else
#define MGCLOTH_HOST_DEVICE
#endif

namespace mgcloth::hd {

/// A 3-vector of plain doubles for host/device element math.
struct V3 {
  double x, y, z;
};
MGCLOTH_HOST_DEVICE inline V3 load3(const double* p) { return {p[0], p[1], p[2]}; }
MGCLOTH_HOST_DEVICE inline void store3(double* p, const V3& v) {
  p[0] = v.x;
  p[1] = v.y;
  p[2] = v.z;
}
MGCLOTH_HOST_DEVICE inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
MGCLOTH_HOST_DEVICE inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
MGCLOTH_HOST_DEVICE inline V3 operator-(const V3& a) { return {-a.x, -a.y, -a.z}; }
MGCLOTH_HOST_DEVICE inline V3 operator*(double s, const V3& a) { return {s * a.x, s * a.y, s * a.z}; }
MGCLOTH_HOST_DEVICE inline double dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
MGCLOTH_HOST_DEVICE inline V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
MGCLOTH_HOST_DEVICE inline double norm(const V3& a) { return std::sqrt(dot(a, a)); }
MGCLOTH_HOST_DEVICE inline double comp(const V3& a, int i) { return i == 0 ? a.x : i == 1 ? a.y : a.z; }

/// out (row-major 3x3) = s · I.
MGCLOTH_HOST_DEVICE inline void set_scaled_identity(double* out, double s) {
  for (int i = 0; i < 9; ++i) out[i] = (i % 4 == 0) ? s : 0.0;
}

/// Inverse of a row-major 3x3 matrix by the adjugate; false (inv untouched) when the determinant is not a finite
/// nonzero number.
MGCLOTH_HOST_DEVICE inline bool invert3(const double* a, double* inv) {
  const double c00 = a[4] * a[8] - a[5] * a[7], c01 = a[5] * a[6] - a[3] * a[8], c02 = a[3] * a[7] - a[4] * a[6];
  const double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
  if (!(det != 0.0) || !std::isfinite(det)) return false;
  const double r = 1.0 / det;
  inv[0] = c00 * r;
  inv[1] = (a[2] * a[7] - a[1] * a[8]) * r;
  inv[2] = (a[1] * a[5] - a[2] * a[4]) * r;
  inv[3] = c01 * r;
  inv[4] = (a[0] * a[8] - a[2] * a[6]) * r;
  inv[5] = (a[2] * a[3] - a[0] * a[5]) * r;
  inv[6] = c02 * r;
  inv[7] = (a[1] * a[6] - a[0] * a[7]) * r;
  inv[8] = (a[0] * a[4] - a[1] * a[3]) * r;
  return true;
}

}  // namespace mgcloth::hd
