// Exact point-to-mesh distance through a bounding-volume hierarchy; see mesh_distance.hpp.
#include "scanalign/evaluation/mesh_distance.hpp"
#include "scanalign/common/threads.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace scanalign {

namespace {

/// Nearest point of segment [a, a + e] to p (a zero-length segment is its end point).
double segmentSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& e,
                              Eigen::Vector3d& closest) {
  const double ee = e.squaredNorm();
  const double t = ee > 0.0 ? std::clamp((p - a).dot(e) / ee, 0.0, 1.0) : 0.0;
  closest = a + t * e;
  return (p - closest).squaredNorm();
}

// A sine of the angle at vertex a below 1e-12 makes the triangle a sliver whose width is
// under 1e-12 of its edges: it is handled as its edges, which moves no distance by more
// than that, instead of trusting a normal computed from rounding noise.
constexpr double kDegenerateSin2 = 1e-24;

// Longest tree over median splits: ceil(log2(2^32)) + 1 levels, one pending sibling each.
constexpr int kMaxStack = 64;

}  // namespace

double pointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, const Eigen::Vector3d& n, double nn,
                                    Eigen::Vector3d& closest) {
  const Eigen::Vector3d ab = b - a, bc = c - b, ca = a - c;
  if (nn > 0.0) {
    const Eigen::Vector3d pa = p - a, pb = p - b, pc = p - c;
    // Face region: the projection is on the inner side of every edge.
    if (n.dot(ab.cross(pa)) >= 0.0 && n.dot(bc.cross(pb)) >= 0.0 && n.dot(ca.cross(pc)) >= 0.0) {
      const double h = n.dot(pa);
      closest = p - (h / nn) * n;
      return h * h / nn;
    }
  }
  // Vertex and edge regions: the closest point is on the boundary.
  Eigen::Vector3d q;
  double best = segmentSquaredDistance(p, a, ab, closest);
  double d2 = segmentSquaredDistance(p, b, bc, q);
  if (d2 < best) best = d2, closest = q;
  d2 = segmentSquaredDistance(p, c, ca, q);
  if (d2 < best) best = d2, closest = q;
  return best;
}

MeshDistanceIndex::MeshDistanceIndex(const CloudView<double>& vertices, const std::int64_t* faces,
                                     std::size_t num_faces, int leaf_size)
    : leaf_size_(leaf_size) {
  if (leaf_size < 1) throw std::invalid_argument("leaf_size must be >= 1, got " + std::to_string(leaf_size));
  if (num_faces == 0) throw std::invalid_argument("faces: the mesh has no triangles");
  if (num_faces >= (std::size_t{1} << 31)) throw std::invalid_argument("faces: more than 2^31 triangles");
  const auto nv = static_cast<std::int64_t>(vertices.size);
  std::vector<Triangle> input(num_faces);
  std::vector<Eigen::Vector3d> centroid(num_faces);
  for (std::size_t f = 0; f < num_faces; ++f) {
    Eigen::Vector3d corner[3];
    for (int k = 0; k < 3; ++k) {
      const std::int64_t v = faces[3 * f + k];
      if (v < 0 || v >= nv)
        throw std::invalid_argument("faces: vertex indices must lie in [0, " + std::to_string(nv) + "), row " +
                                    std::to_string(f) + " has " + std::to_string(v));
      if (!vertices.isFinite(static_cast<std::size_t>(v)))
        throw std::invalid_argument("vertices: vertex " + std::to_string(v) + ", used by face " + std::to_string(f) +
                                    ", is not finite");
      corner[k] = vertices[static_cast<std::size_t>(v)];
    }
    Triangle& t = input[f];
    t.a = corner[0], t.b = corner[1], t.c = corner[2];
    const Eigen::Vector3d ab = t.b - t.a, ac = t.c - t.a;
    t.n = ab.cross(ac);
    t.nn = t.n.squaredNorm();
    if (!(t.nn > kDegenerateSin2 * ab.squaredNorm() * ac.squaredNorm())) t.nn = 0.0;
    t.id = static_cast<std::int64_t>(f);
    centroid[f] = (t.a + t.b + t.c) / 3.0;
  }
  std::vector<std::uint32_t> order(num_faces);
  std::iota(order.begin(), order.end(), 0u);
  nodes_.reserve(2 * num_faces / static_cast<std::size_t>(leaf_size) + 2);
  build(order, 0, static_cast<std::uint32_t>(num_faces), centroid, input);
  triangles_.resize(num_faces);
  for (std::size_t i = 0; i < num_faces; ++i) triangles_[i] = input[order[i]];
}

std::uint32_t MeshDistanceIndex::build(std::vector<std::uint32_t>& order, std::uint32_t begin, std::uint32_t end,
                                       const std::vector<Eigen::Vector3d>& centroid,
                                       const std::vector<Triangle>& input) {
  const auto index = static_cast<std::uint32_t>(nodes_.size());
  nodes_.emplace_back();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  Eigen::Vector3d clo = lo, chi = hi;
  for (std::uint32_t i = begin; i < end; ++i) {
    const Triangle& t = input[order[i]];
    lo = lo.cwiseMin(t.a).cwiseMin(t.b).cwiseMin(t.c);
    hi = hi.cwiseMax(t.a).cwiseMax(t.b).cwiseMax(t.c);
    clo = clo.cwiseMin(centroid[order[i]]);
    chi = chi.cwiseMax(centroid[order[i]]);
  }
  nodes_[index].lo = lo;
  nodes_[index].hi = hi;
  if (end - begin <= static_cast<std::uint32_t>(leaf_size_)) {
    nodes_[index].first_or_second = begin;
    nodes_[index].count = end - begin;
    return index;
  }
  int axis;
  (chi - clo).maxCoeff(&axis);
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                   [&](std::uint32_t x, std::uint32_t y) { return centroid[x][axis] < centroid[y][axis]; });
  build(order, begin, mid, centroid, input);  // lands at index + 1
  const std::uint32_t second = build(order, mid, end, centroid, input);
  nodes_[index].first_or_second = second;
  return index;
}

double MeshDistanceIndex::boxSquaredDistance(const Node& node, const Eigen::Vector3d& p) {
  const Eigen::Vector3d d = (node.lo - p).cwiseMax(p - node.hi).cwiseMax(0.0);
  return d.squaredNorm();
}

MeshClosestPoint MeshDistanceIndex::closest(const Eigen::Vector3d& p) const {
  MeshClosestPoint best;
  if (!p.allFinite()) {
    best.squared_distance = std::numeric_limits<double>::quiet_NaN();
    best.point.setConstant(std::numeric_limits<double>::quiet_NaN());
    return best;
  }
  best.squared_distance = std::numeric_limits<double>::infinity();
  std::uint32_t stack[kMaxStack];
  double stack_d2[kMaxStack];
  int top = 0;
  stack[top] = 0;
  stack_d2[top++] = boxSquaredDistance(nodes_[0], p);
  Eigen::Vector3d q;
  while (top > 0) {
    --top;
    if (stack_d2[top] > best.squared_distance) continue;  // the bound shrank since the push
    const Node& node = nodes_[stack[top]];
    if (node.count > 0) {
      for (std::uint32_t i = node.first_or_second; i < node.first_or_second + node.count; ++i) {
        const Triangle& t = triangles_[i];
        const double d2 = pointTriangleSquaredDistance(p, t.a, t.b, t.c, t.n, t.nn, q);
        if (d2 < best.squared_distance) best.squared_distance = d2, best.triangle = t.id, best.point = q;
      }
      continue;
    }
    std::uint32_t near = stack[top] + 1, far = node.first_or_second;
    double d_near = boxSquaredDistance(nodes_[near], p), d_far = boxSquaredDistance(nodes_[far], p);
    if (d_far < d_near) std::swap(near, far), std::swap(d_near, d_far);
    // The nearer child is pushed last so it is searched first and tightens the bound.
    if (d_far <= best.squared_distance) stack[top] = far, stack_d2[top++] = d_far;
    if (d_near <= best.squared_distance) stack[top] = near, stack_d2[top++] = d_near;
  }
  return best;
}

void MeshDistanceIndex::closestPoints(const CloudView<double>& points, double* distances, std::int64_t* triangles,
                                      double* closest_points, int num_threads) const {
  if (num_threads < 0) throw std::invalid_argument("num_threads must be >= 0");
  const auto n = static_cast<std::int64_t>(points.size);
#ifdef _OPENMP
  const int threads = resolveThreads(num_threads);
#endif
  // Dynamic chunks: points far from the surface visit many more nodes than near ones.
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
  for (std::int64_t i = 0; i < n; ++i) {
    const MeshClosestPoint c = closest(points[static_cast<std::size_t>(i)]);
    if (distances) distances[i] = std::sqrt(c.squared_distance);
    if (triangles) triangles[i] = c.triangle;
    if (closest_points)
      for (int k = 0; k < 3; ++k) closest_points[3 * i + k] = c.point[k];
  }
}

void MeshDistanceIndex::distances(const CloudView<double>& points, double* out, int num_threads) const {
  closestPoints(points, out, nullptr, nullptr, num_threads);
}

}  // namespace scanalign
