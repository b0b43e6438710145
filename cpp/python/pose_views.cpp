// Bindings of the model views (scanalign/pose/model_views.hpp; Kleppe, PhD thesis, NTNU 2018,
// §7.3): the tessellated sphere of viewpoints, the view camera, how a mesh is rendered
// (ModelViewSettings) and the views themselves (ModelView, in the part library's flat state).
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <limits>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "pose.hpp"
#include "scanalign/pose/model_views.hpp"

namespace scanalign::python {

namespace {

using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Pixels = Eigen::Matrix<std::int64_t, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// Field-table accessors of ModelView's (N, 3) float64 rows (points, normals).
auto rowsOf(std::vector<double> ModelView::*member) {
  return [member](const ModelView& v) { return Rows3(Eigen::Map<const Rows3>((v.*member).data(), static_cast<Eigen::Index>(v.size()), 3)); };
}
auto setRows(std::vector<double> ModelView::*member) {
  return [member](ModelView& v, const Rows3& r) { (v.*member).assign(r.data(), r.data() + r.size()); };
}

/// `state` entries whose key starts with `prefix`, the prefix removed.
py::dict withPrefix(const py::dict& state, const std::string& prefix) {
  py::dict d;
  for (const auto& item : state) {
    const std::string key = py::str(item.first);
    if (key.rfind(prefix, 0) == 0) d[py::str(key.substr(prefix.size()))] = item.second;
  }
  return d;
}

/// ModelView's own fields (N points), flat: points, normals (N, 3) float64, face_id (N,)
/// int32, pixels (N, 2) int32, T_model_camera (4, 4), intrinsics (6,) [width, height, fx, fy,
/// cx, cy].
std::vector<PickleField<ModelView>> modelViewFields() {
  using V = ModelView;
  const auto rows = [](const char* name, auto member, auto tag) {
    using Row = decltype(tag);
    return field<V>(
        name,
        [member](const V& v) {
          std::vector<Row> r((v.*member).size() / Row::RowsAtCompileTime);
          for (std::size_t i = 0; i < r.size(); ++i)
            for (int c = 0; c < Row::RowsAtCompileTime; ++c) r[i][c] = (v.*member)[Row::RowsAtCompileTime * i + c];
          return r;
        },
        [member](V& v, const std::vector<Row>& r) {
          (v.*member).clear();
          for (const Row& x : r) (v.*member).insert((v.*member).end(), x.data(), x.data() + Row::RowsAtCompileTime);
        });
  };
  return {rows("points", &V::points, Eigen::Vector3d{}), rows("normals", &V::normals, Eigen::Vector3d{}),
          field("face_id", &V::face_id), rows("pixels", &V::pixels, Eigen::Matrix<std::int32_t, 2, 1>{}),
          field("T_model_camera", &V::T_model_camera),
          field<V>(
              "intrinsics",
              [](const V& v) {
                const PinholeIntrinsics& k = v.intrinsics;
                return Eigen::Matrix<double, 6, 1>(k.width, k.height, k.fx, k.fy, k.cx, k.cy);
              },
              [](V& v, const Eigen::Matrix<double, 6, 1>& k) {
                v.intrinsics = {static_cast<int>(k[0]), static_cast<int>(k[1]), k[2], k[3], k[4], k[5]};
              })};
}

/// ModelView's state: its fields, cbd_settings/<name> (cbdSettingsFields), has_cbd and, when
/// it has cached descriptors, cbd/<name> (cbdFeatureFields). Flat: every value an array or
/// a Python scalar.
py::dict modelViewState(const ModelView& v) {
  py::dict d = stateOf(v, modelViewFields());
  for (const auto& item : stateOf(v.cbd_settings, cbdSettingsFields()))
    d[py::str("cbd_settings/" + std::string(py::str(item.first)))] = item.second;
  d["has_cbd"] = v.cbd.has_value();
  if (v.cbd)
    for (const auto& item : stateOf(*v.cbd, cbdFeatureFields()))
      d[py::str("cbd/" + std::string(py::str(item.first)))] = item.second;
  return d;
}

ModelView modelViewFromState(const py::dict& state) {
  const std::string cls = "ModelView";
  if (!state.contains("has_cbd")) throw py::value_error(cls + ": pickled state lacks 'has_cbd'");
  const bool has_cbd = fromState<bool>(state["has_cbd"], cls + ": pickled state 'has_cbd'");
  py::dict own;
  for (const auto& item : state) {
    const std::string key = py::str(item.first);
    if (key != "has_cbd" && key.rfind("cbd_settings/", 0) != 0 && key.rfind("cbd/", 0) != 0) own[item.first] = item.second;
  }
  ModelView v;
  assignState(v, own, modelViewFields(), cls);
  const std::size_t n = v.points.size() / 3;
  if (v.normals.size() != 3 * n || v.face_id.size() != n || v.pixels.size() != 2 * n)
    throw py::value_error(cls + ": pickled points, normals, face_id and pixels differ in length");
  assignState(v.cbd_settings, withPrefix(state, "cbd_settings/"), cbdSettingsFields(), cls + " cbd_settings/");
  const py::dict cbd = withPrefix(state, "cbd/");
  if (has_cbd) {
    CbdFeatures f;
    assignState(f, cbd, cbdFeatureFields(), cls + " cbd/");
    checkCbdFeatures(f, cls);
    for (std::uint32_t i : f.keypoints)
      if (i >= n) throw py::value_error(cls + ": pickled cbd/keypoints index past the view's points");
    v.cbd = std::move(f);
  } else if (!cbd.empty()) {
    throw py::value_error(cls + ": pickled state has cbd/ entries but has_cbd is False");
  }
  return v;
}

void bindModelView(py::module_& m) {
  using V = ModelView;
  auto views =
      fieldsOf(
          py::class_<V>(m, "ModelView", "One virtual depth camera's view of a model (model frame, m)")
              .def(py::init([](const F64& points, const F64& normals) {
                     if (points.ndim() != 2 || points.shape(1) != 3 || normals.ndim() != 2 || normals.shape(1) != 3 ||
                         normals.shape(0) != points.shape(0))
                       throw py::value_error("points and normals: expected two (N, 3) arrays of the same length");
                     V v;
                     v.points.assign(points.data(), points.data() + points.size());
                     v.normals.assign(normals.data(), normals.data() + normals.size());
                     v.face_id.assign(static_cast<std::size_t>(points.shape(0)), -1);
                     v.pixels.assign(2 * static_cast<std::size_t>(points.shape(0)), -1);
                     return v;
                   }),
                   py::arg("points"), py::arg("normals"), "a view made of a model cloud and its normals (no camera)")
              .def(
                  "points_in_camera",
                  [](const V& v) {
                    const Eigen::Matrix3d Rt = v.T_model_camera.topLeftCorner<3, 3>().transpose();
                    const Eigen::Vector3d t = v.T_model_camera.topRightCorner<3, 1>();
                    Rows3 out(static_cast<Eigen::Index>(v.size()), 3);
                    for (std::size_t i = 0; i < v.size(); ++i)
                      out.row(static_cast<Eigen::Index>(i)) = (Rt * (Eigen::Vector3d(&v.points[3 * i]) - t)).transpose();
                    return out;
                  },
                  "(N, 3) the points in the camera frame (z = depth), m")
              .def("__len__", &V::size))
          .field("points", rowsOf(&V::points), setRows(&V::points), "m", "(N, 3) visible surface points", false)
          .field("normals", rowsOf(&V::normals), setRows(&V::normals), "",
                 "(N, 3) unit normals of their triangles, oriented towards the camera", false)
          .field("face_id", int64Getter(&V::face_id), int64Setter(&V::face_id), "",
                 "(N,) int64 triangle index in the mesh (-1: not from a mesh)", false)
          .field(
              "pixels",
              [](const V& v) {
                return Pixels(Eigen::Map<const Eigen::Matrix<std::int32_t, Eigen::Dynamic, 2, Eigen::RowMajor>>(
                                  v.pixels.data(), static_cast<Eigen::Index>(v.pixels.size() / 2), 2)
                                  .cast<std::int64_t>());
              },
              [](V& v, const Pixels& p) {
                if (p.size() && (p.minCoeff() < std::numeric_limits<std::int32_t>::min() ||
                                 p.maxCoeff() > std::numeric_limits<std::int32_t>::max()))
                  throw py::value_error("ModelView.pixels: out of range of int32");
                const Eigen::Matrix<std::int32_t, Eigen::Dynamic, 2, Eigen::RowMajor> q = p.cast<std::int32_t>();
                v.pixels.assign(q.data(), q.data() + q.size());
              },
              "px", "(N, 2) int64 (column, row) in the image", false)
          .output("T_model_camera", &V::T_model_camera, "m", "(4, 4) camera -> model (OpenCV camera axes)")
          .output("intrinsics", &V::intrinsics, "", "the view's pinhole camera")
          .field("cbd", &V::cbd, "",
                 "CbdFeatures computed once for this view (describe_model_views, a part library), or None; "
                 "estimate_pose uses them when its CBD settings equal cbd_settings (threads aside), else computes "
                 "afresh")
          .field("cbd_settings", &V::cbd_settings, "", "the CbdSettings cbd was computed with")
          .derived(
              "viewpoint", [](const V& v) { return Eigen::Vector3d(v.T_model_camera.topRightCorner<3, 1>()); }, "m",
              "(3,) camera centre, model frame")
          .result();
  // The part library's flat layout (arrays and scalars only: np.savez without pickle; its
  // keys are fixed by the libraries already written), not the table's nested state.
  replacePickle(views, &modelViewState, &modelViewFromState);
}

}  // namespace

void bindPoseViews(py::module_& m) {
  m.def(
      "tessellated_sphere",
      [](int level) {
        const TessellatedSphere s = tessellatedSphere(level);
        py::array_t<double> v({static_cast<py::ssize_t>(s.vertices.size()), py::ssize_t{3}});
        py::array_t<std::int64_t> f({static_cast<py::ssize_t>(s.faces.size()), py::ssize_t{3}});
        for (std::size_t i = 0; i < s.vertices.size(); ++i)
          for (int k = 0; k < 3; ++k) v.mutable_data()[3 * i + k] = s.vertices[i][k];
        for (std::size_t i = 0; i < s.faces.size(); ++i)
          for (int k = 0; k < 3; ++k) f.mutable_data()[3 * i + k] = s.faces[i][k];
        return py::make_tuple(v, f);
      },
      py::arg("level") = 1,
      "(vertices (V, 3) unit length, faces (F, 3) counter-clockwise) of an icosahedron subdivided `level` times: "
      "10 4^level + 2 vertices, 20 4^level faces");
  m.def("view_intrinsics", &viewIntrinsics, py::arg("resolution"), py::arg("view_angle") = kDefaultViewAngle,
        "square pinhole camera with field of view view_angle (rad) across resolution pixels");
  m.attr("DEFAULT_VIEW_ANGLE") = kDefaultViewAngle;
  using CS = CloudModelSettings;
  fieldsOf(py::class_<CS>(m, "CloudModelSettings", "How the views of a model cloud are made (metres)"))
      .field("normal_radius", &CS::normal_radius, "m",
             "PCA normal radius of a model cloud given without normals (points without 3 neighbours left out)")
      .field("splat_radius", &CS::splat_radius, "m",
             "disc drawn per point into a view's depth buffer; 0 = 1.5 x the median nearest-neighbour distance")
      .field("depth_tolerance", &CS::depth_tolerance, "m",
             "a point is visible at most this far behind the depth buffer; 0 = its disc's radius (>= 0.75 pixel)")
      .settings();
  using S = ModelViewSettings;
  fieldsOf(py::class_<S>(m, "ModelViewSettings", "How a CAD model is rendered into partial views"))
      .field("resolution", &S::resolution, "px", "image width and height (thesis: 90 to 400)")
      .field("view_angle", &S::view_angle, "rad", "field of view (PCL's 57 degrees)")
      .field("level", &S::level, "", "icosahedron subdivisions; 1 gives the thesis's 42 views")
      .field("distance", &S::distance, "m",
             "camera distance from center; 0 = the bounding sphere fills 90 % of the field of view")
      .field("center", &S::center, "m", "(3,) what the cameras look at; None = bounding-box centre")
      .field("num_threads", &S::num_threads, "", "rasteriser threads, 0 = all cores")
      .field("max_memory_bytes", &S::max_memory_bytes, "bytes",
             "refuse (ValueError, before rendering) when views x resolution^2 x 64 bytes exceeds this")
      .field("cloud", &S::cloud, "", "CloudModelSettings: the views of a model given as a cloud")
      .settings();
  bindModelView(m);
  m.def(
      "render_model_views",
      [](const py::array& vertices, const py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>& faces,
         const ModelViewSettings& s) {
        const auto V = cloudView<double>(vertices, "mesh vertices");
        if (faces.ndim() != 2 || faces.shape(1) != 3) throw py::value_error("mesh faces: expected an (F, 3) integer array");
        std::vector<std::int32_t> f(static_cast<std::size_t>(faces.size()));
        for (std::size_t i = 0; i < f.size(); ++i) {
          const std::int64_t v = faces.data()[i];
          if (v < 0 || static_cast<std::size_t>(v) >= V.size) throw py::value_error("mesh faces: vertex index out of range");
          f[i] = static_cast<std::int32_t>(v);
        }
        py::gil_scoped_release release;
        return renderModelViews(V, f.data(), f.size() / 3, s);
      },
      py::arg("vertices"), py::arg("faces"), py::arg("settings"),
      "the views of a mesh (vertices (V, 3) m, faces (F, 3)) from the vertices of the tessellated sphere, in order. "
      "ValueError for a malformed mesh, bad settings, or views whose worst-case memory (views x resolution^2 x 64 "
      "bytes) exceeds settings.max_memory_bytes, checked before anything is allocated");
  m.def(
      "cloud_model_views",
      [](const py::array& points, const py::object& normals, const ModelViewSettings& s) {
        const auto P = cloudView<double>(points, "model cloud");
        const py::array held = normals.is_none() ? py::array() : asCloudArray<double>(normals, "model normals");
        const CloudView<double> N = normals.is_none() ? CloudView<double>() : cloudView<double>(held, "model normals");
        py::gil_scoped_release release;
        return cloudModelViews(P, N, s);
      },
      py::arg("points"), py::arg("normals"), py::arg("settings"),
      "the views of a model cloud (points (N, 3) float64, m; normals (N, 3) or None: PCA normals of radius "
      "settings.cloud.normal_radius) from the same cameras as render_model_views: the points each camera sees (a "
      "splat z-buffer), normals turned towards it. ValueError for a malformed cloud or bad settings");
  m.def("is_cloud_model", &isCloudModel, py::arg("views"),
        "whether the views are a model cloud's (face_id -1 throughout): find_parts's coverage gate then checks the "
        "matching view against the cluster");
}

}  // namespace scanalign::python
