#pragma once
// Private helpers shared by the curve projection sources (circular clipping, Ma & Hewitt).

#include <cstdint>

#include "nurbsreg/engine/curve_projection.hpp"

namespace nurbsreg::engine::detail {

struct LocalMinimum {
  double t = 0.0;   // local parameter of the piece
  double d2 = 0.0;  // squared distance
  Vec3 point;       // C(t) relative to the piece's origin
};

// Local t of a piece -> parent u (the ends map exactly onto the piece's interval ends).
double piece_parameter(const PreparedCurvePiece& pc, double t);

// Replaces `best` when d2 is smaller; `local_point` is C(t) relative to pc.origin.
bool offer(const PreparedCurvePiece& pc, double t, double d2, const Vec3& local_point,
           CurveHit& best);

// Minimum of |C(t) - q|^2 on [lo, hi] when g = (C - q).C' changes sign once there, from
// - to + (seed 002: "the hybrid method of [24]", Ye 1994). q is relative to pc.origin;
// `t` is the starting guess. Adds the evaluations to `iterations`.
LocalMinimum safeguarded_newton(const PreparedCurvePiece& pc, const Vec3& q, double lo, double hi,
                                double t, std::uint64_t& iterations);

}  // namespace nurbsreg::engine::detail
