// Point-cloud and point-table I/O: the real scans in shared/data/real (counts from SOURCES.md,
// coordinates against independent decoders written here: an istream parser for ascii files and
// a separate LZF decoder for binary_compressed), round trips through every writer, hand-made
// binary PLY files of both byte orders, and malformed input of every format.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

namespace fs = std::filesystem;
using engine::Vec3;

const std::string kPcl = nurbsreg::test::shared_dir() + "/data/real/pcl/";
const std::string kBunny = nurbsreg::test::shared_dir() + "/data/real/stanford-bunny-scans/";

class TempDir {
 public:
  TempDir() {
    static int counter = 0;
    path_ = fs::temp_directory_path() /
            ("nurbsreg_point_io_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::size_t entries() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(path_), fs::directory_iterator()));
  }

 private:
  fs::path path_;
};

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Runs `read`, expects an InputError whose message names the file and contains every fragment.
template <class Read>
void expect_input_error(const std::string& path, std::initializer_list<std::string> fragments,
                        Read read) {
  try {
    read();
    ADD_FAILURE() << path << ": expected InputError, got success";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(fs::path(path).filename().string()), std::string::npos) << what;
    EXPECT_EQ(e.file(), path);
    for (const std::string& fragment : fragments) {
      EXPECT_NE(what.find(fragment), std::string::npos) << "'" << fragment << "' not in: " << what;
    }
  } catch (const std::exception& e) {
    ADD_FAILURE() << path << ": expected InputError, got " << e.what();
  }
}

void expect_cloud_error(const std::string& path, std::initializer_list<std::string> fragments) {
  expect_input_error(path, fragments, [&] { read_point_cloud(path); });
}

// ---- independent reference decoders ------------------------------------------------------

struct RefHeader {
  std::vector<std::string> fields;
  std::vector<int> sizes, counts;
  std::vector<char> types;
  std::size_t points = 0;
  std::string data;
  std::size_t data_offset = 0;
};

RefHeader ref_header(const std::string& bytes) {
  RefHeader h;
  std::size_t pos = 0;
  while (h.data.empty()) {
    const std::size_t eol = bytes.find('\n', pos);
    std::istringstream line(bytes.substr(pos, eol - pos));
    pos = eol + 1;
    std::string key;
    line >> key;
    if (key == "FIELDS") {
      for (std::string s; line >> s;)
        h.fields.push_back(s);
    } else if (key == "SIZE") {
      for (int v; line >> v;)
        h.sizes.push_back(v);
    } else if (key == "COUNT") {
      for (int v; line >> v;)
        h.counts.push_back(v);
    } else if (key == "TYPE") {
      for (char v; line >> v;)
        h.types.push_back(v);
    } else if (key == "POINTS") {
      line >> h.points;
    } else if (key == "DATA") {
      line >> h.data;
    }
  }
  if (h.counts.empty()) h.counts.assign(h.fields.size(), 1);
  h.data_offset = pos;
  return h;
}

// LZF decoder after Marc Lehmann's liblzf lzf_d.c (format: control byte < 32 = literal run of
// ctrl+1 bytes; otherwise a back reference of length (ctrl >> 5) + 2, 7 meaning "add next byte",
// at distance ((ctrl & 31) << 8) + next byte + 1).
std::string ref_lzf_decompress(const unsigned char* in, std::size_t in_size, std::size_t out_size) {
  std::string out;
  std::size_t i = 0;
  while (i < in_size) {
    const unsigned ctrl = in[i++];
    if (ctrl < 32) {
      out.append(reinterpret_cast<const char*>(in + i), ctrl + 1);
      i += ctrl + 1;
    } else {
      std::size_t length = ctrl >> 5;
      if (length == 7) length += in[i++];
      const std::size_t distance = ((ctrl & 31u) << 8) + in[i++] + 1;
      length += 2;
      const std::size_t from = out.size() - distance;
      for (std::size_t k = 0; k < length; ++k)
        out.push_back(out[from + k]);
    }
  }
  EXPECT_EQ(out.size(), out_size);
  return out;
}

// All points (NaN included) of a PCD whose x y z are F4, decoded without our reader.
std::vector<std::array<float, 3>> ref_pcd_points(const std::string& path) {
  const std::string bytes = read_bytes(path);
  const RefHeader h = ref_header(bytes);
  std::vector<std::array<float, 3>> points(h.points);
  std::vector<int> index(3);
  for (int a = 0; a < 3; ++a) {
    index[a] = static_cast<int>(
        std::find(h.fields.begin(), h.fields.end(), std::string(1, static_cast<char>('x' + a))) -
        h.fields.begin());
  }
  if (h.data == "ascii") {
    std::istringstream body(bytes.substr(h.data_offset));
    for (auto& p : points) {
      std::vector<float> row(h.fields.size());
      for (float& v : row)
        body >> v;
      for (int a = 0; a < 3; ++a)
        p[a] = row[index[a]];
    }
    return points;
  }
  std::size_t step = 0;
  for (std::size_t f = 0; f < h.fields.size(); ++f)
    step += h.sizes[f] * h.counts[f];
  if (h.data == "binary_compressed") {
    std::uint32_t sizes[2];
    std::memcpy(sizes, bytes.data() + h.data_offset, 8);
    const std::string soa =
        ref_lzf_decompress(reinterpret_cast<const unsigned char*>(bytes.data()) + h.data_offset + 8,
                           sizes[0], sizes[1]);
    for (int a = 0; a < 3; ++a) {
      std::size_t start = 0;
      for (int f = 0; f < index[a]; ++f)
        start += h.sizes[f] * h.counts[f] * h.points;
      for (std::size_t i = 0; i < h.points; ++i) {
        std::memcpy(&points[i][a], soa.data() + start + 4 * i, 4);
      }
    }
    return points;
  }
  for (int a = 0; a < 3; ++a) {
    std::size_t offset = 0;
    for (int f = 0; f < index[a]; ++f)
      offset += h.sizes[f] * h.counts[f];
    for (std::size_t i = 0; i < h.points; ++i) {
      std::memcpy(&points[i][a], bytes.data() + h.data_offset + i * step + offset, 4);
    }
  }
  return points;
}

// Checks `cloud` against all points of the file: finite ones kept in order with their index,
// the others counted.
void expect_matches(const PointCloud& cloud, const std::vector<std::array<float, 3>>& all) {
  ASSERT_EQ(cloud.total, all.size());
  std::size_t kept = 0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const auto& p = all[i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
    ASSERT_LT(kept, cloud.size());
    ASSERT_EQ(cloud.source_index[kept], i);
    ASSERT_EQ(cloud.points[kept], Vec3(p[0], p[1], p[2])) << "point " << i;
    ++kept;
  }
  EXPECT_EQ(kept, cloud.size());
  EXPECT_EQ(cloud.skipped_nonfinite, all.size() - kept);
}

// ---- real files --------------------------------------------------------------------------

TEST(RealPcd, AsciiBunny) {
  const PointCloud cloud = read_point_cloud(kPcl + "bunny.pcd");
  EXPECT_EQ(cloud.size(), 397u);
  EXPECT_EQ(cloud.skipped_nonfinite, 0u);
  // First data line; F4 fields hold floats.
  EXPECT_EQ(cloud.points.front(), Eigen::Vector3f(0.0054216f, 0.11349f, 0.040749f).cast<double>());
  expect_matches(cloud, ref_pcd_points(kPcl + "bunny.pcd"));
}

TEST(RealPcd, AsciiWithNormalsAndOldVersion) {
  // bun0: x y z normal_x normal_y normal_z curvature (v0.7); bun4: version .5 header.
  const PointCloud bun0 = read_point_cloud(kPcl + "bun0.pcd");
  EXPECT_EQ(bun0.size(), 397u);
  EXPECT_EQ(bun0.points.front(),
            Eigen::Vector3f(0.0054215998f, 0.11349f, 0.040748999f).cast<double>());
  expect_matches(bun0, ref_pcd_points(kPcl + "bun0.pcd"));
  const PointCloud bun4 = read_point_cloud(kPcl + "bun4.pcd");
  EXPECT_EQ(bun4.size(), 361u);
  expect_matches(bun4, ref_pcd_points(kPcl + "bun4.pcd"));
}

TEST(RealPcd, Binary) {
  const PointCloud cloud = read_point_cloud(kPcl + "curve_close.pcd");
  EXPECT_EQ(cloud.size(), 110u);
  expect_matches(cloud, ref_pcd_points(kPcl + "curve_close.pcd"));
}

TEST(RealPcd, BinaryCompressedMilkAndCar) {
  const PointCloud milk = read_point_cloud(kPcl + "milk.pcd");
  EXPECT_EQ(milk.size(), 13704u);
  expect_matches(milk, ref_pcd_points(kPcl + "milk.pcd"));
  const PointCloud car = read_point_cloud(kPcl + "car6.pcd");
  EXPECT_EQ(car.size(), 10031u);
  expect_matches(car, ref_pcd_points(kPcl + "car6.pcd"));
}

TEST(RealPcd, OrganisedStereoScanWithNaN) {
  const std::string path = kPcl + "table_scene_mug_stereo_textured.pcd";
  const PointCloud cloud = read_point_cloud(path);
  EXPECT_EQ(cloud.total, 307200u);
  EXPECT_EQ(cloud.size(), 209280u);
  EXPECT_EQ(cloud.skipped_nonfinite, 307200u - 209280u);
  EXPECT_EQ(cloud.width, 640u);
  EXPECT_EQ(cloud.height, 480u);
  expect_matches(cloud, ref_pcd_points(path));
}

TEST(RealPly, StanfordRangeScans) {
  for (const auto& [name, count] :
       {std::pair<std::string, std::size_t>{"bun000.ply", 40256}, {"bun045.ply", 40097}}) {
    const std::string path = kBunny + name;
    const PointCloud cloud = read_point_cloud(path);
    ASSERT_EQ(cloud.size(), count) << name;
    EXPECT_EQ(cloud.skipped_nonfinite, 0u);
    // Reference: the `count` lines after end_header, parsed by an istream (properties are
    // declared float).
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line) && line.rfind("end_header", 0) != 0) {
    }
    for (std::size_t i = 0; i < count; ++i) {
      ASSERT_TRUE(std::getline(in, line));
      std::istringstream fields(line);
      float x, y, z;
      fields >> x >> y >> z;
      ASSERT_EQ(cloud.points[i], Vec3(x, y, z)) << name << " vertex " << i;
      ASSERT_EQ(cloud.source_index[i], i);
    }
  }
}

// ---- round trips -------------------------------------------------------------------------

std::vector<Vec3> random_points(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1000.0, 1000.0);
  std::vector<Vec3> points(n);
  for (Vec3& p : points)
    p = Vec3(u(rng), u(rng) * 1e-7, u(rng) * 1e5);
  points[0] = Vec3(0.1, -0.0, 1e-300);  // shortest-form printing must keep these exactly
  points[1] = Vec3(std::numeric_limits<double>::max(), std::numeric_limits<double>::denorm_min(),
                   -std::numeric_limits<double>::min());
  return points;
}

// PCL pads PointXYZRGB-like types with `_` fields; the coordinates after the padding must be
// found at the right offsets (binary: interleaved rows).
TEST(HandMadePcd, PaddingFieldsAndFieldOrder) {
  TempDir dir;
  const std::string path = dir.file("pad.pcd");
  std::string bytes =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS rgb _ z x y\nSIZE 4 1 8 4 2\nTYPE U U F F I\n"
      "COUNT 1 4 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n";
  for (int i = 0; i < 2; ++i) {
    const std::uint32_t rgb = 0xff00ffu;
    const char pad[4] = {9, 9, 9, 9};
    const double z = 0.5 + i;
    const float x = -1.25f * static_cast<float>(i + 1);
    const std::int16_t y = static_cast<std::int16_t>(-300 + i);
    bytes.append(reinterpret_cast<const char*>(&rgb), 4);
    bytes.append(pad, 4);
    bytes.append(reinterpret_cast<const char*>(&z), 8);
    bytes.append(reinterpret_cast<const char*>(&x), 4);
    bytes.append(reinterpret_cast<const char*>(&y), 2);
  }
  write_bytes(path, bytes);
  const PointCloud cloud = read_point_cloud(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[0], Vec3(-1.25, -300, 0.5));
  EXPECT_EQ(cloud.points[1], Vec3(-2.5, -299, 1.5));
}

TEST(RoundTrip, EveryPointFormatDoublePrecision) {
  TempDir dir;
  const std::vector<Vec3> points = random_points(5000, 7);
  struct Case {
    std::string name;
    PcdEncoding encoding;
  };
  for (const Case& c : {Case{"a.pcd", PcdEncoding::binary}, Case{"b.pcd", PcdEncoding::ascii},
                        Case{"c.pcd", PcdEncoding::binary_compressed}, Case{"d.PLY", {}},
                        Case{"e.xyz", {}}, Case{"f.txt", {}}, Case{"g.csv", {}}}) {
    const std::string path = dir.file(c.name);
    write_point_cloud(path, points, {c.encoding, /*double_precision=*/true});
    const PointCloud back = read_point_cloud(path);
    ASSERT_EQ(back.size(), points.size()) << c.name;
    EXPECT_EQ(back.total, points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_EQ(back.points[i], points[i]) << c.name << " point " << i;
      ASSERT_EQ(back.source_index[i], i);
    }
  }
  EXPECT_EQ(dir.entries(), 7u);  // no temporaries left behind
}

TEST(RoundTrip, EmptyClouds) {
  TempDir dir;
  for (const std::string name : {"a.pcd", "b.ply", "c.xyz", "d.csv"}) {
    for (const PcdEncoding encoding :
         {PcdEncoding::binary, PcdEncoding::ascii, PcdEncoding::binary_compressed}) {
      write_point_cloud(dir.file(name), std::vector<Vec3>{}, {encoding, false});
      const PointCloud back = read_point_cloud(dir.file(name));
      EXPECT_EQ(back.total, 0u) << name;
      EXPECT_TRUE(back.points.empty()) << name;
    }
  }
}

TEST(RoundTrip, SinglePrecisionGivesTheFloatValues) {
  TempDir dir;
  std::vector<Vec3> points = random_points(3000, 8);
  points[1] = Vec3(1e30, 1e-30, -3.0);  // representable range of float
  for (const std::string name : {"a.pcd", "b.ply", "c.xyz"}) {
    write_point_cloud(dir.file(name), points);  // float32 by default
    const PointCloud back = read_point_cloud(dir.file(name));
    ASSERT_EQ(back.size(), points.size());
    // Text carries no type: the shortest float form reads back as the nearest double, which
    // rounds to the same float.
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (name == "c.xyz") {
        ASSERT_EQ(back.points[i].cast<float>(), points[i].cast<float>()) << name << " " << i;
      } else {
        ASSERT_EQ(back.points[i], points[i].cast<float>().cast<double>()) << name << " " << i;
      }
    }
  }
  // Our binary_compressed and binary files, decoded by the independent reference decoder.
  for (const PcdEncoding encoding : {PcdEncoding::binary_compressed, PcdEncoding::binary}) {
    write_point_cloud(dir.file("r.pcd"), points, {encoding, false});
    expect_matches(read_point_cloud(dir.file("r.pcd")), ref_pcd_points(dir.file("r.pcd")));
  }
  // The default PCD is binary with F4 fields (what PCL's PointXYZ expects).
  const std::string header = read_bytes(dir.file("a.pcd")).substr(0, 200);
  EXPECT_NE(header.find("SIZE 4 4 4\nTYPE F F F"), std::string::npos) << header;
  EXPECT_NE(header.find("DATA binary\n"), std::string::npos) << header;
}

TEST(RoundTrip, NonFinitePointsAreSkippedWithTheirIndex) {
  TempDir dir;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<Vec3> points{{1, 2, 3},   {nan, 0, 0}, {4, 5, 6},      {0, -inf, 0},
                                 {0, 0, inf}, {7, 8, 9},   {nan, nan, nan}};
  for (const std::string name : {"a.pcd", "b.ply", "c.xyz"}) {
    write_point_cloud(dir.file(name), points);
    const PointCloud back = read_point_cloud(dir.file(name));
    EXPECT_EQ(back.total, 7u) << name;
    EXPECT_EQ(back.skipped_nonfinite, 4u) << name;
    ASSERT_EQ(back.size(), 3u) << name;
    EXPECT_EQ(back.source_index, (std::vector<std::uint64_t>{0, 2, 5})) << name;
    EXPECT_EQ(back.points[2], Vec3(7, 8, 9)) << name;
  }
}

// A table with every column type and awkward values.
PointTable sample_table(std::size_t rows) {
  PointTable table;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  auto& x = table.add_column<double>("x");
  auto& y = table.add_column<float>("y");
  auto& z = table.add_column<double>("z");
  auto& index = table.add_column<std::uint64_t>("index");
  auto& entity = table.add_column<std::int32_t>("entity");
  auto& flags = table.add_column<std::uint32_t>("flags");
  auto& offset = table.add_column<std::int64_t>("offset");
  for (std::size_t i = 0; i < rows; ++i) {
    x.push_back(u(rng) * 1e3);
    y.push_back(static_cast<float>(u(rng)));
    z.push_back(std::ldexp(u(rng), static_cast<int>(i % 200) - 100));
    index.push_back(std::numeric_limits<std::uint64_t>::max() - i);
    entity.push_back(std::numeric_limits<std::int32_t>::min() + static_cast<std::int32_t>(i));
    flags.push_back(std::numeric_limits<std::uint32_t>::max() - static_cast<std::uint32_t>(i));
    offset.push_back(-static_cast<std::int64_t>(i) * 1000000000007LL);
  }
  x[0] = 0.1;
  z[0] = -0.0;
  y[1] = std::numeric_limits<float>::denorm_min();
  return table;
}

TEST(PointTableIo, PcdRoundTripKeepsTypesAndValues) {
  TempDir dir;
  const PointTable table = sample_table(1000);
  for (const PcdEncoding encoding :
       {PcdEncoding::binary, PcdEncoding::ascii, PcdEncoding::binary_compressed}) {
    const std::string path = dir.file("t" + std::to_string(static_cast<int>(encoding)) + ".pcd");
    write_pcd(path, table, encoding);
    const PointTable back = read_point_table(path);
    ASSERT_EQ(back.columns().size(), table.columns().size());
    EXPECT_EQ(*back.values<double>("x"), *table.values<double>("x"));
    EXPECT_EQ(*back.values<float>("y"), *table.values<float>("y"));
    EXPECT_EQ(*back.values<std::int32_t>("entity"), *table.values<std::int32_t>("entity"));
    EXPECT_EQ(*back.values<std::uint32_t>("flags"), *table.values<std::uint32_t>("flags"));
    EXPECT_TRUE(std::signbit((*back.values<double>("z"))[0]));
    if (encoding != PcdEncoding::ascii) {  // ascii goes through double: 64-bit ints are rounded
      EXPECT_EQ(*back.values<double>("z"), *table.values<double>("z"));
      EXPECT_EQ(*back.values<std::uint64_t>("index"), *table.values<std::uint64_t>("index"));
      EXPECT_EQ(*back.values<std::int64_t>("offset"), *table.values<std::int64_t>("offset"));
    } else {
      EXPECT_EQ(*back.values<double>("z"), *table.values<double>("z"));
    }
    // The same file read as a point cloud gives x, y, z.
    const PointCloud cloud = read_point_cloud(path);
    ASSERT_EQ(cloud.size(), 1000u);
    EXPECT_EQ(cloud.points[5], Vec3((*table.values<double>("x"))[5], (*table.values<float>("y"))[5],
                                    (*table.values<double>("z"))[5]));
  }
  const std::string header = read_bytes(dir.file("t0.pcd")).substr(0, 300);
  EXPECT_NE(header.find("FIELDS x y z index entity flags offset\nSIZE 8 4 8 8 4 4 8\n"
                        "TYPE F F F U I U I\nCOUNT 1 1 1 1 1 1 1\nWIDTH 1000\nHEIGHT 1\n"),
            std::string::npos)
      << header;
}

TEST(PointTableIo, CsvRoundTripIsExact) {
  TempDir dir;
  const PointTable table = sample_table(2000);
  const std::string path = dir.file("r.csv");
  write_csv(path, table);
  const std::string text = read_bytes(path);
  EXPECT_EQ(text.substr(0, text.find('\n')), "x,y,z,index,entity,flags,offset");
  // Second line, formatted independently: shortest forms of the first row.
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);
  std::getline(lines, line);
  EXPECT_EQ(line.substr(0, 4), "0.1,");
  EXPECT_NE(line.find(",-0,18446744073709551615,-2147483648,4294967295,0"), std::string::npos)
      << line;
  const PointTable back = read_point_table(path);
  ASSERT_EQ(back.rows(), 2000u);
  for (const Column& column : table.columns()) {
    const std::vector<double>* values = back.values<double>(column.name);
    ASSERT_NE(values, nullptr) << column.name;
    std::visit(
        [&](const auto& original) {
          using T = typename std::decay_t<decltype(original)>::value_type;
          for (std::size_t i = 0; i < original.size(); ++i) {
            // CSV is typeless: a float column reads back as the double nearest its shortest
            // form, which rounds back to the identical float.
            if constexpr (std::is_same_v<T, float>) {
              ASSERT_EQ(static_cast<float>((*values)[i]), original[i]) << column.name << " " << i;
            } else {
              ASSERT_EQ((*values)[i], static_cast<double>(original[i])) << column.name << " " << i;
            }
          }
        },
        column.values);
  }
  // A projection-results CSV is also a point cloud (x, y, z picked by name from the header).
  const PointCloud cloud = read_point_cloud(path);
  ASSERT_EQ(cloud.size(), 2000u);
  EXPECT_EQ(cloud.points[7].x(), (*table.values<double>("x"))[7]);
}

TEST(PointTableIo, IntegerAndDoubleCoordinatesReadAsPoints) {
  TempDir dir;
  PointTable table;
  table.add_column<std::int32_t>("x", {-7, 2147483647, 0});
  table.add_column<std::uint32_t>("y", {4294967295u, 1, 2});
  table.add_column<double>("z", {0.1, -1e-310, 3});
  table.add_column<float>("intensity", {1, 2, 3});
  for (const PcdEncoding encoding :
       {PcdEncoding::binary, PcdEncoding::ascii, PcdEncoding::binary_compressed}) {
    const std::string path = dir.file("i.pcd");
    write_pcd(path, table, encoding);
    const PointCloud cloud = read_point_cloud(path);
    ASSERT_EQ(cloud.size(), 3u);
    EXPECT_EQ(cloud.points[0], Vec3(-7, 4294967295.0, 0.1));
    EXPECT_EQ(cloud.points[1], Vec3(2147483647, 1, -1e-310));
  }
  // Text with a byte-order mark and a header naming the columns in another order.
  const std::string csv = dir.file("bom.csv");
  write_bytes(csv, "\xEF\xBB\xBFZ, Y, X, w\n3,2,1,0\n6,5,4,0\n");
  const PointCloud cloud = read_point_cloud(csv);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[1], Vec3(4, 5, 6));
}

TEST(PointTableIo, InvalidTablesAreRejected) {
  PointTable uneven;
  uneven.add_column<double>("x", {1, 2});
  uneven.add_column<double>("y", {1});
  ASSERT_TRUE(uneven.validate());
  EXPECT_NE(uneven.validate()->find("'y'"), std::string::npos);
  PointTable spaced;
  spaced.add_column<double>("foot x", {1});
  EXPECT_TRUE(spaced.validate());
  PointTable twice;
  twice.add_column<double>("x", {1});
  twice.add_column<float>("x", {1});
  EXPECT_TRUE(twice.validate());
  TempDir dir;
  EXPECT_THROW(write_csv(dir.file("u.csv"), uneven), std::invalid_argument);
  PointTable no_xyz;
  no_xyz.add_column<double>("distance", {1});
  EXPECT_THROW(write_pcd(dir.file("u.pcd"), no_xyz), std::invalid_argument);
  EXPECT_EQ(dir.entries(), 0u);
}

// ---- hand-made binary PLY ----------------------------------------------------------------

class ByteWriter {
 public:
  explicit ByteWriter(bool big_endian) : big_(big_endian) {}
  template <class T>
  void put(T value) {
    std::array<char, sizeof(T)> bytes = std::bit_cast<std::array<char, sizeof(T)>>(value);
    if (big_ != (std::endian::native == std::endian::big)) std::reverse(bytes.begin(), bytes.end());
    out_.append(bytes.data(), bytes.size());
  }
  std::string& str() { return out_; }

 private:
  bool big_;
  std::string out_;
};

// A camera element with a list comes first; the vertex element mixes types, aliases and a list;
// a face element follows.
std::string odd_ply(bool big_endian, const std::vector<std::array<double, 3>>& xyz) {
  ByteWriter w(big_endian);
  w.str() = std::string("ply\r\nformat ") +
            (big_endian ? "binary_big_endian" : "binary_little_endian") +
            " 1.0\r\ncomment odd types\r\nobj_info scanner 1\r\nelement camera 2\r\n"
            "property list uint8 float32 params\r\nproperty int16 id\r\n"
            "element vertex " +
            std::to_string(xyz.size()) +
            "\r\nproperty uchar red\r\n"
            "property short x\r\nproperty list ushort int tags\r\nproperty double y\r\n"
            "property int8 flag\r\nproperty float z\r\nproperty uint quality\r\n"
            "element face 1\r\nproperty list uchar uint vertex_indices\r\nend_header\r\n";
  for (int c = 0; c < 2; ++c) {
    w.put<std::uint8_t>(3);
    for (int k = 0; k < 3; ++k)
      w.put<float>(static_cast<float>(k));
    w.put<std::int16_t>(static_cast<std::int16_t>(-c));
  }
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    w.put<std::uint8_t>(200);
    w.put<std::int16_t>(static_cast<std::int16_t>(xyz[i][0]));
    w.put<std::uint16_t>(static_cast<std::uint16_t>(i % 3));
    for (std::size_t k = 0; k < i % 3; ++k)
      w.put<std::int32_t>(-1);
    w.put<double>(xyz[i][1]);
    w.put<std::int8_t>(-5);
    w.put<float>(static_cast<float>(xyz[i][2]));
    w.put<std::uint32_t>(0xdeadbeef);
  }
  w.put<std::uint8_t>(3);
  for (std::uint32_t k = 0; k < 3; ++k)
    w.put<std::uint32_t>(k);
  return w.str();
}

TEST(BinaryPly, BothByteOrdersWithOddPropertyTypes) {
  TempDir dir;
  const std::vector<std::array<double, 3>> xyz{
      {-32768, 0.1, 0.25}, {32767, -1e200, -3.5}, {7, std::nan(""), 1}, {-1, 2.5, 1e-3}};
  for (const bool big : {false, true}) {
    const std::string path = dir.file(big ? "be.ply" : "le.ply");
    write_bytes(path, odd_ply(big, xyz));
    const PointCloud cloud = read_point_cloud(path);
    EXPECT_EQ(cloud.total, 4u);
    EXPECT_EQ(cloud.skipped_nonfinite, 1u);
    ASSERT_EQ(cloud.size(), 3u);
    EXPECT_EQ(cloud.source_index, (std::vector<std::uint64_t>{0, 1, 3}));
    EXPECT_EQ(cloud.points[0], Vec3(-32768, 0.1, 0.25));
    EXPECT_EQ(cloud.points[1], Vec3(32767, -1e200, -3.5));
    EXPECT_EQ(cloud.points[2], Vec3(-1, 2.5, static_cast<double>(1e-3f)));
    // Truncating anywhere inside the vertex block is an error, not a crash.
    const std::string bytes = read_bytes(path);
    for (const std::size_t cut : {bytes.size() - 13 - 8, bytes.size() - 13 - 30}) {
      const std::string truncated = dir.file(big ? "be_cut.ply" : "le_cut.ply");
      write_bytes(truncated, bytes.substr(0, cut));
      expect_cloud_error(truncated, {"element 'vertex'", "truncated"});
    }
  }
}

TEST(AsciiPly, ListsAndElementsBeforeVertex) {
  TempDir dir;
  const std::string path = dir.file("a.ply");
  write_bytes(path,
              "ply\nformat ascii 1.0\nelement material 2\nproperty list uchar float rgb\n"
              "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
              "property list uchar int extra\nend_header\n3 1 0 0\n0\n"
              "1 2 3 0\n4 5 nan 2 7 8\n7e1 8 -9 1 5\n");
  const PointCloud cloud = read_point_cloud(path);
  EXPECT_EQ(cloud.total, 3u);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[1], Vec3(70, 8, -9));
  EXPECT_EQ(cloud.source_index[1], 2u);
}

// ---- malformed input ---------------------------------------------------------------------

TEST(MalformedInput, Xyz) {
  TempDir dir;
  const std::string ok = dir.file("ok.xyz");
  write_bytes(ok,
              "# comment\n\n1 2 3\n4,5,6 extra columns\n  7 ,8, 9 # trailing\n"
              "nan 0 0\n1 inf 1\n-INF 1 1\n+1 -2 3e-2\r\n");
  const PointCloud cloud = read_point_cloud(ok);
  EXPECT_EQ(cloud.total, 7u);
  EXPECT_EQ(cloud.skipped_nonfinite, 3u);
  EXPECT_EQ(cloud.source_index, (std::vector<std::uint64_t>{0, 1, 2, 6}));
  EXPECT_EQ(cloud.points[1], Vec3(4, 5, 6));
  EXPECT_EQ(cloud.points[3], Vec3(1, -2, 0.03));

  const std::string bad = dir.file("scan.xyz");
  write_bytes(bad, "1 2 3\n# c\n4 5 6\n4 five 6\n");
  expect_cloud_error(bad, {"line 4", "not a number", "'five'"});
  write_bytes(bad, "1 2 3\n1 2\n");
  expect_cloud_error(bad, {"line 2", "expected 3 numbers"});
  write_bytes(bad, "1,,3\n");
  expect_cloud_error(bad, {"line 1", "not a number"});
  write_bytes(bad, "a b c\n");
  expect_cloud_error(bad, {"line 1", "header naming columns x, y, z"});
}

TEST(MalformedInput, FilesAndExtensions) {
  TempDir dir;
  expect_cloud_error(dir.file("missing.pcd"), {"cannot open"});
  const std::string other = dir.file("scan.obj");
  write_bytes(other, "v 1 2 3\n");
  expect_cloud_error(other, {"unsupported", ".pcd, .ply, .xyz, .txt, .csv"});
  const std::string upper = dir.file("UP.XYZ");
  write_bytes(upper, "1 2 3\n");
  EXPECT_EQ(read_point_cloud(upper).size(), 1u);
}

TEST(MalformedInput, Pcd) {
  TempDir dir;
  const std::vector<Vec3> points = random_points(1000, 3);
  const std::string binary = dir.file("b.pcd");
  const std::string compressed = dir.file("c.pcd");
  write_point_cloud(binary, points, {PcdEncoding::binary, false});
  write_point_cloud(compressed, points, {PcdEncoding::binary_compressed, false});
  const std::string bin_bytes = read_bytes(binary);
  const std::string cmp_bytes = read_bytes(compressed);
  const std::size_t cmp_data = cmp_bytes.find("DATA binary_compressed\n") + 23;
  const std::string bad = dir.file("bad.pcd");

  write_bytes(bad, bin_bytes.substr(0, bin_bytes.size() - 5));
  expect_cloud_error(bad, {"truncated", "12000 bytes"});
  // Every truncation of the compressed file, and sizes that disagree with the header.
  for (std::size_t cut = cmp_data; cut < cmp_bytes.size(); cut += 97) {
    write_bytes(bad, cmp_bytes.substr(0, cut));
    expect_cloud_error(bad, {});
  }
  auto with_sizes = [&](std::uint32_t compressed_size, std::uint32_t uncompressed_size) {
    std::string bytes = cmp_bytes;
    std::memcpy(bytes.data() + cmp_data, &compressed_size, 4);
    std::memcpy(bytes.data() + cmp_data + 4, &uncompressed_size, 4);
    return bytes;
  };
  std::uint32_t sizes[2];
  std::memcpy(sizes, cmp_bytes.data() + cmp_data, 8);
  write_bytes(bad, with_sizes(0xffffff00u, sizes[1]));
  expect_cloud_error(bad, {"compressed size"});
  write_bytes(bad, with_sizes(sizes[0], sizes[1] + 4));
  expect_cloud_error(bad, {"uncompressed size"});
  write_bytes(bad, with_sizes(sizes[0] - 20, sizes[1]));  // stream cut short: LZF fails
  expect_cloud_error(bad, {"LZF"});
  // Header lies: a huge POINTS must be refused before anything is allocated.
  std::string huge = bin_bytes;
  huge.replace(huge.find("WIDTH 1000"), 10, "WIDTH 999999999999");
  huge.replace(huge.find("POINTS 1000"), 11, "POINTS 999999999999");
  write_bytes(bad, huge);
  expect_cloud_error(bad, {"WIDTH"});
  huge.replace(huge.find("WIDTH 999999999999"), 18, "WIDTH 4000000000");
  huge.replace(huge.find("POINTS 999999999999"), 19, "POINTS 4000000000");
  write_bytes(bad, huge);
  expect_cloud_error(bad, {"truncated"});

  const std::string ascii_header =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n";
  write_bytes(bad, ascii_header + "1 2 3\n4 5 6\n7 8 x\n");
  expect_cloud_error(bad, {"line 13", "not a number", "'x'"});
  write_bytes(bad, ascii_header + "1 2 3\n4 5\n7 8 9\n");
  expect_cloud_error(bad, {"line 12", "expected 3 numbers"});
  write_bytes(bad, ascii_header + "1 2 3\n4 5 6\n");
  expect_cloud_error(bad, {"truncated", "3 points", "has 2"});
  std::string no_z = ascii_header;
  no_z.replace(no_z.find("FIELDS x y z"), 12, "FIELDS x y w");
  write_bytes(bad, no_z + "1 2 3\n4 5 6\n7 8 9\n");
  expect_cloud_error(bad, {"no field 'z'"});
  std::string mismatch = ascii_header;
  mismatch.replace(mismatch.find("TYPE F F F"), 10, "TYPE F F");
  write_bytes(bad, mismatch + "1 2 3\n");
  expect_cloud_error(bad, {"FIELDS, SIZE, TYPE and COUNT"});
  write_bytes(bad, "FIELDS x y z\nSIZE 4 4 4\n");
  expect_cloud_error(bad, {"no DATA line"});
  write_bytes(bad, "");
  expect_cloud_error(bad, {"no DATA line"});
  // Missing z in a binary file (PCL decodes it, we must still refuse it).
  std::string binary_no_z = bin_bytes;
  binary_no_z.replace(binary_no_z.find("FIELDS x y z"), 12, "FIELDS x y q");
  write_bytes(bad, binary_no_z);
  expect_cloud_error(bad, {"no field 'z'"});
}

TEST(MalformedInput, Ply) {
  TempDir dir;
  const std::string bad = dir.file("bad.ply");
  write_bytes(bad,
              "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int v\nend_header\n"
              "3 0 1 2\n");
  expect_cloud_error(bad, {"no 'vertex' element"});
  write_bytes(bad,
              "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n1 2 3\n4 5 6\n7 8\n");
  expect_cloud_error(bad, {"element 'vertex' 2 of 3", "truncated"});
  write_bytes(bad,
              "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n1 2 3\n4 5 six\n");
  expect_cloud_error(bad, {"line 9", "'six'"});
  write_bytes(bad,
              "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
              "end_header\n1 2\n");
  expect_cloud_error(bad, {"no property 'z'"});
  write_bytes(bad, "ply\nformat binary_middle_endian 1.0\nend_header\n");
  expect_cloud_error(bad, {"line 2", "unknown format"});
  write_bytes(bad, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
  expect_cloud_error(bad, {"no end_header"});
  write_bytes(bad, "solid cube\n");
  expect_cloud_error(bad, {"not a PLY file"});
  write_bytes(bad,
              "ply\nformat binary_little_endian 1.0\nelement vertex 99999999999999\n"
              "property double x\nproperty double y\nproperty double z\nend_header\nabc");
  expect_cloud_error(bad, {"truncated"});
  // The real scan cut in the middle of its vertices.
  const std::string bunny = read_bytes(kBunny + "bun000.ply");
  write_bytes(bad, bunny.substr(0, bunny.size() / 2));
  expect_cloud_error(bad, {"element 'vertex'", "truncated"});
}

TEST(MalformedInput, CsvTable) {
  TempDir dir;
  const std::string bad = dir.file("r.csv");
  write_bytes(bad, "index,x,y\n0,1,2\n1,2\n");
  expect_input_error(bad, {"line 3", "expected 3 values"}, [&] { read_point_table(bad); });
  write_bytes(bad, "index,x,y\n0,1,zz\n");
  expect_input_error(bad, {"line 2", "column 'y'"}, [&] { read_point_table(bad); });
  write_bytes(bad, "index,x,y\n0,1,2\n");
  expect_cloud_error(bad, {"line 1", "header naming columns x, y, z"});
}

// Random byte corruption of valid files of every format: each read either succeeds or throws
// InputError (never crashes, hangs or throws anything else). Deterministic seeds.
TEST(MalformedInput, CorruptedBytesNeverCrash) {
  TempDir dir;
  const std::vector<Vec3> points = random_points(300, 5);
  std::vector<std::string> sources;
  for (const std::string name : {"a.pcd", "b.pcd", "c.pcd", "d.ply", "e.xyz"}) {
    const PcdEncoding encoding = name == "b.pcd"   ? PcdEncoding::ascii
                                 : name == "c.pcd" ? PcdEncoding::binary_compressed
                                                   : PcdEncoding::binary;
    write_point_cloud(dir.file(name), points, {encoding, false});
    sources.push_back(dir.file(name));
  }
  const std::string odd = dir.file("odd.ply");
  write_bytes(odd, odd_ply(true, {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}}));
  sources.push_back(odd);
  std::mt19937_64 rng(99);
  std::size_t failures = 0, successes = 0;
  for (const std::string& source : sources) {
    const std::string original = read_bytes(source);
    const std::string corrupt = dir.file("corrupt" + fs::path(source).extension().string());
    for (int trial = 0; trial < 100; ++trial) {
      std::string bytes = original;
      // Mostly the header and the first bytes of data, where sizes and counts live.
      const std::size_t span =
          trial % 2 == 0 ? std::min<std::size_t>(bytes.size(), 400) : bytes.size();
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) {
        bytes[rng() % span] = static_cast<char>(rng() % 256);
      }
      if (trial % 5 == 0) bytes.resize(rng() % bytes.size());
      write_bytes(corrupt, bytes);
      try {
        const PointCloud cloud = read_point_cloud(corrupt);
        EXPECT_EQ(cloud.size() + cloud.skipped_nonfinite, cloud.total);
        ++successes;
      } catch (const InputError& e) {
        // The CLI prints the message as one line: no control or non-ASCII bytes from the file.
        const std::string what = e.what();
        EXPECT_TRUE(std::all_of(what.begin(), what.end(), [](char c) {
          return c >= 0x20 && c < 0x7f;
        })) << what;
        ++failures;
      } catch (const std::exception& e) {
        ADD_FAILURE() << source << " trial " << trial << ": " << e.what();
      }
    }
  }
  EXPECT_GT(failures, 60u);   // the corruption really was seen
  EXPECT_GT(successes, 10u);  // and flipped data bytes still read
}

// ---- atomic writes -----------------------------------------------------------------------

TEST(AtomicWrites, MissingDirectoryGivesOutputErrorAndNoFile) {
  TempDir dir;
  const std::string path = dir.file("no/such/dir/out.pcd");
  EXPECT_THROW(write_point_cloud(path, random_points(10, 1)), OutputError);
  EXPECT_THROW(write_csv(dir.file("no/r.csv"), sample_table(3)), OutputError);
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(dir.entries(), 0u);
}

TEST(AtomicWrites, InterruptedWriteLeavesNoFile) {
  TempDir dir;
  const std::string path = dir.file("out.csv");
  EXPECT_THROW(write_atomically(path,
                                [](std::ostream& out) {
                                  out << std::string(1 << 20, 'x');  // some data already written
                                  throw std::runtime_error("interrupted");
                                }),
               std::runtime_error);
  EXPECT_EQ(dir.entries(), 0u);
  // An existing file is not touched by a failed rewrite.
  write_point_cloud(path, random_points(4, 2));
  const std::string before = read_bytes(path);
  EXPECT_THROW(write_atomically(path, [](std::ostream&) { throw std::runtime_error("x"); }),
               std::runtime_error);
  EXPECT_EQ(read_bytes(path), before);
  EXPECT_EQ(dir.entries(), 1u);
}

TEST(WritePointCloud, UnsupportedExtension) {
  TempDir dir;
  EXPECT_THROW(write_point_cloud(dir.file("a.obj"), random_points(3, 1)), OutputError);
  EXPECT_THROW(write_point_table(dir.file("a.json"), sample_table(3)), OutputError);
}

}  // namespace
}  // namespace nurbsreg::io
