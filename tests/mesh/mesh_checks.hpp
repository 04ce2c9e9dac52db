#pragma once
// Shared helpers for the mesh tests: small hand-made meshes, temp files, exception checks.
#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <string>
#include <unistd.h>

namespace mgcloth::mesh::test {

/// A mesh lying in z = 0 with x = (u, 0).
inline TriMesh flat_mesh(const std::vector<Vec2>& points, const std::vector<Tri>& tris) {
  TriMesh m;
  m.u.resize(2, static_cast<Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) m.u.col(static_cast<Index>(i)) = points[i];
  m.x.setZero(3, m.u.cols());
  m.x.topRows<2>() = m.u;
  m.tris = tris;
  return m;
}

/// The unit square as two triangles sharing the diagonal 0-2.
inline TriMesh unit_square() { return flat_mesh({{0, 0}, {1, 0}, {1, 1}, {0, 1}}, {{0, 1, 2}, {0, 2, 3}}); }

/// A 4 x 4 vertex grid (3 x 3 cells) without its centre cell: an annulus, Euler characteristic 0.
inline TriMesh square_annulus() {
  std::vector<Vec2> p;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) p.emplace_back(i, j);
  std::vector<Tri> t;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      if (i == 1 && j == 1) continue;
      const Index a = 4 * j + i;
      t.push_back({a, a + 1, a + 5});
      t.push_back({a, a + 5, a + 4});
    }
  return flat_mesh(p, t);
}

/// Smallest interior angle of triangle t in material space, degrees.
inline double min_angle_deg(const TriMesh& m, Index t) {
  double a_min = 180.0;
  for (int k = 0; k < 3; ++k) {
    const Vec2 a = m.u.col(m.tris[t][(k + 1) % 3]) - m.u.col(m.tris[t][k]);
    const Vec2 b = m.u.col(m.tris[t][(k + 2) % 3]) - m.u.col(m.tris[t][k]);
    a_min = std::min(a_min, std::atan2(std::abs(a.x() * b.y() - a.y() * b.x()), a.dot(b)) * 180.0 / std::numbers::pi);
  }
  return a_min;
}

inline double signed_loop_area(const TriMesh& m, const std::vector<Index>& loop) {
  double a = 0.0;
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Vec2 p = m.u.col(loop[i]), q = m.u.col(loop[(i + 1) % loop.size()]);
    a += 0.5 * (p.x() * q.y() - p.y() * q.x());
  }
  return a;
}

/// Runs f and checks that it throws InputError whose message contains every one of `parts`.
inline ::testing::AssertionResult throws_input_error(const std::function<void()>& f,
                                                     const std::vector<std::string>& parts) {
  try {
    f();
  } catch (const InputError& e) {
    const std::string what = e.what();
    for (const std::string& p : parts)
      if (what.find(p) == std::string::npos)
        return ::testing::AssertionFailure() << "message \"" << what << "\" lacks \"" << p << "\"";
    if (what.find('\n') != std::string::npos)
      return ::testing::AssertionFailure() << "message \"" << what << "\" is not one line";
    return ::testing::AssertionSuccess() << what;
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "threw something else than InputError: " << e.what();
  }
  return ::testing::AssertionFailure() << "did not throw";
}

/// A fresh directory under the system temp folder, removed with its content on destruction.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    m_path = std::filesystem::temp_directory_path() /
             ("mgcloth_mesh_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(m_path);
    std::filesystem::create_directories(m_path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(m_path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  std::filesystem::path file(const std::string& name, const std::string& content) const {
    const std::filesystem::path p = m_path / name;
    std::ofstream(p, std::ios::binary) << content;
    return p;
  }
  std::filesystem::path path(const std::string& name) const { return m_path / name; }

 private:
  std::filesystem::path m_path;
};

}  // namespace mgcloth::mesh::test
