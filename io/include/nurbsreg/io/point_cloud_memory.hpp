#pragma once
// Point clouds from bytes already in memory (a request body of `nurbsreg serve`), decoded by the
// same readers as the files of read_point_cloud (point_cloud.hpp), so a body and a file with the
// same bytes give the same cloud, bit for bit.
//
// Encodings: PCD (ascii, binary, binary_compressed), PLY (ascii and binary), and raw
// little-endian float32 x y z triples (12 bytes a point, no header) for clients that have the
// points in a buffer already. Non-finite points are skipped and counted as for files.
// Errors: io::InputError whose message starts with `label` (what the caller calls the bytes,
// e.g. "request body"). Thread-safe; allocates the cloud (and, for PCD, one decoded copy).

#include <optional>
#include <string>
#include <string_view>

#include "nurbsreg/io/point_cloud.hpp"

namespace nurbsreg::io {

enum class CloudEncoding { pcd, ply, float32_xyz };

// PLY when the bytes start with the PLY magic line ("ply" and a line end), else PCD: the two
// formats the service takes under one content type.
CloudEncoding sniff_cloud_encoding(std::string_view bytes);

PointCloud parse_point_cloud(const std::string& bytes, CloudEncoding encoding,
                             const std::string& label);

}  // namespace nurbsreg::io
