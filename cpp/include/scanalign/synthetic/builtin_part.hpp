// The built-in machined part of the synthetic scans, as a closed triangle mesh generated from
// its analytic surfaces (metres, the part's own frame: origin at the box centre, z up):
// - a box [-0.040, 0.040] x [-0.025, 0.025] x [-0.015, 0.015] (80 x 50 x 30 mm);
// - a cylindrical boss of radius 0.012 on the top face, axis along z through (x, y) =
//   (-0.015, 0), 0.015 high (top at z = 0.030);
// - a spherical cap: the part of the sphere of radius 0.015 centred at (0.020, 0.006, 0.006)
//   above the top face (cap height 0.006, base radius 0.012).
// Flat faces, a cylinder and a sphere without symmetry constrain point-to-plane ICP in all
// six degrees of freedom.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace scanalign {

/// The analytic surface a face of the part lies on.
enum class PartSurface : std::int32_t { kPlane = 0, kBoss = 1, kCap = 2 };

struct BuiltinPartMesh {
  std::vector<Eigen::Vector3d> vertices;            ///< metres, part frame
  std::vector<Eigen::Vector3i> faces;               ///< counter-clockwise seen from outside
  std::vector<PartSurface> surface;                 ///< per face: the surface it lies on
};

/// The part as a watertight mesh (every edge shared by exactly two faces, outward winding);
/// the boss and the cap are inscribed polygons with `segments` vertices around (>= 8), their
/// vertices on the exact surfaces; vertices with bit-identical coordinates are shared.
/// Throws std::invalid_argument for segments outside [8, kMaxPartSegments].
BuiltinPartMesh builtinPartMesh(int segments);

/// Most segments builtinPartMesh() takes (its chord error is then 4e-9 m, far below any
/// sensor); more would only allocate (the mesh grows with the segments).
constexpr int kMaxPartSegments = 4096;

}  // namespace scanalign
