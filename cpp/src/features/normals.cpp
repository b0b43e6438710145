#include "scanalign/features/normals.hpp"
#include "scanalign/common/interrupt.hpp"
#include "scanalign/common/threads.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "scanalign/common/radix_sort.hpp"

namespace scanalign {

void validate(const NormalEstimationSettings& settings) {
  if (!(settings.radius > 0.0) || !std::isfinite(settings.radius))
    throw std::invalid_argument("normal estimation: radius must be a finite positive distance in metres");
  if (!settings.viewpoint.allFinite()) throw std::invalid_argument("normal estimation: viewpoint must be finite");
  if (settings.min_neighbors < 3) throw std::invalid_argument("normal estimation: min_neighbors must be >= 3");
  if (settings.num_threads < 0) throw std::invalid_argument("normal estimation: num_threads must be >= 0");
  if (settings.grid_subdivisions < 0 || settings.grid_subdivisions > 16)
    throw std::invalid_argument("normal estimation: grid_subdivisions must be in [0, 16] (0 = automatic)");
}

namespace {

void validateSettings(const NormalEstimationSettings& settings) { validate(settings); }

/// Normal (and curvature) of point q from the moments of its neighbours' offsets d = p - q:
/// s1 = sum d, s2 = sum d d^T, k neighbours. Writes NaN when k < min_neighbors.
template <typename Scalar>
void finishNormal(const Scalar* q, const Eigen::Vector3d& s1, const Eigen::Matrix3d& s2, int k,
                  const NormalEstimationSettings& settings, Scalar* out, Scalar* curvature) {
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  out[0] = out[1] = out[2] = nan;
  if (curvature) *curvature = nan;
  if (k < settings.min_neighbors) return;
  const Eigen::Vector3d mean = s1 / k;
  const Eigen::Matrix3d cov = s2 / k - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(cov);
  Eigen::Vector3d n = eig.eigenvectors().col(0);
  const Eigen::Vector3d to_view = settings.viewpoint - Eigen::Vector3d(q[0], q[1], q[2]);
  if (n.dot(to_view) < 0.0) n = -n;
  n.normalize();
  out[0] = static_cast<Scalar>(n.x());
  out[1] = static_cast<Scalar>(n.y());
  out[2] = static_cast<Scalar>(n.z());
  if (curvature) {
    const Eigen::Vector3d lambda = eig.eigenvalues().cwiseMax(0.0);
    const double sum = lambda.sum();
    *curvature = static_cast<Scalar>(sum > 0.0 ? lambda(0) / sum : 0.0);
  }
}

/// Points at which the shell buffers are padded to whole vectors: far outside any ball.
template <typename T>
constexpr T kFarAway = T(1e15);

/// Moments of the points (px, py, pz)[0, n) within sqrt(r2) of q, about q, added to out:
/// count, x y z, xx xy xz yy yz zz. n must be a multiple of kLanes<T> (pad with kFarAway).
/// Branch-free on whole SIMD vectors of Bytes bytes (GCC/Clang vector extensions:
/// compilers do not vectorise these floating-point sums by themselves, as that reorders
/// them); the lanes are summed in a fixed order, so results do not depend on threads (the
/// lane count, 8 with AVX2 else 4 for float, changes only the rounding of the sums).
#if defined(__GNUC__)
constexpr std::size_t kVectorBytes = 32;  // the padding unit: whole AVX vectors
template <typename T>
constexpr std::size_t kLanes = kVectorBytes / sizeof(T);

template <typename T, std::size_t Bytes>
__attribute__((always_inline)) inline void ballMomentsKernel(const T* px, const T* py, const T* pz, std::size_t n,
                                                             T qx, T qy, T qz, T r2, double* out) {
  typedef T V __attribute__((vector_size(Bytes)));
  constexpr std::size_t L = Bytes / sizeof(T);
  V a0 = {}, a1 = {}, a2 = {}, a3 = {}, a4 = {}, a5 = {}, a6 = {}, a7 = {}, a8 = {}, a9 = {};
  const V one = V{} + T(1), zero = {};
  for (std::size_t t = 0; t < n; t += L) {
    V x, y, z;
    std::memcpy(&x, px + t, sizeof(V));
    std::memcpy(&y, py + t, sizeof(V));
    std::memcpy(&z, pz + t, sizeof(V));
    const V dx = x - qx, dy = y - qy, dz = z - qz;
    const V w = dx * dx + dy * dy + dz * dz <= r2 ? one : zero;
    const V wx = w * dx, wy = w * dy, wz = w * dz;
    a0 += w;
    a1 += wx;
    a2 += wy;
    a3 += wz;
    a4 += wx * dx;
    a5 += wx * dy;
    a6 += wx * dz;
    a7 += wy * dy;
    a8 += wy * dz;
    a9 += wz * dz;
  }
  const V acc[10] = {a0, a1, a2, a3, a4, a5, a6, a7, a8, a9};
  for (int k = 0; k < 10; ++k)
    for (std::size_t l = 0; l < L; ++l) out[k] += acc[k][l];
}

#if defined(__x86_64__) || defined(__i386__)
template <typename T>
__attribute__((target("avx2"))) void ballMomentsAvx2(const T* px, const T* py, const T* pz, std::size_t n, T qx,
                                                     T qy, T qz, T r2, double* out) {
  ballMomentsKernel<T, 32>(px, py, pz, n, qx, qy, qz, r2, out);
}
#endif

template <typename T>
void addBallMoments(const T* px, const T* py, const T* pz, std::size_t n, T qx, T qy, T qz, T r2, double* out) {
#if defined(__x86_64__) || defined(__i386__)
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2) return ballMomentsAvx2<T>(px, py, pz, n, qx, qy, qz, r2, out);
#endif
  ballMomentsKernel<T, 16>(px, py, pz, n, qx, qy, qz, r2, out);
}
#else
template <typename T>
constexpr std::size_t kLanes = 1;
template <typename T>
void addBallMoments(const T* px, const T* py, const T* pz, std::size_t n, T qx, T qy, T qz, T r2, double* out) {
  for (std::size_t t = 0; t < n; ++t) {
    const T dx = px[t] - qx, dy = py[t] - qy, dz = pz[t] - qz;
    if (!(dx * dx + dy * dy + dz * dz <= r2)) continue;
    out[0] += 1;
    out[1] += dx, out[2] += dy, out[3] += dz;
    out[4] += dx * dx, out[5] += dx * dy, out[6] += dx * dz, out[7] += dy * dy, out[8] += dy * dz, out[9] += dz * dz;
  }
}
#endif

/// Cells per radius for gridNormals. A query costs about one test per point in the band of
/// cells its sphere crosses plus some work per cell nearby: the band narrows and the cells
/// multiply as the cells shrink. Measured on 1 mm-gridded scans (40k points, radii 5, 10
/// and 20 mm), the time is lowest when a cell holds about 20 points; on a surface a
/// cell's population falls with the square of its edge, so D = sqrt(N_r / 20) where N_r
/// is the mean number of points sharing a point's radius-sized cell, estimated here from
/// up to 4096 evenly spaced points (a cheap estimate is enough: the time varies slowly
/// around the optimum). Any D gives the same normals; only the speed depends on it.
template <typename Offset>
int chooseSubdivisions(std::size_t m, double r, Offset offset) {
  const std::size_t samples = std::min<std::size_t>(m, 4096);
  const double inv = 1.0 / r;
  std::vector<std::uint64_t> keys(samples);  // cells packed 21 bits per axis (wrapping: rare merges)
  for (std::size_t s = 0; s < samples; ++s) {
    const std::size_t j = s * m / samples;
    keys[s] = 0;
    for (int k = 0; k < 3; ++k) {
      const double v = offset(j, k) * inv;
      const auto c = static_cast<std::uint64_t>(std::abs(v) < 1e15 ? static_cast<std::int64_t>(std::floor(v)) : 0);
      keys[s] |= (c & 0x1FFFFF) << (21 * k);
    }
  }
  std::sort(keys.begin(), keys.end());
  double pairs = 0.0;  // sum over the samples of the other samples in the same cell
  for (std::size_t a = 0; a < samples;) {
    std::size_t b = a;
    while (b < samples && keys[b] == keys[a]) ++b;
    pairs += double(b - a) * double(b - a - 1);
    a = b;
  }
  const double fraction = double(samples) / double(m);
  const double population = 1.0 + pairs / double(samples) / fraction;
  return static_cast<int>(std::clamp(std::lround(std::sqrt(population / 20.0)), 1L, 8L));
}

/// One cell of the moment grid: its points' count, centroid and second moments about the
/// centroid (double), and the tight bounding box of its points; offsets from the cloud's
/// first finite point (m).
struct MomentCell {
  double lo[3], hi[3];
  double c[3];
  double s2[6];  // xx xy xz yy yz zz
  std::uint32_t start, count;
};

/// Radius-neighbourhood PCA from a grid of cells of edge radius / D that keeps, per cell,
/// the count, the centroid c and the second moments S2 about it (double), and the bounding
/// box of its points. Why: at the demo's 10 mm radius on a 1 mm grid a point has ~300
/// neighbours among ~1200 candidates in the 27 radius-sized cells around it, and testing
/// every candidate one by one was the whole cost of normals (95 ms a frame). Here the
/// cells near a query cell Q are split once against Q's whole box: a cell whose every point
/// is within the radius of every point of Q adds its moments for all of Q's queries at once
/// (summed about Q's centroid, then moved to each query by the parallel-axis theorem:
/// sum (p - q) = n (c - q), sum (p - q)(p - q)^T = S2 + n (c - q)(c - q)^T); a cell out of
/// reach of all of Q is dropped; only the points of the cells in between (a shell a few
/// millimetres thick) are tested against each query, branch-free on SIMD vectors.
///
/// Exactness: the neighbour set is that of the brute-force test |p - q|^2 <= radius^2.
/// Whole cells are taken or dropped only with a relative margin of 1e-12 in the squared
/// distance, far above the rounding of that test, so every point of such a cell gets the
/// answer the test would give it; the shell points are tested in the cloud's precision on
/// offsets from Q's centroid. All cell moments are double; the shell's are summed in the
/// cloud's precision (as the k-d tree path tests in it). So a double cloud gets the
/// brute-force PCA up to double rounding, and a float cloud up to float rounding: only
/// points within about 1e-6 r^2 of the sphere may be counted differently, and the shell
/// sums carry float rounding (about 1e-7 of r^2 per term). The time, not the result,
/// depends on D. Points are sorted by cell so each cell is contiguous; the rows of cells
/// (same y and z) near a row of query cells are looked up once per row (through a dense
/// table, else by binary search) and walked with a sliding window along x.
/// Returns false (nothing written) when the cloud's extent needs more than 2^21 cells
/// along an axis; the caller then uses the k-d tree.
template <typename Scalar>
bool gridNormals(const CloudView<Scalar>& points, const NormalEstimationSettings& settings, int subdivisions,
                 Scalar* normals, Scalar* curvature) {
  const double r = settings.radius, r2 = r * r;
  std::vector<std::uint32_t> finite;
  finite.reserve(points.size);
  for (std::size_t i = 0; i < points.size; ++i)
    if (points.isFinite(i)) finite.push_back(static_cast<std::uint32_t>(i));
  if (finite.empty()) return true;
  const Scalar* origin = points.ptr(finite[0]);
  const double o[3] = {double(origin[0]), double(origin[1]), double(origin[2])};
  auto offset = [&](std::uint32_t i, int k) { return double(points.ptr(i)[k]) - o[k]; };
  const std::size_t m = finite.size();
  if (subdivisions <= 0)
    subdivisions = chooseSubdivisions(m, r, [&](std::size_t j, int k) { return offset(finite[j], k); });
  const int R = subdivisions;  // neighbour cells lie within R cells along each axis
  const double h = r / subdivisions, inv = 1.0 / h;
  std::vector<std::int64_t> icell(3 * m);
  std::int64_t lo[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, hi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
  for (std::size_t j = 0; j < m; ++j)
    for (int k = 0; k < 3; ++k) {
      const double v = offset(finite[j], k) * inv;
      if (!(std::abs(v) < 1e15)) return false;
      std::int64_t c = static_cast<std::int64_t>(v);  // floor, without a libm call
      c -= static_cast<double>(c) > v;
      icell[3 * j + k] = c;
      lo[k] = std::min(lo[k], icell[3 * j + k]);
      hi[k] = std::max(hi[k], icell[3 * j + k]);
    }
  constexpr std::int64_t kAxis = std::int64_t{1} << 21;
  for (int k = 0; k < 3; ++k)
    if (hi[k] - lo[k] + 2 * R + 1 >= kAxis) {
      // Too many cells along this axis for the packed keys (a far outlier, or a radius tiny
      // next to the extent). Close the empty gaps instead: every run of more than R + 1
      // empty cell coordinates shrinks to R + 1. Two occupied coordinates are then within
      // R of each other exactly when they were before (a shrunk gap alone exceeds R), and
      // only such pairs are ever compared, on the points' true coordinates; so the normals
      // are unchanged. Without this the k-d tree path below took over, and with a radius
      // spanning most of the cloud it visits N neighbours per point (200k points: minutes).
      std::vector<std::int64_t> used(m);
      for (std::size_t j = 0; j < m; ++j) used[j] = icell[3 * j + k];
      std::sort(used.begin(), used.end());
      used.erase(std::unique(used.begin(), used.end()), used.end());
      std::vector<std::int64_t> packed(used.size(), 0);
      for (std::size_t u = 1; u < used.size(); ++u)
        packed[u] = packed[u - 1] + std::min<std::int64_t>(used[u] - used[u - 1], R + 1);
      for (std::size_t j = 0; j < m; ++j)
        icell[3 * j + k] = packed[std::lower_bound(used.begin(), used.end(), icell[3 * j + k]) - used.begin()];
      lo[k] = 0;
      hi[k] = packed.back();
      if (hi[k] - lo[k] + 2 * R + 1 >= kAxis) return false;  // room for the +-R neighbours
    }
  auto key = [](std::uint64_t x, std::uint64_t y, std::uint64_t z) { return (z << 42) | (y << 21) | x; };
  // Sort by cell (z, y, x) on compact keys (a few radix passes), then keep the packed keys.
  const auto span_x = static_cast<std::uint64_t>(hi[0] - lo[0] + 1);
  const auto span_y = static_cast<std::uint64_t>(hi[1] - lo[1] + 1);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(m);
  for (std::size_t j = 0; j < m; ++j) {
    std::uint64_t u[3];
    for (int k = 0; k < 3; ++k) u[k] = static_cast<std::uint64_t>(icell[3 * j + k] - lo[k]);
    keyed[j] = {(u[2] * span_y + u[1]) * span_x + u[0], static_cast<std::uint32_t>(j)};
  }
  radixSortByKey(keyed);
  for (auto& [k, j] : keyed) {
    const std::int64_t* c = &icell[3 * std::size_t{j}];
    k = key(static_cast<std::uint64_t>(c[0] - lo[0] + R), static_cast<std::uint64_t>(c[1] - lo[1] + R),
            static_cast<std::uint64_t>(c[2] - lo[2] + R));
    j = finite[j];
  }
  std::vector<std::int64_t>().swap(icell);
  // Sorted offsets, one array per axis so the point tests vectorise.
  std::vector<double> X(m), Y(m), Z(m);
  for (std::size_t j = 0; j < m; ++j) {
    X[j] = offset(keyed[j].second, 0);
    Y[j] = offset(keyed[j].second, 1);
    Z[j] = offset(keyed[j].second, 2);
  }
  // Cells with their moments, and rows of cells (same y and z).
  std::vector<std::uint64_t> cell_keys;
  std::vector<MomentCell> cells;
  for (std::size_t j = 0; j < m; ++j)
    if (j == 0 || keyed[j].first != keyed[j - 1].first) {
      cell_keys.push_back(keyed[j].first);
      cells.push_back(MomentCell{});
      cells.back().start = static_cast<std::uint32_t>(j);
    }
  const std::size_t nc = cells.size();
  for (std::size_t cc = 0; cc < nc; ++cc) {
    MomentCell& c = cells[cc];
    const std::uint32_t a = c.start, b = cc + 1 < nc ? cells[cc + 1].start : static_cast<std::uint32_t>(m);
    c.count = b - a;
    double sum[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      c.lo[k] = std::numeric_limits<double>::infinity();
      c.hi[k] = -std::numeric_limits<double>::infinity();
    }
    for (std::uint32_t t = a; t < b; ++t) {
      const double p[3] = {X[t], Y[t], Z[t]};
      for (int k = 0; k < 3; ++k) {
        sum[k] += p[k];
        c.lo[k] = std::min(c.lo[k], p[k]);
        c.hi[k] = std::max(c.hi[k], p[k]);
      }
    }
    for (int k = 0; k < 3; ++k) c.c[k] = sum[k] / c.count;
    for (double& v : c.s2) v = 0.0;
    for (std::uint32_t t = a; t < b; ++t) {
      const double dx = X[t] - c.c[0], dy = Y[t] - c.c[1], dz = Z[t] - c.c[2];
      c.s2[0] += dx * dx;
      c.s2[1] += dx * dy;
      c.s2[2] += dx * dz;
      c.s2[3] += dy * dy;
      c.s2[4] += dy * dz;
      c.s2[5] += dz * dz;
    }
  }
  std::vector<std::uint64_t> row_keys;
  std::vector<std::uint32_t> row_start;
  for (std::size_t cc = 0; cc < nc; ++cc)
    if (cc == 0 || (cell_keys[cc] >> 21) != (cell_keys[cc - 1] >> 21)) {
      row_keys.push_back(cell_keys[cc] >> 21);
      row_start.push_back(static_cast<std::uint32_t>(cc));
    }
  row_start.push_back(static_cast<std::uint32_t>(nc));
  // Dense (y, z) -> row table when small (the usual case: a scan's extent over a few
  // hundred cells); otherwise binary search over the sorted row keys.
  const std::uint64_t ny = static_cast<std::uint64_t>(hi[1] - lo[1] + 2 * R + 1);
  const std::uint64_t nz = static_cast<std::uint64_t>(hi[2] - lo[2] + 2 * R + 1);
  std::vector<std::int32_t> row_table;
  if (ny * nz <= (std::uint64_t{1} << 22) && row_keys.size() < std::size_t{INT32_MAX}) {
    row_table.assign(ny * nz, -1);
    for (std::size_t rr = 0; rr < row_keys.size(); ++rr)
      row_table[(row_keys[rr] >> 21) * ny + (row_keys[rr] & 0x1FFFFF)] = static_cast<std::int32_t>(rr);
  }
  auto findRow = [&](std::uint64_t y, std::uint64_t z) -> std::ptrdiff_t {
    if (!row_table.empty()) return row_table[z * ny + y];
    const std::uint64_t rk = (z << 21) | y;
    auto it = std::lower_bound(row_keys.begin(), row_keys.end(), rk);
    return it != row_keys.end() && *it == rk ? it - row_keys.begin() : -1;
  };
  const double r2_in = r2 * (1.0 - 1e-12), r2_out = r2 * (1.0 + 1e-12);
  const std::size_t nrows = row_keys.size();
  const int threads = resolveThreads(settings.num_threads);
  // Ctrl-C (common/interrupt.hpp): the calling thread (OpenMP thread 0) asks between rows
  // and raises a flag that makes every thread skip the remaining rows; thrown after the region.
  std::atomic<bool> interrupted{false};
#pragma omp parallel num_threads(threads)
  {
    struct Window {
      std::uint32_t next, end;  // cells of one neighbour row not yet passed
    };
    std::vector<Window> windows;
    std::vector<std::uint32_t> ambiguous;  // cells the sphere may cross for some query of Q
    std::vector<Scalar> bx, by, bz;        // their points, about Q's centroid
#pragma omp for schedule(dynamic, 1)
    for (std::ptrdiff_t qr = 0; qr < static_cast<std::ptrdiff_t>(nrows); ++qr) {
      if (interrupted.load(std::memory_order_relaxed)) continue;
      if (omp_get_thread_num() == 0 && interruptRequested()) {
        interrupted.store(true, std::memory_order_relaxed);
        continue;
      }
      // The rows of cells that can hold neighbours of this row's cells.
      const std::uint64_t y = row_keys[qr] & 0x1FFFFF, z = row_keys[qr] >> 21;
      windows.clear();
      for (std::int64_t dz = -R; dz <= R; ++dz) {
        const double gz = static_cast<double>(std::max<std::int64_t>(std::abs(dz) - 1, 0)) * h;
        for (std::int64_t dy = -R; dy <= R; ++dy) {
          const double gy = static_cast<double>(std::max<std::int64_t>(std::abs(dy) - 1, 0)) * h;
          if (gz * gz + gy * gy > r2_out) continue;
          const std::ptrdiff_t row = findRow(y + dy, z + dz);
          if (row >= 0) windows.push_back({row_start[row], row_start[row + 1]});
        }
      }
      for (std::uint32_t qc = row_start[qr]; qc < row_start[qr + 1]; ++qc) {
        const MomentCell& Q = cells[qc];
        const std::uint64_t x = cell_keys[qc] & 0x1FFFFF;
        // Cells within R along x of each neighbour row, split against Q's whole box: inside
        // for every query of Q (summed once, about Q's centroid), outside for all (dropped),
        // or ambiguous (classified per query below).
        double A[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};  // n, x y z, xx xy xz yy yz zz about Q.c
        ambiguous.clear();
        std::size_t nb = 0;
        for (Window& w : windows) {
          while (w.next < w.end && (cell_keys[w.next] & 0x1FFFFF) + R < x) ++w.next;
          for (std::uint32_t c = w.next; c < w.end && (cell_keys[c] & 0x1FFFFF) <= x + R; ++c) {
            const MomentCell& C = cells[c];
            double near2 = 0.0, far2 = 0.0;
            for (int k = 0; k < 3; ++k) {
              const double below = C.lo[k] - Q.hi[k], above = Q.lo[k] - C.hi[k];
              const double g = below > 0.0 ? below : (above > 0.0 ? above : 0.0);
              const double f = std::max(C.hi[k] - Q.lo[k], Q.hi[k] - C.lo[k]);
              near2 += g * g;
              far2 += f * f;
            }
            if (near2 > r2_out) continue;
            if (far2 > r2_in) {
              ambiguous.push_back(c);
              nb += C.count;
              continue;
            }
            const double n = C.count;
            const double dx = C.c[0] - Q.c[0], dy = C.c[1] - Q.c[1], dz = C.c[2] - Q.c[2];
            A[0] += n;
            A[1] += n * dx;
            A[2] += n * dy;
            A[3] += n * dz;
            A[4] += C.s2[0] + n * dx * dx;
            A[5] += C.s2[1] + n * dx * dy;
            A[6] += C.s2[2] + n * dx * dz;
            A[7] += C.s2[3] + n * dy * dy;
            A[8] += C.s2[4] + n * dy * dz;
            A[9] += C.s2[5] + n * dz * dz;
          }
        }
        // The ambiguous cells' points about Q's centroid, padded to whole vectors.
        const std::size_t padded = (nb + kLanes<Scalar> - 1) / kLanes<Scalar> * kLanes<Scalar>;
        bx.resize(padded);
        by.resize(padded);
        bz.resize(padded);
        {
          std::size_t t = 0;
          for (const std::uint32_t c : ambiguous)
            for (std::uint32_t u = cells[c].start; u < cells[c].start + cells[c].count; ++u, ++t) {
              bx[t] = static_cast<Scalar>(X[u] - Q.c[0]);
              by[t] = static_cast<Scalar>(Y[u] - Q.c[1]);
              bz[t] = static_cast<Scalar>(Z[u] - Q.c[2]);
            }
          for (; t < padded; ++t) bx[t] = by[t] = bz[t] = kFarAway<Scalar>;
        }
        for (std::uint32_t j = Q.start; j < Q.start + Q.count; ++j) {
          const double qx = X[j], qy = Y[j], qz = Z[j];
          // The cells inside for all of Q, moved from Q's centroid to q.
          double count = A[0];
          double s[9];
          {
            const double ex = Q.c[0] - qx, ey = Q.c[1] - qy, ez = Q.c[2] - qz;
            s[0] = A[1] + A[0] * ex;
            s[1] = A[2] + A[0] * ey;
            s[2] = A[3] + A[0] * ez;
            s[3] = A[4] + 2.0 * A[1] * ex + A[0] * ex * ex;
            s[4] = A[5] + A[1] * ey + A[2] * ex + A[0] * ex * ey;
            s[5] = A[6] + A[1] * ez + A[3] * ex + A[0] * ex * ez;
            s[6] = A[7] + 2.0 * A[2] * ey + A[0] * ey * ey;
            s[7] = A[8] + A[2] * ez + A[3] * ey + A[0] * ey * ez;
            s[8] = A[9] + 2.0 * A[3] * ez + A[0] * ez * ez;
          }
          // The points of the ambiguous cells, each tested against q's ball.
          double shell[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
          addBallMoments<Scalar>(bx.data(), by.data(), bz.data(), bx.size(), static_cast<Scalar>(qx - Q.c[0]),
                                 static_cast<Scalar>(qy - Q.c[1]), static_cast<Scalar>(qz - Q.c[2]),
                                 static_cast<Scalar>(r2), shell);
          count += shell[0];
          for (int k = 0; k < 9; ++k) s[k] += shell[k + 1];
          const Eigen::Vector3d s1(s[0], s[1], s[2]);
          Eigen::Matrix3d s2;
          s2 << s[3], s[4], s[5], s[4], s[6], s[7], s[5], s[7], s[8];
          const std::uint32_t i = keyed[j].second;
          finishNormal(points.ptr(i), s1, s2, static_cast<int>(count + 0.5), settings, normals + 3 * i,
                       curvature ? curvature + i : nullptr);
        }
      }
    }
  }
  if (interrupted.load()) throw Interrupted();
  return true;
}

}  // namespace

template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const LeftBalancedKdTree<Scalar>& tree,
                     const NormalEstimationSettings& settings, Scalar* normals, Scalar* curvature) {
  validateSettings(settings);
  if (points.size > 0 && normals == nullptr) throw std::invalid_argument("normal estimation: null output");
  const Scalar r2 = static_cast<Scalar>(settings.radius * settings.radius);
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  const int threads = resolveThreads(settings.num_threads);
  // In chunks, so that Ctrl-C is honoured between them (common/interrupt.hpp; never inside
  // the parallel region).
  constexpr std::size_t kChunk = 16384;
  for (std::size_t first = 0; first < points.size; first += kChunk) {
    checkInterrupt();
    const auto last = static_cast<std::ptrdiff_t>(std::min(points.size, first + kChunk));
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
    for (std::ptrdiff_t ii = static_cast<std::ptrdiff_t>(first); ii < last; ++ii) {
      const std::size_t i = static_cast<std::size_t>(ii);
      Scalar* out = normals + 3 * i;
      out[0] = out[1] = out[2] = nan;
      if (curvature) curvature[i] = nan;
      if (!points.isFinite(i)) continue;
      const Scalar* q = points.ptr(i);
      // Moments about the query point (not the origin) to avoid cancellation far from it.
      Eigen::Vector3d s1 = Eigen::Vector3d::Zero();
      Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
      int k = 0;
      tree.forEachInRadius(q, r2, [&](std::uint32_t node, Scalar) {
        const Scalar* p = tree.node(node).p;
        const Eigen::Vector3d d(double(p[0]) - q[0], double(p[1]) - q[1], double(p[2]) - q[2]);
        s1 += d;
        s2.noalias() += d * d.transpose();
        ++k;
      });
      finishNormal(q, s1, s2, k, settings, out, curvature ? curvature + i : nullptr);
    }
  }
}

template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const NormalEstimationSettings& settings, Scalar* normals,
                     Scalar* curvature) {
  validateSettings(settings);
  if (points.size > 0 && normals == nullptr) throw std::invalid_argument("normal estimation: null output");
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  for (std::size_t i = 0; i < points.size; ++i) {
    normals[3 * i] = normals[3 * i + 1] = normals[3 * i + 2] = nan;
    if (curvature) curvature[i] = nan;
  }
  if (gridNormals(points, settings, settings.grid_subdivisions, normals, curvature)) return;
  LeftBalancedKdTree<Scalar> tree(points);
  estimateNormals(points, tree, settings, normals, curvature);
}

#define SCANALIGN_INSTANTIATE(S)                                                                              \
  template void estimateNormals<S>(const CloudView<S>&, const NormalEstimationSettings&, S*, S*);             \
  template void estimateNormals<S>(const CloudView<S>&, const LeftBalancedKdTree<S>&,                         \
                                   const NormalEstimationSettings&, S*, S*);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
