// Area-weighted sampling of a triangle mesh's surface: each point is drawn on a triangle
// chosen with probability proportional to its area, uniformly inside it by the square-root
// parametrisation p = a + sqrt(u) (1 - v) (b - a) + sqrt(u) v (c - a), u, v uniform in
// [0, 1) (Osada, Funkhouser, Chazelle and Dobkin, "Shape distributions", ACM Trans.
// Graphics 21(4), 2002, §4.2). Used to turn CAD meshes into clouds (pose estimation, the
// built-in parts, the pick cell's scenes).
//
// The random numbers are NumPy's: Pcg64 is numpy.random.default_rng(seed)'s generator, and
// MeshSampler::draw consumes it as NumPy's Generator.choice(p=areas) and Generator.random
// do, with NumPy's summation order for the areas, so a seed gives the samples the library's
// former NumPy implementation gave (and a NumPy script gets with the same seed).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// NumPy's default bit generator, PCG64 (O'Neill, "PCG: A family of simple fast space-efficient
/// statistically good algorithms for random number generation", HMC-CS-2014-0905, 2014: a
/// 128-bit LCG with the XSL-RR 128/64 output), seeded through NumPy's SeedSequence (O'Neill's
/// seed_seq hash mixing of the seed's 32-bit words): the stream of
/// numpy.random.default_rng(seed).bit_generator.random_raw().
class Pcg64 {
 public:
  explicit Pcg64(std::uint64_t seed);
  /// The next 64 random bits.
  std::uint64_t next();
  /// A double uniform in [0, 1) from the top 53 bits of next(): Generator.random()'s.
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  unsigned __int128 state_ = 0, increment_ = 0;
};

/// Points drawn on a mesh, with the unit normal and the index of the face each lies on.
struct MeshSamples {
  std::vector<Eigen::Vector3d> points;   ///< in the mesh's unit and frame
  std::vector<Eigen::Vector3d> normals;  ///< unit face normals, right-hand rule on the winding
  std::vector<std::int64_t> faces;       ///< the face (row of `faces`) each point lies on
  std::size_t size() const { return points.size(); }
};

/// A mesh prepared for sampling: its faces' corners, unit normals and cumulative area weights.
class MeshSampler {
 public:
  /// Throws std::invalid_argument for a face index outside [0, vertices.size), a non-finite
  /// vertex used by a face, or a mesh of zero total area ("cannot sample its surface").
  MeshSampler(const CloudView<double>& vertices, const std::int64_t* faces, std::size_t n_faces);

  /// Appends n samples drawn from `rng` in NumPy's order: n uniforms choosing the faces by
  /// area (the first face whose cumulative weight exceeds the draw: a zero-area face never),
  /// then n uniforms u and n uniforms v placing the points. A point is relative to its face's
  /// first corner a, term by term ((a + sqrt(u) (1 - v) (b - a)) + sqrt(u) v (c - a)), so a
  /// point on an axis-aligned face keeps that face's exact coordinate.
  void draw(Pcg64& rng, std::size_t n, MeshSamples& out) const;

  std::size_t faceCount() const { return normal_.size(); }

 private:
  std::vector<Eigen::Vector3d> a_, ab_, ac_, normal_;  ///< per face: a, b - a, c - a, unit normal
  std::vector<double> cdf_;  ///< cumulative area weights, normalised to end at 1
};

/// n_points samples of the mesh from Pcg64(seed) (see MeshSampler::draw). Throws as
/// MeshSampler's constructor.
MeshSamples sampleMesh(const CloudView<double>& vertices, const std::int64_t* faces, std::size_t n_faces,
                       std::size_t n_points, std::uint64_t seed);

}  // namespace scanalign
