// Planned camera paths of the synthetic scans (base frame, metres, radians): a loop around
// the object as in the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929,
// Fig. 4), and rings on a hemisphere. Poses are T_base_camera (camera -> base), OpenCV
// camera axes (x right, y down, z along the optical axis), built with lookAt.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace scanalign {

using Poses = std::vector<Eigen::Matrix4d, Eigen::aligned_allocator<Eigen::Matrix4d>>;

/// Most frames of a planned path (about 13 MB of poses; at 10 Hz nearly 3 hours of
/// scanning): larger counts are refused before anything is allocated.
constexpr int kMaxPathFrames = 100000;
/// Largest length (m) a path takes, for distances and coordinates: beyond it the camera
/// geometry overflows (lookAt squares the distances).
constexpr double kMaxPathLength = 1e6;

/// Camera k at center + (radius cos a_k, radius sin a_k, height), a_k = start_angle +
/// sweep k / n_frames (a full loop by default, without repeating the first pose), its optical
/// axis through `target`, image up towards +z (outwards along the azimuth when radius is 0).
/// Throws std::invalid_argument naming the bad argument (n_frames in [1, kMaxPathFrames],
/// height > 0, radius >= 0, lengths and coordinates finite and within kMaxPathLength, finite
/// angles).
Poses loopCameraPoses(int n_frames, const Eigen::Vector3d& center, double height, double radius, double start_angle,
                      double sweep, const Eigen::Vector3d& target);

/// Rings at `distance` from `target`, one per elevation (in (0, pi/2]); frames shared between
/// rings in proportion to their circumferences (cos(elevation), largest remainder, at least one
/// each); successive rings run in opposite directions, each starting where the previous ended
/// (one continuous serpentine), the first at azimuth start_angle. Image up towards +z
/// (outwards at 90 deg). Throws std::invalid_argument naming the bad argument (n_frames in
/// [rings, kMaxPathFrames], distance in (0, kMaxPathLength], target within kMaxPathLength).
Poses hemisphereCameraPoses(int n_frames, const Eigen::Vector3d& target, double distance,
                            const std::vector<double>& elevations, double start_angle);

}  // namespace scanalign
