// Bindings of the two-step pose's 2D step (scanalign._core.pose): the reference image's
// geometry, the planar pose from a homography (Kleppe et al., Robotics 6 (2017) 14, eqs.
// (5)-(6)) and the step's settings, which scanalign.pose.image_matching reads.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "pose.hpp"
#include "scanalign/pose/homography_pose.hpp"
#include "scanalign/pose/refine_2d_settings.hpp"

namespace scanalign::python {

namespace {

Eigen::Matrix3d homography(const py::object& h) { return fields::Conv<Eigen::Matrix3d>::set(h, "H_image_reference"); }
Eigen::Isometry3d pose(const py::object& T, const char* name) { return fields::Conv<Eigen::Isometry3d>::set(T, name); }

void bindGeometry(py::module_& m) {
  using R = ReferenceImageGeometry;
  fieldsOf(py::class_<R>(m, "ReferenceImageGeometry",
                         "Where a part's top-face reference image lies on the part: an orthographic view from above, "
                         "pixel u along part +x, v along part -y. validate() raises ValueError naming a bad field."))
      .field("width", &R::width, "px", "image width")
      .field("height", &R::height, "px", "image height")
      .field("pixels_per_metre", &R::pixels_per_metre, "px/m", "scale of the image (5000: 0.2 mm per pixel)")
      .field("origin_pixel", &R::origin_pixel, "px", "(u, v) of the point above the part origin")
      .field("top_height", &R::top_height, "m", "height of the top face above the part origin (part z)")
      .settings()
      .def("validate", &R::validate)
      .def("part_point", &R::partPoint, py::arg("u"), py::arg("v"),
           "(3,) the part-frame point (x, y, top_height) under reference pixel (u, v), m");
  using H = HomographyPoseSettings;
  fieldsOf(py::class_<H>(m, "HomographyPoseSettings", "How a homography becomes a planar pose"))
      .field("max_scale_error", &H::max_scale_error, "",
             "largest |singular value - 1| of the top-plane map the homography implies; beyond it: 'non_rigid'")
      .field("axis_length", &H::axis_length, "m", "the step along the reference x axis to p1 (eqs. (5)-(6))")
      .settings()
      .def("validate", &H::validate);
  using P = HomographyPose;
  fieldsOf(py::class_<P>(m, "HomographyPose", "A part's planar pose read off a reference-to-image homography")
               .def("__bool__", [](const P& p) { return p.status == HomographyPoseStatus::Ok; })
               .def("__repr__", [](const P& p) {
                 return std::string("HomographyPose(status='") + toString(p.status) + "', x=" + std::to_string(p.x) +
                        ", y=" + std::to_string(p.y) + ", theta=" + std::to_string(p.theta) + ")";
               }))
      .name("status", &P::status, 5, "",
            "'ok', 'non_rigid' (a scaled, sheared or mirrored fit), 'part_outside_image', 'not_in_view' (the top "
            "plane is behind the camera) or 'not_finite' (a singular homography)",
            false)
      .output("reason", &P::reason, "", "why not 'ok', with the measured value")
      .output("T_base_part", &P::T_base_part, "m", "(4, 4) refined: x, y, yaw from the image, z from the rough pose")
      .output("x", &P::x, "m", "part origin, base frame")
      .output("y", &P::y, "m", "part origin, base frame")
      .output("theta", &P::theta, "rad", "yaw of part x about base z (eq. (6))")
      .output("p0", &P::p0, "px", "(2,) the part origin in the camera image (eq. (5))")
      .output("p1", &P::p1, "px", "(2,) the reference x-axis point in the camera image")
      .output("singular_values", &P::singular_values, "", "(2,) of the top-plane map (1, 1: rigid)")
      .result();
}

void bindSettings(py::module_& m) {
  using I = ImageMatchSettings;
  fieldsOf(py::class_<I>(m, "ImageMatchSettings",
                         "Keypoint matching of a reference image against a camera image (OpenCV, run by "
                         "scanalign.pose.image_matching) and the homography's RANSAC fit"))
      .field("detector", &I::detector, "",
             "'sift' (the paper's), 'akaze' or 'orb' (free substitutes for its SIFT/SURF hybrid)")
      .field("max_features", &I::max_features, "", "keypoints kept per image, 100..100000")
      .field("ratio", &I::ratio, "", "Lowe's ratio test threshold, (0, 1]")
      .field("ransac_threshold", &I::ransac_threshold, "px", "reprojection error of a RANSAC inlier")
      .field("ransac_iterations", &I::ransac_iterations, "", "RANSAC's cap, 10..1000000")
      .field("min_matches", &I::min_matches, "", "fewer matches: status 'too_few_matches' (>= 4)")
      .field("min_inliers", &I::min_inliers, "", "fewer inliers: status 'too_few_inliers' (>= 4)")
      .settings()
      .def("validate", &I::validate);
  using S = Refine2dSettings;
  fieldsOf(py::class_<S>(m, "Refine2dSettings",
                         "The 2D refinement of the two-step pose (Kleppe et al., Robotics 6 (2017) 14, §3.3)"))
      .field("matching", &S::matching, "", "ImageMatchSettings")
      .field("homography", &S::homography, "", "HomographyPoseSettings")
      .field("max_steps", &S::max_steps, "", "views taken at most, 1..100")
      .field("converged_translation", &S::converged_translation, "m", "converged when a step moves less than this")
      .field("converged_angle", &S::converged_angle, "rad", "... and turns less than this")
      .settings()
      .def("validate", &S::validate);
}

}  // namespace

void bindPoseHomography(py::module_& m) {
  bindGeometry(m);
  bindSettings(m);
  m.def(
      "planar_pose_from_homography",
      [](const py::object& H, const ReferenceImageGeometry& reference, const PinholeIntrinsics& intrinsics,
         const py::object& T_base_camera, const py::object& T_base_part_rough, const HomographyPoseSettings& s) {
        return planarPoseFromHomography(homography(H), reference, intrinsics, pose(T_base_camera, "T_base_camera"),
                                        pose(T_base_part_rough, "T_base_part_rough"), s);
      },
      py::arg("H_image_reference"), py::arg("reference"), py::arg("intrinsics"), py::arg("T_base_camera"),
      py::arg("T_base_part_rough"), py::arg("settings") = HomographyPoseSettings{},
      "The part's planar pose (HomographyPose) from a homography of reference pixels to undistorted camera pixels "
      "(any scale): eqs. (5)-(6) of Kleppe et al. 2017 on the top plane of the rough pose. ValueError naming the "
      "argument for bad input or distorted intrinsics.");
  m.def(
      "homography_of_part",
      [](const ReferenceImageGeometry& reference, const PinholeIntrinsics& intrinsics, const py::object& T_base_camera,
         const py::object& T_base_part) {
        return homographyOfPart(reference, intrinsics, pose(T_base_camera, "T_base_camera"),
                                pose(T_base_part, "T_base_part"));
      },
      py::arg("reference"), py::arg("intrinsics"), py::arg("T_base_camera"), py::arg("T_base_part"),
      "(3, 3) the homography reference pixels -> camera pixels of an upright part at T_base_part (H[2, 2] = 1)");
}

}  // namespace scanalign::python
