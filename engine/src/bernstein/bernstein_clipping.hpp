#pragma once
// Circular clipping of a 1-D rational Bernstein function (seed paper 002, Chen et al. 2008, §2),
// independent of where the function comes from: the curve projector feeds it the squared
// distance from a point to a rational Bézier piece; a surface projector can feed it the
// squared distance to a boundary curve. Header-only, allocation-free (fixed-size stack),
// no global state; every function is thread-safe.
//
// The function on a sub-interval [a, b] of the local domain [0, 1] is
//   f(t) = sum_k B_k^m(s) num[k] / sum_k B_k^m(s) den[k],   s = (t - a) / (b - a),  den[k] > 0,
// so f_k = num[k] / den[k] are its control values and, by the convex hull property,
// min_k f_k <= f(t) <= max_k f_k on [a, b] (seed 002, Property 1).

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>

#include "bernstein/de_casteljau.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {

// Highest Bernstein degree of a squared-distance function: 2 x the geometric degree.
inline constexpr int kMaxBernsteinDegree = 2 * kMaxDegree;
// Safety net on the subdivision depth: 2^-52 of a piece is below double resolution, so deeper
// subdivision cannot separate anything. Reaching it is counted (ClippingCounters).
inline constexpr int kMaxClippingDepth = 52;

// No default member initialisers on purpose: circular_clip keeps a stack of these per call
// and initialising it would cost more than the clipping itself. Set every field (num and den
// for [0, degree]) before use.
struct RationalBernstein {
  int degree;
  int depth;  // number of halvings from the piece
  // Set on the halves of a unimodal sub-interval that was split rather than solved (see
  // circular_clip): such halves are solved directly.
  bool speculative;
  double a;  // the sub-interval of the piece's local [0, 1] this function covers
  double b;
  std::array<double, kMaxBernsteinDegree + 1> num;
  std::array<double, kMaxBernsteinDegree + 1> den;

  double control_value(int k) const { return num[k] / den[k]; }
  // Copies the used part only.
  void assign(const RationalBernstein& o) {
    degree = o.degree;
    depth = o.depth;
    speculative = o.speculative;
    a = o.a;
    b = o.b;
    std::copy(o.num.begin(), o.num.begin() + o.degree + 1, num.begin());
    std::copy(o.den.begin(), o.den.begin() + o.degree + 1, den.begin());
  }
};

// de Casteljau at s = 1/2 on the homogeneous scalars num and den: both halves are
// again rational Bernstein functions of the same degree. `left` or `right` may alias `from`.
inline void split_half(const RationalBernstein& from, RationalBernstein& left,
                       RationalBernstein& right) {
  const int m = from.degree;
  const double a = from.a;
  const double b = from.b;
  const double mid = 0.5 * (a + b);
  const int depth = from.depth + 1;
  const bool speculative = from.speculative;
  halve(from.num.data(), 1, m, left.num.data(), right.num.data());  // left or right may be `from`
  halve(from.den.data(), 1, m, left.den.data(), right.den.data());
  left.degree = right.degree = m;
  left.a = a;
  left.b = mid;
  right.a = mid;
  right.b = b;
  left.depth = right.depth = depth;
  left.speculative = right.speculative = speculative;
}

// Seed 002, Property 2, in its non-strict form: the control values first do not increase,
// then do not decrease (successive differences change sign at most once, from - to +). Then
// every horizontal line meets the control polygon at most twice, so by the variation
// diminishing property of rational Bézier functions (positive weights) f has at most one local
// minimum on the interval. Monotone sequences qualify (the minimum is at an end).
inline bool is_unimodal(const double* f, int m) {
  int k = 0;
  while (k < m && f[k + 1] <= f[k])
    ++k;
  while (k < m && f[k + 1] >= f[k])
    ++k;
  return k == m;
}

enum class TerminalReason : std::uint8_t {
  unimodal,     // Property 2 holds: at most one local minimum on [a, b]
  flat,         // all control values agree within the rounding bound: any point is as good
  depth_limit,  // safety net
};

struct ClippingCounters {
  std::uint64_t subdivisions = 0;      // midpoint splits
  std::uint64_t eliminated = 0;        // sub-intervals dropped by Property 1
  std::uint64_t terminals = 0;         // sub-intervals handed to the local minimiser
  std::uint64_t depth_limit_hits = 0;  // of which by the safety net
};

// Circular clipping (seed 002, §2, with DESIGN.md's refinements) on `root`.
//
// `alpha` (in/out) is an upper bound on the minimum of f over everything searched so far (the
// squared radius of the elimination circle); +inf when nothing is known. `noise` bounds the
// absolute rounding error of every control value (the caller knows its magnitudes): a
// sub-interval is eliminated only when min_k f_k > alpha + noise, so rounding never discards
// the true minimum. The exact end values f_0 = f(a) and f_m = f(b) shrink alpha on the way
// (plus `noise`, so alpha stays an upper bound).
//
// `terminal(const RationalBernstein& node, const double* f, TerminalReason why)`, with
// f[k] = node's control values, must minimise f on
// [node.a, node.b] on the underlying geometry and return the smallest value it found (it is
// where the caller records its answer); alpha shrinks to it. Sub-intervals are visited
// depth-first, the one with the smaller control minimum first, so alpha shrinks early.
template <typename Terminal>
void circular_clip(const RationalBernstein& root, double noise, double& alpha, Terminal&& terminal,
                   ClippingCounters& counters) {
  // Depth-first with the second child pushed below the first: at most one pending sibling per
  // level, so kMaxClippingDepth + 2 slots suffice.
  RationalBernstein stack[kMaxClippingDepth + 2];
  int top = 0;
  stack[top++].assign(root);
  const int m = root.degree;
  double f[kMaxBernsteinDegree + 1];
  while (top > 0) {
    RationalBernstein& node = stack[top - 1];
    double fmin = std::numeric_limits<double>::infinity();
    double fmax = -fmin;
    for (int k = 0; k <= m; ++k) {
      f[k] = node.num[k] / node.den[k];
      fmin = std::min(fmin, f[k]);
      fmax = std::max(fmax, f[k]);
    }
    alpha = std::min(alpha, std::min(f[0], f[m]) + noise);
    if (fmin > alpha + noise) {  // Property 1: the piece is outside the elimination circle
      ++counters.eliminated;
      --top;
      continue;
    }
    const bool flat = fmax - fmin <= noise;
    bool unimodal = !flat && is_unimodal(f, m);
    // A unimodal sub-interval whose end values are both above alpha holds a better point only
    // if f dips below alpha inside; its control values overestimate that dip. Halving once
    // (cheap) often eliminates both halves, which saves a local solve (expensive).
    bool speculate = false;
    if (unimodal && !node.speculative && f[0] > alpha && f[m] > alpha &&
        node.depth < kMaxClippingDepth) {
      unimodal = false;
      speculate = true;
    }
    if (flat || unimodal || (!speculate && node.depth >= kMaxClippingDepth)) {
      const TerminalReason why = flat       ? TerminalReason::flat
                                 : unimodal ? TerminalReason::unimodal
                                            : TerminalReason::depth_limit;
      ++counters.terminals;
      if (why == TerminalReason::depth_limit) ++counters.depth_limit_hits;
      const double found =
          terminal(static_cast<const RationalBernstein&>(node), static_cast<const double*>(f), why);
      --top;
      alpha = std::min(alpha, found);
      continue;
    }
    ++counters.subdivisions;
    // The half holding the smallest control value is the more promising one: it goes on top
    // of the stack, to be processed next (split_half writes both halves in place, no copies).
    int kmin = 0;
    for (int k = 1; k <= m; ++k) {
      if (f[k] < f[kmin]) kmin = k;
    }
    if (speculate) node.speculative = true;
    if (2 * kmin <= m) {
      split_half(node, stack[top], node);
    } else {
      split_half(node, node, stack[top]);
    }
    ++top;
  }
}

}  // namespace nurbsreg::engine
