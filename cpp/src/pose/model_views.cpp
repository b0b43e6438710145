// Model views for CAD pose. See model_views.hpp.
#include "scanalign/pose/model_views.hpp"

#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "scanalign/common/rigid.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"

namespace scanalign {

TessellatedSphere tessellatedSphere(int level) {
  if (level < 0 || level > 6) throw std::invalid_argument("tessellatedSphere: level must be in [0, 6], got " + std::to_string(level));
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TessellatedSphere s;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(-1, t, 0), Eigen::Vector3d(1, t, 0), Eigen::Vector3d(-1, -t, 0),
                                   Eigen::Vector3d(1, -t, 0), Eigen::Vector3d(0, -1, t), Eigen::Vector3d(0, 1, t),
                                   Eigen::Vector3d(0, -1, -t), Eigen::Vector3d(0, 1, -t), Eigen::Vector3d(t, 0, -1),
                                   Eigen::Vector3d(t, 0, 1), Eigen::Vector3d(-t, 0, -1), Eigen::Vector3d(-t, 0, 1)})
    s.vertices.push_back(p.normalized());
  s.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  // Each subdivision splits a triangle into four at its edge midpoints, shared between the
  // two faces of an edge, so vertex numbering is deterministic (views are referred to by index).
  for (int k = 0; k < level; ++k) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = a < b ? std::make_pair(a, b) : std::make_pair(b, a);
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      s.vertices.push_back((s.vertices[a] + s.vertices[b]).normalized());
      return midpoint[key] = static_cast<int>(s.vertices.size()) - 1;
    };
    std::vector<Eigen::Vector3i> faces;
    faces.reserve(4 * s.faces.size());
    for (const Eigen::Vector3i& f : s.faces) {
      const int ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
      faces.insert(faces.end(), {{f[0], ab, ca}, {f[1], bc, ab}, {f[2], ca, bc}, {ab, bc, ca}});
    }
    s.faces = std::move(faces);
  }
  return s;
}

PinholeIntrinsics viewIntrinsics(int resolution, double view_angle) {
  if (resolution < 2 || resolution > 8192)
    throw std::invalid_argument("resolution must be in [2, 8192] pixels, got " + std::to_string(resolution));
  if (!(view_angle > 0 && view_angle < M_PI))
    throw std::invalid_argument("view_angle must be in (0, pi) radians, got " + std::to_string(view_angle));
  const double f = 0.5 * resolution / std::tan(0.5 * view_angle), c = 0.5 * (resolution - 1);
  return {resolution, resolution, f, f, c, c};
}

namespace {

void checkMesh(const CloudView<double>& V, const std::int32_t* faces, std::size_t n_faces) {
  if (V.size < 3) throw std::invalid_argument("mesh vertices: need at least 3, got " + std::to_string(V.size));
  for (std::size_t i = 0; i < V.size; ++i)
    if (!V.isFinite(i)) throw std::invalid_argument("mesh vertices: non-finite coordinates at vertex " + std::to_string(i));
  if (n_faces == 0 || faces == nullptr) throw std::invalid_argument("mesh faces: need at least one triangle");
  for (std::size_t k = 0; k < 3 * n_faces; ++k)
    if (faces[k] < 0 || static_cast<std::size_t>(faces[k]) >= V.size)
      throw std::invalid_argument("mesh faces: vertex index out of range");
  // A mesh whose every triangle is degenerate renders nothing: say so, rather than reporting
  // later that no view found a consensus.
  Eigen::Vector3d lo = V[0], hi = V[0];
  for (std::size_t i = 1; i < V.size; ++i) lo = lo.cwiseMin(V[i]), hi = hi.cwiseMax(V[i]);
  const double extent2 = (hi - lo).squaredNorm();
  bool any_area = false;
  for (std::size_t f = 0; f < n_faces && !any_area; ++f) {
    const Eigen::Vector3d a = V[faces[3 * f]], b = V[faces[3 * f + 1]], c = V[faces[3 * f + 2]];
    any_area = (b - a).cross(c - a).norm() > 1e-12 * extent2;
  }
  if (!any_area)
    throw std::invalid_argument("mesh faces: every triangle has zero area (repeated or collinear vertices)");
}

// Face normals by the right-hand rule; a degenerate triangle gets a zero normal (it is never
// the visible face of a pixel in practice).
std::vector<Eigen::Vector3d> faceNormals(const CloudView<double>& V, const std::int32_t* F, std::size_t n_faces) {
  std::vector<Eigen::Vector3d> n(n_faces);
  for (std::size_t f = 0; f < n_faces; ++f) {
    const Eigen::Vector3d a = V[F[3 * f]], b = V[F[3 * f + 1]], c = V[F[3 * f + 2]];
    const Eigen::Vector3d m = (b - a).cross(c - a);
    const double len = m.norm();
    n[f] = len > 0 ? Eigen::Vector3d(m / len) : Eigen::Vector3d::Zero();
  }
  return n;
}

ModelView backProject(const DepthImage& img, const PinholeIntrinsics& K, const Eigen::Matrix4d& T_model_camera,
                      const std::vector<Eigen::Vector3d>& face_normal) {
  ModelView v;
  v.T_model_camera = T_model_camera;
  v.intrinsics = K;
  const Eigen::Matrix3d R = T_model_camera.topLeftCorner<3, 3>();
  const Eigen::Vector3d eye = T_model_camera.topRightCorner<3, 1>();
  for (int row = 0; row < K.height; ++row)
    for (int col = 0; col < K.width; ++col) {
      const std::int32_t f = img.faceAt(col, row);
      if (f < 0) continue;
      const double z = double(img.at(col, row));
      const Eigen::Vector3d pc((col - K.cx) * z / K.fx, (row - K.cy) * z / K.fy, z);
      const Eigen::Vector3d p = R * pc + eye;
      Eigen::Vector3d n = face_normal[f];
      if (n.dot(eye - p) < 0) n = -n;  // towards the camera
      v.points.insert(v.points.end(), {p.x(), p.y(), p.z()});
      v.normals.insert(v.normals.end(), {n.x(), n.y(), n.z()});
      v.face_id.push_back(f);
      v.pixels.insert(v.pixels.end(), {col, row});
    }
  return v;
}

}  // namespace

std::vector<ModelView> renderModelViews(const CloudView<double>& V, const std::int32_t* faces, std::size_t n_faces,
                                        const ModelViewSettings& s) {
  checkMesh(V, faces, n_faces);
  const PinholeIntrinsics K = viewIntrinsics(s.resolution, s.view_angle);
  if (s.level < 0 || s.level > 6)
    throw std::invalid_argument("level must be in [0, 6], got " + std::to_string(s.level));
  if (!(s.max_memory_bytes > 0)) throw std::invalid_argument("max_memory_bytes must be > 0");
  // Refuse before allocating: every view may hold a point per pixel.
  const double n_views = 10.0 * std::pow(4.0, s.level) + 2.0;
  const double need = n_views * double(s.resolution) * double(s.resolution) * kModelViewBytesPerPixel;
  if (need > s.max_memory_bytes)
    throw std::invalid_argument("model views: " + std::to_string(static_cast<long long>(n_views)) + " views of " +
                                std::to_string(s.resolution) + "^2 pixels may need " +
                                std::to_string(static_cast<long long>(need / (1 << 20))) +
                                " MiB, more than max_memory_bytes (" +
                                std::to_string(static_cast<long long>(s.max_memory_bytes / (1 << 20))) +
                                " MiB); lower resolution or level, or raise max_memory_bytes");
  Eigen::Vector3d lo = V[0], hi = V[0];
  for (std::size_t i = 1; i < V.size; ++i) {
    lo = lo.cwiseMin(V[i]);
    hi = hi.cwiseMax(V[i]);
  }
  const Eigen::Vector3d c = s.center ? *s.center : Eigen::Vector3d(0.5 * (lo + hi));
  if (!c.allFinite()) throw std::invalid_argument("center: expected 3 finite coordinates (m)");
  double radius = 0;
  for (std::size_t i = 0; i < V.size; ++i) radius = std::max(radius, (V[i] - c).norm());
  if (!(radius > 0)) throw std::invalid_argument("mesh: all vertices coincide");
  const double distance = s.distance == 0.0 ? radius / std::sin(0.5 * 0.9 * s.view_angle) : s.distance;
  if (!(std::isfinite(distance) && distance > radius))
    throw std::invalid_argument("distance must be finite and larger than the model's bounding radius " +
                                std::to_string(radius) + " m, got " + std::to_string(s.distance));
  const std::vector<Eigen::Vector3d> normals = faceNormals(V, faces, n_faces);
  const std::vector<std::int32_t> face_list(faces, faces + 3 * n_faces);
  DepthRenderSettings rs;
  rs.near_clip = 1e-3 * distance;
  rs.num_threads = s.num_threads;
  std::vector<ModelView> views;
  for (const Eigen::Vector3d& d : tessellatedSphere(s.level).vertices) {
    const Eigen::Vector3d eye = c + distance * d;
    const Eigen::Vector3d up = std::abs(d.z()) < 0.99 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY();
    const Eigen::Matrix4d T_model_camera = lookAt(eye, c, up);
    const DepthImage img = renderDepth(V, face_list, K, rigidInverse(T_model_camera), rs);
    views.push_back(backProject(img, K, T_model_camera, normals));
  }
  return views;
}

}  // namespace scanalign
