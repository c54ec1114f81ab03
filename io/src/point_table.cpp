// PointTable, its CSV and PCD writers and read_point_table.
//
// Writers format whole chunks of rows into one buffer and hand it to the stream in large
// blocks; numbers go through std::to_chars (shortest exact form), so millions of rows take
// about a second (see bench/README.md, "Point I/O").
#include "nurbsreg/io/point_table.hpp"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <limits>
#include <ostream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unordered_set>

#include "lzf.hpp"
#include "nurbsreg/io/atomic_file.hpp"
#include "point_cloud_detail.hpp"

namespace nurbsreg::io {

std::size_t Column::size() const {
  return std::visit([](const auto& v) { return v.size(); }, values);
}

const Column* PointTable::find(std::string_view name) const {
  for (const Column& column : columns_) {
    if (column.name == name) return &column;
  }
  return nullptr;
}

std::optional<std::string> PointTable::validate() const {
  std::unordered_set<std::string_view> seen;
  for (const Column& column : columns_) {
    if (column.name.empty()) return "a column has an empty name";
    for (const char c : column.name) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') {
        return "column " + text_detail::quote(column.name) +
               ": names may hold only letters, digits and '_'";
      }
    }
    if (!seen.insert(column.name).second)
      return "column " + text_detail::quote(column.name) + " appears twice";
    if (column.size() != rows()) {
      return "column " + text_detail::quote(column.name) + " has " + std::to_string(column.size()) +
             " values, column " + text_detail::quote(columns_.front().name) + " has " +
             std::to_string(rows());
    }
  }
  return std::nullopt;
}

namespace {

void require_valid(const PointTable& table) {
  if (const auto problem = table.validate()) {
    throw std::invalid_argument("invalid point table: " + *problem);
  }
}

// A column seen as raw typed memory, so the row loops switch on a small integer instead of
// visiting a variant per value.
struct ColumnView {
  const void* data;
  std::size_t kind;  // ColumnData alternative index
  std::size_t size;  // bytes per value
  char pcd_type;
};

ColumnView view_of(const Column& column) {
  return std::visit(
      [&](const auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        const char type = std::is_floating_point_v<T> ? 'F' : std::is_signed_v<T> ? 'I' : 'U';
        return ColumnView{v.data(), column.values.index(), sizeof(T), type};
      },
      column.values);
}

void append_value(std::string& out, const ColumnView& c, std::size_t i) {
  switch (c.kind) {
    case 0:
      detail::append_number(out, static_cast<const double*>(c.data)[i]);
      break;
    case 1:
      detail::append_number(out, static_cast<const float*>(c.data)[i]);
      break;
    case 2:
      detail::append_number(out, static_cast<const std::int32_t*>(c.data)[i]);
      break;
    case 3:
      detail::append_number(out, static_cast<const std::uint32_t*>(c.data)[i]);
      break;
    case 4:
      detail::append_number(out, static_cast<const std::int64_t*>(c.data)[i]);
      break;
    default:
      detail::append_number(out, static_cast<const std::uint64_t*>(c.data)[i]);
      break;
  }
}

constexpr std::size_t kFlushBytes = std::size_t{1} << 20;

void flush_if_full(std::ostream& out, std::string& buffer) {
  if (buffer.size() >= kFlushBytes) {
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    buffer.clear();
  }
}

void write_text_rows(std::ostream& out, const std::vector<ColumnView>& views, std::size_t rows,
                     char separator, std::string& buffer) {
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t c = 0; c < views.size(); ++c) {
      if (c != 0) buffer.push_back(separator);
      append_value(buffer, views[c], i);
    }
    buffer.push_back('\n');
    flush_if_full(out, buffer);
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  buffer.clear();
}

std::vector<ColumnView> views_of(const PointTable& table) {
  std::vector<ColumnView> views;
  for (const Column& column : table.columns())
    views.push_back(view_of(column));
  return views;
}

}  // namespace

void write_csv(const std::string& path, const PointTable& table) {
  require_valid(table);
  const std::vector<ColumnView> views = views_of(table);
  write_atomically(path, [&](std::ostream& out) {
    std::string buffer;
    buffer.reserve(kFlushBytes + 4096);
    for (std::size_t c = 0; c < table.columns().size(); ++c) {
      if (c != 0) buffer.push_back(',');
      buffer += table.columns()[c].name;
    }
    buffer.push_back('\n');
    write_text_rows(out, views, table.rows(), ',', buffer);
  });
}

void write_pcd(const std::string& path, const PointTable& table, PcdEncoding encoding) {
  require_valid(table);
  const auto& columns = table.columns();
  if (columns.size() < 3 || columns[0].name != "x" || columns[1].name != "y" ||
      columns[2].name != "z") {
    throw std::invalid_argument("write_pcd: the first three columns must be x, y, z");
  }
  static_assert(std::endian::native == std::endian::little, "PCD binary data is little-endian");
  const std::vector<ColumnView> views = views_of(table);
  const std::size_t rows = table.rows();
  std::size_t point_step = 0;
  for (const ColumnView& v : views)
    point_step += v.size;
  if (encoding == PcdEncoding::binary_compressed &&
      rows * point_step > std::numeric_limits<std::uint32_t>::max()) {
    throw OutputError(path, "binary_compressed PCD cannot hold more than 4 GiB; use binary");
  }

  // Header (PCD v0.7 as specified in PCL's pcd_file_format documentation).
  std::string header = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS";
  for (const Column& c : columns)
    header += " " + c.name;
  header += "\nSIZE";
  for (const ColumnView& v : views)
    header += " " + std::to_string(v.size);
  header += "\nTYPE";
  for (const ColumnView& v : views)
    header += std::string(" ") + v.pcd_type;
  header += "\nCOUNT";
  for (std::size_t c = 0; c < views.size(); ++c)
    header += " 1";
  header += "\nWIDTH " + std::to_string(rows) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
            std::to_string(rows) + "\nDATA " +
            (encoding == PcdEncoding::ascii    ? "ascii"
             : encoding == PcdEncoding::binary ? "binary"
                                               : "binary_compressed") +
            "\n";

  write_atomically(path, [&](std::ostream& out) {
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    if (encoding == PcdEncoding::ascii) {
      std::string buffer;
      buffer.reserve(kFlushBytes + 4096);
      write_text_rows(out, views, rows, ' ', buffer);
    } else if (encoding == PcdEncoding::binary) {
      // Row-major records, interleaved column by column, in chunks of rows.
      const std::size_t chunk_rows =
          std::max<std::size_t>(1, kFlushBytes / std::max<std::size_t>(point_step, 1));
      std::vector<char> buffer(chunk_rows * point_step);
      for (std::size_t first = 0; first < rows; first += chunk_rows) {
        const std::size_t count = std::min(chunk_rows, rows - first);
        std::size_t offset = 0;
        for (const ColumnView& v : views) {
          const char* src = static_cast<const char*>(v.data) + first * v.size;
          char* dst = buffer.data() + offset;
          for (std::size_t i = 0; i < count; ++i) {
            std::memcpy(dst + i * point_step, src + i * v.size, v.size);
          }
          offset += v.size;
        }
        out.write(buffer.data(), static_cast<std::streamsize>(count * point_step));
      }
    } else {
      // Structure of arrays (each field's values contiguous), then one LZF block preceded by
      // the compressed and uncompressed sizes (uint32 each), as PCL's PCDWriter does.
      const std::size_t bytes = rows * point_step;
      std::vector<char> soa(bytes);
      std::size_t offset = 0;
      for (const ColumnView& v : views) {
        if (rows == 0) break;  // memcpy from an empty vector's null data() is undefined
        std::memcpy(soa.data() + offset, v.data, rows * v.size);
        offset += rows * v.size;
      }
      // LZF output exceeds its input by at most one control byte per 32 literals.
      std::vector<char> compressed(bytes + bytes / 16 + 64);
      const std::size_t compressed_size =
          bytes == 0 ? 0
                     : detail::lzf_compress(
                           reinterpret_cast<const std::uint8_t*>(soa.data()), bytes,
                           reinterpret_cast<std::uint8_t*>(compressed.data()), compressed.size());
      if (bytes != 0 && compressed_size == 0) throw OutputError(path, "LZF compression failed");
      const std::uint32_t sizes[2] = {static_cast<std::uint32_t>(compressed_size),
                                      static_cast<std::uint32_t>(bytes)};
      out.write(reinterpret_cast<const char*>(sizes), sizeof sizes);
      out.write(compressed.data(), static_cast<std::streamsize>(compressed_size));
    }
  });
}

void write_point_table(const std::string& path, const PointTable& table) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".csv") {
    write_csv(path, table);
  } else if (ext == ".pcd") {
    write_pcd(path, table);
  } else {
    throw OutputError(path, "unsupported result format '" + ext + "' (supported: .csv, .pcd)");
  }
}

namespace {

// An ASCII value (read as a double) as the field's type. For an integer type a value beyond
// the type's range (or NaN) is an error: the cast would be undefined behaviour. The type's
// maximum as a double may round up (2^64 for U8): that value is the written maximum, rounded.
template <class T>
T column_value(double v, const std::string& path, const detail::PcdField& f) {
  if constexpr (std::is_integral_v<T>) {
    constexpr double lo = static_cast<double>(std::numeric_limits<T>::lowest());
    constexpr double hi = static_cast<double>(std::numeric_limits<T>::max());
    if (!(v >= lo && v <= hi)) {
      throw InputError(path, "PCD field " + text_detail::quote(f.name) + ": value " +
                                 text_detail::quote(std::to_string(v)) + " is outside TYPE " +
                                 f.type + " SIZE " + std::to_string(f.size));
    }
    if (v == hi) return std::numeric_limits<T>::max();
  }
  return static_cast<T>(v);
}

template <class T>
std::vector<T> pcd_column(const std::string& path, const detail::PcdData& pcd,
                          const detail::PcdField& f, std::size_t k) {
  std::vector<T> out(pcd.points);
  if (pcd.ascii) {
    for (std::size_t i = 0; i < pcd.points; ++i)
      out[i] = column_value<T>(pcd.value(i, f, k), path, f);
    return out;
  }
  // Binary: read the stored type exactly (64-bit integers would lose bits through double).
  for (std::size_t i = 0; i < pcd.points; ++i) {
    const std::uint8_t* p = pcd.rows.data() + i * pcd.point_step + f.offset + k * f.size;
    if (f.size == sizeof(T)) {
      std::memcpy(&out[i], p, sizeof(T));
    } else {
      out[i] = column_value<T>(pcd.value(i, f, k), path, f);
    }
  }
  return out;
}

PointTable read_pcd_table(const std::string& path) {
  const detail::PcdData pcd = detail::read_pcd_data(path);
  PointTable table;
  for (const detail::PcdField& f : pcd.fields) {
    for (std::size_t k = 0; k < f.count; ++k) {
      std::string name = f.count == 1 ? f.name : f.name + "_" + std::to_string(k);
      if (f.type == 'F') {
        if (f.size == 8) {
          table.add_column(std::move(name), pcd_column<double>(path, pcd, f, k));
        } else {
          table.add_column(std::move(name), pcd_column<float>(path, pcd, f, k));
        }
      } else if (f.type == 'I') {
        if (f.size == 8) {
          table.add_column(std::move(name), pcd_column<std::int64_t>(path, pcd, f, k));
        } else {
          table.add_column(std::move(name), pcd_column<std::int32_t>(path, pcd, f, k));
        }
      } else if (f.size == 8) {
        table.add_column(std::move(name), pcd_column<std::uint64_t>(path, pcd, f, k));
      } else {
        table.add_column(std::move(name), pcd_column<std::uint32_t>(path, pcd, f, k));
      }
    }
  }
  return table;
}

PointTable read_csv_table(const std::string& path) {
  const std::string data = detail::read_text_file(path);
  PointTable table;
  std::vector<std::vector<double>*> columns;  // stable: the table keeps columns in a deque
  std::vector<std::string_view> fields;
  bool have_header = false;
  const char* p = data.data();
  const char* const end = p + data.size();
  if (data.starts_with(detail::kUtf8Bom)) p += detail::kUtf8Bom.size();
  std::size_t line_number = 0;
  while (p < end) {
    ++line_number;
    const char* eol =
        static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
    if (eol == nullptr) eol = end;
    std::string_view line(p, static_cast<std::size_t>(eol - p));
    p = eol + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.find_first_not_of(" \t") == std::string_view::npos || line.front() == '#') continue;
    const auto fail = [&](const std::string& what) {
      return InputError(path, "line " + std::to_string(line_number) + ": " + what);
    };
    text_detail::split_csv(line, fields);
    for (std::size_t k = 0; k < fields.size(); ++k) {
      const std::string_view token = fields[k];
      if (!have_header) {
        if (token.empty()) throw fail("empty column name in the header");
        columns.push_back(&table.add_column<double>(std::string(token)));
      } else {
        if (k >= columns.size()) {
          throw fail("more values than the " + std::to_string(columns.size()) + " header columns");
        }
        double value = 0.0;
        if (!detail::parse_number(token, value)) {
          throw fail("column " + text_detail::quote(table.columns()[k].name) + ": " +
                     text_detail::bad_number(token));
        }
        columns[k]->push_back(value);
      }
    }
    const std::size_t k = fields.size();
    if (!have_header) {
      have_header = true;
      if (const auto problem = table.validate()) throw fail("bad header: " + *problem);
    } else if (k != columns.size()) {
      throw fail("expected " + std::to_string(columns.size()) + " values, got " +
                 std::to_string(k));
    }
  }
  if (!have_header) throw InputError(path, "empty CSV file (no header line)");
  return table;
}

}  // namespace

PointTable read_point_table(const std::string& path) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".pcd") return read_pcd_table(path);
  if (ext == ".csv") return read_csv_table(path);
  throw InputError(path, "unsupported table format '" + ext + "' (supported: .csv, .pcd)");
}

}  // namespace nurbsreg::io
