// Conformal geometric algebra G(4,1): a general multivector over the 32 basis blades
// (Kleppe, PhD thesis, NTNU 2018, equations (4.40)-(4.51)).
//
// Storage and products use the orthonormal basis e1, e2, e3, e+, e- (e+^2 = 1, e-^2 = -1,
// (4.40)-(4.43)); blade k of the storage is the outer product of the vectors whose bits are
// set in k (bit 0 = e1, 1 = e2, 2 = e3, 3 = e+, 4 = e-), in that order. The user-facing
// basis is the null basis (4.44)-(4.46)
//     e0 = 1/2 (e- - e+),   einf = e- + e+,   e0^2 = einf^2 = 0,   e0 . einf = -1,
// with blades named by their vectors in the order e0, e1, e2, e3, einf ("e0", "e12",
// "e1inf", "e0123inf", ...); nullCoefficients() / fromNull() convert.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <Eigen/Core>
#include <Eigen/LU>

namespace scanalign::cga {

namespace detail {

constexpr int popcount(unsigned v) {
  int n = 0;
  while (v) {
    n += static_cast<int>(v & 1u);
    v >>= 1;
  }
  return n;
}

/// Sign of the product of two orthonormal basis blades (canonical reordering times the
/// metric of the shared vectors; only e- (bit 4) squares to -1).
constexpr int bladeSign(unsigned a, unsigned b) {
  int swaps = 0;
  unsigned x = a >> 1;
  while (x) {
    swaps += popcount(x & b);
    x >>= 1;
  }
  int s = (swaps & 1) ? -1 : 1;
  if ((a & b) & 16u) s = -s;
  return s;
}

struct Tables {
  std::array<std::array<signed char, 32>, 32> sign{};
  std::array<signed char, 32> grade{};
};

constexpr Tables makeTables() {
  Tables t{};
  for (unsigned a = 0; a < 32; ++a) {
    t.grade[a] = static_cast<signed char>(popcount(a));
    for (unsigned b = 0; b < 32; ++b) t.sign[a][b] = static_cast<signed char>(bladeSign(a, b));
  }
  return t;
}

inline constexpr Tables kTables = makeTables();

}  // namespace detail

/// A general element of G(4,1). Units: whatever the embedded objects carry (metres).
class Multivector {
 public:
  using Coeffs = Eigen::Matrix<double, 32, 1>;

  Multivector() : c_(Coeffs::Zero()) {}
  explicit Multivector(double scalar) : c_(Coeffs::Zero()) { c_[0] = scalar; }
  /// From coefficients in the orthonormal bitmask basis (see the file comment).
  static Multivector fromOrthonormal(const Coeffs& c) {
    Multivector m;
    m.c_ = c;
    return m;
  }
  const Coeffs& orthonormal() const { return c_; }
  Coeffs& orthonormal() { return c_; }

  // ----- basis vectors (4.44) -----
  static Multivector blade(unsigned bits, double v = 1.0) {
    Multivector m;
    m.c_[bits] = v;
    return m;
  }
  static Multivector e1() { return blade(1); }
  static Multivector e2() { return blade(2); }
  static Multivector e3() { return blade(4); }
  static Multivector ePlus() { return blade(8); }
  static Multivector eMinus() { return blade(16); }
  static Multivector e0() { return blade(16, 0.5) - blade(8, 0.5); }   // (4.44)
  static Multivector eInf() { return blade(16) + blade(8); }           // (4.44)
  /// Euclidean vector x e1 + y e2 + z e3.
  static Multivector vector(const Eigen::Vector3d& v) {
    Multivector m;
    m.c_[1] = v.x();
    m.c_[2] = v.y();
    m.c_[4] = v.z();
    return m;
  }
  /// Conformal pseudoscalar Ic = e0^e1^e2^e3^einf = e1 e2 e3 e+ e- (4.48)-(4.49).
  static Multivector pseudoscalar() { return blade(31); }
  /// Euclidean pseudoscalar I3 = e123.
  static Multivector pseudoscalar3() { return blade(7); }

  // ----- linear operations -----
  Multivector operator+(const Multivector& o) const { return fromOrthonormal(c_ + o.c_); }
  Multivector operator-(const Multivector& o) const { return fromOrthonormal(c_ - o.c_); }
  Multivector operator-() const { return fromOrthonormal(-c_); }
  Multivector operator*(double s) const { return fromOrthonormal(c_ * s); }
  Multivector operator/(double s) const { return fromOrthonormal(c_ / s); }
  friend Multivector operator*(double s, const Multivector& m) { return m * s; }
  Multivector& operator+=(const Multivector& o) {
    c_ += o.c_;
    return *this;
  }
  Multivector& operator-=(const Multivector& o) {
    c_ -= o.c_;
    return *this;
  }

  // ----- products (4.18)-(4.22) -----
  /// Geometric product.
  Multivector operator*(const Multivector& o) const { return product<0>(o); }
  /// Outer product: <A_r B_s>_{r+s}.
  Multivector outer(const Multivector& o) const { return product<1>(o); }
  /// "Fat"/Hestenes inner product A_r . B_s = <A_r B_s>_{|r-s|}, zero when either grade is 0
  /// (thesis (4.21), as CluCalc; the same convention as the `clifford` package's `|`).
  Multivector inner(const Multivector& o) const { return product<2>(o); }
  /// Left contraction A_r _| B_s = <A_r B_s>_{s-r} (zero for r > s).
  Multivector leftContraction(const Multivector& o) const { return product<3>(o); }
  /// Scalar product <A B>_0.
  double scalarProduct(const Multivector& o) const {
    double s = 0;
    for (unsigned a = 0; a < 32; ++a) s += c_[a] * o.c_[a] * detail::kTables.sign[a][a];
    return s;
  }

  // ----- unary operations -----
  /// Reverse: <A>_k -> (-1)^{k(k-1)/2} <A>_k (4.32).
  Multivector reverse() const {
    Multivector m;
    for (unsigned a = 0; a < 32; ++a) {
      const int k = detail::kTables.grade[a];
      m.c_[a] = ((k * (k - 1) / 2) & 1) ? -c_[a] : c_[a];
    }
    return m;
  }
  Multivector operator~() const { return reverse(); }
  /// Grade involution: <A>_k -> (-1)^k <A>_k.
  Multivector involute() const {
    Multivector m;
    for (unsigned a = 0; a < 32; ++a) m.c_[a] = (detail::kTables.grade[a] & 1) ? -c_[a] : c_[a];
    return m;
  }
  /// Grade projection <A>_k.
  Multivector grade(int k) const {
    Multivector m;
    for (unsigned a = 0; a < 32; ++a)
      if (detail::kTables.grade[a] == k) m.c_[a] = c_[a];
    return m;
  }
  double scalar() const { return c_[0]; }
  /// Dual A* = A Ic^{-1} = -A Ic (4.50).
  Multivector dual() const { return -(*this * pseudoscalar()); }
  /// Undual A = A* Ic (4.51).
  Multivector undual() const { return *this * pseudoscalar(); }
  /// sqrt(|<A ~A>_0|) (Paper 1 §3.7 normalisation).
  double norm() const { return std::sqrt(std::abs(scalarProduct(reverse()))); }
  /// Largest absolute coefficient (orthonormal basis), for tolerances.
  double maxAbs() const { return c_.cwiseAbs().maxCoeff(); }
  bool allFinite() const { return c_.allFinite(); }

  /// Inverse. For versors and blades A^{-1} = ~A / (A ~A) (4.34); for any other invertible
  /// multivector the linear system A X = 1 is solved. Throws std::domain_error when A is
  /// not invertible (e.g. a null vector).
  Multivector inverse() const {
    if (!allFinite()) throw std::domain_error("cga: inverse of a non-finite multivector");
    const Multivector r = reverse();
    const Multivector aa = *this * r;
    const double s = aa.c_[0];
    const double scale = std::max(maxAbs() * maxAbs(), 1e-300);
    Multivector rest = aa;
    rest.c_[0] = 0;
    if (std::abs(s) > 1e-12 * scale && rest.maxAbs() <= 1e-12 * scale) return r / s;
    Eigen::Matrix<double, 32, 32> L;  // left multiplication by A
    for (unsigned b = 0; b < 32; ++b) L.col(b) = (*this * blade(b)).c_;
    Eigen::FullPivLU<Eigen::Matrix<double, 32, 32>> lu(L);
    lu.setThreshold(1e-12);
    if (!lu.isInvertible()) throw std::domain_error("cga: multivector is not invertible");
    Coeffs one = Coeffs::Zero();
    one[0] = 1;
    return fromOrthonormal(lu.solve(one));
  }

  // ----- null basis (e0, e1, e2, e3, einf) -----
  /// Number of the null-basis blade: bit 0 = e0, 1 = e1, 2 = e2, 3 = e3, 4 = einf.
  static std::string nullBladeName(unsigned bits) {
    if (bits == 0) return "1";
    static const char* names[5] = {"0", "1", "2", "3", "inf"};
    std::string s = "e";
    for (int i = 0; i < 5; ++i)
      if (bits & (1u << i)) s += names[i];
    return s;
  }
  /// Coefficients on the 32 null-basis blades (index = nullBladeName bits).
  Coeffs nullCoefficients() const { return basis().toNull * c_; }
  static Multivector fromNull(const Coeffs& n) { return fromOrthonormal(basis().toOrtho * n); }

  /// Coefficient of a blade given by name, e.g. "e0", "e12", "e1inf", "e123inf", "einf0"
  /// (a permuted name gives the signed coefficient of that ordering).
  double get(const std::string& name) const {
    int sign = 1;
    const unsigned bits = parseName(name, sign);
    return sign * nullCoefficients()[bits];
  }
  /// Multivector of one named null-basis blade times v.
  static Multivector named(const std::string& name, double v = 1.0) {
    int sign = 1;
    const unsigned bits = parseName(name, sign);
    Coeffs n = Coeffs::Zero();
    n[bits] = sign * v;
    return fromNull(n);
  }

 private:
  template <int Kind>
  Multivector product(const Multivector& o) const {
    Multivector m;
    const auto& T = detail::kTables;
    for (unsigned a = 0; a < 32; ++a) {
      const double x = c_[a];
      if (x == 0) continue;
      const int ga = T.grade[a];
      for (unsigned b = 0; b < 32; ++b) {
        const double y = o.c_[b];
        if (y == 0) continue;
        const unsigned r = a ^ b;
        if constexpr (Kind == 1) {
          if (a & b) continue;
        } else if constexpr (Kind == 2) {
          const int gb = T.grade[b];
          if (ga == 0 || gb == 0 || T.grade[r] != std::abs(ga - gb)) continue;
        } else if constexpr (Kind == 3) {
          if (T.grade[r] != T.grade[b] - ga) continue;
        }
        m.c_[r] += T.sign[a][b] * x * y;
      }
    }
    return m;
  }

  struct Basis {
    Eigen::Matrix<double, 32, 32> toOrtho, toNull;
  };
  static const Basis& basis() {
    static const Basis B = [] {
      Basis b;
      const Multivector vecs[5] = {e0(), e1(), e2(), e3(), eInf()};
      for (unsigned bits = 0; bits < 32; ++bits) {
        Multivector m(1.0);
        for (int i = 0; i < 5; ++i)
          if (bits & (1u << i)) m = m.outer(vecs[i]);
        b.toOrtho.col(bits) = m.c_;
      }
      b.toNull = b.toOrtho.inverse();
      return b;
    }();
    return B;
  }
  static unsigned parseName(const std::string& name, int& sign) {
    if (name == "1" || name == "") {
      sign = 1;
      return 0;
    }
    if (name.empty() || name[0] != 'e') throw std::invalid_argument("cga: bad blade name '" + name + "'");
    int order[5];
    int n = 0;
    for (std::size_t i = 1; i < name.size();) {
      int idx;
      if (name.compare(i, 3, "inf") == 0) {
        idx = 4;
        i += 3;
      } else if (name[i] >= '0' && name[i] <= '3') {
        idx = name[i] - '0';
        i += 1;
      } else {
        throw std::invalid_argument("cga: bad blade name '" + name + "' (use e0, e1, e2, e3, einf)");
      }
      for (int k = 0; k < n; ++k)
        if (order[k] == idx) throw std::invalid_argument("cga: repeated vector in blade name '" + name + "'");
      if (n == 5) throw std::invalid_argument("cga: bad blade name '" + name + "'");
      order[n++] = idx;
    }
    if (n == 0) throw std::invalid_argument("cga: bad blade name '" + name + "'");
    int inversions = 0;
    unsigned bits = 0;
    for (int i = 0; i < n; ++i) {
      bits |= 1u << order[i];
      for (int j = i + 1; j < n; ++j) inversions += order[i] > order[j];
    }
    sign = (inversions & 1) ? -1 : 1;
    return bits;
  }

  Coeffs c_;
};

}  // namespace scanalign::cga
