#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <sstream>

#include "arrays.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/registration/icp.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace scanalign::python {

namespace {

IcpEstimator estimatorFromString(const std::string& s) {
  if (s == "point_to_plane") return IcpEstimator::PointToPlane;
  if (s == "point_to_point") return IcpEstimator::PointToPoint;
  throw py::value_error("estimator must be 'point_to_plane' or 'point_to_point', got '" + s + "'");
}

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

PclIcpVariant variantFromString(const std::string& s) {
  for (auto v : {PclIcpVariant::Svd, PclIcpVariant::DualQuaternion, PclIcpVariant::PointToPlaneLLS,
                 PclIcpVariant::ScanalignPointToPlaneLLS})
    if (s == toString(v)) return v;
  throw py::value_error("variant must be 'svd', 'dual_quaternion', 'point_to_plane_lls' or "
                        "'scanalign_point_to_plane_lls', got '" + s + "'");
}

template <typename Scalar>
void defineIcp(py::module_& m, const char* name) {
  py::class_<Icp<Scalar>>(m, name)
      .def(py::init<IcpSettings>(), py::arg("settings"))
      .def(
          "set_target",
          [](Icp<Scalar>& self, const py::array& points, const py::object& normals) {
            const auto p = cloudView<Scalar>(points, "target");
            const auto n = optionalCloudView<Scalar>(normals, "target_normals");
            py::gil_scoped_release release;
            self.setTarget(p, n);
          },
          py::arg("points"), py::arg("normals"))
      .def(
          "align",
          [](Icp<Scalar>& self, const py::array& source, const Eigen::Matrix4d& init) {
            const auto s = cloudView<Scalar>(source, "source");
            py::gil_scoped_release release;
            return self.align(s, init);
          },
          py::arg("source"), py::arg("init"))
      .def_property(
          "settings", [](const Icp<Scalar>& self) { return self.settings(); },
          [](Icp<Scalar>& self, const IcpSettings& s) { self.settings() = s; })
      .def_property_readonly("target_size", &Icp<Scalar>::targetSize)
      .def_property_readonly("has_normals", &Icp<Scalar>::hasNormals)
      .def_property_readonly("tree_height", &Icp<Scalar>::treeHeight)
      .def_property_readonly("tree_build_seconds", &Icp<Scalar>::treeBuildSeconds);
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

template <typename Scalar>
void defineKdTree(py::module_& m, const char* name) {
  using Tree = LeftBalancedKdTree<Scalar>;
  py::class_<Tree>(m, name)
      .def(py::init([](const py::array& points) {
             const auto view = cloudView<Scalar>(points, "points");
             py::gil_scoped_release release;
             return Tree(view);
           }),
           py::arg("points"))
      .def_property_readonly("size", &Tree::size)
      .def_property_readonly("height", &Tree::height)
      .def(
          "nearest",
          [](const Tree& tree, const py::array& queries, double max_distance, int stack_depth) {
            return nearestAll<Scalar>(
                queries, max_distance,
                [&](const Scalar* q, Scalar max_d2) { return tree.nearest(q, max_d2, stack_depth); },
                [&](std::uint32_t node) { return tree.node(node).index(); });
          },
          py::arg("queries"), py::arg("max_distance"), py::arg("stack_depth"))
      .def(
          "radius",
          [](const Tree& tree, const py::array& query, double radius) {
            const auto q = cloudView<Scalar>(query, "query");
            if (q.size != 1) throw py::value_error("radius: query must be a (1, 3) array");
            std::vector<std::int64_t> out;
            tree.forEachInRadius(q.ptr(0), static_cast<Scalar>(radius * radius),
                                 [&](std::uint32_t node, Scalar) { out.push_back(tree.node(node).index()); });
            return out;
          },
          py::arg("query"), py::arg("radius"));
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
            return py::make_tuple(r[0], r[1]);  // always exact
          },
          py::arg("queries"), py::arg("max_distance"));
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
  py::class_<Box>(m, "Box", "Axis-aligned box in the source camera frame (metres), eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929) §3.4.")
      .def(py::init<double, double, double, double, double, double>(), py::arg("x_min"), py::arg("x_max"),
           py::arg("y_min"), py::arg("y_max"), py::arg("z_min"), py::arg("z_max"))
      .def_property_readonly("min", [](const Box& b) { return Eigen::Vector3d(b.min); })
      .def_property_readonly("max", [](const Box& b) { return Eigen::Vector3d(b.max); })
      .def("as_tuple",
           [](const Box& b) {
             return py::make_tuple(b.min.x(), b.max.x(), b.min.y(), b.max.y(), b.min.z(), b.max.z());
           })
      .def_property_readonly("valid", &Box::valid)
      .def_static("free_hand_preset", &Box::freeHandPreset)
      .def_static("banana_preset", &Box::bananaPreset)
      .def("__repr__", [](const Box& b) {
        std::ostringstream os;
        os << "Box(x=[" << b.min.x() << ", " << b.max.x() << "], y=[" << b.min.y() << ", " << b.max.y() << "], z=["
           << b.min.z() << ", " << b.max.z() << "])";
        return os.str();
      });

  py::class_<IcpSettings>(m, "IcpSettings")
      .def(py::init<>())
      .def_property(
          "estimator", [](const IcpSettings& s) { return std::string(toString(s.estimator)); },
          [](IcpSettings& s, const std::string& v) { s.estimator = estimatorFromString(v); })
      .def_readwrite("max_correspondence_distance", &IcpSettings::max_correspondence_distance)
      .def_readwrite("max_iterations", &IcpSettings::max_iterations)
      .def_readwrite("transformation_epsilon", &IcpSettings::transformation_epsilon)
      .def_readwrite("transformation_rotation_epsilon", &IcpSettings::transformation_rotation_epsilon)
      .def_readwrite("fitness_epsilon", &IcpSettings::fitness_epsilon)
      .def_readwrite("absolute_mse_epsilon", &IcpSettings::absolute_mse_epsilon)
      .def_property(
          "robust_kernel", [](const IcpSettings& s) { return std::string(toString(s.robust_kernel)); },
          [](IcpSettings& s, const std::string& v) { s.robust_kernel = kernelFromString(v); })
      .def_readwrite("robust_scale", &IcpSettings::robust_scale)
      .def_readwrite("box", &IcpSettings::box)
      .def_property(
          "search", [](const IcpSettings& s) { return std::string(toString(s.search)); },
          [](IcpSettings& s, const std::string& v) { s.search = searchFromString(v); })
      .def_readwrite("search_stack_depth", &IcpSettings::search_stack_depth)
      .def_readwrite("warm_start", &IcpSettings::warm_start)
      .def_readwrite("min_correspondences", &IcpSettings::min_correspondences)
      .def_readwrite("degeneracy_threshold", &IcpSettings::degeneracy_threshold)
      .def_readwrite("coarse_stride", &IcpSettings::coarse_stride)
      .def_readwrite("num_threads", &IcpSettings::num_threads)
      .def("validate", [](const IcpSettings& s) { validate(s); });

  py::class_<IcpResult>(m, "IcpResult")
      .def_property_readonly("T_target_source", [](const IcpResult& r) { return r.T_target_source; })
      .def_readonly("converged", &IcpResult::converged)
      .def_property_readonly("status", [](const IcpResult& r) { return std::string(toString(r.status)); })
      .def_readonly("iterations", &IcpResult::iterations)
      .def_readonly("coarse_iterations", &IcpResult::coarse_iterations)
      .def_readonly("fitness", &IcpResult::fitness)
      .def_readonly("inlier_rmse", &IcpResult::inlier_rmse)
      .def_readonly("correspondence_count", &IcpResult::correspondence_count)
      .def_readonly("source_points_used", &IcpResult::source_points_used)
      .def_readonly("mse", &IcpResult::mse)
      .def_readonly("degenerate", &IcpResult::degenerate)
      .def_readonly("min_rank", &IcpResult::min_rank)
      .def_readonly("exact_search", &IcpResult::exact_search)
      .def_readonly("seconds", &IcpResult::seconds)
      .def("__repr__", &describe);

  defineIcp<float>(m, "Icp32");
  defineIcp<double>(m, "Icp64");
  defineKdTree<float>(m, "KdTree32");
  defineKdTree<double>(m, "KdTree64");
  m.attr("RIGID_TOLERANCE") = kRigidTolerance;
  m.attr("RIGID_ROW_TOLERANCE") = kRigidRowTolerance;
  m.def(
      "rigid_problem",
      [](const Eigen::Matrix4d& T) -> py::object {
        const char* problem = rigidProblem(T);
        return problem ? py::object(py::str(problem)) : py::object(py::none());
      },
      py::arg("T"), "Why a 4x4 matrix is not a rigid transform (common/rigid.hpp), or None when it is.");
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
      [](const py::array& source, const std::vector<int>& query_indices, const Box& box) {
        return boxRejectorKeep(cloudView<float>(source, "source"), query_indices, box);
      },
      py::arg("source"), py::arg("query_indices"), py::arg("box"),
      "Runs scanalign::BoxRejector (the PCL plug-in) on correspondences with the given source indices; returns "
      "the kept source indices.");
}

}  // namespace scanalign::python
