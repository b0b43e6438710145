// _core.synthetic: the built-in parts (mesh, symmetry, surface samples), the simulator's scene
// (compositing and shading), camera paths, the sensor noise model and the Morton order behind
// scanalign.data.parts and scanalign.synthetic.
#include <cmath>
#include <limits>
#include <string>

#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "fields.hpp"
#include "scanalign/common/morton_order.hpp"
#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/synthetic/builtin_part.hpp"
#include "scanalign/synthetic/scan_paths.hpp"
#include "scanalign/synthetic/scene.hpp"
#include "scanalign/synthetic/sensor_noise.hpp"

namespace scanalign::python {

namespace {

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
  const Image z = checkedAs<float>(depth, "depth"), c = checkedAs<float>(cos_incidence, "cos_incidence");
  if (z.ndim() != 2) throw py::value_error("depth: expected an (H, W) float array");
  if (c.ndim() != 2 || c.shape(0) != z.shape(0) || c.shape(1) != z.shape(1))
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
  using N = SensorNoise;
  fieldsOf(py::class_<N>(s, "SensorNoise",
                         "A depth sensor's error model, applied to noise-free depth (see apply_sensor_noise): "
                         "dropouts at grazing incidence, on both sides of depth edges and at random, axial Gaussian "
                         "noise sigma(z) = axial_sigma_ref (z / z_ref)^axial_exponent (2: the depth error of a "
                         "triangulation sensor grows with the square of the distance; about 1-1.5 for time of "
                         "flight), time-of-flight mixed pixels at depth edges (flying_pixels), the range [min_range, "
                         "max_range] and rounding to depth_unit. Read-only (the presets are shared); invalid fields raise ValueError naming "
                         "them.")
               .def(py::init([](std::string name, double axial_sigma_ref, double z_ref, double depth_unit,
                                double min_range, double max_range, double grazing_cos, double edge_threshold,
                                int edge_width, double dropout, double axial_exponent, double flying_pixels) {
                      N n{std::move(name), axial_sigma_ref, z_ref,          depth_unit, min_range,
                          max_range,       grazing_cos,     edge_threshold, edge_width, dropout,
                          axial_exponent,  flying_pixels};
                      n.validate();
                      return n;
                    }),
                    py::kw_only(), py::arg("name") = "custom", py::arg("axial_sigma_ref") = 0.0,
                    py::arg("z_ref") = 1.0, py::arg("depth_unit") = 0.0, py::arg("min_range") = 0.0,
                    py::arg("max_range") = inf, py::arg("grazing_cos") = 0.0, py::arg("edge_threshold") = 0.0,
                    py::arg("edge_width") = 0, py::arg("dropout") = 0.0, py::arg("axial_exponent") = 2.0,
                    py::arg("flying_pixels") = 0.0)
               .def(
                   "sigma",
                   [](const N& n, const py::array_t<double>& z) {
                     return py::vectorize([&n](double v) { return n.sigma(v); })(z);
                   },
                   py::arg("z"), "Axial standard deviation (m) at depth z (m), element-wise for arrays."))
      .output("name", &N::name, "", "label")
      .output("axial_sigma_ref", &N::axial_sigma_ref, "m", "standard deviation of the depth error at z_ref")
      .output("z_ref", &N::z_ref, "m", "reference depth of axial_sigma_ref")
      .output("depth_unit", &N::depth_unit, "m", "quantisation step of the reported depth; 0 for none")
      .output("min_range", &N::min_range, "m", "nearest measurable depth")
      .output("max_range", &N::max_range, "m", "farthest measurable depth")
      .output("grazing_cos", &N::grazing_cos, "", "minimum |cosine of incidence| for a measurement")
      .output("edge_threshold", &N::edge_threshold, "",
              "relative depth jump marking a discontinuity; 0 disables edge dropout")
      .output("edge_width", &N::edge_width, "px", "pixels dropped on each side of a discontinuity")
      .output("dropout", &N::dropout, "", "probability that any other pixel is missing")
      .output("axial_exponent", &N::axial_exponent, "", "exponent p of sigma(z) = axial_sigma_ref (z / z_ref)^p")
      .output("flying_pixels", &N::flying_pixels, "",
              "probability that an edge pixel returns a mixed depth between its neighbours' (time of flight)")
      .result();
  s.def("apply_sensor_noise", &applySensorNoisePy, py::arg("noise"), py::arg("depth"), py::arg("cos_incidence"),
        py::arg("seed"),
        "Noisy (H, W) float32 depth in metres (NaN = missing) from noise-free `depth` (m, NaN = nothing hit) and the "
        "rendered `cos_incidence`, by the SensorNoise model; all randomness from the 64-bit `seed` (equal seeds give "
        "identical images with one build of the library). ValueError for an image beyond 2^27 pixels, before "
        "allocating.");
}

/// A 3-vector or 2-vector of finite reals; ValueError naming `what` otherwise.
template <int N>
Eigen::Matrix<double, N, 1> fixedArg(const py::handle& o, const char* what) {
  const auto a = checkedAs<double>(o, what, kReals);
  if (a.ndim() != 1 || a.shape(0) != N)
    throw py::value_error(std::string(what) + ": expected " + std::to_string(N) + " numbers");
  return Eigen::Map<const Eigen::Matrix<double, N, 1>>(a.data());
}

/// The per-face colour tables as (F + 1, 3) uint8 arrays, and back.
py::array_t<std::uint8_t> colorTable(const std::vector<std::uint8_t>& c) { return vectorArray(c, 3); }
std::vector<std::uint8_t> colorTableArg(const py::object& o, const char* what) {
  const auto a = py::array_t<std::uint8_t, py::array::c_style>::ensure(o);
  if (!a || !holds<std::uint8_t>(py::array(a)) || a.ndim() != 2 || a.shape(1) != 3 || a.shape(0) < 1)
    throw py::value_error(std::string(what) + ": expected an (F + 1, 3) uint8 colour table");
  return std::vector<std::uint8_t>(a.data(), a.data() + a.size());
}

void bindScene(py::module_& s) {
  s.def(
      "compose_scene",
      [](const py::list& objects, const py::object& table_size, const py::object& table_center, double table_height,
         const py::object& table_albedo) {
        std::vector<py::array_t<double, py::array::c_style | py::array::forcecast>> keep_vertices;
        std::vector<std::vector<std::int64_t>> keep_faces;
        std::vector<SceneObjectMesh> in;
        for (const py::handle item : objects) {
          if (!py::isinstance<py::tuple>(item) || py::len(item) != 4)
            throw py::value_error("objects: expected (vertices, faces, T_base_object, albedo) tuples");
          const auto t = py::reinterpret_borrow<py::tuple>(item);
          keep_vertices.push_back(checkedAs<double>(t[0], "objects: vertices", kReals));
          const auto& v = keep_vertices.back();
          if (v.ndim() != 2 || v.shape(1) != 3) throw py::value_error("objects: vertices must be (V, 3) reals");
          keep_faces.push_back(indexRows(t[1], "objects: faces", 3));
          SceneObjectMesh o;
          o.vertices = CloudView<double>(v.data(), static_cast<std::size_t>(v.shape(0)));
          o.faces = keep_faces.back().data();
          o.n_faces = keep_faces.back().size() / 3;
          o.T_base_object = fields::Conv<Eigen::Matrix4d>::set(t[2], "objects: T_base_object");
          o.albedo = fixedArg<3>(t[3], "objects: albedo");
          in.push_back(o);
        }
        SceneTable table;
        const bool has_table = !table_size.is_none();
        if (has_table) {
          table.size = fixedArg<2>(table_size, "table_size");
          table.center = fixedArg<2>(table_center, "table_center");
          table.height = table_height;
          table.checker_colors[0] = fixedArg<3>(table_albedo, "table_albedo");
        }
        SceneMesh mesh;
        {
          py::gil_scoped_release release;
          mesh = composeScene(in, has_table ? &table : nullptr);
        }
        py::dict d;
        d["vertices"] = rowsArray(mesh.vertices);
        d["faces"] = vectorArray(mesh.faces, 3);
        d["owner"] = vectorArray(mesh.face_object);
        d["source"] = vectorArray(mesh.face_source);
        d["albedo"] = rowsArray(mesh.albedo);
        d["normals"] = rowsArray(mesh.normals);
        d["n_object_faces"] = mesh.object_faces;
        return d;
      },
      py::arg("objects"), py::arg("table_size"), py::arg("table_center"), py::arg("table_height"),
      py::arg("table_albedo"),
      "The scene as one mesh in the base frame (synthetic/scene.hpp): objects [(vertices (V, 3) m, faces (F, 3), "
      "T_base_object 4x4, albedo (3,))] moved into the base frame, each one's faces in Morton order of their "
      "centroids and its used vertices in order of first use, then the table (table_size (x, y) m, or None for none; "
      "two triangles, normal +z, albedo table_albedo). A dict: vertices (V, 3) float64, faces (F, 3) int32, owner "
      "(F,) int32 (object index, -1 the table), source (F,) int64 (row in the object's mesh), albedo (F, 3), "
      "normals (F, 3) unit (0 for zero-area faces), n_object_faces.");
  s.def(
      "scene_colors",
      [](const py::object& normals, const py::object& albedo, const py::object& owner, std::size_t n_object_faces,
         const Eigen::Vector3d& light_direction, double ambient, const py::object& table_alternate) {
        SceneMesh mesh;
        const auto n = checkedAs<double>(normals, "normals", kReals);
        const auto a = checkedAs<double>(albedo, "albedo", kReals);
        const auto o = checkedAs<std::int32_t>(owner, "owner", kIntegers);
        if (n.ndim() != 2 || n.shape(1) != 3 || a.ndim() != 2 || a.shape(1) != 3 ||
            a.shape(0) != n.shape(0) || o.ndim() != 1 || o.shape(0) != n.shape(0))
          throw py::value_error("normals, albedo: expected (F, 3) arrays and owner an (F,) array");
        const auto faces = static_cast<std::size_t>(n.shape(0));
        if (n_object_faces > faces) throw py::value_error("n_object_faces: more than the faces");
        mesh.normals.resize(faces);
        mesh.albedo.resize(faces);
        for (std::size_t f = 0; f < faces; ++f) {
          mesh.normals[f] = Eigen::Map<const Eigen::Vector3d>(n.data() + 3 * f);
          mesh.albedo[f] = Eigen::Map<const Eigen::Vector3d>(a.data() + 3 * f);
        }
        mesh.face_object.assign(o.data(), o.data() + faces);
        mesh.object_faces = n_object_faces;
        SceneTable table;
        table.checker_colors[1] = fixedArg<3>(table_alternate, "table_alternate");
        const SceneColors c = sceneColors(mesh, table, light_direction, ambient);
        return py::make_tuple(colorTable(c.albedo), colorTable(c.alternate));
      },
      py::arg("normals"), py::arg("albedo"), py::arg("owner"), py::arg("n_object_faces"), py::arg("light_direction"),
      py::arg("ambient"), py::arg("table_alternate"),
      "(colors, alternate): (F + 1, 3) uint8 colours of the faces under a distant light, two-sided Lambert plus "
      "ambient, round(255 albedo (ambient + (1 - ambient) |n . light_direction|)); alternate with the table's faces "
      "(owner < 0) in table_alternate, its second checker colour; the last row black (the background). "
      "light_direction: unit, towards the light.");
  s.def(
      "shade_scene",
      [](const py::object& colors, const py::object& alternate, std::size_t n_object_faces, const py::array& face_id,
         const py::array& depth, const PinholeIntrinsics& intrinsics, const py::object& T_base_camera_in,
         const py::object& table_center, double checker_size) {
        // converted here, not by pybind11's Eigen caster, so a wrong shape names the argument
        const Eigen::Matrix4d T_base_camera = fields::Conv<Eigen::Matrix4d>::set(T_base_camera_in, "T_base_camera");
        SceneColors c;
        c.albedo = colorTableArg(colors, "colors");
        c.alternate = colorTableArg(alternate, "alternate");
        c.object_faces = n_object_faces;
        const py::ssize_t h = intrinsics.height, w = intrinsics.width;
        const auto fid = checkedAs<std::int32_t>(face_id, "face_id", kIntegers);
        const auto z = checkedAs<float>(depth, "depth");
        if (fid.ndim() != 2 || fid.shape(0) != h || fid.shape(1) != w || z.ndim() != 2 ||
            z.shape(0) != h || z.shape(1) != w)
          throw py::value_error("face_id, depth: expected (" + std::to_string(h) + ", " + std::to_string(w) +
                                ") images matching the intrinsics");
        SceneTable table;
        table.center = fields::Conv<Eigen::Vector2d>::set(table_center, "table_center");
        table.checker_size = checker_size;
        py::array_t<std::uint8_t> rgb({h, w, py::ssize_t{3}});
        std::uint8_t* out = rgb.mutable_data();
        {
          py::gil_scoped_release release;
          shadeScene(c, table, intrinsics, T_base_camera, z.data(), fid.data(), out);
        }
        return rgb;
      },
      py::arg("colors"), py::arg("alternate"), py::arg("n_object_faces"), py::arg("face_id"), py::arg("depth"),
      py::arg("intrinsics"), py::arg("T_base_camera"), py::arg("table_center"), py::arg("checker_size"),
      "(H, W, 3) uint8 colour image of a rendering (face_id, depth): colors of the face seen; on the table (faces "
      "from n_object_faces on) alternate where the checker square (checker_size m, from table_center (x, y) m) of "
      "the base-frame point hit (depth back-projected as depth_to_cloud does, moved by T_base_camera) has odd "
      "parity; black where nothing is hit. ValueError for distorted intrinsics (pinhole renderings only).");
  s.def(
      "sample_builtin_block",
      [](const py::object& n_points, const py::object& seed, int segments) {
        const auto n = static_cast<std::size_t>(intArg(n_points, "n_points", 0, std::int64_t{1} << 40));
        requireMemory(160.0 * static_cast<double>(n), "n_points = " + std::to_string(n));  // points, normals, draws
        const std::uint64_t seed_value = seedArg(seed, "seed");
        MeshSamples r;
        {
          py::gil_scoped_release release;
          r = sampleBuiltinBlock(n, seed_value, segments);
        }
        return py::make_tuple(rowsArray(r.points), rowsArray(r.normals), vectorArray(r.faces));
      },
      py::arg("n_points"), py::arg("seed") = 0, py::arg("segments") = 96,
      "(points (n, 3), normals (n, 3), faces (n,) int64) on the built-in block's exposed surface, uniform per unit "
      "area, with exact normals: mesh samples (sample_mesh) of builtin_part_mesh(segments, 'block') with the boss's "
      "and the cap's points moved onto the exact cylinder and sphere and the top face's points inside their true "
      "circles dropped (builtin_part.hpp). The random numbers are numpy.random.default_rng(seed)'s (seed in "
      "[0, 2^64)), drawn as sample_mesh draws them.");
}

}  // namespace

void defineSynthetic(py::module_& s) {
  bindSensorNoise(s);
  bindScene(s);
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
        "A built-in part (see scanalign.data.parts: block, bracket, standoff) as a watertight mesh in metres, its own "
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
