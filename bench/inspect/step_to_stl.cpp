// A tessellation of a STEP part for the peers of bench/inspect (CloudCompare's cloud-to-mesh
// distance needs a mesh): OpenCASCADE's BRepMesh with a stated chord tolerance, written as
// binary STL. The chord tolerance bounds how far the mesh lies from the exact faces, which is
// the error the mesh-based distance inherits.
//
// Usage: step_to_stl PART.stp OUT.stl CHORD_TOLERANCE [ANGLE_RADIANS]
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Poly_Triangulation.hxx>
#include <STEPControl_Reader.hxx>
#include <StlAPI_Writer.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <chrono>
#include <cstdio>
#include <cstdlib>

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: step_to_stl PART.stp OUT.stl CHORD_TOLERANCE [ANGLE_RADIANS]\n");
    return 2;
  }
  const double chord = std::atof(argv[3]);
  const double angle = argc > 4 ? std::atof(argv[4]) : 0.1;
  const auto start = std::chrono::steady_clock::now();
  STEPControl_Reader reader;
  if (reader.ReadFile(argv[1]) != IFSelect_RetDone) {
    std::fprintf(stderr, "error: %s: OpenCASCADE cannot read it\n", argv[1]);
    return 3;
  }
  reader.TransferRoots();
  const TopoDS_Shape shape = reader.OneShape();
  BRepMesh_IncrementalMesh mesh(shape, chord, /*isRelative=*/false, angle, /*isInParallel=*/true);
  std::size_t triangles = 0;
  for (TopExp_Explorer it(shape, TopAbs_FACE); it.More(); it.Next()) {
    TopLoc_Location location;
    const Handle(Poly_Triangulation) t =
        BRep_Tool::Triangulation(TopoDS::Face(it.Current()), location);
    if (!t.IsNull()) triangles += static_cast<std::size_t>(t->NbTriangles());
  }
  StlAPI_Writer writer;
  writer.ASCIIMode() = false;
  if (!writer.Write(shape, argv[2])) {
    std::fprintf(stderr, "error: %s: cannot write\n", argv[2]);
    return 1;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s: %zu triangles, chord tolerance %g, angle %g rad, %.2f s\n", argv[2], triangles,
              chord, angle, seconds);
  return 0;
}
