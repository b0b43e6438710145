// _core.reconstruction, frame to model: the pipeline of the eye-in-hand paper (Comput.
// Electron. Agric. 180 (2021) 105929, §3 and Algorithm 1), its settings and per-frame result,
// and the settings of the whole reconstruction job.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <chrono>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "fields.hpp"
#include "pickle.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/reconstruction/frame_to_model.hpp"
#include "scanalign/reconstruction/reconstruction_settings.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace scanalign::python {

namespace {

/// "pcl_svd", "pcl_dual_quaternion", "pcl_point_to_plane_lls", ...: the stock PCL ICP variant.
PclIcpVariant pclVariant(const std::string& registration) {
  for (auto v : {PclIcpVariant::Svd, PclIcpVariant::DualQuaternion, PclIcpVariant::PointToPlaneLLS,
                 PclIcpVariant::ScanalignPointToPlaneLLS})
    if (registration == std::string("pcl_") + toString(v)) return v;
  throw py::value_error("registration must be 'scanalign' or 'pcl_' + a PCL ICP variant, got '" + registration + "'");
}

/// Runs a stock PCL ICP where FrameToModel::integrate runs the engine: prepare, register
/// to the model from the guess, check, merge (the pipeline's PCL baselines).
FrameResult integrateWithPcl(FrameToModel& self, const CloudView<float>& points, const std::uint8_t* colors,
                             const std::optional<Eigen::Matrix4d>& guess, PclIcpVariant variant) {
  const auto t_start = std::chrono::steady_clock::now();
  FrameResult r;
  r.T_model_camera = guess ? *guess : self.predictedPose();
  requireRigid(r.T_model_camera, "guess");
  // Counted only once nothing can throw any more: a call that throws saw no frame, as in
  // FrameToModel::integratePrepared.
  r.index = self.framesSeen();
  r.input_points = points.size;
  const PreparedFrame frame = self.prepare(points, colors);
  r.frame_points = frame.size();
  r.far_points = frame.far_points;
  r.model_points = self.model().size();
  r.prepare_seconds = frame.seconds;
  if (frame.size() == 0) {
    self.countFrame();
    return r;
  }
  if (frame.size() < static_cast<std::size_t>(self.settings().min_frame_points)) {
    r.status = FrameStatus::SkippedTooFewPoints;
    self.countFrame();
    return r;
  }
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  const Model& m = self.model();
  const bool plane = variant == PclIcpVariant::PointToPlaneLLS || variant == PclIcpVariant::ScanalignPointToPlaneLLS;
  r.icp = pclIcp(frame.view(), CloudView<float>(m.points.data(), m.size()),
                 plane ? CloudView<float>(m.normals.data(), m.size()) : CloudView<float>(), r.T_model_camera,
                 self.settings().icp, variant);
  r.register_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.status = self.check(r.icp, r.T_model_camera);
  if (r.status == FrameStatus::Registered) {
    t0 = Clock::now();
    std::size_t far = 0;
    r.model_points = self.merge(frame, r.icp.T_target_source, &far);  // all or nothing
    r.T_model_camera = r.icp.T_target_source;
    r.far_points += far;
    r.merge_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  }
  self.countFrame();
  r.total_seconds = std::chrono::duration<double>(Clock::now() - t_start).count();
  return r;
}

const std::uint8_t* colorPointer(const py::object& colors, std::size_t n, py::array_t<std::uint8_t, py::array::c_style>& keep) {
  if (colors.is_none()) return nullptr;
  keep = py::array_t<std::uint8_t, py::array::c_style>::ensure(colors);
  if (!keep || keep.ndim() != 2 || keep.shape(1) != 3 || static_cast<std::size_t>(keep.shape(0)) != n)
    throw py::value_error("colors: expected a uint8 (N, 3) array with one row per point");
  return keep.data();
}
bool first(const FrameResult& r) { return r.status == FrameStatus::Initialized; }

py::dict frameResultDict(const FrameResult& r) {
  py::dict d;
  d["index"] = r.index;
  d["timestamp"] = r.timestamp;
  d["status"] = std::string(toString(r.status));
  d["merged"] = r.merged();
  py::list T;
  for (int i = 0; i < 4; ++i) T.append(py::make_tuple(r.T_model_camera(i, 0), r.T_model_camera(i, 1), r.T_model_camera(i, 2),
                                                       r.T_model_camera(i, 3)));
  d["T_model_camera"] = T;
  d["converged"] = first(r) || r.icp.converged;
  d["icp_status"] = first(r) ? std::string() : std::string(toString(r.icp.status));
  d["iterations"] = r.icp.iterations;
  d["fitness"] = first(r) ? 1.0 : r.icp.fitness;
  d["inlier_rmse"] = first(r) ? 0.0 : r.icp.inlier_rmse;
  d["correspondences"] = r.icp.correspondence_count;
  d["input_points"] = r.input_points;
  d["frame_points"] = r.frame_points;
  d["model_points"] = r.model_points;
  d["far_points"] = r.far_points;
  d["prepare_seconds"] = r.prepare_seconds;
  d["register_seconds"] = r.register_seconds;
  d["merge_seconds"] = r.merge_seconds;
  d["total_seconds"] = r.total_seconds;
  return d;
}

std::string describe(const FrameResult& r) {
  std::ostringstream os;
  os << "FrameResult(index=" << r.index << ", status='" << toString(r.status) << "', frame_points=" << r.frame_points
     << ", model_points=" << r.model_points << ", iterations=" << r.icp.iterations << ", fitness=" << r.icp.fitness
     << ", total_seconds=" << r.total_seconds << ")";
  return os.str();
}
/// A per-point member (3 values a point) as an (N, 3) array of its type (an Eigen matrix, which
/// the field table shows as one), or None when empty and `none_when_empty`; set from any
/// (N, 3) array of real numbers (None: empty).
template <typename V>
using Rows = Eigen::Matrix<V, Eigen::Dynamic, 3, Eigen::RowMajor>;
template <typename V>
auto rowsGet(std::vector<V> PreparedFrame::*member, bool none_when_empty) {
  return [member, none_when_empty](const PreparedFrame& f) -> std::optional<Rows<V>> {
    if (none_when_empty && (f.*member).empty()) return std::nullopt;
    return Rows<V>(Eigen::Map<const Rows<V>>((f.*member).data(), static_cast<Eigen::Index>((f.*member).size() / 3), 3));
  };
}
template <typename V>
auto rowsSet(std::vector<V> PreparedFrame::*member, const char* where) {
  return [member, where](PreparedFrame& f, py::handle h) {
    (f.*member).clear();
    if (h.is_none()) return;
    const py::array given = fields::realArray(h, where, "an (N, 3) array");
    const auto a = py::array_t<V, py::array::c_style | py::array::forcecast>::ensure(given);
    if (!a || a.ndim() != 2 || a.shape(1) != 3)
      throw py::value_error(std::string(where) + ": expected an (N, 3) array");
    (f.*member).assign(a.data(), a.data() + a.size());
  };
}

}  // namespace

void defineReconstructionFrameToModel(py::module_& m) {
  using FS = FrameToModelSettings;
  fieldsOf(py::class_<FrameToModelSettings>(m, "FrameToModelSettings",
                                            "Settings of the frame-to-model pipeline (eye-in-hand paper (Comput. "
                                            "Electron. Agric. 180 (2021) 105929), §3). validate() raises ValueError "
                                            "naming a bad field."))
      .field("normal_radius", &FS::normal_radius, "m", "PCA normal radius (eye-in-hand paper §3.5: 0.005)")
      .field("model_voxel_size", &FS::model_voxel_size, "m",
             "voxel edge of the grid applied to the model after every merge (eye-in-hand paper §3.6: 0.001)")
      .field("frame_voxel_size", &FS::frame_voxel_size, "m",
             "voxel edge applied to each frame before normals and registration; 0 keeps full resolution")
      .field(
          "crop_box", [](const FS& s) { return s.crop_box; },
          [](FS& s, py::handle v) {
            if (v.is_none())
              s.crop_box = std::nullopt;
            else if (py::isinstance<Box>(v))  // Box(a Box) is no constructor: take it as it is
              s.crop_box = v.cast<Box>();
            else
              s.crop_box = py::type::of<Box>()(v).cast<Box>();
          },
          "m",
          "optional Box (or 6 numbers) in the frame's camera coordinates; points outside are dropped before "
          "anything, so they are neither registered nor merged (bounds the model to the workspace)")
      .field("min_frame_points", &FS::min_frame_points, "", "frames with fewer points after crop and downsampling are skipped")
      .field("min_fitness", &FS::min_fitness, "", "registrations whose inlier fraction is below this are rejected")
      .field("require_convergence", &FS::require_convergence, "",
             "reject registrations that hit the iteration cap (False for fixed iteration budgets as in eye-in-hand "
             "paper Figs. 6 and 9)")
      .field("max_translation_change", &FS::max_translation_change, "m",
             "largest accepted distance of the result from the initial guess (inf = off)")
      .field("max_rotation_change", &FS::max_rotation_change, "rad",
             "largest accepted rotation of the result from the initial guess (inf = off)")
      .name("motion_model", &FS::motion_model, 3, "",
            "initial guess of a frame integrated without one: 'previous' (eye-in-hand paper §3.2: the previous "
            "registration), 'constant_velocity' (the motion between the last two merged frames applied once more; "
            "fewer ICP iterations on a smooth scan path) or 'reference' (odometry-aided: the caller passes each "
            "frame's guess, the robot's reference motion since the last merged frame applied to that frame's "
            "estimate; without a guess, constant_velocity)")
      .field("num_threads", &FS::num_threads, "", "OpenMP threads for normals and ICP (overrides icp.num_threads when > 0), 0 = all cores")
      .field("icp", &FS::icp, "",
             "IcpSettings of the registration (eye-in-hand paper §3.3 convergence defaults; "
             "max_correspondence_distance 0.02 m here, as consecutive eye-in-hand frames move little; optional box "
             "rejector in the frame's camera coordinates, §3.4)")
      .settings()
      .def("validate", [](const FrameToModelSettings& s) { validate(s); });
  using R = FrameResult;
  fieldsOf(py::class_<R>(m, "FrameResult", "What the reconstruction did with one frame")
               .def(py::init<>())
               .def("to_dict", &frameResultDict, "the result as a JSON-ready dict (the columns of frames.csv, in order)")
               .def("__repr__", &describe))
      .output("index", &R::index, "", "0-based count of frames given to the pipeline")
      .field("timestamp", &R::timestamp, "s", "the frame's time stamp, as the caller gives it")
      .output("input_points", &R::input_points, "", "points given (before crop and downsampling)")
      .name("status", &R::status, 8, "",
            "'initialized', 'registered' or 'skipped_*' (empty, too_few_points, not_converged, "
            "too_few_correspondences, low_fitness, motion)",
            false)
      .output("T_model_camera", &R::T_model_camera, "m",
              "4x4 camera -> model pose; for a skipped frame the initial guess it was tried from")
      .output("icp", &R::icp, "", "IcpResult of the registration (defaults for the first frame)")
      .output("frame_points", &R::frame_points, "", "points after crop, downsampling and normals")
      .output("model_points", &R::model_points, "", "model size after this frame")
      .output("far_points", &R::far_points, "",
              "finite points dropped as beyond the voxel grids' range: over 2^19 frame voxels from the camera along "
              "an axis (524 m at 1 mm) or 2^20 model voxels from the first merged camera (1048 m)")
      .output("prepare_seconds", &R::prepare_seconds, "s", "crop + downsample + normals")
      .output("register_seconds", &R::register_seconds, "s", "tree build + ICP")
      .output("merge_seconds", &R::merge_seconds, "s", "transform + merge + voxel grid")
      .output("total_seconds", &R::total_seconds, "s", "the whole step")
      .derived("merged", [](const R& r) { return r.merged(); }, "", "the frame was added to the model")
      .derived("converged", [](const R& r) { return first(r) || r.icp.converged; }, "",
               "the registration converged (True for the first frame)")
      .derived("icp_status", [](const R& r) { return first(r) ? std::string() : std::string(toString(r.icp.status)); },
               "", "IcpStatus name ('' for the first frame)")
      .derived("iterations", [](const R& r) { return r.icp.iterations; }, "", "ICP iterations")
      .derived("fitness", [](const R& r) { return first(r) ? 1.0 : r.icp.fitness; }, "",
               "ICP inlier fraction (1 for the first frame)")
      .derived("inlier_rmse", [](const R& r) { return first(r) ? 0.0 : r.icp.inlier_rmse; }, "m",
               "ICP inlier RMS distance (0 for the first frame)")
      .derived("correspondences", [](const R& r) { return r.icp.correspondence_count; }, "",
               "ICP inlier correspondences")
      .result();

  using P = PreparedFrame;
  fieldsOf(py::class_<P>(m, "PreparedFrame", "A frame ready to register (camera frame, after crop and downsampling)")
               .def("__len__", &P::size))
      .field("points", rowsGet(&P::points, false), rowsSet(&P::points, "PreparedFrame.points"), "m",
             "(N, 3) float32 points", false)
      .field("normals", rowsGet(&P::normals, false), rowsSet(&P::normals, "PreparedFrame.normals"), "",
             "(N, 3) float32 unit normals, towards the camera", false)
      .field("colors", rowsGet(&P::colors, true), rowsSet(&P::colors, "PreparedFrame.colors"), "",
             "(N, 3) uint8 colours, or None", false)
      .output("input_points", &P::input_points, "", "points given to prepare()")
      .output("far_points", &P::far_points, "",
              "finite points dropped as beyond 2^19 frame voxels from the camera along an axis")
      .output("seconds", &P::seconds, "s", "time to crop, downsample and estimate normals")
      .result();

  py::class_<FrameToModel>(m, "FrameToModel",
                           "Frame-to-model reconstruction (eye-in-hand paper, Algorithm 1). A frame that is skipped, "
                           "and a call that raises (bad input, MemoryError, KeyboardInterrupt during the "
                           "registration), leave the model, the poses and the frame counts exactly as they were.")
      .def(py::init<FrameToModelSettings>(), py::arg("settings"))
      .def("reset", &FrameToModel::reset, py::arg("T_model_camera0"),
           "Empties the model; the next accepted frame is placed at T_model_camera0 (4x4 rigid)")
      .def(
          "prepare",
          [](const FrameToModel& self, const py::array& points, const py::object& colors) {
            const auto p = cloudView<float>(points, "points");
            py::array_t<std::uint8_t, py::array::c_style> keep;
            const std::uint8_t* c = colorPointer(colors, p.size, keep);
            py::gil_scoped_release release;
            return self.prepare(p, c);
          },
          py::arg("points"), py::arg("colors"))
      .def(
          "integrate",
          [](FrameToModel& self, const py::array& points, const py::object& colors,
             const std::optional<Eigen::Matrix4d>& guess, const std::string& registration) {
            const auto p = cloudView<float>(points, "points");
            py::array_t<std::uint8_t, py::array::c_style> keep;
            const std::uint8_t* c = colorPointer(colors, p.size, keep);
            if (registration == "scanalign" || !self.hasModel()) {
              py::gil_scoped_release release;
              return self.integrate(p, c, guess ? &*guess : nullptr);
            }
            const PclIcpVariant v = pclVariant(registration);
            py::gil_scoped_release release;
            return integrateWithPcl(self, p, c, guess, v);
          },
          py::arg("points"), py::arg("colors"), py::arg("guess"), py::arg("registration") = "scanalign",
          "One camera-frame cloud (float32 m, uint8 colours or None) registered from guess (T_model_camera or "
          "None: the motion model) by 'scanalign' or a stock PCL ICP 'pcl_<variant>', checked and merged")
      .def(
          "integrate_prepared",
          [](FrameToModel& self, const PreparedFrame& f, const std::optional<Eigen::Matrix4d>& guess) {
            py::gil_scoped_release release;
            return self.integratePrepared(f, guess ? &*guess : nullptr);
          },
          py::arg("frame"), py::arg("guess"))
      .def(
          "merge",
          [](FrameToModel& self, const PreparedFrame& f, const Eigen::Matrix4d& T) {
            py::gil_scoped_release release;
            return self.merge(f, T);
          },
          py::arg("frame"), py::arg("T_model_camera"),
          "Merges a frame at a pose found elsewhere; returns the model size. Points beyond 2^20 model voxels from "
          "the first merged camera are dropped. Raises ValueError (nothing merged) for a non-rigid pose")
      .def(
          "check", [](const FrameToModel& self, const IcpResult& r, const Eigen::Matrix4d& guess) {
            return std::string(toString(self.check(r, guess)));
          },
          py::arg("result"), py::arg("guess"), "The acceptance checks of integrate() on an external IcpResult")
      .def("model_points", [](const FrameToModel& self) { return vectorArray(self.model().points, 3); })
      .def("model_normals", [](const FrameToModel& self) { return vectorArray(self.model().normals, 3); })
      .def("model_colors", [](const FrameToModel& self) -> py::object {
        if (self.model().colors.empty()) return py::none();
        return vectorArray(self.model().colors, 3);
      })
      .def_property_readonly("model_size", [](const FrameToModel& self) { return self.model().size(); })
      .def_property_readonly("last_pose", [](const FrameToModel& self) { return self.lastPose(); },
                             "the last accepted T_model_camera (T_model_camera0 before any frame)")
      .def_property_readonly("predicted_pose", [](const FrameToModel& self) { return self.predictedPose(); },
                             "the initial guess T_model_camera of the next frame given none (motion_model)")
      .def_property_readonly("frames_seen", &FrameToModel::framesSeen)
      .def_property_readonly("frames_merged", &FrameToModel::framesMerged)
      .def_property(
          "settings", [](const FrameToModel& self) { return self.settings(); },
          [](FrameToModel& self, const FrameToModelSettings& s) {
            validate(s);
            self.settings() = s;
          });

  // Its voxel model (per-voxel sums and counts, the grid's hash) is not worth a format;
  // a worker rebuilds one from the settings and the frames.
  refusePickle<FrameToModel>(m, "FrameToModel",
                             "send its FrameToModelSettings and the frames (or the model's points from "
                             "model_points() / model_normals()) and build a FrameToModel in the worker");

  using RS = ReconstructionSettings;
  fieldsOf(py::class_<RS>(m, "ReconstructionSettings",
                          "Settings of the reconstruction job (depth images of an RGB-D sequence to a model, frame to "
                          "model: the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3, Algorithm 1). "
                          "validate() raises ValueError naming a bad field."))
      .field("min_depth", &RS::min_depth, "m",
             "nearer pixels are dropped (along z): sensors report garbage below their range")
      .field("max_depth", &RS::max_depth, "m", "farther pixels are dropped")
      .field("pixel_stride", &RS::pixel_stride, "", "use every pixel_stride-th pixel in both directions (1 = all)")
      .field("filter_depth", &RS::filter_depth, "",
             "bilateral-filter every depth image before back-projection (depth_filter): consumer sensors' axial "
             "noise tilts PCA normals (built-in SR300-like scan: ATE 12 -> 4 mm); the eye-in-hand paper had none")
      .field("depth_filter", &RS::depth_filter, "", "BilateralFilterSettings of the depth filter (used when filter_depth)")
      .field("frame_to_model", &RS::frame_to_model, "",
             "FrameToModelSettings of the pipeline. Defaults for a tabletop part and a consumer sensor, not the "
             "eye-in-hand paper's: motion_model 'constant_velocity', normal_radius 0.01 (5 mm is too few points "
             "above the noise), icp.box (-0.1, 0.1, -0.1, 0.1, 0.0001, 10), the paper's box rejector sized to a "
             "part's workspace (the table around it drags frames sideways; remove it for room-scale scans)")
      .name("model_frame", &RS::model_frame, 3, "",
            "the model's frame: 'camera' (the first camera's), 'base' (the robot base frame: the first frame placed at "
            "its reference pose T_base_camera, required) or 'auto' (base when the first frame has a reference pose, "
            "else camera)")
      .name("registration", &RS::registration, 4, "",
            "'scanalign' (the engine; its estimator in frame_to_model.icp.estimator) or a stock PCL ICP for "
            "comparison (eye-in-hand paper §3.7): 'pcl_svd', 'pcl_dual_quaternion', 'pcl_point_to_plane_lls'")
      .field("min_merged_fraction", &RS::min_merged_fraction, "",
             "a run merging fewer than this fraction of its frames has failed (result status 'failed', the command "
             "line exits 1), in [0, 1]")
      .settings()
      .def("validate", [](const RS& s) { validate(s); });

}

}  // namespace scanalign::python
