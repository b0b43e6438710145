#include "scanalign/synthetic/builtin_part.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>
#include <Eigen/Geometry>  // cross()

namespace scanalign {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kHx = 0.040, kHy = 0.025, kHz = 0.015;  // box half sizes
constexpr double kBossX = -0.015, kBossY = 0.0, kBossRadius = 0.012, kBossHeight = 0.015;
constexpr double kCapX = 0.020, kCapY = 0.006, kCapZ = kHz - 0.009, kCapRadius = 0.015;

/// Collects labelled triangles; vertices with bit-identical coordinates are shared, which
/// keeps the surfaces watertight without a tolerance.
class MeshBuilder {
 public:
  PartSurface surface = PartSurface::kPlane;

  int vertex(double x, double y, double z) {
    const auto [it, added] = index_.try_emplace({x, y, z}, static_cast<int>(mesh_.vertices.size()));
    if (added) mesh_.vertices.emplace_back(x, y, z);
    return it->second;
  }
  const Eigen::Vector3d& at(int i) const { return mesh_.vertices[static_cast<std::size_t>(i)]; }

  void triangle(int a, int b, int c) {
    mesh_.faces.emplace_back(a, b, c);
    mesh_.surface.push_back(surface);
  }

  /// A planar triangle wound so that its normal points along `outward`.
  void facing(int a, int b, int c, const Eigen::Vector3d& outward) {
    if ((at(b) - at(a)).cross(at(c) - at(a)).dot(outward) < 0) std::swap(b, c);
    triangle(a, b, c);
  }

  /// Closed band between two rings of equal size, both counter-clockwise seen from
  /// outside-above; normals point away from the ring axis.
  void strip(const std::vector<int>& lower, const std::vector<int>& upper) {
    const std::size_t n = lower.size();
    for (std::size_t j = 0; j < n; ++j) {
      const std::size_t k = (j + 1) % n;
      triangle(lower[j], lower[k], upper[k]);
      triangle(lower[j], upper[k], upper[j]);
    }
  }

  /// Fan from `apex` over a closed ring (counter-clockwise seen from the apex's side).
  void fan(int apex, const std::vector<int>& ring) {
    for (std::size_t j = 0; j < ring.size(); ++j) triangle(apex, ring[j], ring[(j + 1) % ring.size()]);
  }

  /// The plane z = const between a circular hole around (cx, cy) and a convex outer boundary
  /// around it (normal +z): both boundaries are walked in angle around the hole's centre,
  /// each step advancing the walk whose next point comes first.
  void annulus(double cx, double cy, const std::vector<int>& hole, const std::vector<int>& outer) {
    auto [inner, ia] = byAngle(cx, cy, hole);
    auto [out, oa] = byAngle(cx, cy, outer);
    const std::size_t n_i = inner.size(), n_o = out.size();
    // Close both loops by repeating the first point at + 2 pi.
    inner.push_back(inner[0]);
    ia.push_back(ia[0] + 2 * kPi);
    out.push_back(out[0]);
    oa.push_back(oa[0] + 2 * kPi);
    std::size_t i = 0, j = 0;
    while (i < n_i || j < n_o) {
      if (j >= n_o || (i < n_i && ia[i + 1] <= oa[j + 1])) {
        triangle(inner[i], out[j], inner[i + 1]);
        ++i;
      } else {
        triangle(inner[i], out[j], out[j + 1]);
        ++j;
      }
    }
  }

  /// A vertical rectangle whose top edge carries `top` (from the corner above b0 to the one
  /// above b1) and whose bottom edge is b0-b1. Its normal is (direction of top) x (up).
  void rectangleSide(const std::vector<int>& top, int b0, int b1) {
    const std::size_t half = (top.size() - 1) / 2;
    for (std::size_t j = 0; j < half; ++j) triangle(b0, top[j + 1], top[j]);
    triangle(b0, b1, top[half]);
    for (std::size_t j = half; j + 1 < top.size(); ++j) triangle(b1, top[j + 1], top[j]);
  }

  BuiltinPartMesh take() { return std::move(mesh_); }

 private:
  std::pair<std::vector<int>, std::vector<double>> byAngle(double cx, double cy, const std::vector<int>& idx) const {
    std::vector<double> ang(idx.size());
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const double a = std::atan2(at(idx[k]).y() - cy, at(idx[k]).x() - cx);
      ang[k] = a < 0 ? a + 2 * kPi : a;
    }
    std::vector<std::size_t> order(idx.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ang[a] < ang[b]; });
    std::pair<std::vector<int>, std::vector<double>> sorted;
    for (std::size_t k : order) {
      sorted.first.push_back(idx[k]);
      sorted.second.push_back(ang[k]);
    }
    return sorted;
  }

  std::map<std::array<double, 3>, int> index_;
  BuiltinPartMesh mesh_;
};

/// n points from a to c, both included (as numpy.linspace).
std::vector<double> linspace(double a, double c, int n) {
  std::vector<double> out(static_cast<std::size_t>(n));
  const double step = (c - a) / (n - 1);
  for (int k = 0; k < n; ++k) out[static_cast<std::size_t>(k)] = a + k * step;
  out.back() = c;
  return out;
}

/// Boundary points at most 4 mm apart: dense enough for the annulus merge.
std::vector<double> boundary(double a, double c) {
  return linspace(a, c, std::max(2, static_cast<int>(std::ceil(std::abs(c - a) / 0.004)) + 1));
}

void checkSegments(int segments) {
  if (segments < 8 || segments > kMaxPartSegments)
    throw std::invalid_argument("segments must be an integer in [8, " + std::to_string(kMaxPartSegments) + "], got " +
                                std::to_string(segments));
}

/// The bracket: its L profile in the (x, z) plane, extruded along y in two slabs. The slab
/// y in [kGussetY, kHalfW] adds the gusset to the profile (the diagonal E-G replaces the
/// corner E-F-G); the step face at y = kGussetY is the gusset's triangle. The profile of the
/// other slab keeps E and G as (collinear) vertices so the slabs share every edge.
BuiltinPartMesh bracketMesh() {
  constexpr double kHalfL = 0.035, kHalfW = 0.020, kT = 0.006, kHeight = 0.040, kLeg = 0.020, kGussetY = 0.014;
  constexpr double kInner = kHalfL - kT;  // x of the upright's inner face
  // Profile, counter-clockwise in (x, z): A B C D E F G H.
  const std::vector<Eigen::Vector2d> p1 = {{-kHalfL, 0},        {kHalfL, 0},     {kHalfL, kHeight},
                                           {kInner, kHeight},   {kInner, kT + kLeg}, {kInner, kT},
                                           {kInner - kLeg, kT}, {-kHalfL, kT}};
  std::vector<Eigen::Vector2d> p2 = p1;
  p2.erase(p2.begin() + 5);  // F is inside the gusset
  MeshBuilder b;
  auto v = [&](const Eigen::Vector2d& q, double y) { return b.vertex(q.x(), y, q.y()); };
  const Eigen::Vector3d minus_y(0, -1, 0), plus_y(0, 1, 0);
  auto walls = [&](const std::vector<Eigen::Vector2d>& p, double y0, double y1) {
    for (std::size_t j = 0; j < p.size(); ++j) {
      const Eigen::Vector2d& a = p[j];
      const Eigen::Vector2d& c = p[(j + 1) % p.size()];
      const Eigen::Vector3d out(c.y() - a.y(), 0, a.x() - c.x());  // (dz, 0, -dx): outward of a CCW profile
      b.facing(v(a, y0), v(c, y0), v(c, y1), out);
      b.facing(v(a, y0), v(c, y1), v(a, y1), out);
    }
  };
  // End caps: both profiles are star-shaped from B (index 1), so a fan from B covers them.
  auto cap = [&](const std::vector<Eigen::Vector2d>& p, double y, const Eigen::Vector3d& out) {
    for (std::size_t j = 2; j < p.size(); ++j) b.facing(v(p[1], y), v(p[j], y), v(p[(j + 1) % p.size()], y), out);
  };
  walls(p1, -kHalfW, kGussetY);
  walls(p2, kGussetY, kHalfW);
  cap(p1, -kHalfW, minus_y);
  cap(p2, kHalfW, plus_y);
  b.facing(v(p1[4], kGussetY), v(p1[5], kGussetY), v(p1[6], kGussetY), minus_y);  // the gusset's step E F G
  return b.take();
}

/// The standoff: a hexagonal prism with a stud. The prism's top edges are subdivided (at
/// most 4 mm apart) so that the annulus between them and the stud's ring is well shaped.
BuiltinPartMesh standoffMesh(int segments) {
  constexpr double kApothem = 0.015, kHeight = 0.020, kStudRadius = 0.006, kStudHeight = 0.015;
  const double circumradius = kApothem / std::cos(kPi / 6);
  const int n = 6 * ((segments + 5) / 6);  // the stud keeps the 6-fold symmetry
  constexpr int kPerEdge = 5;              // 3.5 mm apart
  MeshBuilder b;
  std::vector<Eigen::Vector2d> corner(6);
  for (int k = 0; k < 6; ++k) corner[static_cast<std::size_t>(k)] = circumradius * Eigen::Vector2d(std::cos(k * kPi / 3), std::sin(k * kPi / 3));
  std::vector<int> outer;
  std::vector<std::vector<int>> edge_top(6);
  for (std::size_t k = 0; k < 6; ++k) {
    const Eigen::Vector2d& a = corner[k];
    const Eigen::Vector2d& c = corner[(k + 1) % 6];
    for (int j = 0; j <= kPerEdge; ++j) {
      const Eigen::Vector2d q = j == kPerEdge ? c : Eigen::Vector2d(a + (c - a) * (static_cast<double>(j) / kPerEdge));
      edge_top[k].push_back(b.vertex(q.x(), q.y(), kHeight));
      if (j < kPerEdge) outer.push_back(edge_top[k].back());
    }
  }
  std::vector<int> stud_bottom, stud_top;
  for (int j = 0; j < n; ++j) {
    const double phi = 2 * kPi * j / n;
    stud_bottom.push_back(b.vertex(kStudRadius * std::cos(phi), kStudRadius * std::sin(phi), kHeight));
    stud_top.push_back(b.vertex(kStudRadius * std::cos(phi), kStudRadius * std::sin(phi), kHeight + kStudHeight));
  }
  b.surface = PartSurface::kBoss;
  b.strip(stud_bottom, stud_top);
  b.surface = PartSurface::kPlane;
  b.fan(b.vertex(0, 0, kHeight + kStudHeight), stud_top);
  b.annulus(0, 0, stud_bottom, outer);
  std::vector<int> bottom;
  for (const auto& q : corner) bottom.push_back(b.vertex(q.x(), q.y(), 0));
  for (std::size_t k = 0; k < 6; ++k) b.rectangleSide(edge_top[k], bottom[k], bottom[(k + 1) % 6]);
  for (std::size_t k = 1; k + 1 < 6; ++k) b.facing(bottom[0], bottom[k], bottom[k + 1], Eigen::Vector3d(0, 0, -1));
  return b.take();
}

}  // namespace

const std::vector<std::string>& builtinPartNames() {
  static const std::vector<std::string> names = {"block", "bracket", "standoff"};
  return names;
}

BuiltinPartMesh builtinPartMesh(const std::string& name, int segments) {
  checkSegments(segments);
  if (name == "block") return builtinPartMesh(segments);
  if (name == "bracket") return bracketMesh();
  if (name == "standoff") return standoffMesh(segments);
  throw std::invalid_argument("name: unknown built-in part '" + name + "' (expected block, bracket or standoff)");
}

PartSymmetry builtinPartSymmetry(const std::string& name) {
  const auto& names = builtinPartNames();
  if (std::find(names.begin(), names.end(), name) == names.end())
    throw std::invalid_argument("name: unknown built-in part '" + name + "' (expected block, bracket or standoff)");
  PartSymmetry s;
  if (name == "standoff") s.order = 6;  // axis z through the origin
  return s;
}

BuiltinPartMesh builtinPartMesh(int segments) {
  checkSegments(segments);
  MeshBuilder b;
  const auto n = static_cast<std::size_t>(segments);
  std::vector<double> cs(n), sn(n);
  for (std::size_t j = 0; j < n; ++j) {
    const double phi = 2 * kPi * static_cast<double>(j) / segments;
    cs[j] = std::cos(phi);
    sn[j] = std::sin(phi);
  }
  auto ring = [&](double cx, double cy, double r, double z) {
    std::vector<int> idx(n);
    for (std::size_t j = 0; j < n; ++j) idx[j] = b.vertex(cx + r * cs[j], cy + r * sn[j], z);
    return idx;
  };

  // Boss: a cylinder on the top face, its bottom ring shared with the face's hole.
  const std::vector<int> boss_bottom = ring(kBossX, kBossY, kBossRadius, kHz);
  const std::vector<int> boss_top = ring(kBossX, kBossY, kBossRadius, kHz + kBossHeight);
  b.surface = PartSurface::kBoss;
  b.strip(boss_bottom, boss_top);
  b.surface = PartSurface::kPlane;
  b.fan(b.vertex(kBossX, kBossY, kHz + kBossHeight), boss_top);

  // Cap: the sphere above the top face, in rings from the base circle to the pole; the base
  // ring lies exactly on the top face, so the face's hole matches it bit for bit.
  const double theta_max = std::acos((kHz - kCapZ) / kCapRadius);  // polar angle of the base
  const int n_rings = std::max(4, segments / 8);
  std::vector<std::vector<int>> rings;
  for (int k = 0; k < n_rings; ++k) {
    const double th = theta_max * (n_rings - k) / n_rings;
    rings.push_back(ring(kCapX, kCapY, kCapRadius * std::sin(th), k == 0 ? kHz : kCapZ + kCapRadius * std::cos(th)));
  }
  b.surface = PartSurface::kCap;
  for (std::size_t k = 0; k + 1 < rings.size(); ++k) b.strip(rings[k], rings[k + 1]);
  b.fan(b.vertex(kCapX, kCapY, kCapZ + kCapRadius), rings.back());
  b.surface = PartSurface::kPlane;

  // Top face: split at x = xs between the two holes into two rectangles with one hole each.
  // Each boundary edge is generated once, so faces sharing it share its vertices.
  const double xs = 0.5 * ((kBossX + kBossRadius) + (kCapX - kCapRadius * std::sin(theta_max)));
  const std::vector<double> x_left = boundary(-kHx, xs), x_right = boundary(xs, kHx), y_all = boundary(-kHy, kHy);
  std::vector<double> x_all = x_left;
  x_all.insert(x_all.end(), x_right.begin() + 1, x_right.end());
  std::vector<int> south, north, west, east, split;
  for (double x : x_all) south.push_back(b.vertex(x, -kHy, kHz));  // y = -hy, x ascending
  for (double x : x_all) north.push_back(b.vertex(x, kHy, kHz));   // y = +hy, x ascending
  for (double y : y_all) west.push_back(b.vertex(-kHx, y, kHz));   // x = -hx, y ascending
  for (double y : y_all) east.push_back(b.vertex(kHx, y, kHz));    // x = +hx, y ascending
  for (double y : y_all) split.push_back(b.vertex(xs, y, kHz));
  const std::size_t n_left = x_left.size();
  auto cat = [](std::initializer_list<std::pair<std::vector<int>::const_iterator, std::vector<int>::const_iterator>>
                    parts) {
    std::vector<int> out;
    for (const auto& [first, last] : parts) out.insert(out.end(), first, last);
    return out;
  };
  const auto L = static_cast<std::ptrdiff_t>(n_left);
  const std::vector<int> left_outer = cat({{south.begin(), south.begin() + L},
                                           {split.begin() + 1, split.end() - 1},
                                           {north.begin(), north.begin() + L},
                                           {west.begin() + 1, west.end() - 1}});
  const std::vector<int> right_outer = cat({{south.begin() + L - 1, south.end()},
                                            {east.begin() + 1, east.end() - 1},
                                            {north.begin() + L - 1, north.end()},
                                            {split.begin() + 1, split.end() - 1}});
  b.annulus(kBossX, kBossY, boss_bottom, left_outer);
  b.annulus(kCapX, kCapY, rings[0], right_outer);

  // Side walls (outward normals) and the bottom face.
  const int c000 = b.vertex(-kHx, -kHy, -kHz), c100 = b.vertex(kHx, -kHy, -kHz);
  const int c010 = b.vertex(-kHx, kHy, -kHz), c110 = b.vertex(kHx, kHy, -kHz);
  b.rectangleSide(south, c000, c100);                                  // y = -hy
  b.rectangleSide(std::vector<int>(north.rbegin(), north.rend()), c110, c010);  // y = +hy
  b.rectangleSide(std::vector<int>(west.rbegin(), west.rend()), c010, c000);    // x = -hx
  b.rectangleSide(east, c100, c110);                                   // x = +hx
  b.triangle(c000, c110, c100);
  b.triangle(c000, c010, c110);
  return b.take();
}

MeshSamples sampleBuiltinBlock(std::size_t n_points, std::uint64_t seed, int segments) {
  const BuiltinPartMesh mesh = builtinPartMesh(segments);
  std::vector<std::int64_t> faces;
  faces.reserve(3 * mesh.faces.size());
  for (const Eigen::Vector3i& f : mesh.faces) faces.insert(faces.end(), {f[0], f[1], f[2]});
  const MeshSampler sampler(CloudView<double>(mesh.vertices[0].data(), mesh.vertices.size()), faces.data(),
                            mesh.faces.size());
  const Eigen::Vector2d boss(kBossX, kBossY);
  const Eigen::Vector3d cap(kCapX, kCapY, kCapZ);
  const double cap_base_radius = std::sqrt(kCapRadius * kCapRadius - (kHz - kCapZ) * (kHz - kCapZ));
  const auto norm2 = [](double x, double y) { return std::sqrt(x * x + y * y); };
  Pcg64 rng(seed);
  MeshSamples out, batch;
  while (out.size() < n_points) {
    // Batches of what is missing plus 1 % and 16 (the dropped slivers are about 0.3 %).
    const std::size_t missing = n_points - out.size();
    batch = MeshSamples{};
    sampler.draw(rng, missing + missing / 100 + 16, batch);
    for (std::size_t i = 0; i < batch.size(); ++i) {
      Eigen::Vector3d& p = batch.points[i];
      Eigen::Vector3d& n = batch.normals[i];
      const PartSurface surface = mesh.surface[static_cast<std::size_t>(batch.faces[i])];
      if (surface == PartSurface::kBoss) {  // onto the cylinder, radially from its axis
        Eigen::Vector2d radial = p.head<2>() - boss;
        radial /= norm2(radial.x(), radial.y());
        p.head<2>() = boss + kBossRadius * radial;
        n = Eigen::Vector3d(radial.x(), radial.y(), 0.0);
      } else if (surface == PartSurface::kCap) {  // onto the sphere, from its centre
        n = p - cap;
        n /= std::sqrt((n.x() * n.x() + n.y() * n.y()) + n.z() * n.z());
        p = cap + kCapRadius * n;
      } else if (p.z() == kHz && (norm2(p.x() - boss.x(), p.y() - boss.y()) < kBossRadius ||
                                  norm2(p.x() - cap.x(), p.y() - cap.y()) < cap_base_radius)) {
        continue;  // the top face inside a true circle: the boss's or the cap's surface
      }
      if (out.size() == n_points) break;
      out.points.push_back(p);
      out.normals.push_back(n);
      out.faces.push_back(batch.faces[i]);
    }
  }
  return out;
}

}  // namespace scanalign
