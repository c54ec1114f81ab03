// The CLI on STEP and IGES models (through OpenCASCADE): `info` lists faces with their
// trimming; `synth` samples the trimmed faces only; malformed CAD files exit 3 with one line
// naming the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "support/run_command.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {
namespace {

const std::string kReal = nurbsreg::test::shared_dir() + "/data/real/";

TEST(CliCad, InfoListsTheFacesOfAStepFile) {
  ScratchDir dir("cad_info");
  const CommandResult r =
      run_nurbsreg("info --json --model " + kReal + "occt/screw.step", dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto doc = nlohmann::json::parse(r.out);  // nothing but JSON on stdout (OCCT is quiet)
  EXPECT_EQ(doc["units"], "mm");
  EXPECT_EQ(doc["surfaces"].size(), 10u);
  EXPECT_EQ(doc["trimmed_surfaces"], 10);
  EXPECT_EQ(doc["skipped_faces"].size(), 0u);
  EXPECT_EQ(doc["surfaces"][3]["name"], "face 3");
  const CommandResult text =
      run_nurbsreg("info --model " + kReal + "dealii/wigley.iges", dir.path());
  ASSERT_EQ(text.status, 0) << text.err;
  EXPECT_NE(text.out.find("surface 0 \"face 0\""), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("trimmed ("), std::string::npos) << text.out;
}

TEST(CliCad, SynthSamplesTheTrimmedFacesOnly) {
  // hammer.iges: 162 patches, every face trimmed. A noise-free synthetic scan lies on the faces:
  // projected back, each point is at the text file's rounding from the model (coordinates up to
  // ~20,000 mm with 8 significant digits). Sampling the untrimmed surfaces put points up to
  // ~3,000 mm away (mean 131 mm).
  ScratchDir dir("cad_synth");
  const std::string model = kReal + "occt/hammer.iges";
  const CommandResult synth = run_nurbsreg(
      "synth --model " + model + " --points 3000 --noise 0 --seed 2 --out " + (dir / "s.xyz"),
      dir.path());
  ASSERT_EQ(synth.status, 0) << synth.err;
  const CommandResult project = run_nurbsreg(
      "project --model " + model + " --points " + (dir / "s.xyz") + " --out " + (dir / "p.csv"),
      dir.path());
  ASSERT_EQ(project.status, 0) << project.err;
  std::istringstream csv(read_text(dir / "p.csv"));
  std::string line;
  std::getline(csv, line);
  ASSERT_EQ(line.rfind("index,x,y,z,foot_x,foot_y,foot_z,distance,", 0), 0u) << line;
  int rows = 0;
  double largest = 0.0;
  while (std::getline(csv, line)) {
    std::istringstream fields(line);
    std::string field;
    for (int k = 0; k <= 7; ++k)
      std::getline(fields, field, ',');
    largest = std::max(largest, std::stod(field));
    ++rows;
  }
  EXPECT_EQ(rows, 3000);
  EXPECT_LT(largest, 0.01);
}

// A face whose trim loops leave its surface's parameter domain is only partly in the model: every
// command that loads the file says which faces and by how much. NIST CTC 02: faces 278 and 281,
// non-periodic, whose loops run 0.016% of the domain beyond it (the faces whose loops cross a
// periodic or closed surface's seam are whole since the import places their wires); screw.step
// has none.
TEST(CliCad, FacesPartlyBeyondTheirSurfaceAreNamed) {
  ScratchDir dir("cad_beyond");
  const CommandResult nist =
      run_nurbsreg("info --model " + kReal + "nist/nist_ctc_02_asme1_ap242-1.stp", dir.path());
  ASSERT_EQ(nist.status, 0) << nist.err;
  EXPECT_NE(nist.err.find("warning"), std::string::npos) << nist.err;
  EXPECT_NE(nist.err.find("the trim loops of 2 faces leave their surface's parameter domain"),
            std::string::npos)
      << nist.err;
  EXPECT_NE(nist.err.find("face 278 by 0.016%"), std::string::npos) << nist.err;
  for (const char* whole : {"face 27 ", "face 49 ", "face 56 ", "face 279 "})
    EXPECT_EQ(nist.err.find(whole), std::string::npos) << whole << nist.err;
  const CommandResult screw = run_nurbsreg("info --model " + kReal + "occt/screw.step", dir.path());
  ASSERT_EQ(screw.status, 0) << screw.err;
  EXPECT_EQ(screw.err.find("warning"), std::string::npos) << screw.err;
}

TEST(CliCad, MalformedCadFilesExitThreeWithOneLine) {
  ScratchDir dir("cad_bad");
  const std::string step = dir / "broken.step";
  std::ofstream(step) << "ISO-10303-21;\nHEADER;\nthis is not STEP at all (((\n";
  const std::string iges = dir / "broken.igs";
  std::ofstream(iges) << "not an IGES file\n";
  const std::string empty = dir / "empty.stp";
  std::ofstream(empty) << "";
  for (const std::string& model : {step, iges, empty}) {
    const CommandResult r = run_nurbsreg("info --model " + model, dir.path());
    EXPECT_EQ(r.status, 3) << model << ": " << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(model), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

// OpenCASCADE is loaded by an import only (io/src/occt_module.hpp), and io has no PCL: the
// binary links neither, so that a run that reads no CAD file does not pay for loading them.
TEST(CliCad, TheBinaryLinksNeitherOpenCascadeNorPcl) {
  const std::string command = "ldd " + nurbsreg_binary() + " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string libraries;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr)
    libraries += buffer;
  ASSERT_EQ(::pclose(pipe), 0) << libraries;
  ASSERT_NE(libraries.find("libtbb"), std::string::npos) << libraries;  // ldd listed them
  for (const char* absent : {"libTK", "libpcl", "libvtk"})
    EXPECT_EQ(libraries.find(absent), std::string::npos) << absent << " in\n" << libraries;
}

// Without its OpenCASCADE module a STEP import is one clear error naming the module and where
// it was looked for (exit 1: the installation, not the file, is wrong); JSON models need none.
TEST(CliCad, AMissingOpenCascadeModuleIsOneClearError) {
  ScratchDir dir("cad_module");
  const std::string missing = dir / "libnurbsreg_occt.so";
  ::setenv("NURBSREG_OCCT_MODULE", missing.c_str(), 1);
  const CommandResult step =
      run_nurbsreg("--no-cache info --model " + kReal + "occt/screw.step", dir.path());
  const CommandResult json = run_nurbsreg(
      "--no-cache info --model " + nurbsreg::test::examples_dir() + "/panel.json", dir.path());
  ::unsetenv("NURBSREG_OCCT_MODULE");
  EXPECT_EQ(step.status, 1) << step.err;
  EXPECT_NE(step.err.find("OpenCASCADE module libnurbsreg_occt.so"), std::string::npos) << step.err;
  EXPECT_NE(step.err.find(missing + ": no such file"), std::string::npos) << step.err;
  EXPECT_EQ(json.status, 0) << json.err;
}

}  // namespace
}  // namespace nurbsreg::test
