#include "nurbsreg/inspect/inspection_report.hpp"

#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <nlohmann/json.hpp>

namespace nurbsreg::inspect {
namespace {

using Json = nlohmann::ordered_json;

Json number_or_null(double x) {
  return std::isfinite(x) ? Json(x) : Json(nullptr);
}

void put_stats(Json& j, const DeviationStats& s) {
  j["points"] = s.points;
  j["mean"] = number_or_null(s.mean);
  j["std"] = number_or_null(s.std);
  j["rms"] = number_or_null(s.rms);
  j["min"] = number_or_null(s.min);
  j["max"] = number_or_null(s.max);
  j["p5"] = number_or_null(s.p5);
  j["p95"] = number_or_null(s.p95);
  j["inside_tolerance"] = number_or_null(s.inside_fraction());
  j["inside"] = s.inside;
  j["below"] = s.below;
  j["above"] = s.above;
}

// Shortest exact form, as in JSON; empty for NaN.
std::string csv_number(double x) {
  return std::isfinite(x) ? fmt::format("{}", x) : "";
}

std::string csv_text(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string quoted = "\"";
  for (const char c : s) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + "\"";
}

std::string csv_row(int face, const std::string& name, const DeviationStats& s) {
  return fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", face, csv_text(name), s.points,
                     csv_number(s.mean), csv_number(s.std), csv_number(s.rms), csv_number(s.min),
                     csv_number(s.max), csv_number(s.p5), csv_number(s.p95),
                     csv_number(s.inside_fraction()), s.inside, s.below, s.above);
}

}  // namespace

std::string inspection_json(const InspectionReport& r) {
  Json j = Json::parse(io::report_to_json(r.alignment));
  // The contract's overall "points" is the inspected points; the scan's finite points follow.
  j["scan_points"] = r.scan_points;
  j["unprojected_points"] = r.stats.unprojected;
  // Points left out as clutter (`--exclude-beyond`): not in any statistic nor the verdict.
  j["excluded_points"] = r.stats.excluded;
  j["exclude_beyond"] =
      r.stats.exclusion_distance > 0.0 ? Json(r.stats.exclusion_distance) : Json(nullptr);
  j["pose_given"] = r.pose_given;
  j["degenerate"] = !r.degeneracy.empty();
  if (!r.degeneracy.empty()) j["free_directions"] = r.degeneracy;
  j["model"] = r.model_file;
  j["scan"] = r.scan_file;
  j["units"] = r.units;
  j["tolerance"] = Json{{"lower", r.stats.tolerance.lower}, {"upper", r.stats.tolerance.upper}};
  put_stats(j, r.stats.overall);
  j["verdict"] = r.passed() ? "pass" : "fail";
  j["min_inside"] = r.min_inside;
  j["colour_scale"] = Json{{"scheme", std::string(to_string(r.scale.scheme))},
                           {"lower_limit", r.scale.lower_limit},
                           {"upper_limit", r.scale.upper_limit}};
  const Histogram& h = r.stats.histogram;
  j["histogram"] = Json{
      {"low", h.low}, {"high", h.high}, {"counts", h.counts}, {"under", h.under}, {"over", h.over}};
  Json faces = Json::array();
  for (const FaceStats& f : r.stats.faces) {
    Json face{{"face", f.face}, {"name", f.name}};
    put_stats(face, f.stats);
    faces.push_back(std::move(face));
  }
  j["faces"] = std::move(faces);
  j["viewer"] = Json{{"points", r.viewer_points}, {"subset", r.viewer_subset}};
  j["picture_view"] = r.picture_view;
  j["alignment_seconds"] = r.alignment_seconds;
  j["inspection_seconds"] = r.inspection_seconds;
  return j.dump(1) + "\n";
}

std::string faces_csv(const InspectionReport& r) {
  std::string out =
      "face,name,points,mean,std,rms,min,max,p5,p95,inside_tolerance,inside,below,above\n";
  out += csv_row(-1, "(all points)", r.stats.overall);
  for (const FaceStats& f : r.stats.faces)
    out += csv_row(f.face, f.name, f.stats);
  return out;
}

}  // namespace nurbsreg::inspect
