// Z-buffer rasteriser for synthetic depth images: what a pinhole depth camera at a known
// pose sees of a triangle mesh. Ground truth for testing the reconstruction.
//
// Conventions (OpenCV): camera x right, y down, z forward along the optical axis; pixel
// (u, v) is column u, row v, and its centre sits at image coordinates (u, v). A point
// (x, y, z) in the camera frame projects to (fx x / z + cx, fy y / z + cy). Depth is the z
// coordinate (not the ray length), in metres.
//
// How a pixel is decided:
// - Coverage: a pixel belongs to a triangle when its centre lies inside the projected
//   triangle, with a top-left fill rule for centres exactly on an edge. Edge functions are
//   evaluated in double precision with every undirected edge in one canonical direction, so
//   the two triangles sharing an edge compute exactly opposite values: no pixel of a shared
//   edge is left out or drawn twice ("watertight").
// - Depth: the pixel's ray is intersected with the triangle's plane exactly, z = d / (n . r),
//   evaluated as 1/z = (n / d) . r, which is linear in screen space (perspective-correct by
//   construction). A rendered plane back-projects onto the plane to double precision before
//   the float32 store (relative error ~1e-16, then float rounding ~3e-8).
// - Visibility: the smallest depth wins; equal depths go to the smaller face index, so the
//   image does not depend on the number of threads.
// - Near plane: triangles are clipped against z = near in the camera frame (Sutherland-
//   Hodgman, one plane): the part in front of it is drawn, the rest dropped. Triangles
//   wholly behind it are dropped. Depths beyond `far` are not drawn (nothing is hit there).
//
// Parallelisation (OpenMP): (1) vertices are transformed and projected once each; (2) faces
// are set up (cull, clip, bounding box, plane) in parallel over contiguous face ranges and
// listed in every band of 8 image rows they span; (3) bands are rasterised in parallel,
// one thread per band with a private z-buffer, so no locks and no image merges. Triangles
// wider than a few pixels are filled by row spans whose ends are settled with the same edge
// test as single pixels, so both paths make identical decisions.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/reconstruction/depth_image.hpp"

namespace scanalign {

/// Intrinsics of the rendered image, OpenCV convention: the same type depthToCloud()
/// back-projects with, so a rendered image round-trips. The renderer draws pinhole images:
/// its distortion must be zero.
using PinholeCamera = PinholeIntrinsics;

struct DepthRenderSettings {
  /// Near clipping plane z = near (m, > 0) in the camera frame: geometry closer than this
  /// is clipped away. Also bounds the projected coordinates of the clipped triangles.
  double near_clip = 1e-3;
  /// Far limit (m, > near): surface points with a larger depth are not drawn.
  double far_clip = std::numeric_limits<double>::infinity();
  /// Drop triangles seen from their back (clockwise in the image, i.e. the right-hand
  /// normal of the face winding points away from the camera). Off: both sides are drawn.
  bool cull_backfaces = false;
  /// OpenMP threads; 0 = the OpenMP default.
  int num_threads = 0;
};

/// Output buffers, row-major (H x W), owned by the caller. Any of them but `depth` may be
/// null when not wanted.
struct DepthRenderResult {
  /// Depth z (m) of the visible surface; quiet NaN where nothing is hit.
  float* depth = nullptr;
  /// Index (row of `faces`) of the visible triangle; -1 where nothing is hit.
  std::int32_t* face_id = nullptr;
  /// Cosine between the visible face's normal and the direction from the surface point to
  /// the camera, in [-1, 1]: 1 when the surface faces the camera head on, near 0 at grazing
  /// angles, negative when the back of a face is seen (normal from the right-hand rule on
  /// the face winding). 0 where nothing is hit.
  float* cos_incidence = nullptr;
};

/// Renders a triangle mesh seen by a pinhole camera.
///
/// @param vertices  mesh vertices in the world frame (m). Faces using a non-finite vertex
///                  are skipped.
/// @param faces     3 vertex indices per triangle (n_faces x 3, row-major), each in
///                  [0, vertices.size). Degenerate (zero-area) triangles draw nothing.
/// @param camera    image size and pinhole intrinsics.
/// @param T_camera_world  rigid transform mapping world coordinates into the camera frame
///                  (4x4, bottom row 0 0 0 1, rotation orthonormal to 1e-6 with det +1).
/// @throws std::invalid_argument on a face index out of range, a non-finite or non-rigid
///         transform, bad intrinsics (size not in [1, 32768] or width x height beyond
///         kMaxImagePixels = 2^27, checked before allocating; focal length not finite and
///         positive, principal point not finite; lens distortion, which a pinhole rendering
///         cannot show), bad clip planes, or null outputs.
template <typename Scalar>
void renderDepth(const CloudView<Scalar>& vertices, const std::int32_t* faces, std::size_t n_faces,
                 const PinholeCamera& camera, const Eigen::Matrix4d& T_camera_world, const DepthRenderSettings& settings,
                 const DepthRenderResult& out);

/// Owning result of the convenience overload.
struct DepthImage {
  int width = 0, height = 0;
  std::vector<float> depth;             ///< m, NaN where nothing is hit
  std::vector<std::int32_t> face_id;    ///< -1 where nothing is hit
  std::vector<float> cos_incidence;     ///< see DepthRenderResult::cos_incidence
  float at(int u, int v) const { return depth[static_cast<std::size_t>(v) * width + u]; }
  std::int32_t faceAt(int u, int v) const { return face_id[static_cast<std::size_t>(v) * width + u]; }
};

template <typename Scalar>
DepthImage renderDepth(const CloudView<Scalar>& vertices, const std::vector<std::int32_t>& faces,
                       const PinholeCamera& camera, const Eigen::Matrix4d& T_camera_world,
                       const DepthRenderSettings& settings = {});

}  // namespace scanalign
