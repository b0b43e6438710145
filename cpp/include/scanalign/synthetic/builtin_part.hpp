// The built-in parts of the synthetic scans, closed triangle meshes generated from their
// analytic surfaces (metres, each part's own frame, z up).
//
// "block", the machined block (origin at the box centre, lowest point z = -0.015):
// - a box [-0.040, 0.040] x [-0.025, 0.025] x [-0.015, 0.015] (80 x 50 x 30 mm);
// - a cylindrical boss of radius 0.012 on the top face, axis along z through (x, y) =
//   (-0.015, 0), 0.015 high (top at z = 0.030);
// - a spherical cap: the part of the sphere of radius 0.015 centred at (0.020, 0.006, 0.006)
//   above the top face (cap height 0.006, base radius 0.012).
// Flat faces, a cylinder and a sphere without symmetry constrain point-to-plane ICP in all
// six degrees of freedom.
//
// "bracket", an L-shaped angle bracket (origin at the base plate's centre on its bottom face,
// lowest point z = 0): a base plate [-0.035, 0.035] x [-0.020, 0.020] x [0, 0.006], an upright
// plate [0.029, 0.035] x [-0.020, 0.020] x [0, 0.040] at the +x end, and a triangular gusset
// in the inner corner on the +y side (y in [0.014, 0.020], legs 0.020 along x and z from the
// corner (0.029, 0.006)). The gusset breaks the mirror symmetry y -> -y: no rotation or
// reflection maps the bracket onto itself.
//
// "standoff", a hexagonal standoff (origin at the bottom face centre, lowest point z = 0): a
// hexagonal prism 0.030 across flats (corners at angles k 60 degrees), 0.020 high, with a
// coaxial cylindrical stud of radius 0.006 on top, 0.015 high (top at z = 0.035). Its only
// symmetry is the 6-fold rotation about z through the origin.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/mesh_sampling.hpp"
#include "scanalign/pose/part_symmetry.hpp"

namespace scanalign {

/// The analytic surface a face of the part lies on.
/// kBoss is any cylinder: the block's boss, the standoff's stud.
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

/// The built-in part `name` ("block", "bracket" or "standoff") as a watertight mesh, outward
/// winding. `segments` (in [8, kMaxPartSegments]) are the vertices around a curved surface:
/// the bracket has none (the argument is only validated); the standoff's stud uses segments
/// rounded up to a multiple of 6, so the mesh keeps the part's 6-fold symmetry exactly.
/// Throws std::invalid_argument for an unknown name or segments out of range.
BuiltinPartMesh builtinPartMesh(const std::string& name, int segments);

/// The names builtinPartMesh(name, segments) takes, in this order: block, bracket, standoff.
const std::vector<std::string>& builtinPartNames();

/// The rotational symmetry of a built-in part (model frame): order 1 (none) for the block
/// and the bracket, order 6 about z through the origin for the standoff.
/// Throws std::invalid_argument for an unknown name.
PartSymmetry builtinPartSymmetry(const std::string& name);

/// The block's exposed surface sampled uniformly per unit area, with exact normals: samples
/// of builtinPartMesh(segments) (MeshSampler, from Pcg64(seed), in batches of the points
/// missing plus 1 % and 16) whose points on the boss's side are moved radially onto the
/// exact cylinder and those on the cap onto the exact sphere (normals the exact ones there);
/// points of the top face inside the true circles of the boss and the cap (the slivers
/// between the inscribed polygons and the circles, which belong to the boss and the cap) are
/// dropped. The points come in the order drawn (the former NumPy implementation's, sample for
/// sample). `faces` holds each point's mesh face. Throws std::invalid_argument for segments
/// outside [8, kMaxPartSegments].
MeshSamples sampleBuiltinBlock(std::size_t n_points, std::uint64_t seed, int segments = 96);

/// Most segments builtinPartMesh() takes (its chord error is then 4e-9 m, far below any
/// sensor); more would only allocate (the mesh grows with the segments).
constexpr int kMaxPartSegments = 4096;

}  // namespace scanalign
