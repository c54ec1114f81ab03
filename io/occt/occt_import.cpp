// The OpenCASCADE module (libnurbsreg_occt.so, io/src/occt_module.hpp): a STEP or IGES file read
// by OCCT and its faces converted to the engine's trimmed NURBS surfaces. Loaded by io on the
// first import; one import at a time (the caller holds io's OCCT lock).
#include "nurbsreg/io/cad_import.hpp"

// OCCT's readers crash (SIGSEGV) on some malformed files, e.g. a truncated IGES B-spline entity.
// With this macro, OCC_CATCH_SIGNALS turns such a signal inside an import into a C++ exception
// (Debian builds OCCT with it too); see guarded() below.
#ifndef OCC_CONVERT_SIGNALS
#define OCC_CONVERT_SIGNALS
#endif

#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRep_Builder.hxx>
#include <Bnd_Box.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Reader.hxx>
#include <IGESData_IGESModel.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <OSD.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_ErrorHandler.hxx>
#include <Standard_Failure.hxx>
#include <TColStd_SequenceOfAsciiString.hxx>
#include <TopExp.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Compound.hxx>
#include <TopoDS_Shape.hxx>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <optional>
#include <span>

#include <spdlog/spdlog.h>

#include "face_conversion.hpp"
#include "nurbsreg/io/errors.hpp"
#include "occt_module.hpp"

namespace nurbsreg::io {

namespace {

std::string status_text(IFSelect_ReturnStatus status) {
  switch (status) {
    case IFSelect_RetVoid:
      return "nothing to read (empty file?)";
    case IFSelect_RetError:
      return "cannot open or read the file";
    case IFSelect_RetFail:
      return "not a valid file of this format (syntax errors)";
    case IFSelect_RetStop:
      return "the reader stopped (unreadable content)";
    default:
      return "read failed";
  }
}

double diagonal_of(const TopoDS_Shape& shape) {
  Bnd_Box box;
  BRepBndLib::Add(shape, box, Standard_False);
  if (box.IsVoid()) return 0;
  double x0, y0, z0, x1, y1, z1;
  box.Get(x0, y0, z0, x1, y1, z1);
  return std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
}

// Seconds since `start`, for the import's debug log of where its time goes (the NIST part takes
// seconds, nearly all inside OpenCASCADE).
double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// OCCT's NurbsConvert of a compound of the faces `indices` (into `faces`), each converted face
// stored at converted[index]. Where OCCT fails, the two halves are tried, down to single faces,
// which are left empty (convert_face converts them alone and reports why that fails). Returns the
// number of compounds tried: 1 when OCCT converts them all at once.
int nurbs_faces(const TopTools_IndexedMapOfShape& faces, std::span<const int> indices,
                std::vector<std::optional<TopoDS_Face>>& converted) {
  if (indices.empty()) return 0;
  BRep_Builder builder;
  TopoDS_Compound compound;
  builder.MakeCompound(compound);
  for (int i : indices)
    builder.Add(compound, faces(i));
  try {
    BRepBuilderAPI_NurbsConvert convert(compound, Standard_True);
    if (convert.IsDone()) {
      for (int i : indices) {
        const TopoDS_Shape& modified = convert.ModifiedShape(faces(i));
        if (modified.ShapeType() == TopAbs_FACE) converted[i] = TopoDS::Face(modified);
      }
      return 1;
    }
  } catch (const Standard_Failure&) {
  }
  if (indices.size() == 1) return 1;
  const std::size_t half = indices.size() / 2;
  return 1 + nurbs_faces(faces, indices.first(half), converted) +
         nurbs_faces(faces, indices.subspan(half), converted);
}

engine::Model convert_shape(const std::string& path, const TopoDS_Shape& shape,
                            CadImportReport& report) {
  TopTools_IndexedMapOfShape faces;
  TopExp::MapShapes(shape, TopAbs_FACE, faces);
  report.faces = static_cast<std::size_t>(faces.Extent());
  if (faces.Extent() == 0) throw InputError(path, "the file has no faces (no surface geometry)");
  report.diagonal = diagonal_of(shape);
  // Approximations (degree reduction only) stay within 1e-9 of the model's size.
  const double tolerance = 1e-9 * std::max(report.diagonal, 1.0);

  // Analytic faces become B-splines by OCCT's NurbsConvert of a compound of them all: an edge
  // shared by two faces is converted once (face by face would do it twice). B-spline faces stay
  // out of it: they are used as they are, and one of them made the conversion of the whole NIST
  // part fail. Where OCCT fails on the compound, its halves are converted, and so on
  // (nurbs_faces), so that only the failing faces are converted one by one (and skipped if that
  // fails too).
  const auto convert_start = std::chrono::steady_clock::now();
  std::vector<int> analytic;
  for (int i = 1; i <= faces.Extent(); ++i) {
    if (cad_detail::is_analytic(TopoDS::Face(faces(i)))) analytic.push_back(i);
  }
  std::vector<std::optional<TopoDS_Face>> converted(faces.Extent() + 1);
  const int compounds = nurbs_faces(faces, analytic, converted);
  spdlog::debug(
      "{}: OpenCASCADE's NURBS conversion of {} analytic faces in {:.2f} s ({} compound{})", path,
      analytic.size(), seconds_since(convert_start), compounds, compounds == 1 ? "" : "s tried");
  const auto faces_start = std::chrono::steady_clock::now();

  engine::Model model;
  model.units = "mm";  // OCCT's readers convert lengths to millimetres
  for (int i = 1; i <= faces.Extent(); ++i) {
    const int index = i - 1;
    const TopoDS_Face& face = TopoDS::Face(faces(i));
    const std::optional<TopoDS_Face>& nurbs_face = converted[i];
    cad_detail::FaceConversion c =
        cad_detail::convert_face(face, nurbs_face ? &*nurbs_face : nullptr, tolerance);
    ++report.surface_types[c.surface_type.empty() ? "unknown" : c.surface_type];
    if (!c.surface) {
      model.skipped_faces.push_back({index, c.error});
      continue;
    }
    c.surface->name = "face " + std::to_string(index);
    if (c.surface->is_trimmed()) ++report.trimmed_faces;
    if (c.analytic) ++report.analytic_faces;
    report.approximations += static_cast<std::size_t>(c.approximations);
    report.degenerated_edges += static_cast<std::size_t>(c.degenerated_edges);
    report.rebuilt_edges += static_cast<std::size_t>(c.rebuilt_edges);
    report.inconsistent_edges += static_cast<std::size_t>(c.inconsistent_edges);
    report.uv_outside_domain += static_cast<std::size_t>(c.uv_outside_domain);
    report.surface_faces.push_back(index);
    model.surfaces.push_back(std::move(*c.surface));
  }
  spdlog::debug("{}: {} faces converted to trimmed NURBS surfaces in {:.2f} s", path,
                faces.Extent(), seconds_since(faces_start));
  if (model.surfaces.empty()) {
    throw InputError(
        path, "none of the " + std::to_string(faces.Extent()) +
                  " faces could be converted (face 0: " + model.skipped_faces.front().reason + ")");
  }
  return model;
}

template <class Reader>
TopoDS_Shape transfer(const std::string& path, Reader& reader) {
  const auto read_start = std::chrono::steady_clock::now();
  const IFSelect_ReturnStatus status = reader.ReadFile(path.c_str());
  if (status != IFSelect_RetDone) throw InputError(path, status_text(status));
  spdlog::debug("{}: file parsed by OpenCASCADE in {:.2f} s", path, seconds_since(read_start));
  const auto transfer_start = std::chrono::steady_clock::now();
  if (reader.TransferRoots() == 0) throw InputError(path, "no shape could be transferred");
  spdlog::debug("{}: shape transferred and healed by OpenCASCADE in {:.2f} s", path,
                seconds_since(transfer_start));
  TopoDS_Shape shape = reader.OneShape();
  if (shape.IsNull()) throw InputError(path, "no shape could be transferred");
  return shape;
}

// OCCT's signal handlers for the signals a reader bug raises, installed only while an import
// runs (the previous handlers come back afterwards, so the rest of the program is unaffected).
class CrashSignalsAsExceptions {
 public:
  CrashSignalsAsExceptions() {
    for (int s = 1; s < NSIG; ++s)
      saved_ok_[s] = sigaction(s, nullptr, &saved_[s]) == 0;
    OSD::SetSignal(OSD_SignalMode_Set, Standard_False);
    // Keep only the crash signals: Ctrl-C and friends stay the program's.
    for (int s = 1; s < NSIG; ++s) {
      if (!is_crash(s) && saved_ok_[s]) sigaction(s, &saved_[s], nullptr);
    }
  }
  ~CrashSignalsAsExceptions() {
    for (int s = 1; s < NSIG; ++s) {
      if (is_crash(s) && saved_ok_[s]) sigaction(s, &saved_[s], nullptr);
    }
  }
  CrashSignalsAsExceptions(const CrashSignalsAsExceptions&) = delete;
  CrashSignalsAsExceptions& operator=(const CrashSignalsAsExceptions&) = delete;

 private:
  static bool is_crash(int s) { return s == SIGSEGV || s == SIGBUS || s == SIGFPE || s == SIGILL; }
  struct sigaction saved_[NSIG] = {};
  bool saved_ok_[NSIG] = {};
};

// Runs an import with OCCT's exceptions (and crashes inside OCCT) turned into InputError.
template <class Import>
engine::Model guarded(const std::string& path, CadImportReport& r, Import&& import) {
  r = CadImportReport{};
  // OCCT's readers print progress ("Total number of loaded entities") to stdout, which belongs
  // to the CLI's results: silence the default messenger (warnings are reported our way).
  Message::DefaultMessenger()->ChangePrinters().Clear();
  CrashSignalsAsExceptions signals;
  try {
    OCC_CATCH_SIGNALS
    return import(r);
  } catch (const Standard_Failure& e) {
    throw InputError(path, std::string("OpenCASCADE failed on this file: ") +
                               e.DynamicType()->Name() + ": " + e.GetMessageString());
  }
}

}  // namespace

// The reader io chose by the file's extension (io/src/cad_import.cpp).
engine::Model occt_import(const std::string& path, bool step, CadImportReport& report) {
  if (step) {
    return guarded(path, report, [&](CadImportReport& r) {
      r.format = "STEP";
      STEPControl_Reader reader;
      const TopoDS_Shape shape = transfer(path, reader);
      TColStd_SequenceOfAsciiString lengths, angles, solid_angles;
      reader.FileUnits(lengths, angles, solid_angles);
      if (!lengths.IsEmpty()) r.file_units = lengths.First().ToCString();
      return convert_shape(path, shape, r);
    });
  }
  return guarded(path, report, [&](CadImportReport& r) {
    r.format = "IGES";
    IGESControl_Reader reader;
    const TopoDS_Shape shape = transfer(path, reader);
    const Handle(IGESData_IGESModel) model = reader.IGESModel();
    if (!model.IsNull()) {
      const Handle(TCollection_HAsciiString) unit = model->GlobalSection().UnitName();
      if (!unit.IsNull()) r.file_units = unit->ToCString();
    }
    return convert_shape(path, shape, r);
  });
}

}  // namespace nurbsreg::io

// The module's entry points (occt_module.hpp); nothing is thrown across them.
extern "C" {

__attribute__((visibility("default"))) int nurbsreg_occt_abi() {
  return nurbsreg::io::cad_detail::kOcctModuleAbi;
}

__attribute__((visibility("default"))) const char* nurbsreg_occt_version() {
  return NURBSREG_VERSION;
}

__attribute__((visibility("default"))) void nurbsreg_occt_import(
    nurbsreg::io::cad_detail::OcctImportCall* call) {
  using nurbsreg::io::cad_detail::OcctImportCall;
  const std::string& path = *call->path;
  try {
    *call->model = nurbsreg::io::occt_import(path, call->step, *call->report);
    call->status = OcctImportCall::kOk;
  } catch (const nurbsreg::io::InputError& e) {
    std::string what = e.what();
    if (what.starts_with(path + ": ")) what.erase(0, path.size() + 2);
    *call->error = what;
    call->status = OcctImportCall::kInputError;
  } catch (const std::bad_alloc&) {
    call->status = OcctImportCall::kOutOfMemory;
  } catch (const std::exception& e) {
    *call->error = e.what();
    call->status = OcctImportCall::kFailure;
  } catch (...) {
    *call->error = "unknown exception in the OpenCASCADE import";
    call->status = OcctImportCall::kFailure;
  }
}

}  // extern "C"
