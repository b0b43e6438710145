// Bindings of the curvature-based descriptor (scanalign/pose/cbd.hpp; Kleppe, PhD thesis, NTNU
// 2018, ch. 6 and paper 5 §III): settings, features, keypoints and matching.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "arrays.hpp"
#include "pose.hpp"

namespace scanalign::python {

namespace {

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

/// An enum index read from a pickled state, in [0, n).
template <typename E>
E enumIndex(int v, int n, const char* what) {
  if (v < 0 || v >= n) throw py::value_error(std::string(what) + ": pickled value out of range");
  return static_cast<E>(v);
}

Eigen::Vector3d thresholdArray(const ShapeThresholds& t) { return {t.linear, t.planar, t.spherical}; }
ShapeThresholds thresholdsFrom(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

/// One column of a per-keypoint sphere list, flat.
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

using Dual = Eigen::Matrix<double, 5, 1>;

/// Field-table accessors of a sphere list shown as its dual vectors (K, 5) and its flags (K,).
auto dualsOf(std::vector<CbdSphere> CbdFeatures::*spheres) {
  return [spheres](const CbdFeatures& f) {
    std::vector<Dual> d;
    for (const CbdSphere& s : f.*spheres) d.push_back(s.dual);
    return d;
  };
}
auto setDuals(std::vector<CbdSphere> CbdFeatures::*spheres) {
  return [spheres](CbdFeatures& f, const std::vector<Dual>& d) {
    (f.*spheres).resize(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) (f.*spheres)[i].dual = d[i];
  };
}
auto flatsOf(std::vector<CbdSphere> CbdFeatures::*spheres) {
  return [spheres](const CbdFeatures& f) {
    Eigen::Array<bool, Eigen::Dynamic, 1> a(static_cast<Eigen::Index>((f.*spheres).size()));
    for (std::size_t i = 0; i < (f.*spheres).size(); ++i) a[static_cast<Eigen::Index>(i)] = (f.*spheres)[i].flat;
    return a;
  };
}
auto setFlats(std::vector<CbdSphere> CbdFeatures::*spheres) {
  return [spheres](CbdFeatures& f, const Eigen::Array<bool, Eigen::Dynamic, 1>& a) {
    (f.*spheres).resize(static_cast<std::size_t>(a.size()));
    for (std::size_t i = 0; i < (f.*spheres).size(); ++i) (f.*spheres)[i].flat = a[static_cast<Eigen::Index>(i)];
  };
}

void bindSettingsAndFeatures(py::module_& m) {
  py::enum_<CbdKeypointMode>(m, "CbdKeypointMode", "How CBD keypoints are chosen")
      .value("thresholds", CbdKeypointMode::Thresholds, "(6.4) with the given deltas and n_min")
      .value("automatic", CbdKeypointMode::Automatic, "the num_keypoints lowest-score points (paper 5, §III-B4)");
  py::enum_<CbdDescriptorVariant>(m, "CbdDescriptorVariant", "Which descriptor the matcher compares")
      .value("radius_distance", CbdDescriptorVariant::RadiusDistance, "(r1, d1, r2, d2), paper 5 (29)-(32)")
      .value("scalar", CbdDescriptorVariant::Scalar, "F = (S1 + S2).P, thesis (6.17)-(6.18)");
  using T = ShapeThresholds;
  fieldsOf(py::class_<T>(m, "ShapeThresholds", "delta_l, delta_p, delta_s of (6.4); a value >= 1 disables its factor")
               .def(py::init([](double l, double p, double s) { return T{l, p, s}; }), py::arg("linear"),
                    py::arg("planar"), py::arg("spherical")))
      .field("linear", &T::linear, "", "delta_l (thesis Fig 6.3: 0.3)")
      .field("planar", &T::planar, "", "delta_p (thesis: 1, planar points are never keypoints)")
      .field("spherical", &T::spherical, "", "delta_s (thesis: 0.3)")
      .settings();
  using S = CbdSettings;
  fieldsOf(py::class_<S>(m, "CbdSettings", "Settings of the curvature-based descriptor (thesis values by default)"))
      .field("radius", &S::radius, "m", "neighbourhood radius r (paper 5 §IV-A: 0.0063)")
      .field("gamma", &S::gamma, "1/m", "plane-distance weight exp(-gamma |d|) (paper 5: 0.2/mm = 200)")
      .field("min_neighbors", &S::min_neighbors, "",
             "n_min, neighbours (the point included) to be a keypoint (paper 5: 200); 0 = half the median neighbour "
             "count")
      .field("keypoint_mode", &S::keypoint_mode, "", "CbdKeypointMode")
      .field("num_keypoints", &S::num_keypoints, "", "k of the automatic mode (paper 5: 2000)")
      .field("thresholds", &S::thresholds, "", "ShapeThresholds of the thresholds mode")
      .field("max_keypoints", &S::max_keypoints, "", "cap in the thresholds mode, lowest scores kept (0: none)")
      .field("max_sphere_radius", &S::max_sphere_radius, "m", "larger spheres and planes count as flat (r = d = this, F term 0)")
      .field("variant", &S::variant, "", "CbdDescriptorVariant used for matching")
      .field("num_threads", &S::num_threads, "", "OpenMP threads, 0 = all cores")
      .settings();
  using F = CbdFeatures;
  auto features = fieldsOf(py::class_<F>(m, "CbdFeatures",
                                         "CBD keypoints and descriptors of one cloud (arrays indexed by keypoint)")
                               .def("__len__", [](const F& f) { return f.keypoints.size(); }))
                      .field("keypoints", int64Getter(&F::keypoints), int64Setter(&F::keypoints), "",
                             "(K,) int64 indices into the cloud", false)
                      .output("descriptors", &F::descriptors, "m", "(K, 4) (r1, d1, r2, d2)")
                      .output("scalar", &F::scalar, "m^2", "(K,) F (6.16)")
                      .field("sphere1", dualsOf(&F::sphere1), setDuals(&F::sphere1), "",
                             "(K, 5) dual sphere [c; (c^2 - r^2)/2; 1] on (e1, e2, e3, e_inf, e0) fitted with the "
                             "plane normal to v2 (flat ones as dual planes [n; delta; 0])",
                             false)
                      .field("sphere2", dualsOf(&F::sphere2), setDuals(&F::sphere2), "",
                             "(K, 5) the sphere fitted with the plane normal to v1", false)
                      .field("flat1", flatsOf(&F::sphere1), setFlats(&F::sphere1), "",
                             "(K,) sphere1 was a plane or larger than max_sphere_radius", false)
                      .field("flat2", flatsOf(&F::sphere2), setFlats(&F::sphere2), "", "(K,) sphere2 was flat", false)
                      .output("axes", &F::axes, "", "(K, 3, 3) PCA eigenvectors v1, v2, v3 as columns")
                      .output("thresholds", &F::thresholds, "",
                              "the (6.4) deltas used (derived ones in the automatic mode)")
                      .output("min_neighbors", &F::min_neighbors, "", "n_min used")
                      .output("points_with_min_neighbors", &F::points_with_min_neighbors, "",
                              "points with at least n_min neighbours")
                      .output("seconds", &F::seconds, "s", "wall time")
                      .result();
  // The part library's flat layout (arrays and scalars only: np.savez without pickle), the
  // same as a ModelView's cbd/ entries, so that libraries already written keep loading.
  replacePickle(features, [](const F& f) { return stateOf(f, cbdFeatureFields()); },
                [](const py::dict& state) {
                  F f;
                  assignState(f, state, cbdFeatureFields(), "CbdFeatures");
                  checkCbdFeatures(f, "CbdFeatures");
                  return f;
                });
}

void bindFunctions(py::module_& m) {
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

}  // namespace

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

/// CbdFeatures as flat arrays (K keypoints): keypoints (K,) uint32, descriptors (K, 4),
/// scalar (K,), sphere{1,2}_{dual (K, 5), radius, distance, flat}, axes (K, 3, 3),
/// thresholds (3,), and three scalars.
std::vector<PickleField<CbdFeatures>> cbdFeatureFields() {
  using F = CbdFeatures;
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

void bindPoseCbd(py::module_& m) {
  bindSettingsAndFeatures(m);
  bindFunctions(m);
}

}  // namespace scanalign::python
