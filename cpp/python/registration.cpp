#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "arrays.hpp"
#include "fields.hpp"
#include "pickle.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/registration/alignment_fitness.hpp"
#include "scanalign/registration/cuda/icp_device.hpp"
#include "scanalign/registration/icp.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace scanalign::python {

namespace {

IcpSearch searchFromString(const std::string& s) {
  if (s == toString(IcpSearch::BucketKdTree)) return IcpSearch::BucketKdTree;
  if (s == toString(IcpSearch::LeftBalancedKdTree)) return IcpSearch::LeftBalancedKdTree;
  throw py::value_error("search must be 'bucket_kdtree' or 'left_balanced_kdtree', got '" + s + "'");
}

RobustKernel kernelFromString(const std::string& s) {
  for (auto k : {RobustKernel::None, RobustKernel::Huber, RobustKernel::Cauchy})
    if (s == toString(k)) return k;
  throw py::value_error("robust_kernel must be 'none', 'huber' or 'cauchy', got '" + s + "'");
}

constexpr const char* kNeedsNormals =
    "target_normals: point-to-plane ICP needs them (or use estimator='point_to_point')";

/// None, a Box, or 6 numbers (x_min, x_max, y_min, y_max, z_min, z_max) in metres.
std::optional<Box> boxFrom(const py::object& o, const char* what) {
  if (o.is_none()) return std::nullopt;
  if (py::isinstance<Box>(o)) return o.cast<Box>();
  std::vector<double> v;
  try {
    v = o.cast<std::vector<double>>();
  } catch (const py::cast_error&) {
    throw py::type_error(std::string(what) + ": expected a Box, 6 numbers or None");
  }
  if (v.size() != 6) throw py::value_error(std::string(what) + ": expected (x_min, x_max, y_min, y_max, z_min, z_max)");
  return Box(v[0], v[1], v[2], v[3], v[4], v[5]);
}

PclIcpVariant variantFromString(const std::string& s) {
  for (auto v : {PclIcpVariant::Svd, PclIcpVariant::DualQuaternion, PclIcpVariant::PointToPlaneLLS,
                 PclIcpVariant::ScanalignPointToPlaneLLS})
    if (s == toString(v)) return v;
  throw py::value_error("variant must be 'svd', 'dual_quaternion', 'point_to_plane_lls' or "
                        "'scanalign_point_to_plane_lls', got '" + s + "'");
}

/// Nearest neighbour of every query row (in parallel): (input index or -1, squared
/// distance in m^2, exact) arrays. `search(q, max_d2)` returns a NearestNeighbor whose node
/// `index_of` maps back to the input cloud.
template <typename Scalar, typename Search, typename IndexOf>
py::tuple nearestAll(const py::array& queries, double max_distance, Search&& search, IndexOf&& index_of) {
  if (!(max_distance > 0.0)) throw py::value_error("max_distance must be a positive distance in metres (or inf)");
  const auto q = cloudView<Scalar>(queries, "queries");
  const auto n = static_cast<py::ssize_t>(q.size);
  py::array_t<std::int64_t> index(n);
  py::array_t<Scalar> d2(n);
  py::array_t<bool> exact(n);
  auto* ip = index.mutable_data();
  auto* dp = d2.mutable_data();
  auto* ep = exact.mutable_data();
  const Scalar max_d2 = std::isinf(max_distance) ? std::numeric_limits<Scalar>::infinity()
                                                   : static_cast<Scalar>(max_distance * max_distance);
  {
    py::gil_scoped_release release;
#pragma omp parallel for schedule(dynamic, 256)
    for (py::ssize_t i = 0; i < n; ++i) {
      const auto nn = search(q.ptr(static_cast<std::size_t>(i)), max_d2);
      ip[i] = nn.found() ? static_cast<std::int64_t>(index_of(nn.node)) : -1;
      dp[i] = nn.squared_distance;
      ep[i] = nn.exact;
    }
  }
  return py::make_tuple(index, d2, exact);
}

template <typename T>
struct ScalarOf;
template <typename S>
struct ScalarOf<Icp<S>> {
  using type = S;
};
template <typename S>
struct ScalarOf<LeftBalancedKdTree<S>> {
  using type = S;
};

bool isDouble(const py::array& a) { return holds<double>(a); }

/// The ICP engine in the target's precision: float32 when target and normals are float32
/// (half the memory, faster), else float64; sources are cast to it.
class AnyIcp {
 public:
  AnyIcp(const py::array& target, const py::object& normals, const IcpSettings& settings) {
    validate(settings);
    // Copies kept for pickling (the tree reorders and filters its points): the engine is
    // rebuilt from them on load, exactly as here.
    target_ = target.attr("copy")();
    normals_ = normals.is_none() ? normals : py::array::ensure(normals).attr("copy")();
    if (isDouble(target) || (!normals.is_none() && isDouble(py::cast<py::array>(normals))))
      engine_.emplace<Icp<double>>(settings);
    else
      engine_.emplace<Icp<float>>(settings);
    std::visit(
        [&](auto& icp) {
          using Scalar = typename ScalarOf<std::decay_t<decltype(icp)>>::type;
          const py::array t = asCloudArray<Scalar>(target, "target");
          const py::object n = normals.is_none() ? normals : asCloudArray<Scalar>(py::cast<py::array>(normals), "target_normals");
          const auto tv = cloudView<Scalar>(t, "target");
          const auto nv = optionalCloudView<Scalar>(n, "target_normals");
          // Fail here rather than at the first align().
          if (n.is_none() && settings.estimator == IcpEstimator::PointToPlane) throw py::value_error(kNeedsNormals);
          py::gil_scoped_release release;
          icp.setTarget(tv, nv);
        },
        engine_);
  }

  IcpResult align(const py::array& source, const Eigen::Matrix4d& init) {
    return std::visit(
        [&](auto& icp) {
          using Scalar = typename ScalarOf<std::decay_t<decltype(icp)>>::type;
          const py::array s = asCloudArray<Scalar>(source, "source");
          const auto view = cloudView<Scalar>(s, "source");
          py::gil_scoped_release release;
          return icp.align(view, init);
        },
        engine_);
  }

  IcpSettings settings() const { return std::visit([](const auto& icp) { return icp.settings(); }, engine_); }
  void setSettings(const py::object& o) {
    // py::object, not IcpSettings: a wrong value is a TypeError naming the property, not
    // pybind11's dump of the setter's signature.
    if (!py::isinstance<IcpSettings>(o))
      throw py::type_error("Icp.settings: expected an IcpSettings, got " + fields::shown(o));
    const IcpSettings s = o.cast<IcpSettings>();
    validate(s);
    std::visit(
        [&](auto& icp) {
          if (!icp.hasNormals() && s.estimator == IcpEstimator::PointToPlane) throw py::value_error(kNeedsNormals);
          icp.settings() = s;
        },
        engine_);
  }
  std::size_t targetSize() const { return std::visit([](const auto& icp) { return icp.targetSize(); }, engine_); }
  int treeHeight() const { return std::visit([](const auto& icp) { return icp.treeHeight(); }, engine_); }
  double treeBuildSeconds() const {
    return std::visit([](const auto& icp) { return icp.treeBuildSeconds(); }, engine_);
  }
  bool hasNormals() const { return std::visit([](const auto& icp) { return icp.hasNormals(); }, engine_); }
  std::string dtype() const { return std::holds_alternative<Icp<double>>(engine_) ? "float64" : "float32"; }
  const py::array& target() const { return target_; }
  const py::object& targetNormals() const { return normals_; }

 private:
  std::variant<Icp<float>, Icp<double>> engine_;
  py::array target_;   ///< the target as given (a copy), for pickling
  py::object normals_;  ///< its normals (a copy) or None
};

void defineIcp(py::module_& m) {
  py::class_<AnyIcp>(m, "Icp",
                     "Reusable ICP against one target (the model): the k-d tree is built once. The tree keeps the "
                     "target's precision (float32 when target and normals are float32), sources are cast to it.")
      .def(py::init<const py::array&, const py::object&, const IcpSettings&>(), py::arg("target"),
           py::arg("target_normals"), py::arg("settings"),
           "target: (N, 3) float points, m, target frame; target_normals: (N, 3) unit normals (needed for "
           "point-to-plane; non-finite or zero ones leave their point out) or None")
      .def("align", &AnyIcp::align, py::arg("source"), py::arg("init"),
           "Aligns source ((N, 3) float, m, source frame; non-finite rows ignored) from init = T_target_source "
           "(4x4 rigid); returns an IcpResult")
      .def_property("settings", &AnyIcp::settings, &AnyIcp::setSettings,
                    "a copy of the IcpSettings; assign a new one to change them")
      .def_property_readonly("target_size", &AnyIcp::targetSize, "points in the tree (finite, with a valid normal)")
      .def_property_readonly("has_normals", &AnyIcp::hasNormals)
      .def_property_readonly("tree_height", &AnyIcp::treeHeight, "levels of the target's tree below its root")
      .def_property_readonly("tree_build_seconds", &AnyIcp::treeBuildSeconds,
                             "time spent building the target's k-d tree and normal table, s")
      .def_property_readonly("dtype", &AnyIcp::dtype, "'float32' or 'float64': the engine's precision")
      .def(py::pickle(
          [](const AnyIcp& icp) {
            py::dict d;
            d["target"] = icp.target();
            d["target_normals"] = icp.targetNormals();
            d["settings"] = icp.settings();
            return d;
          },
          [](const py::dict& d) {
            for (const char* key : {"target", "target_normals", "settings"})
              if (!d.contains(key)) throw py::value_error(std::string("Icp: pickled state lacks '") + key + "'");
            if (!py::isinstance<py::array>(d["target"]))
              throw py::type_error("Icp: pickled state 'target' must be a NumPy array");
            if (!py::isinstance<IcpSettings>(d["settings"]))
              throw py::type_error("Icp: pickled state 'settings' must be an IcpSettings");
            return AnyIcp(d["target"].cast<py::array>(), d["target_normals"], d["settings"].cast<IcpSettings>());
          }));
}

/// A tree's points back in input order, (max index + 1, 3), NaN rows for the input rows the
/// tree left out (non-finite): rebuilding from it gives the same tree and the same indices.
template <typename Scalar, typename IndexAt, typename PointAt>
py::array_t<Scalar> inputOrderPoints(std::size_t size, IndexAt index_at, PointAt point_at) {
  std::size_t rows = 0;
  for (std::size_t i = 0; i < size; ++i) rows = std::max<std::size_t>(rows, index_at(i) + std::size_t{1});
  py::array_t<Scalar> a({static_cast<py::ssize_t>(rows), py::ssize_t{3}});
  std::fill(a.mutable_data(), a.mutable_data() + 3 * rows, std::numeric_limits<Scalar>::quiet_NaN());
  for (std::size_t i = 0; i < size; ++i) {
    Scalar* row = a.mutable_data() + 3 * static_cast<std::size_t>(index_at(i));
    point_at(i, row);
  }
  return a;
}

/// The "points" entry of a pickled tree: a float array of the tree's precision.
template <typename Scalar>
py::array pickledPoints(const py::dict& d, const char* cls) {
  if (!d.contains("points")) throw py::value_error(std::string(cls) + ": pickled state lacks 'points'");
  if (!py::isinstance<py::array_t<Scalar>>(d["points"]))
    throw py::type_error(std::string(cls) + ": pickled state 'points' must be a " +
                         std::string(py::str(py::dtype::of<Scalar>())) + " array");
  return d["points"].cast<py::array>();
}

/// The left-balanced k-d tree of the eye-in-hand paper, §3.1, in the points' precision.
class AnyKdTree {
 public:
  explicit AnyKdTree(const py::array& points) {
    if (isDouble(points))
      tree_.emplace<LeftBalancedKdTree<double>>();
    else
      tree_.emplace<LeftBalancedKdTree<float>>();
    std::visit(
        [&](auto& tree) {
          using Scalar = typename ScalarOf<std::decay_t<decltype(tree)>>::type;
          const py::array p = asCloudArray<Scalar>(points, "points");
          const auto view = cloudView<Scalar>(p, "points");
          py::gil_scoped_release release;
          tree.build(view);
        },
        tree_);
  }
  std::size_t size() const { return std::visit([](const auto& t) { return t.size(); }, tree_); }
  int height() const { return std::visit([](const auto& t) { return t.height(); }, tree_); }
  /// The input points (input order, NaN rows for the ones left out), for pickling.
  py::array points() const {
    return std::visit(
        [](const auto& tree) -> py::array {
          using Scalar = typename ScalarOf<std::decay_t<decltype(tree)>>::type;
          return inputOrderPoints<Scalar>(
              tree.size(), [&](std::size_t i) { return tree.node(i).index(); },
              [&](std::size_t i, Scalar* row) { std::copy(tree.node(i).p, tree.node(i).p + 3, row); });
        },
        tree_);
  }

  py::tuple nearest(const py::array& queries, double max_distance, int stack_depth) const {
    if (stack_depth < 1 || stack_depth > LeftBalancedKdTree<float>::kMaxStack)
      throw py::value_error("stack_depth must be in [1, " + std::to_string(LeftBalancedKdTree<float>::kMaxStack) + "]");
    return std::visit(
        [&](const auto& tree) {
          using Scalar = typename ScalarOf<std::decay_t<decltype(tree)>>::type;
          const py::tuple r = nearestAll<Scalar>(
              asCloudArray<Scalar>(queries, "queries"), max_distance,
              [&](const Scalar* q, Scalar max_d2) { return tree.nearest(q, max_d2, stack_depth); },
              [&](std::uint32_t node) { return tree.node(node).index(); });
          const auto d2 = r[1].cast<py::array_t<Scalar>>();
          py::array_t<double> d(d2.size());
          for (py::ssize_t i = 0; i < d2.size(); ++i) d.mutable_data()[i] = std::sqrt(double(d2.data()[i]));
          return py::make_tuple(r[0], d, r[2]);
        },
        tree_);
  }

 private:
  std::variant<LeftBalancedKdTree<float>, LeftBalancedKdTree<double>> tree_;
};

void defineKdTree(py::module_& m) {
  py::class_<AnyKdTree>(m, "KdTree",
                        "The left-balanced k-d tree of the eye-in-hand paper, §3.1 (one point per node, searched with "
                        "a fixed stack), in the points' precision")
      .def(py::init<const py::array&>(), py::arg("points"), "points: (N, 3) float, m; non-finite rows are skipped")
      .def_property_readonly("size", &AnyKdTree::size, "points in the tree (the finite input rows)")
      .def_property_readonly("height", &AnyKdTree::height,
                             "levels below the root; the fixed-stack search is exact when stack_depth >= height")
      .def("nearest", &AnyKdTree::nearest, py::arg("queries"),
           py::arg("max_distance") = std::numeric_limits<double>::infinity(), py::arg("stack_depth") = 20,
           "Nearest neighbour of each (N, 3) query within max_distance (m, exclusive; positive), stack_depth in "
           "[1, 64]. Returns (indices int64 into points, -1 for none in range; Euclidean distances, m, float64, inf "
           "where none; exact: per-query flags telling whether the fixed stack sufficed)")
      .def(py::pickle(
          [](const AnyKdTree& t) {
            py::dict d;
            d["points"] = t.points();
            return d;
          },
          [](const py::dict& d) {
            if (!d.contains("points")) throw py::value_error("KdTree: pickled state lacks 'points'");
            if (!py::isinstance<py::array>(d["points"]) || py::array(d["points"]).dtype().kind() != 'f')
              throw py::type_error("KdTree: pickled state 'points' must be a float array");
            return AnyKdTree(d["points"].cast<py::array>());
          }));
}

template <typename Scalar>
void defineBucketKdTree(py::module_& m, const char* name) {
  using Tree = BucketKdTree<Scalar>;
  py::class_<Tree>(m, name)
      .def(py::init([](const py::array& points, int leaf_size) {
             const auto view = cloudView<Scalar>(points, "points");
             py::gil_scoped_release release;
             return Tree(view, leaf_size);
           }),
           py::arg("points"), py::arg("leaf_size"))
      .def_property_readonly("size", &Tree::size)
      .def_property_readonly("height", &Tree::height)
      .def_property_readonly("leaf_size", &Tree::leafSize)
      .def_property_readonly("node_count", &Tree::nodeCount)
      .def_property_readonly("memory_bytes", &Tree::memoryBytes)
      .def(
          "nearest",
          [](const Tree& tree, const py::array& queries, double max_distance) {
            const py::tuple r = nearestAll<Scalar>(
                queries, max_distance, [&](const Scalar* q, Scalar max_d2) { return tree.nearest(q, max_d2); },
                [&](std::uint32_t node) { return tree.index(node); });
            return py::tuple(r[py::slice(0, 2, 1)]);  // (indices, distances): always exact
          },
          py::arg("queries"), py::arg("max_distance"))
      .def(py::pickle(
          [](const Tree& tree) {
            py::dict d;
            d["points"] = inputOrderPoints<Scalar>(
                tree.size(), [&](std::size_t i) { return tree.index(i); },
                [&](std::size_t i, Scalar* row) {
                  row[0] = tree.x(i);
                  row[1] = tree.y(i);
                  row[2] = tree.z(i);
                });
            d["leaf_size"] = tree.leafSize();
            return d;
          },
          [name = std::string(name)](const py::dict& d) {
            const py::array points = pickledPoints<Scalar>(d, name.c_str());
            if (!d.contains("leaf_size")) throw py::value_error(name + ": pickled state lacks 'leaf_size'");
            const int leaf_size = boundedInt(d["leaf_size"], (name + ": pickled state 'leaf_size'").c_str(), 1);
            const auto view = cloudView<Scalar>(points, "points");
            py::gil_scoped_release release;
            return Tree(view, leaf_size);
          }));
}

std::string describe(const IcpResult& r) {
  std::ostringstream os;
  os << "IcpResult(status='" << toString(r.status) << "', converged=" << (r.converged ? "True" : "False")
     << ", iterations=" << r.iterations << ", coarse_iterations=" << r.coarse_iterations << ", fitness=" << r.fitness << ", inlier_rmse=" << r.inlier_rmse
     << ", correspondences=" << r.correspondence_count << ", degenerate=" << (r.degenerate ? "True" : "False")
     << ", seconds=" << r.seconds << ")";
  return os.str();
}

}  // namespace

void defineRegistration(py::module_& m) {
  fieldsOf(py::class_<Box>(m, "Box",
                  "Axis-aligned box (x_min, x_max, y_min, y_max, z_min, z_max) in metres, in the source camera frame "
                  "(x right, y down, z towards the object); eye-in-hand paper (Comput. Electron. Agric. 180 (2021) "
                  "105929), §3.4. A correspondence is kept only when its source point lies inside (bounds inclusive); "
                  "the box moves with the transform ICP applies to the source. Presets: free_hand_preset() (+-0.20 m, "
                  "0.1 mm to 10 m deep) and banana_preset().")
      .def(py::init<double, double, double, double, double, double>(), py::arg("x_min"), py::arg("x_max"),
           py::arg("y_min"), py::arg("y_max"), py::arg("z_min"), py::arg("z_max"))
      .def(py::init([](const py::sequence& bounds) { return *boxFrom(bounds, "Box"); }), py::arg("bounds"),
           "From 6 numbers (x_min, x_max, y_min, y_max, z_min, z_max), m")
      .def("as_tuple",
           [](const Box& b) {
             return py::make_tuple(b.min.x(), b.max.x(), b.min.y(), b.max.y(), b.min.z(), b.max.z());
           })
      .def_property_readonly("valid", &Box::valid, "finite bounds with min <= max on every axis")
      .def_static("free_hand_preset", &Box::freeHandPreset)
      .def_static("banana_preset", &Box::bananaPreset)
      .def("__repr__", [](const Box& b) {
        std::ostringstream os;
        os << "Box(x=[" << b.min.x() << ", " << b.max.x() << "], y=[" << b.min.y() << ", " << b.max.y() << "], z=["
           << b.min.z() << ", " << b.max.z() << "])";
        return os.str();
      }))
      .output("min", &Box::min, "m", "(x_min, y_min, z_min)")
      .output("max", &Box::max, "m", "(x_max, y_max, z_max)")
      .result();

  using IS = IcpSettings;
  fieldsOf(py::class_<IcpSettings>(m, "IcpSettings",
                                   "ICP settings, PCL semantics; defaults are the eye-in-hand paper's (§3.3) where it "
                                   "gives one. validate() raises ValueError naming a bad field."))
      .name("estimator", &IS::estimator, 3, "",
            "'point_to_plane' (Low 2004 LLS, eye-in-hand paper §3.2; needs target normals), 'point_to_point' "
            "(closed form by SVD, Horn / Umeyama) or 'dual_quaternion' (the same least squares by Walker, Shao & "
            "Volz 1991's dual quaternions: the eye-in-hand paper's variant (b))")
      .field("max_correspondence_distance", &IS::max_correspondence_distance, "m", "pairs farther apart are rejected")
      .field("max_iterations", &IS::max_iterations, "",
             "iteration cap; reaching it gives status 'max_iterations', converged False. Ctrl-C stops a long run "
             "between iterations (KeyboardInterrupt)")
      .field("transformation_epsilon", &IS::transformation_epsilon, "m^2",
             "converged when the last increment's squared translation is <= this and its rotation has cos(angle) >= "
             "1 - this")
      .field("transformation_rotation_epsilon", &IS::transformation_rotation_epsilon, "",
             "if > 0, the rotation test is cos(angle) >= this cosine instead (PCL's "
             "setTransformationRotationEpsilon)")
      .field("fitness_epsilon", &IS::fitness_epsilon, "",
             "converged when the relative change of the correspondence MSE is below this (PCL's Euclidean fitness "
             "epsilon)")
      .field("absolute_mse_epsilon", &IS::absolute_mse_epsilon, "m^2", "converged when the MSE changes by less than this")
      .name("robust_kernel", &IS::robust_kernel, 3, "",
            "'none' (Low's plain least squares, as the eye-in-hand paper), 'huber' or 'cauchy': an M-estimator on "
            "the point-to-plane residual solved by IRLS (point-to-plane only). For large correspondence distances: on "
            "the small_gicp LiDAR pair (0.25 m voxels, 1 m distance) Huber at 0.1 m lands 6 mm from the reference "
            "instead of 27 mm")
      .field("robust_scale", &IS::robust_scale, "m",
             "the kernel's scale: residuals up to about this count fully; set it near the residual noise after "
             "convergence")
      .field(
          "box", [](const IS& s) { return s.box; },
          [](IS& s, py::handle v) { s.box = boxFrom(py::reinterpret_borrow<py::object>(v), "IcpSettings.box"); }, "m",
          "optional Box (or 6 numbers) in the source camera frame (eye-in-hand paper §3.4); None = off")
      .name("search", &IS::search, 2, "",
            "'bucket_kdtree' (32-point leaves, tight node boxes, fastest on CPU cores, exact) or "
            "'left_balanced_kdtree' (eye-in-hand paper §3.1: one point per node, fixed search stack, the layout of "
            "its GPU path)")
      .field("search_stack_depth", &IS::search_stack_depth, "",
             "fixed search stack of the left-balanced tree (eye-in-hand paper §3.1: 20); exact for targets of up to "
             "2**21 - 1 points, IcpResult.exact_search reports otherwise")
      .field("warm_start", &IS::warm_start, "", "seed each search with the last iteration's neighbour (exact speed-up)")
      .field("min_correspondences", &IS::min_correspondences, "",
             "stop with 'not_enough_correspondences' below this (at least 3 enforced for point-to-point)")
      .field("degeneracy_threshold", &IS::degeneracy_threshold, "",
             "eigenvalue ratio below which a motion direction counts as unconstrained and is not updated (only "
             "numerical rank loss: a small object on a large table gives ratios near 1e-7 that must still be solved)")
      .field("coarse_stride", &IS::coarse_stride, "",
             "coarse-to-fine when > 1: iterate on every coarse_stride-th source point (an even spatial subset) until "
             "that converges, then on all points; the same full-resolution fixed point in fewer full iterations (1 = "
             "off, as the eye-in-hand paper; skipped below 500 subset points)")
      .field("num_threads", &IS::num_threads, "", "OpenMP threads, 0 = all cores")
      .name("backend", &IS::backend, 2, "",
            "'cpu' (OpenMP on the CPU cores) or 'cuda' (an NVIDIA GPU, the eye-in-hand paper's Algorithm 1: the "
            "model's left-balanced tree stays on the device, one kernel pass per iteration, the 6x6 solve on the "
            "CPU; always the left-balanced search, 'search' is ignored; the CPU engine's poses on the same input). "
            "'cuda' needs a build with SCANALIGN_WITH_CUDA (RuntimeError naming it otherwise) and a device "
            "(scanalign.registration.cuda_devices())")
      .settings()
      .def("validate", [](const IcpSettings& s) { validate(s); });

  using IR = IcpResult;
  fieldsOf(py::class_<IcpResult>(m, "IcpResult",
                                 "Outcome of an ICP run; quality figures are measured at the final transform.")
               .def("__repr__", &describe))
      .output("T_target_source", &IR::T_target_source, "m", "4x4 float64: p_target = T_target_source @ p_source")
      .derived("transformation", [](const IR& r) { return r.T_target_source; }, "m",
               "T_target_source under Open3D's name (RegistrationResult.transformation), for code written for Open3D")
      .output("converged", &IR::converged, "", "a convergence criterion (transform or MSE change) was met")
      .name("status", &IR::status, 6, "",
            "'converged_transform', 'converged_absolute_mse', 'converged_relative_mse', 'max_iterations', "
            "'not_enough_correspondences' or 'degenerate' (point-to-point: the source points, or the target points "
            "they matched, coincide or are collinear, so the rotation is undetermined); for the last two the "
            "transform is the last good estimate and converged is False",
            false)
      .output("iterations", &IR::iterations, "", "full-resolution iterations run")
      .output("coarse_iterations", &IR::coarse_iterations, "",
              "iterations of the coarse phase (coarse_stride > 1), each on a subset of the source")
      .output("fitness", &IR::fitness, "", "inliers / usable source points (finite, inside the box)")
      .output("inlier_rmse", &IR::inlier_rmse, "m", "RMS point-to-point distance of the inliers")
      .output("correspondence_count", &IR::correspondence_count, "", "inliers at the final transform")
      .output("source_points_used", &IR::source_points_used, "", "finite source points inside the box")
      .output("mse", &IR::mse, "m^2", "mean squared correspondence distance of the last iteration")
      .output("degenerate", &IR::degenerate, "", "some iteration could not constrain all 6 motions")
      .output("min_rank", &IR::min_rank, "", "smallest rank of the normal equations over the iterations")
      .output("exact_search", &IR::exact_search, "", "every nearest-neighbour search was exact")
      .output("seconds", &IR::seconds, "s", "wall time of the alignment (target tree build excluded)")
      .result();
  defineIcp(m);
  defineKdTree(m);
  m.def("cuda_devices", &cuda::deviceNames,
        "The CUDA devices the 'cuda' backend can use, as 'index: name (compute capability, memory)'; empty without "
        "a device or driver, or in a build without SCANALIGN_WITH_CUDA (scanalign._core.built_with_cuda)");
  m.def(
      "alignment_fitness",
      [](const py::array& s, const py::array& t, const py::object& T_in, double thr, int threads) {
        const Eigen::Matrix4d T = fields::Conv<Eigen::Matrix4d>::set(T_in, "T_target_source");
        const auto f = alignmentFitness(cloudView<double>(s, "source"), cloudView<double>(t, "target"), T, thr, threads);
        return py::make_tuple(f.first, f.second);
      },
      py::arg("source"), py::arg("target"), py::arg("T_target_source"), py::arg("threshold"), py::arg("num_threads") = 0,
      "(fitness, inlier_rmse): finite source points whose nearest target point is within threshold (m) after "
      "T_target_source, and their RMS distance (m)");
  m.def(
      "fit_similarity",
      [](const py::array& source, const py::array& target, bool with_scale) {
        const auto x = cloudView<double>(source, "source");
        const auto y = cloudView<double>(target, "target");
        Similarity r;
        {
          py::gil_scoped_release release;
          r = fitSimilarity(x, y, with_scale);
        }
        return py::make_tuple(Eigen::Matrix3d(r.R), Eigen::Vector3d(r.t), r.scale);
      },
      py::arg("source"), py::arg("target"), py::arg("with_scale"),
      "Least-squares (R, t, scale) with target ~ scale R source + t (Umeyama 1991); scale 1 "
      "unless with_scale. Raises ValueError for unequal sizes, fewer than 3 pairs, non-finite "
      "or degenerate (coincident or collinear) points.");
  defineBucketKdTree<float>(m, "BucketKdTree32");
  defineBucketKdTree<double>(m, "BucketKdTree64");

  m.def(
      "pcl_icp",
      [](const py::array& source, const py::array& target, const py::object& normals, const Eigen::Matrix4d& init,
         const IcpSettings& settings, const std::string& variant) {
        const auto s = cloudView<float>(source, "source");
        const auto t = cloudView<float>(target, "target");
        const auto n = optionalCloudView<float>(normals, "target_normals");
        const PclIcpVariant v = variantFromString(variant);
        const bool plane = v == PclIcpVariant::PointToPlaneLLS || v == PclIcpVariant::ScanalignPointToPlaneLLS;
        if (plane && n.size != t.size)
          throw py::value_error("target_normals: variant '" + variant + "' needs one normal per target point, got " +
                                std::to_string(n.size) + " for " + std::to_string(t.size));
        py::gil_scoped_release release;
        return pclIcp(s, t, n, init, settings, v);
      },
      py::arg("source"), py::arg("target"), py::arg("target_normals"), py::arg("init"), py::arg("settings"),
      py::arg("variant"));
  m.def(
      "pcl_point_to_plane_lls",
      [](const py::array& source, const py::array& target, const py::array& normals) {
        double seconds = 0.0;
        const Eigen::Matrix4d T = pclPointToPlaneLLS(cloudView<float>(source, "source"), cloudView<float>(target, "target"),
                                                     cloudView<float>(normals, "target_normals"), &seconds);
        return py::make_tuple(T, seconds);
      },
      py::arg("source"), py::arg("target"), py::arg("target_normals"));
  m.def(
      "point_to_plane_lls",
      [](const py::array& source, const py::array& target, const py::array& normals, double threshold) {
        PointToPlaneSolve solve;
        double seconds = 0.0;
        const Eigen::Matrix4d T =
            scanalignPointToPlaneLLS(cloudView<float>(source, "source"), cloudView<float>(target, "target"),
                                     cloudView<float>(normals, "target_normals"), &solve, threshold, &seconds);
        return py::make_tuple(T, solve.rank, solve.conditioning, solve.degenerate, seconds);
      },
      py::arg("source"), py::arg("target"), py::arg("target_normals"), py::arg("degeneracy_threshold"));
  m.def(
      "box_rejector_keep",
      [](const py::array& source, const std::vector<int>& query_indices, const py::object& box) {
        const auto s = cloudView<float>(source, "source");
        const std::optional<Box> b = boxFrom(box, "box");
        if (!b || !b->valid()) throw py::value_error("box: need a Box with finite bounds, min <= max");
        for (int i : query_indices)
          if (i < 0 || static_cast<std::size_t>(i) >= s.size)
            throw py::value_error("query_indices: " + std::to_string(i) + " is out of range of source (" +
                                  std::to_string(s.size) + " points)");
        return boxRejectorKeep(s, query_indices, *b);
      },
      py::arg("source"), py::arg("query_indices"), py::arg("box"),
      "Runs scanalign::BoxRejector (the PCL plug-in) on correspondences with the given source indices; returns "
      "the kept source indices.");
}

}  // namespace scanalign::python
