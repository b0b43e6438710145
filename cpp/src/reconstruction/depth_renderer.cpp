// Z-buffer rasteriser; see depth_renderer.hpp for the conventions.
//
// This file is compiled with -ffp-contract=off (CMakeLists.txt): watertight edges rely on
// the two triangles of a shared edge evaluating bit-identical expressions, which a fused
// multiply-add in one code path (e.g. a vectorised loop body) and not in another would break.
#include "scanalign/reconstruction/depth_renderer.hpp"
#include "scanalign/common/threads.hpp"

#include "scanalign/common/rigid.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>
#include <Eigen/LU>

namespace scanalign {

namespace {

constexpr int kBandRows = 8;          // rows per raster band: a band's buffers (8 x W) stay in L2
constexpr std::size_t kPrefetch = 8;  // faces ahead whose vertices are prefetched in the setup pass
constexpr int kSpanColumns = 8;       // bounding boxes wider than this are rasterised by row spans

/// A vertex in the camera frame and its projection, computed once per vertex so that every
/// triangle using it sees bit-identical screen coordinates. One struct per vertex: a face
/// touches three cache lines, not fifteen.
struct CachedVertex {
  double x, y, z;   // camera frame (m); NaN for non-finite input
  double sx, sy;    // projection (pixels); meaningful only where z >= near
};

/// A face clipped to z >= near and projected: a convex polygon of 3 or 4 vertices.
struct Polygon {
  int n = 0;
  double x[4], y[4];               // screen coordinates (pixels)
  double zmin, zmax;               // camera-frame depth range of the clipped polygon (m)
  Eigen::Vector3d normal;          // unnormalised face normal in the camera frame (right-hand rule)
  double d;                        // plane offset: points p of the face satisfy normal . p = d
};

struct Context {
  const CachedVertex* v;
  const std::int32_t* faces;
  PinholeCamera cam;
  double inv_fx, inv_fy;
  double near_clip, far_clip;
  double w_far;  // 1 / far_clip
  bool cull;
};

/// Builds the clipped, projected polygon of face f. Returns false when nothing of it can be
/// drawn (non-finite vertex, wholly behind the near plane, edge-on, culled back face).
bool facePolygon(const Context& c, std::size_t f, Polygon& poly) {
  const std::int32_t* idx = c.faces + 3 * f;
  const CachedVertex* V[3] = {c.v + idx[0], c.v + idx[1], c.v + idx[2]};
  const double z[3] = {V[0]->z, V[1]->z, V[2]->z};
  if (!(std::isfinite(z[0]) && std::isfinite(z[1]) && std::isfinite(z[2]))) return false;
  const bool in[3] = {z[0] >= c.near_clip, z[1] >= c.near_clip, z[2] >= c.near_clip};
  if (!in[0] && !in[1] && !in[2]) return false;

  const Eigen::Vector3d a(V[0]->x, V[0]->y, z[0]);
  const Eigen::Vector3d b(V[1]->x, V[1]->y, z[1]);
  const Eigen::Vector3d cc(V[2]->x, V[2]->y, z[2]);
  poly.normal = (b - a).cross(cc - a);
  // d = det[a b c]: zero when the camera centre lies on the face's plane (edge-on, zero area
  // on screen) or the face has no area.
  poly.d = poly.normal.dot(a);
  if (!(poly.d != 0.0) || !std::isfinite(poly.d)) return false;
  // d < 0: the normal points towards the camera (front face).
  if (c.cull && poly.d > 0.0) return false;

  poly.n = 0;
  poly.zmin = std::numeric_limits<double>::infinity();
  poly.zmax = -poly.zmin;
  auto emit = [&](double px, double py, double pz) {
    poly.x[poly.n] = px;
    poly.y[poly.n] = py;
    poly.zmin = std::min(poly.zmin, pz);
    poly.zmax = std::max(poly.zmax, pz);
    ++poly.n;
  };
  for (int k = 0; k < 3; ++k) {
    const int l = (k + 1) % 3;
    if (in[k]) emit(V[k]->sx, V[k]->sy, z[k]);
    if (in[k] != in[l]) {
      // Intersection of edge (k, l) with z = near, computed from the endpoint with the
      // smaller vertex index so that the neighbour sharing this edge gets the same point.
      const CachedVertex* p = V[k];
      const CachedVertex* q = V[l];
      if (idx[l] < idx[k]) std::swap(p, q);
      const double t = (c.near_clip - p->z) / (q->z - p->z);
      const double X = p->x + t * (q->x - p->x);
      const double Y = p->y + t * (q->y - p->y);
      emit(c.cam.fx * (X / c.near_clip) + c.cam.cx, c.cam.fy * (Y / c.near_clip) + c.cam.cy, c.near_clip);
    }
  }
  return poly.n >= 3;
}

/// Inclusive pixel range [lo, hi] whose centres lie within [a, b], clamped to [0, size - 1];
/// empty (lo > hi) when there is none or a bound is NaN. Avoids std::ceil / std::floor,
/// which are library calls without SSE4.1 and showed up in profiles.
inline void pixelRange(double a, double b, int size, int& lo, int& hi) {
  lo = 1;
  hi = 0;
  if (!(a <= b)) return;
  const double top = static_cast<double>(size);
  a = a < -1.0 ? -1.0 : (a > top ? top : a);
  b = b < -1.0 ? -1.0 : (b > top ? top : b);
  const int ta = static_cast<int>(a), tb = static_cast<int>(b);  // truncation towards zero
  const int ceil_a = ta + (static_cast<double>(ta) < a);
  const int floor_b = tb - (static_cast<double>(tb) > b);
  lo = std::max(ceil_a, 0);
  hi = std::min(floor_b, size - 1);
}

/// Everything the raster pass needs of one face: its clipped screen polygon and its plane.
struct FaceSetup {
  std::int32_t face;         // row of `faces`
  int n = 0;                 // polygon vertices (3, or 4 after near clipping)
  int v0, v1;                // pixel rows whose centres the polygon's bounding box spans
  double x[4], y[4];         // screen coordinates (pixels), positively oriented (E > 0 inside)
  double nu, nv, n0;         // (n . r(u, v)) / d = nu u + nv v + n0 = 1 / z at pixel (u, v)
  double cos_scale;          // -d / |n|: cos incidence = cos_scale (1 / z) / |r(u, v)|
  double wmin, wmax;         // 1 / zmax, 1 / zmin for the polygon's depth range [zmin, zmax] (1/m)
};

/// Builds the setup of face f. Returns false when it cannot cover any pixel centre (not
/// drawable, or its bounding box holds none). The common case -- wholly in front of the
/// near plane -- uses the cached projections directly and rejects by screen area and
/// bounding box before any 3-D work.
bool faceSetup(const Context& c, std::size_t f, FaceSetup& s) {
  const std::int32_t* idx = c.faces + 3 * f;
  const CachedVertex& A = c.v[idx[0]];
  const CachedVertex& B = c.v[idx[1]];
  const CachedVertex& C = c.v[idx[2]];
  Eigen::Vector3d normal;
  double area2, d, zmin, zmax;
  if (A.z >= c.near_clip && B.z >= c.near_clip && C.z >= c.near_clip) {
    // With every z > 0 the screen orientation has the sign of det[a b c] = d (see
    // facePolygon): positive for a back face. Zero area on screen covers no pixel centre.
    area2 = (B.sx - A.sx) * (C.sy - A.sy) - (B.sy - A.sy) * (C.sx - A.sx);
    if (!(area2 > 0.0 || area2 < 0.0) || (c.cull && area2 > 0.0)) return false;
    int u0, u1;
    pixelRange(std::min({A.sx, B.sx, C.sx}), std::max({A.sx, B.sx, C.sx}), c.cam.width, u0, u1);
    if (u0 > u1) return false;
    pixelRange(std::min({A.sy, B.sy, C.sy}), std::max({A.sy, B.sy, C.sy}), c.cam.height, s.v0, s.v1);
    if (s.v0 > s.v1) return false;
    const Eigen::Vector3d a(A.x, A.y, A.z), b(B.x, B.y, B.z), cc(C.x, C.y, C.z);
    normal = (b - a).cross(cc - a);
    d = normal.dot(a);
    if (!(d > 0.0 || d < 0.0) || !std::isfinite(d)) return false;
    s.n = 3;
    s.x[0] = A.sx; s.x[1] = B.sx; s.x[2] = C.sx;
    s.y[0] = A.sy; s.y[1] = B.sy; s.y[2] = C.sy;
    zmin = std::min({A.z, B.z, C.z});
    zmax = std::max({A.z, B.z, C.z});
  } else {
    Polygon poly;
    if (!facePolygon(c, f, poly)) return false;
    area2 = 0.0;  // shoelace; the clipped polygon is convex
    for (int k = 0; k < poly.n; ++k) {
      const int l = (k + 1) % poly.n;
      area2 += poly.x[k] * poly.y[l] - poly.x[l] * poly.y[k];
    }
    if (!(area2 > 0.0 || area2 < 0.0)) return false;
    int u0, u1;
    pixelRange(*std::min_element(poly.x, poly.x + poly.n), *std::max_element(poly.x, poly.x + poly.n), c.cam.width,
               u0, u1);
    if (u0 > u1) return false;
    pixelRange(*std::min_element(poly.y, poly.y + poly.n), *std::max_element(poly.y, poly.y + poly.n), c.cam.height,
               s.v0, s.v1);
    if (s.v0 > s.v1) return false;
    normal = poly.normal;
    d = poly.d;
    s.n = poly.n;
    std::copy(poly.x, poly.x + poly.n, s.x);
    std::copy(poly.y, poly.y + poly.n, s.y);
    zmin = poly.zmin;
    zmax = poly.zmax;
  }
  if (zmin > c.far_clip) return false;
  s.face = static_cast<std::int32_t>(f);
  if (area2 < 0.0) {  // reverse to positive orientation (keeps vertex 0 first)
    std::reverse(s.x + 1, s.x + s.n);
    std::reverse(s.y + 1, s.y + s.n);
  }
  // Ray through pixel (u, v): r = ((u - cx) / fx, (v - cy) / fy, 1); the face's plane
  // n . p = d is hit at z = d / (n . r), exactly. 1/z = (n . r) / d is linear in (u, v): the
  // z-buffer holds w = 1/z, so a pixel costs two multiply-adds and no division.
  const double inv_d = 1.0 / d;
  s.nu = normal.x() * c.inv_fx * inv_d;
  s.nv = normal.y() * c.inv_fy * inv_d;
  s.n0 = (normal.z() - normal.x() * c.inv_fx * c.cam.cx - normal.y() * c.inv_fy * c.cam.cy) * inv_d;
  s.cos_scale = -d / normal.norm();
  s.wmin = 1.0 / zmax;
  s.wmax = 1.0 / zmin;
  return true;
}

/// An edge function evaluated in the edge's canonical direction (lexicographically smaller
/// endpoint first) and flipped to the triangle's direction: the two triangles of a shared
/// edge compute exactly opposite values at every pixel centre.
struct Edge {
  double sx, sy;   // canonical start
  double ex, ey;   // canonical direction (end - start)
  double sign;     // +1 when the triangle walks the edge canonically, else -1
  bool top_left;   // centres exactly on the edge belong to this triangle

  Edge(double ax, double ay, double bx, double by) {
    // Top-left rule with x right, y down and interior where E > 0: an edge a->b whose
    // direction goes up the image (dy < 0) is a left edge, a horizontal one going right is a
    // top edge. Opposite directions never both qualify, so a shared edge has one owner.
    const double dx = bx - ax, dy = by - ay;
    top_left = (dy < 0.0) | ((dy == 0.0) & (dx > 0.0));
    // Selects rather than branches: which endpoint is canonical is a coin flip per edge.
    const bool canonical = (ax < bx) | ((ax == bx) & (ay <= by));
    sx = canonical ? ax : bx;
    sy = canonical ? ay : by;
    ex = canonical ? dx : -dx;
    ey = canonical ? dy : -dy;
    sign = canonical ? 1.0 : -1.0;
  }
  /// Row part of the canonical edge function at pixel row py.
  double row(double py) const { return ex * (py - sy); }
  /// Inside test at pixel column px given row(py); E(p) = (b - a) x (p - a).
  bool inside(double row_term, double px) const {
    const double e = sign * (row_term - ey * (px - sx));
    return (e > 0.0) | ((e == 0.0) & top_left);
  }
  /// Narrows the column range [lo, hi] of one row (given row(py)) to this edge's inside.
  /// Every floating-point step of inside() is monotone in px, so the inside columns form one
  /// interval: its end is estimated from the line equation, then settled with inside() itself,
  /// which makes the span identical to testing each pixel (typically 1-2 calls per row).
  void clip(double row_term, int& lo, int& hi) const {
    if (lo > hi) return;
    const double slope = -sign * ey;  // dE/du
    if (slope == 0.0) {               // horizontal edge: the same answer for the whole row
      if (!inside(row_term, lo)) hi = lo - 1;
      return;
    }
    double root = sx + row_term / ey;  // E = 0
    if (!(root >= lo - 1.0)) root = lo - 1.0;  // also NaN
    if (root > hi + 1.0) root = hi + 1.0;
    const int t = static_cast<int>(root);     // truncation; root is in [lo - 1, hi + 1]
    if (slope > 0.0) {                        // inside from some column on
      int b = t + (static_cast<double>(t) < root);  // ceil
      b = std::max(b, lo);
      while (b > lo && inside(row_term, b - 1)) --b;
      while (b <= hi && !inside(row_term, b)) ++b;
      lo = b;
    } else {                                  // inside up to some column
      int b = t - (static_cast<double>(t) > root);  // floor
      b = std::min(b, hi);
      while (b < hi && inside(row_term, b + 1)) ++b;
      while (b >= lo && !inside(row_term, b)) --b;
      hi = b;
    }
  }
};

struct BandBuffers {
  std::vector<double> w;            // 1 / depth (1/m); 0 = nothing yet
  std::vector<std::int32_t> id;     // face; -1 = nothing yet
  std::vector<double> cos_scale;    // FaceSetup::cos_scale of the visible face
};

/// Rasterises the triangle (X[k], Y[k]) (positively oriented) of face s.face, whose plane is
/// in `s`, into the band of rows [row0, row1].
void rasterTriangle(const Context& c, const FaceSetup& s, const double* X, const double* Y, int row0, int row1,
                    BandBuffers& band) {
  const std::int32_t f = s.face;
  int u0, u1, v0, v1;
  pixelRange(std::min({Y[0], Y[1], Y[2]}), std::max({Y[0], Y[1], Y[2]}), c.cam.height, v0, v1);
  v0 = std::max(v0, row0);
  v1 = std::min(v1, row1);
  if (v0 > v1) return;
  pixelRange(std::min({X[0], X[1], X[2]}), std::max({X[0], X[1], X[2]}), c.cam.width, u0, u1);
  if (u0 > u1) return;
  const Edge e0(X[0], Y[0], X[1], Y[1]), e1(X[1], Y[1], X[2], Y[2]), e2(X[2], Y[2], X[0], Y[0]);
  const int width = c.cam.width;
  for (int v = v0; v <= v1; ++v) {
    const double py = static_cast<double>(v);
    const double r0 = e0.row(py), r1 = e1.row(py), r2 = e2.row(py);
    const double row_w = s.nv * py + s.n0;
    const std::size_t row = static_cast<std::size_t>(v - row0) * width;
    double* wrow = band.w.data() + row;
    std::int32_t* idrow = band.id.data() + row;
    double* crow = band.cos_scale.data() + row;
    auto shade = [&](int u) {
      double w = s.nu * static_cast<double>(u) + row_w;  // 1 / z
      // A centre inside the projected polygon hits the plane within the polygon's depth
      // range; clamping only guards against round-off on near edge-on slivers.
      if (!(w >= s.wmin)) w = s.wmin;  // also catches NaN
      if (w > s.wmax) w = s.wmax;
      if (w < c.w_far) return;
      double& wb = wrow[u];
      if (w > wb || (w == wb && f < idrow[u])) {
        wb = w;
        idrow[u] = f;
        crow[u] = s.cos_scale;
      }
    };
    if (u1 - u0 < kSpanColumns) {
      // Small triangles: test each pixel (non-short-circuit &: these branches are unpredictable).
      for (int u = u0; u <= u1; ++u) {
        const double px = static_cast<double>(u);
        if (e0.inside(r0, px) & e1.inside(r1, px) & e2.inside(r2, px)) shade(u);
      }
    } else {
      // Wide triangles: find the row's span first (same decisions), then shade it.
      int lo = u0, hi = u1;
      e0.clip(r0, lo, hi);
      e1.clip(r1, lo, hi);
      e2.clip(r2, lo, hi);
      for (int u = lo; u <= hi; ++u) shade(u);
    }
  }
}

void checkInputs(std::size_t n_vertices, const std::int32_t* faces, std::size_t n_faces, const PinholeCamera& cam,
                 const Eigen::Matrix4d& T, const DepthRenderSettings& s, const DepthRenderResult& out) {
  constexpr int kMaxSize = 32768;
  if (cam.width < 1 || cam.height < 1 || cam.width > kMaxSize || cam.height > kMaxSize)
    throw std::invalid_argument("renderDepth: image size must be in [1, 32768] pixels, got " +
                                std::to_string(cam.width) + " x " + std::to_string(cam.height));
  checkImageSize(cam.width, cam.height, "renderDepth");  // at most kMaxImagePixels in all
  if (!(std::isfinite(cam.fx) && std::isfinite(cam.fy) && cam.fx > 0.0 && cam.fy > 0.0))
    throw std::invalid_argument("renderDepth: focal lengths fx, fy must be finite and positive (pixels)");
  if (!(std::isfinite(cam.cx) && std::isfinite(cam.cy)))
    throw std::invalid_argument("renderDepth: principal point cx, cy must be finite (pixels)");
  if (cam.hasDistortion())
    throw std::invalid_argument("renderDepth: the renderer draws pinhole images; give intrinsics without distortion");
  requireRigid(T, "renderDepth: T_camera_world");
  if (!(std::isfinite(s.near_clip) && s.near_clip > 0.0))
    throw std::invalid_argument("renderDepth: near_clip must be finite and positive (m)");
  if (!(s.far_clip > s.near_clip)) throw std::invalid_argument("renderDepth: far_clip must exceed near_clip (m)");
  if (s.num_threads < 0) throw std::invalid_argument("renderDepth: num_threads must be >= 0");
  if (out.depth == nullptr) throw std::invalid_argument("renderDepth: null depth output");
  if (n_faces > 0 && faces == nullptr) throw std::invalid_argument("renderDepth: null faces");
  if (n_faces > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw std::invalid_argument("renderDepth: too many faces for int32 face ids");
  for (std::size_t k = 0; k < 3 * n_faces; ++k) {
    const std::int32_t i = faces[k];
    if (i < 0 || static_cast<std::size_t>(i) >= n_vertices)
      throw std::invalid_argument("renderDepth: face " + std::to_string(k / 3) + " has vertex index " +
                                  std::to_string(i) + ", outside [0, " + std::to_string(n_vertices) + ")");
  }
}

}  // namespace

template <typename Scalar>
void renderDepth(const CloudView<Scalar>& vertices, const std::int32_t* faces, std::size_t n_faces,
                 const PinholeCamera& camera, const Eigen::Matrix4d& T_camera_world, const DepthRenderSettings& settings,
                 const DepthRenderResult& out) {
  checkInputs(vertices.size, faces, n_faces, camera, T_camera_world, settings, out);
  const int threads = resolveThreads(settings.num_threads);
  const int width = camera.width, height = camera.height;
  const std::size_t n_vertices = vertices.size;

  // 1. Vertices into the camera frame and onto the image, once each.
  std::vector<CachedVertex> cache(n_vertices);
  const Eigen::Matrix3d R = T_camera_world.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T_camera_world.topRightCorner<3, 1>();
  const double nan = std::numeric_limits<double>::quiet_NaN();
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(n_vertices); ++ii) {
    const std::size_t i = static_cast<std::size_t>(ii);
    CachedVertex& cv = cache[i];
    if (!vertices.isFinite(i)) {
      cv = {nan, nan, nan, nan, nan};
      continue;
    }
    const Scalar* p = vertices.ptr(i);
    const Eigen::Vector3d q = R * Eigen::Vector3d(double(p[0]), double(p[1]), double(p[2])) + t;
    // Projections of vertices behind the near plane are never used.
    cv = {q.x(), q.y(), q.z(), camera.fx * (q.x() / q.z()) + camera.cx, camera.fy * (q.y() / q.z()) + camera.cy};
  }

  const Context ctx{cache.data(),     faces,      camera, 1.0 / camera.fx, 1.0 / camera.fy, settings.near_clip,
                    settings.far_clip, 1.0 / settings.far_clip, settings.cull_backfaces};
  const int n_bands = (height + kBandRows - 1) / kBandRows;

  // 2. Set up every face that can cover a pixel centre (in parallel over contiguous face
  //    ranges, "chunks") and list it in each band of rows it spans. Each band reads the lists
  //    of chunks 0, 1, ... in turn, so it sees its faces in increasing order. The setups are
  //    kept so that the raster pass reads them instead of fetching the vertices again.
  const int chunks = std::max(1, std::min<int>(threads, static_cast<int>(n_faces / 1024) + 1));
  std::vector<std::vector<FaceSetup>> setups(chunks);
  std::vector<std::vector<std::uint32_t>> lists(static_cast<std::size_t>(chunks) * n_bands);  // [chunk][band]
  auto chunkBegin = [&](int k) { return n_faces * static_cast<std::size_t>(k) / static_cast<std::size_t>(chunks); };
#pragma omp parallel for schedule(static, 1) num_threads(threads)
  for (int k = 0; k < chunks; ++k) {
    std::vector<FaceSetup>& mine = setups[k];
    std::vector<std::uint32_t>* band_list = lists.data() + static_cast<std::size_t>(k) * n_bands;
    mine.reserve(chunkBegin(k + 1) - chunkBegin(k));  // untouched capacity costs no page faults
    FaceSetup s;
    const std::size_t f_end = chunkBegin(k + 1);
    for (std::size_t f = chunkBegin(k); f < f_end; ++f) {
      // The vertices of a face are scattered through the cache: fetch those of a face a few
      // iterations ahead so their latency overlaps this face's work.
#if defined(__GNUC__) || defined(__clang__)
      if (f + kPrefetch < f_end) {
        const std::int32_t* ahead = faces + 3 * (f + kPrefetch);
        __builtin_prefetch(&cache[static_cast<std::size_t>(ahead[0])]);
        __builtin_prefetch(&cache[static_cast<std::size_t>(ahead[1])]);
        __builtin_prefetch(&cache[static_cast<std::size_t>(ahead[2])]);
      }
#endif
      if (!faceSetup(ctx, f, s)) continue;
      const auto index = static_cast<std::uint32_t>(mine.size());
      mine.push_back(s);
      for (int b = s.v0 / kBandRows; b <= s.v1 / kBandRows; ++b) band_list[b].push_back(index);
    }
  }

  // 3. Rasterise each band on its own (no two threads touch the same pixel).
#pragma omp parallel num_threads(threads)
  {
    BandBuffers band;
    band.w.resize(static_cast<std::size_t>(kBandRows) * width);
    band.id.resize(band.w.size());
    band.cos_scale.resize(band.w.size());
#pragma omp for schedule(dynamic, 1)
    for (int b = 0; b < n_bands; ++b) {
      const int row0 = b * kBandRows, row1 = std::min(height - 1, row0 + kBandRows - 1);
      std::fill(band.w.begin(), band.w.end(), 0.0);
      std::fill(band.id.begin(), band.id.end(), -1);
      for (int chunk = 0; chunk < chunks; ++chunk)
        for (const std::uint32_t index : lists[static_cast<std::size_t>(chunk) * n_bands + b]) {
          const FaceSetup& setup = setups[chunk][index];
          // Fan from vertex 0; the diagonal (0, 2) of a clipped quad is shared by its two
          // halves and follows the same watertight rule.
          for (int k = 1; k + 1 < setup.n; ++k) {
            const double X[3] = {setup.x[0], setup.x[k], setup.x[k + 1]};
            const double Y[3] = {setup.y[0], setup.y[k], setup.y[k + 1]};
            rasterTriangle(ctx, setup, X, Y, row0, row1, band);
          }
        }
      // Depth and cosine of the visible surface: one division and one square root per
      // covered pixel, none per tested one.
      const float nanf = std::numeric_limits<float>::quiet_NaN();
      for (int v = row0; v <= row1; ++v) {
        const std::size_t k0 = static_cast<std::size_t>(v - row0) * width;
        const std::size_t o0 = static_cast<std::size_t>(v) * width;
        const double ry = (v - camera.cy) * ctx.inv_fy;
        for (int u = 0; u < width; ++u) {
          const std::size_t k = k0 + u;
          const bool hit = band.id[k] >= 0;
          out.depth[o0 + u] = hit ? static_cast<float>(1.0 / band.w[k]) : nanf;
          if (out.face_id) out.face_id[o0 + u] = band.id[k];
          if (out.cos_incidence) {
            const double rx = (u - camera.cx) * ctx.inv_fx;
            out.cos_incidence[o0 + u] =
                hit ? static_cast<float>(band.cos_scale[k] * band.w[k] / std::sqrt(rx * rx + ry * ry + 1.0)) : 0.0f;
          }
        }
      }
    }
  }
}

template <typename Scalar>
DepthImage renderDepth(const CloudView<Scalar>& vertices, const std::vector<std::int32_t>& faces,
                       const PinholeCamera& camera, const Eigen::Matrix4d& T_camera_world,
                       const DepthRenderSettings& settings) {
  if (faces.size() % 3 != 0) throw std::invalid_argument("renderDepth: faces must hold 3 indices per triangle");
  DepthImage img;
  if (camera.width < 1 || camera.height < 1 || camera.width > 32768 || camera.height > 32768)
    throw std::invalid_argument("renderDepth: image size must be in [1, 32768] pixels");
  checkImageSize(camera.width, camera.height, "renderDepth");  // before allocating the images
  img.width = camera.width;
  img.height = camera.height;
  const std::size_t n = static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
  img.depth.resize(n);
  img.face_id.resize(n);
  img.cos_incidence.resize(n);
  renderDepth(vertices, faces.data(), faces.size() / 3, camera, T_camera_world, settings,
              DepthRenderResult{img.depth.data(), img.face_id.data(), img.cos_incidence.data()});
  return img;
}

#define SCANALIGN_INSTANTIATE(S)                                                                               \
  template void renderDepth<S>(const CloudView<S>&, const std::int32_t*, std::size_t, const PinholeCamera&,    \
                               const Eigen::Matrix4d&, const DepthRenderSettings&, const DepthRenderResult&);  \
  template DepthImage renderDepth<S>(const CloudView<S>&, const std::vector<std::int32_t>&, const PinholeCamera&, \
                                     const Eigen::Matrix4d&, const DepthRenderSettings&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
