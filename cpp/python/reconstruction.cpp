#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <sstream>

#include "arrays.hpp"
#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/reconstruction/frame_to_model.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"

namespace scanalign::python {

namespace {
template <typename Scalar>
py::tuple voxel(const py::array& points, double leaf_size, const py::object& attributes, unsigned min_points) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  py::array_t<double, py::array::c_style> attrs;
  std::size_t dim = 0;
  if (!attributes.is_none()) {
    attrs = py::array_t<double, py::array::c_style>::ensure(attributes);
    if (!attrs || attrs.ndim() != 2 || static_cast<std::size_t>(attrs.shape(0)) != view.size)
      throw py::value_error("attributes: expected an (N, k) float64 array with one row per point");
    dim = static_cast<std::size_t>(attrs.shape(1));
  }
  VoxelGridResult r;
  {
    py::gil_scoped_release release;
    r = voxelGrid(view, leaf_size, dim ? attrs.data() : nullptr, dim, min_points);
  }
  const auto m = static_cast<py::ssize_t>(r.size());
  py::array_t<double> pts({m, py::ssize_t{3}});
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

template <typename DepthT>
py::tuple depthToCloudPy(const py::array_t<DepthT, py::array::c_style>& depth, const PinholeIntrinsics& K,
                         const DepthToCloudSettings& s, const py::object& rgb_obj) {
  if (depth.ndim() != 2 || depth.shape(0) != K.height || depth.shape(1) != K.width)
    throw py::value_error("depth: expected shape (" + std::to_string(K.height) + ", " + std::to_string(K.width) +
                          ") for these intrinsics");
  py::array_t<std::uint8_t, py::array::c_style> rgb;
  if (!rgb_obj.is_none()) {
    rgb = py::array_t<std::uint8_t, py::array::c_style>::ensure(rgb_obj);
    if (!rgb || rgb.ndim() != 3 || rgb.shape(0) != K.height || rgb.shape(1) != K.width || rgb.shape(2) != 3)
      throw py::value_error("rgb: expected a uint8 array of shape (height, width, 3) matching the depth image");
  }
  DepthCloud c;
  {
    py::gil_scoped_release release;
    c = depthToCloud(depth.data(), K, s, rgb_obj.is_none() ? nullptr : rgb.data());
  }
  py::object colors = py::none();
  if (!rgb_obj.is_none()) colors = toArray(c.colors, 3);
  py::array_t<std::int32_t> pixels(static_cast<py::ssize_t>(c.pixels.size()));
  std::copy(c.pixels.begin(), c.pixels.end(), pixels.mutable_data());
  return py::make_tuple(toArray(c.points, 3), colors, pixels);
}

const std::uint8_t* colorPointer(const py::object& colors, std::size_t n, py::array_t<std::uint8_t, py::array::c_style>& keep) {
  if (colors.is_none()) return nullptr;
  keep = py::array_t<std::uint8_t, py::array::c_style>::ensure(colors);
  if (!keep || keep.ndim() != 2 || keep.shape(1) != 3 || static_cast<std::size_t>(keep.shape(0)) != n)
    throw py::value_error("colors: expected a uint8 (N, 3) array with one row per point");
  return keep.data();
}

std::string describe(const FrameReport& r) {
  std::ostringstream os;
  os << "FrameReport(index=" << r.index << ", status='" << toString(r.status) << "', frame_points=" << r.frame_points
     << ", model_points=" << r.model_points << ", iterations=" << r.icp.iterations << ", fitness=" << r.icp.fitness
     << ", total_seconds=" << r.total_seconds << ")";
  return os.str();
}

}  // namespace

void defineReconstruction(py::module_& m) {
  py::class_<PinholeIntrinsics>(m, "PinholeIntrinsics")
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
      .def_readwrite("depth_scale", &DepthToCloudSettings::depth_scale)
      .def_readwrite("min_depth", &DepthToCloudSettings::min_depth)
      .def_readwrite("max_depth", &DepthToCloudSettings::max_depth)
      .def_readwrite("stride", &DepthToCloudSettings::stride);
  m.def(
      "bilateral_filter_depth",
      [](const py::array_t<float, py::array::c_style | py::array::forcecast>& depth, int radius, double sigma_space,
         double sigma_depth, int num_threads) {
        if (depth.ndim() != 2) throw py::value_error("depth: expected a 2-D float image in metres");
        const int h = static_cast<int>(depth.shape(0)), w = static_cast<int>(depth.shape(1));
        py::array_t<float> out({depth.shape(0), depth.shape(1)});
        float* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          bilateralFilterDepth(depth.data(), w, h, o, radius, sigma_space, sigma_depth, num_threads);
        }
        return out;
      },
      py::arg("depth"), py::arg("radius"), py::arg("sigma_space"), py::arg("sigma_depth"), py::arg("num_threads"));
  m.def("depth_to_cloud_u16", &depthToCloudPy<std::uint16_t>, py::arg("depth"), py::arg("intrinsics"),
        py::arg("settings"), py::arg("rgb"));
  m.def("depth_to_cloud_f32", &depthToCloudPy<float>, py::arg("depth"), py::arg("intrinsics"), py::arg("settings"),
        py::arg("rgb"));

  py::class_<FrameToModelSettings>(m, "FrameToModelSettings")
      .def(py::init<>())
      .def_readwrite("icp", &FrameToModelSettings::icp)
      .def_readwrite("normal_radius", &FrameToModelSettings::normal_radius)
      .def_readwrite("model_voxel_size", &FrameToModelSettings::model_voxel_size)
      .def_readwrite("frame_voxel_size", &FrameToModelSettings::frame_voxel_size)
      .def_readwrite("crop_box", &FrameToModelSettings::crop_box)
      .def_readwrite("min_frame_points", &FrameToModelSettings::min_frame_points)
      .def_readwrite("min_fitness", &FrameToModelSettings::min_fitness)
      .def_readwrite("require_convergence", &FrameToModelSettings::require_convergence)
      .def_readwrite("max_translation_change", &FrameToModelSettings::max_translation_change)
      .def_readwrite("max_rotation_change", &FrameToModelSettings::max_rotation_change)
      .def_readwrite("num_threads", &FrameToModelSettings::num_threads)
      .def_property(
          "motion_model", [](const FrameToModelSettings& s) { return std::string(toString(s.motion_model)); },
          [](FrameToModelSettings& s, const std::string& v) {
            if (v == toString(MotionModel::Previous))
              s.motion_model = MotionModel::Previous;
            else if (v == toString(MotionModel::ConstantVelocity))
              s.motion_model = MotionModel::ConstantVelocity;
            else
              throw py::value_error("motion_model must be 'previous' or 'constant_velocity', got '" + v + "'");
          })
      .def("validate", [](const FrameToModelSettings& s) { validate(s); });

  py::class_<FrameReport>(m, "FrameReport")
      .def_readonly("index", &FrameReport::index)
      .def_property_readonly("status", [](const FrameReport& r) { return std::string(toString(r.status)); })
      .def_property_readonly("merged", &FrameReport::merged)
      .def_property_readonly("T_model_camera", [](const FrameReport& r) { return r.T_model_camera; })
      .def_readonly("icp", &FrameReport::icp)
      .def_readonly("frame_points", &FrameReport::frame_points)
      .def_readonly("model_points", &FrameReport::model_points)
      .def_readonly("prepare_seconds", &FrameReport::prepare_seconds)
      .def_readonly("register_seconds", &FrameReport::register_seconds)
      .def_readonly("merge_seconds", &FrameReport::merge_seconds)
      .def_readonly("total_seconds", &FrameReport::total_seconds)
      .def("__repr__", py::overload_cast<const FrameReport&>(&describe));

  py::class_<PreparedFrame>(m, "PreparedFrame")
      .def_property_readonly("points", [](const PreparedFrame& f) { return toArray(f.points, 3); })
      .def_property_readonly("normals", [](const PreparedFrame& f) { return toArray(f.normals, 3); })
      .def_property_readonly("colors", [](const PreparedFrame& f) -> py::object {
        if (f.colors.empty()) return py::none();
        return toArray(f.colors, 3);
      })
      .def_readonly("input_points", &PreparedFrame::input_points)
      .def_readonly("seconds", &PreparedFrame::seconds)
      .def("__len__", &PreparedFrame::size);

  py::class_<FrameToModel>(m, "FrameToModel")
      .def(py::init<FrameToModelSettings>(), py::arg("settings"))
      .def("reset", &FrameToModel::reset, py::arg("T_model_camera0"))
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
          [](FrameToModel& self, const py::array& points, const py::object& colors, const std::optional<Eigen::Matrix4d>& guess) {
            const auto p = cloudView<float>(points, "points");
            py::array_t<std::uint8_t, py::array::c_style> keep;
            const std::uint8_t* c = colorPointer(colors, p.size, keep);
            py::gil_scoped_release release;
            return self.integrate(p, c, guess ? &*guess : nullptr);
          },
          py::arg("points"), py::arg("colors"), py::arg("guess"))
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
          py::arg("frame"), py::arg("T_model_camera"))
      .def(
          "check", [](const FrameToModel& self, const IcpResult& r, const Eigen::Matrix4d& guess) {
            return std::string(toString(self.check(r, guess)));
          },
          py::arg("result"), py::arg("guess"))
      .def("model_points", [](const FrameToModel& self) { return toArray(self.model().points, 3); })
      .def("model_normals", [](const FrameToModel& self) { return toArray(self.model().normals, 3); })
      .def("model_colors", [](const FrameToModel& self) -> py::object {
        if (self.model().colors.empty()) return py::none();
        return toArray(self.model().colors, 3);
      })
      .def_property_readonly("model_size", [](const FrameToModel& self) { return self.model().size(); })
      .def_property_readonly("last_pose", [](const FrameToModel& self) { return self.lastPose(); })
      .def_property_readonly("predicted_pose", [](const FrameToModel& self) { return self.predictedPose(); })
      .def_property_readonly("frames_seen", &FrameToModel::framesSeen)
      .def_property_readonly("frames_merged", &FrameToModel::framesMerged)
      .def_property(
          "settings", [](const FrameToModel& self) { return self.settings(); },
          [](FrameToModel& self, const FrameToModelSettings& s) {
            validate(s);
            self.settings() = s;
          });

  m.def("voxel_grid_f32", &voxel<float>, py::arg("points"), py::arg("leaf_size"), py::arg("attributes"),
        py::arg("min_points_per_voxel"));
  m.def("voxel_grid_f64", &voxel<double>, py::arg("points"), py::arg("leaf_size"), py::arg("attributes"),
        py::arg("min_points_per_voxel"));
}

}  // namespace scanalign::python
