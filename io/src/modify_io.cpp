#include "nurbsreg/io/modify_io.hpp"

#include <charconv>
#include <cmath>
#include <set>
#include <sstream>
#include <string_view>

#include <flann/flann.hpp>
#include <nlohmann/json.hpp>

#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

bool parse_index(std::string_view token, int& value) {
  const auto r = std::from_chars(token.data(), token.data() + token.size(), value);
  return r.ec == std::errc() && r.ptr == token.data() + token.size() && value >= 0;
}

}  // namespace

std::vector<engine::SegmentTarget> read_modify_targets(const std::string& path) {
  const std::string text = text_detail::read_text_file(path);
  std::vector<std::string_view> cells;
  int line_number = 0;
  int col_segment = -1;
  int col_x = -1;
  int col_y = -1;
  int col_z = -1;
  bool have_header = false;
  std::vector<engine::SegmentTarget> targets;
  std::set<int> seen;
  auto where = [&] { return "line " + std::to_string(line_number) + ": "; };
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view view(text.data() + start, end - start);
    start = end + 1;
    ++line_number;
    if (const std::size_t hash = view.find('#'); hash != std::string_view::npos) {
      view = view.substr(0, hash);
    }
    view = trim(view);
    if (view.empty()) continue;
    text_detail::split_csv(view, cells);
    if (!have_header) {
      for (int c = 0; c < static_cast<int>(cells.size()); ++c) {
        if (cells[c] == "segment") col_segment = c;
        if (cells[c] == "x") col_x = c;
        if (cells[c] == "y") col_y = c;
        if (cells[c] == "z") col_z = c;
      }
      if (col_segment < 0 || col_x < 0 || col_y < 0) {
        throw InputError(path, where() + "expected the header `segment,x,y,z` (z optional), got " +
                                   text_detail::quote(view));
      }
      have_header = true;
      continue;
    }
    const int needed = std::max({col_segment, col_x, col_y, col_z}) + 1;
    if (static_cast<int>(cells.size()) < needed) {
      throw InputError(path, where() + "expected " + std::to_string(needed) + " columns, got " +
                                 std::to_string(cells.size()));
    }
    engine::SegmentTarget t;
    if (!parse_index(cells[col_segment], t.segment)) {
      throw InputError(path, where() + "segment: expected a 0-based integer, got " +
                                 text_detail::quote(cells[col_segment]));
    }
    const int cols[3] = {col_x, col_y, col_z};
    const char* names[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      double v = 0.0;
      if (cols[k] >= 0 && !(text_detail::parse_number(cells[cols[k]], v) && std::isfinite(v))) {
        throw InputError(path, where() + names[k] + ": expected a finite number, got " +
                                   text_detail::quote(cells[cols[k]]));
      }
      t.point[k] = v;
    }
    if (!seen.insert(t.segment).second) {
      throw InputError(path, where() + "segment " + std::to_string(t.segment) +
                                 " appears twice (one target per segment)");
    }
    targets.push_back(t);
  }
  if (!have_header) throw InputError(path, "empty file (expected the header `segment,x,y,z`)");
  if (targets.empty()) throw InputError(path, "no target rows after the header");
  return targets;
}

std::vector<engine::SegmentTarget> nearest_scan_targets(std::span<const engine::Vec3> scan,
                                                        std::span<const engine::NosePoint> noses,
                                                        const std::string& scan_label) {
  if (scan.empty()) throw InputError(scan_label, "the scan has no (finite) points");
  // FLANN reads the points in place: Eigen::Vector3d is three contiguous doubles with no padding.
  static_assert(sizeof(engine::Vec3) == 3 * sizeof(double));
  flann::Matrix<double> data(const_cast<double*>(scan.data()->data()), scan.size(), 3);
  // A single kd-tree searched with unlimited checks is an exact nearest-neighbour search.
  flann::Index<flann::L2<double>> index(data, flann::KDTreeSingleIndexParams(10));
  index.buildIndex();
  std::vector<double> queries(3 * noses.size());
  for (std::size_t j = 0; j < noses.size(); ++j) {
    for (int k = 0; k < 3; ++k)
      queries[3 * j + k] = noses[j].point[k];
  }
  flann::Matrix<double> query(queries.data(), noses.size(), 3);
  std::vector<std::size_t> indices_storage(noses.size());
  std::vector<double> dists_storage(noses.size());
  flann::Matrix<std::size_t> indices(indices_storage.data(), noses.size(), 1);
  flann::Matrix<double> dists(dists_storage.data(), noses.size(), 1);
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED);
  params.cores = 1;  // a handful of queries; results must not depend on threads
  index.knnSearch(query, indices, dists, 1, params);
  std::vector<engine::SegmentTarget> out;
  for (std::size_t j = 0; j < noses.size(); ++j) {
    std::size_t best = indices_storage[j];
    // Ties: prefer the lowest index, so the choice does not depend on the tree layout.
    const double d = (scan[best] - noses[j].point).squaredNorm();
    for (std::size_t i = 0; i < best; ++i) {
      if ((scan[i] - noses[j].point).squaredNorm() == d) {
        best = i;
        break;
      }
    }
    out.push_back({noses[j].segment, scan[best]});
  }
  return out;
}

const char* to_string(engine::ModifyMethod method) {
  switch (method) {
    case engine::ModifyMethod::points:
      return "points";
    case engine::ModifyMethod::weights:
      return "weights";
    case engine::ModifyMethod::weights_knots:
      return "weights-knots";
    case engine::ModifyMethod::combined:
      return "combined";
  }
  return "unknown";
}

const char* to_string(engine::NoseRule rule) {
  return rule == engine::NoseRule::mean_parameter ? "mean-parameter" : "nearest-to-control-point";
}

std::string modify_report_to_json(const ModifyReport& report) {
  using nlohmann::json;
  auto point = [](const engine::Vec3& p) { return json::array({p.x(), p.y(), p.z()}); };
  json j;
  j["curve"] = report.curve_name;
  j["model"] = report.model_file;
  j["target_source"] = report.target_source;
  j["method"] = to_string(report.options.method);
  j["nose_rule"] = to_string(report.options.nose_rule);
  j["iterate"] = report.options.iterate;
  j["rho_min"] = report.options.rho_min;
  j["max_iterations"] = report.options.max_iterations;
  json targets = json::array();
  for (const engine::SegmentTarget& t : report.targets) {
    targets.push_back({{"segment", t.segment}, {"point", point(t.point)}});
  }
  j["targets"] = targets;
  json steps = json::array();
  for (const engine::ModifyStep& s : report.result.steps) {
    json row;
    row["operation"] = s.operation;
    row["errors"] = s.errors;
    row["total"] = s.total;
    row["rho"] = s.rho;
    row["weights"] = s.weights;
    row["knots"] = s.knots;
    row["note"] = s.note;
    row["reverted"] = s.reverted;
    steps.push_back(row);
  }
  j["steps"] = steps;
  const auto& all = report.result.steps;
  if (!all.empty()) {
    const engine::ModifyStep* last = &all.front();
    for (const engine::ModifyStep& s : all) {
      if (!s.reverted) last = &s;
    }
    j["initial_errors"] = all.front().errors;
    j["initial_total"] = all.front().total;
    j["final_errors"] = last->errors;
    j["final_total"] = last->total;
  }
  j["termination"] = report.result.termination;
  return j.dump(2) + "\n";
}

void write_modify_report(const std::string& path, const ModifyReport& report) {
  const std::string text = modify_report_to_json(report);
  write_atomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace nurbsreg::io
