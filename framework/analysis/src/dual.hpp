#pragma once
// Private to vibro_analysis: dual numbers a + b ε (ε² = 0) for forward-mode differentiation.
//
// The event resets (restitution law, chatter rule, projection onto the held stops) and the
// constrained generators of linearisation.cpp are written once, as templates over the scalar
// type. Evaluated in double they give values; evaluated in Dual with the inputs seeded along a
// direction (a state perturbation δz, a time shift, or a parameter direction dD of the system
// data) they give the exact directional derivative of the same code, to rounding, with no step
// size and no hand-derived formula that could drift from what the code computes.
//
// Eigen works with the type through NumTraits (below); decompositions of Dual matrices
// (LLT, PartialPivLU) differentiate the factorisation itself, which is exact for the solves
// they are used for here.
#include <Eigen/Core>

#include <cmath>

namespace vibro::detail {

struct Dual {
  double v = 0.0;  ///< value
  double d = 0.0;  ///< derivative (coefficient of ε)

  constexpr Dual() = default;
  constexpr Dual(double value) : v(value) {}  // NOLINT(google-explicit-constructor): a constant
  constexpr Dual(double value, double derivative) : v(value), d(derivative) {}

  Dual& operator+=(const Dual& o) { v += o.v; d += o.d; return *this; }
  Dual& operator-=(const Dual& o) { v -= o.v; d -= o.d; return *this; }
  Dual& operator*=(const Dual& o) { d = d * o.v + v * o.d; v *= o.v; return *this; }
  Dual& operator/=(const Dual& o) {
    const double q = v / o.v;
    d = (d - q * o.d) / o.v;
    v = q;
    return *this;
  }
};

inline Dual operator+(Dual a, const Dual& b) { return a += b; }
inline Dual operator-(Dual a, const Dual& b) { return a -= b; }
inline Dual operator*(Dual a, const Dual& b) { return a *= b; }
inline Dual operator/(Dual a, const Dual& b) { return a /= b; }
inline Dual operator-(const Dual& a) { return {-a.v, -a.d}; }
inline Dual operator+(const Dual& a) { return a; }
inline bool operator<(const Dual& a, const Dual& b) { return a.v < b.v; }
inline bool operator>(const Dual& a, const Dual& b) { return a.v > b.v; }
inline bool operator<=(const Dual& a, const Dual& b) { return a.v <= b.v; }
inline bool operator>=(const Dual& a, const Dual& b) { return a.v >= b.v; }
inline bool operator==(const Dual& a, const Dual& b) { return a.v == b.v && a.d == b.d; }
inline bool operator!=(const Dual& a, const Dual& b) { return !(a == b); }

inline Dual sqrt(const Dual& a) {
  const double s = std::sqrt(a.v);
  return {s, a.d / (2.0 * s)};
}
inline Dual abs(const Dual& a) { return a.v < 0.0 ? -a : a; }
inline Dual abs2(const Dual& a) { return a * a; }
inline Dual conj(const Dual& a) { return a; }
inline Dual real(const Dual& a) { return a; }
inline Dual imag(const Dual&) { return 0.0; }
inline Dual cos(const Dual& a) { return {std::cos(a.v), -std::sin(a.v) * a.d}; }
inline Dual sin(const Dual& a) { return {std::sin(a.v), std::cos(a.v) * a.d}; }
inline Dual exp(const Dual& a) {
  const double e = std::exp(a.v);
  return {e, e * a.d};
}
inline bool isfinite(const Dual& a) { return std::isfinite(a.v) && std::isfinite(a.d); }
inline bool isnan(const Dual& a) { return std::isnan(a.v) || std::isnan(a.d); }
inline bool isinf(const Dual& a) { return std::isinf(a.v) || std::isinf(a.d); }

/// Value and derivative of a scalar that may be double or Dual (generic code reads both).
inline double value_of(double a) { return a; }
inline double value_of(const Dual& a) { return a.v; }
inline double derivative_of(double) { return 0.0; }
inline double derivative_of(const Dual& a) { return a.d; }

}  // namespace vibro::detail

namespace Eigen {

template <>
struct NumTraits<vibro::detail::Dual> : NumTraits<double> {
  using Real = vibro::detail::Dual;
  using NonInteger = vibro::detail::Dual;
  using Nested = vibro::detail::Dual;
  using Literal = vibro::detail::Dual;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = 2,
    AddCost = 2,
    MulCost = 4
  };
  static inline Real epsilon() { return NumTraits<double>::epsilon(); }
  static inline Real dummy_precision() { return NumTraits<double>::dummy_precision(); }
  static inline Real highest() { return NumTraits<double>::highest(); }
  static inline Real lowest() { return NumTraits<double>::lowest(); }
  static inline int digits10() { return NumTraits<double>::digits10(); }
};

template <typename BinaryOp>
struct ScalarBinaryOpTraits<vibro::detail::Dual, double, BinaryOp> {
  using ReturnType = vibro::detail::Dual;
};
template <typename BinaryOp>
struct ScalarBinaryOpTraits<double, vibro::detail::Dual, BinaryOp> {
  using ReturnType = vibro::detail::Dual;
};

}  // namespace Eigen
