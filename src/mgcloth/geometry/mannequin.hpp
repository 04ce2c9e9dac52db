#pragma once
#include <mgcloth/geometry/skin.hpp>

namespace mgcloth::geometry {

/// The generated mannequin's body. z is up, x forward (the walking direction), y to its left; the soles stand on
/// z = 0 in the bind pose, which has straight legs and arms hanging `arm_abduction` away from the body.
struct MannequinParams {
  double height = 1.75;       ///< m, sole to the top of the head (1.2 – 2.2)
  double build = 1.0;         ///< girth: every limb and torso radius scaled by it (0.7 slim – 1.5 heavy)
  double resolution = 0.015;  ///< m, the surface's edge length, about
  double arm_abduction = 12.0;  ///< degrees, the upper arms away from the vertical in the bind pose
};

/// The walk cycle (sagittal hip, knee, ankle and shoulder angles from normative gait curves), with a standing start.
struct WalkParams {
  double period = 1.1;     ///< s, one gait cycle (two steps)
  double stand = 0.5;      ///< s, standing still in the bind pose before the first step
  double ramp = 1.0;       ///< s, the gait angles and the speed blend in over this long
  double duration = 60.0;  ///< s, the animation's length (it stands at its last pose after it)
  double key_rate = 60.0;  ///< keyframes per second of the joint tracks
  bool forward = true;     ///< false: walks in place (a treadmill), the pelvis stays over the origin
  double arm_swing = 1.0;  ///< the arms' swing, scaled
};

/// The body's segments as the generator builds it (round cones between joints), exposed for tests.
struct MannequinInfo {
  double speed = 0.0;          ///< m/s, the walking speed once the ramp is over (0 in place)
  double stride = 0.0;         ///< m, the distance covered in one gait cycle
  double volume = 0.0;         ///< m³, enclosed by the bind-pose surface
  double min_angle = 0.0;      ///< degrees, the smallest triangle angle
};

/// An articulated mannequin of 16 joints (pelvis, abdomen, chest, head, and per side upper arm, forearm, hand,
/// thigh, shank, foot): the bind-pose surface is the zero set of a smooth union of round cones sized from the
/// Drillis–Contini segment proportions, polygonized by surface nets and relaxed onto the zero set; its linear
/// blend skin weights fall off with the distance to each segment; its joint tracks are the walk cycle sampled at
/// `walk.key_rate`. Throws InputError naming the parameter when one is out of range, Error when the surface comes
/// out non-manifold (a resolution too coarse for the thinnest limb).
SkinnedMesh make_mannequin(const MannequinParams& body, const WalkParams& walk, MannequinInfo* info = nullptr);

/// Normative sagittal joint angles in degrees at gait phase `phase` (0: right heel strike, periodic with period 1)
/// for the right side; the left side is half a cycle later. Flexion positive (dorsiflexion for the ankle).
struct GaitAngles {
  double hip, knee, ankle, shoulder, elbow;
};
GaitAngles gait_angles(double phase);

}  // namespace mgcloth::geometry
