// Projection result tables: CSV and PCD write -> read is bit-exact (the PCD is read back through
// PCL, an independent reader), the CSV header is the contract's, hostile values survive, and
// bad columns or files give errors naming the column, line or file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include <tbb/global_control.h>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/projection_results.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::io {
namespace {

using engine::Vec3;

std::filesystem::path temp_dir() {
  const auto dir = std::filesystem::path(::testing::TempDir()) / "nurbsreg_io_results";
  std::filesystem::create_directories(dir);
  return dir;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_file(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// A table with skipped inputs (gaps in index), two extra columns and awkward doubles.
ProjectionTable random_table(std::size_t rows, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  ProjectionTable t;
  t.extra_names = {"normal_x", "signed_distance"};
  t.extra_values.resize(2);
  std::uint64_t index = 0;
  const double awkward[] = {-0.0, 5e-324, 1e308, -2.2250738585072014e-308, 0.1, 1.0 / 3.0};
  for (std::size_t r = 0; r < rows; ++r) {
    index += 1 + rng() % 3;
    t.index.push_back(index);
    t.point.emplace_back(test::uniform(rng, -1e4, 1e4), test::uniform(rng, -1, 1), awkward[r % 6]);
    t.foot.emplace_back(test::uniform(rng, -1e4, 1e4), awkward[(r + 1) % 6],
                        test::uniform(rng, -1, 1));
    t.distance.push_back(std::abs(test::uniform(rng, 0, 10)));
    t.entity.push_back(static_cast<std::int32_t>(rng() % 300));
    t.u.push_back(test::uniform(rng, 0, 1));
    t.v.push_back(r % 5 == 0 ? 0.0 : test::uniform(rng, -3, 7));
    t.extra_values[0].push_back(test::uniform(rng, -1, 1));
    t.extra_values[1].push_back(awkward[(r + 2) % 6]);
  }
  return t;
}

template <typename T>
bool bit_equal(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expect_bit_equal(const ProjectionTable& a, const ProjectionTable& b) {
  EXPECT_TRUE(bit_equal(a.index, b.index));
  EXPECT_TRUE(bit_equal(a.point, b.point));
  EXPECT_TRUE(bit_equal(a.foot, b.foot));
  EXPECT_TRUE(bit_equal(a.distance, b.distance));
  EXPECT_TRUE(bit_equal(a.entity, b.entity));
  EXPECT_TRUE(bit_equal(a.u, b.u));
  EXPECT_TRUE(bit_equal(a.v, b.v));
  EXPECT_EQ(a.extra_names, b.extra_names);
  ASSERT_EQ(a.extra_values.size(), b.extra_values.size());
  for (std::size_t k = 0; k < a.extra_values.size(); ++k) {
    EXPECT_TRUE(bit_equal(a.extra_values[k], b.extra_values[k])) << a.extra_names[k];
  }
}

class ProjectionRoundTrip : public ::testing::TestWithParam<const char*> {};

TEST_P(ProjectionRoundTrip, IsBitExact) {
  // 30,000 rows: more than one 1 MB flush block in both formats.
  const ProjectionTable table = random_table(30000, 3);
  const std::string path = (temp_dir() / (std::string("round_trip.") + GetParam())).string();
  write_projection_results(path, table.columns());
  expect_bit_equal(read_projection_results(path), table);
}

INSTANTIATE_TEST_SUITE_P(Formats, ProjectionRoundTrip, ::testing::Values("csv", "pcd", "CSV"));

// More rows than one parallel batch (32 blocks of 8192): one thread and all threads must
// write the same bytes.
TEST(ProjectionResults, CsvBytesDoNotDependOnThreads) {
  // Short numbers keep the two files small; the block logic is what is under test.
  ProjectionTable table;
  const std::size_t rows = 32 * 8192 + 1000;
  for (std::size_t r = 0; r < rows; ++r) {
    const double x = static_cast<double>(r % 1000);
    table.point.emplace_back(x, 0.5, -x);
    table.foot.emplace_back(x, 0, -x);
    table.distance.push_back(0.5);
    table.entity.push_back(static_cast<std::int32_t>(r % 7));
    table.u.push_back(0.25);
    table.v.push_back(x);
  }
  const std::string serial = (temp_dir() / "serial.csv").string();
  const std::string parallel = (temp_dir() / "parallel.csv").string();
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    write_projection_csv(serial, table.columns());
  }
  write_projection_csv(parallel, table.columns());
  const std::string a = read_file(serial);
  EXPECT_EQ(a, read_file(parallel));
  EXPECT_EQ(static_cast<std::size_t>(std::count(a.begin(), a.end(), '\n')), rows + 1);
  EXPECT_EQ(read_projection_csv(parallel).index.back(), rows - 1);
}

TEST(ProjectionResults, CsvHasTheContractHeaderAndRows) {
  ProjectionTable t = random_table(3, 4);
  t.index.clear();  // nothing skipped: rows are numbered 0, 1, 2
  t.point[1] = Vec3(1.5, -2, 0.25);
  t.foot[1] = Vec3(1, -2, 0);
  t.distance[1] = 0.5;
  t.entity[1] = 7;
  t.u[1] = 0.125;
  t.v[1] = 0;
  t.extra_values[0][1] = -1;
  t.extra_values[1][1] = 1e-300;
  const std::string path = (temp_dir() / "header.csv").string();
  write_projection_csv(path, t.columns());
  const std::string text = read_file(path);
  const std::size_t first = text.find('\n');
  EXPECT_EQ(text.substr(0, first),
            "index,x,y,z,foot_x,foot_y,foot_z,distance,entity,u,v,normal_x,signed_distance");
  const std::size_t second = text.find('\n', first + 1);
  const std::size_t third = text.find('\n', second + 1);
  EXPECT_EQ(text.substr(second + 1, third - second - 1),
            "1,1.5,-2,0.25,1,-2,0,0.5,7,0.125,0,-1,1e-300");
  EXPECT_EQ(read_projection_csv(path).index, (std::vector<std::uint64_t>{0, 1, 2}));
}

TEST(ProjectionResults, PcdHeaderDeclaresOneTypedFieldPerColumn) {
  const ProjectionTable t = random_table(5, 6);
  const std::string path = (temp_dir() / "header.pcd").string();
  write_projection_pcd(path, t.columns());
  const std::string text = read_file(path);
  EXPECT_NE(
      text.find(
          "\nFIELDS index x y z foot_x foot_y foot_z distance entity u v normal_x "
          "signed_distance\nSIZE 4 8 8 8 8 8 8 8 4 8 8 8 8\nTYPE U F F F F F F F I F F F F\n"),
      std::string::npos);
  EXPECT_NE(text.find("\nWIDTH 5\nHEIGHT 1\n"), std::string::npos);
  EXPECT_NE(text.find("\nPOINTS 5\nDATA binary\n"), std::string::npos);
  // Packed rows: 4 + 7 x 8 + 4 + 4 x 8 bytes each, nothing else after the header.
  const std::size_t data = text.find("DATA binary\n") + 12;
  EXPECT_EQ(text.size() - data, 5u * (4 + 7 * 8 + 4 + 4 * 8));
}

TEST(ProjectionResults, ColumnsReadByNameInAnyOrder) {
  const std::string path = (temp_dir() / "reordered.csv").string();
  write_file(path,
             "v,u,entity,distance,foot_z,foot_y,foot_x,z,y,x,index,extra\r\n"
             "0.5,0.25,3,1,0,0,0,1,0,0,12,-4\r\n\r\n");
  const ProjectionTable t = read_projection_csv(path);
  ASSERT_EQ(t.rows(), 1u);
  EXPECT_EQ(t.index[0], 12u);
  EXPECT_EQ(t.point[0], Vec3(0, 0, 1));
  EXPECT_EQ(t.entity[0], 3);
  EXPECT_EQ(t.u[0], 0.25);
  EXPECT_EQ(t.v[0], 0.5);
  EXPECT_EQ(t.extra_names, std::vector<std::string>{"extra"});
  EXPECT_EQ(t.extra_values[0][0], -4.0);
}

TEST(ProjectionResults, EmptyTableHasOnlyAHeader) {
  const ProjectionTable empty;
  for (const char* ext : {"csv", "pcd"}) {
    const std::string path = (temp_dir() / (std::string("empty.") + ext)).string();
    write_projection_results(path, empty.columns());
    const ProjectionTable back = read_projection_results(path);
    EXPECT_EQ(back.rows(), 0u) << ext;
  }
}

std::string output_error(const std::string& path, const ProjectionColumns& c) {
  try {
    write_projection_results(path, c);
  } catch (const OutputError& e) {
    return e.what();
  }
  return "";
}

TEST(ProjectionResults, InvalidColumnsAreRefusedWithoutAFile) {
  const ProjectionTable t = random_table(10, 8);
  const auto path = temp_dir() / "refused.csv";
  std::filesystem::remove(path);

  ProjectionColumns short_u = t.columns();
  short_u.u = short_u.u.first(9);
  EXPECT_NE(output_error(path.string(), short_u).find("column u: has 9 values, expected 10"),
            std::string::npos);

  ProjectionColumns bad_name = t.columns();
  bad_name.extra[1].name = "signed distance";
  EXPECT_NE(output_error(path.string(), bad_name).find("\"signed distance\": names use letters"),
            std::string::npos);

  ProjectionColumns clash = t.columns();
  clash.extra[0].name = "u";
  EXPECT_NE(output_error(path.string(), clash).find("clashes with a contract column"),
            std::string::npos);

  ProjectionColumns twice = t.columns();
  twice.extra[1].name = "normal_x";
  EXPECT_NE(output_error(path.string(), twice).find("appears twice"), std::string::npos);

  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_NE(output_error((temp_dir() / "r.txt").string(), t.columns()).find("use a .csv or .pcd"),
            std::string::npos);

  std::vector<std::uint64_t> huge_index(t.index);
  huge_index[4] = std::uint64_t{1} << 32;
  ProjectionColumns huge = t.columns();
  huge.index = huge_index;
  EXPECT_NE(output_error((temp_dir() / "huge.pcd").string(), huge).find("does not fit"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(temp_dir() / "huge.pcd"));
}

std::string input_error(const std::string& text) {
  const std::string path = (temp_dir() / "bad.csv").string();
  write_file(path, text);
  try {
    read_projection_csv(path);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    return e.what();
  }
  return "";
}

TEST(ProjectionResults, MalformedCsvNamesLineAndColumn) {
  const std::string header = "index,x,y,z,foot_x,foot_y,foot_z,distance,entity,u,v\n";
  EXPECT_NE(input_error("").find("empty file"), std::string::npos);
  EXPECT_NE(input_error("index,x,y,z,foot_x,foot_y,foot_z,distance,entity,u\n")
                .find("line 1 (header): required column \"v\" is missing"),
            std::string::npos);
  EXPECT_NE(input_error("index,x,y,z,foot_x,foot_y,foot_z,distance,entity,u,v,x\n")
                .find("\"x\" appears twice"),
            std::string::npos);
  EXPECT_NE(input_error(header + "0,0,0,0,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0,0,0\n")
                .find("line 3: expected 11 comma-separated values (as in the header), got 10"),
            std::string::npos);
  EXPECT_NE(input_error(header + "0,0,0,zero,0,0,0,0,0,0,0\n")
                .find("line 2, column 4: not a number: 'zero'"),
            std::string::npos);
  EXPECT_NE(input_error(header + "-1,0,0,0,0,0,0,0,0,0,0\n")
                .find("line 2: index must be a non-negative integer"),
            std::string::npos);
  EXPECT_NE(
      input_error(header + "0,0,0,0,0,0,0,0,1.5,0,0\n").find("line 2: entity must be an integer"),
      std::string::npos);
}

TEST(ProjectionResults, UnreadablePcdIsAnInputError) {
  EXPECT_THROW(read_projection_pcd((temp_dir() / "missing.pcd").string()), InputError);
  const std::string path = (temp_dir() / "garbage.pcd").string();
  write_file(path, "this is not a point cloud\n");
  EXPECT_THROW(read_projection_pcd(path), InputError);
}

}  // namespace
}  // namespace nurbsreg::io
