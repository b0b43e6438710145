// Stock PCL 1.13 global registration baselines (Kleppe, PhD thesis, NTNU 2018, Paper 5 §IV-A): FPFH,
// SHOT and 3D shape context matched by SampleConsensusPrerejective or SAC-IA, and Drost's
// point-pair features with PCL's hash-map voting. The only translation unit that pays for
// PCL's feature and sample-consensus templates; the header stays PCL-free.
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
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Eigenvalues>
#include <pcl/common/common.h>
#include <pcl/features/3dsc.h>
#include <pcl/features/fpfh_omp.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/features/ppf.h>
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

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool finitePositive(double v) { return std::isfinite(v) && v > 0.0; }
bool finiteNonNegative(double v) { return std::isfinite(v) && v >= 0.0; }

void validate(const PclFeatureAlignmentSettings& s) {
  const auto fail = [](const std::string& what) {
    throw std::invalid_argument("pclFeatureAlignment: " + what);
  };
  switch (s.descriptor) {
    case PclDescriptor::FPFH:
    case PclDescriptor::SHOT:
    case PclDescriptor::ShapeContext3D:
    case PclDescriptor::PPF: break;
    default: fail("unknown descriptor");
  }
  switch (s.matcher) {
    case PclMatcher::Prerejective:
    case PclMatcher::SacIA: break;
    default: fail("unknown matcher");
  }
  // The header documents the matcher as ignored for PPF, so only the local descriptors are
  // checked: PCL's SAC-IA is only instantiated (and only meaningful) for FPFH here.
  if (s.matcher == PclMatcher::SacIA && s.descriptor != PclDescriptor::FPFH && s.descriptor != PclDescriptor::PPF)
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

/// Nearest-neighbour score of T on the (downsampled) clouds, independent of which PCL
/// matcher produced T, so every baseline is scored alike.
void score(const Cloud& source, const Cloud& target, const Eigen::Matrix4d& T, double threshold,
           PclFeatureAlignmentResult& result) {
  result.fitness = 0.0;
  result.inlier_rmse = 0.0;
  if (source.empty() || target.empty()) return;
  auto tgt = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  tgt->resize(target.size());
  for (std::size_t i = 0; i < target.size(); ++i) {
    (*tgt)[i].x = target[i].x;
    (*tgt)[i].y = target[i].y;
    (*tgt)[i].z = target[i].z;
  }
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(tgt);
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  const double threshold2 = threshold * threshold;
  std::size_t inliers = 0;
  double sum2 = 0.0;
  pcl::Indices index(1);
  std::vector<float> d2(1);
  for (const auto& p : source) {
    const Eigen::Vector3d q = R * Eigen::Vector3d(p.x, p.y, p.z) + t;
    pcl::PointXYZ query(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()));
    if (tree.nearestKSearch(query, 1, index, d2) < 1) continue;
    // Recompute the distance in double: FLANN's float squared distance is coarse at mm scale.
    const auto& n = (*tgt)[static_cast<std::size_t>(index[0])];
    const double e2 = (q - Eigen::Vector3d(n.x, n.y, n.z)).squaredNorm();
    if (e2 < threshold2) {
      ++inliers;
      sum2 += e2;
    }
  }
  result.fitness = static_cast<double>(inliers) / static_cast<double>(source.size());
  result.inlier_rmse = inliers > 0 ? std::sqrt(sum2 / static_cast<double>(inliers)) : 0.0;
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
  src = estimateNormals(src, settings);
  tgt = estimateNormals(tgt, settings);
  result.source_points = src->size();
  result.target_points = tgt->size();
  result.feature_seconds = secondsSince(t_features);

  const std::size_t min_points = settings.descriptor == PclDescriptor::PPF ? 2 : static_cast<std::size_t>(settings.num_samples);
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
  bool ran = false;
  switch (settings.descriptor) {
    case PclDescriptor::FPFH: ran = alignWithDescriptors<pcl::FPFHSignature33>(src, tgt, settings, result); break;
    case PclDescriptor::SHOT: ran = alignWithDescriptors<pcl::SHOT352>(src, tgt, settings, result); break;
    case PclDescriptor::ShapeContext3D:
      ran = alignWithDescriptors<pcl::ShapeContext1980>(src, tgt, settings, result);
      break;
    case PclDescriptor::PPF: ran = alignWithPpf(src, tgt, settings, result); break;
  }
  if (!ran) return finish();

  // Stage 3: score on the downsampled clouds with points that have normals (the ones
  // counted in source_points / target_points), independent of the matcher's own error.
  score(*src, *tgt, result.T_target_source, settings.inlier_threshold, result);
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
