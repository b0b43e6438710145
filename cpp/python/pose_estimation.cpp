// Bindings of the pose of a part from its CAD model (Kleppe, PhD thesis, NTNU 2018, ch. 6-7):
// estimate_pose on one object cloud (scanalign/pose/pose_estimation.hpp), find_objects on a
// table scene (find_objects.hpp), and describe_model_views (CBD features cached in the views).
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <vector>

#include "arrays.hpp"
#include "pose.hpp"
#include "scanalign/pose/find_objects.hpp"
#include "scanalign/pose/pose_estimation.hpp"
#include "warnings.hpp"

namespace scanalign::python {

PoseProgress progressOf(const py::object& callback) {
  if (callback.is_none()) return {};
  return [callback](std::size_t done, std::size_t total) {
    py::gil_scoped_acquire acquire;
    callback(done, total);
  };
}

namespace {

void bindSettings(py::module_& m) {
  py::enum_<CoarseMethod>(m, "CoarseMethod", "How each model view is brought near the object before ICP")
      .value("cbd", CoarseMethod::Cbd, "curvature-based descriptor + RANSAC + motor refit (paper 5)")
      .value("flags", CoarseMethod::Flags, "centroid + average normal line (paper 4)")
      .value("pcl", CoarseMethod::Pcl, "the stock PCL baseline of PoseSettings.pcl (thesis §7.6)")
      .value("external", CoarseMethod::External, "a coarse aligner given by a C++ caller (not from Python)");
  using S = PoseSettings;
  fieldsOf(py::class_<S>(m, "PoseSettings", "Settings of estimate_pose / find_objects (metres)"))
      .field("method", &S::method, "", "CoarseMethod")
      .field("inlier_threshold", &S::inlier_threshold, "m",
             "fitness/coverage distance and the CBD RANSAC inlier threshold (thesis: 0.005)")
      .field("icp_distance", &S::icp_distance, "m", "ICP maximum correspondence distance")
      .field("normal_radius", &S::normal_radius, "m", "scene normals for point-to-plane ICP and flags")
      .field("min_fitness", &S::min_fitness, "", "found only if the best view's fitness reaches this")
      .field("min_coverage", &S::min_coverage, "", "found only if the best view's coverage reaches this")
      .field("cbd", &S::cbd, "", "CbdAlignmentSettings (min_neighbors 0: automatic)")
      .field("flags", &S::flags, "", "FlagAlignmentSettings")
      .field("pcl", &S::pcl, "", "PclFeatureAlignmentSettings of method 'pcl' (the thesis's FPFH preset)")
      .field("views", &S::views, "",
             "ModelViewSettings a mesh is rendered with (estimate_pose: 150 px; find_parts: 100 px, as accurate on "
             "the built-in parts and 2-3x faster)")
      .field("num_threads", &S::num_threads, "", "0 = all cores")
      .settings();
  using O = FindObjectsSettings;
  fieldsOf(py::class_<O>(m, "FindObjectsSettings", "Settings of find_objects"))
      .field("table", &O::table, "", "TableSegmentationSettings: table plane and object clusters")
      .field("max_objects", &O::max_objects, "", "clusters tried, largest first")
      .field("pose", &O::pose, "", "PoseSettings per cluster")
      .settings();
}

py::dict poseSummary(const PoseResult& r) {
  py::dict d;
  d["found"] = r.found;
  d["fitness"] = r.fitness;
  d["coverage"] = r.coverage;
  d["inlier_rmse"] = r.inlier_rmse;
  d["method"] = r.method;
  d["view"] = r.view < 0 ? py::object(py::none()) : py::object(py::int_(r.view));
  d["seconds"] = r.seconds;
  d["coarse_seconds"] = r.coarse_seconds;
  d["message"] = r.message;
  py::list T;
  for (int i = 0; i < 4; ++i) {
    py::list row;
    for (int j = 0; j < 4; ++j) row.append(r.T_scene_model(i, j));
    T.append(row);
  }
  d["T_scene_model"] = T;
  return d;
}

void bindResults(py::module_& m) {
  using C = PoseCandidate;
  fieldsOf(py::class_<C>(m, "PoseCandidate", "Per-view summary of estimate_pose"))
      .output("view", &C::view, "", "index into the model views")
      .output("found", &C::found, "", "the coarse alignment produced a pose")
      .output("coarse_fitness", &C::coarse_fitness, "", "fitness after the coarse alignment alone")
      .output("fitness", &C::fitness, "", "after ICP")
      .output("coverage", &C::coverage, "", "after ICP")
      .output("inlier_rmse", &C::inlier_rmse, "m", "after ICP")
      .output("score", &C::score, "", "2 fitness coverage / (fitness + coverage)")
      .output("T_scene_model", &C::T_scene_model, "m",
              "(4, 4) the view's pose after ICP, model -> scene (identity when the coarse alignment failed)")
      .result();
  using R = PoseResult;
  fieldsOf(py::class_<R>(m, "PoseResult", "Pose of a model in an object cloud")
               .def(py::init<>())
               .def("as_dict", &poseSummary, "a JSON-ready summary (candidates left out)"))
      .field("T_scene_model", &R::T_scene_model, "m", "(4, 4) maps model (CAD) coordinates into the scene")
      .derived("transformation", [](const R& r) { return r.T_scene_model; }, "m",
               "T_scene_model under Open3D's name: the model (source) registered onto the scene (target)")
      .field("found", &R::found, "", "a coarse alignment succeeded and ICP refined it")
      .field("fitness", &R::fitness, "", "fraction of the view's points within inlier_threshold of the object")
      .field("coverage", &R::coverage, "", "fraction of the object's points within inlier_threshold of the model")
      .field("inlier_rmse", &R::inlier_rmse, "m", "over the fitness inliers")
      .field("method", &R::method, "",
             "coarse method used: 'cbd', 'flags', 'external', or a PCL baseline's name ('fpfh', 'fpfh_sac_ia', "
             "'shot', '3dsc', 'ppf', 'pfh', 'rsd', 'gasd', 'vfh')")
      .field("view", optionalIndexGetter(&R::view), optionalIndexSetter(&R::view), "",
             "index of the best model view (None when nothing was found or the model was a cloud)")
      .field("seconds", &R::seconds, "s", "wall time, all views")
      .field("coarse_seconds", &R::coarse_seconds, "s", "the part in coarse alignment")
      .output("candidates", &R::candidates, "", "PoseCandidate per view tried")
      .field("message", &R::message, "", "why nothing was found")
      .result();
  using O = FindObjectsResult;
  fieldsOf(py::class_<O>(m, "FindObjectsResult", "Result of find_objects"))
      .field("poses", &O::poses, "",
             "PoseResult per object cluster, largest first (assignable: a list of PoseResult, one per cluster)")
      .derived(
          "objects",
          [](const O& o) {
            std::vector<Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1>> out;
            for (const auto& idx : o.table.objects)
              out.push_back(Eigen::Map<const Eigen::Matrix<std::uint32_t, Eigen::Dynamic, 1>>(
                                idx.data(), static_cast<Eigen::Index>(idx.size()))
                                .cast<std::int64_t>());
            return out;
          },
          "", "the clusters as int64 index arrays into the scene")
      .derived("plane", [](const O& o) { return o.table.plane; }, "", "the table plane (PlaneResult)")
      .output("table", &O::table, "", "the whole TableSegmentationResult")
      .output("seconds", &O::seconds, "s", "wall time")
      .result();
}

void bindFunctions(py::module_& m) {
  m.def(
      "estimate_pose",
      [](const std::vector<ModelView>& views, const py::array& scene, const PoseSettings& s, const std::vector<int>& ids,
         const py::object& progress) {
        const auto view = cloudView<double>(scene, "scene");
        const PoseProgress cb = progressOf(progress);
        py::gil_scoped_release release;
        return estimatePose(views, view, s, ids, {}, cb);
      },
      py::arg("views"), py::arg("scene"), py::arg("settings"), py::arg("view_ids") = std::vector<int>{},
      py::arg("progress") = py::none(),
      "Pose of the model (its views) in one object cloud (N, 3) float64, m, with the coarse method of the settings "
      "(method 'pcl': settings.pcl); progress(done, total) after each view");
  m.def(
      "find_objects",
      [](const std::vector<ModelView>& views, const py::array& scene, const FindObjectsSettings& s,
         const std::vector<int>& ids, const py::object& progress) {
        const auto view = cloudView<double>(scene, "scene");
        const PoseProgress cb = progressOf(progress);
        FindObjectsResult result;
        {
          py::gil_scoped_release release;
          result = findObjects(views, view, s, ids, {}, cb);
        }
        warnPython(result.table.warning);
        return result;
      },
      py::arg("views"), py::arg("scene"), py::arg("settings"), py::arg("view_ids") = std::vector<int>{},
      py::arg("progress") = py::none(), "Poses of the model in a table scene: table plane, clusters, estimate_pose each");
  m.def(
      "describe_model_views",
      [](std::vector<ModelView> views, const PoseSettings& s) {
        {
          py::gil_scoped_release release;
          describeModelViews(views, s);
        }
        return views;
      },
      py::arg("views"), py::arg("settings"),
      "Copies of the views with their CBD features computed (ModelView.cbd) with the settings estimate_pose, "
      "find_objects and find_parts use for these PoseSettings, so those calls skip that work (most of a pose's "
      "time). For find_parts pass part_pose_settings(views, find_parts_settings): with cbd_radius_fraction the "
      "radius follows each part's size.");
}

}  // namespace

void bindPoseEstimation(py::module_& m) {
  bindSettings(m);
  bindResults(m);
  bindFunctions(m);
}

}  // namespace scanalign::python
