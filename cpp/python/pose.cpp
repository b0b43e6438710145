// Bindings of the CAD-pose chain: model views, CBD descriptor, motor estimation, correspondence
// RANSAC, CBD alignment, paper 4's flag alignment, and the estimatePose / findObjects
// pipeline. Settings and results are the C++ structs, documented here once.
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <cstring>

#include "arrays.hpp"
#include "pickle.hpp"
#include "scanalign/pose/cbd.hpp"
#include "scanalign/pose/model_views.hpp"
#include "scanalign/pose/pcl/coarse_aligner.hpp"
#include "scanalign/pose/pose_estimation.hpp"
#include "scanalign/pose/cbd_alignment.hpp"
#include "scanalign/pose/correspondence_ransac.hpp"
#include "scanalign/pose/flag_alignment.hpp"
#include "scanalign/pose/motor_estimation.hpp"

namespace scanalign::python {

namespace {

using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
using U32 = py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>;

template <typename Out, typename In>
py::array_t<Out> vec(const std::vector<In>& v) {
  py::array_t<Out> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// (n, k) copy of row-major data.
template <typename Out, typename In>
py::array_t<Out> rows(const std::vector<In>& v, py::ssize_t k) {
  py::array_t<Out> a({static_cast<py::ssize_t>(v.size()) / k, k});
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// (n, k) from a vector of fixed-size Eigen vectors/matrices (k = coefficients, row-major for matrices).
template <typename E>
py::array_t<double> stack(const std::vector<E>& v, std::vector<py::ssize_t> tail) {
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(v.size())};
  shape.insert(shape.end(), tail.begin(), tail.end());
  py::array_t<double> a(shape);
  double* d = a.mutable_data();
  for (const E& e : v) {
    constexpr int C = E::ColsAtCompileTime;
    const Eigen::Matrix<double, E::RowsAtCompileTime, C, C == 1 ? Eigen::ColMajor : Eigen::RowMajor> r = e;
    d = std::copy(r.data(), r.data() + r.size(), d);
  }
  return a;
}

std::vector<NeighbourhoodPca> pcaFrom(const U32& count, const F64& ev) {
  if (ev.ndim() != 2 || ev.shape(1) != 3 || count.ndim() != 1 || count.shape(0) != ev.shape(0))
    throw py::value_error("expected counts (N,) and eigenvalues (N, 3)");
  std::vector<NeighbourhoodPca> p(static_cast<std::size_t>(count.shape(0)));
  for (std::size_t i = 0; i < p.size(); ++i) {
    p[i].count = count.data()[i];
    p[i].eigenvalues = Eigen::Vector3d(ev.data()[3 * i], ev.data()[3 * i + 1], ev.data()[3 * i + 2]);
  }
  return p;
}

const double* optionalWeights(const py::object& w, const F64& held, std::size_t n) {
  if (w.is_none()) return nullptr;
  if (held.ndim() != 1 || static_cast<std::size_t>(held.shape(0)) != n)
    throw py::value_error("weights: expected shape (" + std::to_string(n) + ",)");
  return held.data();
}

void bindCbd(py::module_& m) {
  py::enum_<CbdKeypointMode>(m, "CbdKeypointMode", "How CBD keypoints are chosen")
      .value("thresholds", CbdKeypointMode::Thresholds, "(6.4) with the given deltas and n_min")
      .value("automatic", CbdKeypointMode::Automatic, "the num_keypoints lowest-score points (paper 5, §III-B4)");
  py::enum_<CbdDescriptorVariant>(m, "CbdDescriptorVariant", "Which descriptor the matcher compares")
      .value("radius_distance", CbdDescriptorVariant::RadiusDistance, "(r1, d1, r2, d2), paper 5 (29)-(32)")
      .value("scalar", CbdDescriptorVariant::Scalar, "F = (S1 + S2).P, thesis (6.17)-(6.18)");
  py::class_<ShapeThresholds>(m, "ShapeThresholds", "delta_l, delta_p, delta_s of (6.4); a value >= 1 disables its factor")
      .def(py::init([](double l, double p, double s) { return ShapeThresholds{l, p, s}; }), py::arg("linear") = 0.3,
           py::arg("planar") = 1.0, py::arg("spherical") = 0.3)
      .def_readwrite("linear", &ShapeThresholds::linear, "delta_l (thesis Fig 6.3: 0.3)")
      .def_readwrite("planar", &ShapeThresholds::planar, "delta_p (thesis: 1, planar points are never keypoints)")
      .def_readwrite("spherical", &ShapeThresholds::spherical, "delta_s (thesis: 0.3)")
      .def("__repr__", [](const ShapeThresholds& t) {
        return "ShapeThresholds(linear=" + std::to_string(t.linear) + ", planar=" + std::to_string(t.planar) +
               ", spherical=" + std::to_string(t.spherical) + ")";
      });
  py::class_<CbdSettings>(m, "CbdSettings", "Settings of the curvature-based descriptor (thesis values by default)")
      .def(py::init<>())
      .def_readwrite("radius", &CbdSettings::radius, "neighbourhood radius r, m (paper 5 §IV-A: 0.0063)")
      .def_readwrite("gamma", &CbdSettings::gamma, "plane-distance weight exp(-gamma |d|), 1/m (paper 5: 0.2/mm = 200)")
      .def_readwrite("min_neighbors", &CbdSettings::min_neighbors,
                     "n_min, neighbours (the point included) to be a keypoint (paper 5: 200); 0 = half the median "
                     "neighbour count")
      .def_readwrite("keypoint_mode", &CbdSettings::keypoint_mode, "CbdKeypointMode (default thresholds)")
      .def_readwrite("num_keypoints", &CbdSettings::num_keypoints, "k of the automatic mode (paper 5: 2000)")
      .def_readwrite("thresholds", &CbdSettings::thresholds, "ShapeThresholds of the thresholds mode")
      .def_readwrite("max_keypoints", &CbdSettings::max_keypoints, "cap in the thresholds mode, lowest scores kept (0: none)")
      .def_readwrite("max_sphere_radius", &CbdSettings::max_sphere_radius,
                     "m; larger spheres and planes count as flat (r = d = this, F term 0)")
      .def_readwrite("variant", &CbdSettings::variant, "CbdDescriptorVariant used for matching")
      .def_readwrite("num_threads", &CbdSettings::num_threads, "OpenMP threads, 0 = all cores");
  py::class_<CbdFeatures>(m, "CbdFeatures", "CBD keypoints and descriptors of one cloud (arrays indexed by keypoint)")
      .def_property_readonly(
          "keypoints", [](const CbdFeatures& f) { return vec<std::int64_t>(f.keypoints); }, "(K,) indices into the cloud")
      .def_property_readonly(
          "descriptors", [](const CbdFeatures& f) { return stack(f.descriptors, {4}); }, "(K, 4) (r1, d1, r2, d2), m")
      .def_property_readonly(
          "scalar", [](const CbdFeatures& f) { return vec<double>(f.scalar); }, "(K,) F, m^2 (6.16)")
      .def_property_readonly(
          "sphere1",
          [](const CbdFeatures& f) {
            std::vector<Eigen::Matrix<double, 5, 1>> d;
            for (const auto& s : f.sphere1) d.push_back(s.dual);
            return stack(d, {5});
          },
          "(K, 5) dual sphere [c; (c^2 - r^2)/2; 1] on (e1, e2, e3, e_inf, e0) fitted with the plane normal to v2 "
          "(flat ones as dual planes [n; delta; 0])")
      .def_property_readonly(
          "sphere2",
          [](const CbdFeatures& f) {
            std::vector<Eigen::Matrix<double, 5, 1>> d;
            for (const auto& s : f.sphere2) d.push_back(s.dual);
            return stack(d, {5});
          },
          "(K, 5) the sphere fitted with the plane normal to v1")
      .def_property_readonly(
          "flat1",
          [](const CbdFeatures& f) {
            py::array_t<bool> a(static_cast<py::ssize_t>(f.sphere1.size()));
            for (std::size_t i = 0; i < f.sphere1.size(); ++i) a.mutable_data()[i] = f.sphere1[i].flat;
            return a;
          },
          "(K,) sphere1 was a plane or larger than max_sphere_radius")
      .def_property_readonly(
          "flat2",
          [](const CbdFeatures& f) {
            py::array_t<bool> a(static_cast<py::ssize_t>(f.sphere2.size()));
            for (std::size_t i = 0; i < f.sphere2.size(); ++i) a.mutable_data()[i] = f.sphere2[i].flat;
            return a;
          },
          "(K,) sphere2 was flat")
      .def_property_readonly(
          "axes", [](const CbdFeatures& f) { return stack(f.axes, {3, 3}); }, "(K, 3, 3) PCA eigenvectors v1, v2, v3 as columns")
      .def_readonly("thresholds", &CbdFeatures::thresholds, "the (6.4) deltas used (derived ones in the automatic mode)")
      .def_readonly("min_neighbors", &CbdFeatures::min_neighbors, "n_min used")
      .def_readonly("points_with_min_neighbors", &CbdFeatures::points_with_min_neighbors,
                    "points with at least n_min neighbours")
      .def_readonly("seconds", &CbdFeatures::seconds, "wall time")
      .def("__len__", [](const CbdFeatures& f) { return f.keypoints.size(); });

  m.def(
      "compute_cbd",
      [](const py::array& points, const CbdSettings& s, std::optional<ShapeThresholds> t) {
        return withCloud(points, "points", [&](auto view) {
          py::gil_scoped_release release;
          return computeCbd(view, s, t ? &*t : nullptr);
        });
      },
      py::arg("points"), py::arg("settings"), py::arg("thresholds") = py::none(),
      "CBD keypoints and descriptors of an (N, 3) float32/float64 cloud (m); `thresholds` forces (6.4) with these "
      "deltas (inclusive)");
  m.def(
      "neighbourhood_pca",
      [](const py::array& points, double radius, int threads) {
        const auto p = withCloud(points, "points", [&](auto view) {
          py::gil_scoped_release release;
          return neighbourhoodPca(view, radius, threads);
        });
        py::array_t<std::int64_t> count(static_cast<py::ssize_t>(p.size()));
        py::array_t<double> ev({static_cast<py::ssize_t>(p.size()), py::ssize_t{3}});
        for (std::size_t i = 0; i < p.size(); ++i) {
          count.mutable_data()[i] = p[i].count;
          for (int k = 0; k < 3; ++k) ev.mutable_data()[3 * i + k] = p[i].eigenvalues(k);
        }
        return py::make_tuple(count, ev);
      },
      py::arg("points"), py::arg("radius"), py::arg("num_threads") = 0,
      "Neighbour counts (N,) and covariance eigenvalues (N, 3), descending, m^2, of each point's ball of `radius` m");
  m.def(
      "select_keypoints",
      [](const U32& count, const F64& ev, const ShapeThresholds& t, int min_neighbors, bool inclusive) {
        return vec<std::int64_t>(selectKeypoints(pcaFrom(count, ev), t, min_neighbors, inclusive));
      },
      py::arg("counts"), py::arg("eigenvalues"), py::arg("thresholds"), py::arg("min_neighbors"), py::arg("inclusive"));
  m.def(
      "automatic_keypoints",
      [](const U32& count, const F64& ev, int k, int min_neighbors) {
        ShapeThresholds t;
        auto keys = automaticKeypoints(pcaFrom(count, ev), k, min_neighbors, &t);
        return py::make_tuple(vec<std::int64_t>(keys), t);
      },
      py::arg("counts"), py::arg("eigenvalues"), py::arg("k"), py::arg("min_neighbors"));
  m.def(
      "keypoint_scores",
      [](const U32& count, const F64& ev, int min_neighbors) {
        const auto p = pcaFrom(count, ev);
        std::vector<double> s(p.size());
        for (std::size_t i = 0; i < p.size(); ++i) s[i] = keypointScore(p[i], min_neighbors);
        return vec<double>(s);
      },
      py::arg("counts"), py::arg("eigenvalues"), py::arg("min_neighbors"));
  m.def(
      "match_cbd",
      [](const CbdFeatures& a, const CbdFeatures& b, CbdDescriptorVariant variant, int k, int threads) {
        CbdMatches mm;
        {
          py::gil_scoped_release release;
          mm = matchCbd(a, b, variant, k, threads);
        }
        py::array_t<std::int64_t> pairs({static_cast<py::ssize_t>(mm.source.size()), py::ssize_t{2}});
        for (std::size_t i = 0; i < mm.source.size(); ++i) {
          pairs.mutable_data()[2 * i] = a.keypoints[mm.source[i]];
          pairs.mutable_data()[2 * i + 1] = b.keypoints[mm.target[i]];
        }
        return py::make_tuple(pairs, vec<double>(mm.error));
      },
      py::arg("source"), py::arg("target"), py::arg("variant"), py::arg("k"), py::arg("num_threads"),
      "(pairs (M, 2) point indices source/target, errors (M,)): each source keypoint with its k nearest target "
      "keypoints in descriptor space");
}

void bindMotors(py::module_& m) {
  py::class_<MotorEstimationResult>(m, "MotorEstimationResult", "A rigid motion estimated from point pairs")
      .def_readonly("T_target_source", &MotorEstimationResult::T_target_source, "(4, 4) y = R x + t")
      .def_property_readonly(
          "motor", [](const MotorEstimationResult& e) { return Eigen::VectorXd(e.motor); },
          "(8,) coefficients on (1, e23, e31, e12, e1inf, e2inf, e3inf, e123inf), M ~M = 1")
      .def_readonly("rmse", &MotorEstimationResult::rmse, "weighted RMS pair residual, m")
      .def_readonly("count", &MotorEstimationResult::count, "pairs used")
      .def_readonly("valid", &MotorEstimationResult::valid, "False for fewer than 3 pairs or collinear data")
      .def_readonly("message", &MotorEstimationResult::message, "why not valid");
  m.def(
      "estimate_motor",
      [](const py::array& s, const py::array& t, const py::object& w, bool normalize) {
        const auto a = cloudView<double>(s, "source"), b = cloudView<double>(t, "target");
        const F64 held = w.is_none() ? F64() : py::cast<F64>(w);
        return estimateMotor(a, b, optionalWeights(w, held, a.size), normalize);
      },
      py::arg("source"), py::arg("target"), py::arg("weights") = py::none(), py::arg("normalize") = true,
      "Valkenburg-Dorst motor from paired (N, 3) float64 points (thesis (36)-(44) of paper 5)");
  m.def(
      "estimate_rigid_svd",
      [](const py::array& s, const py::array& t, const py::object& w) {
        const auto a = cloudView<double>(s, "source"), b = cloudView<double>(t, "target");
        const F64 held = w.is_none() ? F64() : py::cast<F64>(w);
        return estimateRigidSvd(a, b, optionalWeights(w, held, a.size));
      },
      py::arg("source"), py::arg("target"), py::arg("weights") = py::none(), "Kabsch/Umeyama (SVD) from the same pairs");
  m.def(
      "motor_to_matrix", [](const Eigen::Matrix<double, 8, 1>& mv) { return motorToMatrix(mv); }, py::arg("motor"),
      "(4, 4) transform of an 8-coefficient motor (normalised first)");

  py::class_<CorrespondenceRansacSettings>(m, "CorrespondenceRansacSettings", "RANSAC over putative point pairs")
      .def(py::init<>())
      .def_readwrite("max_iterations", &CorrespondenceRansacSettings::max_iterations, "hypotheses (thesis baselines: 1000)")
      .def_readwrite("inlier_threshold", &CorrespondenceRansacSettings::inlier_threshold, "m (thesis: 0.005)")
      .def_readwrite("edge_similarity", &CorrespondenceRansacSettings::edge_similarity,
                     "prerejection: sample triangles' edge-length ratios must exceed this, in [0, 1)")
      .def_readwrite("min_edge", &CorrespondenceRansacSettings::min_edge, "m; shortest sample edge")
      .def_readwrite("confidence", &CorrespondenceRansacSettings::confidence, "early stop, in (0, 1)")
      .def_readwrite("refine_iterations", &CorrespondenceRansacSettings::refine_iterations, "motor refits on the inliers")
      .def_readwrite("seed", &CorrespondenceRansacSettings::seed, "random seed (results do not depend on threads)")
      .def_readwrite("num_threads", &CorrespondenceRansacSettings::num_threads, "0 = all cores");
  py::class_<CorrespondenceRansacResult>(m, "CorrespondenceRansacResult", "Outcome of ransac_rigid_motion")
      .def_readonly("T_target_source", &CorrespondenceRansacResult::T_target_source, "(4, 4), identity when not found")
      .def_readonly("found", &CorrespondenceRansacResult::found, "a hypothesis with at least 3 inlier pairs")
      .def_property_readonly(
          "inliers", [](const CorrespondenceRansacResult& r) { return vec<std::int64_t>(r.inliers); },
          "(K,) indices into the pair list")
      .def_readonly("inlier_rmse", &CorrespondenceRansacResult::inlier_rmse, "m, over the inlier pairs")
      .def_readonly("iterations", &CorrespondenceRansacResult::iterations, "hypotheses drawn")
      .def_readonly("message", &CorrespondenceRansacResult::message, "why nothing was found");
  m.def(
      "ransac_rigid_motion",
      [](const py::array& s, const py::array& t, const py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>& pairs,
         const CorrespondenceRansacSettings& settings) {
        const auto a = cloudView<double>(s, "source"), b = cloudView<double>(t, "target");
        if (pairs.ndim() != 2 || pairs.shape(1) != 2) throw py::value_error("pairs: expected an integer (K, 2) array");
        std::vector<std::uint32_t> p(static_cast<std::size_t>(pairs.size()));
        for (std::size_t i = 0; i < p.size(); ++i) {
          const std::int64_t v = pairs.data()[i];
          if (v < 0 || static_cast<std::size_t>(v) >= (i % 2 ? b.size : a.size))
            throw py::value_error("pairs: index out of range");
          p[i] = static_cast<std::uint32_t>(v);
        }
        py::gil_scoped_release release;
        return ransacRigidMotion(a, b, p.data(), p.size() / 2, settings);
      },
      py::arg("source"), py::arg("target"), py::arg("pairs"), py::arg("settings"));
}

void bindAlignment(py::module_& m) {
  py::class_<CbdAlignmentSettings>(m, "CbdAlignmentSettings", "CBD coarse alignment")
      .def(py::init<>())
      .def_readwrite("cbd", &CbdAlignmentSettings::cbd, "CbdSettings for both clouds")
      .def_readwrite("ransac", &CbdAlignmentSettings::ransac, "CorrespondenceRansacSettings (10000 hypotheses)")
      .def_readwrite("matches_per_keypoint", &CbdAlignmentSettings::matches_per_keypoint,
                     "k nearest target descriptors per source keypoint")
      .def_readwrite("hypotheses", &CbdAlignmentSettings::hypotheses,
                     "sequential RANSAC: up to this many hypotheses (each on the pairs the earlier ones left), the "
                     "one whose whole source cloud fits the target best wins (a half-turn look-alike's flipped pose "
                     "can have the largest consensus); 1: classic RANSAC")
      .def_readwrite("target_thresholds_from_source", &CbdAlignmentSettings::target_thresholds_from_source,
                     "derive the deltas from the source's automatic keypoints and apply them to the target");
  py::class_<CbdAlignmentResult>(m, "CbdAlignmentResult", "Outcome of align_cbd")
      .def_readonly("T_target_source", &CbdAlignmentResult::T_target_source, "(4, 4) maps source into target")
      .def_property_readonly(
          "transformation", [](const CbdAlignmentResult& r) { return r.T_target_source; },
          "T_target_source under Open3D's name (RegistrationResult.transformation)")
      .def_readonly("found", &CbdAlignmentResult::found, "RANSAC found a consistent set of matches")
      .def_readonly("fitness", &CbdAlignmentResult::fitness, "source points within the inlier threshold of the target")
      .def_readonly("inlier_rmse", &CbdAlignmentResult::inlier_rmse, "m, over those points")
      .def_readonly("source_keypoints", &CbdAlignmentResult::source_keypoints)
      .def_readonly("target_keypoints", &CbdAlignmentResult::target_keypoints)
      .def_readonly("matches", &CbdAlignmentResult::matches, "descriptor matches fed to RANSAC")
      .def_readonly("match_inliers", &CbdAlignmentResult::match_inliers, "matches consistent with the pose")
      .def_readonly("feature_seconds", &CbdAlignmentResult::feature_seconds)
      .def_readonly("match_seconds", &CbdAlignmentResult::match_seconds)
      .def_readonly("ransac_seconds", &CbdAlignmentResult::ransac_seconds)
      .def_readonly("seconds", &CbdAlignmentResult::seconds)
      .def_readonly("message", &CbdAlignmentResult::message, "why nothing was found");
  m.def(
      "align_cbd",
      [](const py::array& source, const py::array& target, const CbdAlignmentSettings& s) {
        if (holds<float>(source) != holds<float>(target)) throw py::type_error("source and target must have the same dtype");
        if (holds<float>(source)) {
          const auto a = cloudView<float>(source, "source"), b = cloudView<float>(target, "target");
          py::gil_scoped_release release;
          return alignCbd(a, b, s);
        }
        const auto a = cloudView<double>(source, "source"), b = cloudView<double>(target, "target");
        py::gil_scoped_release release;
        return alignCbd(a, b, s);
      },
      py::arg("source"), py::arg("target"), py::arg("settings"));

  py::class_<NormalLineFlag>(m, "NormalLineFlag", "A cloud's flag (paper 4): centroid and average normal line")
      .def_readonly("centroid", &NormalLineFlag::centroid, "(3,) m")
      .def_readonly("direction", &NormalLineFlag::direction, "(3,) unit direction of the average normal line")
      .def_readonly("foot", &NormalLineFlag::foot, "(3,) m, the line's point nearest the centroid")
      .def_readonly("mean_normal_length", &NormalLineFlag::mean_normal_length, "|mean unit normal|, ~0 on a closed surface")
      .def_readonly("pitch", &NormalLineFlag::pitch, "m")
      .def_readonly("count", &NormalLineFlag::count, "points used");
  py::class_<FlagAlignmentSettings>(m, "FlagAlignmentSettings", "Paper 4 initial alignment")
      .def(py::init<>())
      .def_readwrite("min_mean_normal_length", &FlagAlignmentSettings::min_mean_normal_length,
                     "refuse when |mean unit normal| of either cloud is below this (closed surfaces)")
      .def_readwrite("min_centroid_offset", &FlagAlignmentSettings::min_centroid_offset,
                     "m; refuse when the centroid lies this close to the average line")
      .def_readwrite("min_points", &FlagAlignmentSettings::min_points,
                     "refuse (valid False) when either cloud has fewer usable points (finite, non-zero normal)")
      .def_readwrite("max_iterations", &FlagAlignmentSettings::max_iterations, "Levenberg-Marquardt iterations")
      .def_readwrite("tolerance", &FlagAlignmentSettings::tolerance, "convergence tolerance");
  py::class_<FlagAlignmentResult>(m, "FlagAlignmentResult", "Outcome of align_flags")
      .def_readonly("T_target_source", &FlagAlignmentResult::T_target_source, "(4, 4) the motor, f_target = M f_source ~M")
      .def_readonly("valid", &FlagAlignmentResult::valid,
                    "False when refused (message says why): fewer than min_points usable points, collinear or "
                    "coincident points, a closed surface, a centroid on the average line, a non-finite result")
      .def_readonly("iterations", &FlagAlignmentResult::iterations)
      .def_readonly("cost", &FlagAlignmentResult::cost, "(delta^2 + sin^2(theta/2) + d^2)/2 at the solution")
      .def_readonly("source_flag", &FlagAlignmentResult::source_flag)
      .def_readonly("target_flag", &FlagAlignmentResult::target_flag)
      .def_readonly("message", &FlagAlignmentResult::message, "why refused");
  m.def(
      "normal_line_flag",
      [](const py::array& p, const py::array& n) {
        return normalLineFlag(cloudView<double>(p, "points"), cloudView<double>(n, "normals"));
      },
      py::arg("points"), py::arg("normals"));
  m.def(
      "align_flags",
      [](const py::array& a, const py::array& an, const py::array& b, const py::array& bn, const FlagAlignmentSettings& s) {
        const auto sa = cloudView<double>(a, "source"), sn = cloudView<double>(an, "source_normals");
        const auto ta = cloudView<double>(b, "target"), tn = cloudView<double>(bn, "target_normals");
        py::gil_scoped_release release;
        return alignFlags(sa, sn, ta, tn, s);
      },
      py::arg("source"), py::arg("source_normals"), py::arg("target"), py::arg("target_normals"), py::arg("settings"),
      "Paper 4 flag alignment of two partial views (m, rad). ValueError for mismatched shapes, no usable point or "
      "coordinates beyond 1e6 m (the cost mixes metres and radians); refusals are valid=False with a message.");
}

void bindViews(py::module_& m) {
  m.def(
      "tessellated_sphere",
      [](int level) {
        const TessellatedSphere s = tessellatedSphere(level);
        py::array_t<std::int64_t> f({static_cast<py::ssize_t>(s.faces.size()), py::ssize_t{3}});
        for (std::size_t i = 0; i < s.faces.size(); ++i)
          for (int k = 0; k < 3; ++k) f.mutable_data()[3 * i + k] = s.faces[i][k];
        return py::make_tuple(stack(s.vertices, {3}), f);
      },
      py::arg("level") = 1,
      "(vertices (V, 3) unit length, faces (F, 3) counter-clockwise) of an icosahedron subdivided `level` times: "
      "10 4^level + 2 vertices, 20 4^level faces");
  m.def("view_intrinsics", &viewIntrinsics, py::arg("resolution"), py::arg("view_angle") = kDefaultViewAngle,
        "square pinhole camera with field of view view_angle (rad) across resolution pixels");
  m.attr("DEFAULT_VIEW_ANGLE") = kDefaultViewAngle;
  py::class_<ModelViewSettings>(m, "ModelViewSettings", "How a CAD model is rendered into partial views")
      .def(py::init<>())
      .def_readwrite("resolution", &ModelViewSettings::resolution, "image width and height, pixels (thesis: 90 to 400)")
      .def_readwrite("view_angle", &ModelViewSettings::view_angle, "field of view, rad (PCL's 57 degrees)")
      .def_readwrite("level", &ModelViewSettings::level, "icosahedron subdivisions; 1 gives the thesis's 42 views")
      .def_readwrite("distance", &ModelViewSettings::distance,
                     "camera distance from center, m; 0 = the bounding sphere fills 90 % of the field of view")
      .def_readwrite("center", &ModelViewSettings::center, "(3,) what the cameras look at, m; None = bounding-box centre")
      .def_readwrite("num_threads", &ModelViewSettings::num_threads, "rasteriser threads, 0 = all cores")
      .def_readwrite("max_memory_bytes", &ModelViewSettings::max_memory_bytes,
                     "refuse (ValueError, before rendering) when views x resolution^2 x 64 bytes exceeds this "
                     "(default 4 GiB)");
  py::class_<ModelView>(m, "ModelView", "One virtual depth camera's view of a model (model frame, m)")
      .def(py::init([](const F64& points, const F64& normals) {
             if (points.ndim() != 2 || points.shape(1) != 3 || normals.ndim() != 2 || normals.shape(1) != 3 ||
                 normals.shape(0) != points.shape(0))
               throw py::value_error("points and normals: expected two (N, 3) arrays of the same length");
             ModelView v;
             v.points.assign(points.data(), points.data() + points.size());
             v.normals.assign(normals.data(), normals.data() + normals.size());
             v.face_id.assign(static_cast<std::size_t>(points.shape(0)), -1);
             v.pixels.assign(2 * static_cast<std::size_t>(points.shape(0)), -1);
             return v;
           }),
           py::arg("points"), py::arg("normals"), "a view made of a model cloud and its normals (no camera)")
      .def_property_readonly(
          "points", [](const ModelView& v) { return rows<double>(v.points, 3); }, "(N, 3) visible surface points, m")
      .def_property_readonly(
          "normals", [](const ModelView& v) { return rows<double>(v.normals, 3); },
          "(N, 3) unit normals of their triangles, oriented towards the camera")
      .def_property_readonly(
          "face_id", [](const ModelView& v) { return vec<std::int64_t>(v.face_id); }, "(N,) triangle index in the mesh")
      .def_property_readonly(
          "pixels", [](const ModelView& v) { return rows<std::int64_t>(v.pixels, 2); }, "(N, 2) (column, row) in the image")
      .def_readonly("T_model_camera", &ModelView::T_model_camera, "(4, 4) camera -> model (OpenCV camera axes)")
      .def_readonly("intrinsics", &ModelView::intrinsics, "the view's pinhole camera")
      .def_readwrite("cbd", &ModelView::cbd,
                     "CbdFeatures computed once for this view (describe_model_views, a part library), or None; "
                     "estimate_pose uses them when its CBD settings equal cbd_settings (threads aside), else "
                     "computes afresh")
      .def_readwrite("cbd_settings", &ModelView::cbd_settings, "the CbdSettings cbd was computed with")
      .def_property_readonly(
          "viewpoint", [](const ModelView& v) { return Eigen::Vector3d(v.T_model_camera.topRightCorner<3, 1>()); },
          "(3,) camera centre, model frame, m")
      .def(
          "points_in_camera",
          [](const ModelView& v) {
            const Eigen::Matrix3d Rt = v.T_model_camera.topLeftCorner<3, 3>().transpose();
            const Eigen::Vector3d t = v.T_model_camera.topRightCorner<3, 1>();
            std::vector<double> out(v.points.size());
            for (std::size_t i = 0; i < v.size(); ++i) {
              const Eigen::Vector3d p = Rt * (Eigen::Vector3d(&v.points[3 * i]) - t);
              std::copy(p.data(), p.data() + 3, &out[3 * i]);
            }
            return rows<double>(out, 3);
          },
          "(N, 3) the points in the camera frame (z = depth), m")
      .def("__len__", &ModelView::size);
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
}

PoseProgress progressOf(const py::object& callback) {
  if (callback.is_none()) return {};
  return [callback](std::size_t done, std::size_t total) {
    py::gil_scoped_acquire acquire;
    callback(done, total);
  };
}

CoarseAligner alignerOf(const py::object& pcl) {
  if (pcl.is_none()) return {};
  return pclCoarseAligner(py::cast<PclFeatureAlignmentSettings>(pcl));
}

/// Part symmetries from Python: None (no part symmetric), or one object per part with the
/// fields of PartSymmetry (axis, point, order) -- the class bound in scanalign._core.grasp or
/// any object with those attributes -- or None for a part without symmetry.
std::vector<PartSymmetry> symmetriesOf(const py::object& o) {
  std::vector<PartSymmetry> out;
  if (o.is_none()) return out;
  if (!py::isinstance<py::sequence>(o) || py::isinstance<py::str>(o))
    throw py::type_error("symmetries: expected a list with one PartSymmetry (or None) per part");
  for (const py::handle h : o) {
    PartSymmetry s;
    if (!h.is_none()) {
      const std::string at = "symmetries[" + std::to_string(out.size()) + "]";
      if (!py::hasattr(h, "axis") || !py::hasattr(h, "point") || !py::hasattr(h, "order"))
        throw py::type_error(at + ": expected a PartSymmetry (axis, point, order) or None");
      try {
        s.axis = py::cast<Eigen::Vector3d>(h.attr("axis"));
        s.point = py::cast<Eigen::Vector3d>(h.attr("point"));
        s.order = py::cast<int>(h.attr("order"));
      } catch (const py::cast_error&) {
        throw py::type_error(at + ": axis and point must be 3-vectors (m) and order an integer");
      }
      try {
        s.validate();
      } catch (const std::invalid_argument& e) {
        throw py::value_error(at + ": " + e.what());
      }
    }
    out.push_back(s);
  }
  return out;
}

void bindFindParts(py::module_& m) {
  py::enum_<DetectionStatus>(m, "DetectionStatus", "How find_parts judged an object cluster")
      .value("found", DetectionStatus::Found, "the best part's pose passes min_fitness/min_coverage, nothing else scores alike")
      .value("not_found", DetectionStatus::NotFound, "no part's pose passes min_fitness/min_coverage (or all were skipped by size)")
      .value("ambiguous", DetectionStatus::Ambiguous,
             "found, but another part or a non-equivalent pose of the same part scores within ambiguity_margin");
  py::class_<FindPartsSettings>(m, "FindPartsSettings", "Settings of find_parts (metres, radians)")
      .def(py::init<>())
      .def_readwrite("table", &FindPartsSettings::table, "TableSegmentationSettings (m)")
      .def_readwrite("max_objects", &FindPartsSettings::max_objects, "clusters tried, largest first")
      .def_readwrite("pose", &FindPartsSettings::pose, "PoseSettings per cluster and part")
      .def_readwrite("ambiguity_margin", &FindPartsSettings::ambiguity_margin,
                     "a runner-up scoring at least (1 - margin) x the best score makes the detection ambiguous (0.02)")
      .def_readwrite("ambiguity_rmse_ratio", &FindPartsSettings::ambiguity_rmse_ratio,
                     "a runner-up fits alike only if its inlier RMSE is at most this times the best's (1.5; 0: no "
                     "RMSE test): the score saturates at the inlier threshold, the RMSE does not")
      .def_readwrite("score_tie", &FindPartsSettings::score_tie,
                     "candidates of the best part within this of its best score are ties: the smallest inlier RMSE "
                     "wins (0.01)")
      .def_readwrite("polish_distance", &FindPartsSettings::polish_distance,
                     "m; the reported candidate is refined again by ICP with this correspondence distance and a tight "
                     "stop (0.003; 0 = none)")
      .def_readwrite("same_pose_angle", &FindPartsSettings::same_pose_angle,
                     "rad; poses of one part this close (over its symmetry) are the same pose (5 degrees)")
      .def_readwrite("same_pose_distance", &FindPartsSettings::same_pose_distance,
                     "m; with same_pose_angle (0.005)")
      .def_readwrite("max_size_ratio", &FindPartsSettings::max_size_ratio,
                     "skip a part for a cluster larger than this x the part's size (largest principal extent); 0 = no "
                     "bound (1.5)")
      .def_readwrite("min_size_ratio", &FindPartsSettings::min_size_ratio,
                     "skip a part for a cluster smaller than this x its smallest view; 0 = no bound (0.5)")
      .def_readwrite("max_table_penetration", &FindPartsSettings::max_table_penetration,
                     "m; poses that put the part's surface (its views merged) further below the table plane are "
                     "dropped (0.005; infinity: no check)")
      .def_readwrite("surface_polish", &FindPartsSettings::surface_polish,
                     "refine the reported pose against the part's whole surface, cluster points onto the model within "
                     "polish_distance (True)")
      .def_readwrite("cbd_radius_fraction", &FindPartsSettings::cbd_radius_fraction,
                     "CBD radius per part: max(the CBD radius, this x the part's size); 0 = fixed (0)")
      .def_readwrite("min_surface_coverage", &FindPartsSettings::min_surface_coverage,
                     "fraction of the cluster's points within polish_distance of the part's whole surface a "
                     "detection needs, else not_found (0.97; 0 = no check)")
      .def_readwrite("voxel_size", &FindPartsSettings::voxel_size,
                     "m; each cluster reduced to one point (the centroid) per voxel before its pose; 0 = every point "
                     "(0: default; 1 to 1.5 mm for a merged multi-view scan)");
  py::class_<PartDetection>(m, "PartDetection", "One object cluster and the part found in it")
      .def_readonly("status", &PartDetection::status, "DetectionStatus")
      .def_property_readonly(
          "part", [](const PartDetection& d) -> py::object { return d.part < 0 ? py::object(py::none()) : py::int_(d.part); },
          "index of the best-scoring part in the models (None when every part was skipped)")
      .def_readonly("pose", &PartDetection::pose, "PoseResult of that part (found False unless found/ambiguous)")
      .def_readonly("score", &PartDetection::score, "its best candidate's score")
      .def_readonly("surface_coverage", &PartDetection::surface_coverage,
                    "fraction of the cluster's points within polish_distance of the part's whole surface at the "
                    "reported pose")
      .def_property_readonly(
          "runner_up_part",
          [](const PartDetection& d) -> py::object {
            return d.runner_up_part < 0 ? py::object(py::none()) : py::int_(d.runner_up_part);
          },
          "part of the best competing pose (None when there is none)")
      .def_readonly("runner_up_score", &PartDetection::runner_up_score, "its score")
      .def_readonly("runner_up_angle", &PartDetection::runner_up_angle,
                    "rad; symmetric pose difference to the best pose (over the best part's symmetry)")
      .def_readonly("runner_up_distance", &PartDetection::runner_up_distance, "m; the same, translation")
      .def_property_readonly(
          "indices", [](const PartDetection& d) { return vec<std::int64_t>(d.indices); },
          "(N,) int64 the cluster's points, indices into the scene")
      .def_readonly("parts", &PartDetection::parts, "PoseResult per part (a skipped part says why in its message)")
      .def_readonly("size", &PartDetection::size, "m; the cluster's largest extent along its principal axes")
      .def_readonly("message", &PartDetection::message, "why not found, or what made it ambiguous")
      .def_readonly("seconds", &PartDetection::seconds, "wall time of this cluster, all parts");
  py::class_<PartDetections>(m, "PartDetections", "Result of find_parts")
      .def_readonly("detections", &PartDetections::detections, "PartDetection per object cluster, largest first")
      .def_property_readonly(
          "plane", [](const PartDetections& o) { return o.table.plane; }, "the table plane (PlaneResult)")
      .def_readonly("table", &PartDetections::table, "the whole TableSegmentationResult")
      .def_readonly("seconds", &PartDetections::seconds, "wall time");
  m.def(
      "find_parts",
      [](const std::vector<std::vector<ModelView>>& models, const py::array& scene, const FindPartsSettings& s,
         const py::object& symmetries, const std::vector<int>& ids, const py::object& pcl, const py::object& progress) {
        const auto view = cloudView<double>(scene, "scene");
        const std::vector<PartSymmetry> sym = symmetriesOf(symmetries);
        const CoarseAligner aligner = alignerOf(pcl);
        const PoseProgress cb = progressOf(progress);
        py::gil_scoped_release release;
        return findParts(models, sym, view, s, ids, aligner, cb);
      },
      py::arg("models"), py::arg("scene"), py::arg("settings"), py::arg("symmetries") = py::none(),
      py::arg("view_ids") = std::vector<int>{}, py::arg("pcl_settings") = py::none(), py::arg("progress") = py::none(),
      "Which of several parts (models: one list of ModelView per part) lies in each object cluster of a table scene "
      "(N, 3) float64, m, and its pose; symmetries: one PartSymmetry (axis, point, order) or None per part, or None");
}

void bindDescribe(py::module_& m) {
  m.def(
      "describe_model_views",
      [](std::vector<ModelView> views, const PoseSettings& s) {
        {
          py::gil_scoped_release release;
          describeModelViews(views, s);
        }
        return views;
      },
      py::arg("views"), py::arg("settings"),
      "Copies of the views with their CBD features computed (ModelView.cbd) with the settings estimate_pose, "
      "find_objects and find_parts use for these PoseSettings, so those calls skip that work (most of a pose's "
      "time). For find_parts pass part_pose_settings(views, find_parts_settings): with cbd_radius_fraction the "
      "radius follows each part's size.");
  m.def(
      "part_pose_settings",
      [](const std::vector<ModelView>& views, const FindPartsSettings& s) { return partPoseSettings(views, s); },
      py::arg("views"), py::arg("settings"),
      "The PoseSettings find_parts matches this part (its views) with: settings.pose with the part's CBD radius, "
      "max(radius, cbd_radius_fraction x the part's size, m)");
}

void bindPipeline(py::module_& m) {
  py::enum_<CoarseMethod>(m, "CoarseMethod", "How each model view is brought near the object before ICP")
      .value("cbd", CoarseMethod::Cbd, "curvature-based descriptor + RANSAC + motor refit (paper 5)")
      .value("flags", CoarseMethod::Flags, "centroid + average normal line (paper 4)")
      .value("external", CoarseMethod::External, "a PCL baseline (pcl_settings)");
  py::class_<PoseSettings>(m, "PoseSettings", "Settings of estimate_pose / find_objects (metres)")
      .def(py::init<>())
      .def_readwrite("method", &PoseSettings::method, "CoarseMethod")
      .def_readwrite("inlier_threshold", &PoseSettings::inlier_threshold,
                     "m; fitness/coverage distance and the CBD RANSAC inlier threshold (thesis: 0.005)")
      .def_readwrite("icp_distance", &PoseSettings::icp_distance, "m; ICP maximum correspondence distance")
      .def_readwrite("normal_radius", &PoseSettings::normal_radius, "m; scene normals for point-to-plane ICP and flags")
      .def_readwrite("min_fitness", &PoseSettings::min_fitness, "found only if the best view's fitness reaches this")
      .def_readwrite("min_coverage", &PoseSettings::min_coverage, "found only if the best view's coverage reaches this")
      .def_readwrite("cbd", &PoseSettings::cbd, "CbdAlignmentSettings (min_neighbors 0: automatic)")
      .def_readwrite("flags", &PoseSettings::flags, "FlagAlignmentSettings")
      .def_readwrite("num_threads", &PoseSettings::num_threads, "0 = all cores");
  py::class_<PoseCandidate>(m, "PoseCandidate", "Per-view summary of estimate_pose")
      .def_readonly("view", &PoseCandidate::view, "index into the model views")
      .def_readonly("found", &PoseCandidate::found, "the coarse alignment produced a pose")
      .def_readonly("coarse_fitness", &PoseCandidate::coarse_fitness, "fitness after the coarse alignment alone")
      .def_readonly("fitness", &PoseCandidate::fitness, "after ICP")
      .def_readonly("coverage", &PoseCandidate::coverage, "after ICP")
      .def_readonly("inlier_rmse", &PoseCandidate::inlier_rmse, "m, after ICP")
      .def_readonly("score", &PoseCandidate::score, "2 fitness coverage / (fitness + coverage)")
      .def_readonly("T_scene_model", &PoseCandidate::T_scene_model,
                    "(4, 4) the view's pose after ICP, model -> scene, m (identity when the coarse alignment failed)");
  py::class_<PoseResult>(m, "PoseResult", "Pose of a model in an object cloud")
      .def(py::init<>())
      .def_readwrite("T_scene_model", &PoseResult::T_scene_model, "(4, 4) maps model (CAD) coordinates into the scene")
      .def_property_readonly(
          "transformation", [](const PoseResult& r) { return r.T_scene_model; },
          "T_scene_model under Open3D's name: the model (source) registered onto the scene (target)")
      .def_readwrite("found", &PoseResult::found, "a coarse alignment succeeded and ICP refined it")
      .def_readwrite("fitness", &PoseResult::fitness, "fraction of the view's points within inlier_threshold of the object")
      .def_readwrite("coverage", &PoseResult::coverage, "fraction of the object's points within inlier_threshold of the model")
      .def_readwrite("inlier_rmse", &PoseResult::inlier_rmse, "m, fitness inliers")
      .def_readwrite("method", &PoseResult::method, "coarse method used")
      .def_property(
          "view", [](const PoseResult& r) -> py::object { return r.view < 0 ? py::object(py::none()) : py::object(py::int_(r.view)); },
          [](PoseResult& r, const py::object& v) { r.view = v.is_none() ? -1 : v.cast<int>(); },
          "index of the best model view (None when nothing was found or the model was a cloud)")
      .def_readwrite("seconds", &PoseResult::seconds, "wall time, all views")
      .def_readwrite("coarse_seconds", &PoseResult::coarse_seconds, "the part in coarse alignment")
      .def_readonly("candidates", &PoseResult::candidates, "PoseCandidate per view tried")
      .def_readwrite("message", &PoseResult::message, "why nothing was found")
      .def(
          "as_dict",
          [](const PoseResult& r) {
            py::dict d;
            d["found"] = r.found;
            d["fitness"] = r.fitness;
            d["coverage"] = r.coverage;
            d["inlier_rmse"] = r.inlier_rmse;
            d["method"] = r.method;
            d["view"] = r.view < 0 ? py::object(py::none()) : py::object(py::int_(r.view));
            d["seconds"] = r.seconds;
            d["coarse_seconds"] = r.coarse_seconds;
            d["message"] = r.message;
            py::list T;
            for (int i = 0; i < 4; ++i) {
              py::list row;
              for (int j = 0; j < 4; ++j) row.append(r.T_scene_model(i, j));
              T.append(row);
            }
            d["T_scene_model"] = T;
            return d;
          },
          "a JSON-ready summary (candidates left out)");
  py::class_<FindObjectsSettings>(m, "FindObjectsSettings", "Settings of find_objects")
      .def(py::init<>())
      .def_readwrite("table", &FindObjectsSettings::table, "TableSegmentationSettings (m)")
      .def_readwrite("max_objects", &FindObjectsSettings::max_objects, "clusters tried, largest first")
      .def_readwrite("pose", &FindObjectsSettings::pose, "PoseSettings per cluster");
  py::class_<ObjectPoses>(m, "ObjectPoses", "Result of find_objects")
      .def_readonly("poses", &ObjectPoses::poses, "PoseResult per object cluster, largest first")
      .def_property_readonly(
          "objects",
          [](const ObjectPoses& o) {
            py::list l;
            for (const auto& idx : o.table.objects) l.append(vec<std::int64_t>(idx));
            return l;
          },
          "the clusters as int64 index arrays into the scene")
      .def_property_readonly(
          "plane", [](const ObjectPoses& o) { return o.table.plane; }, "the table plane (PlaneResult)")
      .def_readonly("table", &ObjectPoses::table, "the whole TableSegmentationResult")
      .def_readonly("seconds", &ObjectPoses::seconds, "wall time");
  m.def(
      "estimate_pose",
      [](const std::vector<ModelView>& views, const py::array& scene, const PoseSettings& s, const std::vector<int>& ids,
         const py::object& pcl, const py::object& progress) {
        const auto view = cloudView<double>(scene, "scene");
        const CoarseAligner aligner = alignerOf(pcl);
        const PoseProgress cb = progressOf(progress);
        py::gil_scoped_release release;
        return estimatePose(views, view, s, ids, aligner, cb);
      },
      py::arg("views"), py::arg("scene"), py::arg("settings"), py::arg("view_ids") = std::vector<int>{},
      py::arg("pcl_settings") = py::none(), py::arg("progress") = py::none(),
      "Pose of the model (its views) in one object cloud (N, 3) float64, m; pcl_settings (a "
      "PclFeatureAlignmentSettings) with method external; progress(done, total) after each view");
  m.def(
      "find_objects",
      [](const std::vector<ModelView>& views, const py::array& scene, const FindObjectsSettings& s,
         const std::vector<int>& ids, const py::object& pcl, const py::object& progress) {
        const auto view = cloudView<double>(scene, "scene");
        const CoarseAligner aligner = alignerOf(pcl);
        const PoseProgress cb = progressOf(progress);
        py::gil_scoped_release release;
        return findObjects(views, view, s, ids, aligner, cb);
      },
      py::arg("views"), py::arg("scene"), py::arg("settings"), py::arg("view_ids") = std::vector<int>{},
      py::arg("pcl_settings") = py::none(),
      py::arg("progress") = py::none(), "Poses of the model in a table scene: table plane, clusters, estimate_pose each");
}

/// An enum index read from a pickled state, in [0, n).
template <typename E>
E enumIndex(int v, int n, const char* what) {
  if (v < 0 || v >= n) throw py::value_error(std::string(what) + ": pickled value out of range");
  return static_cast<E>(v);
}

Eigen::Vector3d thresholdArray(const ShapeThresholds& t) { return {t.linear, t.planar, t.spherical}; }
ShapeThresholds thresholdsFrom(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

/// CbdSettings as flat fields (enums as ints, thresholds as a (3,) array): the part library
/// stores a ModelView's cached descriptors with np.savez(allow_pickle=False), which takes
/// only arrays and scalars.
std::vector<PickleField<CbdSettings>> cbdSettingsFields() {
  using S = CbdSettings;
  return {field("radius", &S::radius), field("gamma", &S::gamma), field("min_neighbors", &S::min_neighbors),
          field<S>(
              "keypoint_mode", [](const S& s) { return static_cast<int>(s.keypoint_mode); },
              [](S& s, int v) { s.keypoint_mode = enumIndex<CbdKeypointMode>(v, 2, "CbdSettings.keypoint_mode"); }),
          field("num_keypoints", &S::num_keypoints),
          field<S>(
              "thresholds", [](const S& s) { return thresholdArray(s.thresholds); },
              [](S& s, const Eigen::Vector3d& v) { s.thresholds = thresholdsFrom(v); }),
          field("max_keypoints", &S::max_keypoints), field("max_sphere_radius", &S::max_sphere_radius),
          field<S>(
              "variant", [](const S& s) { return static_cast<int>(s.variant); },
              [](S& s, int v) { s.variant = enumIndex<CbdDescriptorVariant>(v, 2, "CbdSettings.variant"); }),
          field("num_threads", &S::num_threads)};
}

/// One column of a per-keypoint sphere list.
template <typename V, typename Get, typename Set>
PickleField<CbdFeatures> sphereColumn(const std::string& name, std::vector<CbdSphere> CbdFeatures::*spheres, Get get,
                                      Set set) {
  return field<CbdFeatures>(
      name.c_str(),
      [spheres, get](const CbdFeatures& f) {
        std::vector<V> v;
        for (const CbdSphere& s : f.*spheres) v.push_back(get(s));
        return v;
      },
      [spheres, set](CbdFeatures& f, const std::vector<V>& v) {
        (f.*spheres).resize(v.size());
        for (std::size_t i = 0; i < v.size(); ++i) set((f.*spheres)[i], v[i]);
      });
}

/// CbdFeatures as flat arrays (K keypoints): keypoints (K,) uint32, descriptors (K, 4),
/// scalar (K,), sphere{1,2}_{dual (K, 5), radius, distance, flat}, axes (K, 3, 3),
/// thresholds (3,), and three scalars.
std::vector<PickleField<CbdFeatures>> cbdFeatureFields() {
  using F = CbdFeatures;
  using Dual = Eigen::Matrix<double, 5, 1>;
  std::vector<PickleField<F>> fields{field("keypoints", &F::keypoints), field("descriptors", &F::descriptors),
                                     field("scalar", &F::scalar)};
  for (const auto& [prefix, member] : {std::pair{std::string("sphere1"), &F::sphere1}, std::pair{std::string("sphere2"), &F::sphere2}}) {
    fields.push_back(sphereColumn<Dual>(prefix + "_dual", member, [](const CbdSphere& s) { return s.dual; },
                                        [](CbdSphere& s, const Dual& v) { s.dual = v; }));
    fields.push_back(sphereColumn<double>(prefix + "_radius", member, [](const CbdSphere& s) { return s.radius; },
                                          [](CbdSphere& s, double v) { s.radius = v; }));
    fields.push_back(sphereColumn<double>(prefix + "_distance", member, [](const CbdSphere& s) { return s.distance; },
                                          [](CbdSphere& s, double v) { s.distance = v; }));
    fields.push_back(sphereColumn<bool>(prefix + "_flat", member, [](const CbdSphere& s) { return s.flat; },
                                        [](CbdSphere& s, bool v) { s.flat = v; }));
  }
  fields.push_back(field("axes", &F::axes));
  fields.push_back(field<F>(
      "thresholds", [](const F& f) { return thresholdArray(f.thresholds); },
      [](F& f, const Eigen::Vector3d& v) { f.thresholds = thresholdsFrom(v); }));
  fields.push_back(field("points_with_min_neighbors", &F::points_with_min_neighbors));
  fields.push_back(field("min_neighbors", &F::min_neighbors));
  fields.push_back(field("seconds", &F::seconds));
  return fields;
}

/// The matcher indexes every per-keypoint array by keypoint: a state whose arrays disagree
/// in length is refused instead of read out of bounds.
void checkCbdFeatures(const CbdFeatures& f, const std::string& cls) {
  const std::size_t k = f.keypoints.size();
  if (f.descriptors.size() != k || f.scalar.size() != k || f.sphere1.size() != k || f.sphere2.size() != k ||
      f.axes.size() != k)
    throw py::value_error(cls + ": pickled per-keypoint arrays differ in length");
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

/// ModelView's own fields (N points): points, normals (N, 3) float64, face_id (N,) int32,
/// pixels (N, 2) int32, T_model_camera (4, 4), intrinsics (6,) [width, height, fx, fy, cx, cy].
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

void pickleCbdAndViews(py::module_& m) {
  pickleFields(m, "ShapeThresholds", field("linear", &ShapeThresholds::linear),
               field("planar", &ShapeThresholds::planar), field("spherical", &ShapeThresholds::spherical));
  auto settings = py::reinterpret_borrow<py::class_<CbdSettings>>(m.attr("CbdSettings"));
  pickleFields(settings, cbdSettingsFields());
  auto features = py::reinterpret_borrow<py::class_<CbdFeatures>>(m.attr("CbdFeatures"));
  features.def(py::pickle([](const CbdFeatures& f) { return stateOf(f, cbdFeatureFields()); },
                          [](const py::dict& state) {
                            CbdFeatures f;
                            assignState(f, state, cbdFeatureFields(), "CbdFeatures");
                            checkCbdFeatures(f, "CbdFeatures");
                            return f;
                          }));
  auto views = py::reinterpret_borrow<py::class_<ModelView>>(m.attr("ModelView"));
  views.def(py::pickle(&modelViewState, &modelViewFromState));
}

void picklePoseResults(py::module_& m) {
  using ME = MotorEstimationResult;
  pickleFields(m, "MotorEstimationResult", field("T_target_source", &ME::T_target_source), field("motor", &ME::motor),
               field("rmse", &ME::rmse), field("count", &ME::count), field("valid", &ME::valid),
               field("message", &ME::message));
  using CS = CorrespondenceRansacSettings;
  pickleFields(m, "CorrespondenceRansacSettings", field("max_iterations", &CS::max_iterations),
               field("inlier_threshold", &CS::inlier_threshold), field("edge_similarity", &CS::edge_similarity),
               field("min_edge", &CS::min_edge), field("confidence", &CS::confidence),
               field("refine_iterations", &CS::refine_iterations), field("seed", &CS::seed),
               field("num_threads", &CS::num_threads));
  using CR = CorrespondenceRansacResult;
  pickleFields(m, "CorrespondenceRansacResult", field("T_target_source", &CR::T_target_source),
               field("found", &CR::found), field("inliers", &CR::inliers), field("inlier_rmse", &CR::inlier_rmse),
               field("iterations", &CR::iterations), field("message", &CR::message));
  using AS = CbdAlignmentSettings;
  pickleFields(m, "CbdAlignmentSettings", field("cbd", &AS::cbd), field("ransac", &AS::ransac),
               field("matches_per_keypoint", &AS::matches_per_keypoint), field("hypotheses", &AS::hypotheses),
               field("target_thresholds_from_source", &AS::target_thresholds_from_source));
  using AR = CbdAlignmentResult;
  pickleFields(m, "CbdAlignmentResult", field("T_target_source", &AR::T_target_source), field("found", &AR::found),
               field("fitness", &AR::fitness), field("inlier_rmse", &AR::inlier_rmse),
               field("source_keypoints", &AR::source_keypoints), field("target_keypoints", &AR::target_keypoints),
               field("matches", &AR::matches), field("match_inliers", &AR::match_inliers),
               field("feature_seconds", &AR::feature_seconds), field("match_seconds", &AR::match_seconds),
               field("ransac_seconds", &AR::ransac_seconds), field("seconds", &AR::seconds),
               field("message", &AR::message));
  using NF = NormalLineFlag;
  pickleFields(m, "NormalLineFlag", field("centroid", &NF::centroid), field("direction", &NF::direction),
               field("foot", &NF::foot), field("mean_normal_length", &NF::mean_normal_length),
               field("pitch", &NF::pitch), field("count", &NF::count));
  using FS = FlagAlignmentSettings;
  pickleFields(m, "FlagAlignmentSettings", field("min_mean_normal_length", &FS::min_mean_normal_length),
               field("min_centroid_offset", &FS::min_centroid_offset), field("min_points", &FS::min_points),
               field("max_iterations", &FS::max_iterations), field("tolerance", &FS::tolerance));
  using FR = FlagAlignmentResult;
  pickleFields(m, "FlagAlignmentResult", field("T_target_source", &FR::T_target_source), field("valid", &FR::valid),
               field("iterations", &FR::iterations), field("cost", &FR::cost),
               field("source_flag", &FR::source_flag), field("target_flag", &FR::target_flag),
               field("message", &FR::message));
  using VS = ModelViewSettings;
  pickleFields(m, "ModelViewSettings", field("resolution", &VS::resolution), field("view_angle", &VS::view_angle),
               field("level", &VS::level), field("distance", &VS::distance), field("center", &VS::center),
               field("num_threads", &VS::num_threads), field("max_memory_bytes", &VS::max_memory_bytes));
  using PS = PoseSettings;
  pickleFields(m, "PoseSettings", field("method", &PS::method), field("inlier_threshold", &PS::inlier_threshold),
               field("icp_distance", &PS::icp_distance), field("normal_radius", &PS::normal_radius),
               field("min_fitness", &PS::min_fitness), field("min_coverage", &PS::min_coverage),
               field("cbd", &PS::cbd), field("flags", &PS::flags), field("num_threads", &PS::num_threads));
  using PC = PoseCandidate;
  pickleFields(m, "PoseCandidate", field("view", &PC::view), field("found", &PC::found),
               field("coarse_fitness", &PC::coarse_fitness), field("fitness", &PC::fitness),
               field("coverage", &PC::coverage), field("inlier_rmse", &PC::inlier_rmse), field("score", &PC::score),
               field("T_scene_model", &PC::T_scene_model));
  // view: the raw index (-1: none), which the property shows as None.
  using PR = PoseResult;
  pickleFields(m, "PoseResult", field("T_scene_model", &PR::T_scene_model), field("found", &PR::found),
               field("fitness", &PR::fitness), field("coverage", &PR::coverage),
               field("inlier_rmse", &PR::inlier_rmse), field("method", &PR::method), field("view", &PR::view),
               field("seconds", &PR::seconds), field("coarse_seconds", &PR::coarse_seconds),
               field("candidates", &PR::candidates), field("message", &PR::message));
  using OS = FindObjectsSettings;
  pickleFields(m, "FindObjectsSettings", field("table", &OS::table), field("max_objects", &OS::max_objects),
               field("pose", &OS::pose));
  using OP = ObjectPoses;
  pickleFields(m, "ObjectPoses", field("poses", &OP::poses), field("table", &OP::table),
               field("seconds", &OP::seconds));
  using FP = FindPartsSettings;
  pickleFields(m, "FindPartsSettings", field("table", &FP::table), field("max_objects", &FP::max_objects),
               field("pose", &FP::pose), field("ambiguity_margin", &FP::ambiguity_margin),
               field("ambiguity_rmse_ratio", &FP::ambiguity_rmse_ratio),
               field("score_tie", &FP::score_tie), field("polish_distance", &FP::polish_distance),
               field("same_pose_angle", &FP::same_pose_angle), field("same_pose_distance", &FP::same_pose_distance),
               field("max_size_ratio", &FP::max_size_ratio), field("min_size_ratio", &FP::min_size_ratio),
               field("max_table_penetration", &FP::max_table_penetration),
               field("surface_polish", &FP::surface_polish), field("cbd_radius_fraction", &FP::cbd_radius_fraction),
               field("min_surface_coverage", &FP::min_surface_coverage), field("voxel_size", &FP::voxel_size));
  // part and runner_up_part: raw indices (-1: none), shown as None by their properties.
  using PD = PartDetection;
  pickleFields(m, "PartDetection", field("status", &PD::status), field("part", &PD::part), field("pose", &PD::pose),
               field("score", &PD::score), field("runner_up_part", &PD::runner_up_part),
               field("runner_up_score", &PD::runner_up_score), field("runner_up_angle", &PD::runner_up_angle),
               field("runner_up_distance", &PD::runner_up_distance),
               field("surface_coverage", &PD::surface_coverage), field("indices", &PD::indices),
               field("parts", &PD::parts), field("size", &PD::size), field("message", &PD::message),
               field("seconds", &PD::seconds));
  using PDs = PartDetections;
  pickleFields(m, "PartDetections", field("detections", &PDs::detections), field("table", &PDs::table),
               field("seconds", &PDs::seconds));
}

}  // namespace

void definePose(py::module_& m) {
  bindCbd(m);
  bindMotors(m);
  bindAlignment(m);
  bindViews(m);
  bindPipeline(m);
  bindFindParts(m);
  bindDescribe(m);
  pickleCbdAndViews(m);
  picklePoseResults(m);
}

}  // namespace scanalign::python
