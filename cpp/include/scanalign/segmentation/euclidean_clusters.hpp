// Euclidean clustering: the objects left on a table once its plane is removed (Kleppe, PhD
// thesis, NTNU 2018, paper 3 §3.1.3; the clusters of PCL's EuclideanClusterExtraction).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// Euclidean clustering of points[indices]: the connected components of the graph linking
/// points with |p - q| <= tolerance (the clusters of PCL's region growing), by union-find
/// over cells of edge just under tolerance / sqrt(3) (euclidean_clusters.cpp): O(N log N) whatever
/// the tolerance. Non-finite points and repeated indices are ignored. Returns clusters of
/// input indices (ascending), ordered by decreasing size (ties: smallest first index),
/// sizes within [min, max]. Throws std::invalid_argument for a tolerance that is not
/// finite and > 0 or an index out of range, and Interrupted (common/interrupt.hpp) when the
/// interrupt hook asks to stop.
template <typename Scalar>
std::vector<std::vector<std::uint32_t>> euclideanClusters(const CloudView<Scalar>& points,
                                                          const std::vector<std::uint32_t>& indices,
                                                          double tolerance, std::size_t min_size,
                                                          std::size_t max_size);

}  // namespace scanalign
