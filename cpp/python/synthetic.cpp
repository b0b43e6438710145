// _core.synthetic: the z-buffer depth renderer behind scanalign.synthetic. The Python layer
// validates and converts inputs; the checks here are the last line of defence.
#include <pybind11/eigen.h>

#include "arrays.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"

namespace scanalign::python {

namespace {

py::tuple renderDepthPy(const py::array& vertices, const py::array& faces, int width, int height, double fx, double fy,
                        double cx, double cy, const Eigen::Matrix4d& T_camera_world, double near_clip, double far_clip,
                        bool cull_backfaces, int num_threads) {
  if (!faces.dtype().is(py::dtype::of<std::int32_t>()))
    throw py::type_error("faces: expected dtype int32, got " + std::string(py::str(faces.dtype())));
  if (faces.ndim() != 2 || faces.shape(1) != 3) throw py::value_error("faces: expected an (M, 3) array");
  if (!(faces.flags() & py::array::c_style)) throw py::value_error("faces: must be C-contiguous");
  if (width < 1 || height < 1 || width > 32768 || height > 32768)
    throw py::value_error("image size must be in [1, 32768] pixels");
  const bool f32 = vertices.dtype().is(py::dtype::of<float>());
  CloudView<float> vf;
  CloudView<double> vd;
  if (f32)
    vf = cloudView<float>(vertices, "vertices");
  else
    vd = cloudView<double>(vertices, "vertices");  // raises TypeError for other dtypes
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
  const auto* f = static_cast<const std::int32_t*>(faces.data());
  const auto n_faces = static_cast<std::size_t>(faces.shape(0));
  {
    py::gil_scoped_release release;
    if (f32)
      renderDepth(vf, f, n_faces, camera, T_camera_world, settings, out);
    else
      renderDepth(vd, f, n_faces, camera, T_camera_world, settings, out);
  }
  return py::make_tuple(depth, face_id, cosine);
}

}  // namespace

void bindSynthetic(py::module_& m) {
  auto s = m.def_submodule("synthetic", "z-buffer depth renderer for synthetic RGB-D frames");
  s.def("render_depth", &renderDepthPy, py::arg("vertices"), py::arg("faces"), py::arg("width"), py::arg("height"),
        py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"), py::arg("T_camera_world"), py::arg("near_clip"),
        py::arg("far_clip"), py::arg("cull_backfaces"), py::arg("num_threads"),
        "Renders an (N,3) float32/float64 mesh with int32 (M,3) faces; returns (depth float32 m, NaN = no hit; "
        "face_id int32, -1 = no hit; cos_incidence float32).");
}

}  // namespace scanalign::python
