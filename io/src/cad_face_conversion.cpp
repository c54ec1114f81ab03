#include "cad_face_conversion.hpp"

#include <BRepAdaptor_Surface.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRep_Tool.hxx>
#include <Geom2dConvert.hxx>
#include <Geom2dConvert_ApproxCurve.hxx>
#include <Geom2d_BSplineCurve.hxx>
#include <Geom2d_BezierCurve.hxx>
#include <Geom2d_Line.hxx>
#include <Geom2d_TrimmedCurve.hxx>
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
#include <stdexcept>

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
Handle(BSpline) restricted_bspline(Handle(Curve) curve, double first, double last,
                                   double tolerance, int& approximations) {
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
  Handle(Curve) source = result.IsNull() ? Handle(Curve)(new Trimmed(curve, first, last))
                                         : Handle(Curve)(result);
  Approx approx(source, tolerance, GeomAbs_C2, 1000, engine::kMaxDegree);
  if (!approx.HasResult() || approx.MaxError() > tolerance) {
    throw Unconvertible(std::string("cannot approximate a ") + curve->DynamicType()->Name() +
                        " within " + std::to_string(tolerance));
  }
  ++approximations;
  return approx.Curve();
}

Handle(Geom2d_BSplineCurve) uv_bspline(const Handle(Geom2d_Curve)& c, double first, double last,
                                       double tolerance, int& approximations) {
  return restricted_bspline<Geom2d_Curve, Geom2d_BSplineCurve, Geom2d_Line, Geom2d_BezierCurve,
                            Geom2d_TrimmedCurve, Geom2dConvert, Geom2dConvert_ApproxCurve>(
      c, first, last, tolerance, approximations);
}

Handle(Geom_BSplineCurve) edge_bspline(const Handle(Geom_Curve)& c, double first, double last,
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

engine::NurbsSurface surface_of(const TopoDS_Face& converted, double tolerance,
                                int& approximations) {
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
  if (bspline->IsUPeriodic()) bspline->SetUNotPeriodic();
  if (bspline->IsVPeriodic()) bspline->SetVNotPeriodic();
  if (bspline->UDegree() > engine::kMaxDegree || bspline->VDegree() > engine::kMaxDegree) {
    GeomConvert_ApproxSurface approx(bspline, tolerance, GeomAbs_C2, GeomAbs_C2,
                                     engine::kMaxDegree, engine::kMaxDegree, 1000, 0);
    if (!approx.HasResult() || approx.MaxError() > tolerance) {
      throw Unconvertible("surface of degree (" + std::to_string(bspline->UDegree()) + ", " +
                          std::to_string(bspline->VDegree()) + ") cannot be approximated within " +
                          std::to_string(tolerance) + " by degree <= " +
                          std::to_string(engine::kMaxDegree));
    }
    bspline = approx.Surface();
    ++approximations;
  }
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

// One edge use of a wire: uv curve and 3-D edge on the same domain, oriented along the wire.
engine::TrimCurve trim_curve(const TopoDS_Edge& edge, const TopoDS_Face& face, double tolerance,
                             double uv_tolerance, FaceConversion& result) {
  double first = 0, last = 0;
  const Handle(Geom2d_Curve) pcurve = BRep_Tool::CurveOnSurface(edge, face, first, last);
  if (pcurve.IsNull()) throw Unconvertible("an edge has no curve on the face (pcurve)");
  engine::TrimCurve out;
  out.uv = to_engine(*uv_bspline(pcurve, first, last, uv_tolerance, result.approximations));
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
    if (curve.IsNull()) throw Unconvertible("an edge has no 3-D curve");
    out.edge = to_engine(*edge_bspline(curve, first3, last3, tolerance, result.approximations));
    map_domain(*out.edge, domain.lo, domain.hi);
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

}  // namespace

FaceConversion convert_face(const TopoDS_Face& face, double tolerance) {
  FaceConversion result;
  try {
    result.surface_type = surface_type(face);
    if (result.surface_type == "none") throw Unconvertible("the face has no surface");
    result.analytic =
        result.surface_type != "Geom_BSplineSurface" && result.surface_type != "Geom_BezierSurface";
    // NurbsConvert makes the surface a B-spline (infinite ones bounded by the face) and
    // recomputes the pcurves in the new parameterisation. The face is explored FORWARD: the
    // engine's even-odd rule ignores loop direction, and `reversed` carries the orientation.
    BRepBuilderAPI_NurbsConvert convert(face, Standard_True);
    if (!convert.IsDone()) throw Unconvertible("OCCT's NURBS conversion failed");
    const TopoDS_Face converted = TopoDS::Face(convert.Shape().Oriented(TopAbs_FORWARD));
    engine::NurbsSurface s = surface_of(converted, tolerance, result.approximations);
    s.reversed = face.Orientation() == TopAbs_REVERSED;
    BRepAdaptor_Surface adaptor(converted, Standard_False);
    const double uv_tolerance =
        std::min(adaptor.UResolution(tolerance), adaptor.VResolution(tolerance));
    for (TopExp_Explorer wires(converted, TopAbs_WIRE); wires.More(); wires.Next()) {
      engine::TrimLoop loop;
      for (BRepTools_WireExplorer edges(TopoDS::Wire(wires.Current()), converted); edges.More();
           edges.Next()) {
        loop.curves.push_back(trim_curve(edges.Current(), converted, tolerance, uv_tolerance,
                                         result));
      }
      if (!loop.curves.empty()) s.trim_loops.push_back(std::move(loop));
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
