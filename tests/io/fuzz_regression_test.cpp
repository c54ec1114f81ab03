// Every input the fuzzers found (tests/data/fuzz-regressions, copied from
// shared/data/fuzz-findings; README there) and each new finding: what the readers must do with
// it now. Each case names the finding; the messages checked are the user's one line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/io/modify_io.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"
#include "nurbsreg/io/pose.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

namespace fs = std::filesystem;

const std::string kFindings = nurbsreg::test::examples_dir() + "/../tests/data/fuzz-regressions/";

// The message of the InputError that `read` throws ("" and a test failure when none).
template <class Read>
std::string error_of(Read&& read) {
  try {
    read();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

bool printable(const std::string& s) {
  for (const char c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) return false;
  }
  return true;
}

#define EXPECT_HAS(haystack, needle) \
  EXPECT_NE((haystack).find(needle), std::string::npos) << (haystack)

class Scratch {
 public:
  Scratch() {
    static int counter = 0;
    dir_ = fs::temp_directory_path() /
           ("nurbsreg_fuzzreg_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(dir_);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string write(const std::string& name, const std::string& text) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }

 private:
  fs::path dir_;
};

// Sets an environment variable for one test (each test runs in its own process under ctest).
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) { setenv(name, value, 1); }
  ~ScopedEnv() { unsetenv(name_); }

 private:
  const char* name_;
};

// ---- PCD ---------------------------------------------------------------------------------

TEST(FuzzRegression, PcdCountThatWrapsTheRowSizeIsRejected) {
  // Was: heap write overflow in the ascii reader, SIGSEGV without a message.
  const std::string ascii = kFindings + "pcd_count_wrap_ascii_hbo_write.pcd";
  EXPECT_HAS(error_of([&] { read_point_cloud(ascii); }),
             "PCD field 'y': COUNT 18446744073709551615 makes the row size overflow");
  // Was: 8.6 GB allocated by PCL's header reader from a 102-byte file.
  const std::string binary = kFindings + "pcd_count_wrap_binary_8GB_alloc.pcd";
  EXPECT_HAS(error_of([&] { read_point_cloud(binary); }),
             "PCD field 'y': COUNT 4611686018427387904 makes the row size overflow");
}

TEST(FuzzRegression, PcdCountZeroIsRejectedByName) {
  // Was: exit 0 with coordinates read from the neighbouring field or past the buffer.
  EXPECT_HAS(error_of([&] { read_point_cloud(kFindings + "pcd_count0_ascii_silent.pcd"); }),
             "PCD field 'x': COUNT 0");
  EXPECT_HAS(error_of([&] { read_point_cloud(kFindings + "pcd_count0_binary_min.pcd"); }),
             "PCD field 'z': COUNT 0");
  EXPECT_HAS(error_of([&] { read_point_cloud(kFindings + "pcd_count0_binary_hbo.pcd"); }),
             "PCD field 'y': COUNT 0");
}

TEST(FuzzRegression, PcdPaddingFieldInBinaryCompressedReadsLikeBinary) {
  // Was: rows read with the wrong stride (exit 0, wrong coordinates). `_` is a padding plane
  // like any other: x = 1..4, y = 10..40, z = 100..400 (the planes of the file, decoded by hand).
  const PointCloud cloud = read_point_cloud(kFindings + "pcd_underscore_bc_silent.pcd");
  ASSERT_EQ(cloud.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(cloud.points[i], engine::Vec3(i + 1, 10 * (i + 1), 100 * (i + 1))) << i;
  }
}

// Found by UBSan in io_tests (2026-12-02): an ASCII PCD table's integer value went through
// double into the column's type, and 18446744073709551615 (U8's maximum) rounds to 2^64,
// beyond uint64_t: the cast was undefined behaviour, as for any value beyond the type or NaN.
TEST(FuzzRegression, PcdAsciiIntegersBeyondTheirTypeAreRejected) {
  Scratch dir;
  const std::string header =
      "VERSION 0.7\nFIELDS x y z id\nSIZE 4 4 4 ID_SIZE\nTYPE F F F ID_TYPE\nCOUNT 1 1 1 1\n"
      "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n";
  const auto file = [&](const std::string& size, const std::string& type, const std::string& id) {
    std::string text = header;
    text.replace(text.find("ID_SIZE"), 7, size);
    text.replace(text.find("ID_TYPE"), 7, type);
    return dir.write("t" + size + type + ".pcd", text + "1 2 3 " + id + "\n");
  };
  const PointTable max = read_point_table(file("8", "U", "18446744073709551615"));
  EXPECT_EQ((*max.values<std::uint64_t>("id"))[0], std::numeric_limits<std::uint64_t>::max());
  struct Case {
    const char *size, *type, *id;
  };
  // (Not a structured binding: clang 14 cannot capture one in the lambda.)
  for (const Case c : {Case{"8", "U", "1e30"}, Case{"4", "U", "-1"}, Case{"4", "I", "nan"},
                       Case{"8", "I", "1e19"}}) {
    const std::string message = error_of([&] { read_point_table(file(c.size, c.type, c.id)); });
    EXPECT_HAS(message, "PCD field 'id': value ");
    EXPECT_HAS(message, std::string("is outside TYPE ") + c.type + " SIZE " + c.size);
  }
}

TEST(FuzzRegression, PcdPointsZeroWithABodyIsRejected) {
  EXPECT_HAS(
      error_of([&] { read_point_cloud(kFindings + "pcd_points0_garbage_body_accepted.pcd"); }),
      "line 7: more data than POINTS 0");
}

TEST(FuzzRegression, PcdHeaderClaimsBeyondTheFileAreRejectedBeforeAllocation) {
  Scratch dir;
  const std::string huge =
      dir.write("huge.pcd",
                "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1000000 1 1\nPOINTS 100000000\nDATA "
                "binary\n0123");
  EXPECT_HAS(error_of([&] { read_point_cloud(huge); }), "PCD data is truncated or corrupt");
}

TEST(FuzzRegression, PcdCountsBeyondTheFileAreRejectedWithNoPoints) {
  // Found by CI's fuzz stage (2026-12-03): POINTS 0 (WIDTH 2 HEIGHT 0), so no body size check
  // bounded the COUNTs, and the table reader made a column per value: 4.6e14 columns (out of
  // memory at 2 GB) or 4.7e13 column names (a timeout).
  for (const char* name :
       {"pcd_points0_huge_count_table_oom.pcd", "pcd_points0_huge_count_table_timeout.pcd"}) {
    SCOPED_TRACE(name);
    const std::string file = kFindings + name;
    const std::string table = error_of([&] { read_point_table(file); });
    EXPECT_HAS(table, file + ": PCD header: the COUNTs add up to ");
    EXPECT_HAS(table, " values per point, more than the file's ");
    EXPECT_HAS(error_of([&] { read_point_cloud(file); }), "values per point, more than the file's");
  }
  // The bound is the file's size, not a fixed cap: a wide record that the file holds is read.
  Scratch dir;
  const PointTable wide =
      read_point_table(dir.write("wide.pcd",
                                 "FIELDS x y z h\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 33\n"
                                 "POINTS 0\nDATA ascii\n"));
  EXPECT_EQ(wide.columns().size(), 36u);
}

// ---- PLY ---------------------------------------------------------------------------------

TEST(FuzzRegression, PlyCountsAreIntegersNotCastFloats) {
  // Was: float-to-integer cast overflow (undefined behaviour) on 1e30 and 1e300.
  EXPECT_HAS(error_of([&] { read_point_cloud(kFindings + "ply_count_float_cast_ub.ply"); }),
             "line 3: expected 'element <name> <count>' with a non-negative integer count, got "
             "'1e30'");
  EXPECT_HAS(error_of([&] { read_point_cloud(kFindings + "ply_listlen_float_cast_ub.ply"); }),
             "property 'l': list length is not a non-negative integer: '1e300'");
}

// ---- Pose --------------------------------------------------------------------------------

TEST(FuzzRegression, PoseErrorsShowControlBytesEscaped) {
  const std::string message =
      error_of([&] { read_pose(kFindings + "pose_raw_escape_in_message.txt"); });
  EXPECT_TRUE(printable(message)) << message;
  EXPECT_HAS(message, "line 4: '\\x1b[31m1' is not a finite number");
}

// ---- STEP --------------------------------------------------------------------------------

TEST(FuzzRegression, StepSelfReferenceBecomesAnErrorNotACrash) {
  // Was: unbounded recursion inside OpenCASCADE, stack overflow, SIGSEGV, no message. The
  // import's child process dies instead; this process gets one line naming the file.
  for (const char* name : {"step_oriented_edge_self_ref_stack_overflow.step",
                           "step_surface_curve_self_ref_stack_overflow.step"}) {
    const std::string path = kFindings + name;
    const std::string message = error_of([&] { read_model_file(path); });
    EXPECT_TRUE(message.starts_with(path + ": ")) << message;
    EXPECT_TRUE(printable(message)) << message;
    // A plain build sees the signal; under AddressSanitizer its handler reports the overflow
    // and exits with status 1.
    EXPECT_TRUE(message.find("reader crashed on this file (signal 11") != std::string::npos ||
                message.find("import process ended (exit status") != std::string::npos)
        << message;
  }
}

TEST(FuzzRegression, CadImportTimeoutAndMemoryLimitsAreReported) {
  // A wall-clock limit of 1 s is too short for no file here, so take the NIST part's STEP
  // import (seconds) to check that the limit stops it with the documented message.
  const std::string nist =
      nurbsreg::test::shared_dir() + "/data/real/nist/nist_ctc_02_asme1_ap242-1.stp";
  const ScopedEnv timeout("NURBSREG_CAD_TIMEOUT", "1");
  // From the model cache the import would not run at all.
  const ScopedEnv no_cache("NURBSREG_NO_CACHE", "1");
  // The limit is both a wall-clock deadline (the parent stops the import) and the child's CPU
  // limit (RLIMIT_CPU, SIGXCPU): a single-threaded import on an idle core reaches both at about
  // 1 s, either first. Both messages name the limit and how to raise it.
  const std::string message = error_of([&] { read_model_file(nist); });
  EXPECT_TRUE(message.find("STEP import did not finish within 1 s and was stopped (raise the "
                           "limit with NURBSREG_CAD_TIMEOUT=<s>)") != std::string::npos ||
              message.find("STEP import used more than 1 s of CPU time and was stopped "
                           "(NURBSREG_CAD_TIMEOUT=<s>)") != std::string::npos)
      << message;
}

// ---- JSON models -------------------------------------------------------------------------

TEST(FuzzRegression, FileBytesInMessagesAreEscaped) {
  // Found in the fuzz stage's first full run (2026-12-02): messages quoted bytes of the file
  // raw: a PCD field name, a PLY property name, a CSV column name (fuzz_xyz's CSV pass, which
  // had read the .xyz scratch file until then), nlohmann's "last read" excerpt of a JSON model.
  // Names from files now go through text_detail::quote, library messages through printable.
  const std::string pcd =
      error_of([&] { read_point_cloud(kFindings + "pcd_raw_bytes_in_field_name.pcd"); });
  EXPECT_TRUE(printable(pcd)) << pcd;
  EXPECT_HAS(pcd, "PCD field 'z\\xff\\xff");
  EXPECT_HAS(pcd, "': COUNT 0");
  const std::string ply =
      error_of([&] { read_point_cloud(kFindings + "ply_raw_bytes_in_property_name.ply"); });
  EXPECT_TRUE(printable(ply)) << ply;
  EXPECT_HAS(ply, "line 13: property '\\x");
  const std::string csv =
      error_of([&] { read_point_table(kFindings + "csv_raw_bytes_in_column_name.csv"); });
  EXPECT_TRUE(printable(csv)) << csv;
  EXPECT_HAS(csv, "column '\\xc3\\xaf\\xc2\\xbb\\xc2\\xbfindex': names may hold only");
  const std::string json =
      error_of([&] { read_model_json(kFindings + "json_raw_bytes_in_syntax_error.json"); });
  EXPECT_TRUE(printable(json)) << json;
  EXPECT_HAS(json, "line 11, column 52: invalid JSON: ");
  EXPECT_HAS(json, "36,\\xe0");
  // Found by the fuzz stage (2026-12-03): a JSON string value quoted in a message kept its DEL
  // byte (JSON escapes only control characters); a UTF-8 letter likewise.
  const std::string del =
      error_of([&] { read_model_json(kFindings + "json_del_byte_in_string_message.json"); });
  EXPECT_TRUE(printable(del)) << del;
  EXPECT_HAS(del, "at the top level, got a string (\"\\x7fnH ] 11,");
  Scratch dir;
  const std::string utf8 =
      error_of([&] { read_model_json(dir.write("utf8.json", "\"\xc3\xa9t\xc3\xa9\"")); });
  EXPECT_TRUE(printable(utf8)) << utf8;
  EXPECT_HAS(utf8, "got a string (\"\\xc3\\xa9t\\xc3\\xa9\")");
}

TEST(FuzzRegression, ModelCoordinatesBeyondTheProjectionsRangeAreRejected) {
  // Was: `project` wrote NaN rows with exit 0 (1e155), or ran for minutes (1e150).
  for (const char* name :
       {"json_cp1e155_project_nonfinite.json", "json_cp1e150_project_timeout.json"}) {
    const std::string message = error_of([&] { read_model_json(kFindings + name); });
    EXPECT_HAS(message, "surface 0: control_points[");
    EXPECT_HAS(message, "is beyond the supported range |coordinate| <= 1e15");
  }
  // And the scan that came with it: its points are as far out.
  EXPECT_HAS(error_of([&] { read_scan(kFindings + "json_cp1e150_project_timeout_points.xyz"); }),
             "point 1: y = -7.7674238621028755e+149 is beyond the supported range");
}

TEST(FuzzRegression, KnotsAndWeightsBeyondTheRangeAreRejected) {
  const std::string base =
      R"({"nurbsreg_model": 1, "curves": [{"name": "c", "degree": 1, "knots": KNOTS,
          "control_points": [[0, 0], [1, 0]], "weights": WEIGHTS}]})";
  const auto model = [&](const std::string& knots, const std::string& weights) {
    std::string text = base;
    text.replace(text.find("KNOTS"), 5, knots);
    text.replace(text.find("WEIGHTS"), 7, weights);
    return text;
  };
  EXPECT_HAS(error_of([&] { parse_model(model("[0, 0, 1e16, 1e16]", "[1, 1]"), "m.json"); }),
             "m.json: curve 0 \"c\": knots[2] = 1e+16 is beyond the supported parameter range");
  EXPECT_HAS(error_of([&] { parse_model(model("[0, 0, 1e-50, 1e-50]", "[1, 1]"), "m.json"); }),
             "knots[2]: knot span 1e-50 is narrower than the supported 1e-40");
  EXPECT_HAS(error_of([&] { parse_model(model("[0, 0, 1, 1]", "[1, 1e11]"), "m.json"); }),
             "weights[1] = 1e+11 is outside the supported range [1e-10, 1e10]");
  EXPECT_NO_THROW(parse_model(model("[0, 0, 1, 1]", "[1e-3, 1e3]"), "m.json"));
}

// gen_json_deg12_patch_blowup.py: one degree-12 surface, n x n control points, distinct knots.
std::string degree12_model(int n) {
  const int p = 12;
  std::string knots = "[";
  for (int i = 0; i <= p; ++i)
    knots += "0,";
  for (int i = 1; i < n - p; ++i)
    knots += std::to_string(i) + ",";
  for (int i = 0; i <= p; ++i)
    knots += std::to_string(n - p) + (i < p ? "," : "]");
  std::string rows;
  for (int i = 0; i < n; ++i) {
    rows += i ? ",[" : "[";
    for (int j = 0; j < n; ++j)
      rows += (j ? ",[" : "[") + std::to_string(i) + "," + std::to_string(j) + ",0]";
    rows += "]";
  }
  return R"({"nurbsreg_model":1,"surfaces":[{"degree":[12,12],"knots_u":)" + knots +
         R"(,"knots_v":)" + knots + R"(,"control_points":[)" + rows + "]}]}";
}

TEST(FuzzRegression, ModelsBeyondTheBezierLimitAreRejectedWithTheSwitch) {
  // Was: 82,944 patches and 850 MB for `info` on a 1 MB file, without a limit.
  const std::string message = error_of([&] { parse_model(degree12_model(300), "deg12.json"); });
  EXPECT_HAS(message,
             "deg12.json: the model decomposes into 82944 Bezier patches with 14017536 "
             "control points in all, more than the limit of 4000000");
  EXPECT_HAS(message, "surface 0, has 288 x 288 patches of degree (12, 12)");
  EXPECT_HAS(message, "NURBSREG_MAX_BEZIER_POINTS=<n>");
  // Raised, the same model loads.
  const ScopedEnv raised("NURBSREG_MAX_BEZIER_POINTS", "20000000");
  EXPECT_EQ(parse_model(degree12_model(300), "deg12.json").surfaces.size(), 1u);
}

// ---- Limits and empty scans ------------------------------------------------------------------

TEST(FuzzRegression, PointAndByteLimitsNameTheirSwitches) {
  Scratch dir;
  const std::string xyz = dir.write("three.xyz", "0 0 0\n1 1 1\n2 2 2\n");
  {
    const ScopedEnv limit("NURBSREG_MAX_POINTS", "2");
    EXPECT_HAS(error_of([&] { read_point_cloud(xyz); }),
               "three.xyz: more than 2 points, the limit (raise it with NURBSREG_MAX_POINTS=<n>)");
  }
  {
    const ScopedEnv limit("NURBSREG_MAX_FILE_BYTES", "10");
    EXPECT_HAS(error_of([&] { read_point_cloud(xyz); }),
               "three.xyz: the file has 18 bytes, more than the limit of 10 (raise it with "
               "NURBSREG_MAX_FILE_BYTES=<bytes>)");
  }
  {
    const ScopedEnv bad("NURBSREG_MAX_POINTS", "lots");
    EXPECT_HAS(error_of([&] { read_point_cloud(xyz); }),
               "environment variable NURBSREG_MAX_POINTS: expected a positive integer, got 'lots'");
  }
  EXPECT_EQ(read_point_cloud(xyz).size(), 3u);
}

TEST(FuzzRegression, AnEmptyScanIsBadInput) {
  Scratch dir;
  EXPECT_HAS(error_of([&] { read_scan(dir.write("empty.xyz", "")); }),
             "empty.xyz: the scan has no points");
  EXPECT_HAS(error_of([&] { read_scan(dir.write("nan.xyz", "nan 0 0\n")); }),
             "nan.xyz: the scan has no finite points (all 1 are NaN or infinite)");
  // The plain reader still reads an empty file (a valid, empty cloud).
  EXPECT_EQ(read_point_cloud(dir.write("empty2.xyz", "")).total, 0u);
}

// ---- One number parser -------------------------------------------------------------------

TEST(FuzzRegression, OneNumberParserEverywhere) {
  // `1e999` was inf in the point readers and an error in the pose and table readers: now an
  // error in all of them, saying why.
  Scratch dir;
  EXPECT_HAS(error_of([&] { read_point_cloud(dir.write("a.xyz", "1e999 0 0\n")); }),
             "line 1: column 1: out of the range of a double: '1e999'");
  EXPECT_HAS(error_of([&] { read_point_table(dir.write("b.csv", "x,y\n1,1e999\n")); }),
             "line 2: column 'y': out of the range of a double: '1e999'");
  EXPECT_HAS(
      error_of([&] { read_pose(dir.write("c.txt", "1 0 0 1e999\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")); }),
      "line 1: '1e999' is not a finite number");
  EXPECT_HAS(error_of([&] { read_modify_targets(dir.write("d.csv", "segment,x,y\n0,1e999,0\n")); }),
             "line 2: x: expected a finite number, got '1e999'");
  EXPECT_HAS(error_of([&] {
               read_point_cloud(dir.write("e.ply",
                                          "ply\nformat ascii 1.0\nelement vertex 1\n"
                                          "property float x\nproperty float y\n"
                                          "property float z\nend_header\n0 1e999 0\n"));
             }),
             "property 'y': out of the range of a double: '1e999'");
  // `inf` and `nan` literals stay non-finite values, skipped and counted.
  const PointCloud cloud = read_point_cloud(dir.write("f.xyz", "inf 0 0\nnan 1 1\n2 2 2\n"));
  EXPECT_EQ(cloud.size(), 1u);
  EXPECT_EQ(cloud.skipped_nonfinite, 2u);
}

}  // namespace
}  // namespace nurbsreg::io
