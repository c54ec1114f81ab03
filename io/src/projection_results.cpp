#include "nurbsreg/io/projection_results.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>

#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "point_cloud_detail.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

constexpr std::size_t kContractColumns = std::size(kProjectionColumnNames);
// Bytes buffered before each write: large enough that the stream call costs nothing per row,
// small enough that memory does not grow with the row count.
constexpr std::size_t kFlushBytes = std::size_t{1} << 20;

bool is_contract_name(std::string_view name) {
  return std::find(std::begin(kProjectionColumnNames), std::end(kProjectionColumnNames), name) !=
         std::end(kProjectionColumnNames);
}

void require_valid(const std::string& path, const ProjectionColumns& c) {
  if (auto error = c.validate()) throw OutputError(path, *error);
}

std::uint64_t row_index(const ProjectionColumns& c, std::size_t row) {
  return c.index.empty() ? row : c.index[row];
}

// Writes `rows` rows through `append_row(buffer, row)`, flushing the buffer every kFlushBytes.
template <typename AppendRow>
void stream_rows(std::ostream& out, std::string& buffer, std::size_t rows, AppendRow&& append_row) {
  for (std::size_t r = 0; r < rows; ++r) {
    append_row(buffer, r);
    if (buffer.size() >= kFlushBytes) {
      out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      buffer.clear();
    }
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  buffer.clear();
}

// CSV text costs ~0.5 us per row to format (std::to_chars), as much as projecting the point,
// so rows are formatted in blocks on TBB workers and the blocks written in order. The bytes do
// not depend on the thread count (STYLE.md 9) and memory stays bounded by one batch of blocks
// (~30 MB); the thread count is whatever the application's tbb::global_control allows.
constexpr std::size_t kRowsPerBlock = 8192;
constexpr std::size_t kBlocksPerBatch = 32;

template <typename AppendRow>
void stream_rows_parallel(std::ostream& out, std::size_t rows, const AppendRow& append_row) {
  std::vector<std::string> blocks(kBlocksPerBatch);
  for (std::size_t first = 0; first < rows; first += kRowsPerBlock * kBlocksPerBatch) {
    const std::size_t batch_rows = std::min(rows - first, kRowsPerBlock * kBlocksPerBatch);
    const std::size_t block_count = (batch_rows + kRowsPerBlock - 1) / kRowsPerBlock;
    tbb::parallel_for(std::size_t{0}, block_count, [&](std::size_t b) {
      std::string& block = blocks[b];
      block.clear();
      const std::size_t lo = first + b * kRowsPerBlock;
      const std::size_t hi = std::min(first + batch_rows, lo + kRowsPerBlock);
      for (std::size_t r = lo; r < hi; ++r)
        append_row(block, r);
    });
    nurbsreg::engine::stop_if_cancelled();
    for (std::size_t b = 0; b < block_count; ++b) {
      out.write(blocks[b].data(), static_cast<std::streamsize>(blocks[b].size()));
    }
  }
}

template <typename T>
void append_binary(std::string& buffer, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  buffer.append(bytes, sizeof(T));
}

using text_detail::lower_extension;
using text_detail::split_csv;

// Where each contract column sits in a file, and the extra columns, found by name.
struct ColumnMap {
  std::size_t contract[kContractColumns];
  std::vector<std::size_t> extra;
};

ColumnMap map_columns(const std::string& path, const std::string& where,
                      const std::vector<std::string>& names, ProjectionTable& table) {
  ColumnMap map;
  std::map<std::string, std::size_t, std::less<>> position;
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (!position.emplace(names[k], k).second) {
      throw InputError(path, where + ": column \"" + names[k] + "\" appears twice");
    }
  }
  for (std::size_t k = 0; k < kContractColumns; ++k) {
    const auto it = position.find(kProjectionColumnNames[k]);
    if (it == position.end()) {
      throw InputError(path, where + ": required column \"" +
                                 std::string(kProjectionColumnNames[k]) + "\" is missing");
    }
    map.contract[k] = it->second;
  }
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (!is_contract_name(names[k])) {
      map.extra.push_back(k);
      table.extra_names.push_back(names[k]);
    }
  }
  table.extra_values.resize(map.extra.size());
  return map;
}

// Appends one row, given column k's value as a double through `value(k)`; `where` names the
// row for messages. Integer columns must hold exact non-negative (index) or any (entity)
// integers.
template <typename Value>
void append_row(const std::string& path, const ColumnMap& map, Value&& value,
                const std::function<std::string()>& where, ProjectionTable& t) {
  const auto at = [&](std::size_t k) { return value(map.contract[k]); };
  const double index = at(0);
  if (!(index >= 0.0 && index == std::floor(index) && index < 0x1p63)) {
    throw InputError(path, where() + ": index must be a non-negative integer");
  }
  const double entity = at(8);
  if (!(entity == std::floor(entity) && std::abs(entity) < 0x1p31)) {
    throw InputError(path, where() + ": entity must be an integer");
  }
  t.index.push_back(static_cast<std::uint64_t>(index));
  t.point.emplace_back(at(1), at(2), at(3));
  t.foot.emplace_back(at(4), at(5), at(6));
  t.distance.push_back(at(7));
  t.entity.push_back(static_cast<std::int32_t>(entity));
  t.u.push_back(at(9));
  t.v.push_back(at(10));
  for (std::size_t e = 0; e < map.extra.size(); ++e)
    t.extra_values[e].push_back(value(map.extra[e]));
}

}  // namespace

std::optional<std::string> ProjectionColumns::validate() const {
  const std::size_t n = rows();
  const auto check = [n](const char* name, std::size_t size) -> std::optional<std::string> {
    if (size == n) return std::nullopt;
    return std::string("column ") + name + ": has " + std::to_string(size) + " values, expected " +
           std::to_string(n) + " (one per row, like x y z)";
  };
  if (!index.empty()) {
    if (auto e = check("index", index.size())) return e;
  }
  if (auto e = check("foot", foot.size())) return e;
  if (auto e = check("distance", distance.size())) return e;
  if (auto e = check("entity", entity.size())) return e;
  if (auto e = check("u", u.size())) return e;
  if (auto e = check("v", v.size())) return e;
  for (std::size_t k = 0; k < extra.size(); ++k) {
    const std::string& name = extra[k].name;
    const bool well_formed =
        !name.empty() && std::all_of(name.begin(), name.end(), [](unsigned char ch) {
          return std::isalnum(ch) || ch == '_';
        });
    if (!well_formed) {
      return "extra column " + std::to_string(k) + " \"" + name +
             "\": names use letters, digits and '_' only (they become CSV headers and PCD fields)";
    }
    if (is_contract_name(name))
      return "extra column \"" + name + "\": clashes with a contract column";
    for (std::size_t j = 0; j < k; ++j) {
      if (extra[j].name == name) return "extra column \"" + name + "\": appears twice";
    }
    if (auto e = check(name.c_str(), extra[k].values.size())) return e;
  }
  return std::nullopt;
}

ProjectionColumns ProjectionTable::columns() const {
  ProjectionColumns c{index, point, foot, distance, entity, u, v, {}};
  for (std::size_t k = 0; k < extra_names.size(); ++k) {
    c.extra.push_back({extra_names[k], extra_values[k]});
  }
  return c;
}

std::optional<TableFormat> table_format_for(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".csv") return TableFormat::csv;
  if (ext == ".pcd") return TableFormat::pcd;
  return std::nullopt;
}

void write_projection_csv(const std::string& path, const ProjectionColumns& c) {
  require_valid(path, c);
  write_atomically(path, [&](std::ostream& out) { write_projection_csv(out, c); });
}

void write_projection_csv(std::ostream& out, const ProjectionColumns& c) {
  require_valid("projection table", c);
  std::string buffer;
  for (std::size_t k = 0; k < kContractColumns; ++k) {
    if (k > 0) buffer += ',';
    buffer += kProjectionColumnNames[k];
  }
  for (const ExtraColumn& e : c.extra)
    buffer += ',' + e.name;
  buffer += '\n';
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  stream_rows_parallel(out, c.rows(), [&c](std::string& b, std::size_t r) {
    text_detail::append_integer(b, static_cast<std::int64_t>(row_index(c, r)));
    for (const engine::Vec3* p : {&c.point[r], &c.foot[r]}) {
      for (int k = 0; k < 3; ++k) {
        b += ',';
        text_detail::append_number(b, (*p)[k]);
      }
    }
    b += ',';
    text_detail::append_number(b, c.distance[r]);
    b += ',';
    text_detail::append_integer(b, c.entity[r]);
    b += ',';
    text_detail::append_number(b, c.u[r]);
    b += ',';
    text_detail::append_number(b, c.v[r]);
    for (const ExtraColumn& e : c.extra) {
      b += ',';
      text_detail::append_number(b, e.values[r]);
    }
    b += '\n';
  });
}

void write_projection_pcd(const std::string& path, const ProjectionColumns& c) {
  require_valid(path, c);
  const std::size_t n = c.rows();
  if (!c.index.empty() && *std::max_element(c.index.begin(), c.index.end()) >
                              std::numeric_limits<std::uint32_t>::max()) {
    throw OutputError(path, "index above 2^32 - 1 does not fit the PCD field (U 4); write CSV");
  }
  std::string header = "# .PCD v0.7 - Point Cloud Data file format (nurbsreg projection results)\n";
  header += "VERSION 0.7\nFIELDS";
  for (const char* name : kProjectionColumnNames)
    header += std::string(" ") + name;
  for (const ExtraColumn& e : c.extra)
    header += ' ' + e.name;
  // index U4, x..distance F8, entity I4, u v F8, extras F8.
  std::string sizes = "\nSIZE 4 8 8 8 8 8 8 8 4 8 8";
  std::string types = "\nTYPE U F F F F F F F I F F";
  std::string counts = "\nCOUNT 1 1 1 1 1 1 1 1 1 1 1";
  for (std::size_t k = 0; k < c.extra.size(); ++k) {
    sizes += " 8";
    types += " F";
    counts += " 1";
  }
  header += sizes + types + counts;
  header += "\nWIDTH " + std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
            std::to_string(n) + "\nDATA binary\n";
  write_atomically(path, [&](std::ostream& out) {
    std::string buffer;
    buffer.reserve(kFlushBytes + 4096);
    buffer += header;
    // Binary PCD rows are the fields packed in order, host byte order (little-endian on every
    // platform PCL supports), no padding.
    stream_rows(out, buffer, n, [&c](std::string& b, std::size_t r) {
      append_binary(b, static_cast<std::uint32_t>(row_index(c, r)));
      for (int k = 0; k < 3; ++k)
        append_binary(b, c.point[r][k]);
      for (int k = 0; k < 3; ++k)
        append_binary(b, c.foot[r][k]);
      append_binary(b, c.distance[r]);
      append_binary(b, c.entity[r]);
      append_binary(b, c.u[r]);
      append_binary(b, c.v[r]);
      for (const ExtraColumn& e : c.extra)
        append_binary(b, e.values[r]);
    });
  });
}

void write_projection_results(const std::string& path, const ProjectionColumns& columns) {
  const auto format = table_format_for(path);
  if (!format) throw OutputError(path, "unknown results format: use a .csv or .pcd file name");
  if (*format == TableFormat::csv) {
    write_projection_csv(path, columns);
  } else {
    write_projection_pcd(path, columns);
  }
}

ProjectionTable read_projection_csv(const std::string& path) {
  const std::string text = text_detail::read_text_file(path);
  ProjectionTable table;
  std::vector<std::string_view> fields;
  std::vector<double> values;
  ColumnMap map{};
  bool have_header = false;
  std::size_t line_number = 0;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + start, end - start);
    start = end + 1;
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    split_csv(line, fields);
    // Built only for a message: formatting it for every row would dominate the reader.
    const auto where = [line_number] { return "line " + std::to_string(line_number); };
    if (!have_header) {
      std::vector<std::string> names(fields.begin(), fields.end());
      map = map_columns(path, where() + " (header)", names, table);
      values.resize(names.size());
      have_header = true;
      continue;
    }
    if (fields.size() != values.size()) {
      throw InputError(path, where() + ": expected " + std::to_string(values.size()) +
                                 " comma-separated values (as in the header), got " +
                                 std::to_string(fields.size()));
    }
    for (std::size_t k = 0; k < fields.size(); ++k) {
      if (!text_detail::parse_number(fields[k], values[k])) {
        throw InputError(path, where() + ", column " + std::to_string(k + 1) + ": " +
                                   text_detail::bad_number(fields[k]));
      }
    }
    append_row(
        path, map, [&values](std::size_t k) { return values[k]; }, where, table);
  }
  if (!have_header) throw InputError(path, "empty file: expected a header line");
  return table;
}

ProjectionTable read_projection_pcd(const std::string& path) {
  // The project's own PCD reader (io/src/point_cloud_pcd.cpp): every header count checked
  // against the file's bytes before anything is allocated.
  const detail::PcdData pcd = detail::read_pcd_data(path);
  ProjectionTable table;
  std::vector<std::string> names;
  for (const detail::PcdField& f : pcd.fields) {
    if (f.count != 1) throw InputError(path, "field \"" + f.name + "\": COUNT must be 1");
    names.push_back(f.name);
  }
  const ColumnMap map = map_columns(path, "FIELDS", names, table);
  for (std::size_t r = 0; r < pcd.points; ++r) {
    append_row(
        path, map, [&](std::size_t k) { return pcd.value(r, pcd.fields[k]); },
        [r] { return "point " + std::to_string(r); }, table);
  }
  return table;
}

ProjectionTable read_projection_results(const std::string& path) {
  const auto format = table_format_for(path);
  if (!format) throw InputError(path, "unknown results format: expected a .csv or .pcd file");
  return *format == TableFormat::csv ? read_projection_csv(path) : read_projection_pcd(path);
}

}  // namespace nurbsreg::io
