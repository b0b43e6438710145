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


/// How the views of a model *cloud* (a scanned part, cloudModelViews) are made. A cloud has no
/// faces to rasterise: each point is drawn as a disc (a splat) into the view's depth buffer, and
/// the points at most depth_tolerance behind it are the view (the hidden points are those
/// behind another splat).
struct CloudModelSettings {
  /// m: radius of the PCA normals (features/normals.hpp) of a cloud given without normals; the
  /// eye-in-hand paper's 5 mm. Points with fewer than 3 neighbours within it are left out.
  double normal_radius = 0.005;
  /// m: radius of each point's disc in the depth buffer (at least 0.75 pixel); 0 = 1.5 x the
  /// median distance from a point to its nearest neighbour (the gaps between samples close, the
  /// surface hides what is behind it).
  double splat_radius = 0.0;
  /// m: a point is visible when it lies at most this far behind the depth buffer's surface at
  /// its pixel; 0 = the point's disc radius (at least 0.75 pixel at its depth, so that every
  /// point covers its own pixel's centre). The discs lie in the points' tangent planes
  /// (surfels), so a sloped surface does not hide itself.
  double depth_tolerance = 0.0;
};

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
  CloudModelSettings cloud;  ///< for a model given as a cloud (cloudModelViews); meshes ignore it
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

/// The views of a model cloud (points in the model frame, m; e.g. a scanned part, whole or
/// partial) from the same cameras as renderModelViews: the points each camera sees (a splat
/// z-buffer, CloudModelSettings), the nearest one per pixel (a view as dense as a mesh's at
/// the same resolution), with their normals turned towards that camera (given normals
/// are taken as unoriented lines; `normals` empty: PCA normals of radius cloud.normal_radius).
/// Pixels are the points' image positions, face_id -1 (no mesh). A view may be empty (a
/// partial scan seen from where it has no points).
/// @throws std::invalid_argument for fewer than 3 points, a non-finite point or normal, a
///         normal count other than the points', no point with a normal, bad settings, or
///         views whose worst-case memory (views x points x kModelViewBytesPerPixel) exceeds
///         settings.max_memory_bytes.
std::vector<ModelView> cloudModelViews(const CloudView<double>& points, const CloudView<double>& normals,
                                       const ModelViewSettings& settings = {});

/// Whether `views` are those of a model cloud (every point's face_id is -1: cloudModelViews, or
/// ModelView(points, normals)): its surface may be partial, which findParts's coverage gate
/// takes into account.
bool isCloudModel(const std::vector<ModelView>& views);

}  // namespace scanalign
