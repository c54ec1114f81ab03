#pragma once
// Point-cloud files (CONTRACT §2 "Point clouds").
//
// read_point_cloud accepts, chosen by the extension (case-insensitive):
//  - .pcd  ascii, binary and binary_compressed (LZF); fields x y z of any type and position
//          (F4/F8/I/U of any size), other fields ignored. Organised clouds keep width/height.
//  - .ply  ascii, binary_little_endian, binary_big_endian; element `vertex` with x y z of any
//          scalar type; other properties (including lists) and other elements are skipped.
//  - .xyz, .txt, .csv  text, x y z separated by whitespace and/or commas, extra columns ignored,
//          `#` starts a comment, blank lines ignored. A first line that names the columns
//          (e.g. `x,y,z` or `index,x,y,z,...`) is taken as a header and x, y, z are picked by
//          name. `nan`/`inf` are non-finite values.
// Points with a NaN or infinite coordinate are skipped and counted; every kept point remembers
// its 0-based position in the file, so results can report the input index.
//
// Errors: io::InputError whose message names the file and the problem, with the line number
// (text formats) or the field/element (binary formats): `scan.xyz: line 12: expected 3 numbers`.
// Thread safety: reads of different files may run concurrently. PCL's console verbosity (a PCL
// global) is lowered while PCL decodes a binary PCD body, under a lock, and restored after.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/types.hpp"
#include "nurbsreg/io/point_table.hpp"

namespace nurbsreg::io {

struct PointCloud {
  std::vector<engine::Vec3> points;         // finite points, in file order
  std::vector<std::uint64_t> source_index;  // source_index[i]: 0-based index in the file
  std::size_t skipped_nonfinite = 0;        // points dropped for a NaN/inf coordinate
  std::size_t total = 0;                    // points in the file = size() + skipped_nonfinite
  // Grid of an organised scan (PCD HEIGHT > 1): point k of the file is pixel
  // (k % width, k / width). Unorganised files have width = total, height = 1.
  std::uint32_t width = 0;
  std::uint32_t height = 0;

  std::size_t size() const { return points.size(); }
};

// A cloud of more points than resource_limits().max_points is an error; an empty cloud is not
// (a file may be empty), and any finite coordinate is read as it is (faithful file I/O).
PointCloud read_point_cloud(const std::string& path);

// read_point_cloud for a scan to be projected, aligned or used as targets: a cloud without a
// single finite point, and a coordinate beyond kMaxCoordinate (input_ranges.hpp: what the
// exact projection can represent), are bad input here (InputError "the scan has no points" /
// "no finite points" / "point 7: x = ... is beyond the supported range"), so that every command
// treats such scans alike.
PointCloud read_scan(const std::string& path);

struct PointCloudWriteOptions {
  PcdEncoding pcd_encoding = PcdEncoding::binary;
  // float64 coordinates (exact round trip) instead of float32 (what PCL's PointXYZ and most
  // viewers expect). PLY follows the same choice (double/float); text always prints the shortest
  // exact form of the double.
  bool double_precision = false;
};

// Writes points by extension: .pcd (PCD, binary by default), .ply (binary_little_endian vertex
// x y z), .xyz/.txt (`x y z` lines), .csv (header `x,y,z`). Atomic (see atomic_file.hpp); throws
// OutputError on failure or for an unsupported extension.
void write_point_cloud(const std::string& path, std::span<const engine::Vec3> points,
                       const PointCloudWriteOptions& options = {});
inline void write_point_cloud(const std::string& path, const PointCloud& cloud,
                              const PointCloudWriteOptions& options = {}) {
  write_point_cloud(path, std::span<const engine::Vec3>(cloud.points), options);
}

}  // namespace nurbsreg::io
