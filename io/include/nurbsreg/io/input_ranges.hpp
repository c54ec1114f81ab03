#pragma once
// The numeric ranges the exact projection can stand behind (README "Coordinate range"). Models
// and scans outside them are rejected at load (InputError naming the entity and field, or the
// point), instead of yielding NaN rows or endless searches.
//
// Why these bounds. The engine works on squared distances: per Bézier patch it caches
// G = sum c w_a w_b P_a.P_b, E = sum c w_a w_b (P_a + P_b)/2 and W = sum c w_a w_b, and a point q
// costs G - 2 q.E + |q|^2 W per coefficient (DESIGN.md); the convexity tests take second
// differences of these coefficients (factors up to (2p)(2p - 1) <= 552 at degree 12, times 4
// for the differences), and Newton's 2 x 2 systems multiply two such second derivatives. With
// every |coordinate| <= C and every weight in [1/R, R]:
//   |coefficient| <= 12 C^2 R^2, |second difference| <= 2.7e4 C^2 R^2,
//   Newton's determinant <= (2.7e4 C^2 R^2)^2 / h^4 for the smallest knot span h.
// C = 1e15 and R = 1e10 give coefficients <= 1.2e51 and determinants <= 1e111 / h^4: with
// h >= 1e-40 below, finite with more than 40 orders of magnitude to spare (double overflows at
// 1.8e308). Coordinates near 1e150 (as a fuzzed model had) square to 1e300 and overflow at the
// first product: NaN distances, or bounds that never prune. C = 1e15 is also where a double
// still resolves an eighth of a unit (ulp(1e15) = 0.125): any physical part in mm (or m) is far
// inside it, while a point there carries no usable precision anyway.
// Knots obey the same C (a parameter range is added to and multiplied with coordinates in the
// trim curves' uv space) and their non-empty spans must be at least kMinKnotSpan, so that the
// derivatives S_u ~ p C / h and their products stay finite as above.

namespace nurbsreg::io {

inline constexpr double kMaxCoordinate = 1e15;  // |x|, |y|, |z| of control points and scan points
inline constexpr double kMaxKnot = 1e15;        // |knot value|
inline constexpr double kMinKnotSpan = 1e-40;   // width of a non-empty knot span
inline constexpr double kMinWeight = 1e-10;     // weights in [kMinWeight, kMaxWeight]
inline constexpr double kMaxWeight = 1e10;

}  // namespace nurbsreg::io
