// STEP and IGES import through OpenCASCADE, checked against OCCT's own (pre-conversion) geometry:
// every face converts; our surfaces lie on the original face surfaces; trim curves connect along
// their loops; each 3-D edge runs on our surface along its uv curve. The reference shapes are
// read here independently with OCCT and indexed the same documented way (TopExp::MapShapes).
#include <gtest/gtest.h>

#include <BRepBndLib.hxx>
#include <BRepGProp.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GProp_GProps.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_RectangularTrimmedSurface.hxx>
#include <IGESControl_Reader.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <STEPControl_Reader.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/source_paths.hpp"
#include "support/test_scale.hpp"

namespace nurbsreg::io {
namespace {

const std::string kReal = nurbsreg::test::shared_dir() + "/data/real/";

// One file, loaded once per test process: our model plus OCCT's own reading of the file.
struct Loaded {
  engine::Model model;
  CadImportReport report;
  double seconds = 0;
  TopoDS_Shape shape;
  TopTools_IndexedMapOfShape faces;
  double diagonal = 0;
};

TopoDS_Shape occt_read(const std::string& path) {
  Message::DefaultMessenger()->ChangePrinters().Clear();
  const bool step = path.ends_with(".stp") || path.ends_with(".step");
  if (step) {
    STEPControl_Reader reader;
    if (reader.ReadFile(path.c_str()) != IFSelect_RetDone) return {};
    reader.TransferRoots();
    return reader.OneShape();
  }
  IGESControl_Reader reader;
  if (reader.ReadFile(path.c_str()) != IFSelect_RetDone) return {};
  reader.TransferRoots();
  return reader.OneShape();
}

const Loaded& load(const std::string& relative) {
  static std::map<std::string, Loaded> cache;
  auto it = cache.find(relative);
  if (it != cache.end()) return it->second;
  Loaded& l = cache[relative];
  const std::string path = kReal + relative;
  const auto start = std::chrono::steady_clock::now();
  l.model = read_cad_file(path, &l.report);
  l.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  l.shape = occt_read(path);
  TopExp::MapShapes(l.shape, TopAbs_FACE, l.faces);
  Bnd_Box box;
  BRepBndLib::Add(l.shape, box, Standard_False);
  double x0, y0, z0, x1, y1, z1;
  box.Get(x0, y0, z0, x1, y1, z1);
  l.diagonal = std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
  return l;
}

int face_index(const engine::NurbsSurface& s) {
  return std::stoi(s.name.substr(std::string("face ").size()));
}

engine::Vec3 vec(const gp_Pnt& p) {
  return {p.X(), p.Y(), p.Z()};
}

// Whether uv(t) leaves the surface's parameter domain at 65 sampled t (our own check, finer
// than the importer's 33 samples).
bool leaves_domain(const engine::NurbsCurve& uv, const engine::NurbsSurface& s) {
  const engine::ParamInterval du = s.domain_u(), dv = s.domain_v(), d = uv.domain();
  const double su = 1e-9 * std::max(1.0, du.hi - du.lo), sv = 1e-9 * std::max(1.0, dv.hi - dv.lo);
  for (int k = 0; k <= 64; ++k) {
    const engine::Vec3 p = uv.evaluate(d.lo + (d.hi - d.lo) * k / 64);
    if (p.x() < du.lo - su || p.x() > du.hi + su || p.y() < dv.lo - sv || p.y() > dv.hi + sv)
      return true;
  }
  return false;
}

class CadFiles : public ::testing::TestWithParam<const char*> {};

TEST_P(CadFiles, EveryFaceConverts) {
  const Loaded& l = load(GetParam());
  ASSERT_FALSE(l.shape.IsNull());
  EXPECT_EQ(l.report.faces, static_cast<std::size_t>(l.faces.Extent()));
  EXPECT_EQ(l.model.surfaces.size(), static_cast<std::size_t>(l.faces.Extent()));
  for (const engine::SkippedFace& f : l.model.skipped_faces)
    ADD_FAILURE() << "face " << f.face << " skipped: " << f.reason;
  EXPECT_EQ(l.model.units, "mm");
  EXPECT_FALSE(l.model.validate().has_value());
  std::size_t trimmed = 0;
  for (std::size_t k = 0; k < l.model.surfaces.size(); ++k) {
    EXPECT_EQ(face_index(l.model.surfaces[k]), l.report.surface_faces[k]);
    trimmed += l.model.surfaces[k].is_trimmed() ? 1 : 0;
  }
  std::printf(
      "[ report   ] %s: %zu faces, %zu trimmed, %zu analytic converted, %zu approximations, "
      "%zu degenerated edges, %zu edges rebuilt as S(uv), %zu edges kept off S(uv), "
      "%zu uv curves outside the domain, file units \"%s\", load %.2f s\n",
      GetParam(), l.report.faces, trimmed, l.report.analytic_faces, l.report.approximations,
      l.report.degenerated_edges, l.report.rebuilt_edges, l.report.inconsistent_edges,
      l.report.uv_outside_domain, l.report.file_units.c_str(), l.seconds);
}

// Our surface at a grid of (u, v) on the ORIGINAL face surface: evaluated at the same (u, v)
// when the surface was a B-spline already (the parameter is kept), projected otherwise.
TEST_P(CadFiles, SurfacesLieOnTheOriginalFaceSurfaces) {
  const Loaded& l = load(GetParam());
  const double tolerance = 1e-9 * l.diagonal;
  const int n = 5;
  double worst = 0;
  for (const engine::NurbsSurface& s : l.model.surfaces) {
    const int f = face_index(s);
    const TopoDS_Face face = TopoDS::Face(l.faces(f + 1));
    Handle(Geom_Surface) original = BRep_Tool::Surface(face);
    Handle(Geom_Surface) basis = original;
    while (const auto t = Handle(Geom_RectangularTrimmedSurface)::DownCast(basis))
      basis = t->BasisSurface();
    const bool same_parameter = !Handle(Geom_BSplineSurface)::DownCast(basis).IsNull();
    EXPECT_EQ(s.reversed, face.Orientation() == TopAbs_REVERSED) << s.name;
    const engine::ParamInterval du = s.domain_u(), dv = s.domain_v();
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; j <= n; ++j) {
        const double u = du.lo + (du.hi - du.lo) * i / n;
        const double v = dv.lo + (dv.hi - dv.lo) * j / n;
        const engine::Vec3 p = s.evaluate(u, v);
        double d = 0;
        if (same_parameter) {
          d = (p - vec(original->Value(u, v))).norm();
        } else {
          GeomAPI_ProjectPointOnSurf projection(gp_Pnt(p.x(), p.y(), p.z()), original);
          ASSERT_GT(projection.NbPoints(), 0) << s.name << " at (" << u << ", " << v << ")";
          d = projection.LowerDistance();
        }
        worst = std::max(worst, d);
        EXPECT_LE(d, tolerance) << s.name << " (" << basis->DynamicType()->Name() << ") at (" << u
                                << ", " << v << ")";
      }
    }
  }
  std::printf("[ report   ] %s: surfaces off the original faces by <= %.3g (%.3g x diagonal)\n",
              GetParam(), worst, worst / l.diagonal);
}

// The trim loops against the original wires: one loop per wire, one curve per edge use; each
// 3-D edge on our surface along its uv curve within the edge's tolerance; consecutive curves
// meet within the tolerance of the vertex between them.
TEST_P(CadFiles, TrimCurvesRunOnTheSurfaceAndCloseTheirLoops) {
  const Loaded& l = load(GetParam());
  const double floor_tolerance = 1e-9 * l.diagonal;
  double worst_on_surface = 0, worst_gap = 0;
  std::size_t outside = 0;
  for (const engine::NurbsSurface& s : l.model.surfaces) {
    const TopoDS_Face face = TopoDS::Face(l.faces(face_index(s) + 1).Oriented(TopAbs_FORWARD));
    std::size_t loop = 0;
    for (TopExp_Explorer wires(face, TopAbs_WIRE); wires.More(); wires.Next()) {
      std::vector<TopoDS_Edge> edges;
      for (BRepTools_WireExplorer e(TopoDS::Wire(wires.Current()), face); e.More(); e.Next())
        edges.push_back(e.Current());
      if (edges.empty()) continue;
      ASSERT_LT(loop, s.trim_loops.size()) << s.name;
      const engine::TrimLoop& trim = s.trim_loops[loop++];
      ASSERT_EQ(trim.curves.size(), edges.size()) << s.name;
      for (std::size_t c = 0; c < edges.size(); ++c) {
        const engine::TrimCurve& curve = trim.curves[c];
        ASSERT_TRUE(curve.edge.has_value());
        const double tolerance = std::max(BRep_Tool::Tolerance(edges[c]), floor_tolerance);
        const engine::ParamInterval d = curve.uv.domain();
        // A uv curve that leaves the surface's domain (the file's pcurve runs past the
        // surface's knot range; OCCT extrapolates there, the engine clamps) cannot be checked
        // this way: counted, and the count must be the one the importer reports.
        if (leaves_domain(curve.uv, s)) {
          ++outside;
          continue;
        }
        for (int k = 0; k <= 8; ++k) {
          const double t = d.lo + (d.hi - d.lo) * k / 8;
          const engine::Vec3 uv = curve.uv.evaluate(t);
          const double gap = (curve.edge->evaluate(t) - s.evaluate(uv.x(), uv.y())).norm();
          worst_on_surface = std::max(worst_on_surface, gap / tolerance);
          EXPECT_LE(gap, tolerance)
              << s.name << " loop " << loop - 1 << " curve " << c << " t = " << t;
        }
        // The end of this curve and the start of the next (the loop closes on itself).
        const std::size_t next = (c + 1) % edges.size();
        const engine::TrimCurve& after = trim.curves[next];
        TopoDS_Vertex shared = TopExp::LastVertex(edges[c], Standard_True);
        const double vertex_tolerance = shared.IsNull() ? 0.0 : BRep_Tool::Tolerance(shared);
        const double joint_tolerance =
            std::max({tolerance, BRep_Tool::Tolerance(edges[next]), vertex_tolerance});
        const double joint =
            (curve.edge->evaluate(d.hi) - after.edge->evaluate(after.uv.domain().lo)).norm();
        worst_gap = std::max(worst_gap, joint / joint_tolerance);
        EXPECT_LE(joint, joint_tolerance) << s.name << " loop " << loop - 1 << " after curve " << c;
      }
    }
    EXPECT_EQ(loop, s.trim_loops.size()) << s.name;
  }
  EXPECT_EQ(outside, l.report.uv_outside_domain);
  std::printf(
      "[ report   ] %s: edge vs S(uv) <= %.3g x tolerance, joints <= %.3g x tolerance, "
      "%zu uv curves leave their surface's domain (not checked)\n",
      GetParam(), worst_on_surface, worst_gap, outside);
}

// Every face is all there: its area in the model (the trim loops' region on our surface,
// engine::surface_area) against OpenCASCADE's area of the file's face (BRepGProp). A part of a
// face lost in the conversion shows here: on a periodic surface, loops that cross the seam
// (NIST CTC 02 faces 49, 56, 279, 280 kept 0-9% of their area before their wires were made
// continuous and the surface repeated over the periods they span). surface_area's quadrature is
// within ~6% on the smallest faces (0.04 mm2 in linkrods.step), and a file's total within 0.2%.
// Under sanitizers (test_scale.hpp) every face of the small files but only about 24 faces spread
// over each large one, and no total (the file's total needs every face).
TEST_P(CadFiles, FaceAreasMatchOpenCascade) {
  const Loaded& l = load(GetParam());
  const std::size_t faces = l.model.surfaces.size();
  const std::size_t stride = test::test_size<std::size_t>(1, std::max<std::size_t>(1, faces / 24));
  double ours_total = 0, theirs_total = 0;
  for (std::size_t k = 0; k < faces; k += stride) {
    const engine::NurbsSurface& s = l.model.surfaces[k];
    engine::Model one;
    one.surfaces.push_back(s);
    const double ours = engine::surface_area(one);
    GProp_GProps props;
    BRepGProp::SurfaceProperties(l.faces(face_index(s) + 1), props);
    const double theirs = props.Mass();
    ours_total += ours;
    theirs_total += theirs;
    EXPECT_NEAR(ours, theirs, 0.1 * theirs) << s.name;
  }
  if (stride == 1) {
    EXPECT_NEAR(ours_total, theirs_total, 5e-3 * theirs_total);
  }
  std::printf("[ report   ] %s: area %.9g, OpenCASCADE's %.9g (%zu of %zu faces)\n", GetParam(),
              ours_total, theirs_total, (faces + stride - 1) / stride, faces);
}

INSTANTIATE_TEST_SUITE_P(
    RealFiles, CadFiles,
    ::testing::Values("iea-15mw/IEA_15MW_CFD.stp", "iea-15mw/IEA_15MW_CFD.igs", "bladex/lower.iges",
                      "bladex/upper.iges", "dealii/DTMB-5415_bulbous_bow.iges",
                      "dealii/goteborg.iges", "dealii/goteborg.step", "dealii/wigley.iges",
                      "dealii/wigley.step", "dealii/wing.iges", "occt/bearing.iges",
                      "occt/hammer.iges", "occt/linkrods.step", "occt/screw.step",
                      "gmsh/as1-tu-203.stp", "gmsh/t20_data.step",
                      "nist/nist_ctc_02_asme1_ap242-1.stp"),
    [](const ::testing::TestParamInfo<const char*>& info) {
      std::string name = info.param;
      for (char& ch : name)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return name;
    });

TEST(CadImport, BearingHas213TrimmedFaces) {
  const Loaded& l = load("occt/bearing.iges");
  ASSERT_EQ(l.model.surfaces.size(), 213u);
  for (const engine::NurbsSurface& s : l.model.surfaces)
    EXPECT_TRUE(s.is_trimmed()) << s.name;
}

TEST(CadImport, ScrewIsAnalyticOnlyAndBecomesExactNurbs) {
  const Loaded& l = load("occt/screw.step");
  EXPECT_EQ(l.report.analytic_faces, l.model.surfaces.size());
  EXPECT_EQ(l.report.surface_types.count("Geom_BSplineSurface"), 0u);
  std::size_t rational = 0;
  for (const engine::NurbsSurface& s : l.model.surfaces)
    rational += s.is_rational() ? 1 : 0;
  EXPECT_GT(rational, 0u);  // cylinders, cones and tori are rational
}

// A converted CAD model survives the JSON format bit for bit (trim loops, edges, orientation).
TEST(CadImport, TrimmedModelRoundTripsThroughJson) {
  const Loaded& l = load("gmsh/as1-tu-203.stp");
  const std::string text = model_to_json(l.model);
  const engine::Model back = parse_model(text, "round-trip");
  EXPECT_EQ(model_to_json(back), text);
  ASSERT_EQ(back.surfaces.size(), l.model.surfaces.size());
  for (std::size_t k = 0; k < back.surfaces.size(); ++k) {
    const engine::NurbsSurface &a = l.model.surfaces[k], &b = back.surfaces[k];
    EXPECT_EQ(a.control_points, b.control_points);
    EXPECT_EQ(a.reversed, b.reversed);
    ASSERT_EQ(a.trim_loops.size(), b.trim_loops.size());
    for (std::size_t i = 0; i < a.trim_loops.size(); ++i) {
      ASSERT_EQ(a.trim_loops[i].curves.size(), b.trim_loops[i].curves.size());
      for (std::size_t c = 0; c < a.trim_loops[i].curves.size(); ++c) {
        const engine::TrimCurve &x = a.trim_loops[i].curves[c], &y = b.trim_loops[i].curves[c];
        EXPECT_EQ(x.uv.knots, y.uv.knots);
        EXPECT_EQ(x.uv.control_points, y.uv.control_points);
        EXPECT_EQ(x.uv.dimension, 2);
        EXPECT_EQ(y.uv.dimension, 2);
        ASSERT_EQ(x.edge.has_value(), y.edge.has_value());
        if (x.edge) {
          EXPECT_EQ(x.edge->control_points, y.edge->control_points);
        }
      }
    }
  }
}

// Malformed files: InputError naming the file and saying what is wrong, never a crash.
class BadCadFiles : public ::testing::Test {
 protected:
  std::string write(const std::string& name, const std::string& content) {
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "nurbsreg_cad";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / name).string();
    std::ofstream(path, std::ios::binary) << content;
    return path;
  }
  static std::string expect_input_error(const std::string& path) {
    try {
      read_model_file(path);
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), path);
      return e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << path << ": " << typeid(e).name() << ": " << e.what();
      return {};
    }
    ADD_FAILURE() << path << ": accepted";
    return {};
  }
};

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST_F(BadCadFiles, EmptyGarbageMissingAndFacelessFilesAreInputErrors) {
  EXPECT_NE(expect_input_error(write("empty.step", "")).find("empty"), std::string::npos);
  EXPECT_NE(expect_input_error(write("empty.igs", "")).find("empty"), std::string::npos);
  const std::string garbage = "this is not a CAD file\n\x01\x02\x03 nonsense;;;(((\n";
  EXPECT_FALSE(expect_input_error(write("garbage.stp", garbage)).empty());
  EXPECT_FALSE(expect_input_error(write("garbage.iges", garbage)).empty());
  EXPECT_NE(expect_input_error(write("dir", "") + "/missing.step").find("cannot open"),
            std::string::npos);
  // Valid STEP syntax, but nothing that makes a face.
  const std::string faceless =
      "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('','',(''),(''),'','','');"
      "\nFILE_SCHEMA(('CONFIG_CONTROL_DESIGN'));\nENDSEC;\nDATA;\n"
      "#1=CARTESIAN_POINT('',(0.,0.,0.));\nENDSEC;\nEND-ISO-10303-21;\n";
  const std::string message = expect_input_error(write("faceless.step", faceless));
  EXPECT_FALSE(message.empty());
}

TEST_F(BadCadFiles, TruncatedFilesNeverCrash) {
  // Cut real files at several places: an InputError or a (partial) valid model, nothing else.
  for (const char* relative : {"dealii/goteborg.step", "dealii/goteborg.iges"}) {
    const std::string text = read_all(kReal + relative);
    ASSERT_FALSE(text.empty());
    const std::string ext = std::filesystem::path(relative).extension().string();
    for (int k = 1; k <= 4; ++k) {
      const std::string path =
          write("truncated" + std::to_string(k) + ext, text.substr(0, text.size() * k / 5));
      try {
        const engine::Model m = read_model_file(path);
        EXPECT_FALSE(m.validate().has_value());
        EXPECT_FALSE(m.surfaces.empty());
      } catch (const InputError& e) {
        EXPECT_EQ(e.file(), path);
      } catch (const std::exception& e) {
        ADD_FAILURE() << path << ": " << typeid(e).name() << ": " << e.what();
      }
    }
  }
}

}  // namespace
}  // namespace nurbsreg::io
