#pragma once
// Independent brute-force closest point on a trimmed CAD model, for tests and benchmarks only.
// It reads the file with OpenCASCADE itself and uses nothing of nurbsreg's import or projection:
//  - every face of the ORIGINAL OCCT shape is sampled densely over its (u, v) bounds; samples are
//    kept when OCCT's polygonal classifier (BRepTopAdaptor_FClass2d) puts them strictly IN the
//    face; the grid's discrete local minima near the best sample are polished by a Newton in
//    (u, v) whose steps are cut back until the point stays in the closed face (IN or ON), and
//    the best polished point is accepted only when OCCT's exact classifier
//    (BRepClass_FaceClassifier) does not say OUT (else the next best);
//  - every edge of the shape (its 3-D curve) is sampled densely and the local minima polished by
//    a golden-section search in the parameter.
// The answer is the best of both: an upper bound of the true distance to the trimmed shape that
// is tight up to the Newton/golden precision wherever the sampling is dense enough to seed the
// right basin. Sampling is done once (CadReference's constructor, ~0.1-3 s on the test models);
// a query scans the samples and runs a few short polishes. Not thread-safe (OCCT's adaptors
// cache evaluation data): one instance per thread.
//
// Header-only on purpose: tests/support/*.cpp are compiled into every test executable, and only
// targets that link OpenCASCADE include this file.

#include <BRepAdaptor_Curve.hxx>
#include <BRepAdaptor_Curve2d.hxx>
#include <BRepAdaptor_Surface.hxx>
#include <BRepBndLib.hxx>
#include <BRepClass_FaceClassifier.hxx>
#include <BRepTools.hxx>
#include <BRepTopAdaptor_FClass2d.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Reader.hxx>
#include <STEPControl_Reader.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Face.hxx>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::test {

inline gp_Pnt to_gp(const engine::Vec3& p) {
  return gp_Pnt(p.x(), p.y(), p.z());
}
inline engine::Vec3 from_gp(const gp_Pnt& p) {
  return engine::Vec3(p.X(), p.Y(), p.Z());
}
inline engine::Vec3 from_gp(const gp_Vec& p) {
  return engine::Vec3(p.X(), p.Y(), p.Z());
}

// The file's shape as OCCT's data-exchange readers give it (what a user of OCCT would load),
// with its faces and edges in TopExp::MapShapes order and its bounding box.
struct CadShape {
  TopoDS_Shape shape;
  TopTools_IndexedMapOfShape faces, edges;
  engine::Vec3 box_min = engine::Vec3::Zero(), box_max = engine::Vec3::Zero();
  double diagonal = 0;
};

inline CadShape read_cad_shape(const std::string& path) {
  const std::string ext = path.substr(path.find_last_of('.') + 1);
  const bool step = ext == "step" || ext == "stp" || ext == "STEP" || ext == "STP";
  CadShape out;
  if (step) {
    STEPControl_Reader reader;
    if (reader.ReadFile(path.c_str()) != IFSelect_RetDone)
      throw std::runtime_error(path + ": OCCT cannot read it");
    reader.TransferRoots();
    out.shape = reader.OneShape();
  } else {
    IGESControl_Reader reader;
    if (reader.ReadFile(path.c_str()) != IFSelect_RetDone)
      throw std::runtime_error(path + ": OCCT cannot read it");
    reader.TransferRoots();
    out.shape = reader.OneShape();
  }
  TopExp::MapShapes(out.shape, TopAbs_FACE, out.faces);
  TopExp::MapShapes(out.shape, TopAbs_EDGE, out.edges);
  Bnd_Box box;
  BRepBndLib::Add(out.shape, box);
  double x0, y0, z0, x1, y1, z1;
  box.Get(x0, y0, z0, x1, y1, z1);
  out.box_min = {x0, y0, z0};
  out.box_max = {x1, y1, z1};
  out.diagonal = (out.box_max - out.box_min).norm();
  return out;
}

struct CadFoot {
  double distance = std::numeric_limits<double>::infinity();
  engine::Vec3 foot = engine::Vec3::Zero();
  int face = -1;  // 0-based index into CadShape::faces, or -1 when the foot is on an edge
  int edge = -1;  // 0-based index into CadShape::edges, or -1 when the foot is inside a face
  double u = 0, v = 0, t = 0;
  // The foot is on the face's boundary: the interior polish was stopped by it, or OCCT's exact
  // classifier says ON (the minimum over the face's closure is on its trim curve, where the file's
  // 3-D edge may be off the surface: see TrimmedFaceCheck::boundary_allowance).
  bool stopped_by_boundary = false;
};

struct CadReferenceOptions {
  std::size_t face_samples = 120000;  // over all faces, shared by 3-D size
  double edge_sample_ratio = 0.25;    // edge sample spacing / face sample spacing
  int max_polish = 48;                // interior polishes per query (best seeds first)
};

class CadReference {
 public:
  explicit CadReference(const CadShape& shape, CadReferenceOptions options = {})
      : shape_(shape), options_(options) {
    build_faces();
    build_edges();
    TopExp::MapShapesAndAncestors(shape_.shape, TopAbs_EDGE, TopAbs_FACE, ancestors_);
  }

  const CadShape& shape() const { return shape_; }
  double face_spacing() const { return spacing_; }
  std::size_t sample_count() const { return face_samples_ + edge_samples_; }

  // The largest distance between an edge's 3-D curve and the image of its parameter-space curve
  // on each face that uses it (measured at 16 points per edge use, projected onto the curve):
  // how far the file's face boundaries and edges disagree.
  double max_edge_gap() const { return max_edge_gap_; }
  double face_edge_gap(int face) const { return faces_[face].edge_gap; }

  CadFoot closest(const engine::Vec3& p) const {
    CadFoot best;
    // 1. Scan the face samples; remember the best and the per-face bests.
    double best_sample = std::numeric_limits<double>::infinity();
    for (std::size_t f = 0; f < faces_.size(); ++f) {
      const Face& face = faces_[f];
      double fb = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < face.points.size(); ++k) {
        if (!face.in[k]) continue;
        fb = std::min(fb, (face.points[k] - p).squaredNorm());
      }
      face_best_[f] = std::sqrt(fb);
      best_sample = std::min(best_sample, face_best_[f]);
    }
    double best_edge_sample = std::numeric_limits<double>::infinity();
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      double eb = std::numeric_limits<double>::infinity();
      for (const engine::Vec3& q : edges_[e].points)
        eb = std::min(eb, (q - p).squaredNorm());
      edge_best_[e] = std::sqrt(eb);
      best_edge_sample = std::min(best_edge_sample, edge_best_[e]);
    }
    const double bound = std::min(best_sample, best_edge_sample);
    // 2. Seeds: discrete local minima of faces whose best sample could beat the bound.
    seeds_.clear();
    for (std::size_t f = 0; f < faces_.size(); ++f) {
      const Face& face = faces_[f];
      // The foot's nearest IN sample is within a grid diagonal of it (the nearest row or column
      // may be OUT when the foot is near a loop): hence twice the spacing.
      const double limit = bound + 2 * face.spacing;
      if (face_best_[f] > limit) continue;
      for (int i = 0; i < face.nu; ++i) {
        for (int j = 0; j < face.nv; ++j) {
          const int k = i * face.nv + j;
          if (!face.in[k]) continue;
          const double d = (face.points[k] - p).norm();
          if (d > limit) continue;
          bool is_min = true;
          for (int a = -1; a <= 1 && is_min; ++a) {
            for (int b = -1; b <= 1; ++b) {
              const int ii = i + a, jj = j + b;
              if ((a || b) && ii >= 0 && jj >= 0 && ii < face.nu && jj < face.nv &&
                  face.in[ii * face.nv + jj] && (face.points[ii * face.nv + jj] - p).norm() < d) {
                is_min = false;
                break;
              }
            }
          }
          if (is_min) seeds_.push_back({d, static_cast<int>(f), k});
        }
      }
    }
    std::sort(seeds_.begin(), seeds_.end(), [](const Seed& a, const Seed& b) { return a.d < b.d; });
    const std::size_t polish = std::min<std::size_t>(seeds_.size(), options_.max_polish);
    candidates_.clear();
    for (std::size_t s = 0; s < polish; ++s)
      candidates_.push_back(polish_face(p, seeds_[s].face, seeds_[s].sample));
    // The exact classifier is slow (up to 0.3 ms a call): ask it about the best candidates only,
    // until one is in the closed face (the polygonal one may err near a loop).
    std::sort(candidates_.begin(), candidates_.end(),
              [](const CadFoot& a, const CadFoot& b) { return a.distance < b.distance; });
    for (const CadFoot& hit : candidates_) {
      const TopAbs_State state = classify(hit.face, hit.u, hit.v);
      if (state != TopAbs_OUT) {
        best = hit;
        best.stopped_by_boundary = hit.stopped_by_boundary || state == TopAbs_ON;
        break;
      }
    }
    // 3. Edges: local minima of the edge samples near the bound, golden-section polished.
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      const Edge& edge = edges_[e];
      if (edge_best_[e] > bound + 2 * edge.spacing) continue;
      const int n = static_cast<int>(edge.points.size());
      for (int k = 0; k < n; ++k) {
        const double d = (edge.points[k] - p).norm();
        if (d > bound + 2 * edge.spacing) continue;
        const double dl = k > 0 ? (edge.points[k - 1] - p).norm() : HUGE_VAL;
        const double dr = k + 1 < n ? (edge.points[k + 1] - p).norm() : HUGE_VAL;
        if (d > dl || d > dr) continue;
        const CadFoot hit = polish_edge(p, static_cast<int>(e), k);
        if (hit.distance < best.distance) best = hit;
      }
    }
    return best;
  }

  // Test points of four kinds, deterministic for a seed: near the faces (a random IN sample
  // moved along the normal by 0 to 5 % of the diagonal, either side), near edges and vertices
  // (random offsets up to 5 %), in holes (points of the untrimmed surfaces that are OUT of their
  // face, moved slightly along the normal) and anywhere in the box enlarged by 20 % per side.
  std::vector<engine::Vec3> make_points(std::size_t count, std::uint64_t seed) const {
    std::mt19937_64 rng(seed);
    auto uniform = [&rng] { return std::uniform_real_distribution<double>(0.0, 1.0)(rng); };
    const double diag = shape_.diagonal;
    const double scales[] = {0.0, 1e-6, 1e-4, 1e-3, 1e-2, 5e-2};
    auto scale = [&] { return scales[rng() % 6] * diag; };
    std::vector<std::pair<int, int>> in_samples, out_samples;
    for (std::size_t f = 0; f < faces_.size(); ++f) {
      for (std::size_t k = 0; k < faces_[f].in.size(); ++k)
        (faces_[f].in[k] ? in_samples : out_samples).push_back({static_cast<int>(f), k});
    }
    std::vector<engine::Vec3> points;
    points.reserve(count);
    while (points.size() < count) {
      const std::size_t kind = points.size() % 10;
      if (kind < 4 || (kind < 6 && out_samples.empty())) {
        const auto [f, k] = in_samples[rng() % in_samples.size()];
        const double s = (uniform() < 0.5 ? -1.0 : 1.0) * scale();
        points.push_back(faces_[f].points[k] + s * faces_[f].normals[k]);
      } else if (kind < 6) {
        const auto [f, k] = out_samples[rng() % out_samples.size()];
        const double s = (uniform() < 0.5 ? -1.0 : 1.0) * scales[rng() % 4] * diag;
        points.push_back(faces_[f].points[k] + s * faces_[f].normals[k]);
      } else if (kind < 8) {
        const Edge& edge = edges_[rng() % edges_.size()];
        // Every third one at a vertex (an end of the edge).
        const std::size_t n = edge.points.size();
        const std::size_t k = rng() % 3 == 0 ? (rng() % 2 ? n - 1 : 0) : rng() % n;
        engine::Vec3 dir(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
        if (dir.norm() < 1e-3) dir = engine::Vec3(1, 0, 0);
        points.push_back(edge.points[k] + scale() * dir.normalized());
      } else {
        const engine::Vec3 lo = shape_.box_min - 0.2 * (shape_.box_max - shape_.box_min);
        const engine::Vec3 hi = shape_.box_max + 0.2 * (shape_.box_max - shape_.box_min);
        points.push_back(engine::Vec3(lo.x() + uniform() * (hi.x() - lo.x()),
                                      lo.y() + uniform() * (hi.y() - lo.y()),
                                      lo.z() + uniform() * (hi.z() - lo.z())));
      }
    }
    return points;
  }

  // The faces (0-based) that use shape edge e (0-based).
  std::vector<int> edge_faces(int e) const {
    std::vector<int> out;
    const TopoDS_Shape& edge = shape_.edges(e + 1);
    if (!ancestors_.Contains(edge)) return out;
    for (const TopoDS_Shape& face : ancestors_.FindFromKey(edge)) {
      const int f = shape_.faces.FindIndex(face) - 1;
      if (f >= 0 && std::find(out.begin(), out.end(), f) == out.end()) out.push_back(f);
    }
    return out;
  }

  // Is the 3-D point q on the trimmed shape (within tol)? The reference distance from q.
  double distance_to_shape(const engine::Vec3& q) const { return closest(q).distance; }

  // OCCT's exact classifier on face f (0-based) at (u, v): IN, ON or OUT.
  TopAbs_State classify(int f, double u, double v, double tol = 1e-9) const {
    BRepClass_FaceClassifier classifier(faces_[f].face, gp_Pnt2d(u, v), tol);
    return classifier.State();
  }

 private:
  struct Face {
    TopoDS_Face face;
    std::unique_ptr<BRepAdaptor_Surface> surface;
    std::unique_ptr<BRepTopAdaptor_FClass2d> classifier;
    double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
    int nu = 0, nv = 0;
    std::vector<engine::Vec3> points, normals;
    std::vector<std::uint8_t> in;
    double spacing = 0;         // largest 3-D distance between grid neighbours
    double edge_gap = 0;        // see face_edge_gap()
    std::vector<int> edge_ids;  // indices into edges_ of the face's edges
    double u_at(int i) const { return u0 + (u1 - u0) * i / (nu - 1); }
    double v_at(int j) const { return v0 + (v1 - v0) * j / (nv - 1); }
  };
  struct Edge {
    std::unique_ptr<BRepAdaptor_Curve> curve;
    double t0 = 0, t1 = 0;
    std::vector<engine::Vec3> points;
    double spacing = 0;
    double t_at(int k) const { return t0 + (t1 - t0) * k / static_cast<double>(points.size() - 1); }
  };
  struct Seed {
    double d;
    int face, sample;
  };

  // Samples must be strictly IN; the polish may walk onto the loops (ON: the closed face).
  bool inside(const Face& face, double u, double v, bool closed = false) const {
    if (u < face.u0 || u > face.u1 || v < face.v0 || v > face.v1) return false;
    const TopAbs_State state = face.classifier->Perform(gp_Pnt2d(u, v));
    return state == TopAbs_IN || (closed && state == TopAbs_ON);
  }

  void build_faces() {
    const int n = shape_.faces.Extent();
    faces_.resize(n);
    face_best_.resize(n);
    // Approximate 3-D extents along u and v (iso-curve lengths) share the sample budget.
    std::vector<double> lu(n), lv(n);
    double area = 0;
    for (int f = 0; f < n; ++f) {
      Face& face = faces_[f];
      face.face = TopoDS::Face(shape_.faces(f + 1));
      face.surface = std::make_unique<BRepAdaptor_Surface>(face.face);
      BRepTools::UVBounds(face.face, face.u0, face.u1, face.v0, face.v1);
      for (int a = 0; a < 3; ++a) {
        const double fu = face.u0 + (face.u1 - face.u0) * (0.5 * a);
        const double fv = face.v0 + (face.v1 - face.v0) * (0.5 * a);
        gp_Pnt pu = face.surface->Value(face.u0, fv), pv = face.surface->Value(fu, face.v0);
        for (int k = 1; k <= 32; ++k) {
          const gp_Pnt qu = face.surface->Value(face.u0 + (face.u1 - face.u0) * k / 32.0, fv);
          const gp_Pnt qv = face.surface->Value(fu, face.v0 + (face.v1 - face.v0) * k / 32.0);
          lu[f] = std::max(lu[f], 0.0) + pu.Distance(qu) / 3.0;
          lv[f] = std::max(lv[f], 0.0) + pv.Distance(qv) / 3.0;
          pu = qu;
          pv = qv;
        }
      }
      area += std::max(lu[f], 1e-12 * shape_.diagonal) * std::max(lv[f], 1e-12 * shape_.diagonal);
    }
    const double h = std::sqrt(area / static_cast<double>(options_.face_samples));
    spacing_ = h;
    for (int f = 0; f < n; ++f) {
      Face& face = faces_[f];
      face.nu = std::clamp(static_cast<int>(std::ceil(lu[f] / h)) + 1, 6, 600);
      face.nv = std::clamp(static_cast<int>(std::ceil(lv[f] / h)) + 1, 6, 600);
      // The 3-D tolerance of the face converted to (u, v) by OCCT; small so that IN means in.
      face.classifier = std::make_unique<BRepTopAdaptor_FClass2d>(face.face, 1e-9);
      const std::size_t m = static_cast<std::size_t>(face.nu) * face.nv;
      face.points.resize(m);
      face.normals.resize(m);
      face.in.resize(m);
      for (int i = 0; i < face.nu; ++i) {
        for (int j = 0; j < face.nv; ++j) {
          const std::size_t k = static_cast<std::size_t>(i) * face.nv + j;
          gp_Pnt s;
          gp_Vec su, sv;
          face.surface->D1(face.u_at(i), face.v_at(j), s, su, sv);
          face.points[k] = from_gp(s);
          const engine::Vec3 nrm = from_gp(su).cross(from_gp(sv));
          face.normals[k] = nrm.norm() > 0 ? engine::Vec3(nrm.normalized()) : engine::Vec3(0, 0, 1);
          face.in[k] = inside(face, face.u_at(i), face.v_at(j));
          face_samples_ += face.in[k];
        }
      }
      for (int i = 0; i < face.nu; ++i) {
        for (int j = 0; j < face.nv; ++j) {
          const std::size_t k = static_cast<std::size_t>(i) * face.nv + j;
          if (i + 1 < face.nu)
            face.spacing =
                std::max(face.spacing, (face.points[k + face.nv] - face.points[k]).norm());
          if (j + 1 < face.nv)
            face.spacing = std::max(face.spacing, (face.points[k + 1] - face.points[k]).norm());
        }
      }
      // Edge-versus-boundary gap of the file, measured by projecting S(uv(t)) on the 3-D curve.
      for (TopExp_Explorer ex(face.face, TopAbs_EDGE); ex.More(); ex.Next()) {
        const TopoDS_Edge e = TopoDS::Edge(ex.Current());
        if (BRep_Tool::Degenerated(e)) continue;
        BRepAdaptor_Curve c(e);
        BRepAdaptor_Curve2d c2(e, face.face);
        for (int k = 0; k <= 16; ++k) {
          const double t =
              c2.FirstParameter() + (c2.LastParameter() - c2.FirstParameter()) * k / 16;
          const gp_Pnt2d uv = c2.Value(t);
          const engine::Vec3 q = from_gp(face.surface->Value(uv.X(), uv.Y()));
          const double g = curve_distance(c, q);
          face.edge_gap = std::max(face.edge_gap, g);
        }
      }
      max_edge_gap_ = std::max(max_edge_gap_, face.edge_gap);
    }
  }

  // Distance from q to a curve (dense sampling + golden section), for the gap measure.
  static double curve_distance(const BRepAdaptor_Curve& c, const engine::Vec3& q) {
    const double t0 = c.FirstParameter(), t1 = c.LastParameter();
    const int n = 256;
    int best = 0;
    double bd = HUGE_VAL;
    for (int k = 0; k <= n; ++k) {
      const double d = (from_gp(c.Value(t0 + (t1 - t0) * k / n)) - q).norm();
      if (d < bd) bd = d, best = k;
    }
    const double a = t0 + (t1 - t0) * std::max(best - 1, 0) / n;
    const double b = t0 + (t1 - t0) * std::min(best + 1, n) / n;
    const double t = golden(a, b, [&](double x) { return (from_gp(c.Value(x)) - q).norm(); });
    return std::min(bd, (from_gp(c.Value(t)) - q).norm());
  }

  template <class F>
  static double golden(double a, double b, const F& f) {
    const double r = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = b - r * (b - a), x2 = a + r * (b - a);
    double f1 = f(x1), f2 = f(x2);
    for (int it = 0; it < 80 && b - a > 1e-15 * (std::abs(a) + std::abs(b) + 1e-300); ++it) {
      if (f1 < f2) {
        b = x2, x2 = x1, f2 = f1;
        x1 = b - r * (b - a), f1 = f(x1);
      } else {
        a = x1, x1 = x2, f1 = f2;
        x2 = a + r * (b - a), f2 = f(x2);
      }
    }
    const double fa = f(a), fb = f(b);
    double x = f1 < f2 ? x1 : x2, fx = std::min(f1, f2);
    if (fa < fx) x = a, fx = fa;
    if (fb < fx) x = b;
    return x;
  }

  void build_edges() {
    const int n = shape_.edges.Extent();
    edges_.reserve(n);
    const double h = options_.edge_sample_ratio * spacing_;
    for (int e = 0; e < n; ++e) {
      const TopoDS_Edge te = TopoDS::Edge(shape_.edges(e + 1));
      if (BRep_Tool::Degenerated(te) || !BRep_Tool::IsGeometric(te)) continue;
      Edge edge;
      edge.curve = std::make_unique<BRepAdaptor_Curve>(te);
      edge.t0 = edge.curve->FirstParameter();
      edge.t1 = edge.curve->LastParameter();
      double length = 0;
      gp_Pnt prev = edge.curve->Value(edge.t0);
      for (int k = 1; k <= 64; ++k) {
        const gp_Pnt q = edge.curve->Value(edge.t0 + (edge.t1 - edge.t0) * k / 64.0);
        length += prev.Distance(q);
        prev = q;
      }
      const int m = std::clamp(static_cast<int>(std::ceil(length / h)) + 1, 16, 20000);
      edge.points.resize(m);
      for (int k = 0; k < m; ++k)
        edge.points[k] = from_gp(edge.curve->Value(edge.t_at(k)));
      for (int k = 0; k + 1 < m; ++k)
        edge.spacing = std::max(edge.spacing, (edge.points[k + 1] - edge.points[k]).norm());
      edge_samples_ += m;
      edge_index_.push_back(e);
      edges_.push_back(std::move(edge));
    }
    edge_best_.resize(edges_.size());
    std::vector<int> position(n, -1);
    for (std::size_t k = 0; k < edge_index_.size(); ++k)
      position[edge_index_[k]] = static_cast<int>(k);
    for (Face& face : faces_) {
      for (TopExp_Explorer ex(face.face, TopAbs_EDGE); ex.More(); ex.Next()) {
        const int e = shape_.edges.FindIndex(ex.Current()) - 1;
        if (e >= 0 && position[e] >= 0) face.edge_ids.push_back(position[e]);
      }
    }
  }

  CadFoot polish_edge(const engine::Vec3& p, int e, int k) const {
    const Edge& edge = edges_[e];
    const int n = static_cast<int>(edge.points.size());
    const double a = edge.t_at(std::max(k - 1, 0)), b = edge.t_at(std::min(k + 1, n - 1));
    auto dist = [&](double t) { return (from_gp(edge.curve->Value(t)) - p).norm(); };
    const double t = golden(a, b, dist);
    CadFoot hit;
    hit.edge = edge_index_[e];
    hit.t = t;
    hit.foot = from_gp(edge.curve->Value(t));
    hit.distance = (hit.foot - p).norm();
    return hit;
  }

  // Newton on F(u, v) = |S(u, v) - p|^2 with steps halved until F decreases and (u, v) stays IN
  // (gradient steps when the Hessian is not positive definite).
  CadFoot polish_face(const engine::Vec3& p, int f, int sample) const {
    const Face& face = faces_[f];
    double u = face.u_at(sample / face.nv), v = face.v_at(sample % face.nv);
    auto value = [&](double uu, double vv) {
      return (from_gp(face.surface->Value(uu, vv)) - p).squaredNorm();
    };
    double fx = value(u, v);
    bool blocked = false;
    for (int it = 0; it < 60; ++it) {
      gp_Pnt s;
      gp_Vec su, sv, suu, svv, suv;
      face.surface->D2(u, v, s, su, sv, suu, svv, suv);
      const engine::Vec3 r = from_gp(s) - p, Su = from_gp(su), Sv = from_gp(sv);
      const double gu = r.dot(Su), gv = r.dot(Sv);
      const double huu = Su.dot(Su) + r.dot(from_gp(suu));
      const double hvv = Sv.dot(Sv) + r.dot(from_gp(svv));
      const double huv = Su.dot(Sv) + r.dot(from_gp(suv));
      const double det = huu * hvv - huv * huv;
      double du, dv;
      if (huu > 0 && det > 1e-14 * std::abs(huu * hvv)) {
        du = -(hvv * gu - huv * gv) / det;
        dv = -(huu * gv - huv * gu) / det;
      } else {
        // Gradient step scaled to a tenth of the (u, v) box.
        const double g = std::hypot(gu, gv);
        if (g == 0) break;
        const double len = 0.1 * std::hypot(face.u1 - face.u0, face.v1 - face.v0);
        du = -gu / g * len;
        dv = -gv / g * len;
      }
      bool moved = false;
      blocked = false;
      for (int cut = 0; cut < 50; ++cut, du *= 0.5, dv *= 0.5) {
        const double nu = std::clamp(u + du, face.u0, face.u1);
        const double nv = std::clamp(v + dv, face.v0, face.v1);
        if (nu == u && nv == v) break;
        if (!inside(face, nu, nv, true)) {
          blocked = true;
          continue;
        }
        const double fn = value(nu, nv);
        if (fn < fx) {
          u = nu, v = nv, fx = fn;
          moved = true;
          break;
        }
      }
      if (!moved) break;
    }
    CadFoot hit;
    hit.face = f;
    hit.u = u;
    hit.v = v;
    hit.foot = from_gp(face.surface->Value(u, v));
    hit.distance = (hit.foot - p).norm();
    hit.stopped_by_boundary = blocked;
    return hit;
  }

  const CadShape& shape_;
  CadReferenceOptions options_;
  std::vector<Face> faces_;
  std::vector<Edge> edges_;
  std::vector<int> edge_index_;                          // edges_[k] is shape edge edge_index_[k]
  TopTools_IndexedDataMapOfShapeListOfShape ancestors_;  // edge -> faces
  double spacing_ = 0;
  double max_edge_gap_ = 0;
  std::size_t face_samples_ = 0, edge_samples_ = 0;
  // Query scratch (why the class is not thread-safe besides OCCT's adaptors).
  mutable std::vector<double> face_best_, edge_best_;
  mutable std::vector<Seed> seeds_;
  mutable std::vector<CadFoot> candidates_;
};

}  // namespace nurbsreg::test
