// CAD pose of one object cloud. See pose_estimation.hpp.
#include "scanalign/pose/pose_estimation.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "scanalign/common/interrupt.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/features/normals.hpp"
#include "scanalign/pose/detail/pose_in_scene.hpp"
#include "scanalign/pose/pcl/coarse_aligner.hpp"
#include "scanalign/registration/alignment_fitness.hpp"
#include "scanalign/registration/icp.hpp"

namespace scanalign {

namespace detail {

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace detail

namespace {

void requirePositive(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0))
    throw std::invalid_argument(std::string(name) + " must be a finite positive distance in metres, got " +
                                std::to_string(v));
}

/// The view's cached CBD features when they were computed with these settings, else fresh ones
/// (into `fresh`).
const CbdFeatures& viewFeatures(const ModelView& view, const CbdSettings& settings, CbdFeatures& fresh) {
  if (view.cbd && sameDescriptors(view.cbd_settings, settings)) return *view.cbd;
  fresh = computeCbd(view.cloud(), settings);
  return fresh;
}

// Coarse pose of one view, or found = false with the reason.
CoarseResult coarse(const ModelView& view, const PreparedScene& scene, const PoseSettings& s,
                    const CoarseAligner& aligner) {
  CoarseResult out;
  if (s.method == CoarseMethod::External || s.method == CoarseMethod::Pcl) return aligner(view, scene);
  if (s.method == CoarseMethod::Flags) {
    const std::size_t n = scene.oriented_points.size() / 3;
    const FlagAlignmentResult r = alignFlags(view.cloud(), view.normalCloud(), CloudView<double>(scene.oriented_points.data(), n),
                                             CloudView<double>(scene.oriented_normals.data(), n), s.flags);
    out.T_scene_model = r.T_target_source;
    out.found = r.valid;
    out.message = r.message;
    return out;
  }
  const CbdAlignmentSettings c = cbdSettings(s);
  CbdFeatures fresh;
  const CbdFeatures& f = viewFeatures(view, c.cbd, fresh);
  if (f.keypoints.size() < 3) {
    out.message = "too few model keypoints";
    return out;
  }
  const CbdAlignmentResult r = alignCbd(view.cloud(), f, scene.cloud(), scene.cbd, c);
  out.T_scene_model = r.T_target_source;
  out.found = r.found;
  out.message = r.message;
  return out;
}

/// Point-to-plane ICP against the scene's oriented points: the tree is built once per scene
/// and every view is aligned to it.
Icp<double> sceneIcp(const PreparedScene& scene, const PoseSettings& s) {
  IcpSettings is;
  is.max_correspondence_distance = s.icp_distance;
  is.num_threads = s.num_threads;
  Icp<double> icp(is);
  const std::size_t n = scene.oriented_points.size() / 3;
  icp.setTarget(CloudView<double>(scene.oriented_points.data(), n), CloudView<double>(scene.oriented_normals.data(), n));
  return icp;
}

/// Fitness and coverage only tell a fit from a misfit when the inlier distance is small
/// against the part: at a quarter of the model's bounding-box diagonal or more, any placement
/// near the object scores about 1 (found=True with a pose 36 cm off was seen with 1e300 m).
/// Returns why the threshold cannot discriminate, or an empty string.
std::string undiscriminatingThreshold(const std::vector<ModelView>& views, const std::vector<int>& ids, double threshold) {
  Eigen::AlignedBox3d box;
  for (int i : ids) {
    const CloudView<double> c = views[static_cast<std::size_t>(i)].cloud();
    for (std::size_t k = 0; k < c.size; ++k)
      if (c.isFinite(k)) box.extend(Eigen::Vector3d(c.ptr(k)[0], c.ptr(k)[1], c.ptr(k)[2]));
  }
  if (box.isEmpty() || threshold < 0.25 * box.diagonal().norm()) return {};
  char message[200];
  std::snprintf(message, sizeof message,
                "inlier_threshold %g m is a quarter of the model's size or more (bounding-box diagonal %g m): "
                "fitness and coverage cannot tell a fit from a misfit", threshold, box.diagonal().norm());
  return message;
}

}  // namespace

namespace detail {

void scoreCandidate(const ModelView& view, const PreparedScene& scene, const PoseSettings& s, PoseCandidate& c,
                    const Eigen::Matrix4d& T) {
  const auto fit = alignmentFitness(view.cloud(), scene.cloud(), T, s.inlier_threshold, s.num_threads);
  const auto cov = alignmentFitness(scene.cloud(), view.cloud(), rigidInverse(T), s.inlier_threshold, s.num_threads);
  c.fitness = fit.first;
  c.inlier_rmse = fit.second;
  c.coverage = cov.first;
  c.score = c.fitness + c.coverage > 0 ? 2 * c.fitness * c.coverage / (c.fitness + c.coverage) : 0.0;
}

void refineCandidate(const ModelView& view, const PreparedScene& scene, const PoseSettings& s, Icp<double>& icp,
                     const Eigen::Matrix4d& init, PoseCandidate& c, Eigen::Matrix4d& T) {
  T = icp.align(view.cloud(), init).T_target_source;
  scoreCandidate(view, scene, s, c, T);
}

}  // namespace detail

CbdAlignmentSettings cbdSettings(const PoseSettings& s) {
  CbdAlignmentSettings c = s.cbd;
  c.ransac.inlier_threshold = s.inlier_threshold;
  if (c.cbd.num_threads == 0) c.cbd.num_threads = s.num_threads;
  if (c.ransac.num_threads == 0) c.ransac.num_threads = s.num_threads;
  return c;
}

void describeModelViews(std::vector<ModelView>& views, const PoseSettings& s) {
  validate(s);
  const CbdSettings c = cbdSettings(s).cbd;
  for (ModelView& view : views) {
    if (view.size() == 0 || (view.cbd && sameDescriptors(view.cbd_settings, c))) continue;
    checkInterrupt();
    view.cbd = computeCbd(view.cloud(), c);
    view.cbd_settings = c;
  }
}

const char* toString(CoarseMethod method) {
  switch (method) {
    case CoarseMethod::Cbd: return "cbd";
    case CoarseMethod::Flags: return "flags";
    case CoarseMethod::Pcl: return "pcl";
    case CoarseMethod::External: return "external";
  }
  return "?";
}

void validate(const PoseSettings& s) {
  requirePositive(s.inlier_threshold, "inlier_threshold");
  requirePositive(s.icp_distance, "icp_distance");
  requirePositive(s.normal_radius, "normal_radius");
  if (!(s.min_fitness >= 0 && s.min_fitness <= 1) || !(s.min_coverage >= 0 && s.min_coverage <= 1))
    throw std::invalid_argument("min_fitness and min_coverage must be in [0, 1]");
  if (s.num_threads < 0) throw std::invalid_argument("num_threads must be >= 0 (0 = all cores)");
}

PreparedScene prepareScene(const CloudView<double>& scene, const PoseSettings& s) {
  validate(s);
  PreparedScene p;
  for (std::size_t i = 0; i < scene.size; ++i)
    if (scene.isFinite(i)) p.points.insert(p.points.end(), scene.ptr(i), scene.ptr(i) + 3);
  const std::size_t n = p.points.size() / 3;
  p.normals.resize(p.points.size());
  if (n == 0) return p;
  NormalEstimationSettings ns;
  ns.radius = s.normal_radius;
  ns.num_threads = s.num_threads;
  estimateNormals(p.cloud(), ns, p.normals.data());
  for (std::size_t i = 0; i < n; ++i)
    if (std::isfinite(p.normals[3 * i]) && std::isfinite(p.normals[3 * i + 1]) && std::isfinite(p.normals[3 * i + 2])) {
      p.oriented_points.insert(p.oriented_points.end(), &p.points[3 * i], &p.points[3 * i] + 3);
      p.oriented_normals.insert(p.oriented_normals.end(), &p.normals[3 * i], &p.normals[3 * i] + 3);
    }
  if (s.method == CoarseMethod::Cbd && n >= 10) p.cbd = computeCbd(p.cloud(), cbdSettings(s).cbd);
  return p;
}

namespace detail {

std::vector<int> viewIds(const std::vector<ModelView>& views, const std::vector<int>& view_ids) {
  std::vector<int> ids = view_ids;
  if (ids.empty())
    for (std::size_t i = 0; i < views.size(); ++i) ids.push_back(static_cast<int>(i));
  for (int i : ids)
    if (i < 0 || static_cast<std::size_t>(i) >= views.size())
      throw std::invalid_argument("views: index " + std::to_string(i) + " out of range 0.." +
                                  std::to_string(static_cast<long>(views.size()) - 1));
  return ids;
}

void requireCoarseMethod(const PoseSettings& s, const CoarseAligner& aligner, const char* caller) {
  if (s.method == CoarseMethod::External && !aligner)
    throw std::invalid_argument(std::string(caller) + ": CoarseMethod::External needs a coarse aligner");
  if (s.method == CoarseMethod::Pcl) requirePclBaselines(s.pcl);
}

PoseResult poseInPreparedScene(const std::vector<ModelView>& views, const std::vector<int>& ids,
                               const PreparedScene& prepared, const PoseSettings& s, const CoarseAligner& external,
                               const PoseProgress& progress) {
  const std::string threshold_problem = undiscriminatingThreshold(views, ids, s.inlier_threshold);
  PoseResult best;
  best.method = s.method == CoarseMethod::Pcl ? pclBaselineName(s.pcl) : toString(s.method);
  const CoarseAligner aligner = s.method == CoarseMethod::Pcl ? pclCoarseAligner(s.pcl) : external;
  const std::size_t n = prepared.points.size() / 3;
  if (!threshold_problem.empty()) {
    best.message = threshold_problem;
  } else if (n < 10) {
    best.message = "scene has " + std::to_string(n) + " finite points; need at least 10";
  } else if (s.method == CoarseMethod::Cbd && prepared.cbd.keypoints.size() < 3) {
    best.message = "the object has " + std::to_string(prepared.cbd.keypoints.size()) +
                   " CBD keypoints (need 3): too few points or no curved/edge regions at radius " +
                   std::to_string(s.cbd.cbd.radius) + " m";
  } else {
    double best_score = -1;
    Icp<double> icp = sceneIcp(prepared, s);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      checkInterrupt();  // Ctrl-C between views (each view's ICP also checks per iteration)
      const ModelView& view = views[static_cast<std::size_t>(ids[k])];
      PoseCandidate c;
      c.view = ids[k];
      const auto tc = std::chrono::steady_clock::now();
      const CoarseResult cr = view.size() ? coarse(view, prepared, s, aligner) : CoarseResult{};
      best.coarse_seconds += secondsSince(tc);
      c.found = cr.found;
      if (cr.found) {
        c.coarse_fitness = alignmentFitness(view.cloud(), prepared.cloud(), cr.T_scene_model, s.inlier_threshold,
                                            s.num_threads).first;
        refineCandidate(view, prepared, s, icp, cr.T_scene_model, c, c.T_scene_model);
        if (c.score > best_score) {
          best_score = c.score;
          best.T_scene_model = c.T_scene_model;
          best.found = true;
          best.fitness = c.fitness;
          best.coverage = c.coverage;
          best.inlier_rmse = c.inlier_rmse;
          best.view = c.view;
        }
      }
      best.candidates.push_back(c);
      if (progress) progress(k + 1, ids.size());
    }
    if (!best.found) {
      best.message = "no model view aligned with " + best.method + " (coarse alignment found no consensus)";
    } else if (best.fitness < s.min_fitness || best.coverage < s.min_coverage) {
      best.found = false;
      best.message = "the best view (" + std::to_string(best.view) + ") has fitness " + std::to_string(best.fitness) +
                     " and coverage " + std::to_string(best.coverage) + ", below min_fitness " +
                     std::to_string(s.min_fitness) + " / min_coverage " + std::to_string(s.min_coverage) +
                     ": the part is not in this cloud, or only a small piece of it";
    }
  }
  return best;
}

}  // namespace detail

PoseResult estimatePose(const std::vector<ModelView>& views, const CloudView<double>& scene, const PoseSettings& s,
                        const std::vector<int>& view_ids, const CoarseAligner& aligner, const PoseProgress& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(s);
  detail::requireCoarseMethod(s, aligner, "estimatePose");
  const std::vector<int> ids = detail::viewIds(views, view_ids);
  PoseResult best = detail::poseInPreparedScene(views, ids, prepareScene(scene, s), s, aligner, progress);
  best.seconds = detail::secondsSince(t0);
  return best;
}

}  // namespace scanalign
