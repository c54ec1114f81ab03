#pragma once
// Modification of a NURBS curve through the "nose points" of its segments (seed paper 004,
// Lu & Huang 1998, "Modification of a NURBS curve with nose features").
//
// A segment is a non-empty knot span. Each segment has one nose point C(t_j) and, optionally, a
// target P_j. Every operation below rests on the exact identity (paper eq. 2, re-derived in
// curve_modification.cpp): with S_j = sum_i N_i(t_j) W_i,
//
//   sum_i N_i(t_j) (W_i + dW_i) dB_i + sum_i N_i(t_j) dW_i (B_i - P_j) = S_j (P_j - C(t_j)),
//
// which holds if and only if the modified curve passes through P_j at the same parameter t_j.
// Consequences used here:
//   - control-point movement with fixed weights (eqs. 3-7) is an exact *linear* problem: solved
//     exactly (square system, degree 2) or with the minimum-norm exact solution (degree >= 3);
//   - weight changes with fixed control points (eqs. 8-13) are exact only along u_j (the
//     direction from P_j to the segment's nose control point); the sideways (v_j) error is why
//     the paper iterates (Table 1) and why the local form (eqs. 16-19) exists;
//   - joining-knot positioning (eqs. 20-21, Appendix A11-A16) is exact for quadratic curves
//     when the old joining point still lies on the new control-polygon edge (always true after
//     weight-only changes).
//
// All functions are pure: they take a curve by const reference and return a new one. They
// allocate (small dense systems with Eigen); none is on a per-point hot path. Thread-safe.
//
// Degrees: the paper works with order 3 (degree 2). Nose points, eqs. 5 and 7, eq. 13 and
// Process 1 are implemented for every degree (see each function for what changes); the local
// weight form (eqs. 16-19) and joining-knot positioning (eqs. 20-21) need degree 2, a clamped
// knot vector and simple interior knots, and report `applicable == false` otherwise.

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/nurbs_curve.hpp"

namespace nurbsreg::engine {

// How the nose point of a segment is chosen (paper, section "Nose points").
enum class NoseRule {
  // The curve point at the mean parameter of the segment's two joining points (the paper's
  // definition).
  mean_parameter,
  // The paper's alternative: the curve point of the segment nearest to the segment's nose
  // control point (its "second governing control point").
  nearest_to_control_point,
};

// One non-empty knot span [knots[span], knots[span + 1]].
struct CurveSegment {
  int span = 0;
  ParamInterval param;
};

// The non-empty knot spans of the curve's domain, in parameter order (segment j = 0, 1, ...).
std::vector<CurveSegment> curve_segments(const NurbsCurve& curve);

// The control point that governs a segment's nose: index span - ceil(degree / 2). For degree 2
// and 3 this is the paper's "second governing control point" (B_{j+1} for segment j, 1-based);
// for higher degrees it is the central one, whose basis function dominates mid-span.
int nose_control_index(const NurbsCurve& curve, int span);

struct NosePoint {
  int segment = 0;
  int span = 0;
  double u = 0.0;        // parameter t_pj
  Vec3 point;            // C(t_pj)
  int nose_control = 0;  // nose_control_index(curve, span)
};

// Nose points of every segment. With nearest_to_control_point the nearest point is found by
// sampling plus safeguarded Newton on (C - B)·C' = 0 inside the span, end points included.
std::vector<NosePoint> nose_points(const NurbsCurve& curve,
                                   NoseRule rule = NoseRule::mean_parameter);

// Joining points C(knots[span + 1]) between consecutive segments (n - 1 points for n segments).
std::vector<Vec3> joining_points(const NurbsCurve& curve);

// Result of one modification step.
struct StepResult {
  NurbsCurve curve;
  // False when the operation cannot be applied to this curve (the reason is in `message`);
  // `curve` is then the input unchanged.
  bool applicable = true;
  // True when the linear system was consistent and solved exactly (residual <= 1e-10 relative).
  bool exact = false;
  // Relative residual of the solved linear system (0 when square and well conditioned).
  double residual = 0.0;
  // Control-point displacements dB_i or weight changes dW_i actually applied (one per control
  // point; zero where not changed).
  std::vector<Vec3> delta_points;
  std::vector<double> delta_weights;
  // Weight changes of eq. 13 before Process 1 (empty for other operations).
  std::vector<double> delta_weights_eq13;
  std::string message;
};

// Eq. 5: moves only the nose control point of segment `nose.segment` so that the curve passes
// exactly through `target` at nose.u (weights unchanged). Neighbouring nose points move too.
StepResult move_nose_control_point(const NurbsCurve& curve, const NosePoint& nose,
                                   const Vec3& target);

// Eqs. 6-7: moves every control point except the first and last (which stay fixed, as in the
// paper) so that every nose point lands on its target at the same parameter. `targets[j]` is the
// target of noses[j]; pass the nose point itself to hold a segment in place. Degree 2 with simple
// knots gives the paper's square tridiagonal system (exact LU solve); more free control points
// than segments give the minimum-norm exact solution; fewer (degree 1) give least squares, and
// `exact` says whether it was exact.
StepResult move_control_points(const NurbsCurve& curve, std::span<const NosePoint> noses,
                               std::span<const Vec3> targets);

struct WeightOptions {
  // Apply Process 1 when eq. 13 yields a weight <= min_weight_ratio * max weight.
  bool process1 = true;
  double min_weight_ratio = 1e-6;
};

// Eqs. 8-13 (+ Process 1): changes the weights of all control points except the first and last
// so that, for every segment, the nose point moves to its target along u_j = (B_nose - P_j)/|.|
// exactly (eq. 10); the component along v_j is not controlled. If a new weight is not positive,
// Process 1 re-allocates the changes inside the null space of the eq. 10 rows (so eq. 10 still
// holds exactly for every segment) and may change the end weights; `message` says which
// allocation was used. If no positive allocation exists, `applicable` is false.
StepResult change_weights(const NurbsCurve& curve, std::span<const NosePoint> noses,
                          std::span<const Vec3> targets, const WeightOptions& options = {});

// The local form, eqs. 16-19 (degree 2 only): eq. 13 with only `segment` moving (the other
// targets are the current nose points), then the outer two weights of that segment re-allocated
// so that the u_j equation still holds and the sideways forces balance (eq. 12). Exact when the
// target lies on the line through the nose point and the nose control point (the paper's
// assumption) and the curve is planar.
StepResult change_weights_local(const NurbsCurve& curve, std::span<const NosePoint> noses,
                                std::span<const Vec3> targets, int segment);

// Eqs. 20-21: new knot spans so that the curve's joining points return to `joins` (typically the
// joining points before the modification). The first knot and the first span stay fixed.
// Degree 2, clamped, simple interior knots only. Each joining point is projected onto its
// control-polygon edge; `residual` is the largest distance from a joining point to its edge
// (0 when exact).
StepResult position_joining_knots(const NurbsCurve& curve, std::span<const Vec3> joins);

// ---------------------------------------------------------------------------------------------
// The recipe of the paper's Figure 9: steps, errors per step, improvement efficiency (eq. 22).

enum class ModifyMethod {
  points,         // dB (eq. 7)
  weights,        // dW (eq. 13 + Process 1)
  weights_knots,  // dW/X: dW then joining-knot positioning (eqs. 20-21)
  combined,       // dW -> dW -> dB; with `iterate`: (dW/X) x k -> dB, k chosen by rho
};

struct ModifyOptions {
  ModifyMethod method = ModifyMethod::points;
  NoseRule nose_rule = NoseRule::mean_parameter;
  // Repeat the method's step until the improvement efficiency rho (eq. 22) falls below rho_min
  // (the paper uses 0.25, Table 3), the total error is below tolerance, or max_iterations.
  bool iterate = false;
  double rho_min = 0.25;
  int max_iterations = 10;
  // Absolute total nose-point error at which iteration stops (model units).
  double tolerance = 1e-9;
  WeightOptions weights;

  // Error naming the option, or nothing.
  std::optional<std::string> validate() const;
};

// One row of the paper's Tables 1-2.
struct ModifyStep {
  std::string operation;       // "initial", "dB", "dW", "dW/X"
  std::vector<double> errors;  // |P_j - nose_j| per segment
  double total = 0.0;          // sum of errors
  double rho = 0.0;            // eq. 22 relative to the previous row (0 for "initial")
  std::vector<double> weights;
  std::vector<double> knots;
  std::string note;  // e.g. "Process 1 applied", "reverted: rho < 0"
  // The step made the total error worse and was undone; `errors` are those of the undone state
  // and the next row's rho is relative to the last row that was kept.
  bool reverted = false;
};

struct ModifyResult {
  NurbsCurve curve;
  std::vector<ModifyStep> steps;
  std::string termination;  // why the loop stopped
};

// Targets for a subset of segments: segment index into curve_segments(curve).
struct SegmentTarget {
  int segment = 0;
  Vec3 point;
};

// Runs the chosen method. Segments without a target are held at their current nose point
// (target = initial nose point), so that their errors measure how far the modification disturbs
// them (the paper's neighbouring nose point C, Figure 10). Throws std::invalid_argument on an
// invalid curve, options or targets (segment out of range or duplicated, empty list).
// A step with rho < 0 (it made the total error worse) is reverted and ends the iteration.
ModifyResult modify_curve(const NurbsCurve& curve, std::span<const SegmentTarget> targets,
                          const ModifyOptions& options);

// Nose-point errors |targets[j] - noses[j].point| and their sum.
std::vector<double> nose_errors(std::span<const NosePoint> noses, std::span<const Vec3> targets);

// Eq. 22: rho = sum_j (e_prev_j - e_j) / sum_j e_prev_j (0 when sum e_prev is 0).
double improvement_efficiency(std::span<const double> previous, std::span<const double> current);

}  // namespace nurbsreg::engine
