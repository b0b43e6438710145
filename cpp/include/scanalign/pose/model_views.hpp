// The partial clouds a depth camera sees of a CAD part (Kleppe, PhD thesis, NTNU 2018, §7.3):
// virtual cameras sit on the vertices of a tessellated sphere around the model and look at
// its centre. The thesis uses the icosahedron subdivided once, whose 42 vertices give the
// 42 views of PCL's renderViewTesselatedSphere. Each view is rendered with the exact z-buffer
// of reconstruction/depth_renderer.hpp; its points are back-projected into the model frame
// and carry the normal of the triangle they lie on, oriented towards that view's camera.
//
// Units: metres and radians. T_model_camera maps camera coordinates (OpenCV axes: x right,
// y down, z along the optical axis) into the model frame.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/common/look_at.hpp"
#include "scanalign/pose/cbd.hpp"
#include "scanalign/reconstruction/depth_image.hpp"

namespace scanalign {

/// Vertices (unit sphere) and counter-clockwise faces of an icosahedron subdivided `level`
/// times: 10·4^level + 2 vertices and 20·4^level faces (level 0: 12 and 20; level 1: 42 and 80).
struct TessellatedSphere {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
};
/// @throws std::invalid_argument unless 0 <= level <= 6.
TessellatedSphere tessellatedSphere(int level = 1);

/// PCL's default field of view for renderViewTesselatedSphere: 57 degrees, in radians.
constexpr double kDefaultViewAngle = 57.0 * 3.14159265358979323846 / 180.0;

/// Square pinhole camera with field of view `view_angle` (rad) across `resolution` pixels:
/// f = (resolution / 2) / tan(view_angle / 2), principal point at the image centre.
/// @throws std::invalid_argument unless resolution in [2, 8192] and 0 < view_angle < pi.
PinholeIntrinsics viewIntrinsics(int resolution, double view_angle = kDefaultViewAngle);


struct ModelViewSettings {
  int resolution = 150;                  ///< image width and height, pixels (the thesis uses 90 to 400)
  double view_angle = kDefaultViewAngle; ///< field of view, rad
  int level = 1;                         ///< icosahedron subdivisions; 1 gives the thesis's 42 views
  /// Camera distance from `center`, m. 0 = automatic: the smallest distance at which the
  /// model's bounding sphere fills at most 90 % of the field of view from every viewpoint.
  double distance = 0.0;
  /// What the cameras look at, model frame (m); default the centre of the bounding box.
  std::optional<Eigen::Vector3d> center;
  int num_threads = 0;                   ///< rasteriser threads; 0 = all cores
  /// Refuse (std::invalid_argument, before rendering) when the views could need more memory
  /// than this, bytes: views x resolution^2 x kModelViewBytesPerPixel (every pixel a point).
  /// The default, 4 GiB, admits the thesis's 42 views up to 1200 pixels, 642 views (level 3) at
  /// 300 pixels; level 6 (40962 views) at 150 pixels would need 66 GB.
  double max_memory_bytes = 4.0 * (1ull << 30);
};

/// Upper bound of the memory one rendered pixel costs in a ModelView: a point and a normal
/// (6 doubles), its face id and pixel (3 int32), rounded up.
inline constexpr double kModelViewBytesPerPixel = 64;

/// One virtual camera's view of a model.
struct ModelView {
  std::vector<double> points;            ///< N x 3 visible surface points, model frame, m
  std::vector<double> normals;           ///< N x 3 unit normals, oriented towards the camera
  std::vector<std::int32_t> face_id;     ///< N triangle indices into the mesh (-1: not from a mesh)
  std::vector<std::int32_t> pixels;      ///< N x 2 (column, row) in the image
  Eigen::Matrix4d T_model_camera = Eigen::Matrix4d::Identity();  ///< camera -> model
  PinholeIntrinsics intrinsics;          ///< the view's camera
  /// CBD keypoints and descriptors of this view, computed once (describeModelViews, a part
  /// library) with `cbd_settings`. estimatePose uses them instead of recomputing when the CBD
  /// settings it would use are the same (sameDescriptors): for a 42-view part that is most of
  /// a pose's time. Empty: computed per call.
  std::optional<CbdFeatures> cbd;
  CbdSettings cbd_settings;              ///< the settings `cbd` was computed with
  std::size_t size() const { return points.size() / 3; }
  CloudView<double> cloud() const { return {points.data(), size()}; }
  CloudView<double> normalCloud() const { return {normals.data(), size()}; }
};

/// The views of a triangle mesh (vertices in the model frame, m; faces n_faces x 3) from the
/// vertices of tessellatedSphere(settings.level), in that order.
/// @throws std::invalid_argument for a malformed mesh (fewer than 3 vertices, a non-finite
///         vertex, a face index out of range, all vertices coinciding, no triangle of non-zero
///         area), bad settings, or views
///         whose worst-case memory exceeds settings.max_memory_bytes (checked before allocating).
std::vector<ModelView> renderModelViews(const CloudView<double>& vertices, const std::int32_t* faces,
                                        std::size_t n_faces, const ModelViewSettings& settings = {});

}  // namespace scanalign
