#include "arrays.hpp"
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
}  // namespace

void defineReconstruction(py::module_& m) {
  m.def("voxel_grid_f32", &voxel<float>, py::arg("points"), py::arg("leaf_size"), py::arg("attributes"),
        py::arg("min_points_per_voxel"));
  m.def("voxel_grid_f64", &voxel<double>, py::arg("points"), py::arg("leaf_size"), py::arg("attributes"),
        py::arg("min_points_per_voxel"));
}

}  // namespace scanalign::python
