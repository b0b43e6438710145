// Bindings of the coarse alignment building blocks of the pose area (Kleppe, PhD thesis, NTNU
// 2018): motor estimation from point pairs (paper 5 (36)-(44), motor_estimation.hpp),
// correspondence RANSAC (correspondence_ransac.hpp), CBD alignment (cbd_alignment.hpp) and
// paper 4's flag alignment (flag_alignment.hpp).
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "arrays.hpp"
#include "pose.hpp"
#include "scanalign/pose/cbd_alignment.hpp"
#include "scanalign/pose/correspondence_ransac.hpp"
#include "scanalign/pose/flag_alignment.hpp"
#include "scanalign/pose/motor_estimation.hpp"

namespace scanalign::python {

namespace {

const double* optionalWeights(const py::object& w, const F64& held, std::size_t n) {
  if (w.is_none()) return nullptr;
  if (held.ndim() != 1 || static_cast<std::size_t>(held.shape(0)) != n)
    throw py::value_error("weights: expected shape (" + std::to_string(n) + ",)");
  return held.data();
}

void bindMotors(py::module_& m) {
  using R = MotorEstimationResult;
  fieldsOf(py::class_<R>(m, "MotorEstimationResult", "A rigid motion estimated from point pairs"))
      .output("T_target_source", &R::T_target_source, "m", "(4, 4) y = R x + t")
      .output("motor", &R::motor, "", "(8,) coefficients on (1, e23, e31, e12, e1inf, e2inf, e3inf, e123inf), M ~M = 1")
      .output("rmse", &R::rmse, "m", "weighted RMS pair residual")
      .output("count", &R::count, "", "pairs used")
      .output("valid", &R::valid, "", "False for fewer than 3 pairs or collinear data")
      .output("message", &R::message, "", "why not valid")
      .result();
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
}

void bindRansac(py::module_& m) {
  using S = CorrespondenceRansacSettings;
  fieldsOf(py::class_<S>(m, "CorrespondenceRansacSettings", "RANSAC over putative point pairs"))
      .field("max_iterations", &S::max_iterations, "", "hypotheses (thesis baselines: 1000)")
      .field("inlier_threshold", &S::inlier_threshold, "m", "a pair is an inlier if |y - (R x + t)| < this (thesis: 0.005)")
      .field("edge_similarity", &S::edge_similarity, "",
             "prerejection: sample triangles' edge-length ratios must exceed this, in [0, 1)")
      .field("min_edge", &S::min_edge, "m", "shortest sample edge")
      .field("confidence", &S::confidence, "", "early stop, in (0, 1)")
      .field("refine_iterations", &S::refine_iterations, "", "motor refits on the inliers")
      .field("seed", &S::seed, "", "random seed (results do not depend on threads)")
      .field("num_threads", &S::num_threads, "", "0 = all cores")
      .settings();
  using R = CorrespondenceRansacResult;
  fieldsOf(py::class_<R>(m, "CorrespondenceRansacResult", "Outcome of ransac_rigid_motion"))
      .output("T_target_source", &R::T_target_source, "m", "(4, 4), identity when not found")
      .output("found", &R::found, "", "a hypothesis with at least 3 inlier pairs")
      .field("inliers", int64Getter(&R::inliers), int64Setter(&R::inliers), "", "(K,) int64 indices into the pair list",
             false)
      .output("inlier_rmse", &R::inlier_rmse, "m", "over the inlier pairs")
      .output("iterations", &R::iterations, "", "hypotheses drawn")
      .output("message", &R::message, "", "why nothing was found")
      .result();
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

void bindCbdAlignment(py::module_& m) {
  using S = CbdAlignmentSettings;
  fieldsOf(py::class_<S>(m, "CbdAlignmentSettings", "CBD coarse alignment"))
      .field("cbd", &S::cbd, "", "CbdSettings for both clouds")
      .field("ransac", &S::ransac, "", "CorrespondenceRansacSettings (10000 hypotheses)")
      .field("matches_per_keypoint", &S::matches_per_keypoint, "", "k nearest target descriptors per source keypoint")
      .field("hypotheses", &S::hypotheses, "",
             "sequential RANSAC: up to this many hypotheses (each on the pairs the earlier ones left), the one whose "
             "whole source cloud fits the target best wins (a half-turn look-alike's flipped pose can have the "
             "largest consensus); 1: classic RANSAC")
      .field("target_thresholds_from_source", &S::target_thresholds_from_source, "",
             "derive the deltas from the source's automatic keypoints and apply them to the target")
      .settings();
  using R = CbdAlignmentResult;
  fieldsOf(py::class_<R>(m, "CbdAlignmentResult", "Outcome of align_cbd"))
      .output("T_target_source", &R::T_target_source, "m", "(4, 4) maps source into target")
      .derived("transformation", [](const R& r) { return r.T_target_source; }, "m",
               "T_target_source under Open3D's name (RegistrationResult.transformation)")
      .output("found", &R::found, "", "RANSAC found a consistent set of matches")
      .output("fitness", &R::fitness, "", "source points within the inlier threshold of the target")
      .output("inlier_rmse", &R::inlier_rmse, "m", "over those points")
      .output("source_keypoints", &R::source_keypoints, "", "CBD keypoints of the source")
      .output("target_keypoints", &R::target_keypoints, "", "CBD keypoints of the target")
      .output("matches", &R::matches, "", "descriptor matches fed to RANSAC")
      .output("match_inliers", &R::match_inliers, "", "matches consistent with the pose")
      .output("feature_seconds", &R::feature_seconds, "s", "CBD of both clouds")
      .output("match_seconds", &R::match_seconds, "s", "descriptor matching")
      .output("ransac_seconds", &R::ransac_seconds, "s", "RANSAC and the motor refit")
      .output("seconds", &R::seconds, "s", "wall time")
      .output("message", &R::message, "", "why nothing was found")
      .result();
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
}

void bindFlags(py::module_& m) {
  using N = NormalLineFlag;
  fieldsOf(py::class_<N>(m, "NormalLineFlag", "A cloud's flag (paper 4): centroid and average normal line"))
      .output("centroid", &N::centroid, "m", "(3,)")
      .output("direction", &N::direction, "", "(3,) unit direction of the average normal line")
      .output("foot", &N::foot, "m", "(3,) the line's point nearest the centroid")
      .output("mean_normal_length", &N::mean_normal_length, "", "|mean unit normal|, ~0 on a closed surface")
      .output("pitch", &N::pitch, "m", "n.m/|n|^2 of the averaged screw (0 for a pure line)")
      .output("count", &N::count, "", "points used")
      .result();
  using S = FlagAlignmentSettings;
  fieldsOf(py::class_<S>(m, "FlagAlignmentSettings", "Paper 4 initial alignment"))
      .field("min_mean_normal_length", &S::min_mean_normal_length, "",
             "refuse when |mean unit normal| of either cloud is below this (closed surfaces)")
      .field("min_centroid_offset", &S::min_centroid_offset, "m", "refuse when the centroid lies this close to the average line")
      .field("min_points", &S::min_points, "",
             "refuse (valid False) when either cloud has fewer usable points (finite, non-zero normal)")
      .field("max_iterations", &S::max_iterations, "", "Levenberg-Marquardt iterations")
      .field("tolerance", &S::tolerance, "", "convergence tolerance (relative cost decrease)")
      .settings();
  using R = FlagAlignmentResult;
  fieldsOf(py::class_<R>(m, "FlagAlignmentResult", "Outcome of align_flags"))
      .output("T_target_source", &R::T_target_source, "m", "(4, 4) the motor, f_target = M f_source ~M")
      .output("valid", &R::valid, "",
              "False when refused (message says why): fewer than min_points usable points, collinear or coincident "
              "points, a closed surface, a centroid on the average line, a non-finite result")
      .output("iterations", &R::iterations, "", "Levenberg-Marquardt iterations run")
      .output("cost", &R::cost, "", "(delta^2 + sin^2(theta/2) + d^2)/2 at the solution (m^2 and rad mixed, paper 4)")
      .output("source_flag", &R::source_flag, "", "NormalLineFlag of the source")
      .output("target_flag", &R::target_flag, "", "NormalLineFlag of the target")
      .output("message", &R::message, "", "why refused")
      .result();
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

}  // namespace

void bindPoseAlignment(py::module_& m) {
  bindMotors(m);
  bindRansac(m);
  bindCbdAlignment(m);
  bindFlags(m);
}

}  // namespace scanalign::python
