#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/skin.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::geometry {

namespace {

Eigen::Vector4d slerp(const Eigen::Vector4d& a, const Eigen::Vector4d& b, double w) {
  const Eigen::Quaterniond qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
  const Eigen::Quaterniond q = qa.normalized().slerp(w, qb.normalized());
  return {q.x(), q.y(), q.z(), q.w()};
}

}  // namespace

template <int N>
typename Track<N>::Value Track<N>::at(double t) const {
  // NaN lands here too (no comparison holds for it), rather than past the end of the keys.
  if (times.size() == 1 || !(t > times.front())) return values.front();
  if (t >= times.back()) return values.back();
  const auto k = static_cast<size_t>(std::upper_bound(times.begin(), times.end(), t) - times.begin()) - 1;
  const double dt = times[k + 1] - times[k];
  const double s = (t - times[k]) / dt;
  Value v;
  switch (interpolation) {
    case Interpolation::Step: return values[k];
    case Interpolation::Linear:
      if constexpr (N == 4) return slerp(values[k], values[k + 1], s);
      else return (1.0 - s) * values[k] + s * values[k + 1];
    case Interpolation::CubicSpline: {
      // glTF 2.0 Appendix C: p(s) = (2s³−3s²+1) v_k + (s³−2s²+s) dt·b_k + (−2s³+3s²) v_k+1 + (s³−s²) dt·a_k+1.
      const double s2 = s * s, s3 = s2 * s;
      v = (2 * s3 - 3 * s2 + 1) * values[k] + (s3 - 2 * s2 + s) * dt * out_tangents[k] +
          (-2 * s3 + 3 * s2) * values[k + 1] + (s3 - s2) * dt * in_tangents[k + 1];
      if constexpr (N == 4) v.normalize();
      return v;
    }
  }
  return values[k];
}

template struct Track<3>;
template struct Track<4>;

Eigen::Affine3d JointTransform::matrix() const {
  Eigen::Affine3d m = Eigen::Affine3d::Identity();
  m.translate(translation);
  m.rotate(rotation.normalized());
  m.scale(scale);
  return m;
}

double SkinnedMesh::duration() const {
  double d = 0.0;
  for (const auto& tr : tracks) {
    if (!tr.translation.empty()) d = std::max(d, tr.translation.times.back());
    if (!tr.rotation.empty()) d = std::max(d, tr.rotation.times.back());
    if (!tr.scale.empty()) d = std::max(d, tr.scale.times.back());
  }
  return d;
}

std::vector<JointTransform> SkinnedMesh::local_at(double t) const {
  std::vector<JointTransform> local = rest_local;
  for (size_t j = 0; j < tracks.size() && j < local.size(); ++j) {
    const auto& tr = tracks[j];
    if (!tr.translation.empty()) local[j].translation = tr.translation.at(t);
    if (!tr.rotation.empty()) {
      const Eigen::Vector4d q = tr.rotation.at(t);
      local[j].rotation = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized();
    }
    if (!tr.scale.empty()) local[j].scale = tr.scale.at(t);
  }
  return local;
}

std::vector<Eigen::Affine3d> SkinnedMesh::world_at(double t) const {
  const auto local = local_at(t);
  std::vector<Eigen::Affine3d> world(local.size());
  for (size_t j = 0; j < local.size(); ++j) {
    world[j] = parent[j] < 0 ? local[j].matrix() : world[static_cast<size_t>(parent[j])] * local[j].matrix();
  }
  return world;
}

Mat3X SkinnedMesh::at(double t) const {
  const auto world = world_at(t);
  std::vector<Eigen::Matrix<double, 3, 4>> skin(world.size());
  for (size_t j = 0; j < world.size(); ++j) skin[j] = (placement * world[j] * inverse_bind[j]).matrix().topRows<3>();
  Mat3X out(3, rest.cols());
  for (Index v = 0; v < rest.cols(); ++v) {
    const Eigen::Vector4d p(rest(0, v), rest(1, v), rest(2, v), 1.0);
    Vec3 sum = Vec3::Zero();
    double total = 0.0;
    for (int k = 0; k < 4; ++k) {
      const double w = weights(k, v);
      if (w != 0.0) sum += w * (skin[static_cast<size_t>(joints(k, v))] * p);
      total += w;
    }
    // validate() lets the weights sum to 1 within 1e-3; an error that far from a joint is millimetres.
    out.col(v) = sum / total;
  }
  return out;
}

void SkinnedMesh::validate(const std::string& what) const {
  const auto nj = joint_names.size();
  const auto nv = static_cast<size_t>(rest.cols());
  if (nj == 0) throw_error<InputError>("{}: the skin has no joints", what);
  if (parent.size() != nj || rest_local.size() != nj || inverse_bind.size() != nj || tracks.size() != nj) {
    throw_error<InputError>("{}: the skin's joint arrays disagree in size ({} joints)", what, nj);
  }
  if (static_cast<size_t>(joints.cols()) != nv || static_cast<size_t>(weights.cols()) != nv) {
    throw_error<InputError>("{}: {} vertices but {} joint and {} weight entries", what, nv, joints.cols(), weights.cols());
  }
  if (!rest.allFinite()) throw_error<InputError>("{}: a vertex position is not finite", what);
  if (!placement.matrix().allFinite()) throw_error<InputError>("{}: the placement is not finite", what);
  for (const auto& t : tris) {
    for (Index i : t) {
      if (i < 0 || static_cast<size_t>(i) >= nv) throw_error<InputError>("{}: a triangle names vertex {} of {}", what, i, nv);
    }
  }
  for (size_t j = 0; j < nj; ++j) {
    if (parent[j] >= static_cast<int>(j) || parent[j] < -1) {
      throw_error<InputError>("{}: joint {} (\"{}\") has parent {}, which does not come before it", what, j,
                              joint_names[j], parent[j]);
    }
    if (!inverse_bind[j].matrix().allFinite()) throw_error<InputError>("{}: joint \"{}\": inverse bind matrix not finite", what, joint_names[j]);
    const auto& r = rest_local[j];
    if (!r.translation.allFinite() || !r.scale.allFinite() || !r.rotation.coeffs().allFinite() ||
        !(r.rotation.norm() > 1e-12)) {
      throw_error<InputError>("{}: joint \"{}\": its rest transform is not finite or has a zero rotation", what,
                              joint_names[j]);
    }
    auto check = [&](const auto& tr, const char* path) {
      if (tr.values.size() != tr.times.size()) {
        throw_error<InputError>("{}: joint \"{}\": {} track has {} keys but {} values", what, joint_names[j], path,
                                tr.times.size(), tr.values.size());
      }
      if (tr.interpolation == Interpolation::CubicSpline &&
          (tr.in_tangents.size() != tr.times.size() || tr.out_tangents.size() != tr.times.size())) {
        throw_error<InputError>("{}: joint \"{}\": {} track lacks its spline tangents", what, joint_names[j], path);
      }
      for (size_t k = 0; k < tr.times.size(); ++k) {
        const bool zero_rotation = tr.values[k].size() == 4 && !(tr.values[k].norm() > 1e-12);
        const bool bad_tangent = tr.interpolation == Interpolation::CubicSpline &&
                                 (!tr.in_tangents[k].allFinite() || !tr.out_tangents[k].allFinite());
        if (zero_rotation || bad_tangent) {
          throw_error<InputError>("{}: joint \"{}\": {} key {} is a zero rotation or has a tangent that is not finite",
                                  what, joint_names[j], path, k);
        }
        if (!std::isfinite(tr.times[k]) || !tr.values[k].allFinite() || (k > 0 && !(tr.times[k] > tr.times[k - 1]))) {
          throw_error<InputError>("{}: joint \"{}\": {} key {} has a time or value that is not finite or not after "
                                  "the one before",
                                  what, joint_names[j], path, k);
        }
      }
    };
    check(tracks[j].translation, "translation");
    check(tracks[j].rotation, "rotation");
    check(tracks[j].scale, "scale");
  }
  for (size_t v = 0; v < nv; ++v) {
    double sum = 0.0;
    for (int k = 0; k < 4; ++k) {
      const double w = weights(k, static_cast<Index>(v));
      const int j = joints(k, static_cast<Index>(v));
      if (!std::isfinite(w) || w < 0.0) throw_error<InputError>("{}: vertex {}: weight {} is negative or not finite", what, v, w);
      if (w > 0.0 && (j < 0 || static_cast<size_t>(j) >= nj)) {
        throw_error<InputError>("{}: vertex {}: joint index {} of {} joints", what, v, j, nj);
      }
      sum += w;
    }
    if (std::abs(sum - 1.0) > 1e-3) throw_error<InputError>("{}: vertex {}: weights sum to {}, not 1", what, v, sum);
  }
}

}  // namespace mgcloth::geometry
