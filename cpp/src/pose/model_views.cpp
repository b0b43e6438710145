// Model views for CAD pose. See model_views.hpp.
#include "scanalign/pose/model_views.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "scanalign/common/rigid.hpp"
#include "scanalign/common/threads.hpp"
#include "scanalign/features/normals.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"
#include "scanalign/registration/kdtree.hpp"

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

namespace {

/// Validates the settings every model's views share and refuses views that could need more
/// than max_memory_bytes (`points_per_view`: the most points one view can hold).
void checkViewSettings(const ModelViewSettings& s, double points_per_view) {
  viewIntrinsics(s.resolution, s.view_angle);  // validates resolution and view_angle
  if (s.level < 0 || s.level > 6) throw std::invalid_argument("level must be in [0, 6], got " + std::to_string(s.level));
  if (!(s.max_memory_bytes > 0)) throw std::invalid_argument("max_memory_bytes must be > 0");
  // Refuse before allocating: every view may hold points_per_view points.
  const double n_views = 10.0 * std::pow(4.0, s.level) + 2.0;
  const double need = n_views * points_per_view * kModelViewBytesPerPixel;
  if (need > s.max_memory_bytes)
    throw std::invalid_argument("model views: " + std::to_string(static_cast<long long>(n_views)) + " views of up to " +
                                std::to_string(static_cast<long long>(points_per_view)) + " points may need " +
                                std::to_string(static_cast<long long>(need / (1 << 20))) +
                                " MiB, more than max_memory_bytes (" +
                                std::to_string(static_cast<long long>(s.max_memory_bytes / (1 << 20))) +
                                " MiB); lower resolution or level, or raise max_memory_bytes");
}

/// The cameras' common target and distance: the settings' centre (default the bounding box's)
/// and the distance at which the bounding sphere fills 90 % of the field of view (or the
/// settings' distance, which must clear the model).
std::pair<Eigen::Vector3d, double> viewRig(const CloudView<double>& V, const ModelViewSettings& s, const char* what) {
  Eigen::Vector3d lo = V[0], hi = V[0];
  for (std::size_t i = 1; i < V.size; ++i) {
    lo = lo.cwiseMin(V[i]);
    hi = hi.cwiseMax(V[i]);
  }
  const Eigen::Vector3d c = s.center ? *s.center : Eigen::Vector3d(0.5 * (lo + hi));
  if (!c.allFinite()) throw std::invalid_argument("center: expected 3 finite coordinates (m)");
  double radius = 0;
  for (std::size_t i = 0; i < V.size; ++i) radius = std::max(radius, (V[i] - c).norm());
  if (!(radius > 0)) throw std::invalid_argument(std::string(what) + ": all points coincide");
  const double distance = s.distance == 0.0 ? radius / std::sin(0.5 * 0.9 * s.view_angle) : s.distance;
  if (!(std::isfinite(distance) && distance > radius))
    throw std::invalid_argument("distance must be finite and larger than the model's bounding radius " +
                                std::to_string(radius) + " m, got " + std::to_string(s.distance));
  return {c, distance};
}

/// The camera on the tessellated sphere's vertex d: camera -> model.
Eigen::Matrix4d viewCamera(const Eigen::Vector3d& c, double distance, const Eigen::Vector3d& d) {
  const Eigen::Vector3d up = std::abs(d.z()) < 0.99 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY();
  return lookAt(c + distance * d, c, up);
}

}  // namespace

std::vector<ModelView> renderModelViews(const CloudView<double>& V, const std::int32_t* faces, std::size_t n_faces,
                                        const ModelViewSettings& s) {
  checkMesh(V, faces, n_faces);
  const PinholeIntrinsics K = viewIntrinsics(s.resolution, s.view_angle);
  checkViewSettings(s, double(s.resolution) * double(s.resolution));
  const auto [c, distance] = viewRig(V, s, "mesh");
  const std::vector<Eigen::Vector3d> normals = faceNormals(V, faces, n_faces);
  const std::vector<std::int32_t> face_list(faces, faces + 3 * n_faces);
  DepthRenderSettings rs;
  rs.near_clip = 1e-3 * distance;
  rs.num_threads = s.num_threads;
  std::vector<ModelView> views;
  for (const Eigen::Vector3d& d : tessellatedSphere(s.level).vertices) {
    const Eigen::Matrix4d T_model_camera = viewCamera(c, distance, d);
    const DepthImage img = renderDepth(V, face_list, K, rigidInverse(T_model_camera), rs);
    views.push_back(backProject(img, K, T_model_camera, normals));
  }
  return views;
}

namespace {

/// The median distance from a point to its nearest other point (up to 1000 points sampled), m.
double medianSpacing(const std::vector<Eigen::Vector3d>& P, double extent) {
  std::vector<double> xyz;
  xyz.reserve(3 * P.size());
  for (const auto& p : P) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  const CloudView<double> cloud(xyz.data(), P.size());
  const LeftBalancedKdTree<double> tree(cloud);
  std::vector<double> nearest;
  const std::size_t step = std::max<std::size_t>(1, P.size() / 1000);
  for (std::size_t i = 0; i < P.size(); i += step) {
    double best = std::numeric_limits<double>::infinity();
    for (double r = 1e-3 * extent; !std::isfinite(best) && r <= 2 * extent; r *= 2)
      tree.forEachInRadius(cloud.ptr(i), r * r, [&](std::uint32_t, double d2) {
        if (d2 > 0) best = std::min(best, d2);
      });
    if (std::isfinite(best)) nearest.push_back(std::sqrt(best));
  }
  if (nearest.empty()) return 1e-3 * extent;
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  return nearest[nearest.size() / 2];
}

/// One camera's view of the cloud: splat every point into a depth buffer, keep those at most
/// `tolerance` behind it, turn their normals towards the camera.
ModelView splatView(const std::vector<Eigen::Vector3d>& P, const std::vector<Eigen::Vector3d>& N,
                    const Eigen::Matrix4d& T_model_camera, const PinholeIntrinsics& K, double splat, double tolerance) {
  ModelView v;
  v.T_model_camera = T_model_camera;
  v.intrinsics = K;
  const Eigen::Matrix3d R = T_model_camera.topLeftCorner<3, 3>();
  const Eigen::Vector3d eye = T_model_camera.topRightCorner<3, 1>();
  const int W = K.width, H = K.height;
  std::vector<double> depth(static_cast<std::size_t>(W) * H, std::numeric_limits<double>::infinity());
  std::vector<Eigen::Vector3d> pc(P.size());
  for (std::size_t i = 0; i < P.size(); ++i) {
    pc[i] = R.transpose() * (P[i] - eye);
    const double z = pc[i].z();
    if (!(z > 0)) continue;
    // A surfel: the disc lies in the point's tangent plane n . (X - p) = 0, so its depth at a
    // pixel is where that pixel's ray meets the plane (a disc at constant depth would hide the
    // rest of a sloped surface); at grazing angles the offset is capped at the splat radius.
    const Eigen::Vector3d n = R.transpose() * N[i];
    const double np = n.dot(pc[i]);
    const double u = K.fx * pc[i].x() / z + K.cx, w = K.fy * pc[i].y() / z + K.cy;
    // pixels: at least 0.75, so that a point covers the centre of its own pixel (0.71 away at most);
    // at most 32 (a point next to the camera)
    const double r = std::clamp(splat * K.fx / z, 0.75, 32.0);
    const double reach = r * z / K.fx;  // the disc's radius in metres
    const int c0 = std::max(0, int(std::ceil(u - r))), c1 = std::min(W - 1, int(std::floor(u + r)));
    const int r0 = std::max(0, int(std::ceil(w - r))), r1 = std::min(H - 1, int(std::floor(w + r)));
    for (int row = r0; row <= r1; ++row)
      for (int col = c0; col <= c1; ++col)
        if ((col - u) * (col - u) + (row - w) * (row - w) <= r * r) {
          const Eigen::Vector3d ray((col - K.cx) / K.fx, (row - K.cy) / K.fy, 1.0);
          const double nr = n.dot(ray);
          const double zp = std::abs(nr) > 1e-9 ? np / nr : z;
          double& d = depth[static_cast<std::size_t>(row) * W + col];
          d = std::min(d, std::clamp(zp, z - reach, z + reach));
        }
  }
  // Close one-pixel holes (random sampling leaves pixels of a surface that no disc reaches) where
  // a surface lies on both sides of the pixel, along a row, a column or a diagonal: the nearer of
  // the two depths stands for it. An edge has the surface on one side only, so edges stay sharp.
  const std::vector<double> splatted = depth;
  for (int row = 1; row + 1 < H; ++row)
    for (int col = 1; col + 1 < W; ++col) {
      const auto at = [&](int r, int c) { return splatted[static_cast<std::size_t>(r) * W + c]; };
      double& d = depth[static_cast<std::size_t>(row) * W + col];
      for (const auto& [dr, dc] : {std::pair{0, 1}, std::pair{1, 0}, std::pair{1, 1}, std::pair{1, -1}})
        d = std::min(d, std::max(at(row - dr, col - dc), at(row + dr, col + dc)));
    }
  // Of the visible points in each pixel, the one that projects nearest its centre (where a mesh
  // view's ray samples the surface): a view as dense as a mesh's at this resolution, however
  // dense the cloud.
  constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> nearest(depth.size(), kNone);
  std::vector<double> offset(depth.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < P.size(); ++i) {
    const double z = pc[i].z();
    if (!(z > 0)) continue;
    const double u = K.fx * pc[i].x() / z + K.cx, w = K.fy * pc[i].y() / z + K.cy;
    const int col = int(std::lround(u)), row = int(std::lround(w));
    if (col < 0 || col >= W || row < 0 || row >= H) continue;
    const std::size_t pixel = static_cast<std::size_t>(row) * W + col;
    // Hidden when behind the surface by more than the tolerance (default: the disc's radius,
    // the depth a surface sloped at 45 degrees spans across it).
    const double tol = tolerance > 0 ? tolerance : 2 * std::max(splat, 0.75 * z / K.fx);
    if (z > depth[pixel] + tol) continue;
    const double off = (u - col) * (u - col) + (w - row) * (w - row);
    if (off < offset[pixel]) {
      offset[pixel] = off;
      nearest[pixel] = i;
    }
  }
  for (std::size_t pixel = 0; pixel < nearest.size(); ++pixel) {
    const std::size_t i = nearest[pixel];
    if (i == kNone) continue;
    const Eigen::Vector3d n = N[i].dot(eye - P[i]) < 0 ? Eigen::Vector3d(-N[i]) : N[i];
    v.points.insert(v.points.end(), {P[i].x(), P[i].y(), P[i].z()});
    v.normals.insert(v.normals.end(), {n.x(), n.y(), n.z()});
    v.face_id.push_back(-1);
    v.pixels.insert(v.pixels.end(), {static_cast<std::int32_t>(pixel % W), static_cast<std::int32_t>(pixel / W)});
  }
  return v;
}

/// The cloud's points and unit normals (given, or estimated; points without one dropped).
void cloudWithNormals(const CloudView<double>& points, const CloudView<double>& normals, double normal_radius,
                      int num_threads, std::vector<Eigen::Vector3d>& P, std::vector<Eigen::Vector3d>& N) {
  std::vector<double> estimated;
  CloudView<double> nv = normals;
  if (normals.empty()) {
    NormalEstimationSettings ns;
    ns.radius = normal_radius;
    ns.num_threads = num_threads;
    estimated.resize(3 * points.size);
    estimateNormals(points, ns, estimated.data());
    nv = CloudView<double>(estimated.data(), points.size);
  }
  for (std::size_t i = 0; i < points.size; ++i) {
    const Eigen::Vector3d n = nv[i];
    if (!normals.empty() && !(n.allFinite() && n.norm() > 0))
      throw std::invalid_argument("model cloud: normal " + std::to_string(i) + " is not a finite non-zero vector");
    if (!n.allFinite()) continue;  // estimated: too few neighbours within normal_radius
    P.push_back(points[i]);
    N.push_back(n.normalized());
  }
  if (P.size() < 3)
    throw std::invalid_argument("model cloud: fewer than 3 points have a normal (" + std::to_string(P.size()) +
                                "); raise views.cloud.normal_radius (" + std::to_string(normal_radius) +
                                " m) to the cloud's point spacing or more, or give normals");
}

}  // namespace

std::vector<ModelView> cloudModelViews(const CloudView<double>& points, const CloudView<double>& normals,
                                       const ModelViewSettings& s) {
  if (points.size < 3) throw std::invalid_argument("model cloud: need at least 3 points, got " + std::to_string(points.size));
  for (std::size_t i = 0; i < points.size; ++i)
    if (!points.isFinite(i)) throw std::invalid_argument("model cloud: non-finite coordinates at point " + std::to_string(i));
  if (!normals.empty() && normals.size != points.size)
    throw std::invalid_argument("model cloud: " + std::to_string(normals.size) + " normals for " +
                                std::to_string(points.size) + " points");
  const CloudModelSettings& cs = s.cloud;
  if (!(cs.normal_radius > 0) || !std::isfinite(cs.normal_radius))
    throw std::invalid_argument("cloud.normal_radius must be a finite positive distance in metres");
  if (!(cs.splat_radius >= 0) || !std::isfinite(cs.splat_radius))
    throw std::invalid_argument("cloud.splat_radius must be finite and >= 0 metres (0: automatic)");
  if (!(cs.depth_tolerance >= 0) || !std::isfinite(cs.depth_tolerance))
    throw std::invalid_argument("cloud.depth_tolerance must be finite and >= 0 metres (0: the splat radius)");
  const PinholeIntrinsics K = viewIntrinsics(s.resolution, s.view_angle);
  checkViewSettings(s, std::min(double(points.size), double(s.resolution) * double(s.resolution)));
  const auto [c, distance] = viewRig(points, s, "model cloud");
  std::vector<Eigen::Vector3d> P, N;
  cloudWithNormals(points, normals, cs.normal_radius, s.num_threads, P, N);
  const double splat = cs.splat_radius > 0 ? cs.splat_radius : 1.5 * medianSpacing(P, distance);
  const double tolerance = cs.depth_tolerance;  // 0: per point, the disc's radius
  const std::vector<Eigen::Vector3d> dirs = tessellatedSphere(s.level).vertices;
  std::vector<ModelView> views(dirs.size());
  const int threads = resolveThreads(s.num_threads);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int k = 0; k < static_cast<int>(dirs.size()); ++k)
    views[static_cast<std::size_t>(k)] = splatView(P, N, viewCamera(c, distance, dirs[static_cast<std::size_t>(k)]), K,
                                                   splat, tolerance);
  return views;
}

bool isCloudModel(const std::vector<ModelView>& views) {
  bool any = false;
  for (const ModelView& v : views)
    for (const std::int32_t f : v.face_id) {
      if (f >= 0) return false;
      any = true;
    }
  return any;
}

}  // namespace scanalign
