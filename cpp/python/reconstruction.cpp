#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "arrays.hpp"
#include "fields.hpp"
#include "pickle.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/reconstruction/frame_to_model.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace scanalign::python {

namespace {

/// NotRealError: values that are not real numbers (strings, complex) where real ones belong.
/// A TypeError, and also a ValueError, which voxel_grid raised for them before: callers
/// catching that keep working (as NumPy's AxisError is both a ValueError and an IndexError).
py::handle notRealError() {
  static py::handle cls = PyErr_NewExceptionWithDoc(
      "scanalign._core.reconstruction.NotRealError",
      "Values that are not real numbers (strings, complex) where real ones belong: a TypeError (and a ValueError)",
      py::make_tuple(py::handle(PyExc_TypeError), py::handle(PyExc_ValueError)).release().ptr(), nullptr);
  return cls;
}

template <typename Scalar>
py::tuple voxel(const CloudView<Scalar>& view, double leaf_size, const py::object& attributes,
                const py::object& min_points_arg) {
  const auto min_points = intArg(min_points_arg, "min_points_per_voxel", 1, 0xFFFFFFFFLL);
  py::array_t<double, py::array::c_style> attrs;
  std::size_t dim = 0;
  if (!attributes.is_none()) {
    // Real numbers only: a string or complex array must not be parsed or lose its
    // imaginary part on the way to float64.
    const py::array given = py::array::ensure(attributes);
    if (!given || std::string("biuf").find(given.dtype().kind()) == std::string::npos) {
      const std::string message = "attributes: expected real numbers (bool, integer or float), got " +
                                  (given ? "dtype " + std::string(py::str(given.dtype())) : std::string("a non-array"));
      PyErr_SetString(notRealError().ptr(), message.c_str());
      throw py::error_already_set();
    }
    attrs = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(given);
    if (!attrs || attrs.ndim() != 2 || static_cast<std::size_t>(attrs.shape(0)) != view.size)
      throw py::value_error("attributes: expected an (N, k) array with one row per point");
    dim = static_cast<std::size_t>(attrs.shape(1));
  }
  VoxelGridResult r;
  {
    py::gil_scoped_release release;
    r = voxelGrid(view, leaf_size, dim ? attrs.data() : nullptr, dim, static_cast<std::uint32_t>(min_points));
  }
  const auto m = static_cast<py::ssize_t>(r.size());
  py::array_t<Scalar> pts({m, py::ssize_t{3}});
  std::copy(r.points.begin(), r.points.end(), pts.mutable_data());
  py::array_t<double> att({m, static_cast<py::ssize_t>(dim)});
  std::copy(r.attributes.begin(), r.attributes.end(), att.mutable_data());
  py::array_t<std::uint32_t> counts(m);
  std::copy(r.counts.begin(), r.counts.end(), counts.mutable_data());
  return py::make_tuple(pts, att, counts);
}

template <typename T>
py::array_t<T> toArray(const std::vector<T>& v, py::ssize_t cols) {
  py::array_t<T> a({static_cast<py::ssize_t>(v.size()) / cols, cols});
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

void checkImage(const py::array& depth, const PinholeIntrinsics& K) {
  if (depth.ndim() != 2) throw py::value_error("depth: expected a 2-D image, got " + std::to_string(depth.ndim()) + "-D");
  if (depth.shape(0) != K.height || depth.shape(1) != K.width)
    throw py::value_error("depth image is " + std::to_string(depth.shape(1)) + "x" + std::to_string(depth.shape(0)) +
                          " (WxH) but the intrinsics are " + std::to_string(K.width) + "x" + std::to_string(K.height));
}

/// uint16 depth as is; other integers when they fit uint16; floats as float32 metres.
/// Returns the (possibly converted) C-contiguous image and whether it is float.
std::pair<py::array, bool> depthImage(const py::array& depth) {
  const char kind = depth.dtype().kind();
  if (kind == 'f') return {py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(depth), true};
  if (kind != 'u' && kind != 'i')
    throw py::type_error("depth: expected uint16 or float, got dtype " + std::string(py::str(depth.dtype())));
  if (!holds<std::uint16_t>(depth) && depth.size() > 0) {
    const auto wide = py::array_t<std::int64_t, py::array::forcecast>::ensure(depth);
    const auto* d = wide.data();
    for (py::ssize_t i = 0; i < wide.size(); ++i)
      if (d[i] < 0 || d[i] > 65535) throw py::value_error("depth: integer depth must fit uint16 (0..65535)");
  }
  return {py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>::ensure(depth), false};
}

py::tuple depthToCloudPy(const py::array& depth_in, const PinholeIntrinsics& K, const DepthToCloudSettings& s,
                         const py::object& rgb_obj, const py::object& rays_obj) {
  checkImage(depth_in, K);
  // The ray table of a distorted camera (undistorted_rays): (H, W, 2) float64, used as is.
  py::array_t<double, py::array::c_style> rays;
  if (!rays_obj.is_none()) {
    const auto a = py::cast<py::array>(rays_obj);
    if (a.ndim() != 3 || a.shape(0) != K.height || a.shape(1) != K.width || a.shape(2) != 2)
      throw py::value_error("rays: expected shape (" + std::to_string(K.height) + ", " + std::to_string(K.width) +
                            ", 2) matching the depth image (undistorted_rays of its intrinsics)");
    if (!holds<double>(a)) throw py::type_error("rays: expected float64, got " + std::string(py::str(a.dtype())));
    rays = py::array_t<double, py::array::c_style>::ensure(a);
  }
  const double* r = rays_obj.is_none() ? nullptr : rays.data();
  const auto [depth, is_float] = depthImage(depth_in);
  py::array_t<std::uint8_t, py::array::c_style> rgb;
  if (!rgb_obj.is_none()) {
    const auto a = py::cast<py::array>(rgb_obj);
    if (a.ndim() != 3 || a.shape(0) != K.height || a.shape(1) != K.width || a.shape(2) != 3)
      throw py::value_error("rgb: expected shape (" + std::to_string(K.height) + ", " + std::to_string(K.width) +
                            ", 3) matching the depth image");
    if (!holds<std::uint8_t>(a))
      throw py::type_error("rgb: expected uint8, got " + std::string(py::str(a.dtype())));
    rgb = py::array_t<std::uint8_t, py::array::c_style>::ensure(a);
  }
  const std::uint8_t* c = rgb_obj.is_none() ? nullptr : rgb.data();
  DepthCloud cloud;
  {
    py::gil_scoped_release release;
    cloud = is_float ? depthToCloud(static_cast<const float*>(depth.data()), K, s, c, r)
                     : depthToCloud(static_cast<const std::uint16_t*>(depth.data()), K, s, c, r);
  }
  py::object colors = py::none();
  if (c) colors = toArray(cloud.colors, 3);
  py::array_t<std::int32_t> pixels(static_cast<py::ssize_t>(cloud.pixels.size()));
  std::copy(cloud.pixels.begin(), cloud.pixels.end(), pixels.mutable_data());
  return py::make_tuple(toArray(cloud.points, 3), colors, pixels);
}

/// Float metres with NaN for invalid pixels: float images as they are, integer images
/// times depth_scale with 0 = invalid.
py::array_t<float, py::array::c_style> depthMetres(const py::array& depth, double depth_scale) {
  if (depth.ndim() != 2) throw py::value_error("depth: expected a 2-D image, got " + std::to_string(depth.ndim()) + "-D");
  const auto [image, is_float] = depthImage(depth);
  if (is_float) return py::array_t<float, py::array::c_style>::ensure(image);
  if (!(depth_scale > 0.0 && depth_scale <= 1.0))  // as depthToCloud: 65535 units stay finite metres
    throw py::value_error("depth_scale must be in (0, 1] metres per unit");
  py::array_t<float, py::array::c_style> out({image.shape(0), image.shape(1)});
  const auto* d = static_cast<const std::uint16_t*>(image.data());
  float* o = out.mutable_data();
  for (py::ssize_t i = 0; i < image.size(); ++i)
    o[i] = d[i] == 0 ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(d[i]) * static_cast<float>(depth_scale);
  return out;
}

/// "pcl_svd", "pcl_dual_quaternion", "pcl_point_to_plane_lls", ...: the stock PCL ICP variant.
PclIcpVariant pclVariant(const std::string& registration) {
  for (auto v : {PclIcpVariant::Svd, PclIcpVariant::DualQuaternion, PclIcpVariant::PointToPlaneLLS,
                 PclIcpVariant::ScanalignPointToPlaneLLS})
    if (registration == std::string("pcl_") + toString(v)) return v;
  throw py::value_error("registration must be 'scanalign' or 'pcl_' + a PCL ICP variant, got '" + registration + "'");
}

/// Runs a stock PCL ICP where FrameToModel::integrate runs the engine: prepare, register
/// to the model from the guess, check, merge (the pipeline's PCL baselines).
FrameReport integrateWithPcl(FrameToModel& self, const CloudView<float>& points, const std::uint8_t* colors,
                             const std::optional<Eigen::Matrix4d>& guess, PclIcpVariant variant) {
  const auto t_start = std::chrono::steady_clock::now();
  FrameReport r;
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

bool first(const FrameReport& r) { return r.status == FrameStatus::Initialized; }

py::dict frameReportDict(const FrameReport& r) {
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

std::string describe(const FrameReport& r) {
  std::ostringstream os;
  os << "FrameReport(index=" << r.index << ", status='" << toString(r.status) << "', frame_points=" << r.frame_points
     << ", model_points=" << r.model_points << ", iterations=" << r.icp.iterations << ", fitness=" << r.icp.fitness
     << ", total_seconds=" << r.total_seconds << ")";
  return os.str();
}

/// A per-point vector (3 values per point) as a pickled field: an (N, 3) array, as the
/// Python property shows it.
template <typename T, typename V>
PickleField<T> rowsField(const char* name, std::vector<V> T::*member) {
  return {name, [member](const T& t) { return py::object(toArray(t.*member, 3)); },
          [member](T& t, py::handle h, const std::string& what) {
            const auto rows = pickling::arrayToVector<std::vector<Eigen::Matrix<V, 3, 1>>>(h, what);
            (t.*member).clear();
            for (const auto& r : rows) (t.*member).insert((t.*member).end(), r.data(), r.data() + 3);
          }};
}

void pickleReconstruction(py::module_& m) {
  using K = PinholeIntrinsics;
  pickleFields(m, "PinholeIntrinsics", field("width", &K::width), field("height", &K::height), field("fx", &K::fx),
               field("fy", &K::fy), field("cx", &K::cx), field("cy", &K::cy));
  using D = DepthToCloudSettings;
  pickleFields(m, "DepthToCloudSettings", field("depth_scale", &D::depth_scale), field("min_depth", &D::min_depth),
               field("max_depth", &D::max_depth), field("stride", &D::stride));
  using S = FrameToModelSettings;
  using R = FrameReport;
  pickleFields(m, "FrameReport", field("index", &R::index), field("timestamp", &R::timestamp),
               field("input_points", &R::input_points), namedEnum("status", &R::status, 8),
               field("T_model_camera", &R::T_model_camera), field("icp", &R::icp),
               field("frame_points", &R::frame_points), field("model_points", &R::model_points),
               field("far_points", &R::far_points), field("prepare_seconds", &R::prepare_seconds),
               field("register_seconds", &R::register_seconds), field("merge_seconds", &R::merge_seconds),
               field("total_seconds", &R::total_seconds));
  using P = PreparedFrame;
  pickleFields(m, "PreparedFrame", rowsField("points", &P::points), rowsField("normals", &P::normals),
               rowsField("colors", &P::colors), field("input_points", &P::input_points),
               field("far_points", &P::far_points), field("seconds", &P::seconds));
  // Its voxel model (per-voxel sums and counts, the grid's hash) is not worth a format;
  // a worker rebuilds one from the settings and the frames.
  refusePickle<FrameToModel>(m, "FrameToModel",
                             "send its FrameToModelSettings and the frames (or the model's points from "
                             "model_points() / model_normals()) and build a FrameToModel in the worker");
}

}  // namespace

void defineReconstruction(py::module_& m) {
  m.attr("NotRealError") = notRealError();
  py::class_<PinholeIntrinsics>(m, "PinholeIntrinsics", "Pinhole intrinsics of a depth image (OpenCV convention)")
      .def(py::init([](int w, int h, double fx, double fy, double cx, double cy) {
             PinholeIntrinsics k{w, h, fx, fy, cx, cy};
             k.validate();
             return k;
           }),
           py::arg("width"), py::arg("height"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"))
      .def_readonly("width", &PinholeIntrinsics::width, "pixels")
      .def_readonly("height", &PinholeIntrinsics::height, "pixels")
      .def_readonly("fx", &PinholeIntrinsics::fx, "focal length along x, pixels")
      .def_readonly("fy", &PinholeIntrinsics::fy, "focal length along y, pixels")
      .def_readonly("cx", &PinholeIntrinsics::cx, "principal point column, pixels")
      .def_readonly("cy", &PinholeIntrinsics::cy, "principal point row, pixels");
  py::class_<DepthToCloudSettings>(m, "DepthToCloudSettings")
      .def(py::init<>())
      .def_readwrite("depth_scale", &DepthToCloudSettings::depth_scale,
                     "metres per unit of an integer image, in (0, 1] (1e-3: millimetres; TUM: 1/5000); float images "
                     "are metres")
      .def_readwrite("min_depth", &DepthToCloudSettings::min_depth, "nearer pixels are dropped, m along z (0.1)")
      .def_readwrite("max_depth", &DepthToCloudSettings::max_depth, "farther pixels are dropped, m (2.0)")
      .def_readwrite("stride", &DepthToCloudSettings::stride, "use every stride-th pixel in both directions (1)");
  m.def(
      "bilateral_filter_depth",
      [](const py::array& depth, const py::object& radius_arg, double sigma_space, double sigma_depth,
         double depth_scale, const py::object& threads_arg) {
        const int radius = static_cast<int>(intArg(radius_arg, "radius", 0, 32));
        // Thread counts beyond the machine are clamped by resolveThreads (common/threads.hpp).
        const int num_threads = static_cast<int>(intArg(threads_arg, "num_threads", 0, 1 << 30));
        if (depth.ndim() != 2) throw py::value_error("depth: expected a 2-D image, got " + std::to_string(depth.ndim()) + "-D");
        // Before any conversion or allocation (a broadcast view claims any size for free).
        if (depth.size() > 0) checkImageSize(depth.shape(1), depth.shape(0), "depth");
        const auto d = depthMetres(depth, depth_scale);
        const int h = static_cast<int>(d.shape(0)), w = static_cast<int>(d.shape(1));
        py::array_t<float> out({d.shape(0), d.shape(1)});
        float* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          bilateralFilterDepth(d.data(), w, h, o, radius, sigma_space, sigma_depth, num_threads);
        }
        return out;
      },
      py::arg("depth"), py::arg("radius"), py::arg("sigma_space"), py::arg("sigma_depth"), py::arg("depth_scale"),
      py::arg("num_threads"),
      "(H, W) float32 metres (NaN = invalid) of a uint16 (units of depth_scale m, 0 = invalid) or float (m) image; "
      "an empty image gives an empty one, a pixel whose mean overflows float32 NaN. ValueError for an image beyond "
      "kMaxImagePixels (2^27) pixels, checked before allocating, a radius outside [0, 32] pixels, sigma_space < "
      "1e-3 pixels, sigma_depth < 1e-9 m or depth_scale outside (0, 1] m per unit");
  m.def("depth_to_cloud", &depthToCloudPy, py::arg("depth"), py::arg("intrinsics"), py::arg("settings"),
        py::arg("rgb"), py::arg("rays") = py::none(),
        "(points (N, 3) float32 m, colors (N, 3) uint8 or None, pixels (N,) int32 row * W + column); rays: None "
        "(pinhole) or the (H, W, 2) float64 undistorted_rays table of a distorted camera");
  m.def(
      "undistorted_rays",
      [](const PinholeIntrinsics& K, const std::vector<double>& coefficients, int max_iterations,
         double max_reprojection_error, int num_threads) {
        if (coefficients.size() != 5)
          throw py::value_error("distortion: expected 5 coefficients (k1, k2, p1, p2, k3), got " +
                                std::to_string(coefficients.size()));
        const LensDistortion d{coefficients[0], coefficients[1], coefficients[2], coefficients[3], coefficients[4]};
        std::vector<double> rays;
        {
          py::gil_scoped_release release;
          rays = undistortedRays(K, d, max_iterations, max_reprojection_error, num_threads);
        }
        py::array_t<double> out(
            {static_cast<py::ssize_t>(K.height), static_cast<py::ssize_t>(K.width), py::ssize_t{2}});
        std::copy(rays.begin(), rays.end(), out.mutable_data());
        return out;
      },
      py::arg("intrinsics"), py::arg("distortion"), py::arg("max_iterations") = 100,
      py::arg("max_reprojection_error") = 1e-3, py::arg("num_threads") = 0,
      "(H, W, 2) float64: the undistorted normalised coordinates (x, y) = (X/Z, Y/Z) of every pixel centre of a "
      "Brown-Conrady camera (distortion k1 k2 p1 p2 k3, OpenCV's order), by OpenCV undistortPoints' fixed-point "
      "iteration; NaN where the ray does not re-project onto its pixel within max_reprojection_error pixels");

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
      .name("motion_model", &FS::motion_model, 2, "",
            "initial guess of a frame integrated without one: 'previous' (eye-in-hand paper §3.2: the previous "
            "registration) or 'constant_velocity' (the motion between the last two merged frames applied once more; "
            "fewer ICP iterations on a smooth scan path)")
      .field("num_threads", &FS::num_threads, "", "OpenMP threads for normals and ICP (overrides icp.num_threads when > 0), 0 = all cores")
      .field("icp", &FS::icp, "",
             "IcpSettings of the registration (eye-in-hand paper §3.3 convergence defaults; "
             "max_correspondence_distance 0.02 m here, as consecutive eye-in-hand frames move little; optional box "
             "rejector in the frame's camera coordinates, §3.4)")
      .settings()
      .def("validate", [](const FrameToModelSettings& s) { validate(s); });

  py::class_<FrameReport>(m, "FrameReport", "What the reconstruction did with one frame")
      .def(py::init<>())
      .def_readonly("index", &FrameReport::index, "0-based count of frames given to the pipeline")
      .def_readwrite("timestamp", &FrameReport::timestamp, "the frame's time stamp, s")
      .def_property_readonly(
          "status", [](const FrameReport& r) { return std::string(toString(r.status)); },
          "'initialized', 'registered' or 'skipped_*' (empty, too_few_points, not_converged, "
          "too_few_correspondences, low_fitness, motion)")
      .def_property_readonly("merged", &FrameReport::merged, "the frame was added to the model")
      .def_property_readonly(
          "T_model_camera", [](const FrameReport& r) { return r.T_model_camera; },
          "4x4 camera -> model pose; for a skipped frame the initial guess it was tried from")
      .def_readonly("icp", &FrameReport::icp, "IcpResult of the registration (defaults for the first frame)")
      .def_readonly("frame_points", &FrameReport::frame_points, "points after crop, downsampling and normals")
      .def_readonly("model_points", &FrameReport::model_points, "model size after this frame")
      .def_readonly("far_points", &FrameReport::far_points,
                    "finite points dropped as beyond the voxel grids' range: over 2^19 frame voxels from the camera "
                    "along an axis (524 m at 1 mm) or 2^20 model voxels from the first merged camera (1048 m)")
      .def_readonly("prepare_seconds", &FrameReport::prepare_seconds, "crop + downsample + normals, s")
      .def_readonly("register_seconds", &FrameReport::register_seconds, "tree build + ICP, s")
      .def_readonly("merge_seconds", &FrameReport::merge_seconds, "transform + merge + voxel grid, s")
      .def_readonly("total_seconds", &FrameReport::total_seconds, "s")
      .def_readonly("input_points", &FrameReport::input_points, "points given (before crop and downsampling)")
      .def_property_readonly("converged", [](const FrameReport& r) { return first(r) || r.icp.converged; },
                             "the registration converged (True for the first frame)")
      .def_property_readonly(
          "icp_status", [](const FrameReport& r) { return first(r) ? std::string() : std::string(toString(r.icp.status)); },
          "IcpStatus name ('' for the first frame)")
      .def_property_readonly("iterations", [](const FrameReport& r) { return r.icp.iterations; }, "ICP iterations")
      .def_property_readonly("fitness", [](const FrameReport& r) { return first(r) ? 1.0 : r.icp.fitness; },
                             "ICP inlier fraction (1 for the first frame)")
      .def_property_readonly("inlier_rmse", [](const FrameReport& r) { return first(r) ? 0.0 : r.icp.inlier_rmse; },
                             "ICP inlier RMS distance, m (0 for the first frame)")
      .def_property_readonly("correspondences", [](const FrameReport& r) { return r.icp.correspondence_count; },
                             "ICP inlier correspondences")
      .def("to_dict", &frameReportDict, "the report as a JSON-ready dict (the columns of frames.csv, in order)")
      .def("__repr__", py::overload_cast<const FrameReport&>(&describe));

  py::class_<PreparedFrame>(m, "PreparedFrame", "A frame ready to register (camera frame, after crop and downsampling)")
      .def_property_readonly("points", [](const PreparedFrame& f) { return toArray(f.points, 3); }, "(N, 3) float32 m")
      .def_property_readonly("normals", [](const PreparedFrame& f) { return toArray(f.normals, 3); }, "(N, 3) unit")
      .def_property_readonly("colors", [](const PreparedFrame& f) -> py::object {
        if (f.colors.empty()) return py::none();
        return toArray(f.colors, 3);
      }, "(N, 3) uint8 or None")
      .def_readonly("input_points", &PreparedFrame::input_points, "points given to prepare()")
      .def_readonly("far_points", &PreparedFrame::far_points,
                    "finite points dropped as beyond 2^19 frame voxels from the camera along an axis")
      .def_readonly("seconds", &PreparedFrame::seconds, "time to crop, downsample and estimate normals, s")
      .def("__len__", &PreparedFrame::size);

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
      .def("model_points", [](const FrameToModel& self) { return toArray(self.model().points, 3); })
      .def("model_normals", [](const FrameToModel& self) { return toArray(self.model().normals, 3); })
      .def("model_colors", [](const FrameToModel& self) -> py::object {
        if (self.model().colors.empty()) return py::none();
        return toArray(self.model().colors, 3);
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

  pickleReconstruction(m);
  m.def(
      "voxel_grid",
      [](const py::array& points, double leaf_size, const py::object& attributes,
         const py::object& min_points_per_voxel) {
        if (holds<float>(points))
          return voxel(cloudView<float>(points, "points"), leaf_size, attributes, min_points_per_voxel);
        return voxel(cloudView<double>(points, "points"), leaf_size, attributes, min_points_per_voxel);
      },
      py::arg("points"), py::arg("leaf_size"), py::arg("attributes"), py::arg("min_points_per_voxel"),
      "(centroids (M, 3) in the points' dtype, m; attribute means (M, k) float64; counts (M,)): pcl::VoxelGrid "
      "voxel for voxel. ValueError for a leaf that is not finite and positive or gives over 2^21 voxels along an "
      "axis; TypeError for attributes that are not real numbers (strings, complex)");
}

}  // namespace scanalign::python
