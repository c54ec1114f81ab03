#pragma once
// Knot insertion and Bézier decomposition (The NURBS Book A5.1/A5.4; seed paper 000 §3.3).
// These run once per model (preparation), not per point; they allocate.

#include <span>
#include <vector>

#include "nurbsreg/engine/bezier.hpp"
#include "nurbsreg/engine/nurbs_curve.hpp"
#include "nurbsreg/engine/nurbs_surface.hpp"

namespace nurbsreg::engine {

// Inserts the sorted values `insert` (each inside the domain) into the knot vector (A5.4,
// knot refinement). The curve is unchanged as a function of u.
NurbsCurve refine_knots(const NurbsCurve& curve, std::span<const double> insert);
// Inserts u `times` times (Boehm).
NurbsCurve insert_knot(const NurbsCurve& curve, double u, int times);
// The same curve on its domain with clamped end knots (multiplicity degree + 1).
NurbsCurve clamp(const NurbsCurve& curve);

// The surface with the sorted values `insert` added to its u (or v) knots: the same function of
// (u, v), the same trim loops and orientation.
NurbsSurface refine_knots_u(const NurbsSurface& surface, std::span<const double> insert);
NurbsSurface refine_knots_v(const NurbsSurface& surface, std::span<const double> insert);
NurbsSurface clamp(const NurbsSurface& surface);
// The surface on the rectangle u x v of its domain (non-empty, within it): the same function of
// (u, v) there, clamped end knots at the rectangle's sides; trim loops dropped, orientation kept.
NurbsSurface restrict_domain(const NurbsSurface& surface, ParamInterval u, ParamInterval v);

// One rational Bézier piece per non-empty knot span of the domain, in parameter order.
std::vector<BezierCurve> decompose(const NurbsCurve& curve);
// One rational Bézier patch per non-empty span pair; patch (a, b) at [a * spans_v + b].
// spans_u / spans_v receive the numbers of non-empty spans when non-null.
std::vector<BezierPatch> decompose(const NurbsSurface& surface, int* spans_u = nullptr,
                                   int* spans_v = nullptr);

}  // namespace nurbsreg::engine
