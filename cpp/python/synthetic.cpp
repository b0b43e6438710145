// _core.synthetic: the z-buffer depth renderer, the built-in part's mesh and the Morton
// order behind scanalign.rendering, scanalign.parts and the simulator's scene.
#include <cmath>
#include <limits>
#include <string>

#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "pickle.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"
#include "scanalign/synthetic/builtin_part.hpp"
#include "scanalign/common/morton_order.hpp"
#include "scanalign/synthetic/scan_paths.hpp"
#include "scanalign/synthetic/sensor_noise.hpp"

namespace scanalign::python {

namespace {

/// (M, 3) faces of any integer dtype as int32, every index checked against [0, n_vertices)
/// before the cast (an int64 index must not wrap into range).
std::vector<std::int32_t> facesArg(const py::array& faces, py::ssize_t n_vertices) {
  if (faces.size() == 0 && faces.ndim() <= 2) return {};
  const char kind = faces.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw py::type_error("faces: expected an integer array, got dtype " + std::string(py::str(faces.dtype())));
  if (faces.ndim() != 2 || faces.shape(1) != 3)
    throw py::value_error("faces: expected shape (M, 3), got " + std::string(py::str(faces.attr("shape"))));
  const auto f = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(faces);
  const std::int64_t* p = f.data();
  const auto [lo, hi] = std::minmax_element(p, p + f.size());
  if (*lo < 0 || *hi >= n_vertices)
    throw py::value_error("faces: vertex indices must lie in [0, " + std::to_string(n_vertices) + "), got [" +
                          std::to_string(*lo) + ", " + std::to_string(*hi) + "]");
  return std::vector<std::int32_t>(p, p + f.size());
}

py::tuple renderDepthPy(const py::array& vertices, const py::array& faces, int width, int height, double fx, double fy,
                        double cx, double cy, const Eigen::Matrix4d& T_camera_world, double near_clip, double far_clip,
                        bool cull_backfaces, int num_threads) {
  if (width < 1 || height < 1 || width > 32768 || height > 32768)
    throw py::value_error("width, height: image size must be in [1, 32768] pixels, got " + std::to_string(width) +
                          " x " + std::to_string(height));
  checkImageSize(width, height, "width, height");  // before allocating the three images
  const bool f32 = holds<float>(vertices);
  CloudView<float> vf;
  CloudView<double> vd;
  if (f32)
    vf = cloudView<float>(vertices, "vertices");
  else
    vd = cloudView<double>(vertices, "vertices");  // raises TypeError for other dtypes
  const std::vector<std::int32_t> f = facesArg(faces, vertices.shape(0));
  const PinholeCamera camera{width, height, fx, fy, cx, cy};
  DepthRenderSettings settings;
  settings.near_clip = near_clip;
  settings.far_clip = far_clip;
  settings.cull_backfaces = cull_backfaces;
  settings.num_threads = num_threads;
  const py::ssize_t h = height, w = width;
  py::array_t<float> depth({h, w});
  py::array_t<std::int32_t> face_id({h, w});
  py::array_t<float> cosine({h, w});
  const DepthRenderOutput out{depth.mutable_data(), face_id.mutable_data(), cosine.mutable_data()};
  {
    py::gil_scoped_release release;
    if (f32)
      renderDepth(vf, f.data(), f.size() / 3, camera, T_camera_world, settings, out);
    else
      renderDepth(vd, f.data(), f.size() / 3, camera, T_camera_world, settings, out);
  }
  return py::make_tuple(depth, face_id, cosine);
}

/// A count argument (n_frames): a Python or NumPy integer, or a float holding an integer
/// (2.0), as an int; a TypeError or ValueError naming `what` otherwise, instead of pybind11's
/// signature dump (1e9 as a float, 2**40, 2.5, NaN, a string).
int countArg(const py::object& o, const char* what) {
  const std::string got = std::string(py::repr(o));
  if (py::isinstance<py::bool_>(o) || !(py::hasattr(o, "__index__") || py::isinstance<py::float_>(o)))
    throw py::type_error(std::string(what) + ": expected an integer, got " + got);
  double v;
  if (py::hasattr(o, "__index__")) {
    int overflow = 0;
    const long long i = PyLong_AsLongLongAndOverflow(py::int_(o).ptr(), &overflow);
    v = overflow ? overflow * std::numeric_limits<double>::infinity() : static_cast<double>(i);
  } else {
    v = o.cast<double>();
    if (!(std::isfinite(v) && v == std::floor(v))) throw py::value_error(std::string(what) + ": expected an integer, got " + got);
  }
  if (!(v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()))
    throw py::value_error(std::string(what) + " must be an integer in [1, " + std::to_string(kMaxPathFrames) + "], got " + got);
  return static_cast<int>(v);
}

py::array_t<double> posesArray(const Poses& poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  for (std::size_t k = 0; k < poses.size(); ++k)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) out.mutable_at(static_cast<py::ssize_t>(k), i, j) = poses[k](i, j);
  return out;
}

py::tuple builtinPartMeshPy(int segments, const std::string& name) {
  const BuiltinPartMesh m = builtinPartMesh(name, segments);
  const auto nv = static_cast<py::ssize_t>(m.vertices.size()), nf = static_cast<py::ssize_t>(m.faces.size());
  py::array_t<double> vertices({nv, py::ssize_t{3}});
  py::array_t<std::int64_t> faces({nf, py::ssize_t{3}});
  py::array_t<std::int32_t> surface(nf);
  for (py::ssize_t i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) vertices.mutable_at(i, k) = m.vertices[static_cast<std::size_t>(i)][k];
  for (py::ssize_t i = 0; i < nf; ++i) {
    for (int k = 0; k < 3; ++k) faces.mutable_at(i, k) = m.faces[static_cast<std::size_t>(i)][k];
    surface.mutable_at(i) = static_cast<std::int32_t>(m.surface[static_cast<std::size_t>(i)]);
  }
  return py::make_tuple(vertices, faces, surface);
}

py::array_t<float> applySensorNoisePy(const SensorNoise& noise, const py::array& depth, const py::array& cos_incidence,
                                      std::uint64_t seed) {
  using Image = py::array_t<float, py::array::c_style | py::array::forcecast>;
  // The size first, before a conversion allocates (a broadcast view claims any size for free).
  if (depth.ndim() == 2 && depth.size() > 0) checkImageSize(depth.shape(1), depth.shape(0), "depth");
  const auto z = Image::ensure(depth), c = Image::ensure(cos_incidence);
  if (!z || z.ndim() != 2) throw py::value_error("depth: expected an (H, W) float array");
  if (!c || c.ndim() != 2 || c.shape(0) != z.shape(0) || c.shape(1) != z.shape(1))
    throw py::value_error("cos_incidence: expected an array of the depth's shape (H, W)");
  py::array_t<float> out({z.shape(0), z.shape(1)});
  const auto w = static_cast<int>(z.shape(1)), h = static_cast<int>(z.shape(0));
  float* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    applySensorNoise(noise, z.data(), c.data(), w, h, seed, o);
  }
  return out;
}

void bindSensorNoise(py::module_& s) {
  const double inf = std::numeric_limits<double>::infinity();
  py::class_<SensorNoise>(s, "SensorNoise",
                          "A depth sensor's error model, applied to noise-free depth (see apply_sensor_noise): "
                          "dropouts at grazing incidence, on both sides of depth edges and at random, axial Gaussian "
                          "noise sigma(z) = axial_sigma_ref (z / z_ref)^2 (the depth error of a triangulation sensor "
                          "grows with the square of the distance), the range [min_range, max_range] and rounding to "
                          "depth_unit. Read-only (the presets are shared); invalid fields raise ValueError naming "
                          "them.")
      .def(py::init([](std::string name, double axial_sigma_ref, double z_ref, double depth_unit, double min_range,
                       double max_range, double grazing_cos, double edge_threshold, int edge_width, double dropout) {
             SensorNoise n{std::move(name), axial_sigma_ref, z_ref,          depth_unit, min_range,
                           max_range,       grazing_cos,     edge_threshold, edge_width, dropout};
             n.validate();
             return n;
           }),
           py::kw_only(), py::arg("name") = "custom", py::arg("axial_sigma_ref") = 0.0, py::arg("z_ref") = 1.0,
           py::arg("depth_unit") = 0.0, py::arg("min_range") = 0.0, py::arg("max_range") = inf,
           py::arg("grazing_cos") = 0.0, py::arg("edge_threshold") = 0.0, py::arg("edge_width") = 0,
           py::arg("dropout") = 0.0)
      .def_readonly("name", &SensorNoise::name, "label")
      .def_readonly("axial_sigma_ref", &SensorNoise::axial_sigma_ref, "standard deviation of the depth error at z_ref (m)")
      .def_readonly("z_ref", &SensorNoise::z_ref, "reference depth of axial_sigma_ref (m)")
      .def_readonly("depth_unit", &SensorNoise::depth_unit, "quantisation step of the reported depth (m); 0 for none")
      .def_readonly("min_range", &SensorNoise::min_range, "nearest measurable depth (m)")
      .def_readonly("max_range", &SensorNoise::max_range, "farthest measurable depth (m)")
      .def_readonly("grazing_cos", &SensorNoise::grazing_cos, "minimum |cosine of incidence| for a measurement")
      .def_readonly("edge_threshold", &SensorNoise::edge_threshold,
                    "relative depth jump marking a discontinuity; 0 disables edge dropout")
      .def_readonly("edge_width", &SensorNoise::edge_width, "pixels dropped on each side of a discontinuity")
      .def_readonly("dropout", &SensorNoise::dropout, "probability that any other pixel is missing")
      .def(
          "sigma",
          [](const SensorNoise& n, const py::array_t<double>& z) {
            return py::vectorize([&n](double v) { return n.sigma(v); })(z);
          },
          py::arg("z"),
           "Axial standard deviation (m) at depth z (m), element-wise for arrays.")
      .def("__repr__", [](const SensorNoise& n) {
        return "SensorNoise(name='" + n.name + "', axial_sigma_ref=" + std::to_string(n.axial_sigma_ref) +
               ", z_ref=" + std::to_string(n.z_ref) + ", depth_unit=" + std::to_string(n.depth_unit) + ", ...)";
      });
  using N = SensorNoise;
  pickleFields(s, "SensorNoise", field("name", &N::name), field("axial_sigma_ref", &N::axial_sigma_ref),
               field("z_ref", &N::z_ref), field("depth_unit", &N::depth_unit), field("min_range", &N::min_range),
               field("max_range", &N::max_range), field("grazing_cos", &N::grazing_cos),
               field("edge_threshold", &N::edge_threshold), field("edge_width", &N::edge_width),
               field("dropout", &N::dropout));
  s.def("apply_sensor_noise", &applySensorNoisePy, py::arg("noise"), py::arg("depth"), py::arg("cos_incidence"),
        py::arg("seed"),
        "Noisy (H, W) float32 depth in metres (NaN = missing) from noise-free `depth` (m, NaN = nothing hit) and the "
        "rendered `cos_incidence`, by the SensorNoise model; all randomness from the 64-bit `seed` (equal seeds give "
        "identical images with one build of the library). ValueError for an image beyond 2^27 pixels, before "
        "allocating.");
}

}  // namespace

void bindSynthetic(py::module_& m) {
  auto s = m.def_submodule("synthetic", "z-buffer depth renderer, the built-in part's mesh, Morton order");
  bindSensorNoise(s);
  s.def("render_depth", &renderDepthPy, py::arg("vertices"), py::arg("faces"), py::arg("width"), py::arg("height"),
        py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"), py::arg("T_camera_world"), py::arg("near_clip"),
        py::arg("far_clip"), py::arg("cull_backfaces"), py::arg("num_threads"),
        "Renders an (N,3) float32/float64 mesh with (M,3) integer faces (indices checked, naming faces); returns "
        "(depth float32 m, NaN = no hit; face_id int32, -1 = no hit; cos_incidence float32). ValueError for a size "
        "outside [1, 32768] or beyond 2^27 pixels in all, before allocating.");
  s.def(
      "loop_camera_poses",
      [](const py::object& n_frames, const Eigen::Vector3d& center, double height, double radius, double start_angle,
         double sweep, const Eigen::Vector3d& target) {
        return posesArray(
            loopCameraPoses(countArg(n_frames, "n_frames"), center, height, radius, start_angle, sweep, target));
      },
      py::arg("n_frames"), py::arg("center"), py::arg("height"), py::arg("radius"), py::arg("start_angle"),
      py::arg("sweep"), py::arg("target"),
      "(n_frames, 4, 4) T_base_camera on a loop: camera k at center + (radius cos a_k, radius sin a_k, height) (m), "
      "a_k = start_angle + sweep k / n_frames (rad), looking at target, image up +z (outwards when radius is 0). "
      "ValueError naming a bad argument (n_frames an integer in [1, 100000]; lengths and coordinates finite, within "
      "1e6 m), checked before allocating.");
  s.def(
      "hemisphere_camera_poses",
      [](const py::object& n_frames, const Eigen::Vector3d& target, double distance,
         const std::vector<double>& elevations, double start_angle) {
        return posesArray(
            hemisphereCameraPoses(countArg(n_frames, "n_frames"), target, distance, elevations, start_angle));
      },
      py::arg("n_frames"), py::arg("target"), py::arg("distance"), py::arg("elevations"), py::arg("start_angle"),
      "(n_frames, 4, 4) T_base_camera on rings at `distance` (m) from target, one per elevation (rad, in (0, pi/2]), "
      "frames shared in proportion to cos(elevation), successive rings in opposite directions. ValueError naming a "
      "bad argument (n_frames an integer in [number of rings, 100000]; distance and target within 1e6 m).");
  s.def("builtin_part_mesh", &builtinPartMeshPy, py::arg("segments"), py::arg("name") = "block",
        "A built-in part (see scanalign.parts: block, bracket, standoff) as a watertight mesh in metres, its own "
        "frame: (vertices (V,3) float64, faces (F,3) int64 wound counter-clockwise seen from outside, surface (F,) "
        "int32: 0 plane, 1 cylinder (boss, stud), 2 cap sphere). ValueError for segments outside [8, 4096] or an "
        "unknown name.");
  s.def(
      "builtin_part_symmetry",
      [](const std::string& name) {
        const PartSymmetry p = builtinPartSymmetry(name);
        return py::make_tuple(p.axis, p.point, p.order);
      },
      py::arg("name"),
      "(axis (3,), point (3,) m, order) of a built-in part's rotational symmetry in its model frame: order 1 = none, "
      "6 for the standoff (about z through the origin). ValueError for an unknown name.");
  s.attr("BUILTIN_PART_NAMES") = builtinPartNames();
  s.def(
      "morton_order",
      [](const py::array& points) {
        const CloudView<double> view = cloudView<double>(points, "points");
        std::vector<std::int64_t> order;
        std::vector<std::pair<std::uint64_t, std::int64_t>> keyed;
        {
          py::gil_scoped_release release;
          mortonOrder(view, order, keyed);
        }
        return py::array_t<std::int64_t>(static_cast<py::ssize_t>(order.size()), order.data());
      },
      py::arg("points"),
      "(N,) int64 permutation sorting (N,3) float64 points along a Morton (Z-order) curve of their bounding box "
      "(21 bits per axis; non-finite points last; ties keep input order).");
}

}  // namespace scanalign::python
