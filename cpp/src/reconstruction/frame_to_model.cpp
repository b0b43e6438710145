#include "scanalign/reconstruction/frame_to_model.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "scanalign/common/rigid.hpp"
#include "scanalign/features/normals.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"

namespace scanalign {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr std::uint8_t kGrey = 128;  // colour of points from frames that had no colour image

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

const char* toString(MotionModel model) {
  switch (model) {
    case MotionModel::Previous: return "previous";
    case MotionModel::ConstantVelocity: return "constant_velocity";
    case MotionModel::Reference: return "reference";
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
  if (s.motion_model != MotionModel::Previous && s.motion_model != MotionModel::ConstantVelocity &&
      s.motion_model != MotionModel::Reference)
    throw std::invalid_argument("motion_model must be Previous, ConstantVelocity or Reference");
}

FrameToModel::FrameToModel(FrameToModelSettings settings) : settings_(std::move(settings)) {
  validate(settings_);
}

void FrameToModel::reset(const Eigen::Matrix4d& T_model_camera0) {
  requireRigid(T_model_camera0, "T_model_camera0");
  model_ = Model{};
  voxels_.clear();
  index_leaf_ = 0.0;
  last_pose_ = T_model_camera0;
  previous_pose_ = T_model_camera0;
  frames_seen_ = 0;
  frames_merged_ = 0;
  tree_current_ = false;
}

PreparedFrame FrameToModel::prepare(const CloudView<float>& points, const std::uint8_t* colors) const {
  validate(settings_);
  const auto t0 = Clock::now();
  PreparedFrame out;
  out.input_points = points.size;
  // 1. Finite points inside the crop box. (Each step writes into buffers sized once and
  // hands them on without copies: at 300k pixels a frame the copies showed in profiles.)
  std::vector<float> kept;
  std::vector<double> attrs;  // colours as doubles for the voxel grid's averaging
  kept.reserve(3 * points.size);
  if (colors) attrs.reserve(3 * points.size);
  // The range check in the frame grid's own arithmetic (voxelGrid's p * inv in float): the
  // kept points span fewer than 2^20 voxels, well inside the grid's 2^21.
  const double grid_leaf = settings_.frame_voxel_size > 0.0 ? settings_.frame_voxel_size : settings_.model_voxel_size;
  const float inv_grid = 1.0f / static_cast<float>(grid_leaf), range = static_cast<float>(kFrameRangeVoxels);
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    const float* p = points.ptr(i);
    if (settings_.crop_box && !settings_.crop_box->contains(p)) continue;
    if (!(std::abs(p[0] * inv_grid) < range && std::abs(p[1] * inv_grid) < range && std::abs(p[2] * inv_grid) < range)) {
      ++out.far_points;
      continue;
    }
    kept.insert(kept.end(), p, p + 3);
    if (colors)
      for (int c = 0; c < 3; ++c) attrs.push_back(colors[3 * i + c]);
  }
  std::size_t n = kept.size() / 3;
  // 2. Downsample.
  if (settings_.frame_voxel_size > 0.0 && n > 0) {
    VoxelGridResult g = voxelGrid(CloudView<float>(kept.data(), n), settings_.frame_voxel_size,
                                  colors ? attrs.data() : nullptr, colors ? 3 : 0);
    kept.assign(g.points.begin(), g.points.end());  // double -> float
    attrs = std::move(g.attributes);
    n = g.size();
  }
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
  // 4. Keep the points with a normal (compacted in place).
  if (colors) out.colors.resize(3 * n);
  std::size_t kept_n = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float* nn = &normals[3 * i];
    if (!(std::isfinite(nn[0]) && std::isfinite(nn[1]) && std::isfinite(nn[2]))) continue;
    for (int c = 0; c < 3; ++c) {
      kept[3 * kept_n + c] = kept[3 * i + c];
      normals[3 * kept_n + c] = nn[c];
      if (colors)
        out.colors[3 * kept_n + c] = static_cast<std::uint8_t>(std::clamp(std::lround(attrs[3 * i + c]), 0L, 255L));
    }
    ++kept_n;
  }
  kept.resize(3 * kept_n);
  normals.resize(3 * kept_n);
  if (colors) out.colors.resize(3 * kept_n);
  out.points = std::move(kept);
  out.normals = std::move(normals);
  out.seconds = since(t0);
  return out;
}

FrameResult FrameToModel::integrate(const CloudView<float>& points, const std::uint8_t* colors,
                                    const Eigen::Matrix4d* guess) {
  const auto t0 = Clock::now();
  const PreparedFrame frame = prepare(points, colors);
  FrameResult r = integratePrepared(frame, guess);
  r.input_points = points.size;
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

Eigen::Matrix4d FrameToModel::predictedPose() const {
  // Reference: the caller gives each frame's guess; without one, constant velocity.
  if (settings_.motion_model == MotionModel::Previous || frames_merged_ < 2) return last_pose_;
  // T_k = T_{k-1} (T_{k-2}^-1 T_{k-1}): the last camera motion, expressed in the camera
  // frame, applied once more. The rotation is re-normalised (through a unit quaternion)
  // so that rounding in the products cannot accumulate into a non-rigid guess.
  const Eigen::Isometry3d last(last_pose_), previous(previous_pose_);
  const Eigen::Isometry3d motion = previous.inverse() * last;
  Eigen::Isometry3d next = last * motion;
  next.linear() = Eigen::Quaterniond(next.rotation()).normalized().toRotationMatrix();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = next.linear();
  T.topRightCorner<3, 1>() = next.translation();
  return T;
}

FrameResult FrameToModel::integratePrepared(const PreparedFrame& frame, const Eigen::Matrix4d* guess_in) {
  validate(settings_);
  const auto t0 = Clock::now();
  FrameResult r;
  r.index = frames_seen_;  // counted at the end: a call that throws saw no frame
  const Eigen::Matrix4d guess = guess_in ? *guess_in : predictedPose();
  requireRigid(guess, "T_model_camera_guess");
  r.T_model_camera = guess;
  r.frame_points = frame.size();
  r.far_points = frame.far_points;
  r.prepare_seconds = frame.seconds;
  r.model_points = model_.size();
  std::size_t far = 0;
  if (frame.size() == 0) {
    r.status = FrameStatus::SkippedEmpty;
  } else if (frame.size() < static_cast<std::size_t>(settings_.min_frame_points)) {
    r.status = FrameStatus::SkippedTooFewPoints;
  } else if (!hasModel()) {
    const auto tm = Clock::now();
    r.model_points = merge(frame, guess, &far);
    r.merge_seconds = since(tm);
    // Every point beyond the model grid's range (a frame grid much coarser than the model's)
    // leaves no model: as an empty frame.
    r.status = hasModel() ? FrameStatus::Initialized : FrameStatus::SkippedEmpty;
  } else {
    const auto tr = Clock::now();
    icp_.settings() = settings_.icp;
    if (settings_.num_threads > 0) icp_.settings().num_threads = settings_.num_threads;
    if (!tree_current_ || icp_.targetSearch() != icp_.settings().search) {
      icp_.setTarget(CloudView<float>(model_.points.data(), model_.size()),
                     CloudView<float>(model_.normals.data(), model_.size()));
      tree_current_ = true;
    }
    r.icp = icp_.align(frame.view(), guess);  // may throw (Interrupted): nothing changed yet
    r.register_seconds = since(tr);
    r.status = check(r.icp, guess);
    if (accepted(r.status)) {
      const auto tm = Clock::now();
      r.model_points = merge(frame, r.icp.T_target_source, &far);  // all or nothing
      r.T_model_camera = r.icp.T_target_source;
      r.merge_seconds = since(tm);
    }
  }
  r.far_points += far;
  ++frames_seen_;
  r.total_seconds = since(t0) + frame.seconds;
  return r;
}

// The merge (the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3.6: the model is voxel-gridded at 1 mm after every frame).
//
// Today's definition, kept exactly: the new model is voxelGrid(model points + frame
// points in the model frame) at model_voxel_size, each model point (a voxel centroid)
// counting as ONE point, with normals averaged and re-normalised (NaN where opposite
// normals cancel) and colours averaged (grey for points from frames without colour).
// Re-gridding the whole model that way cost 25-33 ms a frame on the demo (150k model
// points against 40k new ones), growing with the model. Instead each model voxel keeps
// its index in a hash (voxels_), and a frame's points are folded into their voxels:
// O(frame points).
//
// Exactness: a centroid never leaves its voxel. The voxel coordinate floor(fl(v * inv))
// is monotone in v, the double mean of float coordinates lies between their minimum and
// maximum (the partial sums of k values <= M are <= k M, exact in double for k < 2^29),
// and rounding it to float keeps it there; so re-gridding would put every model point
// back into its own voxel, alone with the frame points that fall there. For each touched voxel the sums run
// in the re-grid's order (the model point first, then the frame's points in order), in
// double, with the same divisions and roundings, so points, colours and the normals of
// touched voxels are bit-identical to the re-grid. The one difference: the re-grid also
// re-normalises the normals of voxels no frame point fell into, which changes them by the
// float rounding of an already-unit vector (about 1e-7); here they are left as they are.
// The order differs: existing points keep their index and new voxels are appended in the
// order the frame first reaches them (the re-grid sorts by z, y, x). When a point's voxel
// coordinates do not fit the index (beyond +-2^20 voxels: +-1 km at 1 mm) or the leaf
// setting changed, the merge re-grids the whole model as before and rebuilds the index.

namespace {

constexpr std::uint64_t kSkipPoint = ~std::uint64_t{0};  // a non-finite point: no voxel

/// The model-grid voxel key of a float point (voxelGrid's arithmetic); false when a
/// coordinate is beyond the index's range.
bool modelVoxelKey(const float* p, float inv_leaf, std::uint64_t& key) {
  std::int64_t c[3];
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(p[k] * inv_leaf) < static_cast<float>(VoxelIndex::kLimit))) return false;
    c[k] = voxelCoordinate(p[k], inv_leaf);
  }
  key = VoxelIndex::pack(c[0], c[1], c[2]);
  return true;
}

}  // namespace

bool FrameToModel::buildIndex() noexcept {
  voxels_.clear();
  index_leaf_ = 0.0;
  const std::size_t m = model_.size();
  const float inv = 1.0f / static_cast<float>(settings_.model_voxel_size);
  try {
    for (std::size_t i = 0; i < m; ++i) {
      std::uint64_t key;
      bool inserted = false;
      // Two model points in one voxel cannot happen after a re-grid (see above); if it
      // did, the index could not represent the model and the merge keeps re-gridding.
      if (!modelVoxelKey(&model_.points[3 * i], inv, key) ||
          (voxels_.findOrInsert(key, static_cast<std::uint32_t>(i), inserted), !inserted)) {
        voxels_.clear();
        return false;
      }
    }
  } catch (const std::bad_alloc&) {  // the model is already committed: merges re-grid until an index fits
    voxels_.clear();
    return false;
  }
  index_leaf_ = settings_.model_voxel_size;
  return true;
}

void FrameToModel::regridMerge(const std::vector<float>& frame_points, const std::vector<double>& frame_normals,
                               const std::vector<std::uint8_t>& frame_colors, bool colored) {
  const std::size_t m = model_.size(), n = frame_points.size() / 3;
  // Attributes for the voxel grid: normal (3) and colour (3) per point, averaged per voxel.
  const std::size_t dim = colored ? 6 : 3;
  std::vector<float> points(3 * (m + n));
  std::vector<double> attrs(dim * (m + n));
  std::copy(model_.points.begin(), model_.points.end(), points.begin());
  std::copy(frame_points.begin(), frame_points.end(), points.begin() + 3 * m);
  for (std::size_t i = 0; i < m; ++i) {
    for (int c = 0; c < 3; ++c) attrs[dim * i + c] = model_.normals[3 * i + c];
    if (colored)
      for (int c = 0; c < 3; ++c) attrs[dim * i + 3 + c] = model_.colors.empty() ? kGrey : model_.colors[3 * i + c];
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = m + i;
    for (int c = 0; c < 3; ++c) attrs[dim * k + c] = frame_normals[3 * i + c];
    if (colored)
      for (int c = 0; c < 3; ++c) attrs[dim * k + 3 + c] = frame_colors.empty() ? kGrey : frame_colors[3 * i + c];
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
}

std::size_t FrameToModel::merge(const PreparedFrame& frame, const Eigen::Matrix4d& T, std::size_t* far_points) {
  // Every check and every step that can throw comes before the first change of the model,
  // the index or the poses (see the header: a failed merge changes nothing).
  requireRigid(T, "T_model_camera");
  validate(settings_);
  const std::size_t n_in = frame.size();
  if (frame.normals.size() != 3 * n_in || (!frame.colors.empty() && frame.colors.size() != 3 * n_in))
    throw std::invalid_argument("merge: prepared frame has inconsistent array sizes");
  if (far_points) *far_points = 0;
  if (n_in == 0) return model_.size();
  const std::size_t m = model_.size();
  const double leaf = settings_.model_voxel_size;
  const bool colored = !model_.colors.empty() || !frame.colors.empty();
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  // The first merged camera's position anchors the model's range (kModelRangeVoxels).
  const Eigen::Vector3d anchor = m == 0 ? t : anchor_;
  const float inv = 1.0f / static_cast<float>(leaf);
  double anchor_voxels[3];
  for (int c = 0; c < 3; ++c) {
    anchor_voxels[c] = static_cast<float>(anchor[c]) * inv;
    if (!(std::abs(anchor_voxels[c]) < 1e18))  // voxel coordinates must fit int64 (voxelGrid)
      throw std::invalid_argument("merge: T_model_camera's translation is beyond the model grid's range");
  }
  // |v - a| < 2^20 - 1 (v = p * inv in float, as voxelGrid) keeps floor(v) within 2^20 - 1
  // voxels of floor(a): the model spans fewer than voxelGrid's 2^21 voxels per axis.
  const double range = static_cast<double>(kModelRangeVoxels - 1);
  // The frame in the model frame: points rounded to float as the model stores them,
  // normals rotated in double; non-finite points are kept (the voxel grid skips them),
  // points beyond the range dropped.
  std::vector<float> points;
  std::vector<double> normals;
  std::vector<std::uint8_t> colors;
  points.reserve(3 * n_in);
  normals.reserve(3 * n_in);
  if (!frame.colors.empty()) colors.reserve(3 * n_in);
  std::size_t far = 0;
  for (std::size_t i = 0; i < n_in; ++i) {
    const Eigen::Vector3d p = R * Eigen::Vector3d(frame.points[3 * i], frame.points[3 * i + 1], frame.points[3 * i + 2]) + t;
    float q[3];
    bool inside = true;
    for (int c = 0; c < 3; ++c) {
      q[c] = static_cast<float>(p[c]);
      const double v = q[c] * inv;  // a finite q may give v = inf: far too
      if (std::isfinite(q[c]) && !(std::abs(v - anchor_voxels[c]) < range)) inside = false;
    }
    if (!inside) {
      ++far;
      continue;
    }
    const Eigen::Vector3d nn = R * Eigen::Vector3d(frame.normals[3 * i], frame.normals[3 * i + 1], frame.normals[3 * i + 2]);
    points.insert(points.end(), q, q + 3);
    normals.insert(normals.end(), {nn[0], nn[1], nn[2]});
    if (!frame.colors.empty()) colors.insert(colors.end(), &frame.colors[3 * i], &frame.colors[3 * i] + 3);
  }
  const std::size_t n = points.size() / 3;
  if (far_points) *far_points = far;
  if (n == 0) return m;  // every point beyond the range: nothing to merge, nothing changes
  // Voxel keys of the frame's points, unless the index cannot take them (an empty model's
  // index is empty, whatever leaf it was built for).
  std::vector<std::uint64_t> keys(n);
  bool incremental = m == 0 || index_leaf_ == leaf;
  for (std::size_t i = 0; i < n && incremental; ++i) {
    const float* p = &points[3 * i];
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])))
      keys[i] = kSkipPoint;  // skipped by the voxel grid too
    else
      incremental = modelVoxelKey(p, inv, keys[i]);
  }
  if (!incremental) {
    regridMerge(points, normals, colors, colored);  // builds the new model aside, then moves it in
    buildIndex();                                    // cannot throw
  } else {
    struct Touched {
      std::uint32_t index;    // model point
      std::size_t position;   // entry in voxels_
    };
    std::vector<Touched> touched;
    std::vector<double> sums;
    std::size_t stride = colored ? 10 : 7, size = m;
    try {
      if (m == 0) {
        voxels_.clear();
        index_leaf_ = leaf;
      }
      // 1. The voxel of each frame point: its model index (new voxels get the next ones) and
      //    its accumulator, numbered in order of first touch (stored in the entry's mark,
      //    offset by one). The index is memory bound: its slots are prefetched ahead.
      std::vector<std::uint32_t> accumulator(n, VoxelIndex::kNone);
      touched.reserve(n);
      voxels_.reserve(m + n);  // no growth below: positions stay valid
      auto next_index = static_cast<std::uint32_t>(m);
      constexpr std::size_t kAhead = 16;  // memory accesses in flight
      for (std::size_t i = 0; i < n; ++i) {
        if (i + kAhead < n && keys[i + kAhead] != kSkipPoint) voxels_.prefetch(keys[i + kAhead]);
        if (keys[i] == kSkipPoint) continue;
        bool inserted;
        const std::size_t position = voxels_.findOrInsert(keys[i], next_index, inserted);
        if (inserted) ++next_index;
        std::uint32_t& mark = voxels_.mark(position);
        if (mark == 0) {
          touched.push_back({voxels_.value(position), position});
          mark = static_cast<std::uint32_t>(touched.size());
        }
        accumulator[i] = mark - 1;
      }
      // 2. Sums per touched voxel, in the re-grid's order: the model point first (counting as
      //    one point), then the frame's points in their order. Layout: x y z, normal, [colour],
      //    count. A colourless model's points count as grey.
      sums.assign(stride * touched.size(), 0.0);
      for (std::size_t k = 0; k < touched.size(); ++k) {
        if (k + kAhead < touched.size() && touched[k + kAhead].index < m) {
#if defined(__GNUC__)
          const std::size_t ahead = 3 * std::size_t{touched[k + kAhead].index};
          __builtin_prefetch(&model_.points[ahead]);
          __builtin_prefetch(&model_.normals[ahead]);
          if (!model_.colors.empty()) __builtin_prefetch(&model_.colors[ahead]);
#endif
        }
        const std::size_t index = touched[k].index;
        if (index >= m) continue;
        double* a = &sums[stride * k];
        for (int c = 0; c < 3; ++c) {
          a[c] = model_.points[3 * index + c];
          a[3 + c] = model_.normals[3 * index + c];
          if (colored) a[6 + c] = model_.colors.empty() ? kGrey : model_.colors[3 * index + c];
        }
        a[stride - 1] = 1.0;
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (accumulator[i] == VoxelIndex::kNone) continue;
        double* a = &sums[stride * accumulator[i]];
        for (int c = 0; c < 3; ++c) {
          a[c] += points[3 * i + c];
          a[3 + c] += normals[3 * i + c];
          if (colored) a[6 + c] += colors.empty() ? kGrey : colors[3 * i + c];
        }
        a[stride - 1] += 1.0;
      }
      size = next_index;
      // The model's memory, so that the commit below cannot fail.
      model_.points.reserve(3 * size);
      model_.normals.reserve(3 * size);
      if (colored) model_.colors.reserve(3 * size);
    } catch (...) {
      // The index may hold the frame's new voxels (and marks): drop it; the next merge
      // re-grids the unchanged model and rebuilds it.
      voxels_.clear();
      index_leaf_ = 0.0;
      throw;
    }
    // 3. Commit (nothing below throws: the capacity is reserved): the touched voxels' new
    //    centroids, normals and colours, as the re-grid rounds them.
    if (colored && model_.colors.empty()) model_.colors.assign(3 * m, kGrey);
    model_.points.resize(3 * size);
    model_.normals.resize(3 * size);
    if (colored) model_.colors.resize(3 * size);
    for (std::size_t k = 0; k < touched.size(); ++k) {
      const std::size_t index = touched[k].index;
      const double* a = &sums[stride * k];
      const double count = a[stride - 1];
      double mean[9];
      for (std::size_t c = 0; c + 1 < stride; ++c) mean[c] = a[c] / count;
      for (int c = 0; c < 3; ++c) model_.points[3 * index + c] = static_cast<float>(mean[c]);
      const double len = std::sqrt(mean[3] * mean[3] + mean[4] * mean[4] + mean[5] * mean[5]);
      // Opposite normals of a thin wall can cancel: such a voxel has no usable normal and
      // is left out of registration (NaN), but kept in the model.
      const double inv_len = len > 1e-6 ? 1.0 / len : std::nan("");
      for (int c = 0; c < 3; ++c) model_.normals[3 * index + c] = static_cast<float>(mean[3 + c] * inv_len);
      if (colored)
        for (int c = 0; c < 3; ++c)
          model_.colors[3 * index + c] = static_cast<std::uint8_t>(std::clamp(std::lround(mean[6 + c]), 0L, 255L));
      voxels_.mark(touched[k].position) = 0;
    }
  }
  if (m == 0) anchor_ = anchor;
  previous_pose_ = frames_merged_ > 0 ? last_pose_ : T;
  last_pose_ = T;  // the next frame starts from this registration (eye-in-hand paper §3.2) or a prediction from it
  tree_current_ = false;
  ++frames_merged_;
  return model_.size();
}

}  // namespace scanalign
