// The synthetic scene: objects (meshes placed on a table) and the table itself composited into
// one mesh in the base frame for the depth renderer, and the colour image of a rendering
// under a distant light. Behind scanalign.synthetic.Scene.
//
// The combined mesh: each object's mesh moved into the base frame by T_base_object, its faces
// in the Morton (Z-curve) order of their centroids and its used vertices in order of first
// use by those faces (neighbouring faces end up close in memory, which cuts the renderer's
// cache misses on meshes stored in random order; unused vertices are dropped), objects in
// the order given; then the table, a rectangle of two triangles with normal +z.
//
// The colour image: two-sided Lambertian shading plus ambient light, c = albedo (ambient +
// (1 - ambient) |n . l|) per face (Lambert, "Photometria", 1760; the "two-sided" |n . l|
// lights a face seen from its back as its front), stored as uint8 by round(255 c); the
// table's albedo alternates between its two checker colours by the parity of the checker
// square of the point hit (in base-frame x, y from the table centre); black where nothing
// is hit.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/reconstruction/depth_image.hpp"

namespace scanalign {

/// An object of the scene: a mesh in its own frame (m) placed by T_base_object.
struct SceneObjectMesh {
  CloudView<double> vertices;          ///< object frame, m
  const std::int64_t* faces = nullptr;  ///< 3 vertex indices a face
  std::size_t n_faces = 0;
  Eigen::Matrix4d T_base_object = Eigen::Matrix4d::Identity();  ///< object -> base
  Eigen::Vector3d albedo = Eigen::Vector3d::Constant(0.5);        ///< linear RGB in [0, 1]
};

/// The table: the rectangle |x - center_x| <= size_x / 2, |y - center_y| <= size_y / 2 at
/// z = height in the base frame (m), with a checker pattern of squares `checker_size` (m)
/// in two albedos, the first at the squares of even parity (the one at the centre's corner).
struct SceneTable {
  Eigen::Vector2d size = Eigen::Vector2d(0.6, 0.6);
  Eigen::Vector2d center = Eigen::Vector2d(0.5, 0.0);
  double height = 0.0;
  double checker_size = 0.05;
  std::array<Eigen::Vector3d, 2> checker_colors = {Eigen::Vector3d(0.80, 0.78, 0.72),
                                                   Eigen::Vector3d(0.45, 0.43, 0.40)};
};

/// The combined mesh of a scene (base frame, m).
struct SceneMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::int32_t> faces;        ///< 3 per face: objects' faces first, then the table's two
  std::vector<std::int32_t> face_object;  ///< per face: its object's index, -1 for the table
  std::vector<std::int64_t> face_source;  ///< per face: its row in its object's mesh (the table: 0, 1)
  std::vector<Eigen::Vector3d> albedo;    ///< per face: the object's albedo, the table's first checker colour
  std::vector<Eigen::Vector3d> normals;   ///< per face: unit right-hand normal (0 for a zero-area face)
  std::size_t object_faces = 0;           ///< faces of the objects (the table's follow)
  std::size_t faceCount() const { return face_object.size(); }
};

/// The scene's combined mesh (see the top of this file); `table` may be null (no table).
/// Throws std::invalid_argument naming the object for a face index out of range, a non-finite
/// T_base_object, or a combined mesh beyond 2^31 - 1 vertices or faces (int32 indices).
SceneMesh composeScene(const std::vector<SceneObjectMesh>& objects, const SceneTable* table);

/// Per-face colours of a scene under a distant light: 3 uint8 a face plus a last, black row
/// (the background), face f's colour at rows 3 f .. 3 f + 2.
struct SceneColors {
  std::vector<std::uint8_t> albedo;     ///< each face in its albedo
  std::vector<std::uint8_t> alternate;  ///< the table's faces in its second checker colour, the rest as albedo
  std::size_t object_faces = 0;         ///< faces before the table's (SceneMesh::object_faces)
  std::size_t faceCount() const { return albedo.size() / 3 - 1; }
};

/// The colours of `mesh`'s faces lit from `light_direction` (towards the light, unit) with
/// `ambient` (in [0, 1]) light, the table's second checker colour from `table`. Throws
/// std::invalid_argument for a light direction that is not finite and of unit length (to
/// 1e-9), an ambient outside [0, 1], or a mesh without one normal and albedo a face.
SceneColors sceneColors(const SceneMesh& mesh, const SceneTable& table, const Eigen::Vector3d& light_direction,
                        double ambient);

/// The colour image (3 uint8 a pixel, row-major, intrinsics.height x intrinsics.width) of a
/// rendering of a scene (its face_id and depth images, renderDepth's) by a camera at
/// T_base_camera (camera -> base): the colour of the face seen, on the table (faces from
/// colors.object_faces on) the colour of the checker square of the point hit, which is the
/// depth's pinhole back-projection (depthToCloud's, so the two agree bit for bit) moved into
/// the base frame; black where face_id < 0. Throws std::invalid_argument for bad or
/// distorted intrinsics (the renderer draws pinhole images), a face id beyond the colours,
/// a non-finite T_base_camera or a bad checker size.
void shadeScene(const SceneColors& colors, const SceneTable& table, const PinholeIntrinsics& intrinsics,
                const Eigen::Matrix4d& T_base_camera, const float* depth, const std::int32_t* face_id,
                std::uint8_t* rgb);

}  // namespace scanalign
