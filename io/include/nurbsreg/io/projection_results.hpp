#pragma once
// Projection results (`project --out R.csv` or `R.pcd`; CONTRACT.md §2 "Projection results").
//
// One row per projected input point, columns (by name, in this order):
//   index,x,y,z,foot_x,foot_y,foot_z,distance,entity,u,v[,extra...]
// `index` is the 0-based index of the input point (skipped points have no row), `entity` the
// 0-based surface (or curve) index, `v` = 0 for curves, `distance` >= 0. Extra columns (normal,
// signed distance, ...) follow under their own names.
//
// Writers take caller-owned columns by span (no copy of the engine's structure-of-arrays
// results) and stream the file in blocks, so memory stays bounded for millions of rows.
//  - CSV: a header line, then numbers in their shortest exact round-trip form (std::to_chars).
//  - PCD: binary PCD v0.7, one field per column: index U4, entity I4, every other column F8
//    (double, so the .pcd carries the same values as the .csv). WIDTH = rows, HEIGHT = 1.
// Files are written atomically. Readers (used by tests and tooling) return owning columns; the
// PCD reader goes through PCL, so it also checks that PCL tools can open what we write.
// All functions are thread-safe (no shared state); they allocate per call, never per row.

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::io {

// A named extra column of doubles (e.g. "normal_x", "signed_distance").
struct ExtraColumn {
  std::string name;
  std::span<const double> values;
};

// Views of the columns to write; every non-empty span has the same length (the row count).
struct ProjectionColumns {
  // Input point indices; empty means 0, 1, ..., rows - 1 (nothing was skipped).
  std::span<const std::uint64_t> index;
  std::span<const engine::Vec3> point;
  std::span<const engine::Vec3> foot;
  std::span<const double> distance;
  std::span<const std::int32_t> entity;
  std::span<const double> u;
  std::span<const double> v;
  std::vector<ExtraColumn> extra;

  std::size_t rows() const { return point.size(); }
  // An error naming the column (length mismatch, bad extra-column name), or nothing.
  std::optional<std::string> validate() const;
};

// The same table, owning its data (what the readers return).
struct ProjectionTable {
  std::vector<std::uint64_t> index;
  std::vector<engine::Vec3> point;
  std::vector<engine::Vec3> foot;
  std::vector<double> distance;
  std::vector<std::int32_t> entity;
  std::vector<double> u;
  std::vector<double> v;
  std::vector<std::string> extra_names;
  std::vector<std::vector<double>> extra_values;  // extra_values[k][row]

  std::size_t rows() const { return point.size(); }
  // Views of this table, for the writers.
  ProjectionColumns columns() const;
};

// The contract's column names, in order.
inline constexpr const char* kProjectionColumnNames[] = {
    "index", "x", "y", "z", "foot_x", "foot_y", "foot_z", "distance", "entity", "u", "v"};

enum class TableFormat { csv, pcd };

// By extension (case-insensitive): .csv or .pcd; nothing for anything else.
std::optional<TableFormat> table_format_for(const std::string& path);

// Writers. Throw OutputError naming the file on invalid columns or write failure; the target
// is never left half-written.
void write_projection_csv(const std::string& path, const ProjectionColumns& columns);
void write_projection_pcd(const std::string& path, const ProjectionColumns& columns);
// The CSV file's bytes to any stream (the service's response body); OutputError on invalid
// columns. The stream's own failures are the caller's to check.
void write_projection_csv(std::ostream& out, const ProjectionColumns& columns);
// Dispatches on table_format_for(path); an unknown extension is an OutputError.
void write_projection_results(const std::string& path, const ProjectionColumns& columns);

// Readers. Columns are matched by name (order free); the contract's columns are required and
// every other column becomes an extra. Throw InputError naming the file, line and column.
ProjectionTable read_projection_csv(const std::string& path);
ProjectionTable read_projection_pcd(const std::string& path);
ProjectionTable read_projection_results(const std::string& path);

}  // namespace nurbsreg::io
