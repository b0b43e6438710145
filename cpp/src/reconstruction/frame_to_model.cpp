#include "scanalign/reconstruction/frame_to_model.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "scanalign/features/normals.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"

namespace scanalign {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr std::uint8_t kGrey = 128;  // colour of points from frames that had no colour image

void requireRigid(const Eigen::Matrix4d& T, const char* what) {
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const bool ok = T.allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-5 &&
                  R.determinant() > 0.0 && T(3, 0) == 0.0 && T(3, 1) == 0.0 && T(3, 2) == 0.0 && T(3, 3) == 1.0;
  if (!ok) throw std::invalid_argument(std::string(what) + " is not a finite rigid transform");
}

}  // namespace

const char* toString(FrameStatus status) {
  switch (status) {
    case FrameStatus::Initialized: return "initialized";
    case FrameStatus::Registered: return "registered";
    case FrameStatus::SkippedEmpty: return "skipped_empty";
    case FrameStatus::SkippedTooFewPoints: return "skipped_too_few_points";
    case FrameStatus::SkippedNoConvergence: return "skipped_not_converged";
    case FrameStatus::SkippedTooFewCorrespondences: return "skipped_too_few_correspondences";
    case FrameStatus::SkippedLowFitness: return "skipped_low_fitness";
    case FrameStatus::SkippedMotion: return "skipped_motion";
  }
  return "unknown";
}

void validate(const FrameToModelSettings& s) {
  validate(s.icp);
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(s.normal_radius)) throw std::invalid_argument("normal_radius must be a positive length (m)");
  if (!positive(s.model_voxel_size)) throw std::invalid_argument("model_voxel_size must be a positive length (m)");
  if (!(std::isfinite(s.frame_voxel_size) && s.frame_voxel_size >= 0.0))
    throw std::invalid_argument("frame_voxel_size must be >= 0 (m; 0 = off)");
  if (s.crop_box && !s.crop_box->valid()) throw std::invalid_argument("crop_box: need finite min <= max on each axis");
  if (s.min_frame_points < 1) throw std::invalid_argument("min_frame_points must be >= 1");
  if (!(s.min_fitness >= 0.0 && s.min_fitness <= 1.0)) throw std::invalid_argument("min_fitness must be in [0, 1]");
  if (!(s.max_translation_change > 0.0) || std::isnan(s.max_translation_change))
    throw std::invalid_argument("max_translation_change must be positive (m; inf = off)");
  if (!(s.max_rotation_change > 0.0) || std::isnan(s.max_rotation_change))
    throw std::invalid_argument("max_rotation_change must be positive (rad; inf = off)");
  if (s.num_threads < 0) throw std::invalid_argument("num_threads must be >= 0");
}

FrameToModel::FrameToModel(FrameToModelSettings settings) : settings_(std::move(settings)) {
  validate(settings_);
}

void FrameToModel::reset(const Eigen::Matrix4d& T_model_camera0) {
  requireRigid(T_model_camera0, "T_model_camera0");
  model_ = Model{};
  last_pose_ = T_model_camera0;
  frames_seen_ = 0;
  frames_merged_ = 0;
  tree_current_ = false;
}

PreparedFrame FrameToModel::prepare(const CloudView<float>& points, const std::uint8_t* colors) const {
  validate(settings_);
  const auto t0 = Clock::now();
  PreparedFrame out;
  out.input_points = points.size;
  // 1. Finite points inside the crop box.
  std::vector<float> kept;
  std::vector<double> attrs;  // colours as doubles for the voxel grid's averaging
  kept.reserve(3 * points.size);
  if (colors) attrs.reserve(3 * points.size);
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    const float* p = points.ptr(i);
    if (settings_.crop_box && !settings_.crop_box->contains(p)) continue;
    kept.insert(kept.end(), p, p + 3);
    if (colors)
      for (int c = 0; c < 3; ++c) attrs.push_back(colors[3 * i + c]);
  }
  // 2. Downsample.
  if (settings_.frame_voxel_size > 0.0 && !kept.empty()) {
    const VoxelGridResult g = voxelGrid(CloudView<float>(kept.data(), kept.size() / 3), settings_.frame_voxel_size,
                                        colors ? attrs.data() : nullptr, colors ? 3 : 0);
    kept.assign(g.points.begin(), g.points.end());  // double -> float
    attrs = g.attributes;
  }
  const std::size_t n = kept.size() / 3;
  if (n == 0) {
    out.seconds = since(t0);
    return out;
  }
  // 3. Normals towards the camera centre (the origin of the camera frame).
  NormalEstimationSettings ns;
  ns.radius = settings_.normal_radius;
  ns.viewpoint = Eigen::Vector3d::Zero();
  ns.num_threads = settings_.num_threads;
  std::vector<float> normals(3 * n);
  estimateNormals(CloudView<float>(kept.data(), n), ns, normals.data());
  out.points.reserve(3 * n);
  out.normals.reserve(3 * n);
  if (colors) out.colors.reserve(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const float* nn = &normals[3 * i];
    if (!(std::isfinite(nn[0]) && std::isfinite(nn[1]) && std::isfinite(nn[2]))) continue;
    out.points.insert(out.points.end(), &kept[3 * i], &kept[3 * i] + 3);
    out.normals.insert(out.normals.end(), nn, nn + 3);
    if (colors)
      for (int c = 0; c < 3; ++c)
        out.colors.push_back(static_cast<std::uint8_t>(std::clamp(std::lround(attrs[3 * i + c]), 0L, 255L)));
  }
  out.seconds = since(t0);
  return out;
}

FrameReport FrameToModel::integrate(const CloudView<float>& points, const std::uint8_t* colors,
                                    const Eigen::Matrix4d* guess) {
  const auto t0 = Clock::now();
  const PreparedFrame frame = prepare(points, colors);
  FrameReport r = integratePrepared(frame, guess);
  r.total_seconds = since(t0);
  return r;
}

FrameStatus FrameToModel::check(const IcpResult& result, const Eigen::Matrix4d& guess) const {
  if (result.status == IcpStatus::NotEnoughCorrespondences) return FrameStatus::SkippedTooFewCorrespondences;
  if (settings_.require_convergence && !result.converged) return FrameStatus::SkippedNoConvergence;
  if (!(result.fitness >= settings_.min_fitness)) return FrameStatus::SkippedLowFitness;
  // Motion relative to the guess: delta = guess^-1 * T.
  const Eigen::Matrix3d Rg = guess.topLeftCorner<3, 3>();
  const Eigen::Matrix3d R = result.T_target_source.topLeftCorner<3, 3>();
  const Eigen::Vector3d dt = result.T_target_source.topRightCorner<3, 1>() - guess.topRightCorner<3, 1>();
  const double cos_angle = std::clamp(((Rg.transpose() * R).trace() - 1.0) / 2.0, -1.0, 1.0);
  if (!result.T_target_source.allFinite() || dt.norm() > settings_.max_translation_change ||
      std::acos(cos_angle) > settings_.max_rotation_change)
    return FrameStatus::SkippedMotion;
  return FrameStatus::Registered;
}

FrameReport FrameToModel::integratePrepared(const PreparedFrame& frame, const Eigen::Matrix4d* guess_in) {
  validate(settings_);
  const auto t0 = Clock::now();
  FrameReport r;
  r.index = frames_seen_++;
  const Eigen::Matrix4d guess = guess_in ? *guess_in : last_pose_;
  requireRigid(guess, "T_model_camera_guess");
  r.T_model_camera = guess;
  r.frame_points = frame.size();
  r.prepare_seconds = frame.seconds;
  r.model_points = model_.size();
  if (frame.size() == 0) {
    r.status = FrameStatus::SkippedEmpty;
  } else if (frame.size() < static_cast<std::size_t>(settings_.min_frame_points)) {
    r.status = FrameStatus::SkippedTooFewPoints;
  } else if (!hasModel()) {
    const auto tm = Clock::now();
    r.model_points = merge(frame, guess);
    r.merge_seconds = since(tm);
    r.status = FrameStatus::Initialized;
  } else {
    const auto tr = Clock::now();
    icp_.settings() = settings_.icp;
    if (settings_.num_threads > 0) icp_.settings().num_threads = settings_.num_threads;
    if (!tree_current_ || icp_.targetSearch() != icp_.settings().search) {
      icp_.setTarget(CloudView<float>(model_.points.data(), model_.size()),
                     CloudView<float>(model_.normals.data(), model_.size()));
      tree_current_ = true;
    }
    r.icp = icp_.align(frame.view(), guess);
    r.register_seconds = since(tr);
    r.status = check(r.icp, guess);
    if (accepted(r.status)) {
      const auto tm = Clock::now();
      r.T_model_camera = r.icp.T_target_source;
      r.model_points = merge(frame, r.T_model_camera);
      r.merge_seconds = since(tm);
    }
  }
  r.total_seconds = since(t0) + frame.seconds;
  return r;
}

std::size_t FrameToModel::merge(const PreparedFrame& frame, const Eigen::Matrix4d& T) {
  requireRigid(T, "T_model_camera");
  validate(settings_);
  const std::size_t n = frame.size();
  if (frame.normals.size() != 3 * n || (!frame.colors.empty() && frame.colors.size() != 3 * n))
    throw std::invalid_argument("merge: prepared frame has inconsistent array sizes");
  if (n == 0) return model_.size();
  const std::size_t m = model_.size();
  const bool colored = !model_.colors.empty() || !frame.colors.empty();
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  // Attributes for the voxel grid: normal (3) and colour (3) per point, averaged per voxel.
  const std::size_t dim = colored ? 6 : 3;
  std::vector<float> points(3 * (m + n));
  std::vector<double> attrs(dim * (m + n));
  std::copy(model_.points.begin(), model_.points.end(), points.begin());
  for (std::size_t i = 0; i < m; ++i) {
    for (int c = 0; c < 3; ++c) attrs[dim * i + c] = model_.normals[3 * i + c];
    if (colored)
      for (int c = 0; c < 3; ++c) attrs[dim * i + 3 + c] = model_.colors.empty() ? kGrey : model_.colors[3 * i + c];
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = R * Eigen::Vector3d(frame.points[3 * i], frame.points[3 * i + 1], frame.points[3 * i + 2]) + t;
    const Eigen::Vector3d q =
        R * Eigen::Vector3d(frame.normals[3 * i], frame.normals[3 * i + 1], frame.normals[3 * i + 2]);
    const std::size_t k = m + i;
    for (int c = 0; c < 3; ++c) {
      points[3 * k + c] = static_cast<float>(p[c]);
      attrs[dim * k + c] = q[c];
    }
    if (colored)
      for (int c = 0; c < 3; ++c) attrs[dim * k + 3 + c] = frame.colors.empty() ? kGrey : frame.colors[3 * i + c];
  }
  const VoxelGridResult g =
      voxelGrid(CloudView<float>(points.data(), m + n), settings_.model_voxel_size, attrs.data(), dim);
  const std::size_t out = g.size();
  Model next;
  next.points.assign(g.points.begin(), g.points.end());
  next.normals.resize(3 * out);
  if (colored) next.colors.resize(3 * out);
  for (std::size_t i = 0; i < out; ++i) {
    const double* a = &g.attributes[dim * i];
    const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    // Opposite normals of a thin wall can cancel: such a voxel has no usable normal and
    // is left out of registration (NaN), but kept in the model.
    const double inv = len > 1e-6 ? 1.0 / len : std::nan("");
    for (int c = 0; c < 3; ++c) next.normals[3 * i + c] = static_cast<float>(a[c] * inv);
    if (colored)
      for (int c = 0; c < 3; ++c)
        next.colors[3 * i + c] = static_cast<std::uint8_t>(std::clamp(std::lround(a[3 + c]), 0L, 255L));
  }
  model_ = std::move(next);
  last_pose_ = T;  // the next frame starts from this registration (seed §3.2)
  tree_current_ = false;
  ++frames_merged_;
  return model_.size();
}

}  // namespace scanalign
