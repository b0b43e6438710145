#include "scanalign/synthetic/scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <Eigen/Geometry>  // cross()

#include "scanalign/common/morton_order.hpp"
#include "scanalign/common/rigid.hpp"

namespace scanalign {

namespace {

constexpr std::size_t kMaxIndex = static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max());

/// Appends one object: its faces in Morton order of their centroids, its used vertices in
/// order of first use.
void appendObject(const SceneObjectMesh& object, std::int32_t index, SceneMesh& out) {
  const std::string what = "scene object " + std::to_string(index);
  const auto n_vertices = static_cast<std::int64_t>(object.vertices.size);
  if (object.n_faces > 0 && object.faces == nullptr) throw std::invalid_argument(what + ": null faces");
  for (std::size_t i = 0; i < 3 * object.n_faces; ++i)
    if (object.faces[i] < 0 || object.faces[i] >= n_vertices)
      throw std::invalid_argument(what + ": face vertex index " + std::to_string(object.faces[i]) + " outside [0, " +
                                  std::to_string(n_vertices) + ")");
  // The vertices in the base frame.
  const std::vector<double> moved = transformPoints(object.T_base_object, object.vertices, what + ": T_base_object");
  const auto vertex = [&](std::int64_t v) {
    return Eigen::Map<const Eigen::Vector3d>(moved.data() + 3 * static_cast<std::size_t>(v));
  };
  // Face centroids (a + b + c) / 3, in the order of the sum of the corners.
  std::vector<double> centroids(3 * object.n_faces);
  for (std::size_t f = 0; f < object.n_faces; ++f) {
    const std::int64_t* c = object.faces + 3 * f;
    for (int r = 0; r < 3; ++r)
      centroids[3 * f + r] = ((vertex(c[0])[r] + vertex(c[1])[r]) + vertex(c[2])[r]) / 3.0;
  }
  std::vector<std::int64_t> order;
  std::vector<std::pair<std::uint64_t, std::int64_t>> keyed;
  mortonOrder(CloudView<double>(centroids.data(), object.n_faces), order, keyed);
  // Vertices renumbered by first use in the reordered faces.
  std::vector<std::int64_t> remap(static_cast<std::size_t>(n_vertices), -1);
  const std::size_t offset = out.vertices.size();
  std::size_t used = 0;
  for (const std::int64_t f : order)
    for (int k = 0; k < 3; ++k) {
      const std::int64_t v = object.faces[3 * static_cast<std::size_t>(f) + k];
      if (remap[static_cast<std::size_t>(v)] < 0) {
        remap[static_cast<std::size_t>(v)] = static_cast<std::int64_t>(used++);
        out.vertices.emplace_back(vertex(v));
      }
    }
  if (out.vertices.size() > kMaxIndex || out.face_object.size() + object.n_faces > kMaxIndex)
    throw std::invalid_argument(what + ": the scene exceeds 2^31 - 1 vertices or faces");
  for (const std::int64_t f : order) {
    for (int k = 0; k < 3; ++k)
      out.faces.push_back(static_cast<std::int32_t>(
          offset + static_cast<std::size_t>(remap[static_cast<std::size_t>(object.faces[3 * f + k])])));
    out.face_object.push_back(index);
    out.face_source.push_back(f);
    out.albedo.push_back(object.albedo);
  }
}

/// round(255 c) of a colour in [0, 1] (clipped), as uint8.
std::uint8_t toByte(double c) { return static_cast<std::uint8_t>(std::min(std::max(c * 255.0 + 0.5, 0.0), 255.0)); }

}  // namespace

SceneMesh composeScene(const std::vector<SceneObjectMesh>& objects, const SceneTable* table) {
  SceneMesh out;
  for (std::size_t k = 0; k < objects.size(); ++k) {
    if (k > kMaxIndex) throw std::invalid_argument("scene: more than 2^31 - 1 objects");
    appendObject(objects[k], static_cast<std::int32_t>(k), out);
  }
  out.object_faces = out.face_object.size();
  if (table) {
    if (!(table->size.allFinite() && table->center.allFinite() && std::isfinite(table->height)))
      throw std::invalid_argument("scene table: size, center and height must be finite");
    if (out.vertices.size() + 4 > kMaxIndex) throw std::invalid_argument("scene: beyond 2^31 - 1 vertices");
    const auto offset = static_cast<std::int32_t>(out.vertices.size());
    // Counter-clockwise seen from above: normal +z.
    constexpr int corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (const auto& c : corners)
      out.vertices.emplace_back(table->center.x() + c[0] * table->size.x() / 2,
                                table->center.y() + c[1] * table->size.y() / 2, table->height);
    for (const int i : {0, 1, 2, 0, 2, 3}) out.faces.push_back(offset + i);
    for (std::int64_t f = 0; f < 2; ++f) {
      out.face_object.push_back(-1);
      out.face_source.push_back(f);
      out.albedo.push_back(table->checker_colors[0]);
    }
  }
  // Unit right-hand normals (zero for zero-area faces).
  out.normals.resize(out.faceCount());
  for (std::size_t f = 0; f < out.faceCount(); ++f) {
    const Eigen::Vector3d& a = out.vertices[static_cast<std::size_t>(out.faces[3 * f])];
    const Eigen::Vector3d& b = out.vertices[static_cast<std::size_t>(out.faces[3 * f + 1])];
    const Eigen::Vector3d& c = out.vertices[static_cast<std::size_t>(out.faces[3 * f + 2])];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double norm = std::sqrt((n.x() * n.x() + n.y() * n.y()) + n.z() * n.z());
    out.normals[f] = norm > 0.0 ? Eigen::Vector3d(n / norm) : Eigen::Vector3d::Zero();
  }
  return out;
}

SceneColors sceneColors(const SceneMesh& mesh, const SceneTable& table, const Eigen::Vector3d& light_direction,
                        double ambient) {
  if (!(light_direction.allFinite() && std::abs(light_direction.norm() - 1.0) <= 1e-9))
    throw std::invalid_argument("scene shading: light_direction must be a finite unit vector");
  if (!(ambient >= 0.0 && ambient <= 1.0)) throw std::invalid_argument("scene shading: ambient must be in [0, 1]");
  const std::size_t n = mesh.faceCount();
  if (mesh.normals.size() != n || mesh.albedo.size() != n)
    throw std::invalid_argument("scene shading: normals and albedo must have one row per face");
  SceneColors out;
  out.object_faces = mesh.object_faces;
  out.albedo.assign(3 * (n + 1), 0);  // the last row: the background, black
  out.alternate.assign(3 * (n + 1), 0);
  for (std::size_t f = 0; f < n; ++f) {
    const Eigen::Vector3d& m = mesh.normals[f];
    const double lambert = std::abs((m.x() * light_direction.x() + m.y() * light_direction.y()) +
                                    m.z() * light_direction.z());  // two-sided
    const double intensity = ambient + (1.0 - ambient) * lambert;
    const Eigen::Vector3d& alt = mesh.face_object[f] < 0 ? table.checker_colors[1] : mesh.albedo[f];
    for (int c = 0; c < 3; ++c) {
      out.albedo[3 * f + c] = toByte(mesh.albedo[f][c] * intensity);
      out.alternate[3 * f + c] = toByte(alt[c] * intensity);
    }
  }
  return out;
}

void shadeScene(const SceneColors& colors, const SceneTable& table, const PinholeIntrinsics& intrinsics,
                const Eigen::Matrix4d& T_base_camera, const float* depth, const std::int32_t* face_id,
                std::uint8_t* rgb) {
  intrinsics.validate();
  if (!intrinsics.distortion.isZero())
    throw std::invalid_argument("scene shading: the renderer draws pinhole images; give intrinsics without distortion");
  if (!T_base_camera.allFinite()) throw std::invalid_argument("scene shading: T_base_camera must be finite");
  if (!(std::isfinite(table.checker_size) && table.checker_size > 0.0 && table.center.allFinite()))
    throw std::invalid_argument("scene shading: the table's checker_size must be > 0 and its center finite");
  if (colors.albedo.size() < 3 || colors.albedo.size() % 3 != 0 || colors.alternate.size() != colors.albedo.size() ||
      colors.object_faces > colors.faceCount())
    throw std::invalid_argument("scene shading: malformed colours (3 uint8 a face plus the background, as many "
                                "alternate ones, object_faces at most the faces)");
  const std::size_t n = colors.faceCount();
  if (depth == nullptr || face_id == nullptr || rgb == nullptr) throw std::invalid_argument("scene shading: null image");
  const std::size_t pixels = static_cast<std::size_t>(intrinsics.width) * static_cast<std::size_t>(intrinsics.height);
  // The face colours; the table's pixels keep their depth for the checker test.
  std::vector<float> table_depth(pixels, std::numeric_limits<float>::quiet_NaN());
  bool any_table = false;
  for (std::size_t i = 0; i < pixels; ++i) {
    const std::int32_t f = face_id[i];
    if (f >= 0 && static_cast<std::size_t>(f) >= n)
      throw std::invalid_argument("scene shading: face id " + std::to_string(f) + " beyond the mesh's " +
                                  std::to_string(n) + " faces");
    const std::size_t row = f < 0 ? n : static_cast<std::size_t>(f);
    std::copy(&colors.albedo[3 * row], &colors.albedo[3 * row] + 3, rgb + 3 * i);
    if (f >= 0 && row >= colors.object_faces) {
      table_depth[i] = depth[i];
      any_table = true;
    }
  }
  if (!any_table) return;
  // Checker parity of the base-frame point hit: depthToCloud's back-projection (every finite
  // depth above 0), so the point is the one a reconstruction of the image would see.
  DepthToCloudSettings s;
  s.min_depth = 0.0;
  s.max_depth = std::numeric_limits<double>::infinity();
  const DepthCloud cloud = depthToCloud(table_depth.data(), intrinsics, s);
  const Eigen::Matrix4d& T = T_base_camera;
  for (std::size_t k = 0; k < cloud.size(); ++k) {
    const double x = cloud.points[3 * k], y = cloud.points[3 * k + 1], z = cloud.points[3 * k + 2];
    double cell = 0.0;
    for (int i = 0; i < 2; ++i) {
      const double base = ((T(i, 0) * x + T(i, 1) * y) + T(i, 2) * z) + T(i, 3);
      cell += std::floor((base - table.center[i]) / table.checker_size);
    }
    const double parity = cell - 2.0 * std::floor(cell / 2.0);  // in [0, 2), as a floored modulo
    if (parity != 1.0) continue;
    const auto i = static_cast<std::size_t>(cloud.pixels[k]);
    const auto row = static_cast<std::size_t>(face_id[i]);
    std::copy(&colors.alternate[3 * row], &colors.alternate[3 * row] + 3, rgb + 3 * i);
  }
}

}  // namespace scanalign
