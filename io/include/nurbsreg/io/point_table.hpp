#pragma once
// Per-point result tables (projection results, aligned scans with extra fields) and their
// writers. A table is a list of named, typed columns of equal length; row i is one output point.
//
// Formats (CONTRACT §2 "Projection results"):
//  - CSV: one header line of column names, then one line per row. Doubles and floats are printed
//    with std::to_chars' shortest round-trip form, so reading them back gives the identical
//    values; non-finite values print as `nan`, `inf`, `-inf`.
//  - PCD v0.7: one field per column (F8/F4/I4/U4/I8/U8), `ascii`, `binary` (the default) or
//    `binary_compressed` (LZF, structure of arrays). PCD readers (PCL, CloudCompare) expect the
//    coordinates first, so write_pcd requires the first three columns to be x, y, z.
//
// Both writers go through write_atomically: a failed or interrupted write leaves no file behind.
// Thread safety: the writers only read the table; concurrent writes to different paths are fine.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

namespace nurbsreg::io {

using ColumnData =
    std::variant<std::vector<double>, std::vector<float>, std::vector<std::int32_t>,
                 std::vector<std::uint32_t>, std::vector<std::int64_t>, std::vector<std::uint64_t>>;

// True for the element types a column can hold.
template <class T>
inline constexpr bool kIsColumnType =
    std::is_same_v<T, double> || std::is_same_v<T, float> || std::is_same_v<T, std::int32_t> ||
    std::is_same_v<T, std::uint32_t> || std::is_same_v<T, std::int64_t> ||
    std::is_same_v<T, std::uint64_t>;

struct Column {
  std::string name;
  ColumnData values;

  std::size_t size() const;
};

class PointTable {
 public:
  // Appends a column and returns a reference to its values, which stays valid while further
  // columns are added (columns live in a deque). Names must be unique, non-empty, and made of
  // letters, digits and `_` (PCD field names cannot hold spaces; CSV needs no quoting then):
  // checked by validate(), which the writers call.
  template <class T>
  std::vector<T>& add_column(std::string name, std::vector<T> values = {}) {
    static_assert(kIsColumnType<T>, "column type must be double, float, (u)int32 or (u)int64");
    columns_.push_back(Column{std::move(name), ColumnData(std::move(values))});
    return std::get<std::vector<T>>(columns_.back().values);
  }

  const std::deque<Column>& columns() const { return columns_; }
  // nullptr when there is no column of that name.
  const Column* find(std::string_view name) const;
  // Typed access; nullptr when absent or of another type.
  template <class T>
  const std::vector<T>* values(std::string_view name) const {
    const Column* column = find(name);
    return column ? std::get_if<std::vector<T>>(&column->values) : nullptr;
  }
  // Number of rows (0 for a table without columns). Meaningful once validate() passes.
  std::size_t rows() const { return columns_.empty() ? 0 : columns_.front().size(); }

  // Empty when the table is writable; otherwise why not (unequal lengths, bad or duplicate
  // names), naming the column.
  std::optional<std::string> validate() const;

 private:
  std::deque<Column> columns_;
};

enum class PcdEncoding { binary, ascii, binary_compressed };

// CSV with a header line. Throws OutputError when the file cannot be written and
// std::invalid_argument when the table is invalid (a programming error of the caller).
void write_csv(const std::string& path, const PointTable& table);

// PCD v0.7, WIDTH = rows, HEIGHT = 1. Columns 0..2 must be named x, y, z (any numeric type).
// Throws as write_csv; binary_compressed also throws OutputError above 4 GiB of data (the format
// stores sizes in 32 bits).
void write_pcd(const std::string& path, const PointTable& table,
               PcdEncoding encoding = PcdEncoding::binary);

// Dispatches on the extension (case-insensitive): .csv -> write_csv, .pcd -> write_pcd (binary).
// Other extensions throw OutputError naming the supported ones.
void write_point_table(const std::string& path, const PointTable& table);

// Reads a table back: .pcd (any encoding, every field; a field with COUNT n > 1 becomes columns
// name_0 .. name_{n-1}; PCD types map to the column types, I1/I2 -> int32, U1/U2 -> uint32) or
// .csv with a header line (every column float64, `nan`/`inf` accepted). Used to check results
// and by tools that post-process them. Throws InputError naming the file (and line) on bad input.
PointTable read_point_table(const std::string& path);

}  // namespace nurbsreg::io
