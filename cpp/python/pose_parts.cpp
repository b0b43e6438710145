// Bindings of part identification (scanalign/pose/part_identification.hpp; Kleppe, PhD
// thesis, NTNU 2018, ch. 7): which of several known parts lies in each object cluster of a
// table scene, its pose, and how sure find_parts is (DetectionStatus).
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "arrays.hpp"
#include "pose.hpp"
#include "scanalign/pose/part_identification.hpp"
#include "warnings.hpp"

namespace scanalign::python {

namespace {

/// Part symmetries from Python: None (no part symmetric), or one object per part with the
/// fields of PartSymmetry (axis, point, order) -- the bound class or any object with those
/// attributes -- or None for a part without symmetry.
std::vector<PartSymmetry> symmetriesOf(const py::object& o) {
  std::vector<PartSymmetry> out;
  if (o.is_none()) return out;
  if (!py::isinstance<py::sequence>(o) || py::isinstance<py::str>(o))
    throw py::type_error("symmetries: expected a list with one PartSymmetry (or None) per part");
  for (const py::handle h : o) {
    PartSymmetry s;
    if (!h.is_none()) {
      const std::string at = "symmetries[" + std::to_string(out.size()) + "]";
      if (!py::hasattr(h, "axis") || !py::hasattr(h, "point") || !py::hasattr(h, "order"))
        throw py::type_error(at + ": expected a PartSymmetry (axis, point, order) or None");
      try {
        s.axis = py::cast<Eigen::Vector3d>(h.attr("axis"));
        s.point = py::cast<Eigen::Vector3d>(h.attr("point"));
        s.order = py::cast<int>(h.attr("order"));
      } catch (const py::cast_error&) {
        throw py::type_error(at + ": axis and point must be 3-vectors (m) and order an integer");
      }
      try {
        s.validate();
      } catch (const std::invalid_argument& e) {
        throw py::value_error(at + ": " + e.what());
      }
    }
    out.push_back(s);
  }
  return out;
}

void bindSettings(py::module_& m) {
  py::enum_<DetectionStatus>(m, "DetectionStatus", "How find_parts judged an object cluster")
      .value("found", DetectionStatus::Found, "the best part's pose passes min_fitness/min_coverage, nothing else scores alike")
      .value("not_found", DetectionStatus::NotFound, "no part's pose passes min_fitness/min_coverage (or all were skipped by size)")
      .value("ambiguous", DetectionStatus::Ambiguous,
             "found, but another part or a non-equivalent pose of the same part scores within ambiguity_margin");
  using S = FindPartsSettings;
  fieldsOf(py::class_<S>(m, "FindPartsSettings", "Settings of find_parts (metres, radians)"))
      .field("table", &S::table, "", "TableSegmentationSettings: table plane and object clusters")
      .field("max_objects", &S::max_objects, "", "clusters tried, largest first")
      .field("pose", &S::pose, "",
             "PoseSettings per cluster and part (one RANSAC hypothesis per view, views rendered at 100 px)")
      .field("ambiguity_margin", &S::ambiguity_margin, "",
             "a runner-up scoring at least (1 - margin) x the best score makes the detection ambiguous")
      .field("ambiguity_rmse_ratio", &S::ambiguity_rmse_ratio, "",
             "a runner-up fits alike only if its inlier RMSE is at most this times the best's (0: no RMSE test): the "
             "score saturates at the inlier threshold, the RMSE does not")
      .field("score_tie", &S::score_tie, "",
             "candidates of the best part within this of its best score are ties: the smallest inlier RMSE wins")
      .field("polish_distance", &S::polish_distance, "m",
             "the reported candidate is refined again by ICP with this correspondence distance and a tight stop (0 = "
             "none)")
      .field("same_pose_angle", &S::same_pose_angle, "rad",
             "poses of one part this close (over its symmetry) are the same pose")
      .field("same_pose_distance", &S::same_pose_distance, "m", "with same_pose_angle")
      .field("max_size_ratio", &S::max_size_ratio, "",
             "skip a part for a cluster larger than this x the part's size (largest principal extent); 0 = no bound")
      .field("min_size_ratio", &S::min_size_ratio, "",
             "skip a part for a cluster smaller than this x its smallest view; 0 = no bound")
      .field("max_table_penetration", &S::max_table_penetration, "m",
             "poses that put the part's surface (its views merged) further below the table plane are dropped "
             "(infinity: no check)")
      .field("surface_polish", &S::surface_polish, "",
             "refine the reported pose against the part's whole surface, cluster points onto the model within "
             "polish_distance")
      .field("cbd_radius_fraction", &S::cbd_radius_fraction, "",
             "CBD radius per part: max(the CBD radius, this x the part's size); 0 = fixed")
      .field("min_surface_coverage", &S::min_surface_coverage, "",
             "fraction of the cluster's points within polish_distance of the part's whole surface a detection needs, "
             "else not_found (0 = no check)")
      .field("voxel_size", &S::voxel_size, "m",
             "each cluster reduced to one point (the centroid) per voxel before its pose; 0 = every point (1 to 1.5 "
             "mm for a merged multi-view scan)")
      .field("max_instances", &S::max_instances, "",
             "instances per object cluster (touching parts, a heap of copies); 1 = one part per cluster")
      .field("min_instance_score", &S::min_instance_score, "",
             "one of several instances in a cluster needs this harmonic mean of its fitness and its agreement (the "
             "share of explained points among the points near it: explained, inside the part, or continuing its "
             "surface past its border)")
      .settings();
}

void bindResults(py::module_& m) {
  using D = PartDetection;
  fieldsOf(py::class_<D>(m, "PartDetection", "One object cluster and the part found in it"))
      .output("status", &D::status, "", "DetectionStatus")
      .field("part", optionalIndexGetter(&D::part), optionalIndexSetter(&D::part), "",
             "index of the best-scoring part in the models (None when every part was skipped)", false)
      .output("pose", &D::pose, "", "PoseResult of that part (found False unless found/ambiguous)")
      .output("score", &D::score, "", "its best candidate's score")
      .output("surface_coverage", &D::surface_coverage, "",
              "fraction of the cluster's points within polish_distance of the part's whole surface at the reported "
              "pose")
      .field("runner_up_part", optionalIndexGetter(&D::runner_up_part), optionalIndexSetter(&D::runner_up_part), "",
             "part of the best competing pose (None when there is none)", false)
      .output("runner_up_score", &D::runner_up_score, "", "its score")
      .output("runner_up_angle", &D::runner_up_angle, "rad",
              "symmetric pose difference to the best pose (over the best part's symmetry)")
      .output("runner_up_distance", &D::runner_up_distance, "m", "the same, translation")
      .field("indices", int64Getter(&D::indices), int64Setter(&D::indices), "",
             "(N,) int64 the detection's points, indices into the scene: its cluster, or the points one of "
             "several instances in the cluster explains", false)
      .output("cluster", &D::cluster, "", "its cluster, index into table.objects")
      .output("parts", &D::parts, "", "PoseResult per part (a skipped part says why in its message)")
      .output("size", &D::size, "m", "the cluster's largest extent along its principal axes")
      .output("message", &D::message, "", "why not found, or what made it ambiguous")
      .output("seconds", &D::seconds, "s", "wall time of this cluster, all parts")
      .result();
  using R = FindPartsResult;
  fieldsOf(py::class_<R>(m, "FindPartsResult", "Result of find_parts"))
      .output("detections", &R::detections, "",
              "PartDetection per object cluster (largest first), or per instance in a cluster of several")
      .derived("plane", [](const R& r) { return r.table.plane; }, "", "the table plane (PlaneResult)")
      .output("table", &R::table, "", "the whole TableSegmentationResult")
      .output("seconds", &R::seconds, "s", "wall time")
      .result();
}

void bindFunctions(py::module_& m) {
  m.def(
      "find_parts",
      [](const std::vector<std::vector<ModelView>>& models, const py::array& scene, const FindPartsSettings& s,
         const py::object& symmetries, const std::vector<int>& ids, const py::object& progress) {
        const auto view = cloudView<double>(scene, "scene");
        const std::vector<PartSymmetry> sym = symmetriesOf(symmetries);
        const PoseProgress cb = progressOf(progress);
        FindPartsResult result;
        {
          py::gil_scoped_release release;
          result = findParts(models, sym, view, s, ids, {}, cb);
        }
        warnPython(result.table.warning);
        return result;
      },
      py::arg("models"), py::arg("scene"), py::arg("settings"), py::arg("symmetries") = py::none(),
      py::arg("view_ids") = std::vector<int>{}, py::arg("progress") = py::none(),
      "Which of several parts (models: one list of ModelView per part) lies in each object cluster of a table scene "
      "(N, 3) float64, m, and its pose; symmetries: one PartSymmetry (axis, point, order) or None per part, or None");
  m.def(
      "part_pose_settings",
      [](const std::vector<ModelView>& views, const FindPartsSettings& s) { return partPoseSettings(views, s); },
      py::arg("views"), py::arg("settings"),
      "The PoseSettings find_parts matches this part (its views) with: settings.pose with the part's CBD radius, "
      "max(radius, cbd_radius_fraction x the part's size, m)");
}

}  // namespace

void bindPoseParts(py::module_& m) {
  bindSettings(m);
  bindResults(m);
  bindFunctions(m);
}

}  // namespace scanalign::python
