#pragma once
// Private: the two stages of Ma & Hewitt's method (seed paper 000), so that the whole-curve
// projector can pick the nearest candidate over all pieces before running Newton, as the
// paper does (§6: "we select the nearest point from candidate points and improve its accuracy
// by applying the Newton-Raphson method").

#include <cstdint>
#include <limits>

#include "curve/curve_local_solve.hpp"

namespace nurbsreg::engine::detail {

struct MaHewittCandidate {
  double t = 0.0;  // local parameter of the piece
  double d2 = std::numeric_limits<double>::infinity();
  bool found = false;
};

// Algorithm 5 over one piece (q relative to pc.origin): keeps the nearest candidate in `best`.
void ma_hewitt_candidates(const PreparedCurvePiece& pc, const Vec3& q, MaHewittCandidate& best,
                          CurveProjectionStats& stats);

// Newton-Raphson from local t, clamped to the piece.
LocalMinimum ma_hewitt_newton(const PreparedCurvePiece& pc, const Vec3& q, double t,
                              std::uint64_t& iterations);

}  // namespace nurbsreg::engine::detail
