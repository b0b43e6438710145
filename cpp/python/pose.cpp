// Bindings of the CAD-pose chain: CBD descriptor, motor estimation, correspondence RANSAC,
// CBD alignment and paper 4's flag alignment. Validation of user input happens in
// python/scanalign/{cbd,pose}.py; the C++ layer re-checks and throws std::invalid_argument.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "scanalign/features/cbd.hpp"
#include "scanalign/registration/cbd_alignment.hpp"
#include "scanalign/registration/correspondence_ransac.hpp"
#include "scanalign/registration/flag_alignment.hpp"
#include "scanalign/registration/motor_estimation.hpp"

namespace scanalign::python {

namespace {

template <typename T>
py::array_t<T> vec(const std::vector<T>& v) {
  py::array_t<T> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::array_t<double> rows4(const std::vector<Eigen::Vector4d>& v) {
  py::array_t<double> a({static_cast<py::ssize_t>(v.size()), py::ssize_t{4}});
  double* d = a.mutable_data();
  for (std::size_t i = 0; i < v.size(); ++i)
    for (int k = 0; k < 4; ++k) d[4 * i + k] = v[i](k);
  return a;
}

py::dict sphereArrays(const std::vector<CbdSphere>& s) {
  py::array_t<double> dual({static_cast<py::ssize_t>(s.size()), py::ssize_t{5}});
  py::array_t<bool> flat(static_cast<py::ssize_t>(s.size()));
  double* d = dual.mutable_data();
  bool* f = flat.mutable_data();
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (int k = 0; k < 5; ++k) d[5 * i + k] = s[i].dual(k);
    f[i] = s[i].flat;
  }
  py::dict out;
  out["dual"] = dual;
  out["flat"] = flat;
  return out;
}

py::dict featuresDict(const CbdFeatures& f) {
  py::dict out;
  out["keypoints"] = vec(f.keypoints);
  out["descriptors"] = rows4(f.descriptors);
  out["scalar"] = vec(f.scalar);
  out["sphere1"] = sphereArrays(f.sphere1);
  out["sphere2"] = sphereArrays(f.sphere2);
  py::array_t<double> axes({static_cast<py::ssize_t>(f.axes.size()), py::ssize_t{3}, py::ssize_t{3}});
  double* a = axes.mutable_data();
  for (std::size_t i = 0; i < f.axes.size(); ++i)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a[9 * i + 3 * r + c] = f.axes[i](r, c);
  out["axes"] = axes;
  out["thresholds"] = f.thresholds;
  out["points_with_min_neighbors"] = f.points_with_min_neighbors;
  out["min_neighbors"] = f.min_neighbors;
  out["seconds"] = f.seconds;
  return out;
}

template <typename Scalar>
py::dict cbd(const py::array& points, const CbdSettings& s, const py::object& thresholds) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  ShapeThresholds t;
  const bool has = !thresholds.is_none();
  if (has) t = py::cast<ShapeThresholds>(thresholds);
  CbdFeatures f;
  {
    py::gil_scoped_release release;
    f = computeCbd(view, s, has ? &t : nullptr);
  }
  return featuresDict(f);
}

template <typename Scalar>
py::tuple pca(const py::array& points, double radius, int threads) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  std::vector<NeighbourhoodPca> p;
  {
    py::gil_scoped_release release;
    p = neighbourhoodPca(view, radius, threads);
  }
  py::array_t<std::uint32_t> count(static_cast<py::ssize_t>(p.size()));
  py::array_t<double> ev({static_cast<py::ssize_t>(p.size()), py::ssize_t{3}});
  for (std::size_t i = 0; i < p.size(); ++i) {
    count.mutable_data()[i] = p[i].count;
    for (int k = 0; k < 3; ++k) ev.mutable_data()[3 * i + k] = p[i].eigenvalues(k);
  }
  return py::make_tuple(count, ev);
}

std::vector<NeighbourhoodPca> pcaFrom(const py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>& count,
                                      const py::array_t<double, py::array::c_style | py::array::forcecast>& ev) {
  if (ev.ndim() != 2 || ev.shape(1) != 3 || count.ndim() != 1 || count.shape(0) != ev.shape(0))
    throw py::value_error("expected counts (N,) and eigenvalues (N, 3)");
  std::vector<NeighbourhoodPca> p(static_cast<std::size_t>(count.shape(0)));
  for (std::size_t i = 0; i < p.size(); ++i) {
    p[i].count = count.data()[i];
    p[i].eigenvalues = Eigen::Vector3d(ev.data()[3 * i], ev.data()[3 * i + 1], ev.data()[3 * i + 2]);
  }
  return p;
}

CbdFeatures featuresFrom(const py::array_t<double, py::array::c_style | py::array::forcecast>& desc,
                         const py::array_t<double, py::array::c_style | py::array::forcecast>& scalar) {
  if (desc.ndim() != 2 || desc.shape(1) != 4 || scalar.ndim() != 1 || scalar.shape(0) != desc.shape(0))
    throw py::value_error("expected descriptors (N, 4) and scalar descriptors (N,)");
  CbdFeatures f;
  const std::size_t n = static_cast<std::size_t>(desc.shape(0));
  f.keypoints.resize(n);
  f.descriptors.resize(n);
  f.scalar.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    f.keypoints[i] = static_cast<std::uint32_t>(i);
    f.descriptors[i] = Eigen::Vector4d(desc.data()[4 * i], desc.data()[4 * i + 1], desc.data()[4 * i + 2],
                                       desc.data()[4 * i + 3]);
    f.scalar[i] = scalar.data()[i];
  }
  return f;
}

py::dict motorDict(const MotorEstimate& e) {
  py::dict out;
  out["T_target_source"] = e.T_target_source;
  out["motor"] = Eigen::VectorXd(e.motor);
  out["rmse"] = e.rmse;
  out["count"] = e.count;
  out["valid"] = e.valid;
  out["message"] = e.message;
  return out;
}

py::array_t<double, py::array::c_style | py::array::forcecast> optWeights(const py::object& w, std::size_t n) {
  if (w.is_none()) return py::array_t<double, py::array::c_style | py::array::forcecast>();
  auto a = py::cast<py::array_t<double, py::array::c_style | py::array::forcecast>>(w);
  if (a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != n) throw py::value_error("weights must have shape (N,)");
  return a;
}

template <typename Scalar>
py::dict alignCbdPy(const py::array& source, const py::array& target, const CbdAlignmentSettings& s) {
  const CloudView<Scalar> src = cloudView<Scalar>(source, "source"), tgt = cloudView<Scalar>(target, "target");
  CbdAlignmentResult r;
  {
    py::gil_scoped_release release;
    r = alignCbd(src, tgt, s);
  }
  py::dict out;
  out["T_target_source"] = r.T_target_source;
  out["found"] = r.found;
  out["fitness"] = r.fitness;
  out["inlier_rmse"] = r.inlier_rmse;
  out["source_keypoints"] = r.source_keypoints;
  out["target_keypoints"] = r.target_keypoints;
  out["matches"] = r.matches;
  out["match_inliers"] = r.match_inliers;
  out["feature_seconds"] = r.feature_seconds;
  out["match_seconds"] = r.match_seconds;
  out["ransac_seconds"] = r.ransac_seconds;
  out["seconds"] = r.seconds;
  out["message"] = r.message;
  return out;
}

py::dict flagDict(const NormalLineFlag& f) {
  py::dict d;
  d["centroid"] = f.centroid;
  d["direction"] = f.direction;
  d["foot"] = f.foot;
  d["mean_normal_length"] = f.mean_normal_length;
  d["pitch"] = f.pitch;
  d["count"] = f.count;
  return d;
}

template <typename Scalar>
py::dict alignFlagsPy(const py::array& source, const py::array& source_normals, const py::array& target,
                      const py::array& target_normals, const FlagAlignmentSettings& s) {
  const auto a = cloudView<Scalar>(source, "source"), an = cloudView<Scalar>(source_normals, "source_normals");
  const auto b = cloudView<Scalar>(target, "target"), bn = cloudView<Scalar>(target_normals, "target_normals");
  FlagAlignmentResult r;
  {
    py::gil_scoped_release release;
    r = alignFlags(a, an, b, bn, s);
  }
  py::dict out;
  out["T_target_source"] = r.T_target_source;
  out["valid"] = r.valid;
  out["iterations"] = r.iterations;
  out["cost"] = r.cost;
  out["source_flag"] = flagDict(r.source_flag);
  out["target_flag"] = flagDict(r.target_flag);
  out["message"] = r.message;
  return out;
}

template <typename Scalar>
py::dict flagPy(const py::array& points, const py::array& normals) {
  return flagDict(normalLineFlag(cloudView<Scalar>(points, "points"), cloudView<Scalar>(normals, "normals")));
}

}  // namespace

void definePose(py::module_& m) {
  py::enum_<CbdKeypointMode>(m, "CbdKeypointMode")
      .value("thresholds", CbdKeypointMode::Thresholds)
      .value("automatic", CbdKeypointMode::Automatic);
  py::enum_<CbdDescriptorVariant>(m, "CbdDescriptorVariant")
      .value("radius_distance", CbdDescriptorVariant::RadiusDistance)
      .value("scalar", CbdDescriptorVariant::Scalar);
  py::class_<ShapeThresholds>(m, "ShapeThresholds")
      .def(py::init([](double l, double p, double s) { return ShapeThresholds{l, p, s}; }), py::arg("linear") = 0.3,
           py::arg("planar") = 1.0, py::arg("spherical") = 0.3)
      .def_readwrite("linear", &ShapeThresholds::linear)
      .def_readwrite("planar", &ShapeThresholds::planar)
      .def_readwrite("spherical", &ShapeThresholds::spherical)
      .def("__repr__", [](const ShapeThresholds& t) {
        return "ShapeThresholds(linear=" + std::to_string(t.linear) + ", planar=" + std::to_string(t.planar) +
               ", spherical=" + std::to_string(t.spherical) + ")";
      });
  py::class_<CbdSettings>(m, "CbdSettings")
      .def(py::init<>())
      .def_readwrite("radius", &CbdSettings::radius)
      .def_readwrite("gamma", &CbdSettings::gamma)
      .def_readwrite("min_neighbors", &CbdSettings::min_neighbors)
      .def_readwrite("keypoint_mode", &CbdSettings::keypoint_mode)
      .def_readwrite("num_keypoints", &CbdSettings::num_keypoints)
      .def_readwrite("thresholds", &CbdSettings::thresholds)
      .def_readwrite("max_keypoints", &CbdSettings::max_keypoints)
      .def_readwrite("max_sphere_radius", &CbdSettings::max_sphere_radius)
      .def_readwrite("variant", &CbdSettings::variant)
      .def_readwrite("num_threads", &CbdSettings::num_threads);
  py::class_<CorrespondenceRansacSettings>(m, "CorrespondenceRansacSettings")
      .def(py::init<>())
      .def_readwrite("max_iterations", &CorrespondenceRansacSettings::max_iterations)
      .def_readwrite("inlier_threshold", &CorrespondenceRansacSettings::inlier_threshold)
      .def_readwrite("edge_similarity", &CorrespondenceRansacSettings::edge_similarity)
      .def_readwrite("min_edge", &CorrespondenceRansacSettings::min_edge)
      .def_readwrite("confidence", &CorrespondenceRansacSettings::confidence)
      .def_readwrite("refine_iterations", &CorrespondenceRansacSettings::refine_iterations)
      .def_readwrite("seed", &CorrespondenceRansacSettings::seed)
      .def_readwrite("num_threads", &CorrespondenceRansacSettings::num_threads);
  py::class_<CbdAlignmentSettings>(m, "CbdAlignmentSettings")
      .def(py::init<>())
      .def_readwrite("cbd", &CbdAlignmentSettings::cbd)
      .def_readwrite("ransac", &CbdAlignmentSettings::ransac)
      .def_readwrite("matches_per_keypoint", &CbdAlignmentSettings::matches_per_keypoint)
      .def_readwrite("target_thresholds_from_source", &CbdAlignmentSettings::target_thresholds_from_source);
  py::class_<FlagAlignmentSettings>(m, "FlagAlignmentSettings")
      .def(py::init<>())
      .def_readwrite("min_mean_normal_length", &FlagAlignmentSettings::min_mean_normal_length)
      .def_readwrite("min_centroid_offset", &FlagAlignmentSettings::min_centroid_offset)
      .def_readwrite("max_iterations", &FlagAlignmentSettings::max_iterations)
      .def_readwrite("tolerance", &FlagAlignmentSettings::tolerance);

  m.def("cbd_f32", &cbd<float>, py::arg("points"), py::arg("settings"), py::arg("thresholds") = py::none());
  m.def("cbd_f64", &cbd<double>, py::arg("points"), py::arg("settings"), py::arg("thresholds") = py::none());
  m.def("neighbourhood_pca_f32", &pca<float>, py::arg("points"), py::arg("radius"), py::arg("num_threads"));
  m.def("neighbourhood_pca_f64", &pca<double>, py::arg("points"), py::arg("radius"), py::arg("num_threads"));
  m.def(
      "select_keypoints",
      [](const py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>& count,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& ev, const ShapeThresholds& t,
         int min_neighbors, bool inclusive) { return vec(selectKeypoints(pcaFrom(count, ev), t, min_neighbors, inclusive)); },
      py::arg("counts"), py::arg("eigenvalues"), py::arg("thresholds"), py::arg("min_neighbors"), py::arg("inclusive"));
  m.def(
      "automatic_keypoints",
      [](const py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>& count,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& ev, int k, int min_neighbors) {
        ShapeThresholds t;
        auto keys = automaticKeypoints(pcaFrom(count, ev), k, min_neighbors, &t);
        return py::make_tuple(vec(keys), t);
      },
      py::arg("counts"), py::arg("eigenvalues"), py::arg("k"), py::arg("min_neighbors"));
  m.def(
      "keypoint_scores",
      [](const py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>& count,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& ev, int min_neighbors) {
        const auto p = pcaFrom(count, ev);
        std::vector<double> s(p.size());
        for (std::size_t i = 0; i < p.size(); ++i) s[i] = keypointScore(p[i], min_neighbors);
        return vec(s);
      },
      py::arg("counts"), py::arg("eigenvalues"), py::arg("min_neighbors"));
  m.def(
      "match_cbd",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& sd,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& ss,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& td,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& ts, CbdDescriptorVariant variant, int k,
         int threads) {
        const CbdFeatures a = featuresFrom(sd, ss), b = featuresFrom(td, ts);
        CbdMatches mm;
        {
          py::gil_scoped_release release;
          mm = matchCbd(a, b, variant, k, threads);
        }
        return py::make_tuple(vec(mm.source), vec(mm.target), vec(mm.error));
      },
      py::arg("source_descriptors"), py::arg("source_scalar"), py::arg("target_descriptors"),
      py::arg("target_scalar"), py::arg("variant"), py::arg("k"), py::arg("num_threads"));

  m.def(
      "estimate_motor",
      [](const py::array& s, const py::array& t, const py::object& w, bool normalize) {
        const auto a = cloudView<double>(s, "source"), b = cloudView<double>(t, "target");
        const auto wa = optWeights(w, a.size);
        return motorDict(estimateMotor(a, b, w.is_none() ? nullptr : wa.data(), normalize));
      },
      py::arg("source"), py::arg("target"), py::arg("weights"), py::arg("normalize"));
  m.def(
      "estimate_rigid_svd",
      [](const py::array& s, const py::array& t, const py::object& w) {
        const auto a = cloudView<double>(s, "source"), b = cloudView<double>(t, "target");
        const auto wa = optWeights(w, a.size);
        return motorDict(estimateRigidSvd(a, b, w.is_none() ? nullptr : wa.data()));
      },
      py::arg("source"), py::arg("target"), py::arg("weights"));
  m.def(
      "motor_to_matrix", [](const Eigen::Matrix<double, 8, 1>& mv) { return motorToMatrix(mv); }, py::arg("motor"));
  m.def(
      "ransac_rigid_motion",
      [](const py::array& s, const py::array& t,
         const py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>& pairs,
         const CorrespondenceRansacSettings& settings) {
        if (pairs.ndim() != 2 || pairs.shape(1) != 2) throw py::value_error("pairs must have shape (K, 2)");
        const auto a = cloudView<double>(s, "source"), b = cloudView<double>(t, "target");
        CorrespondenceRansacResult r;
        {
          py::gil_scoped_release release;
          r = ransacRigidMotion(a, b, pairs.data(), static_cast<std::size_t>(pairs.shape(0)), settings);
        }
        py::dict out;
        out["T_target_source"] = r.T_target_source;
        out["found"] = r.found;
        out["inliers"] = vec(r.inliers);
        out["inlier_rmse"] = r.inlier_rmse;
        out["iterations"] = r.iterations;
        out["message"] = r.message;
        return out;
      },
      py::arg("source"), py::arg("target"), py::arg("pairs"), py::arg("settings"));
  m.def("align_cbd_f32", &alignCbdPy<float>, py::arg("source"), py::arg("target"), py::arg("settings"));
  m.def("align_cbd_f64", &alignCbdPy<double>, py::arg("source"), py::arg("target"), py::arg("settings"));
  m.def(
      "alignment_fitness_f64",
      [](const py::array& s, const py::array& t, const Eigen::Matrix4d& T, double thr, int threads) {
        const auto f = alignmentFitness(cloudView<double>(s, "source"), cloudView<double>(t, "target"), T, thr, threads);
        return py::make_tuple(f.first, f.second);
      },
      py::arg("source"), py::arg("target"), py::arg("T"), py::arg("threshold"), py::arg("num_threads"));
  m.def("normal_line_flag_f32", &flagPy<float>, py::arg("points"), py::arg("normals"));
  m.def("normal_line_flag_f64", &flagPy<double>, py::arg("points"), py::arg("normals"));
  m.def("align_flags_f32", &alignFlagsPy<float>, py::arg("source"), py::arg("source_normals"), py::arg("target"),
        py::arg("target_normals"), py::arg("settings"));
  m.def("align_flags_f64", &alignFlagsPy<double>, py::arg("source"), py::arg("source_normals"), py::arg("target"),
        py::arg("target_normals"), py::arg("settings"));
}

}  // namespace scanalign::python
