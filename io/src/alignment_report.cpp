#include "nurbsreg/io/alignment_report.hpp"

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "printable.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

// ordered_json keeps the contract fields first, in the order a reader expects them.
using Json = nlohmann::ordered_json;

// JSON has no NaN: undefined values become null (nlohmann writes NaN as null anyway; being
// explicit keeps infinities out too).
Json number_or_null(double x) {
  return std::isfinite(x) ? Json(x) : Json(nullptr);
}

// A value from the file for a message: its JSON text, shortened and with bytes outside printable
// ASCII as \xHH (JSON escapes control characters only), so that the message stays one line.
std::string shown(const Json& value) {
  return text_detail::quote(
      value.dump(-1, ' ', /*ensure_ascii=*/false, Json::error_handler_t::replace));
}

class ReportReader {
 public:
  ReportReader(const std::string& file, const Json& object) : file_(file), object_(object) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw InputError(file_, field + ": " + what);
  }
  const Json* find(const Json& object, const char* key) const {
    const auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
  }
  const Json& required(const char* key) const {
    const Json* value = find(object_, key);
    if (value == nullptr) fail(key, "missing (required)");
    return *value;
  }
  double number(const Json& value, const std::string& field) const {
    if (value.is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!value.is_number()) fail(field, "expected a number, got " + shown(value));
    return value.get<double>();
  }
  std::size_t count(const Json& value, const std::string& field) const {
    if (!value.is_number_unsigned())
      fail(field, "expected a non-negative integer, got " + shown(value));
    return value.get<std::size_t>();
  }
  const Json& object() const { return object_; }

 private:
  const std::string& file_;
  const Json& object_;
};

Json matrix_json(const Eigen::Matrix4d& m) {
  Json pose = Json::array();
  for (int i = 0; i < 4; ++i) {
    Json row = Json::array();
    for (int j = 0; j < 4; ++j)
      row.push_back(number_or_null(m(i, j)));
    pose.push_back(std::move(row));
  }
  return pose;
}

Json score_json(const PoseScoreRecord& s) {
  return Json{{"pose", matrix_json(s.pose)},
              {"inlier_fraction", number_or_null(s.inlier_fraction)},
              {"trimmed_rms", number_or_null(s.trimmed_rms)}};
}

}  // namespace

std::string report_to_json(const AlignmentReport& r) {
  Json pose = matrix_json(r.pose);
  Json history = Json::array();
  for (const IterationRecord& it : r.history) {
    history.push_back(Json{{"iteration", it.iteration},
                           {"rms", number_or_null(it.rms)},
                           {"inliers", it.inliers},
                           {"rotation_step", number_or_null(it.rotation_step)},
                           {"translation_step", number_or_null(it.translation_step)},
                           {"seconds", number_or_null(it.seconds)}});
  }
  Json document{{"pose", std::move(pose)},
                {"rms", number_or_null(r.rms)},
                {"iterations", r.iterations},
                {"converged", r.converged},
                {"inliers", r.inliers},
                {"points", r.points},
                {"seconds", number_or_null(r.seconds)},
                {"skipped_points", r.skipped_points},
                {"method", r.method},
                {"termination", r.termination},
                {"history", std::move(history)}};
  if (r.has_fit) {
    const FitRecord& f = r.fit;
    document["fit"] = f.fit;
    document["fit_details"] = Json{{"reason", f.reason},
                                   {"noise", number_or_null(f.noise)},
                                   {"tolerance", number_or_null(f.tolerance)},
                                   {"inlier_fraction", number_or_null(f.inlier_fraction)},
                                   {"rms", number_or_null(f.rms)},
                                   {"rms_over_noise", number_or_null(f.rms_ratio)},
                                   {"coverage", number_or_null(f.coverage)},
                                   {"scan_noise", number_or_null(f.scan_noise)},
                                   {"fit_noise", number_or_null(f.fit_noise)}};
  }
  if (r.has_coarse) {
    const CoarseRecord& c = r.coarse;
    Json alternatives = Json::array();
    for (const PoseScoreRecord& a : c.alternatives)
      alternatives.push_back(score_json(a));
    document["coarse"] = Json{{"method", c.method},
                              {"scan_keypoints", c.scan_keypoints},
                              {"model_keypoints", c.model_keypoints},
                              {"matches", c.matches},
                              {"hypotheses", c.hypotheses},
                              {"verified", c.verified},
                              {"voxel", number_or_null(c.voxel)},
                              {"noise", number_or_null(c.noise)},
                              {"seconds", number_or_null(c.seconds)},
                              {"model_features_seconds", number_or_null(c.model_features_seconds)},
                              {"alignment_seconds", number_or_null(c.alignment_seconds)},
                              {"alignment_cpu_seconds", number_or_null(c.alignment_cpu_seconds)},
                              {"winner", score_json(c.winner)},
                              {"runner_up", c.has_runner_up ? score_json(c.runner_up) : Json()},
                              {"alternatives", std::move(alternatives)},
                              {"symmetry", c.symmetry}};
  }
  return document.dump(2) + "\n";
}

void write_alignment_report(const std::string& path, const AlignmentReport& report) {
  const std::string text = report_to_json(report);
  write_atomically(path, [&](std::ostream& out) {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

AlignmentReport parse_alignment_report(std::string_view text, const std::string& file_label) {
  Json document;
  try {
    document = Json::parse(text.begin(), text.end());
  } catch (const Json::parse_error& error) {
    const auto position = text_detail::position_of(text, error.byte == 0 ? 0 : error.byte - 1);
    throw InputError(file_label, "line " + std::to_string(position.line) + ", column " +
                                     std::to_string(position.column) + ": invalid JSON");
  } catch (const Json::exception& error) {
    throw InputError(file_label, "invalid JSON: " + text_detail::printable(error.what()));
  }
  if (!document.is_object()) throw InputError(file_label, "expected a JSON object");
  const ReportReader in(file_label, document);
  AlignmentReport r;
  const Json& pose = in.required("pose");
  if (!pose.is_array() || pose.size() != 4) in.fail("pose", "expected 4 rows of 4 numbers");
  for (int i = 0; i < 4; ++i) {
    if (!pose[i].is_array() || pose[i].size() != 4) {
      in.fail("pose[" + std::to_string(i) + "]", "expected 4 numbers");
    }
    for (int j = 0; j < 4; ++j) {
      r.pose(i, j) =
          in.number(pose[i][j], "pose[" + std::to_string(i) + "][" + std::to_string(j) + "]");
    }
  }
  r.rms = in.number(in.required("rms"), "rms");
  r.iterations = static_cast<int>(in.count(in.required("iterations"), "iterations"));
  const Json& converged = in.required("converged");
  if (!converged.is_boolean())
    in.fail("converged", "expected true or false, got " + shown(converged));
  r.converged = converged.get<bool>();
  r.inliers = in.count(in.required("inliers"), "inliers");
  r.points = in.count(in.required("points"), "points");
  r.seconds = in.number(in.required("seconds"), "seconds");
  if (const Json* v = in.find(document, "skipped_points"))
    r.skipped_points = in.count(*v, "skipped_points");
  if (const Json* v = in.find(document, "method"); v && v->is_string())
    r.method = v->get<std::string>();
  if (const Json* v = in.find(document, "termination"); v && v->is_string()) {
    r.termination = v->get<std::string>();
  }
  if (const Json* v = in.find(document, "fit"); v && v->is_string()) {
    r.has_fit = true;
    r.fit.fit = v->get<std::string>();
    if (const Json* d = in.find(document, "fit_details"); d && d->is_object()) {
      const auto num = [&](const char* key, double& out) {
        if (const Json* x = in.find(*d, key))
          out = in.number(*x, std::string("fit_details.") + key);
      };
      if (const Json* x = in.find(*d, "reason"); x && x->is_string())
        r.fit.reason = x->get<std::string>();
      num("noise", r.fit.noise);
      num("tolerance", r.fit.tolerance);
      num("inlier_fraction", r.fit.inlier_fraction);
      num("rms", r.fit.rms);
      num("rms_over_noise", r.fit.rms_ratio);
      num("coverage", r.fit.coverage);
      num("scan_noise", r.fit.scan_noise);
      num("fit_noise", r.fit.fit_noise);
    }
  }
  if (const Json* c = in.find(document, "coarse"); c && c->is_object()) {
    r.has_coarse = true;
    if (const Json* x = in.find(*c, "method"); x && x->is_string())
      r.coarse.method = x->get<std::string>();
    if (const Json* x = in.find(*c, "symmetry"); x && x->is_string())
      r.coarse.symmetry = x->get<std::string>();
    if (const Json* x = in.find(*c, "alternatives"); x && x->is_array()) {
      r.coarse.alternatives.resize(x->size());
    }
  }
  if (const Json* history = in.find(document, "history")) {
    if (!history->is_array()) in.fail("history", "expected an array");
    for (std::size_t k = 0; k < history->size(); ++k) {
      const Json& entry = (*history)[k];
      const std::string field = "history[" + std::to_string(k) + "]";
      if (!entry.is_object()) in.fail(field, "expected an object");
      IterationRecord it;
      const auto get = [&](const char* key) -> const Json& {
        const Json* value = in.find(entry, key);
        if (value == nullptr) in.fail(field + "." + key, "missing (required)");
        return *value;
      };
      it.iteration = static_cast<int>(in.count(get("iteration"), field + ".iteration"));
      it.rms = in.number(get("rms"), field + ".rms");
      it.inliers = in.count(get("inliers"), field + ".inliers");
      it.rotation_step = in.number(get("rotation_step"), field + ".rotation_step");
      it.translation_step = in.number(get("translation_step"), field + ".translation_step");
      it.seconds = in.number(get("seconds"), field + ".seconds");
      r.history.push_back(it);
    }
  }
  return r;
}

AlignmentReport read_alignment_report(const std::string& path) {
  const std::string text = text_detail::read_text_file(path);
  return parse_alignment_report(text, path);
}

}  // namespace nurbsreg::io
