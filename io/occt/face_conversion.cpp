#include "face_conversion.hpp"

#include <Adaptor3d_CurveOnSurface.hxx>
#include <BRepAdaptor_Surface.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRepTools.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRep_Tool.hxx>
#include <Geom2dAdaptor_Curve.hxx>
#include <Geom2dConvert.hxx>
#include <Geom2dConvert_ApproxCurve.hxx>
#include <Geom2d_BSplineCurve.hxx>
#include <Geom2d_BezierCurve.hxx>
#include <Geom2d_Line.hxx>
#include <Geom2d_TrimmedCurve.hxx>
#include <GeomAdaptor_Surface.hxx>
#include <GeomConvert.hxx>
#include <GeomConvert_ApproxCurve.hxx>
#include <GeomConvert_ApproxSurface.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_BezierCurve.hxx>
#include <Geom_BezierSurface.hxx>
#include <Geom_Line.hxx>
#include <Geom_RectangularTrimmedSurface.hxx>
#include <Geom_TrimmedCurve.hxx>
#include <Standard_Failure.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Wire.hxx>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "nurbsreg/engine/decompose.hpp"

namespace nurbsreg::io::cad_detail {
namespace {

// A conversion step that cannot be done: the face is skipped with this reason.
struct Unconvertible : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::vector<double> flat_knots(const TColStd_Array1OfReal& sequence) {
  return std::vector<double>(sequence.begin(), sequence.end());
}

engine::NurbsCurve to_engine(const Geom2d_BSplineCurve& c) {
  engine::NurbsCurve out;
  out.degree = c.Degree();
  out.dimension = 2;
  out.knots = flat_knots(c.KnotSequence());
  for (int i = 1; i <= c.NbPoles(); ++i) {
    const gp_Pnt2d p = c.Pole(i);
    out.control_points.emplace_back(p.X(), p.Y(), 0.0);
    if (c.IsRational()) out.weights.push_back(c.Weight(i));
  }
  return out;
}

engine::NurbsCurve to_engine(const Geom_BSplineCurve& c) {
  engine::NurbsCurve out;
  out.degree = c.Degree();
  out.knots = flat_knots(c.KnotSequence());
  for (int i = 1; i <= c.NbPoles(); ++i) {
    const gp_Pnt p = c.Pole(i);
    out.control_points.emplace_back(p.X(), p.Y(), p.Z());
    if (c.IsRational()) out.weights.push_back(c.Weight(i));
  }
  return out;
}

// The curve on [first, last] as a non-periodic B-spline of degree <= kMaxDegree with the SAME
// parameter (t on the result is t on the input): B-splines, lines and Bézier curves are cut
// exactly; anything else (conics, offsets) is approximated within `tolerance`.
template <class Curve, class BSpline, class Line, class Bezier, class Trimmed, class Convert,
          class Approx>
Handle(BSpline) restricted_bspline(Handle(Curve) curve, double first, double last, double tolerance,
                                   int& approximations) {
  while (const auto trimmed = Handle(Trimmed)::DownCast(curve))
    curve = trimmed->BasisCurve();
  Handle(BSpline) result;
  if (const auto b = Handle(BSpline)::DownCast(curve)) {
    result = Handle(BSpline)::DownCast(b->Copy());
    if (!result->IsPeriodic()) {
      // Edge ranges may overshoot a non-periodic curve's ends by rounding.
      first = std::max(first, result->FirstParameter());
      last = std::min(last, result->LastParameter());
    }
    if (first != result->FirstParameter() || last != result->LastParameter() ||
        result->IsPeriodic()) {
      result->Segment(first, last);
    }
    if (result->IsPeriodic()) result->SetNotPeriodic();
  } else if (!Handle(Line)::DownCast(curve).IsNull() || !Handle(Bezier)::DownCast(curve).IsNull()) {
    result = Convert::CurveToBSplineCurve(new Trimmed(curve, first, last));
  }
  if (!result.IsNull() && result->Degree() <= engine::kMaxDegree) return result;
  // Conics and friends: OCCT's exact conversion reparametrises them, which would break the
  // shared parameter of a uv curve and its edge, so they are approximated in their own
  // parameter instead (as is a B-spline of too high a degree).
  Handle(Curve) source =
      result.IsNull() ? Handle(Curve)(new Trimmed(curve, first, last)) : Handle(Curve)(result);
  Approx approx(source, tolerance, GeomAbs_C2, 1000, engine::kMaxDegree);
  if (!approx.HasResult() || approx.MaxError() > tolerance) {
    throw Unconvertible(std::string("cannot approximate a ") + curve->DynamicType()->Name() +
                        " within " + std::to_string(tolerance));
  }
  ++approximations;
  return approx.Curve();
}

Handle(Geom2d_BSplineCurve) uv_bspline(const Handle(Geom2d_Curve) & c, double first, double last,
                                       double tolerance, int& approximations) {
  return restricted_bspline<Geom2d_Curve, Geom2d_BSplineCurve, Geom2d_Line, Geom2d_BezierCurve,
                            Geom2d_TrimmedCurve, Geom2dConvert, Geom2dConvert_ApproxCurve>(
      c, first, last, tolerance, approximations);
}

Handle(Geom_BSplineCurve) edge_bspline(const Handle(Geom_Curve) & c, double first, double last,
                                       double tolerance, int& approximations) {
  return restricted_bspline<Geom_Curve, Geom_BSplineCurve, Geom_Line, Geom_BezierCurve,
                            Geom_TrimmedCurve, GeomConvert, GeomConvert_ApproxCurve>(
      c, first, last, tolerance, approximations);
}

// Maps the curve's parameter affinely from its domain onto [lo, hi] (knots only: the shape is
// unchanged), so that an edge shares its uv curve's domain exactly as validate() requires. The
// domain ends are set exactly and rounding is not allowed to make the knots decrease.
void map_domain(engine::NurbsCurve& c, double lo, double hi) {
  const engine::ParamInterval d = c.domain();
  const double scale = (hi - lo) / (d.hi - d.lo);
  const std::size_t end = c.knots.size() - static_cast<std::size_t>(c.degree) - 1;
  for (std::size_t i = 0; i < c.knots.size(); ++i) {
    double k = lo + (c.knots[i] - d.lo) * scale;
    if (i <= static_cast<std::size_t>(c.degree)) k = std::min(k, lo);
    if (i >= end) k = std::max(k, hi);
    if (i > static_cast<std::size_t>(c.degree) && i < end) k = std::clamp(k, lo, hi);
    c.knots[i] = k;
  }
  c.knots[c.degree] = lo;
  c.knots[end] = hi;
  for (std::size_t i = 1; i < c.knots.size(); ++i)
    c.knots[i] = std::max(c.knots[i], c.knots[i - 1]);
}

// t -> lo + hi - t over the curve's domain [lo, hi]: the same traversal backwards, same domain.
void reverse(engine::NurbsCurve& c) {
  const engine::ParamInterval d = c.domain();
  std::reverse(c.knots.begin(), c.knots.end());
  for (double& k : c.knots)
    k = d.lo + d.hi - k;
  std::reverse(c.control_points.begin(), c.control_points.end());
  std::reverse(c.weights.begin(), c.weights.end());
}

// The B-spline geometry behind an engine surface, and its periods before SetNotPeriodic
// (0: not periodic).
struct SurfaceGeometry {
  Handle(Geom_BSplineSurface) bspline;
  // The surface before SetNotPeriodic when it was periodic (else null): S(uv) of a uv curve that
  // runs beyond one period, where the non-periodic one would be extrapolated.
  Handle(Geom_BSplineSurface) periodic;
  double period_u = 0;
  double period_v = 0;
};

engine::NurbsSurface surface_of(const TopoDS_Face& converted, double tolerance, int& approximations,
                                SurfaceGeometry& geometry) {
  Handle(Geom_Surface) surface = BRep_Tool::Surface(converted);  // located copy
  while (const auto t = Handle(Geom_RectangularTrimmedSurface)::DownCast(surface))
    surface = t->BasisSurface();
  auto bspline = Handle(Geom_BSplineSurface)::DownCast(surface);
  if (bspline.IsNull() && !Handle(Geom_BezierSurface)::DownCast(surface).IsNull())
    bspline = GeomConvert::SurfaceToBSplineSurface(surface);  // same parameter
  if (bspline.IsNull()) {
    throw Unconvertible(std::string("OCCT's NURBS conversion left a ") +
                        surface->DynamicType()->Name());
  }
  bspline = Handle(Geom_BSplineSurface)::DownCast(bspline->Copy());
  if (bspline->IsUPeriodic() || bspline->IsVPeriodic()) {
    geometry.periodic = Handle(Geom_BSplineSurface)::DownCast(bspline->Copy());
  }
  if (bspline->IsUPeriodic()) {
    geometry.period_u = bspline->UPeriod();
    bspline->SetUNotPeriodic();
  }
  if (bspline->IsVPeriodic()) {
    geometry.period_v = bspline->VPeriod();
    bspline->SetVNotPeriodic();
  }
  if (bspline->UDegree() > engine::kMaxDegree || bspline->VDegree() > engine::kMaxDegree) {
    GeomConvert_ApproxSurface approx(bspline, tolerance, GeomAbs_C2, GeomAbs_C2, engine::kMaxDegree,
                                     engine::kMaxDegree, 1000, 0);
    if (!approx.HasResult() || approx.MaxError() > tolerance) {
      throw Unconvertible("surface of degree (" + std::to_string(bspline->UDegree()) + ", " +
                          std::to_string(bspline->VDegree()) + ") cannot be approximated within " +
                          std::to_string(tolerance) +
                          " by degree <= " + std::to_string(engine::kMaxDegree));
    }
    bspline = approx.Surface();
    ++approximations;
  }
  geometry.bspline = bspline;
  engine::NurbsSurface s;
  s.degree_u = bspline->UDegree();
  s.degree_v = bspline->VDegree();
  s.knots_u = flat_knots(bspline->UKnotSequence());
  s.knots_v = flat_knots(bspline->VKnotSequence());
  s.count_u = bspline->NbUPoles();
  s.count_v = bspline->NbVPoles();
  const bool rational = bspline->IsURational() || bspline->IsVRational();
  for (int i = 1; i <= s.count_u; ++i) {
    for (int j = 1; j <= s.count_v; ++j) {
      const gp_Pnt p = bspline->Pole(i, j);
      s.control_points.emplace_back(p.X(), p.Y(), p.Z());
      if (rational) s.weights.push_back(bspline->Weight(i, j));
    }
  }
  return s;
}

// The largest distance between edge(t) and S(uv(t)) over 33 parameters evenly spread.
double edge_gap(const engine::TrimCurve& c, const engine::NurbsSurface& s) {
  const engine::ParamInterval d = c.uv.domain();
  double worst = 0;
  for (int k = 0; k <= 32; ++k) {
    const double t = d.lo + (d.hi - d.lo) * k / 32;
    const engine::Vec3 uv = c.uv.evaluate(t);
    worst = std::max(worst, (c.edge->evaluate(t) - s.evaluate(uv.x(), uv.y())).norm());
  }
  return worst;
}

// One edge use of a wire with its uv curve (the edge's own direction; `reversed` when the wire
// runs it backwards), before its 3-D curve is chosen.
struct WireEdge {
  TopoDS_Edge edge;
  Handle(Geom2d_BSplineCurve) uv;
  bool reversed = false;

  gp_Pnt2d start() const { return reversed ? uv->EndPoint() : uv->StartPoint(); }
  gp_Pnt2d end() const { return reversed ? uv->StartPoint() : uv->EndPoint(); }
};

WireEdge wire_edge(const TopoDS_Edge& edge, const TopoDS_Face& face, double uv_tolerance,
                   FaceConversion& result) {
  double first = 0, last = 0;
  const Handle(Geom2d_Curve) pcurve = BRep_Tool::CurveOnSurface(edge, face, first, last);
  if (pcurve.IsNull()) throw Unconvertible("an edge has no curve on the face (pcurve)");
  return {edge, uv_bspline(pcurve, first, last, uv_tolerance, result.approximations),
          edge.Orientation() == TopAbs_REVERSED};
}

// The range of coordinate `axis` (0: u, 1: v) over the curve (33 points: a rational curve's
// control polygon overshoots it).
std::pair<double, double> curve_range(const Geom2d_BSplineCurve& uv, int axis) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int k = 0; k <= 32; ++k) {
    const gp_Pnt2d p =
        uv.Value(uv.FirstParameter() + (uv.LastParameter() - uv.FirstParameter()) * k / 32);
    lo = std::min(lo, axis == 0 ? p.X() : p.Y());
    hi = std::max(hi, axis == 0 ? p.X() : p.Y());
  }
  return {lo, hi};
}

// Does the curve leave `domain` (the surface's along `axis`) by more than rounding?
bool leaves_along(const Geom2d_BSplineCurve& uv, int axis, const engine::ParamInterval& domain) {
  const auto [lo, hi] = curve_range(uv, axis);
  const double slack = 1e-9 * std::max(1.0, domain.width());
  return lo < domain.lo - slack || hi > domain.hi + slack;
}

void translate(Geom2d_BSplineCurve& uv, int axis, double shift) {
  if (shift != 0) uv.Translate(axis == 0 ? gp_Vec2d(shift, 0) : gp_Vec2d(0, shift));
}

// Index of control point k along `axis` (0: u, 1: v) and l across it.
std::size_t control_index(const engine::NurbsSurface& s, int axis, int k, int l) {
  return static_cast<std::size_t>(axis == 0 ? k * s.count_v + l : l * s.count_v + k);
}

// Is the surface closed along `axis`: with clamped ends (`s` is engine::clamp's; OCCT's
// SetNotPeriodic may leave unclamped ends, whose end rows are not the seam's points), do its
// first and last rows of control points, and weights, agree within `tolerance`?
bool closed_along(const engine::NurbsSurface& s, int axis, double tolerance) {
  const int n = axis == 0 ? s.count_u : s.count_v;
  const int other = axis == 0 ? s.count_v : s.count_u;
  for (int l = 0; l < other; ++l) {
    const std::size_t first = control_index(s, axis, 0, l), last = control_index(s, axis, n - 1, l);
    if ((s.control_points[first] - s.control_points[last]).norm() > tolerance) return false;
    if (!s.weights.empty() &&
        std::abs(s.weights[first] - s.weights[last]) > 1e-12 * s.weights[first]) {
      return false;
    }
  }
  return true;
}

// `copies` periods of the surface along `axis` instead of one, when it is closed there
// (closed_along): the copies joined at the seam (knot multiplicity = degree there), the same
// points of space. Returns false, leaving the surface as it is, when it is not closed.
bool repeat_periods(engine::NurbsSurface& surface, int axis, int copies, double tolerance) {
  engine::NurbsSurface s = engine::clamp(surface);
  if (!closed_along(s, axis, tolerance)) return false;
  const int n = axis == 0 ? s.count_u : s.count_v;
  const int other = axis == 0 ? s.count_v : s.count_u;
  const int degree = axis == 0 ? s.degree_u : s.degree_v;
  const auto at = [&](int k, int l) { return control_index(s, axis, k, l); };
  std::vector<double>& knots = axis == 0 ? s.knots_u : s.knots_v;
  const double period = knots.back() - knots.front();
  // knots = [lo] * (degree + 1), interior, [hi] * (degree + 1).
  const std::vector<double> interior(knots.begin() + degree + 1, knots.end() - degree - 1);
  std::vector<double> extended(knots.begin(), knots.begin() + degree + 1);
  for (int c = 0; c < copies; ++c) {
    for (double k : interior)
      extended.push_back(k + c * period);
    const double seam = knots.front() + (c + 1) * period;
    extended.insert(extended.end(), c + 1 < copies ? degree : degree + 1, seam);
  }
  const int count = copies * n - (copies - 1);
  std::vector<engine::Vec3> points(static_cast<std::size_t>(count) * other);
  std::vector<double> weights(s.weights.empty() ? 0 : points.size());
  const auto new_at = [&](int k, int l) {
    return static_cast<std::size_t>(axis == 0 ? k * other + l : l * count + k);
  };
  for (int k = 0; k < count; ++k) {
    const int source = k == 0 ? 0 : (k - 1) % (n - 1) + 1;  // copy c holds source 1 .. n - 1
    for (int l = 0; l < other; ++l) {
      points[new_at(k, l)] = s.control_points[at(source, l)];
      if (!weights.empty()) weights[new_at(k, l)] = s.weights[at(source, l)];
    }
  }
  knots = std::move(extended);
  (axis == 0 ? s.count_u : s.count_v) = count;
  s.control_points = std::move(points);
  s.weights = std::move(weights);
  // The geometry only: clamp() keeps nothing else (name, orientation, loops).
  surface.knots_u = std::move(s.knots_u);
  surface.knots_v = std::move(s.knots_v);
  surface.count_u = s.count_u;
  surface.count_v = s.count_v;
  surface.control_points = std::move(s.control_points);
  surface.weights = std::move(s.weights);
  return true;
}

// On a periodic surface a face's uv curves may lie in any period, and a wire may jump by whole
// periods from one edge to the next where it crosses the seam (NIST CTC 02: faces whose loop
// runs once around a cylinder, so that half of the loop lies beyond the domain of the
// non-periodic surface). Each wire is made continuous by translating its curves by whole
// periods, then placed as a whole: the outer wire (index `outer`) from the domain's start, the
// others from the outer one's. Where a wire then still runs beyond the domain, the surface is
// repeated over as many periods as needed (repeat_periods), so that the whole face is in it.
// A surface OCCT does not call periodic counts as periodic along an axis (period: the domain's
// width) when it is closed there and a wire leaves its domain along it: NIST CTC 02 faces 27,
// 29, 36 and 50 (revolutions after NurbsConvert) have loops 0.6% beyond their domain, whose
// 3-D edges are S(u - width, v) to 4e-13 mm.
void place_periodic_wires(std::vector<std::vector<WireEdge>>& wires, std::size_t outer,
                          engine::NurbsSurface& s, const SurfaceGeometry& geometry,
                          double tolerance) {
  const double period[2] = {geometry.period_u, geometry.period_v};
  for (int axis = 0; axis < 2; ++axis) {
    if (wires.empty()) break;
    const auto coordinate = [axis](const gp_Pnt2d& x) { return axis == 0 ? x.X() : x.Y(); };
    const engine::ParamInterval domain = axis == 0 ? s.domain_u() : s.domain_v();
    const double slack = 1e-9 * std::max(1.0, domain.width());
    double p = period[axis];
    if (!(p > 0)) {
      bool leaves = false;
      for (const std::vector<WireEdge>& wire : wires) {
        for (const WireEdge& e : wire)
          leaves = leaves || leaves_along(*e.uv, axis, domain);
      }
      if (!leaves || !closed_along(engine::clamp(s), axis, tolerance)) continue;
      p = domain.width();
    }
    std::vector<double> lowest(wires.size()), highest(wires.size());
    for (std::size_t w = 0; w < wires.size(); ++w) {
      for (std::size_t e = 1; e < wires[w].size(); ++e) {
        const double gap = coordinate(wires[w][e - 1].end()) - coordinate(wires[w][e].start());
        translate(*wires[w][e].uv, axis, p * std::round(gap / p));
      }
      lowest[w] = std::numeric_limits<double>::infinity();
      highest[w] = -lowest[w];
      for (const WireEdge& e : wires[w]) {
        const auto [lo, hi] = curve_range(*e.uv, axis);
        lowest[w] = std::min(lowest[w], lo);
        highest[w] = std::max(highest[w], hi);
      }
    }
    // The outer wire from the domain's start, the others within the outer one's periods.
    double top = -std::numeric_limits<double>::infinity();
    const auto place = [&](std::size_t w, double from) {
      const double shift = -p * std::floor((lowest[w] - from + slack) / p);
      for (WireEdge& e : wires[w])
        translate(*e.uv, axis, shift);
      top = std::max(top, highest[w] + shift);
      return lowest[w] + shift;
    };
    const double outer_start = place(outer, domain.lo);
    for (std::size_t w = 0; w < wires.size(); ++w) {
      if (w != outer) place(w, outer_start);
    }
    // repeat_periods repeats the domain's width: only where that is the period.
    if (top > domain.hi + slack && std::abs(p - domain.width()) <= slack) {
      const int copies = static_cast<int>(std::ceil((top - domain.lo - slack) / p));
      repeat_periods(s, axis, copies, tolerance);
    }
  }
}

// Does the curve leave the surface's domain (beyond rounding)? S(uv) clamps there and cannot
// follow the file's edge.
bool leaves_domain(const Geom2d_BSplineCurve& uv, const engine::NurbsSurface& s) {
  return leaves_along(uv, 0, s.domain_u()) || leaves_along(uv, 1, s.domain_v());
}

// One edge use of a wire: uv curve and 3-D edge on the same domain, oriented along the wire.
// The engine reports (u, v) = uv(t) for a foot point edge(t), so the two must agree: a file's
// 3-D curve farther than `tolerance` from S(uv(t)) (CAD edges are only within their own,
// often much looser, tolerance) is replaced by S(uv(t)) itself, approximated within
// `tolerance` in the uv curve's parameter. Counted in result.rebuilt_edges.
engine::TrimCurve trim_curve(const WireEdge& wire_edge, const engine::NurbsSurface& s,
                             const SurfaceGeometry& geometry, double tolerance,
                             FaceConversion& result) {
  const TopoDS_Edge& edge = wire_edge.edge;
  const Handle(Geom2d_BSplineCurve)& uv = wire_edge.uv;
  engine::TrimCurve out;
  if (leaves_domain(*uv, s)) ++result.uv_outside_domain;
  out.uv = to_engine(*uv);
  const engine::ParamInterval domain = out.uv.domain();
  if (BRep_Tool::Degenerated(edge)) {
    // A pole: the whole uv curve maps to one point.
    const gp_Pnt pole = BRep_Tool::Pnt(TopExp::FirstVertex(edge));
    engine::NurbsCurve point = out.uv;
    point.dimension = 3;
    std::fill(point.control_points.begin(), point.control_points.end(),
              engine::Vec3(pole.X(), pole.Y(), pole.Z()));
    out.edge = std::move(point);
    ++result.degenerated_edges;
  } else {
    double first3 = 0, last3 = 0;
    const Handle(Geom_Curve) curve = BRep_Tool::Curve(edge, first3, last3);  // located copy
    if (!curve.IsNull()) {
      out.edge = to_engine(*edge_bspline(curve, first3, last3, tolerance, result.approximations));
      map_domain(*out.edge, domain.lo, domain.hi);
    }
    if (curve.IsNull() || edge_gap(out, s) > tolerance) {
      const Handle(Adaptor3d_Curve) on_surface = new Adaptor3d_CurveOnSurface(
          new Geom2dAdaptor_Curve(uv),
          new GeomAdaptor_Surface(geometry.periodic.IsNull() ? geometry.bspline
                                                             : geometry.periodic));
      // C1 first (fewer pieces); C0 where the uv curve itself has kinks. OCCT's own error
      // estimate is checked on our side (33 samples); the closest candidate is kept.
      double best = out.edge ? edge_gap(out, s) : std::numeric_limits<double>::infinity();
      const double file_gap = best;
      for (const GeomAbs_Shape order : {GeomAbs_C1, GeomAbs_C0}) {
        GeomConvert_ApproxCurve approx(on_surface, tolerance, order, 2000, engine::kMaxDegree);
        if (!approx.HasResult()) continue;
        engine::TrimCurve candidate{out.uv, to_engine(*approx.Curve())};
        map_domain(*candidate.edge, domain.lo, domain.hi);  // rounding only: same parameter
        const double gap = edge_gap(candidate, s);
        if (gap < best) {
          best = gap;
          out.edge = std::move(candidate.edge);
        }
        if (gap <= tolerance) break;
      }
      if (!out.edge) {
        throw Unconvertible("an edge has no 3-D curve and S(uv(t)) cannot be approximated");
      }
      if (best < file_gap) ++result.rebuilt_edges;
      if (best > tolerance) ++result.inconsistent_edges;
    }
  }
  if (edge.Orientation() == TopAbs_REVERSED) {
    reverse(out.uv);
    reverse(*out.edge);
  }
  return out;
}

std::string surface_type(const TopoDS_Face& face) {
  Handle(Geom_Surface) surface = BRep_Tool::Surface(face);
  if (surface.IsNull()) return "none";
  while (const auto t = Handle(Geom_RectangularTrimmedSurface)::DownCast(surface))
    surface = t->BasisSurface();
  return surface->DynamicType()->Name();
}

bool analytic_type(const std::string& type) {
  return type != "Geom_BSplineSurface" && type != "Geom_BezierSurface";
}

}  // namespace

bool is_analytic(const TopoDS_Face& face) {
  const std::string type = surface_type(face);
  return type != "none" && analytic_type(type);
}

FaceConversion convert_face(const TopoDS_Face& face, const TopoDS_Face* nurbs_face,
                            double tolerance) {
  FaceConversion result;
  try {
    result.surface_type = surface_type(face);
    if (result.surface_type == "none") throw Unconvertible("the face has no surface");
    result.analytic = analytic_type(result.surface_type);
    // NurbsConvert makes the surface a B-spline (infinite ones bounded by the face) and
    // recomputes the pcurves in the new parameterisation. The face is explored FORWARD: the
    // engine's even-odd rule ignores loop direction, and `reversed` carries the orientation.
    // B-spline and Bézier faces are used as they are: their surfaces keep their parameter, so
    // their pcurves are already right (NurbsConvert would only spend time re-checking them).
    TopoDS_Face converted = face;
    if (result.analytic && nurbs_face != nullptr) {
      converted = *nurbs_face;
    } else if (result.analytic) {
      BRepBuilderAPI_NurbsConvert convert(face, Standard_True);
      if (!convert.IsDone()) throw Unconvertible("OCCT's NURBS conversion failed");
      converted = TopoDS::Face(convert.Shape());
    }
    converted.Orientation(TopAbs_FORWARD);
    SurfaceGeometry geometry;
    engine::NurbsSurface s = surface_of(converted, tolerance, result.approximations, geometry);
    s.reversed = face.Orientation() == TopAbs_REVERSED;
    BRepAdaptor_Surface adaptor(converted, Standard_False);
    const double uv_tolerance =
        std::min(adaptor.UResolution(tolerance), adaptor.VResolution(tolerance));
    // The wires' uv curves first: on a periodic surface they are placed (and the surface
    // repeated) before any 3-D edge is compared with S(uv).
    const TopoDS_Wire outer_wire = BRepTools::OuterWire(converted);
    std::vector<std::vector<WireEdge>> wires;
    std::size_t outer = 0;
    for (TopExp_Explorer w(converted, TopAbs_WIRE); w.More(); w.Next()) {
      std::vector<WireEdge> edges;
      for (BRepTools_WireExplorer e(TopoDS::Wire(w.Current()), converted); e.More(); e.Next())
        edges.push_back(wire_edge(e.Current(), converted, uv_tolerance, result));
      if (edges.empty()) continue;
      if (w.Current().IsSame(outer_wire)) outer = wires.size();
      wires.push_back(std::move(edges));
    }
    place_periodic_wires(wires, outer, s, geometry, tolerance);
    for (const std::vector<WireEdge>& wire : wires) {
      engine::TrimLoop loop;
      for (const WireEdge& e : wire)
        loop.curves.push_back(trim_curve(e, s, geometry, tolerance, result));
      s.trim_loops.push_back(std::move(loop));
    }
    if (auto error = s.validate()) throw Unconvertible(*error);
    result.surface = std::move(s);
  } catch (const Unconvertible& e) {
    result.error = e.what();
  } catch (const Standard_Failure& e) {
    result.error = std::string("OCCT: ") + e.DynamicType()->Name() + ": " + e.GetMessageString();
  } catch (const std::exception& e) {
    result.error = e.what();
  }
  return result;
}

}  // namespace nurbsreg::io::cad_detail
