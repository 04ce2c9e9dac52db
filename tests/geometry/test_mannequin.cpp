#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/mannequin.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <map>

namespace mgcloth::geometry {
namespace {

double enclosed_volume(const Mat3X& x, const std::vector<Tri>& tris) {
  double v = 0.0;
  for (const auto& t : tris) v += x.col(t[0]).dot(x.col(t[1]).cross(x.col(t[2]))) / 6.0;
  return v;
}

/// Every undirected edge in exactly two triangles, used once in each direction.
bool closed_and_oriented(const std::vector<Tri>& tris) {
  std::map<std::pair<Index, Index>, int> directed;
  for (const auto& t : tris) {
    for (int c = 0; c < 3; ++c) ++directed[{t[c], t[(c + 1) % 3]}];
  }
  for (const auto& [e, n] : directed) {
    const auto back = directed.find({e.second, e.first});
    if (n != 1 || back == directed.end() || back->second != 1) return false;
  }
  return true;
}

struct Built {
  SkinnedMesh skin;
  MannequinInfo info;
};

const Built& default_body() {
  static const Built b = [] {
    Built out;
    WalkParams walk;
    walk.duration = 4.0;
    out.skin = make_mannequin(MannequinParams{}, walk, &out.info);
    return out;
  }();
  return b;
}

TEST(Mannequin, ClosedOutwardSurfaceOfHumanSize) {
  const auto& [skin, info] = default_body();
  EXPECT_TRUE(closed_and_oriented(skin.tris));
  const Mat3X x = skin.at(0.0);
  EXPECT_NEAR(x.row(2).maxCoeff(), 1.75, 0.02);  // sole to crown
  EXPECT_NEAR(x.row(2).minCoeff(), 0.0, 0.003);
  // A 1.75 m adult of average build has about 65–80 kg at ~1010 kg/m³: 0.06–0.08 m³ (outward normals: > 0).
  const double vol = enclosed_volume(x, skin.tris);
  EXPECT_NEAR(vol, info.volume, 1e-9);
  EXPECT_GT(vol, 0.055);
  EXPECT_LT(vol, 0.085);
  // Surface area of a 1.75 m, ~70 kg adult by Du Bois' formula: about 1.85 m²; a mannequin without fingers,
  // ears or nose is somewhat smaller.
  double area = 0.0;
  for (const auto& t : skin.tris) area += 0.5 * (x.col(t[1]) - x.col(t[0])).cross(x.col(t[2]) - x.col(t[0])).norm();
  EXPECT_GT(area, 1.4);
  EXPECT_LT(area, 2.0);
  EXPECT_GT(info.min_angle, 5.0);
  // Arm span from the bind pose: the hands hang beside, not inside, the thighs.
  EXPECT_GT(x.row(1).maxCoeff(), 0.3);
}

TEST(Mannequin, BuildAndHeightScaleTheBody) {
  MannequinParams slim;
  slim.build = 0.8;
  slim.resolution = 0.02;
  MannequinParams tall = slim;
  tall.build = 1.0;
  tall.height = 1.9;
  MannequinInfo a, b;
  WalkParams walk;
  walk.duration = 0.0;
  make_mannequin(slim, walk, &a);
  make_mannequin(tall, walk, &b);
  EXPECT_LT(a.volume, 0.8 * default_body().info.volume);
  // Volume grows with the cube of the height at equal build.
  EXPECT_NEAR(b.volume / default_body().info.volume, std::pow(1.9 / 1.75, 3), 0.06);
}

TEST(Mannequin, ResolutionSetsTheEdgeLength) {
  for (const double h : {0.02, 0.01}) {
    MannequinParams m;
    m.resolution = h;
    WalkParams walk;
    walk.duration = 0.0;
    const SkinnedMesh s = make_mannequin(m, walk);
    EXPECT_TRUE(closed_and_oriented(s.tris));
    double sum = 0.0;
    int n = 0;
    for (const auto& t : s.tris) {
      for (int c = 0; c < 3; ++c) {
        sum += (s.rest.col(t[c]) - s.rest.col(t[(c + 1) % 3])).norm();
        ++n;
      }
    }
    EXPECT_NEAR(sum / n, h, 0.35 * h);
  }
}

TEST(Mannequin, WeightsAreConvexAndFollowTheNearestLimb) {
  const auto& skin = default_body().skin;
  for (Index v = 0; v < skin.num_vertices(); ++v) {
    EXPECT_NEAR(skin.weights.col(v).sum(), 1.0, 1e-12);
    EXPECT_GE(skin.weights.col(v).minCoeff(), 0.0);
  }
  // The crown follows the head alone; the lowest vertex a foot.
  Index top, bottom;
  skin.rest.row(2).maxCoeff(&top);
  skin.rest.row(2).minCoeff(&bottom);
  EXPECT_EQ(skin.joint_names[static_cast<size_t>(skin.joints(0, top))], "head");
  EXPECT_NEAR(skin.weights(0, top), 1.0, 1e-6);
  EXPECT_EQ(skin.joint_names[static_cast<size_t>(skin.joints(0, bottom))].substr(0, 4), "foot");
}

// Published normative gait: thigh ~+25° from the vertical at heel strike, peak knee flexion ~60° in swing, ankle
// plantarflexion ~−15° just after toe-off; stride length ~0.75–0.85 of the height at natural cadence
// (Winter 2009; Perry & Burnfield 2010), walking speed 1.2–1.5 m/s for a 1.75 m adult.
TEST(Mannequin, GaitMatchesNormativeWalking) {
  double knee_max = 0, ankle_min = 0, hip_min = 90, hip_max = -90;
  for (int i = 0; i < 1000; ++i) {
    const GaitAngles a = gait_angles(i / 1000.0);
    knee_max = std::max(knee_max, a.knee);
    ankle_min = std::min(ankle_min, a.ankle);
    hip_min = std::min(hip_min, a.hip);
    hip_max = std::max(hip_max, a.hip);
  }
  EXPECT_NEAR(gait_angles(0.0).hip, 25.0, 1e-9);
  EXPECT_NEAR(knee_max, 62.0, 2.0);
  EXPECT_NEAR(ankle_min, -16.0, 1.5);
  EXPECT_NEAR(hip_max - hip_min, 48.0, 4.0);
  // Periodic and smooth across the cycle's end.
  EXPECT_NEAR(gait_angles(0.9999).knee, gait_angles(1e-4).knee, 0.1);
  const auto& info = default_body().info;
  EXPECT_GT(info.stride, 0.65 * 1.75);
  EXPECT_LT(info.stride, 0.95 * 1.75);
  EXPECT_GT(info.speed, 1.0);
  EXPECT_LT(info.speed, 1.6);
}

TEST(Mannequin, WalksOnTheGroundWithoutTearingItsSkin) {
  const auto& skin = default_body().skin;
  const Mat3X rest = skin.at(0.0);
  double min_ratio = 1e9, max_ratio = 0;
  double lowest = 1e9, highest_low = -1e9;
  for (double t = 0.0; t <= 4.0; t += 0.05) {
    const Mat3X x = skin.at(t);
    const double low = x.row(2).minCoeff();
    lowest = std::min(lowest, low);
    highest_low = std::max(highest_low, low);
    for (const auto& tr : skin.tris) {
      for (int c = 0; c < 3; ++c) {
        const double l0 = (rest.col(tr[c]) - rest.col(tr[(c + 1) % 3])).norm();
        const double l = (x.col(tr[c]) - x.col(tr[(c + 1) % 3])).norm();
        min_ratio = std::min(min_ratio, l / l0);
        max_ratio = std::max(max_ratio, l / l0);
      }
    }
  }
  // The lowest point of the body touches the ground at every time (soles on z = 0 within the mesh's rounding).
  EXPECT_GT(lowest, -0.01);
  EXPECT_LT(highest_low, 0.01);
  // Linear blend skinning shortens the inside of a bent knee; no edge collapses or doubles.
  EXPECT_GT(min_ratio, 0.3);
  EXPECT_LT(max_ratio, 2.2);
  // It moves forward: after 4 s (0.5 s standing, a 1 s ramp) the pelvis is metres ahead.
  const Mat3X end = skin.at(4.0);
  EXPECT_GT(end.row(0).mean() - rest.row(0).mean(), 2.5);
  // Standing still before the ramp.
  EXPECT_LT((skin.at(0.4) - rest).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Mannequin, InPlaceStaysOverTheOrigin) {
  MannequinParams m;
  m.resolution = 0.025;
  WalkParams walk;
  walk.forward = false;
  walk.duration = 3.0;
  MannequinInfo info;
  const SkinnedMesh s = make_mannequin(m, walk, &info);
  EXPECT_EQ(info.speed, 0.0);
  for (double t = 0; t <= 3.0; t += 0.1) EXPECT_LT(std::abs(s.at(t).row(0).mean()), 0.1);
}

TEST(Mannequin, RefusesParametersOutOfRange) {
  MannequinParams m;
  m.height = 0.3;
  EXPECT_THROW(make_mannequin(m, WalkParams{}), InputError);
  m = MannequinParams{};
  m.build = std::nan("");
  EXPECT_THROW(make_mannequin(m, WalkParams{}), InputError);
  WalkParams w;
  w.period = -1.0;
  try {
    make_mannequin(MannequinParams{}, w);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("walk.period"), std::string::npos);
  }
}

}  // namespace
}  // namespace mgcloth::geometry
