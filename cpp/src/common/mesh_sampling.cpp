#include "scanalign/common/mesh_sampling.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <Eigen/Geometry>  // cross()

namespace scanalign {

namespace {

// NumPy's SeedSequence (numpy/random/bit_generator.pyx), after O'Neill's seed_seq: the
// seed's 32-bit words hashed into a pool of 4 words, which then give the state words.
constexpr std::uint32_t kInitA = 0x43b0d7e5, kMultA = 0x931e8875, kInitB = 0x8b51f9dd, kMultB = 0x58f38ded;
constexpr std::uint32_t kMixMultL = 0xca01f9dd, kMixMultR = 0x4973f715;

std::uint32_t hashmix(std::uint32_t value, std::uint32_t& hash_const) {
  value ^= hash_const;
  hash_const *= kMultA;
  value *= hash_const;
  return value ^ (value >> 16);
}

std::uint32_t mix(std::uint32_t x, std::uint32_t y) {
  const std::uint32_t r = kMixMultL * x - kMixMultR * y;
  return r ^ (r >> 16);
}

/// SeedSequence(seed).generate_state(4, uint64).
void seedSequence(std::uint64_t seed, std::uint64_t out[4]) {
  std::vector<std::uint32_t> entropy;  // the seed's 32-bit words, least significant first
  if (seed == 0) entropy.push_back(0);
  for (std::uint64_t n = seed; n > 0; n >>= 32) entropy.push_back(static_cast<std::uint32_t>(n));
  std::uint32_t pool[4];
  std::uint32_t hash_const = kInitA;
  for (std::size_t i = 0; i < 4; ++i) pool[i] = hashmix(i < entropy.size() ? entropy[i] : 0u, hash_const);
  for (std::size_t src = 0; src < 4; ++src)
    for (std::size_t dst = 0; dst < 4; ++dst)
      if (src != dst) pool[dst] = mix(pool[dst], hashmix(pool[src], hash_const));
  // (A seed has at most 2 words: no entropy beyond the pool is left to mix in.)
  std::uint32_t words[8];
  std::uint32_t hash_b = kInitB;
  for (std::size_t i = 0; i < 8; ++i) {
    std::uint32_t v = pool[i % 4];
    v ^= hash_b;
    hash_b *= kMultB;
    v *= hash_b;
    words[i] = v ^ (v >> 16);
  }
  for (std::size_t i = 0; i < 4; ++i) out[i] = words[2 * i] | (std::uint64_t{words[2 * i + 1]} << 32);
}

constexpr unsigned __int128 kPcgMultiplier =
    (static_cast<unsigned __int128>(2549297995355413924ull) << 64) | 4865540595714422341ull;

/// NumPy's pairwise summation of a contiguous array (numpy/_core/src/umath/loops_utils.h):
/// blocks of up to 128 summed in 8 interleaved partial sums, larger arrays split in two.
double pairwiseSum(const double* a, std::size_t n) {
  if (n < 8) {
    double s = 0.0;
    for (std::size_t i = 0; i < n; ++i) s += a[i];
    return s;
  }
  if (n <= 128) {
    double r[8];
    for (int j = 0; j < 8; ++j) r[j] = a[j];
    std::size_t i = 8;
    for (; i < n - n % 8; i += 8)
      for (int j = 0; j < 8; ++j) r[j] += a[i + static_cast<std::size_t>(j)];
    double s = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) s += a[i];
    return s;
  }
  std::size_t half = n / 2;
  half -= half % 8;
  return pairwiseSum(a, half) + pairwiseSum(a + half, n - half);
}

}  // namespace

Pcg64::Pcg64(std::uint64_t seed) {
  std::uint64_t s[4];
  seedSequence(seed, s);
  const unsigned __int128 initstate = (static_cast<unsigned __int128>(s[0]) << 64) | s[1];
  const unsigned __int128 initseq = (static_cast<unsigned __int128>(s[2]) << 64) | s[3];
  // pcg_setseq_128_srandom_r
  state_ = 0;
  increment_ = (initseq << 1) | 1u;
  state_ = state_ * kPcgMultiplier + increment_;
  state_ += initstate;
  state_ = state_ * kPcgMultiplier + increment_;
}

std::uint64_t Pcg64::next() {
  state_ = state_ * kPcgMultiplier + increment_;
  // XSL-RR: the xor of the two halves rotated right by the top 6 bits.
  const auto x = static_cast<std::uint64_t>(state_ >> 64) ^ static_cast<std::uint64_t>(state_);
  const auto rot = static_cast<unsigned>(state_ >> 122);
  return (x >> rot) | (x << ((64u - rot) & 63u));
}

MeshSampler::MeshSampler(const CloudView<double>& vertices, const std::int64_t* faces, std::size_t n_faces) {
  if (n_faces > 0 && faces == nullptr) throw std::invalid_argument("mesh sampling: null faces");
  a_.resize(n_faces);
  ab_.resize(n_faces);
  ac_.resize(n_faces);
  normal_.resize(n_faces);
  std::vector<double> double_area(n_faces);
  const auto n_vertices = static_cast<std::int64_t>(vertices.size);
  for (std::size_t f = 0; f < n_faces; ++f) {
    Eigen::Vector3d corner[3];
    for (int k = 0; k < 3; ++k) {
      const std::int64_t v = faces[3 * f + static_cast<std::size_t>(k)];
      if (v < 0 || v >= n_vertices)
        throw std::invalid_argument("mesh sampling: face " + std::to_string(f) + " has the vertex index " +
                                    std::to_string(v) + " outside [0, " + std::to_string(n_vertices) + ")");
      if (!vertices.isFinite(static_cast<std::size_t>(v)))
        throw std::invalid_argument("mesh sampling: face " + std::to_string(f) + " uses the non-finite vertex " +
                                    std::to_string(v));
      corner[k] = vertices[static_cast<std::size_t>(v)];
    }
    a_[f] = corner[0];
    ab_[f] = corner[1] - corner[0];
    ac_[f] = corner[2] - corner[0];
    const Eigen::Vector3d cross = ab_[f].cross(ac_[f]);
    double_area[f] = std::sqrt((cross.x() * cross.x() + cross.y() * cross.y()) + cross.z() * cross.z());
    normal_[f] = cross / double_area[f];  // NaN for a zero-area face, which is never drawn
  }
  // The weights area / total area, their running sum normalised to end at 1: the cdf
  // NumPy's Generator.choice searches (the total summed pairwise, as NumPy's sum()).
  const double total = 0.0 + pairwiseSum(double_area.data(), n_faces);
  if (!(total > 0.0)) throw std::invalid_argument("mesh has zero total area; cannot sample its surface");
  cdf_.resize(n_faces);
  double running = 0.0;
  for (std::size_t f = 0; f < n_faces; ++f) cdf_[f] = running += double_area[f] / total;
  const double last = cdf_.back();
  for (double& c : cdf_) c /= last;
}

void MeshSampler::draw(Pcg64& rng, std::size_t n, MeshSamples& out) const {
  const std::size_t first = out.size();
  out.points.resize(first + n);
  out.normals.resize(first + n);
  out.faces.resize(first + n);
  for (std::size_t i = first; i < first + n; ++i) {
    // The first face whose cumulative weight exceeds the draw (< 1 = the last weight): a
    // zero-area face repeats its predecessor's weight and is never the first to exceed it.
    const double u = rng.uniform();
    out.faces[i] = static_cast<std::int64_t>(std::upper_bound(cdf_.begin(), cdf_.end(), u) - cdf_.begin());
  }
  std::vector<double> s(n);
  for (double& x : s) x = std::sqrt(rng.uniform());
  for (std::size_t k = 0; k < n; ++k) {
    const double t = rng.uniform();
    const std::size_t i = first + k;
    const auto f = static_cast<std::size_t>(out.faces[i]);
    const double wb = s[k] * (1.0 - t), wc = s[k] * t;
    for (int r = 0; r < 3; ++r) out.points[i][r] = (a_[f][r] + wb * ab_[f][r]) + wc * ac_[f][r];
    out.normals[i] = normal_[f];
  }
}

MeshSamples sampleMesh(const CloudView<double>& vertices, const std::int64_t* faces, std::size_t n_faces,
                       std::size_t n_points, std::uint64_t seed) {
  const MeshSampler sampler(vertices, faces, n_faces);
  Pcg64 rng(seed);
  MeshSamples out;
  sampler.draw(rng, n_points, out);
  return out;
}

}  // namespace scanalign
