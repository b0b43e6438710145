// Which known part lies in each object cluster, and its pose. See part_identification.hpp.
#include "scanalign/pose/part_identification.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "scanalign/common/rigid.hpp"
#include "scanalign/pose/detail/part_surface.hpp"
#include "scanalign/pose/detail/pose_in_scene.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"
#include "scanalign/registration/alignment_fitness.hpp"
#include "scanalign/registration/icp.hpp"

namespace scanalign {

using detail::secondsSince;

const char* toString(DetectionStatus status) {
  switch (status) {
    case DetectionStatus::Found: return "found";
    case DetectionStatus::NotFound: return "not_found";
    case DetectionStatus::Ambiguous: return "ambiguous";
  }
  return "?";
}

void validate(const FindPartsSettings& s) {
  if (s.max_objects < 1) throw std::invalid_argument("max_objects must be >= 1");
  validate(s.pose);
  if (!(std::isfinite(s.ambiguity_rmse_ratio) && (s.ambiguity_rmse_ratio == 0 || s.ambiguity_rmse_ratio >= 1)))
    throw std::invalid_argument("ambiguity_rmse_ratio must be 0 (no RMSE test) or a finite ratio >= 1, got " +
                                std::to_string(s.ambiguity_rmse_ratio));
  if (!(s.ambiguity_margin >= 0 && s.ambiguity_margin < 1))
    throw std::invalid_argument("ambiguity_margin must be in [0, 1), got " + std::to_string(s.ambiguity_margin));
  if (!(std::isfinite(s.same_pose_angle) && s.same_pose_angle >= 0 && s.same_pose_angle <= M_PI))
    throw std::invalid_argument("same_pose_angle must be in [0, pi] rad, got " + std::to_string(s.same_pose_angle));
  if (!(std::isfinite(s.same_pose_distance) && s.same_pose_distance >= 0))
    throw std::invalid_argument("same_pose_distance must be a finite distance >= 0 in metres, got " +
                                std::to_string(s.same_pose_distance));
  if (!(std::isfinite(s.max_size_ratio) && s.max_size_ratio >= 0) || !(std::isfinite(s.min_size_ratio) && s.min_size_ratio >= 0))
    throw std::invalid_argument("max_size_ratio and min_size_ratio must be finite and >= 0 (0 = no bound)");
  if (!(std::isfinite(s.polish_distance) && s.polish_distance >= 0))
    throw std::invalid_argument("polish_distance must be a finite distance >= 0 in metres (0 = no polish)");
  if (!(s.score_tie >= 0 && s.score_tie <= 1)) throw std::invalid_argument("score_tie must be in [0, 1]");
  if (!(std::isfinite(s.cbd_radius_fraction) && s.cbd_radius_fraction >= 0 && s.cbd_radius_fraction <= 1))
    throw std::invalid_argument("cbd_radius_fraction must be in [0, 1] (0: the fixed CBD radius)");
  if (!(s.min_surface_coverage >= 0 && s.min_surface_coverage <= 1))
    throw std::invalid_argument("min_surface_coverage must be in [0, 1] (0: no check)");
  if (s.max_instances < 1) throw std::invalid_argument("max_instances must be >= 1 (1: one part per cluster)");
  if (!(s.min_instance_score >= 0 && s.min_instance_score <= 1))
    throw std::invalid_argument("min_instance_score must be in [0, 1]");
  if (!(s.max_table_penetration >= 0))
    throw std::invalid_argument("max_table_penetration must be a distance >= 0 in metres (infinity: no check)");
  if (!(std::isfinite(s.voxel_size) && s.voxel_size >= 0))
    throw std::invalid_argument("voxel_size must be a finite length >= 0 in metres (0 = every point), got " +
                                std::to_string(s.voxel_size));
}

namespace detail {

double principalExtent(const CloudView<double>& c) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (std::size_t i = 0; i < c.size; ++i)
    if (c.isFinite(i)) mean += Eigen::Vector3d(c.ptr(i)), ++n;
  if (n < 2) return 0;
  mean /= static_cast<double>(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < c.size; ++i)
    if (c.isFinite(i)) {
      const Eigen::Vector3d d = Eigen::Vector3d(c.ptr(i)) - mean;
      cov += d * d.transpose();
    }
  const Eigen::Matrix3d axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < c.size; ++i)
    if (c.isFinite(i)) {
      const Eigen::Vector3d q = axes.transpose() * Eigen::Vector3d(c.ptr(i));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  return (hi - lo).maxCoeff();
}

}  // namespace detail

namespace {

using detail::PartSize;
using detail::PartSurface;
using detail::principalExtent;
using detail::polishOnSurface;

PartSize partSize(const std::vector<ModelView>& views, const std::vector<int>& ids) {
  PartSize out;
  std::vector<double> all;
  for (const ModelView& v : views) all.insert(all.end(), v.points.begin(), v.points.end());
  out.whole = principalExtent(CloudView<double>(all.data(), all.size() / 3));
  out.smallest_view = INFINITY;
  for (int i : ids) {
    const ModelView& v = views[static_cast<std::size_t>(i)];
    if (v.size() >= 2) out.smallest_view = std::min(out.smallest_view, principalExtent(v.cloud()));
  }
  if (!std::isfinite(out.smallest_view)) out.smallest_view = 0;
  return out;
}

/// Why part `p` cannot be the cluster (the size gate), or an empty string.
std::string sizeMismatch(double cluster, const PartSize& part, const FindPartsSettings& s) {
  char m[200] = "";
  if (s.max_size_ratio > 0 && cluster > s.max_size_ratio * part.whole)
    std::snprintf(m, sizeof m, "skipped: the cluster (%.4g m) is more than %g x the part's size (%.4g m)", cluster,
                  s.max_size_ratio, part.whole);
  else if (s.min_size_ratio > 0 && cluster < s.min_size_ratio * part.smallest_view)
    std::snprintf(m, sizeof m, "skipped: the cluster (%.4g m) is less than %g x the part's smallest view (%.4g m)",
                  cluster, s.min_size_ratio, part.smallest_view);
  return m;
}

double bestScore(const PoseResult& r) {
  double best = 0;
  for (const PoseCandidate& c : r.candidates)
    if (c.found) best = std::max(best, c.score);
  return best;
}

/// A candidate refined again by point-to-plane ICP with correspondences within
/// polish_distance and a tight convergence test: the first ICP (icp_distance, PCL's 1e-8
/// stop) can halt while a weakly constrained rotation (a hexagon's about its axis, seen on
/// two faces) still slides.
void polish(const ModelView& view, const PreparedScene& scene, const FindPartsSettings& s, PoseCandidate& c) {
  PoseSettings ps = s.pose;
  ps.icp_distance = s.polish_distance;
  IcpSettings is;
  is.max_correspondence_distance = s.polish_distance;
  is.num_threads = ps.num_threads;
  is.max_iterations = 100;
  is.transformation_epsilon = 1e-14;
  Icp<double> icp(is);
  const std::size_t n = scene.oriented_points.size() / 3;
  icp.setTarget(CloudView<double>(scene.oriented_points.data(), n), CloudView<double>(scene.oriented_normals.data(), n));
  const Eigen::Matrix4d init = c.T_scene_model;
  detail::refineCandidate(view, scene, ps, icp, init, c, c.T_scene_model);
}

}  // namespace

namespace detail {

PartSurface partSurface(const std::vector<ModelView>& views, std::size_t max_points) {
  std::size_t total = 0;
  for (const ModelView& v : views) total += v.size();
  const std::size_t stride = std::max<std::size_t>(1, total / std::max<std::size_t>(1, max_points));
  PartSurface out;
  std::size_t k = 0;
  for (const ModelView& v : views)
    for (std::size_t i = 0; i < v.size(); ++i, ++k)
      if (k % stride == 0) {
        out.points.insert(out.points.end(), v.points.begin() + 3 * i, v.points.begin() + 3 * i + 3);
        out.normals.insert(out.normals.end(), v.normals.begin() + 3 * i, v.normals.begin() + 3 * i + 3);
      }
  return out;
}

Eigen::Matrix4d polishOnSurface(const Eigen::Matrix4d& T_scene_model, const PartSurface& surface,
                                const CloudView<double>& scene, const FindPartsSettings& s) {
  IcpSettings is;
  is.max_correspondence_distance = s.polish_distance;
  is.num_threads = s.pose.num_threads;
  is.max_iterations = 100;
  is.transformation_epsilon = 1e-14;
  Icp<double> icp(is);
  icp.setTarget(surface.cloud(), surface.normalCloud());
  const IcpResult r = icp.align(scene, rigidInverse(T_scene_model));
  if (!r.T_target_source.allFinite() || r.correspondence_count < 6) return T_scene_model;
  const Eigen::Matrix4d T = rigidInverse(r.T_target_source);
  const auto moved = symmetricPoseError(Eigen::Isometry3d(T_scene_model), Eigen::Isometry3d(T), PartSymmetry{});
  return moved.first <= s.same_pose_angle && moved.second <= s.same_pose_distance ? T : T_scene_model;
}

}  // namespace detail

namespace {

/// How far the part's surface at pose T reaches below the table plane, m (<= 0: not below).
double tablePenetration(const PartSurface& surface, const Eigen::Matrix4d& T, const PlaneModel& plane) {
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  double lowest = std::numeric_limits<double>::infinity();
  const CloudView<double> c = surface.cloud();
  for (std::size_t i = 0; i < c.size; ++i)
    lowest = std::min(lowest, plane.signedDistance(R * Eigen::Vector3d(c.ptr(i)) + t));
  return -lowest;
}

/// Drops the candidates that put the part through the table (max_table_penetration) and
/// picks r's best pose again among the rest.
void dropPosesThroughTable(PoseResult& r, const PartSurface& surface, const PlaneModel& plane,
                           const FindPartsSettings& s) {
  int dropped = 0;
  double deepest = 0;
  for (PoseCandidate& c : r.candidates) {
    if (!c.found) continue;
    const double depth = tablePenetration(surface, c.T_scene_model, plane);
    if (depth > s.max_table_penetration) {
      c.found = false;
      c.score = 0;
      deepest = std::max(deepest, depth);
      ++dropped;
    }
  }
  if (dropped == 0) return;
  const PoseCandidate* best = nullptr;
  for (const PoseCandidate& c : r.candidates)
    if (c.found && (!best || c.score > best->score)) best = &c;
  char m[200];
  if (!best) {
    r.found = false;
    r.view = -1;
    std::snprintf(m, sizeof m, "every aligned pose (%d) puts the part through the table (up to %.1f mm below it)",
                  dropped, deepest * 1e3);
    r.message = m;
    return;
  }
  r.T_scene_model = best->T_scene_model;
  r.fitness = best->fitness;
  r.coverage = best->coverage;
  r.inlier_rmse = best->inlier_rmse;
  r.view = best->view;
  r.found = r.fitness >= s.pose.min_fitness && r.coverage >= s.pose.min_coverage;
  std::snprintf(m, sizeof m, "%d pose(s) through the table dropped (up to %.1f mm below it)%s", dropped,
                deepest * 1e3, r.found ? "" : "; the best other pose is below min_fitness / min_coverage");
  r.message = m;
}

/// The share of the cluster's points within polish_distance of a part's merged surface at pose T
/// (the cluster-side coverage). For a partial model cloud it is no gate (what the scan never saw
/// is missing whatever the pose), but between two poses of the same model it tells which one
/// leaves fewer points unexplained.
double clusterAgreement(const Eigen::Matrix4d& T_scene_model, const PartSurface& surface, const PreparedScene& scene,
                        const FindPartsSettings& s) {
  return alignmentFitness(scene.cloud(), surface.cloud(), rigidInverse(T_scene_model), s.polish_distance,
                          s.pose.num_threads)
      .first;
}

/// The surface-coverage gate (FindPartsSettings::min_surface_coverage); false, with the message
/// set, when the detection fails it. A mesh model is the part's whole surface: every cluster
/// point must lie on it. A model cloud may be a partial scan (isCloudModel): cluster points
/// on the side it never saw prove nothing, so the test turns round: the points of the view
/// that matched (what the model shows from the sensor's side) must lie on the cluster.
bool surfaceCoverageHolds(PartDetection& d, const std::vector<ModelView>& views, const PartSurface& surface,
                          const PreparedScene& scene, int best, const FindPartsSettings& s) {
  const double reach = s.polish_distance;
  const bool cloud_model = isCloudModel(views);
  const int v = d.pose.view;
  char m[320];
  if (cloud_model && v >= 0 && static_cast<std::size_t>(v) < views.size() && views[static_cast<std::size_t>(v)].size() > 0) {
    d.surface_coverage = alignmentFitness(views[static_cast<std::size_t>(v)].cloud(), scene.cloud(),
                                          d.pose.T_scene_model, reach, s.pose.num_threads).first;
    std::snprintf(m, sizeof m, "only %.1f %% of the points part %d's model cloud shows from the matching view (%d) lie "
                  "within %.1f mm of the cluster at its best pose (min_surface_coverage %.1f %%): another part, a "
                  "part of another size, or a model scanned from another side",
                  100 * d.surface_coverage, best, v, 1e3 * reach, 100 * s.min_surface_coverage);
  } else {
    d.surface_coverage = alignmentFitness(scene.cloud(), surface.cloud(), rigidInverse(d.pose.T_scene_model), reach,
                                          s.pose.num_threads).first;
    std::snprintf(m, sizeof m, "only %.1f %% of the cluster's points lie within %.1f mm of part %d's surface at its best "
                  "pose (min_surface_coverage %.1f %%): another part, or a part of another size",
                  100 * d.surface_coverage, 1e3 * reach, best, 100 * s.min_surface_coverage);
  }
  if (d.surface_coverage >= s.min_surface_coverage) return true;
  d.message = m;
  d.pose.found = false;
  return false;
}

/// Best part, its status and the runner-up: the best-scoring pose of every other part, and
/// every candidate of the best part whose pose its symmetry does not make the same.
void judge(PartDetection& d, const std::vector<bool>& tried, const std::vector<PartSymmetry>& sym,
           const std::vector<std::vector<ModelView>>& models, const std::vector<PartSurface>& surfaces,
           const PreparedScene& scene, const FindPartsSettings& s) {
  int best = -1;
  for (std::size_t p = 0; p < d.parts.size(); ++p) {
    if (!tried[p]) continue;
    const auto b = static_cast<std::size_t>(best);
    if (best < 0 || (d.parts[p].found && !d.parts[b].found) ||
        (d.parts[p].found == d.parts[b].found && bestScore(d.parts[p]) > bestScore(d.parts[b])))
      best = static_cast<int>(p);
  }
  if (best < 0) {
    d.message = "no part was tried: every part's size differs from the cluster's (see parts[i].message)";
    return;
  }
  d.part = best;
  d.pose = d.parts[static_cast<std::size_t>(best)];
  d.score = bestScore(d.pose);
  if (!d.pose.found) {
    d.message = d.pose.message;
    return;
  }
  // Scores saturate near 1 when the noise is far below inlier_threshold: among the
  // candidates within score_tie of the best, the smallest inlier RMSE is the tightest fit.
  // A model cloud's one view may fit a pose slid along the part better than the true pose's
  // view fits (a partial scan constrains less: the bracket slid 6 mm along its plates scored
  // 0.980 against 0.956): its candidates are ranked by the harmonic mean of the score and the
  // share of the cluster on the model's merged surface (clusterAgreement: 0.904 against 0.999).
  const auto& views_best = models[static_cast<std::size_t>(best)];
  const PartSurface& surface_best = surfaces[static_cast<std::size_t>(best)];
  const bool cloud_model = isCloudModel(views_best) && s.polish_distance > 0;
  auto rank = [&](const PoseCandidate& c) {
    if (!cloud_model) return c.score;
    const double a = clusterAgreement(c.T_scene_model, surface_best, scene, s);
    return a + c.score > 0 ? 2 * a * c.score / (a + c.score) : 0.0;
  };
  double top = -1;
  std::vector<double> ranks(d.pose.candidates.size(), -1.0);
  for (std::size_t k = 0; k < ranks.size(); ++k)
    if (d.pose.candidates[k].found && (cloud_model || d.pose.candidates[k].score >= d.score - s.score_tie))
      top = std::max(top, ranks[k] = rank(d.pose.candidates[k]));
  const PoseCandidate* pick = nullptr;
  for (std::size_t k = 0; k < ranks.size(); ++k) {
    const PoseCandidate& c = d.pose.candidates[k];
    const bool tie = cloud_model ? ranks[k] >= top - s.score_tie : c.score >= d.score - s.score_tie;
    if (c.found && tie && (!pick || c.inlier_rmse < pick->inlier_rmse)) pick = &c;
  }
  if (pick && s.polish_distance > 0) {
    PoseCandidate c = *pick;
    polish(models[static_cast<std::size_t>(best)][static_cast<std::size_t>(c.view)], scene, s, c);
    if (c.score >= pick->score - s.score_tie) pick = &(d.pose.candidates.emplace_back(c));  // kept as a candidate
  }
  if (pick) {
    d.pose.T_scene_model = pick->T_scene_model;
    d.pose.fitness = pick->fitness;
    d.pose.coverage = pick->coverage;
    d.pose.inlier_rmse = pick->inlier_rmse;
    d.pose.view = pick->view;
    d.score = pick->score;
  }
  const bool surface_polish = s.surface_polish && s.polish_distance > 0;
  if (surface_polish && d.pose.view >= 0) {  // reported as a candidate of its view, scored there
    PoseCandidate c = pick ? *pick : PoseCandidate{};
    c.view = d.pose.view;
    c.found = true;
    c.T_scene_model = polishOnSurface(d.pose.T_scene_model, surfaces[static_cast<std::size_t>(best)], scene.cloud(), s);
    detail::scoreCandidate(models[static_cast<std::size_t>(best)][static_cast<std::size_t>(c.view)], scene, s.pose, c,
                           c.T_scene_model);
    d.pose.candidates.push_back(c);
    d.pose.T_scene_model = c.T_scene_model;
    d.pose.fitness = c.fitness;
    d.pose.coverage = c.coverage;
    d.pose.inlier_rmse = c.inlier_rmse;
    d.score = c.score;
  }
  const Eigen::Isometry3d T_best(d.pose.T_scene_model);
  const PartSymmetry& S = sym[static_cast<std::size_t>(best)];
  for (std::size_t p = 0; p < d.parts.size(); ++p)
    for (const PoseCandidate& candidate : d.parts[p].candidates) {
      if (!candidate.found || candidate.score <= d.runner_up_score) continue;
      PoseCandidate c = candidate;
      const bool same_part = static_cast<int>(p) == best;
      auto err = symmetricPoseError(T_best, Eigen::Isometry3d(c.T_scene_model), S);
      auto same = [&] { return same_part && err.first <= s.same_pose_angle && err.second <= s.same_pose_distance; };
      if (same()) continue;
      // A candidate of the best part that would make the detection ambiguous may only have
      // stopped short of the best pose: polished, it counts only if it stays apart.
      if (same_part && s.polish_distance > 0 && c.score >= (1 - s.ambiguity_margin) * d.score) {
        polish(models[p][static_cast<std::size_t>(c.view)], scene, s, c);
        if (surface_polish) c.T_scene_model = detail::polishOnSurface(c.T_scene_model, surfaces[p], scene.cloud(), s);
        err = symmetricPoseError(T_best, Eigen::Isometry3d(c.T_scene_model), S);
        if (same() || c.score <= d.runner_up_score) continue;
      }
      if (s.ambiguity_rmse_ratio > 0 && c.inlier_rmse > s.ambiguity_rmse_ratio * d.pose.inlier_rmse) continue;
      // A model cloud: a pose that leaves clearly more of the cluster off the model is no rival.
      if (same_part && cloud_model &&
          clusterAgreement(c.T_scene_model, surface_best, scene, s) <
              clusterAgreement(d.pose.T_scene_model, surface_best, scene, s) - s.ambiguity_margin)
        continue;
      d.runner_up_part = static_cast<int>(p);
      d.runner_up_score = c.score;
      d.runner_up_angle = err.first;
      d.runner_up_distance = err.second;
    }
  if (s.polish_distance > 0 && !surfaceCoverageHolds(d, models[static_cast<std::size_t>(best)],
                                                      surfaces[static_cast<std::size_t>(best)], scene, best, s))
    return;  // status stays NotFound
  d.status = DetectionStatus::Found;
  if (d.runner_up_part >= 0 && d.runner_up_score >= (1 - s.ambiguity_margin) * d.score) {
    d.status = DetectionStatus::Ambiguous;
    char m[240];
    std::snprintf(m, sizeof m, "part %d (score %.4f) is within %g of the best (part %d, score %.4f), %.2f deg / %.2f mm away",
                  d.runner_up_part, d.runner_up_score, s.ambiguity_margin, best, d.score, d.runner_up_angle * 180 / M_PI,
                  d.runner_up_distance * 1e3);
    d.message = m;
  }
}

}  // namespace

PoseSettings partPoseSettings(const std::vector<ModelView>& views, const FindPartsSettings& s) {
  PoseSettings out = s.pose;
  if (s.cbd_radius_fraction > 0)
    out.cbd.cbd.radius = std::max(s.pose.cbd.cbd.radius, s.cbd_radius_fraction * partSize(views, {}).whole);
  return out;
}

FindPartsResult findParts(const std::vector<std::vector<ModelView>>& models, const std::vector<PartSymmetry>& symmetries,
                          const CloudView<double>& scene, const FindPartsSettings& s, const std::vector<int>& view_ids,
                          const CoarseAligner& aligner, const PoseProgress& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(s);
  if (models.empty()) throw std::invalid_argument("models: need at least one part");
  if (!symmetries.empty() && symmetries.size() != models.size())
    throw std::invalid_argument("symmetries: " + std::to_string(symmetries.size()) + " given for " +
                                std::to_string(models.size()) + " parts (one per part, or none)");
  detail::requireCoarseMethod(s.pose, aligner, "findParts");
  std::vector<PartSymmetry> sym = symmetries;
  sym.resize(models.size());  // no symmetry by default
  for (const PartSymmetry& p : sym) p.validate();
  std::vector<std::vector<int>> ids;
  std::vector<PartSize> sizes;
  for (std::size_t p = 0; p < models.size(); ++p) {
    if (models[p].empty()) throw std::invalid_argument("models: part " + std::to_string(p) + " has no views");
    ids.push_back(detail::viewIds(models[p], view_ids));
    sizes.push_back(partSize(models[p], ids.back()));
  }
  // Every view of each part merged (not only the ids tried): the whole surface, for the table
  // check (a few thousand points bound its lowest point to well under a millimetre) and the
  // final polish.
  std::vector<PoseSettings> part_settings;
  for (const auto& views : models) part_settings.push_back(partPoseSettings(views, s));
  std::vector<PartSurface> coarse_surfaces, surfaces;
  for (const auto& views : models) {
    coarse_surfaces.push_back(detail::partSurface(views, 4000));
    surfaces.push_back(detail::partSurface(views, 40000));
  }
  FindPartsResult out;
  out.table = segmentTable(scene, s.table);
  if (out.table.objects.size() > s.max_objects) out.table.objects.resize(s.max_objects);
  const detail::PartCatalogue catalogue{models, sym, ids, part_settings, sizes, coarse_surfaces, surfaces};
  const bool table_check = out.table.success() && std::isfinite(s.max_table_penetration);
  const PlaneModel* plane = table_check ? &out.table.plane.model : nullptr;
  std::vector<double> object;
  for (std::size_t k = 0; k < out.table.objects.size(); ++k) {
    const auto& idx = out.table.objects[k];
    const auto tc = std::chrono::steady_clock::now();
    PartDetection d;
    d.cluster = static_cast<int>(k);
    d.indices = idx;
    object.clear();
    for (std::uint32_t i : idx) object.insert(object.end(), scene.ptr(i), scene.ptr(i) + 3);
    if (s.voxel_size > 0) object = voxelGrid(CloudView<double>(object.data(), idx.size()), s.voxel_size).points;
    const CloudView<double> cloud(object.data(), object.size() / 3);
    detail::PartPoses poses = detail::poseEveryPart(catalogue, cloud, plane, s, true, aligner, progress);
    d.size = poses.size;
    d.parts = std::move(poses.parts);
    judge(d, poses.tried, sym, models, surfaces, poses.prepared, s);
    d.seconds = secondsSince(tc);
    std::vector<PartDetection> instances;
    if (s.max_instances > 1) instances = detail::findInstances(catalogue, scene, idx, d, plane, s, aligner, progress);
    if (d.status != DetectionStatus::NotFound || instances.empty()) out.detections.push_back(std::move(d));
    for (PartDetection& e : instances) out.detections.push_back(std::move(e));
  }
  out.seconds = secondsSince(t0);
  return out;
}

namespace detail {

PartPoses poseEveryPart(const PartCatalogue& parts, const CloudView<double>& cloud, const PlaneModel* plane,
                        const FindPartsSettings& s, bool upper_size_gate, const CoarseAligner& aligner,
                        const PoseProgress& progress) {
  PartPoses out;
  out.size = principalExtent(cloud);
  // Normals once per cloud; CBD features once per distinct part radius.
  PoseSettings base = s.pose;
  base.cbd.cbd.radius = parts.settings.front().cbd.cbd.radius;
  out.prepared = prepareScene(cloud, base);
  std::map<double, PreparedScene> by_radius;
  FindPartsSettings gate = s;
  if (!upper_size_gate) gate.max_size_ratio = 0;
  for (std::size_t p = 0; p < parts.models.size(); ++p) {
    const auto tp = std::chrono::steady_clock::now();
    PoseResult r;
    r.message = sizeMismatch(out.size, parts.sizes[p], gate);
    out.tried.push_back(r.message.empty());
    const PoseSettings& ps = parts.settings[p];
    if (out.tried.back()) {
      const double radius = ps.cbd.cbd.radius;
      if (radius != base.cbd.cbd.radius && ps.method == CoarseMethod::Cbd && !by_radius.count(radius)) {
        PreparedScene other = out.prepared;
        other.cbd = computeCbd(other.cloud(), cbdSettings(ps).cbd);
        by_radius.emplace(radius, std::move(other));
      }
      const PreparedScene& scene_p = radius == base.cbd.cbd.radius || ps.method != CoarseMethod::Cbd
                                         ? out.prepared : by_radius.at(radius);
      r = poseInPreparedScene(parts.models[p], parts.view_ids[p], scene_p, ps, aligner, progress);
      if (plane) dropPosesThroughTable(r, parts.coarse_surfaces[p], *plane, s);
    }
    r.seconds = secondsSince(tp);
    out.parts.push_back(std::move(r));
  }
  return out;
}

}  // namespace detail

}  // namespace scanalign
