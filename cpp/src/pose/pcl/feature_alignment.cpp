// Stock PCL 1.13 global registration baselines (Kleppe, PhD thesis, NTNU 2018, Paper 5 §IV-A and
// ch. 3; Paper 3): FPFH, SHOT, 3D shape context, PFH and RSD matched by
// SampleConsensusPrerejective or SAC-IA, Drost's point-pair features with PCL's hash-map voting,
// and the global GASD and OUR-CVFH, whose reference frames give the pose. The only translation
// unit that pays for PCL's feature and sample-consensus templates; the header stays PCL-free.
//
// The pipeline is deliberately the stock one (voxel grid, NormalEstimationOMP, descriptor,
// matcher) so the baselines are what a PCL user gets. Where stock PCL would crash or
// silently return garbage, this file guards the call instead of changing the method:
// NaN descriptors are removed before FLANN sees them, the correspondence randomness is
// clamped to the number of target descriptors, the PPF angle step is snapped to a value for
// which PCL's accumulator indexing stays in bounds, and PPF models too large for PCL's
// hash map are refused with a message.
#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/common/threads.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Eigenvalues>
#include <pcl/common/common.h>
#include <pcl/common/io.h>
#include <pcl/features/3dsc.h>
#include <pcl/features/fpfh_omp.h>
#include <pcl/features/gasd.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/features/our_cvfh.h>
#include <pcl/features/pfh.h>
#include <pcl/features/ppf.h>
#include <pcl/features/rsd.h>
#include <pcl/features/shot_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/ia_ransac.h>
#include <pcl/registration/ppf_registration.h>
#include <pcl/registration/sample_consensus_prerejective.h>
#include <pcl/search/kdtree.h>

namespace scanalign {

namespace {

using Clock = std::chrono::steady_clock;
using PointT = pcl::PointNormal;  // xyz + normal + curvature: what every PCL stage below reads
using Cloud = pcl::PointCloud<PointT>;
using Tree = pcl::search::KdTree<PointT>;

constexpr double kPi = 3.14159265358979323846;  // M_PI where PCL's own expressions are mirrored

/// PPFHashMapSearch::setInputFeatureCloud recovers the model size as
/// unsigned(sqrt(float(N * N))); above 4096 points N^2 is no longer exact in a float and
/// the recovered N can be one short, which silently scrambles every model pair index. The
/// hash map also holds N^2 entries (~100 bytes each), so 4096 points already cost ~1.7 GB.
/// Time is the practical limit well below that: PCL's key hash (small ints XOR-shifted)
/// takes a few hundred distinct values, so building and probing the hash map degrade to
/// scans of N^2 / O(100) entries; measured on 2 cores, 410 model points take ~1 s, 957
/// points ~80 s, and the cost grows with N^4. Drost samples the model at the distance step
/// (0.05 x diameter, a few hundred points), which is the regime this baseline is for.
constexpr std::size_t kPpfMaxModelPoints = 4096;

/// PFH describes a point by all pairs of its k neighbours, k (k - 1) / 2 pair features, single-
/// threaded in PCL: at the thesis preset (1 mm voxels, 30 mm support, k ~ 2800 on a surface)
/// that is ~4e6 pairs per point, hours for a scan. PCL computed ~3e6 pairs per second on one
/// core here (a 120 mm view at 3 mm voxels and 30 mm support: 1.2e8 pairs, 40 s), so clouds
/// whose neighbourhoods hold more pairs than this together (~30 s) are refused with a message
/// instead of appearing to hang.
constexpr double kPfhMaxPairs = 1e8;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool finitePositive(double v) { return std::isfinite(v) && v > 0.0; }
bool finiteNonNegative(double v) { return std::isfinite(v) && v >= 0.0; }

/// Local descriptors, matched point to point by a RANSAC matcher (the others give a pose themselves).
bool usesMatcher(PclDescriptor d) {
  return d != PclDescriptor::PPF && d != PclDescriptor::GASD && d != PclDescriptor::VFH;
}

void validate(const PclFeatureAlignmentSettings& s) {
  const auto fail = [](const std::string& what) {
    throw std::invalid_argument("pclFeatureAlignment: " + what);
  };
  switch (s.descriptor) {
    case PclDescriptor::FPFH:
    case PclDescriptor::SHOT:
    case PclDescriptor::ShapeContext3D:
    case PclDescriptor::PPF:
    case PclDescriptor::PFH:
    case PclDescriptor::RSD:
    case PclDescriptor::GASD:
    case PclDescriptor::VFH: break;
    default: fail("unknown descriptor");
  }
  switch (s.matcher) {
    case PclMatcher::Prerejective:
    case PclMatcher::SacIA: break;
    default: fail("unknown matcher");
  }
  // The header documents the matcher as ignored for PPF, GASD and VFH, so only the local
  // descriptors are checked: PCL's SAC-IA is only instantiated (and only meaningful) for FPFH here.
  if (s.matcher == PclMatcher::SacIA && usesMatcher(s.descriptor) && s.descriptor != PclDescriptor::FPFH)
    fail(std::string("SAC-IA supports only the FPFH descriptor, got '") + toString(s.descriptor) + "'");
  if (!finiteNonNegative(s.voxel_size)) fail("voxel_size must be finite and >= 0");
  if (!finitePositive(s.normal_radius)) fail("normal_radius must be finite and > 0");
  if (!finitePositive(s.feature_radius)) fail("feature_radius must be finite and > 0");
  if (!finiteNonNegative(s.shot_lrf_radius)) fail("shot_lrf_radius must be finite and >= 0");
  if (!finitePositive(s.shape_context_min_radius)) fail("shape_context_min_radius must be finite and > 0");
  if (!finitePositive(s.shape_context_density_radius)) fail("shape_context_density_radius must be finite and > 0");
  // ShapeContext3DEstimation::initCompute refuses a support radius below the smallest
  // shell and would return an empty feature cloud.
  if (s.descriptor == PclDescriptor::ShapeContext3D && !(s.shape_context_min_radius < s.feature_radius))
    fail("shape_context_min_radius must be smaller than feature_radius");
  if (s.max_iterations < 1) fail("max_iterations must be >= 1");
  // PCL's RANSAC loops cannot be interrupted (Ctrl-C is not seen until they return): 1e9
  // iterations ran for more than ten minutes. 1e6 is a thousand times the thesis preset.
  if (s.max_iterations > kPclMaxIterations) fail("max_iterations must be <= 1000000");
  if (!finitePositive(s.inlier_threshold)) fail("inlier_threshold must be finite and > 0");
  if (s.num_samples < 3) fail("num_samples must be >= 3");
  if (s.correspondence_randomness < 1) fail("correspondence_randomness must be >= 1");
  if (!(std::isfinite(s.similarity_threshold) && s.similarity_threshold >= 0.0 && s.similarity_threshold < 1.0))
    fail("similarity_threshold must lie in [0, 1)");
  if (!(std::isfinite(s.inlier_fraction) && s.inlier_fraction >= 0.0 && s.inlier_fraction <= 1.0))
    fail("inlier_fraction must lie in [0, 1]");
  if (!finiteNonNegative(s.min_sample_distance)) fail("min_sample_distance must be finite and >= 0");
  if (!(finitePositive(s.ppf_angle_step) && s.ppf_angle_step <= kPi)) fail("ppf_angle_step must lie in (0, pi]");
  if (!finiteNonNegative(s.ppf_distance_step)) fail("ppf_distance_step must be finite and >= 0");
  if (!(std::isfinite(s.ppf_scene_fraction) && s.ppf_scene_fraction > 0.0 && s.ppf_scene_fraction <= 1.0))
    fail("ppf_scene_fraction must lie in (0, 1]");
  if (!finitePositive(s.rsd_plane_radius)) fail("rsd_plane_radius must be finite and > 0");
  if (!(finitePositive(s.vfh_eps_angle) && s.vfh_eps_angle <= kPi)) fail("vfh_eps_angle must lie in (0, pi]");
  if (!finitePositive(s.vfh_curvature_threshold)) fail("vfh_curvature_threshold must be finite and > 0");
  if (!finitePositive(s.vfh_cluster_tolerance)) fail("vfh_cluster_tolerance must be finite and > 0");
  // A SGURF is a weighted covariance of the cluster: three points at least.
  if (s.vfh_min_points < 3) fail("vfh_min_points must be >= 3");
  if (s.num_threads < 0) fail("num_threads must be >= 0 (0 = all cores)");
}

/// Copies the finite points of a view; normals are filled in later by PCL.
Cloud::Ptr toCloud(const CloudView<float>& view) {
  auto cloud = pcl::make_shared<Cloud>();
  cloud->reserve(view.size);
  for (std::size_t i = 0; i < view.size; ++i) {
    if (!view.isFinite(i)) continue;
    PointT p;
    p.x = view.ptr(i)[0];
    p.y = view.ptr(i)[1];
    p.z = view.ptr(i)[2];
    p.normal_x = p.normal_y = p.normal_z = 0.f;
    p.curvature = 0.f;
    cloud->push_back(p);
  }
  cloud->is_dense = true;
  return cloud;
}

/// pcl::VoxelGrid with the given leaf (none when leaf == 0). PCL's VoxelGrid warns and
/// returns the input unfiltered when the voxel count overflows an int32; that would make
/// the baseline silently run on the raw scan, so the same test is done here first and
/// reported as a failure (returns nullptr, message set).
Cloud::Ptr voxelize(const Cloud::Ptr& cloud, double leaf, const char* which, std::string& message) {
  if (leaf <= 0.0 || cloud->empty()) return cloud;
  PointT min_p, max_p;
  pcl::getMinMax3D(*cloud, min_p, max_p);
  const float inv = static_cast<float>(1.0 / leaf);
  const std::int64_t dx = static_cast<std::int64_t>((max_p.x - min_p.x) * inv) + 1;
  const std::int64_t dy = static_cast<std::int64_t>((max_p.y - min_p.y) * inv) + 1;
  const std::int64_t dz = static_cast<std::int64_t>((max_p.z - min_p.z) * inv) + 1;
  if (static_cast<double>(dx) * static_cast<double>(dy) * static_cast<double>(dz) >
      static_cast<double>(std::numeric_limits<std::int32_t>::max())) {
    std::ostringstream os;
    os << which << " cloud: voxel_size " << leaf << " m is too small for its extent (pcl::VoxelGrid would need "
       << dx << " x " << dy << " x " << dz << " voxels)";
    message = os.str();
    return nullptr;
  }
  pcl::VoxelGrid<PointT> grid;
  grid.setLeafSize(static_cast<float>(leaf), static_cast<float>(leaf), static_cast<float>(leaf));
  grid.setInputCloud(cloud);
  auto out = pcl::make_shared<Cloud>();
  grid.filter(*out);
  return out;
}

/// pcl::NormalEstimationOMP in place (the PCL tutorials' pattern: only the normal fields and
/// curvature are written), viewpoint at the origin, then drops points whose neighbourhood
/// was too small for a normal: NaN normals would poison every descriptor and PPF.
Cloud::Ptr estimateNormals(const Cloud::Ptr& cloud, const PclFeatureAlignmentSettings& s) {
  if (cloud->empty()) return cloud;
  pcl::NormalEstimationOMP<PointT, PointT> ne(static_cast<unsigned int>(resolveThreads(s.num_threads)));
  ne.setInputCloud(cloud);
  ne.setSearchMethod(pcl::make_shared<Tree>());
  ne.setRadiusSearch(s.normal_radius);
  ne.setViewPoint(0.f, 0.f, 0.f);
  ne.compute(*cloud);
  auto out = pcl::make_shared<Cloud>();
  out->reserve(cloud->size());
  for (const auto& p : *cloud)
    if (std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z)) out->push_back(p);
  out->is_dense = true;
  return out;
}

template <typename FeatureT>
using FeatureCloud = pcl::PointCloud<FeatureT>;

template <typename FeatureT>
typename FeatureCloud<FeatureT>::Ptr computeDescriptors(const Cloud::Ptr& cloud, const PclFeatureAlignmentSettings& s);

template <>
FeatureCloud<pcl::FPFHSignature33>::Ptr computeDescriptors<pcl::FPFHSignature33>(const Cloud::Ptr& cloud,
                                                                                 const PclFeatureAlignmentSettings& s) {
  pcl::FPFHEstimationOMP<PointT, PointT, pcl::FPFHSignature33> est(static_cast<unsigned int>(resolveThreads(s.num_threads)));
  est.setInputCloud(cloud);
  est.setInputNormals(cloud);
  est.setSearchMethod(pcl::make_shared<Tree>());
  est.setRadiusSearch(s.feature_radius);
  auto out = pcl::make_shared<FeatureCloud<pcl::FPFHSignature33>>();
  est.compute(*out);
  return out;
}

template <>
FeatureCloud<pcl::SHOT352>::Ptr computeDescriptors<pcl::SHOT352>(const Cloud::Ptr& cloud,
                                                                 const PclFeatureAlignmentSettings& s) {
  pcl::SHOTEstimationOMP<PointT, PointT, pcl::SHOT352> est(static_cast<unsigned int>(resolveThreads(s.num_threads)));
  est.setInputCloud(cloud);
  est.setInputNormals(cloud);
  est.setSearchMethod(pcl::make_shared<Tree>());
  est.setRadiusSearch(s.feature_radius);
  est.setLRFRadius(static_cast<float>(s.shot_lrf_radius > 0.0 ? s.shot_lrf_radius : s.feature_radius));
  auto out = pcl::make_shared<FeatureCloud<pcl::SHOT352>>();
  est.compute(*out);
  return out;
}

template <>
FeatureCloud<pcl::ShapeContext1980>::Ptr computeDescriptors<pcl::ShapeContext1980>(
    const Cloud::Ptr& cloud, const PclFeatureAlignmentSettings& s) {
  // Not parallel in PCL. The default constructor (random = false) seeds its internal RNG
  // with a constant, so the descriptors repeat from run to run.
  pcl::ShapeContext3DEstimation<PointT, PointT, pcl::ShapeContext1980> est;
  est.setInputCloud(cloud);
  est.setInputNormals(cloud);
  est.setSearchMethod(pcl::make_shared<Tree>());
  est.setRadiusSearch(s.feature_radius);
  est.setMinimalRadius(s.shape_context_min_radius);
  est.setPointDensityRadius(s.shape_context_density_radius);
  auto out = pcl::make_shared<FeatureCloud<pcl::ShapeContext1980>>();
  est.compute(*out);
  return out;
}

template <>
FeatureCloud<pcl::PFHSignature125>::Ptr computeDescriptors<pcl::PFHSignature125>(const Cloud::Ptr& cloud,
                                                                                 const PclFeatureAlignmentSettings& s) {
  pcl::PFHEstimation<PointT, PointT, pcl::PFHSignature125> est;  // no OpenMP variant in PCL
  est.setInputCloud(cloud);
  est.setInputNormals(cloud);
  est.setSearchMethod(pcl::make_shared<Tree>());
  est.setRadiusSearch(s.feature_radius);
  auto out = pcl::make_shared<FeatureCloud<pcl::PFHSignature125>>();
  est.compute(*out);
  return out;
}

template <>
FeatureCloud<pcl::PrincipalRadiiRSD>::Ptr computeDescriptors<pcl::PrincipalRadiiRSD>(const Cloud::Ptr& cloud,
                                                                                     const PclFeatureAlignmentSettings& s) {
  pcl::RSDEstimation<PointT, PointT, pcl::PrincipalRadiiRSD> est;  // single-threaded in PCL
  est.setInputCloud(cloud);
  est.setInputNormals(cloud);
  est.setSearchMethod(pcl::make_shared<Tree>());
  est.setRadiusSearch(s.feature_radius);
  est.setPlaneRadius(s.rsd_plane_radius);
  auto out = pcl::make_shared<FeatureCloud<pcl::PrincipalRadiiRSD>>();
  est.compute(*out);
  return out;
}

template <std::size_t N>
bool allFinite(const float (&bins)[N]) {
  return std::all_of(bins, bins + N, [](float v) { return std::isfinite(v); });
}

// The bins FLANN matches on (what DefaultPointRepresentation copies; SHOT's and 3DSC's
// reference frames are not matched). NaN anywhere (SHOT/3DSC with an empty or degenerate
// support) makes FLANN's distances NaN and its tree search undefined.
bool descriptorFinite(const pcl::FPFHSignature33& f) { return allFinite(f.histogram); }
bool descriptorFinite(const pcl::SHOT352& f) { return allFinite(f.descriptor); }
bool descriptorFinite(const pcl::ShapeContext1980& f) { return allFinite(f.descriptor); }
bool descriptorFinite(const pcl::PFHSignature125& f) { return allFinite(f.histogram); }
bool descriptorFinite(const pcl::PrincipalRadiiRSD& f) { return std::isfinite(f.r_min) && std::isfinite(f.r_max); }

/// Keeps the points whose descriptor is finite, in both clouds, so the point and feature
/// clouds stay in the one-to-one correspondence PCL's matchers require.
template <typename FeatureT>
void removeNonFiniteDescriptors(Cloud::Ptr& points, typename FeatureCloud<FeatureT>::Ptr& features) {
  auto kept_points = pcl::make_shared<Cloud>();
  auto kept_features = pcl::make_shared<FeatureCloud<FeatureT>>();
  kept_points->reserve(points->size());
  kept_features->reserve(features->size());
  for (std::size_t i = 0; i < features->size(); ++i) {
    if (!descriptorFinite((*features)[i])) continue;
    kept_points->push_back((*points)[i]);
    kept_features->push_back((*features)[i]);
  }
  kept_points->is_dense = kept_features->is_dense = true;
  points = kept_points;
  features = kept_features;
}

/// Nearest-neighbour score of a transform on the (downsampled) clouds, independent of which PCL
/// matcher produced it, so every baseline is scored alike (and GASD's and VFH's candidate poses
/// are ranked by it).
class Scorer {
 public:
  Scorer(const Cloud& source, const Cloud& target, double threshold) : source_(source), threshold_(threshold) {
    auto tgt = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    pcl::copyPointCloud(target, *tgt);
    if (!tgt->empty()) tree_.setInputCloud(tgt);
  }

  /// Sets result.fitness and result.inlier_rmse for T_target_source.
  void operator()(const Eigen::Matrix4d& T, PclFeatureAlignmentResult& result) const {
    result.fitness = 0.0;
    result.inlier_rmse = 0.0;
    const auto tgt = tree_.getInputCloud();
    if (source_.empty() || !tgt || tgt->empty()) return;
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    const Eigen::Vector3d t = T.topRightCorner<3, 1>();
    const double threshold2 = threshold_ * threshold_;
    std::size_t inliers = 0;
    double sum2 = 0.0;
    pcl::Indices index(1);
    std::vector<float> d2(1);
    for (const auto& p : source_) {
      const Eigen::Vector3d q = R * Eigen::Vector3d(p.x, p.y, p.z) + t;
      if (!q.allFinite()) continue;
      pcl::PointXYZ query(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()));
      if (tree_.nearestKSearch(query, 1, index, d2) < 1) continue;
      // Recompute the distance in double: FLANN's float squared distance is coarse at mm scale.
      const auto& n = (*tgt)[static_cast<std::size_t>(index[0])];
      const double e2 = (q - Eigen::Vector3d(n.x, n.y, n.z)).squaredNorm();
      if (e2 < threshold2) {
        ++inliers;
        sum2 += e2;
      }
    }
    result.fitness = static_cast<double>(inliers) / static_cast<double>(source_.size());
    result.inlier_rmse = inliers > 0 ? std::sqrt(sum2 / static_cast<double>(inliers)) : 0.0;
  }

  /// The candidate with the highest fitness (then the lowest inlier RMSE) into result.T_target_source.
  void keepBest(const std::vector<Eigen::Matrix4d>& candidates, PclFeatureAlignmentResult& result) const {
    PclFeatureAlignmentResult best, trial;
    bool any = false;
    for (const auto& T : candidates) {
      if (!T.allFinite()) continue;
      (*this)(T, trial);
      if (!any || trial.fitness > best.fitness || (trial.fitness == best.fitness && trial.inlier_rmse < best.inlier_rmse)) {
        best = trial;
        best.T_target_source = T;
        any = true;
      }
    }
    if (any) result.T_target_source = best.T_target_source;
    result.converged = any;
  }

 private:
  const Cloud& source_;
  double threshold_;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree_;
};

/// Whether PFH's k (k - 1) / 2 pairs per point, over both clouds, stay under kPfhMaxPairs
/// (message set when not).
bool pfhAffordable(const Cloud::Ptr& source, const Cloud::Ptr& target, const PclFeatureAlignmentSettings& s,
                   std::string& message) {
  double pairs = 0.0;
  pcl::Indices nn;
  std::vector<float> d2;
  for (const Cloud::Ptr& cloud : {source, target}) {
    Tree tree;
    tree.setInputCloud(cloud);
    for (const auto& p : *cloud) {
      const double k = tree.radiusSearch(p, s.feature_radius, nn, d2);
      pairs += 0.5 * k * (k - 1.0);
      if (pairs > kPfhMaxPairs) {
        std::ostringstream os;
        os << "pfh: the neighbourhoods (feature_radius " << s.feature_radius << " m; " << source->size() << " source, "
           << target->size() << " target points) hold more than " << kPfhMaxPairs << " point pairs, PFH's cost (k^2 "
           << "per point, single-threaded in PCL); raise voxel_size or lower feature_radius";
        message = os.str();
        return false;
      }
    }
  }
  return true;
}

/// Local descriptors + SampleConsensusPrerejective / SAC-IA. Fills the descriptor counts,
/// feature_seconds (added to the voxel/normal time already in it), the transform and
/// converged; returns false when it could not run (message set).
template <typename FeatureT>
bool alignWithDescriptors(const Cloud::Ptr& source_with_normals, const Cloud::Ptr& target_with_normals,
                          const PclFeatureAlignmentSettings& s, PclFeatureAlignmentResult& result) {
  // Local handles: dropping NaN descriptors must not shrink the clouds the caller scores on.
  Cloud::Ptr source = source_with_normals;
  Cloud::Ptr target = target_with_normals;
  const auto t0 = Clock::now();
  if constexpr (std::is_same_v<FeatureT, pcl::PFHSignature125>) {
    if (!pfhAffordable(source, target, s, result.message)) {
      result.feature_seconds += secondsSince(t0);
      return false;
    }
  }
  auto source_features = computeDescriptors<FeatureT>(source, s);
  auto target_features = computeDescriptors<FeatureT>(target, s);
  if (source_features->size() != source->size() || target_features->size() != target->size()) {
    // Feature::compute leaves an empty output when its initCompute fails.
    result.feature_seconds += secondsSince(t0);
    result.message = std::string(toString(s.descriptor)) + ": PCL descriptor estimation failed";
    return false;
  }
  removeNonFiniteDescriptors<FeatureT>(source, source_features);
  removeNonFiniteDescriptors<FeatureT>(target, target_features);
  result.feature_seconds += secondsSince(t0);
  result.source_descriptors = source_features->size();
  result.target_descriptors = target_features->size();

  const auto needed = static_cast<std::size_t>(s.num_samples);
  if (source_features->size() < needed || target_features->size() < needed) {
    std::ostringstream os;
    os << toString(s.descriptor) << ": too few valid descriptors (source " << source_features->size() << ", target "
       << target_features->size() << ", num_samples " << s.num_samples << ")";
    result.message = os.str();
    return false;
  }
  // Both PCL matchers pick a random one of the k nearest target features by indexing the
  // k-NN result with rand() % k; FLANN returns fewer than k when the target has fewer
  // features, so k is clamped to keep that index in bounds.
  const int k = static_cast<int>(
      std::min<std::size_t>(static_cast<std::size_t>(s.correspondence_randomness), target_features->size()));

  Cloud aligned;
  Eigen::Matrix4f T = Eigen::Matrix4f::Identity();
  bool converged = false;
  // PCL's samplers draw from std::rand(); seeding it makes the baseline repeatable.
  std::srand(s.seed);
  if (s.matcher == PclMatcher::Prerejective) {
    pcl::SampleConsensusPrerejective<PointT, PointT, FeatureT> align;
    align.setInputSource(source);
    align.setSourceFeatures(source_features);
    align.setInputTarget(target);
    align.setTargetFeatures(target_features);
    align.setMaximumIterations(s.max_iterations);
    align.setNumberOfSamples(s.num_samples);
    align.setCorrespondenceRandomness(k);
    align.setSimilarityThreshold(static_cast<float>(s.similarity_threshold));
    align.setMaxCorrespondenceDistance(s.inlier_threshold);
    align.setInlierFraction(static_cast<float>(s.inlier_fraction));
    align.align(aligned);
    T = align.getFinalTransformation();
    converged = align.hasConverged();
  } else {
    if constexpr (std::is_same_v<FeatureT, pcl::FPFHSignature33>) {
      pcl::SampleConsensusInitialAlignment<PointT, PointT, FeatureT> align;
      align.setInputSource(source);
      align.setSourceFeatures(source_features);
      align.setInputTarget(target);
      align.setTargetFeatures(target_features);
      if (s.min_sample_distance > 0.0) align.setMinSampleDistance(static_cast<float>(s.min_sample_distance));
      align.setMaxCorrespondenceDistance(s.inlier_threshold);
      align.setMaximumIterations(s.max_iterations);
      align.setNumberOfSamples(s.num_samples);
      align.setCorrespondenceRandomness(k);
      align.align(aligned);
      T = align.getFinalTransformation();
      converged = align.hasConverged();
    } else {
      // validate() already refused this combination.
      throw std::invalid_argument("pclFeatureAlignment: SAC-IA supports only the FPFH descriptor");
    }
  }
  result.T_target_source = T.cast<double>();
  result.converged = converged;
  if (!converged) {
    std::ostringstream os;
    os << toString(s.matcher) << " (" << toString(s.descriptor) << "): no hypothesis accepted in "
       << s.max_iterations << " iterations";
    result.message = os.str();
  }
  return true;
}

/// The PPF angle step actually handed to PCL. PPFRegistration votes into
/// accumulator[floor((alpha + pi) / step)] of a row with floor(2 pi / step) bins, alpha a
/// float in [-pi, pi]. Unless k * step lands within ~1.5e-7 rad below 2 pi for an integer k,
/// the top index equals the bin count and votes with alpha near pi are written one past the
/// end of the row: heap corruption (with PCL's own 12° default, 29 bins are allocated and
/// index 29 is written, which only survives because it lands in malloc's padding). Few
/// float steps satisfy this, so the valid step 2 pi / k (rounded to a float) nearest the
/// requested one (in ratio) is used: 12° becomes 360°/29 = 12.41°, which is also the bin
/// count PCL effectively uses for 12° (no valid step is coarser than 360°/17 = 21.18°, so
/// larger requests get that). The expressions of ppf_registration.hpp are
/// evaluated exactly as there (float step, double arithmetic) so the rounding is the same.
float safePpfAngleStep(double requested) {
  float alpha_max = static_cast<float>(M_PI);  // rounds above M_PI; PCL wraps such alphas
  while (static_cast<double>(alpha_max) > M_PI) alpha_max = std::nextafter(alpha_max, 0.f);
  const auto safe = [&](float step) {
    if (!(step > 0.f)) return false;
    const double bins = std::floor(2 * M_PI / step);
    const double top = std::floor((static_cast<double>(alpha_max) + M_PI) / step);
    return bins >= 1.0 && top < bins;
  };
  const int nominal_bins = std::max(1, static_cast<int>(std::ceil(2 * M_PI / requested - 1e-9)));
  float best = 0.f;
  double best_ratio = std::numeric_limits<double>::infinity();
  for (int k = 1; k <= 2 * nominal_bins + 64; ++k) {
    // Only floats within a few ulps of 2 pi / k can satisfy the test.
    float step = static_cast<float>(2 * M_PI / k);
    for (int u = 0; u < 4; ++u) step = std::nextafter(step, 1.f);
    for (int u = 0; u < 8; ++u, step = std::nextafter(step, 0.f)) {
      if (!safe(step)) continue;
      const double ratio = std::abs(std::log(static_cast<double>(step) / requested));
      if (ratio < best_ratio) {
        best_ratio = ratio;
        best = step;
      }
    }
  }
  if (!(best > 0.f)) throw std::invalid_argument("pclFeatureAlignment: no usable PPF angle step near the requested one");
  return best;
}

/// Drost's PPF with PCL: model = source, scene = target.
bool alignWithPpf(const Cloud::Ptr& source, const Cloud::Ptr& target, const PclFeatureAlignmentSettings& s,
                  PclFeatureAlignmentResult& result) {
  if (source->size() < 2 || target->empty()) {
    std::ostringstream os;
    os << "ppf: too few points with normals (source " << source->size() << ", target " << target->size() << ")";
    result.message = os.str();
    return false;
  }
  if (source->size() > kPpfMaxModelPoints) {
    std::ostringstream os;
    os << "ppf: the model (source) has " << source->size() << " points after the voxel grid; PCL's PPF hash map "
       << "is only exact for up to " << kPpfMaxModelPoints << " (N^2 point pairs) and its cost grows with N^4; raise "
       << "voxel_size (Drost samples the model at the distance step, a few hundred points)";
    result.message = os.str();
    return false;
  }
  const auto t0 = Clock::now();
  double distance_step = s.ppf_distance_step;
  if (distance_step == 0.0) {
    // Drost samples distances at 0.05 x the model diameter; the bounding-box diagonal
    // bounds the diameter from above and costs O(N).
    PointT min_p, max_p;
    pcl::getMinMax3D(*source, min_p, max_p);
    const double diameter = (max_p.getVector3fMap() - min_p.getVector3fMap()).cast<double>().norm();
    distance_step = 0.05 * diameter;
    if (!(distance_step > 0.0)) {
      result.feature_seconds += secondsSince(t0);
      result.message = "ppf: the model has zero extent";
      return false;
    }
  }
  const float angle_step = safePpfAngleStep(s.ppf_angle_step);

  auto model_features = pcl::make_shared<pcl::PointCloud<pcl::PPFSignature>>();
  pcl::PPFEstimation<PointT, PointT, pcl::PPFSignature> estimation;
  estimation.setInputCloud(source);
  estimation.setInputNormals(source);
  estimation.compute(*model_features);
  if (model_features->size() != source->size() * source->size()) {
    result.feature_seconds += secondsSince(t0);
    result.message = "ppf: PCL PPF estimation failed";
    return false;
  }
  auto search = pcl::make_shared<pcl::PPFHashMapSearch>(angle_step, static_cast<float>(distance_step));
  search->setInputFeatureCloud(model_features);
  model_features.reset();  // the hash map keeps what it needs; the N^2 feature cloud can go
  result.feature_seconds += secondsSince(t0);
  // Every model point carries its pair features, so all are "descriptors"; the scene side
  // is described on the fly from the sampled reference points.
  result.source_descriptors = source->size();
  result.target_descriptors = target->size();

  const double rate = std::max(1.0, std::round(1.0 / s.ppf_scene_fraction));
  pcl::PPFRegistration<PointT, PointT> ppf;
  ppf.setSceneReferencePointSamplingRate(static_cast<unsigned int>(rate));
  // Votes of one pose differ by up to a bin in rotation and a distance step in position;
  // two of each keep a true pose's votes in one cluster without merging distinct poses
  // (PCL's own defaults, 20° and 1 cm, are of the same order for decimetre objects).
  ppf.setPositionClusteringThreshold(static_cast<float>(2.0 * distance_step));
  ppf.setRotationClusteringThreshold(2.f * angle_step);
  ppf.setSearchMethod(search);
  ppf.setInputSource(source);
  ppf.setInputTarget(target);
  Cloud aligned;
  std::srand(s.seed);  // nothing random in PCL's PPF, kept for symmetry with the matchers
  ppf.align(aligned);
  result.T_target_source = ppf.getFinalTransformation().cast<double>();
  result.converged = ppf.hasConverged();
  if (!result.converged) result.message = "ppf: PCL's PPF registration did not return a pose";
  return true;
}

/// GASD's canonical frame of a cloud, T_canonical_cloud (pcl::GASDEstimation::getTransform(),
/// Lima 2016 §3.1): origin at the centroid, z the covariance eigenvector of least variance
/// (turned against the view direction (0, 0, 1)), x that of most, y = z x x. Shape only, as the
/// thesis (Paper 5 §IV-A); PCL's default 8^3-cell, 512-bin shape histogram is computed with it
/// but not needed to align one pair. Empty when PCL refuses the cloud.
std::optional<Eigen::Matrix4d> gasdFrame(const Cloud& cloud) {
  auto xyz = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();  // PCL instantiates GASD for PointXYZ
  pcl::copyPointCloud(cloud, *xyz);
  pcl::GASDEstimation<pcl::PointXYZ, pcl::GASDSignature512> gasd;
  gasd.setInputCloud(xyz);
  pcl::PointCloud<pcl::GASDSignature512> descriptor;
  gasd.compute(descriptor);
  if (descriptor.size() != 1 || !gasd.getTransform().allFinite()) return std::nullopt;
  return gasd.getTransform().cast<double>();
}

/// GASD: T_target_source = inverse(T_canonical_target) * T_canonical_source, with (when
/// gasd_half_turns) the three half-turns of the canonical frame that the eigenvector signs
/// leave open, the best-scoring kept.
bool alignWithGasd(const Cloud::Ptr& source, const Cloud::Ptr& target, const PclFeatureAlignmentSettings& s,
                   const Scorer& scorer, PclFeatureAlignmentResult& result) {
  const auto t0 = Clock::now();
  const auto T_cs = gasdFrame(*source);
  const auto T_ct = gasdFrame(*target);
  result.feature_seconds += secondsSince(t0);
  result.source_descriptors = T_cs ? 1 : 0;
  result.target_descriptors = T_ct ? 1 : 0;
  if (!T_cs || !T_ct) {
    result.message = "gasd: PCL's GASD estimation failed";
    return false;
  }
  std::vector<Eigen::Matrix4d> candidates;
  for (const Eigen::Vector3d& flip : {Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(-1, -1, 1), Eigen::Vector3d(-1, 1, -1),
                                      Eigen::Vector3d(1, -1, -1)}) {
    Eigen::Matrix4d F = Eigen::Matrix4d::Identity();
    F.topLeftCorner<3, 3>() = flip.asDiagonal();
    candidates.push_back(T_ct->inverse() * F * *T_cs);
    if (!s.gasd_half_turns) break;
  }
  scorer.keepBest(candidates, result);
  if (!result.converged) result.message = "gasd: the canonical frames gave no finite pose";
  return true;
}

/// One cloud's OUR-CVFH (Aldoma et al., "OUR-CVFH - Oriented, Unique and Repeatable Clustered
/// Viewpoint Feature Histogram for Object Recognition and 6DOF Pose Estimation", DAGM-OAGM 2012):
/// per smooth cluster a SGURF, T_sgurf_cloud (getTransforms(); several when an axis sign is
/// ambiguous), and its 308-bin descriptor. Only the valid SGURFs: PCL falls back to plain VFH
/// with an identity, invalid transform when no cluster has vfh_min_points.
struct Sgurfs {
  std::vector<Eigen::Matrix4d> T_sgurf_cloud;
  std::vector<std::array<float, 308>> descriptors;
};

Sgurfs ourCvfh(const Cloud& cloud, const PclFeatureAlignmentSettings& s) {
  // PCL instantiates OUR-CVFH for PointXYZ + Normal; the copy keeps the curvature it filters on.
  auto xyz = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  auto normals = pcl::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::copyPointCloud(cloud, *xyz);
  pcl::copyPointCloud(cloud, *normals);
  pcl::OURCVFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::VFHSignature308> est;
  est.setInputCloud(xyz);
  est.setInputNormals(normals);
  est.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  est.setEPSAngleThreshold(static_cast<float>(s.vfh_eps_angle));
  est.setCurvatureThreshold(static_cast<float>(s.vfh_curvature_threshold));
  est.setClusterTolerance(static_cast<float>(s.vfh_cluster_tolerance));
  est.setMinPoints(static_cast<std::size_t>(s.vfh_min_points));
  est.setRadiusNormals(static_cast<float>(s.normal_radius));  // PCL re-estimates the clusters' normals
  // Histograms as fractions of the cloud (PCL's default counts points): source and target are
  // different views with different point counts.
  est.setNormalizeBins(true);
  pcl::PointCloud<pcl::VFHSignature308> descriptors;
  est.compute(descriptors);
  std::vector<Eigen::Matrix4f, Eigen::aligned_allocator<Eigen::Matrix4f>> transforms;
  std::vector<bool> valid;
  est.getTransforms(transforms);
  est.getValidTransformsVec(valid);
  Sgurfs out;
  if (descriptors.size() != transforms.size() || valid.size() != transforms.size()) return out;
  for (std::size_t i = 0; i < transforms.size(); ++i) {
    if (!valid[i] || !transforms[i].allFinite() || !allFinite(descriptors[i].histogram)) continue;
    out.T_sgurf_cloud.push_back(transforms[i].cast<double>());
    std::array<float, 308> d;
    std::copy(std::begin(descriptors[i].histogram), std::end(descriptors[i].histogram), d.begin());
    out.descriptors.push_back(d);
  }
  return out;
}

/// OUR-CVFH: each source SGURF is paired with the target SGURF of the nearest descriptor
/// (squared L2) and each target SGURF with the nearest source one; every pair gives
/// T_target_source = inverse(T_sgurf_target) * T_sgurf_source (and, with vfh_normal_flip, the
/// same with the source SGURF's normal reversed), and the best-scoring is kept.
bool alignWithOurCvfh(const Cloud::Ptr& source, const Cloud::Ptr& target, const PclFeatureAlignmentSettings& s,
                      const Scorer& scorer, PclFeatureAlignmentResult& result) {
  const auto t0 = Clock::now();
  const Sgurfs src = ourCvfh(*source, s);
  const Sgurfs tgt = ourCvfh(*target, s);
  result.feature_seconds += secondsSince(t0);
  result.source_descriptors = src.descriptors.size();
  result.target_descriptors = tgt.descriptors.size();
  if (src.descriptors.empty() || tgt.descriptors.empty()) {
    std::ostringstream os;
    os << "vfh: no smooth cluster of at least vfh_min_points (" << s.vfh_min_points << ") points, so no SGURF "
       << "(source " << src.descriptors.size() << ", target " << tgt.descriptors.size() << " SGURFs)";
    result.message = os.str();
    return false;
  }
  const auto distance = [](const std::array<float, 308>& a, const std::array<float, 308>& b) {
    double d = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) d += (static_cast<double>(a[i]) - b[i]) * (static_cast<double>(a[i]) - b[i]);
    return d;
  };
  const auto nearest = [&](const std::array<float, 308>& query, const Sgurfs& in) {
    std::size_t best = 0;
    for (std::size_t j = 1; j < in.descriptors.size(); ++j)
      if (distance(query, in.descriptors[j]) < distance(query, in.descriptors[best])) best = j;
    return best;
  };
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t i = 0; i < src.descriptors.size(); ++i) pairs.emplace_back(i, nearest(src.descriptors[i], tgt));
  for (std::size_t j = 0; j < tgt.descriptors.size(); ++j) pairs.emplace_back(nearest(tgt.descriptors[j], src), j);
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  // A SGURF's z follows its cluster's mean normal, whose sign is the normal estimation's
  // viewpoint convention: reversing it turns the frame half a turn about its x axis.
  Eigen::Matrix4d flip = Eigen::Matrix4d::Identity();
  flip(1, 1) = flip(2, 2) = -1.0;
  std::vector<Eigen::Matrix4d> candidates;
  for (const auto& [i, j] : pairs) {
    candidates.push_back(tgt.T_sgurf_cloud[j].inverse() * src.T_sgurf_cloud[i]);
    if (s.vfh_normal_flip) candidates.push_back(tgt.T_sgurf_cloud[j].inverse() * flip * src.T_sgurf_cloud[i]);
  }
  scorer.keepBest(candidates, result);
  if (!result.converged) result.message = "vfh: the paired SGURFs gave no finite pose";
  return true;
}

/// Whether the cloud's points span a plane: collinear or coincident points (the second
/// eigenvalue of their scatter ~ 0) leave the rotation about their line undetermined, and
/// PCL's matchers would still "converge" on them.
bool spansPlane(const Cloud& c) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : c.points) mean += Eigen::Vector3d(p.x, p.y, p.z);
  mean /= static_cast<double>(c.size());
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& p : c.points) {
    const Eigen::Vector3d d = Eigen::Vector3d(p.x, p.y, p.z) - mean;
    C += d * d.transpose();
  }
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C, Eigen::EigenvaluesOnly).eigenvalues();
  return ev(2) > 0 && ev(1) > 1e-10 * ev(2);  // float input: relative 1e-10 is rounding
}

}  // namespace

PclFeatureAlignmentResult pclFeatureAlignment(const CloudView<float>& source, const CloudView<float>& target,
                                              const PclFeatureAlignmentSettings& settings) {
  const auto t_start = Clock::now();
  validate(settings);
  if (source.empty()) throw std::invalid_argument("pclFeatureAlignment: empty source cloud");
  if (target.empty()) throw std::invalid_argument("pclFeatureAlignment: empty target cloud");

  PclFeatureAlignmentResult result;
  const auto finish = [&]() -> PclFeatureAlignmentResult {
    result.seconds = secondsSince(t_start);
    return result;
  };

  // Stage 1 (timed as features): finite points, voxel grid, normals of both clouds.
  const auto t_features = Clock::now();
  Cloud::Ptr src = voxelize(toCloud(source), settings.voxel_size, "source", result.message);
  Cloud::Ptr tgt = src ? voxelize(toCloud(target), settings.voxel_size, "target", result.message) : nullptr;
  if (!src || !tgt) {
    result.feature_seconds = secondsSince(t_features);
    return finish();
  }
  if (settings.descriptor != PclDescriptor::GASD) {  // GASD reads points only
    src = estimateNormals(src, settings);
    tgt = estimateNormals(tgt, settings);
  }
  result.source_points = src->size();
  result.target_points = tgt->size();
  result.feature_seconds = secondsSince(t_features);

  const std::size_t min_points = settings.descriptor == PclDescriptor::PPF ? 2
                                 : usesMatcher(settings.descriptor) ? static_cast<std::size_t>(settings.num_samples)
                                                                    : 3;  // GASD, VFH: a covariance
  if (src->size() < min_points || tgt->size() < min_points) {
    std::ostringstream os;
    os << "too few finite points with normals after the voxel grid (source " << src->size() << ", target " << tgt->size()
       << "; normal_radius " << settings.normal_radius << " m may be too small)";
    result.message = os.str();
    return finish();
  }
  for (const auto& [cloud, name] : {std::pair{src, "source"}, std::pair{tgt, "target"}})
    if (!spansPlane(*cloud)) {
      result.message = std::string("degenerate: the ") + name +
                       " points are collinear or coincident, so the rotation about their line is undetermined";
      return finish();
    }

  // Stage 2: descriptors (added to feature_seconds) and matching.
  const Scorer scorer(*src, *tgt, settings.inlier_threshold);
  bool ran = false;
  switch (settings.descriptor) {
    case PclDescriptor::FPFH: ran = alignWithDescriptors<pcl::FPFHSignature33>(src, tgt, settings, result); break;
    case PclDescriptor::SHOT: ran = alignWithDescriptors<pcl::SHOT352>(src, tgt, settings, result); break;
    case PclDescriptor::ShapeContext3D:
      ran = alignWithDescriptors<pcl::ShapeContext1980>(src, tgt, settings, result);
      break;
    case PclDescriptor::PPF: ran = alignWithPpf(src, tgt, settings, result); break;
    case PclDescriptor::PFH: ran = alignWithDescriptors<pcl::PFHSignature125>(src, tgt, settings, result); break;
    case PclDescriptor::RSD: ran = alignWithDescriptors<pcl::PrincipalRadiiRSD>(src, tgt, settings, result); break;
    case PclDescriptor::GASD: ran = alignWithGasd(src, tgt, settings, scorer, result); break;
    case PclDescriptor::VFH: ran = alignWithOurCvfh(src, tgt, settings, scorer, result); break;
  }
  if (!ran) return finish();

  // Stage 3: score on the downsampled clouds with points that have normals (GASD: all points;
  // the ones counted in source_points / target_points), independent of the matcher's own error.
  scorer(result.T_target_source, result);
  if (result.converged && !result.T_target_source.allFinite()) {
    result.converged = false;
    result.message = "the matcher returned a non-finite transform";
  }
  return finish();
}

}  // namespace scanalign

// Named by scanalign::pcl's interface link option (CMakeLists.txt): every program that links
// scanalign::pcl takes this file, whose pclFeatureAlignment replaces the core's weak fallback
// (feature_alignment_unlinked.cpp) even where only the core's estimatePose refers to it.
extern "C" void scanalign_link_pcl_feature_alignment() {}
