// Exact Euclidean distance from points to a triangle mesh (its surface), for scoring a
// reconstruction against a CAD model or a ground-truth mesh.
//
// Point-to-triangle: the closest point of a triangle lies in one of its Voronoi regions
// (Ericson, Real-Time Collision Detection, Morgan Kaufmann 2005, §5.1.5): the face region,
// where it is the orthogonal projection onto the plane, or a vertex / edge region, where it
// lies on the boundary. The face region is recognised by the projection lying on the inner
// side of all three edges (signs of n . (e_k x (p - v_k)), n the triangle normal); outside
// it the closest point is the nearest of the three edge segments' closest points. This is
// Ericson's case analysis with the barycentric tests replaced by edge-normal signs, which
// stay correct for slivers: Ericson's va/vb/vc are differences of nearly equal products
// there and lose their sign to cancellation. A zero-area (degenerate) triangle is exactly
// its edges.
//
// Search: a bounding-volume hierarchy of tight axis-aligned boxes, split top-down at the
// median centroid along the longest axis of each node's centroid extent. A query descends
// nearer child first and skips every node whose box is farther than the best triangle so
// far; a box's distance bounds from below the distance of every triangle inside it, so the
// result is the exact minimum over all triangles (up to floating-point rounding).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// The nearest surface point of a mesh to a query point.
struct MeshClosestPoint {
  double squared_distance = 0.0;  ///< m^2 (NaN for a non-finite query)
  std::int64_t triangle = -1;     ///< row of `faces` holding the closest point (-1 for a non-finite query)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< closest surface point, mesh frame (m)
};

class MeshDistanceIndex {
 public:
  static constexpr int kDefaultLeafSize = 4;

  /// Builds the index. `vertices`: V points (m); `faces`: 3 * num_faces vertex indices,
  /// row-major. Vertices no face uses are ignored (they may be non-finite).
  /// Throws std::invalid_argument: num_faces == 0, an index outside [0, V), a non-finite
  /// vertex used by a face, leaf_size < 1.
  MeshDistanceIndex(const CloudView<double>& vertices, const std::int64_t* faces, std::size_t num_faces,
                    int leaf_size = kDefaultLeafSize);

  std::size_t numFaces() const { return triangles_.size(); }

  /// Nearest surface point of `p` (mesh frame, m).
  MeshClosestPoint closest(const Eigen::Vector3d& p) const;

  /// Distances (m) of every point to the surface, written to out[0 .. points.size);
  /// NaN for points with a non-finite coordinate. OpenMP over the points
  /// (num_threads 0: OpenMP's default). Throws std::invalid_argument for num_threads < 0.
  void distances(const CloudView<double>& points, double* out, int num_threads = 0) const;

  /// closest() for every point; `triangles` and `closest_points` (3 per point) may be null.
  void closestPoints(const CloudView<double>& points, double* distances, std::int64_t* triangles,
                     double* closest_points, int num_threads = 0) const;

 private:
  /// A triangle in leaf order: its corners, normal (not normalised) and input row.
  struct Triangle {
    Eigen::Vector3d a, b, c, n;
    double nn;        ///< |n|^2; 0 marks a degenerate triangle (handled as its edges)
    std::int64_t id;  ///< row in the input faces
  };
  /// Internal node: children at index + 1 and `second`; leaf: triangles [first, first + count).
  struct Node {
    Eigen::Vector3d lo, hi;
    std::uint32_t first_or_second = 0;
    std::uint32_t count = 0;  ///< 0 for an internal node
  };

  std::uint32_t build(std::vector<std::uint32_t>& order, std::uint32_t begin, std::uint32_t end,
                      const std::vector<Eigen::Vector3d>& centroid, const std::vector<Triangle>& input);
  static double boxSquaredDistance(const Node& node, const Eigen::Vector3d& p);

  std::vector<Triangle> triangles_;
  std::vector<Node> nodes_;
  int leaf_size_;
};

/// Squared distance from p to triangle (a, b, c) with normal n = (b - a) x (c - a) and nn =
/// |n|^2 (0: degenerate); `closest` receives the nearest point. See the file comment.
double pointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, const Eigen::Vector3d& n, double nn,
                                    Eigen::Vector3d& closest);

}  // namespace scanalign
