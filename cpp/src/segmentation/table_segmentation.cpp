// The table segmentation pipeline of paper 3. See table_segmentation.hpp.
#include "scanalign/segmentation/table_segmentation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "scanalign/segmentation/euclidean_clusters.hpp"

namespace scanalign {
namespace {

std::string formatVector(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3g, %.3g, %.3g)", v.x(), v.y(), v.z());
  return buf;
}

/// m; how far below the table the origin must lie to contradict `up` when no viewpoint is given.
constexpr double kImplicitViewpointMargin = 0.05;

/// Orients the table normal towards `up`, or else towards the viewpoint (Paper 3: "orient v
/// toward the camera"), and reports an `up` under which the viewpoint lies below the table.
void orientTable(const TableSegmentationSettings& s, TableSegmentationResult& out) {
  PlaneModel& pl = out.plane.model;
  const Eigen::Vector3d viewpoint = s.viewpoint.value_or(Eigen::Vector3d::Zero());
  const bool use_up = s.up.squaredNorm() > 0;
  if (use_up ? pl.normal.dot(s.up) < 0 : pl.signedDistance(viewpoint) < 0) {
    pl.normal = -pl.normal;
    pl.distance = -pl.distance;
    out.plane.hypothesis.normal = -out.plane.hypothesis.normal;
    out.plane.hypothesis.distance = -out.plane.hypothesis.distance;
  }
  // Unset, the viewpoint is the origin only by guess: a base frame's origin often lies on the
  // table top (a robot standing on it), noise puts it a hair below, and nothing is wrong.
  // A camera-frame cloud's origin is a camera, tens of centimetres off the table.
  const double margin = s.viewpoint ? s.plane.threshold : std::max(s.plane.threshold, kImplicitViewpointMargin);
  const double height = pl.signedDistance(viewpoint);
  if (!use_up || height >= -margin) return;
  char depth[32];
  std::snprintf(depth, sizeof depth, "%.3g", -height);
  out.warning = "table segmentation: up " + formatVector(s.up) + " puts the viewpoint " + formatVector(viewpoint) +
                (s.viewpoint ? "" : " (the origin, a camera-frame cloud's camera centre)") + " " + depth +
                " m below the table, which a sensor cannot see from there: the objects on the table are removed as "
                "below it. For a cloud in its camera frame omit up (the normal then faces the camera); "
                "in another frame pass the camera centre as viewpoint.";
}

}  // namespace

void validate(const TableSegmentationSettings& s) {
  validate(s.plane);
  auto fail = [](const std::string& what) { throw std::invalid_argument("table segmentation settings: " + what); };
  if (s.crop_min.hasNaN() || s.crop_max.hasNaN()) fail("crop_min and crop_max must not be NaN");
  if (s.viewpoint && !s.viewpoint->allFinite()) fail("viewpoint must be 3 finite coordinates");
  if (!s.up.allFinite()) fail("up must be 3 finite coordinates");
  if (!(s.cluster_tolerance > 0) || !std::isfinite(s.cluster_tolerance))
    fail("cluster_tolerance must be a finite positive distance in metres");
  if (s.min_cluster_size < 1 || s.max_cluster_size < s.min_cluster_size)
    fail("need 1 <= min_cluster_size <= max_cluster_size");
}

template <typename Scalar>
TableSegmentationResult segmentTable(const CloudView<Scalar>& points, const TableSegmentationSettings& s) {
  validate(s);
  TableSegmentationResult out;
  // (1) pass-through crop.
  std::vector<std::uint32_t> kept;
  std::vector<Scalar> packed;
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    const Eigen::Vector3d p = points[i].template cast<double>();
    if (s.crop && ((p.array() < s.crop_min.array()).any() || (p.array() > s.crop_max.array()).any())) continue;
    kept.push_back(static_cast<std::uint32_t>(i));
    packed.insert(packed.end(), {points.ptr(i)[0], points.ptr(i)[1], points.ptr(i)[2]});
  }
  out.cropped_points = kept.size();
  const CloudView<Scalar> view(packed.empty() ? nullptr : packed.data(), kept.size(), 3);
  // (2) dominant plane.
  out.plane = ransacPlane(view, s.plane);
  out.status = out.plane.status;
  if (!out.success()) return out;
  orientTable(s, out);
  const PlaneModel& pl = out.plane.model;
  // (3) remove the inliers and everything below: keep signed distance >= threshold.
  std::vector<std::uint32_t> above;
  for (std::size_t i = 0; i < kept.size(); ++i)
    if (pl.signedDistance(view[i].template cast<double>()) >= s.plane.threshold)
      above.push_back(static_cast<std::uint32_t>(i));
  out.above_points = above.size();
  // (4)-(5) Euclidean clustering, small/large clusters dropped.
  out.objects = euclideanClusters(view, above, s.cluster_tolerance, s.min_cluster_size, s.max_cluster_size);
  for (auto& c : out.objects)
    for (auto& i : c) i = kept[i];  // back to input indices (kept is ascending: order preserved)
  for (auto& i : out.plane.inliers) i = kept[i];
  return out;
}

#define SCANALIGN_INSTANTIATE(S) \
  template TableSegmentationResult segmentTable<S>(const CloudView<S>&, const TableSegmentationSettings&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
