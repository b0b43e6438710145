// _core.reconstruction, depth images: the intrinsics type, back-projection (depth_to_cloud,
// undistorted_rays), the bilateral depth filter and the z-buffer depth renderer.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "arrays.hpp"
#include "fields.hpp"
#include "scanalign/reconstruction/bilateral_filter.hpp"
#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"

namespace scanalign::python {

namespace {

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
  if (isFloat32Or64(depth.dtype()))
    return {py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(depth), true};
  if (kind != 'u' && kind != 'i')
    throw py::type_error("depth: expected uint16 (or another integer type) or float32/float64, got dtype " + std::string(py::str(depth.dtype())));
  if (!holds<std::uint16_t>(depth) && depth.size() > 0) {
    const auto wide = py::array_t<std::int64_t, py::array::forcecast>::ensure(depth);
    const auto* d = wide.data();
    for (py::ssize_t i = 0; i < wide.size(); ++i)
      if (d[i] < 0 || d[i] > 65535) throw py::value_error("depth: integer depth must fit uint16 (0..65535)");
  }
  return {py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>::ensure(depth), false};
}

py::tuple depthToCloudPy(const py::array& depth_in, const PinholeIntrinsics& K, const DepthToCloudSettings& s,
                         const py::object& rgb_obj) {
  checkImage(depth_in, K);
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
    cloud = is_float ? depthToCloud(static_cast<const float*>(depth.data()), K, s, c)
                     : depthToCloud(static_cast<const std::uint16_t*>(depth.data()), K, s, c);
  }
  py::object colors = py::none();
  if (c) colors = vectorArray(cloud.colors, 3);
  return py::make_tuple(vectorArray(cloud.points, 3), colors, vectorArray(cloud.pixels));
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

py::array_t<float> bilateralFilterPy(const py::array& depth, const BilateralFilterSettings& s, double depth_scale,
                                     const py::object& threads_arg) {
  // Thread counts beyond the machine are clamped by resolveThreads (common/threads.hpp).
  const int num_threads = static_cast<int>(intArg(threads_arg, "num_threads", 0, 1 << 30));
  s.validate();
  if (depth.ndim() != 2) throw py::value_error("depth: expected a 2-D image, got " + std::to_string(depth.ndim()) + "-D");
  // Before any conversion or allocation (a broadcast view claims any size for free).
  if (depth.size() > 0) checkImageSize(depth.shape(1), depth.shape(0), "depth");
  const auto d = depthMetres(depth, depth_scale);
  const int h = static_cast<int>(d.shape(0)), w = static_cast<int>(d.shape(1));
  py::array_t<float> out({d.shape(0), d.shape(1)});
  float* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    bilateralFilterDepth(d.data(), w, h, o, s, num_threads);
  }
  return out;
}

/// (M, 3) faces of any integer dtype as int32, every index checked against [0, n_vertices)
/// before the cast (an int64 index must not wrap into range).
std::vector<std::int32_t> facesArg(const py::array& faces, py::ssize_t n_vertices) {
  const std::vector<std::int64_t> f = indexRows(faces, "faces", 3);
  if (f.empty()) return {};
  const auto [lo, hi] = std::minmax_element(f.begin(), f.end());
  if (*lo < 0 || *hi >= n_vertices)
    throw py::value_error("faces: vertex indices must lie in [0, " + std::to_string(n_vertices) + "), got [" +
                          std::to_string(*lo) + ", " + std::to_string(*hi) + "]");
  return std::vector<std::int32_t>(f.begin(), f.end());
}

py::tuple renderDepthPy(const py::array& vertices, const py::array& faces, const PinholeIntrinsics& camera,
                        const py::object& T_in, const DepthRenderSettings& settings) {
  // Through the field conversion: pybind11's Eigen caster would parse strings, drop imaginary parts.
  const Eigen::Matrix4d T_camera_world = fields::Conv<Eigen::Matrix4d>::set(T_in, "T_camera_world");
  if (camera.width < 1 || camera.height < 1 || camera.width > 32768 || camera.height > 32768)
    throw py::value_error("intrinsics: width, height must be in [1, 32768] pixels, got " +
                          std::to_string(camera.width) + " x " + std::to_string(camera.height));
  checkImageSize(camera.width, camera.height, "intrinsics");  // before allocating the three images
  const bool f32 = holds<float>(vertices);
  CloudView<float> vf;
  CloudView<double> vd;
  if (f32)
    vf = cloudView<float>(vertices, "vertices");
  else
    vd = cloudView<double>(vertices, "vertices");  // raises TypeError for other dtypes
  const std::vector<std::int32_t> f = facesArg(faces, vertices.shape(0));
  const py::ssize_t h = camera.height, w = camera.width;
  py::array_t<float> depth({h, w});
  py::array_t<std::int32_t> face_id({h, w});
  py::array_t<float> cosine({h, w});
  const DepthRenderResult out{depth.mutable_data(), face_id.mutable_data(), cosine.mutable_data()};
  {
    py::gil_scoped_release release;
    if (f32)
      renderDepth(vf, f.data(), f.size() / 3, camera, T_camera_world, settings, out);
    else
      renderDepth(vd, f.data(), f.size() / 3, camera, T_camera_world, settings, out);
  }
  return py::make_tuple(depth, face_id, cosine);
}

/// An image size: a Python or NumPy integer, or a float holding one (640.0); ValueError naming
/// `where` otherwise.
int sizeArg(py::handle v, const char* where) {
  if (fields::isInteger(v))
    return static_cast<int>(intArg(py::reinterpret_borrow<py::object>(v), where, -(1LL << 31), (1LL << 31) - 1));
  if (fields::isReal(v)) {
    const double d = PyFloat_AsDouble(v.ptr());
    if (std::isfinite(d) && d == std::floor(d) && std::abs(d) < 2147483648.0) return static_cast<int>(d);
  } else {
    throw py::type_error(std::string(where) + " must be a positive integer, got " + fields::shown(v));
  }
  throw py::value_error(std::string(where) + " must be a positive integer, got " + fields::shown(v));
}

/// The 5 distortion coefficients (k1, k2, p1, p2, k3) from any sequence or array of 5 finite
/// real numbers; ValueError otherwise.
LensDistortion distortionArg(py::handle v) {
  const auto fail = [&]() -> LensDistortion {
    throw py::value_error("PinholeIntrinsics.distortion must be 5 finite numbers (k1, k2, p1, p2, k3), got " +
                          fields::shown(v));
  };
  if (py::isinstance<py::str>(v) || py::isinstance<py::bytes>(v)) return fail();
  checkedArray(v, "PinholeIntrinsics.distortion", kReals);  // no strings parsed, no imaginary parts dropped
  py::array_t<double> a;
  try {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
        py::module_::import("numpy").attr("asarray")(v, "float64").attr("reshape")(-1));
  } catch (const py::error_already_set&) {
    return fail();
  }
  if (!a || a.size() != 5) return fail();
  const double* d = a.data();
  for (int k = 0; k < 5; ++k)
    if (!std::isfinite(d[k])) return fail();
  return LensDistortion{d[0], d[1], d[2], d[3], d[4]};
}

/// (k1, k2, p1, p2, k3): a Python tuple, so that it compares equal to one.
std::tuple<double, double, double, double, double> distortionTuple(const LensDistortion& d) {
  return {d.k1, d.k2, d.p1, d.p2, d.k3};
}

std::string describe(const PinholeIntrinsics& k) {
  const auto r = [](double x) { return std::string(py::repr(py::float_(x))); };
  std::string s = "PinholeIntrinsics(width=" + std::to_string(k.width) + ", height=" + std::to_string(k.height) +
                  ", fx=" + r(k.fx) + ", fy=" + r(k.fy) + ", cx=" + r(k.cx) + ", cy=" + r(k.cy);
  if (k.hasDistortion()) s += ", distortion=" + std::string(py::repr(py::cast(distortionTuple(k.distortion))));
  return s + ")";
}

double real(py::handle v, const char* where) { return fields::Conv<double>::set(v, where); }

void bindIntrinsics(py::module_& m) {
  using K = PinholeIntrinsics;
  fieldsOf(py::class_<K>(m, "PinholeIntrinsics",
                         "Intrinsics of a depth image, OpenCV convention: x right, y down, z along the optical axis; "
                         "pixel (u, v) = (column, row) has its centre at image coordinates (u, v); a camera point "
                         "projects to u = fx x_d + cx, v = fy y_d + cy, (x_d, y_d) the Brown-Conrady distortion of "
                         "(x/z, y/z) (zero: a pinhole camera). Immutable and hashable (a cache and dict key). The one "
                         "intrinsics type of the library (scanalign.reconstruction.camera.Intrinsics)")
               .def(py::init([](py::handle width, py::handle height, py::handle fx, py::handle fy, py::handle cx,
                                    py::handle cy, py::handle distortion) {
                      K k;
                      k.width = sizeArg(width, "PinholeIntrinsics.width");
                      k.height = sizeArg(height, "PinholeIntrinsics.height");
                      k.fx = real(fx, "PinholeIntrinsics.fx");
                      k.fy = real(fy, "PinholeIntrinsics.fy");
                      k.cx = real(cx, "PinholeIntrinsics.cx");
                      k.cy = real(cy, "PinholeIntrinsics.cy");
                      k.distortion = distortionArg(distortion);
                      k.validate();
                      return k;
                    }),
                    py::arg("width"), py::arg("height"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
                    py::arg("distortion") = py::make_tuple(0.0, 0.0, 0.0, 0.0, 0.0),
                    "Validated intrinsics (ValueError naming a bad value: size, focal lengths, principal point, "
                    "distortion)")
               .def("scaled", &K::scaled, py::arg("factor"),
                    "The intrinsics of the image resized by factor (e.g. 0.5 for half resolution): size rounded "
                    "(halves to even), focal lengths scaled, the principal point mapped as (c + 0.5) factor - 0.5 "
                    "(pixel centres sit at integer coordinates), the distortion (on normalised coordinates) kept")
               .def(
                   "to_dict",
                   [](const K& k) {
                     py::dict d;
                     d["width"] = k.width;
                     d["height"] = k.height;
                     d["fx"] = k.fx;
                     d["fy"] = k.fy;
                     d["cx"] = k.cx;
                     d["cy"] = k.cy;
                     if (k.hasDistortion()) d["distortion"] = py::list(py::cast(distortionTuple(k.distortion)));
                     return d;
                   },
                   "The fields as a JSON-ready dict (width, height, fx, fy, cx, cy; distortion as a list only when "
                   "it is not zero): the keys scanalign.reconstruction.camera.intrinsics_from_dict reads")
               .def("__repr__", &describe))
      .output("width", &K::width, "px", "image width")
      .output("height", &K::height, "px", "image height")
      .output("fx", &K::fx, "px", "focal length along x")
      .output("fy", &K::fy, "px", "focal length along y")
      .output("cx", &K::cx, "px", "principal point column (of the optical axis)")
      .output("cy", &K::cy, "px", "principal point row (of the optical axis)")
      .field(
          "distortion", [](const K& k) { return distortionTuple(k.distortion); },
          [](K& k, py::handle v) { k.distortion = distortionArg(v); }, "",
          "Brown-Conrady lens distortion (k1, k2, p1, p2, k3) of normalised image coordinates, OpenCV's order (ROS "
          "camera_info 'plumb_bob'); all zero for a pinhole camera or rectified images. Back-projection undistorts "
          "every pixel's ray as OpenCV's undistortPoints does",
          false)
      .derived("K", [](const K& k) { return k.K(); }, "px", "the 3x3 camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]")
      .derived("shape", [](const K& k) { return std::make_pair(k.height, k.width); }, "px",
               "(height, width): the shape a depth image for these intrinsics must have")
      .derived("has_distortion", [](const K& k) { return k.hasDistortion(); }, "",
               "any distortion coefficient is non-zero")
      .result()
      .def("__hash__", [](const K& k) {
        return py::hash(py::make_tuple(k.width, k.height, k.fx, k.fy, k.cx, k.cy, py::cast(distortionTuple(k.distortion))));
      });
}

}  // namespace

void defineReconstructionDepth(py::module_& m) {
  bindIntrinsics(m);

  using D = DepthToCloudSettings;
  fieldsOf(py::class_<D>(m, "DepthToCloudSettings", "Which pixels of a depth image become points (depth_to_cloud)"))
      .field("depth_scale", &D::depth_scale, "m",
             "metres per unit of an integer image, in (0, 1] (1e-3: millimetres; TUM: 1/5000); float images are "
             "metres")
      .field("min_depth", &D::min_depth, "m",
             "nearer pixels are dropped (along z): sensors report garbage below their range")
      .field("max_depth", &D::max_depth, "m", "farther pixels are dropped")
      .field("stride", &D::stride, "", "use every stride-th pixel in both directions (1 = full resolution)")
      .settings();

  using B = BilateralFilterSettings;
  fieldsOf(py::class_<B>(m, "BilateralFilterSettings",
                         "Bilateral depth filter (Tomasi and Manduchi, ICCV 1998), as KinectFusion smooths depth "
                         "before normals (Newcombe et al., ISMAR 2011, §3.2). validate() raises ValueError naming a "
                         "bad field."))
      .field("radius", &B::radius, "px", "window radius, in [0, 32] (the window's taps per pixel bound the time)")
      .field("sigma_space", &B::sigma_space, "px", "spatial standard deviation of the weights, >= 1e-3")
      .field("sigma_depth", &B::sigma_depth, "m",
             "range standard deviation of the weights, >= 1e-9: depth jumps much larger than it (edges) are kept")
      .settings()
      .def("validate", &B::validate);

  using R = DepthRenderSettings;
  fieldsOf(py::class_<R>(m, "DepthRenderSettings", "Settings of render_depth (the z-buffer renderer)"))
      .field("near_clip", &R::near_clip, "m",
             "near clipping plane z = near in the camera frame (> 0): closer geometry is clipped away")
      .field("far_clip", &R::far_clip, "m", "far limit (> near_clip): surface points with a larger depth are not drawn")
      .field("cull_backfaces", &R::cull_backfaces, "",
             "drop triangles seen from their back (clockwise in the image); off: both sides are drawn")
      .field("num_threads", &R::num_threads, "", "OpenMP threads, 0 = the OpenMP default")
      .settings();

  const BilateralFilterSettings db;
  // The field-by-field overload first: a bad argument is named after its signature.
  m.def(
      "bilateral_filter_depth",
      [](const py::array& depth, const py::object& radius, double sigma_space, double sigma_depth, double depth_scale,
         const py::object& num_threads) {
        if (py::isinstance<BilateralFilterSettings>(radius))  // the settings overload, given positionally
          return bilateralFilterPy(depth, radius.cast<BilateralFilterSettings>(), depth_scale, num_threads);
        BilateralFilterSettings s;
        s.radius = static_cast<int>(intArg(radius, "radius", 0, 32));
        s.sigma_space = sigma_space;
        s.sigma_depth = sigma_depth;
        return bilateralFilterPy(depth, s, depth_scale, num_threads);
      },
      py::arg("depth"), py::arg("radius") = db.radius, py::arg("sigma_space") = db.sigma_space,
      py::arg("sigma_depth") = db.sigma_depth, py::arg("depth_scale") = 0.001, py::arg("num_threads") = 0,
      "(H, W) float32 metres (NaN = invalid) of a uint16 (units of depth_scale m, 0 = invalid) or float (m) image, "
      "bilateral-filtered with the BilateralFilterSettings fields given one by one (radius and sigma_space in pixels, "
      "sigma_depth in m); an empty image gives an empty one, a pixel whose mean overflows float32 NaN. ValueError for "
      "an image beyond kMaxImagePixels (2^27) pixels, checked before allocating, bad settings (named) or depth_scale "
      "outside (0, 1] m per unit");
  m.def(
      "bilateral_filter_depth",
      [](const py::array& depth, const BilateralFilterSettings& settings, double depth_scale,
         const py::object& num_threads) { return bilateralFilterPy(depth, settings, depth_scale, num_threads); },
      py::arg("depth"), py::arg("settings"), py::arg("depth_scale") = 0.001, py::arg("num_threads") = 0,
      "The same with a BilateralFilterSettings");
  m.def("depth_to_cloud", &depthToCloudPy, py::arg("depth"), py::arg("intrinsics"), py::arg("settings"),
        py::arg("rgb") = py::none(),
        "(points (N, 3) float32 m, colors (N, 3) uint8 or None, pixels (N,) int32 row * W + column). A distorted "
        "camera's pixels back-project along their undistorted rays (undistorted_rays, computed once per intrinsics "
        "and cached in C++), a pinhole camera's by the pinhole formula");
  m.def(
      "undistorted_rays",
      [](const PinholeIntrinsics& K, int max_iterations, double max_reprojection_error, int num_threads) {
        std::vector<double> rays;
        {
          py::gil_scoped_release release;
          if (max_iterations == 100 && max_reprojection_error == 1e-3)
            rays = *cachedUndistortedRays(K);  // the table depth_to_cloud uses
          else
            rays = undistortedRays(K, max_iterations, max_reprojection_error, num_threads);
        }
        py::array_t<double> out(
            {static_cast<py::ssize_t>(K.height), static_cast<py::ssize_t>(K.width), py::ssize_t{2}});
        std::copy(rays.begin(), rays.end(), out.mutable_data());
        return out;
      },
      py::arg("intrinsics"), py::arg("max_iterations") = 100, py::arg("max_reprojection_error") = 1e-3,
      py::arg("num_threads") = 0,
      "(H, W, 2) float64: the undistorted normalised coordinates (x, y) = (X/Z, Y/Z) of every pixel centre of a "
      "camera with intrinsics.distortion (k1 k2 p1 p2 k3, OpenCV's order), by OpenCV undistortPoints' fixed-point "
      "iteration; NaN where the ray does not re-project onto its pixel within max_reprojection_error pixels. With the "
      "defaults, the cached table depth_to_cloud uses");
  m.def("render_depth", &renderDepthPy, py::arg("vertices"), py::arg("faces"), py::arg("intrinsics"),
        py::arg("T_camera_world"), py::arg("settings"),
        "Renders an (N,3) float32/float64 mesh with (M,3) integer faces (indices checked, naming faces) seen by a "
        "pinhole camera (PinholeIntrinsics without distortion) at T_camera_world (world -> camera, rigid); returns "
        "(depth float32 m, NaN = no hit; face_id int32, -1 = no hit; cos_incidence float32). ValueError for a size "
        "outside [1, 32768] or beyond 2^27 pixels in all, before allocating, or distorted intrinsics.");
}

}  // namespace scanalign::python
