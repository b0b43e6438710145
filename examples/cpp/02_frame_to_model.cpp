// 02: eye-in-hand frame-to-model reconstruction with the PCL-free core only, as a robot
// controller would run it: depth images in, camera poses and a model out.
//
// The "sensor" here ray-casts a ball on a table from a camera circling it 35 cm above
// the table; the camera poses are known, so the example checks its own tracking and
// exits non-zero if any frame is off by more than 2 mm.
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include <Eigen/Geometry>

#include <scanalign/reconstruction/depth_image.hpp>
#include <scanalign/reconstruction/frame_to_model.hpp>

namespace {

// Camera looking from `eye` at `target`; z forward, x right, y down (OpenCV).
Eigen::Matrix4d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 1>(0, 0) = x;
  T.block<3, 1>(0, 1) = z.cross(x);
  T.block<3, 1>(0, 2) = z;
  T.block<3, 1>(0, 3) = eye;
  return T;
}

// Depth (m) of a 30 cm table with a ball and a box-like bump, seen from T_base_camera.
std::vector<float> renderDepth(const Eigen::Matrix4d& T_base_camera, const scanalign::PinholeIntrinsics& K) {
  std::vector<float> depth(static_cast<std::size_t>(K.width) * K.height, 0.0f);
  const Eigen::Matrix3d R = T_base_camera.topLeftCorner<3, 3>();
  const Eigen::Vector3d o = T_base_camera.topRightCorner<3, 1>();
  const Eigen::Vector3d ball(0.01, 0.0, 0.03), bump(-0.04, 0.03, 0.012);
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) {
      const Eigen::Vector3d d = R * Eigen::Vector3d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
      double t = std::numeric_limits<double>::infinity();
      const double tp = -o.z() / d.z();
      const Eigen::Vector3d p = o + tp * d;
      if (tp > 0 && std::abs(p.x()) < 0.15 && std::abs(p.y()) < 0.15) t = tp;
      for (const auto& [c, r] : {std::pair{ball, 0.03}, std::pair{bump, 0.015}}) {
        const Eigen::Vector3d oc = o - c;
        const double b = d.dot(oc), disc = b * b - d.squaredNorm() * (oc.squaredNorm() - r * r);
        if (disc > 0) t = std::min(t, (-b - std::sqrt(disc)) / d.squaredNorm());
      }
      if (std::isfinite(t)) depth[static_cast<std::size_t>(v) * K.width + u] = static_cast<float>(t);
    }
  return depth;
}

}  // namespace

int main() {
  const scanalign::PinholeIntrinsics K{320, 240, 240.0, 240.0, 159.5, 119.5};
  scanalign::DepthToCloudSettings depth_settings;  // 0.1 .. 2 m
  scanalign::FrameToModelSettings settings;         // seed defaults: 5 mm normals, 1 mm grid
  scanalign::FrameToModel reconstruction(settings);

  const int n = 24;
  auto pose = [&](int i) {
    const double a = 2.0 * M_PI * i / n;
    return lookAt({0.25 * std::cos(a), 0.25 * std::sin(a), 0.35}, {0.0, 0.0, 0.02});
  };
  // The model is kept in the robot base frame: the first frame sits at its known pose.
  reconstruction.reset(pose(0));
  double worst = 0.0;
  for (int i = 0; i < n; ++i) {
    const std::vector<float> depth = renderDepth(pose(i), K);
    const scanalign::DepthCloud cloud = scanalign::depthToCloud(depth.data(), K, depth_settings);
    const scanalign::FrameResult r =
        reconstruction.integrate(scanalign::CloudView<float>(cloud.points.data(), cloud.size()));
    const double err = (r.T_model_camera.topRightCorner<3, 1>() - pose(i).topRightCorner<3, 1>()).norm();
    worst = std::max(worst, r.merged() ? err : 1.0);
    std::printf("frame %2d  %-12s  %2d iterations  fitness %.3f  model %7zu points  error %.3f mm  %.0f ms\n", i,
                scanalign::toString(r.status), r.icp.iterations, r.icp.fitness, r.model_points, err * 1000.0,
                r.total_seconds * 1000.0);
  }
  std::printf("worst camera position error %.3f mm over %d frames\n", worst * 1000.0, n);
  return worst < 0.002 ? 0 : 1;
}
