// Several instances of the parts in one object cluster: touching parts, a part leaning on
// another, a heap of copies. See part_identification.hpp (FindPartsSettings::max_instances)
// and detail/part_surface.hpp.
//
// Hypotheses come from every view of every part (each view's CBD RANSAC consensus, refined by
// ICP: Kleppe, PhD thesis, NTNU 2018, ch. 7) on the points no accepted instance explains yet.
// Each is verified against the cluster in the spirit of the global hypotheses verification of
// Aldoma, Tombari, Di Stefano and Vincze (ECCV 2012): the model must be seen (fitness), the
// scene points it explains count for it, and two kinds of scene points count against it:
// points inside the placed part (a solid cannot have a surface seen inside it) and points
// that continue its surface smoothly past its border (their "clutter" term: a block placed on
// the corner of a larger box fits the box's faces, but the faces go on where the block ends).
// Accepted greedily, best first, each scene point explained by at most one instance; then
// the points left are clustered again and the next round runs on each piece.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>

#include <Eigen/Geometry>

#include "scanalign/common/rigid.hpp"
#include "scanalign/features/normals.hpp"
#include "scanalign/pose/detail/part_surface.hpp"
#include "scanalign/pose/detail/pose_in_scene.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"
#include "scanalign/registration/alignment_fitness.hpp"
#include "scanalign/registration/kdtree.hpp"
#include "scanalign/segmentation/euclidean_clusters.hpp"

namespace scanalign::detail {

namespace {

/// A part's merged surface (model frame) with a k-d tree over it.
struct SurfaceIndex {
  const PartSurface* surface = nullptr;
  LeftBalancedKdTree<double> tree;
  explicit SurfaceIndex(const PartSurface& s) : surface(&s), tree(s.cloud()) {}
};

/// The cluster: its points (scene frame), their unit normals (NaN where undefined) and which
/// are still unexplained.
struct Cluster {
  std::vector<double> points, normals;
  std::vector<std::uint32_t> scene_index;  ///< position in the scene, per point
  std::vector<char> free;                  ///< not claimed by an accepted instance
  CloudView<double> cloud() const { return {points.data(), points.size() / 3}; }
  Eigen::Map<const Eigen::Vector3d> point(std::size_t i) const { return Eigen::Map<const Eigen::Vector3d>(&points[3 * i]); }
  Eigen::Map<const Eigen::Vector3d> normal(std::size_t i) const { return Eigen::Map<const Eigen::Vector3d>(&normals[3 * i]); }
};

/// How one placed hypothesis explains the cluster's free points.
struct Verdict {
  int part = -1;
  std::size_t candidate = 0;  ///< in the round's PoseResult of that part
  Eigen::Matrix4d T_scene_model = Eigen::Matrix4d::Identity();
  double fitness = 0;                  ///< the view's points within inlier_threshold of the cluster
  std::vector<std::uint32_t> claimed;  ///< free cluster points on the placed surface
  std::vector<std::uint32_t> covered;  ///< free points within inlier_threshold of it, whatever their normal
  std::size_t intrusions = 0;          ///< free points inside the placed part
  std::size_t continuations = 0;       ///< free points continuing its surface past its border
  double agreement() const {
    const std::size_t n = claimed.size() + intrusions + continuations;
    return n ? static_cast<double>(claimed.size()) / static_cast<double>(n) : 0.0;
  }
  double score() const {
    const double a = agreement();
    return a + fitness > 0 ? 2 * a * fitness / (a + fitness) : 0.0;
  }
};

// A scene point within inlier_threshold of the placed surface is explained by it when its
// normal agrees within 45 degrees (a neighbour's face touching the part at a right angle is
// not the part). A point near the part (its surface within kContinuationReach inlier
// thresholds) that is not explained continues the part's surface when it lies within
// inlier_threshold of the tangent plane of an explained point within that reach, with a normal
// within 25 degrees of that point's: the scene's surface goes on where the part ends.
constexpr double kClaimCos = 0.70710678118654752;
constexpr double kContinuationCos = 0.90630778703665;
constexpr double kContinuationReach = 3.0;

Verdict verify(const ModelView& view, const SurfaceIndex& index, const Eigen::Matrix4d& T, const Cluster& cluster,
               const FindPartsSettings& s) {
  Verdict v;
  v.T_scene_model = T;
  const double thr = s.pose.inlier_threshold, reach = kContinuationReach * thr;
  v.fitness = alignmentFitness(view.cloud(), cluster.cloud(), T, thr, s.pose.num_threads).first;
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  const PartSurface& surf = *index.surface;
  std::vector<std::uint32_t> near;  // neither explained nor inside: may continue the surface
  for (std::size_t i = 0; i < cluster.free.size(); ++i) {
    if (!cluster.free[i]) continue;
    const Eigen::Vector3d q = R.transpose() * (cluster.point(i) - t);
    const auto nn = index.tree.nearest(q.data(), reach * reach, LeftBalancedKdTree<double>::kMaxStack);
    if (!nn.found()) continue;
    const std::uint32_t j = index.tree.node(nn.node).index();
    const Eigen::Vector3d s_pt(&surf.points[3 * j]), s_n(&surf.normals[3 * j]);
    const Eigen::Vector3d n_q = R.transpose() * cluster.normal(i);
    const double cos_normals = n_q.allFinite() ? std::abs(n_q.dot(s_n)) : 1.0;
    if (nn.squared_distance <= thr * thr) v.covered.push_back(static_cast<std::uint32_t>(i));
    if (nn.squared_distance <= thr * thr && cos_normals >= kClaimCos)
      v.claimed.push_back(static_cast<std::uint32_t>(i));
    else if (nn.squared_distance > thr * thr && (q - s_pt).dot(s_n) < -thr)
      ++v.intrusions;
    else if (cluster.normal(i).allFinite())
      near.push_back(static_cast<std::uint32_t>(i));
  }
  if (v.claimed.empty() || near.empty()) return v;
  std::vector<double> own;
  for (std::uint32_t i : v.claimed) own.insert(own.end(), &cluster.points[3 * i], &cluster.points[3 * i] + 3);
  const LeftBalancedKdTree<double> tree(CloudView<double>(own.data(), own.size() / 3));
  for (std::uint32_t i : near) {
    const auto nn = tree.nearest(&cluster.points[3 * i], reach * reach, LeftBalancedKdTree<double>::kMaxStack);
    if (!nn.found()) continue;
    const std::uint32_t c = v.claimed[tree.node(nn.node).index()];
    const Eigen::Vector3d n_c = cluster.normal(c);
    if (n_c.allFinite() && std::abs(n_c.dot(cluster.normal(i))) >= kContinuationCos &&
        std::abs((cluster.point(i) - cluster.point(c)).dot(n_c)) <= thr)
      ++v.continuations;
  }
  return v;
}

bool verified(const Verdict& v, const FindPartsSettings& s) {
  return v.fitness >= s.pose.min_fitness && v.score() >= s.min_instance_score &&
         v.claimed.size() >= s.table.min_cluster_size;
}

/// The share of `v`'s claimed points already taken (taken[i]).
double overlap(const Verdict& v, const std::vector<char>& taken) {
  if (v.claimed.empty()) return 0;
  std::size_t k = 0;
  for (std::uint32_t i : v.claimed) k += taken[i] != 0;
  return static_cast<double>(k) / static_cast<double>(v.claimed.size());
}

Cluster gatherCluster(const CloudView<double>& scene, const std::vector<std::uint32_t>& indices,
                      const FindPartsSettings& s) {
  Cluster c;
  for (std::uint32_t i : indices)
    if (scene.isFinite(i)) {
      c.points.insert(c.points.end(), scene.ptr(i), scene.ptr(i) + 3);
      c.scene_index.push_back(i);
    }
  c.normals.resize(c.points.size());
  c.free.assign(c.scene_index.size(), 1);
  if (c.scene_index.empty()) return c;
  NormalEstimationSettings ns;
  ns.radius = s.pose.normal_radius;
  ns.num_threads = s.pose.num_threads;
  estimateNormals(c.cloud(), ns, c.normals.data());
  return c;
}

/// The free points of `members` (cluster positions) split into Euclidean clusters
/// (FindPartsSettings::table: cluster_tolerance, min_cluster_size), largest first.
std::vector<std::vector<std::uint32_t>> freePieces(const Cluster& c, const std::vector<std::uint32_t>& members,
                                                   const FindPartsSettings& s) {
  std::vector<std::uint32_t> free;
  for (std::uint32_t i : members)
    if (c.free[i]) free.push_back(i);
  if (free.size() < s.table.min_cluster_size) return {};
  return euclideanClusters(c.cloud(), free, s.table.cluster_tolerance, s.table.min_cluster_size,
                           std::numeric_limits<std::size_t>::max());
}

/// Whether a piece of free points can hold another instance: at least table.min_cluster_size
/// of its points lie further than kContinuationReach inlier thresholds from every accepted
/// instance. What an instance leaves beside it (noisy edges, flying pixels, a sliver of a
/// face whose normals disagree) is no part, and a round costs as much as a whole cluster.
bool worthARound(const Cluster& c, const std::vector<std::uint32_t>& piece, const std::vector<Verdict>& accepted,
                 const std::vector<SurfaceIndex>& index, const FindPartsSettings& s) {
  const double reach = kContinuationReach * s.pose.inlier_threshold;
  std::size_t far = 0;
  for (std::uint32_t i : piece) {
    bool near = false;
    for (const Verdict& a : accepted) {
      const Eigen::Matrix3d R = a.T_scene_model.topLeftCorner<3, 3>();
      const Eigen::Vector3d q = R.transpose() * (c.point(i) - a.T_scene_model.topRightCorner<3, 1>());
      if ((near = index[static_cast<std::size_t>(a.part)].tree.nearest(q.data(), reach * reach).found())) break;
    }
    if (!near && ++far >= s.table.min_cluster_size) return true;
  }
  return false;
}

PartDetection instanceDetection(const Verdict& v, const PartPoses& poses, const Cluster& c, int cluster_index) {
  PartDetection d;
  d.status = DetectionStatus::Found;
  d.cluster = cluster_index;
  d.part = v.part;
  d.parts = poses.parts;
  d.pose = poses.parts[static_cast<std::size_t>(v.part)];
  const PoseCandidate& cand = d.pose.candidates[v.candidate];
  d.pose.found = true;
  d.pose.message.clear();
  d.pose.T_scene_model = v.T_scene_model;
  d.pose.view = cand.view;
  d.pose.fitness = v.fitness;
  d.pose.coverage = v.agreement();
  d.pose.inlier_rmse = cand.inlier_rmse;
  d.score = v.score();
  d.surface_coverage = v.agreement();
  std::vector<double> pts;
  for (std::uint32_t i : v.claimed) {
    d.indices.push_back(c.scene_index[i]);
    pts.insert(pts.end(), &c.points[3 * i], &c.points[3 * i] + 3);
  }
  std::sort(d.indices.begin(), d.indices.end());
  d.size = principalExtent(CloudView<double>(pts.data(), pts.size() / 3));
  return d;
}

bool samePose(const Verdict& a, const Verdict& b, const PartCatalogue& parts, const FindPartsSettings& s) {
  if (a.part != b.part) return false;
  const auto e = symmetricPoseError(Eigen::Isometry3d(a.T_scene_model), Eigen::Isometry3d(b.T_scene_model),
                                    parts.symmetries[static_cast<std::size_t>(a.part)]);
  return e.first <= s.same_pose_angle && e.second <= s.same_pose_distance;
}

/// One round on one piece of the cluster: every hypothesis verified, then accepted greedily.
/// Returns the accepted verdicts (their points marked taken in c.free) with their detections.
std::vector<PartDetection> round(const PartCatalogue& parts, Cluster& c, const std::vector<std::uint32_t>& piece,
                                 const std::vector<SurfaceIndex>& index, std::vector<Verdict>& accepted,
                                 const PlaneModel* plane, const FindPartsSettings& s, int cluster_index,
                                 std::size_t room, const CoarseAligner& aligner, const PoseProgress& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<double> pts;
  for (std::uint32_t i : piece) pts.insert(pts.end(), &c.points[3 * i], &c.points[3 * i] + 3);
  if (s.voxel_size > 0) pts = voxelGrid(CloudView<double>(pts.data(), pts.size() / 3), s.voxel_size).points;
  const PartPoses poses = poseEveryPart(parts, CloudView<double>(pts.data(), pts.size() / 3), plane, s, false,
                                        aligner, progress);
  std::vector<Verdict> verdicts;
  for (std::size_t p = 0; p < poses.parts.size(); ++p) {
    if (!poses.tried[p]) continue;
    const auto& cands = poses.parts[p].candidates;
    for (std::size_t k = 0; k < cands.size(); ++k) {
      if (!cands[k].found) continue;
      const ModelView& view = parts.models[p][static_cast<std::size_t>(cands[k].view)];
      Verdict v = verify(view, index[p], cands[k].T_scene_model, c, s);
      v.part = static_cast<int>(p);
      v.candidate = k;
      if (verified(v, s)) verdicts.push_back(std::move(v));
    }
  }
  // Best first: the most points explained, weighted by the score (a pose slid along a part
  // explains fewer of its points than the true one, and its score suffers less).
  auto weight = [](const Verdict& v) { return static_cast<double>(v.claimed.size()) * v.score(); };
  std::stable_sort(verdicts.begin(), verdicts.end(), [&](const Verdict& a, const Verdict& b) { return weight(a) > weight(b); });
  std::vector<char> taken(c.free.size(), 0);
  std::vector<std::uint32_t> removed;  // covered by an accepted instance: no other instance's
  std::vector<PartDetection> out;
  std::vector<std::size_t> mine;  // positions in `accepted` of this round's instances
  for (const Verdict& h : verdicts) {
    if (out.size() >= room) break;
    bool duplicate = false;
    for (const Verdict& a : accepted) duplicate = duplicate || samePose(a, h, parts, s);
    if (duplicate) continue;
    if (overlap(h, taken) > 0.2) {
      // A different part, or a distinct pose, on the same points that scores alike: ambiguous.
      for (std::size_t m = 0; m < mine.size(); ++m) {
        PartDetection& d = out[m];
        const Verdict& a = accepted[mine[m]];
        std::vector<char> theirs(c.free.size(), 0);
        for (std::uint32_t i : a.claimed) theirs[i] = 1;
        if (overlap(h, theirs) > 0.5 && h.score() > d.runner_up_score) {
          const auto e = symmetricPoseError(Eigen::Isometry3d(a.T_scene_model), Eigen::Isometry3d(h.T_scene_model),
                                            parts.symmetries[static_cast<std::size_t>(a.part)]);
          d.runner_up_part = h.part;
          d.runner_up_score = h.score();
          d.runner_up_angle = e.first;
          d.runner_up_distance = e.second;
        }
      }
      continue;
    }
    // Refined on its own points against the part's whole surface, kept if it still verifies.
    Verdict v = h;
    if (s.surface_polish && s.polish_distance > 0) {
      std::vector<double> own;
      for (std::uint32_t i : h.claimed) own.insert(own.end(), &c.points[3 * i], &c.points[3 * i] + 3);
      const Eigen::Matrix4d T = polishOnSurface(h.T_scene_model, parts.surfaces[static_cast<std::size_t>(h.part)],
                                                CloudView<double>(own.data(), own.size() / 3), s);
      const auto& cand = poses.parts[static_cast<std::size_t>(h.part)].candidates[h.candidate];
      Verdict polished = verify(parts.models[static_cast<std::size_t>(h.part)][static_cast<std::size_t>(cand.view)],
                                index[static_cast<std::size_t>(h.part)], T, c, s);
      polished.part = h.part;
      polished.candidate = h.candidate;
      if (verified(polished, s) && overlap(polished, taken) <= 0.2) v = std::move(polished);
    }
    // Each point is explained by one instance: the first to claim it.
    v.claimed.erase(std::remove_if(v.claimed.begin(), v.claimed.end(), [&](std::uint32_t i) { return taken[i] != 0; }),
                    v.claimed.end());
    for (std::uint32_t i : v.claimed) taken[i] = 1;
    out.push_back(instanceDetection(v, poses, c, cluster_index));
    for (std::uint32_t i : v.covered) removed.push_back(i);
    mine.push_back(accepted.size());
    accepted.push_back(std::move(v));
  }
  for (PartDetection& d : out) {
    if (d.runner_up_part >= 0 && d.runner_up_score >= (1 - s.ambiguity_margin) * d.score) {
      d.status = DetectionStatus::Ambiguous;
      char m[200];
      std::snprintf(m, sizeof m, "part %d (score %.4f) explains the same points within %g of this instance (part %d, "
                    "score %.4f)", d.runner_up_part, d.runner_up_score, s.ambiguity_margin, d.part, d.score);
      d.message = m;
    }
    d.seconds = secondsSince(t0) / static_cast<double>(out.size());
  }
  for (std::size_t i = 0; i < taken.size(); ++i)
    if (taken[i]) c.free[i] = 0;
  for (std::uint32_t i : removed) c.free[i] = 0;
  return out;
}

}  // namespace

std::vector<PartDetection> findInstances(const PartCatalogue& parts, const CloudView<double>& scene,
                                         const std::vector<std::uint32_t>& indices, PartDetection& whole,
                                         const PlaneModel* plane, const FindPartsSettings& s,
                                         const CoarseAligner& aligner, const PoseProgress& progress) {
  std::vector<PartDetection> out;
  const std::size_t found_whole = whole.status != DetectionStatus::NotFound ? 1 : 0;
  if (s.max_instances <= found_whole) return out;
  Cluster c = gatherCluster(scene, indices, s);
  if (c.scene_index.size() < s.table.min_cluster_size) return out;
  std::vector<SurfaceIndex> index;
  for (const PartSurface& surface : parts.coarse_surfaces) index.emplace_back(surface);
  std::vector<Verdict> accepted;
  if (found_whole) {  // what the single part leaves unexplained
    Verdict v = verify(parts.models[static_cast<std::size_t>(whole.part)][static_cast<std::size_t>(whole.pose.view)],
                       index[static_cast<std::size_t>(whole.part)], whole.pose.T_scene_model, c, s);
    v.part = whole.part;
    for (std::uint32_t i : v.covered) c.free[i] = 0;
    accepted.push_back(std::move(v));
  }
  std::vector<std::uint32_t> all(c.free.size());
  std::iota(all.begin(), all.end(), 0u);
  std::vector<std::vector<std::uint32_t>> queue;
  for (auto& piece : freePieces(c, all, s))
    if (worthARound(c, piece, accepted, index, s)) queue.push_back(std::move(piece));
  const int cluster_index = whole.cluster;
  while (!queue.empty() && found_whole + out.size() < s.max_instances) {
    const std::vector<std::uint32_t> piece = std::move(queue.front());
    queue.erase(queue.begin());
    std::vector<PartDetection> found = round(parts, c, piece, index, accepted, plane, s, cluster_index,
                                             s.max_instances - found_whole - out.size(), aligner, progress);
    if (found.empty()) continue;
    for (PartDetection& d : found) out.push_back(std::move(d));
    for (auto& rest : freePieces(c, piece, s))
      if (worthARound(c, rest, accepted, index, s)) queue.push_back(std::move(rest));
  }
  if (found_whole && !out.empty()) {  // the part found first keeps only the points it explains
    whole.indices.clear();
    for (std::uint32_t i : accepted.front().claimed) whole.indices.push_back(c.scene_index[i]);
    std::sort(whole.indices.begin(), whole.indices.end());
  }
  return out;
}

}  // namespace scanalign::detail
