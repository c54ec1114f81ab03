#include "nurbsreg/inspect/html_report.hpp"

#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <span>

#include "embedded.hpp"
#include "nurbsreg/inspect/picture.hpp"
#include "nurbsreg/io/atomic_file.hpp"

namespace nurbsreg::inspect {
namespace {

std::string escape(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

void base64(std::string& out, const void* data, std::size_t size) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* p = static_cast<const unsigned char*>(data);
  const std::size_t start = out.size();
  out.resize(start + (size + 2) / 3 * 4);
  char* at = out.data() + start;
  std::size_t i = 0;
  for (; i + 2 < size; i += 3) {
    const std::uint32_t v = p[i] << 16 | p[i + 1] << 8 | p[i + 2];
    *at++ = kAlphabet[v >> 18];
    *at++ = kAlphabet[v >> 12 & 63];
    *at++ = kAlphabet[v >> 6 & 63];
    *at++ = kAlphabet[v & 63];
  }
  if (i < size) {
    const std::uint32_t v = p[i] << 16 | (i + 1 < size ? p[i + 1] << 8 : 0);
    *at++ = kAlphabet[v >> 18];
    *at++ = kAlphabet[v >> 12 & 63];
    *at++ = i + 1 < size ? kAlphabet[v >> 6 & 63] : '=';
    *at++ = '=';
  }
}

template <class T>
void data_block(std::string& out, const char* id, std::span<const T> values) {
  out += fmt::format("<script type=\"application/octet-stream\" id=\"{}\">", id);
  base64(out, values.data(), values.size_bytes());
  out += "</script>\n";
}

// A shown number: rounded text, the exact value beside it (data-value, as in inspect.json).
std::string number(const char* key, double value, const std::string& text) {
  if (!std::isfinite(value))
    return fmt::format("<span data-key=\"{}\" data-value=\"\">–</span>", key);
  return fmt::format("<span data-key=\"{}\" data-value=\"{}\">{}</span>", key, value, text);
}
std::string signed_text(double x) {
  return fmt::format("{:+.4f}", x);
}
std::string percent_text(double f) {
  return fmt::format("{:.2f} %", 100.0 * f);
}

// The fit verdict beside the iteration count: a poor fit is what the reader must not miss.
std::string fit_word(const io::AlignmentReport& a) {
  if (!a.has_fit) return "";
  return a.fit.fit == "good" ? ", fit good"
                             : ", <b class=\"poor\">fit " + escape(a.fit.fit) + "</b>";
}
std::string degenerate_word(const InspectionReport& r) {
  return r.degeneracy.empty() ? "" : ", <b>degenerate</b>";
}

std::string summary(const InspectionReport& r) {
  const DeviationStats& s = r.stats.overall;
  const auto card = [](const std::string& label, const std::string& value,
                       const std::string& note = "") {
    return fmt::format(
        "<div class=\"card\"><div class=\"label\">{}</div><div class=\"value\">{}</div>{}</div>\n",
        label, value, note.empty() ? "" : "<div class=\"note\">" + note + "</div>");
  };
  std::string out = "<section class=\"cards\">\n";
  out += card("Inside tolerance",
              number("inside_tolerance", s.inside_fraction(), percent_text(s.inside_fraction())),
              fmt::format("{} of {} points",
                          number("inside", double(s.inside), fmt::format("{}", s.inside)),
                          number("points", double(s.points), fmt::format("{}", s.points))));
  out += card("Above / below",
              number("above_fraction", s.points ? double(s.above) / double(s.points) : NAN,
                     percent_text(s.points ? double(s.above) / double(s.points) : NAN)) +
                  " / " +
                  number("below_fraction", s.points ? double(s.below) / double(s.points) : NAN,
                         percent_text(s.points ? double(s.below) / double(s.points) : NAN)),
              fmt::format("{} above, {} below",
                          number("above", double(s.above), fmt::format("{}", s.above)),
                          number("below", double(s.below), fmt::format("{}", s.below))));
  out += card("Mean ± std",
              number("mean", s.mean, signed_text(s.mean)) + " ± " +
                  number("std", s.std, fmt::format("{:.4f}", s.std)),
              "rms " + number("rms", s.rms, fmt::format("{:.4f}", s.rms)) + " " + escape(r.units));
  out += card(
      "Min / max",
      number("min", s.min, signed_text(s.min)) + " / " + number("max", s.max, signed_text(s.max)),
      "p5 " + number("p5", s.p5, signed_text(s.p5)) + ", p95 " +
          number("p95", s.p95, signed_text(s.p95)));
  const io::AlignmentReport& a = r.alignment;
  out += card(r.pose_given ? "Pose" : "Alignment",
              r.pose_given ? std::string("given (--pose)")
                           : number("alignment_rms", a.rms, fmt::format("rms {:.4g}", a.rms)),
              r.pose_given ? "no alignment run"
                           : fmt::format("{} iterations, {}{}{}", a.iterations,
                                         a.converged ? "converged" : "not converged", fit_word(a),
                                         degenerate_word(r)));
  out += card("Skipped",
              number("skipped_points", double(r.alignment.skipped_points),
                     fmt::format("{}", r.alignment.skipped_points)),
              fmt::format("NaN/inf points; {} without a foot",
                          number("unprojected_points", double(r.stats.unprojected),
                                 fmt::format("{}", r.stats.unprojected))));
  if (r.stats.exclusion_distance > 0.0) {
    out += card(
        "Excluded",
        number("excluded_points", double(r.stats.excluded), fmt::format("{}", r.stats.excluded)),
        fmt::format("farther than {} {} from the model (--exclude-beyond): not in these "
                    "numbers nor the verdict",
                    number("exclude_beyond", r.stats.exclusion_distance,
                           fmt::format("{:g}", r.stats.exclusion_distance)),
                    escape(r.units)));
  }
  out += "</section>\n";
  return out;
}

std::string histogram_svg(const InspectionReport& r) {
  const Histogram& h = r.stats.histogram;
  const ColourScale& sc = r.scale;
  constexpr double W = 720, H = 290, left = 56, right = 16, top = 26, bottom = 44;
  const double pw = W - left - right, ph = H - top - bottom;
  std::size_t peak = 1;
  for (const std::size_t c : h.counts)
    peak = std::max(peak, c);
  const auto x_of = [&](double d) { return left + pw * (d - h.low) / (h.high - h.low); };
  std::string out = fmt::format(
      "<svg id=\"histogram\" viewBox=\"0 0 {} {}\" role=\"img\" aria-label=\"Histogram of signed "
      "deviations\">\n",
      W, H);
  // The tolerance band behind the bars.
  const double bx0 = x_of(std::max(sc.band.lower, h.low)),
               bx1 = x_of(std::min(sc.band.upper, h.high));
  out +=
      fmt::format("<rect class=\"band\" x=\"{:.2f}\" y=\"{}\" width=\"{:.2f}\" height=\"{}\"/>\n",
                  bx0, top, bx1 - bx0, ph);
  const double bw = pw / static_cast<double>(h.counts.size());
  for (std::size_t k = 0; k < h.counts.size(); ++k) {
    const double d0 = h.low + k * h.bin_width(), d1 = d0 + h.bin_width();
    const double bh = ph * static_cast<double>(h.counts[k]) / static_cast<double>(peak);
    const Rgb c = sc.colour(0.5 * (d0 + d1));
    out += fmt::format(
        "<rect x=\"{:.2f}\" y=\"{:.2f}\" width=\"{:.2f}\" height=\"{:.2f}\" "
        "fill=\"rgb({},{},{})\"><title>[{:+.4g}, {:+.4g}): {} points</title></rect>\n",
        left + k * bw + 0.5, top + ph - bh, std::max(bw - 1.0, 0.5), bh, c.r, c.g, c.b, d0, d1,
        h.counts[k]);
  }
  out += fmt::format("<line class=\"axis\" x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\"/>\n", left,
                     top + ph, left + pw, top + ph);
  out += fmt::format("<line class=\"axis\" x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\"/>\n", left, top,
                     left, top + ph);
  for (const double d : {sc.band.lower, sc.band.upper}) {
    if (d < h.low || d > h.high) continue;
    out +=
        fmt::format("<line class=\"tol\" x1=\"{0:.2f}\" y1=\"{1}\" x2=\"{0:.2f}\" y2=\"{2}\"/>\n",
                    x_of(d), top, top + ph);
  }
  for (int k = 0; k <= 6; ++k) {
    const double d = h.low + (h.high - h.low) * k / 6.0;
    const std::string label =
        std::abs(d) < 1e-9 * (h.high - h.low) ? std::string("0") : fmt::format("{:+.3g}", d);
    out +=
        fmt::format("<text class=\"tick\" x=\"{:.2f}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
                    x_of(d), top + ph + 16, label);
  }
  out += fmt::format("<text class=\"tick\" x=\"{}\" y=\"{}\" text-anchor=\"end\">{}</text>\n",
                     left - 6, top + 10, peak);
  out += fmt::format("<text class=\"tick\" x=\"{}\" y=\"{}\" text-anchor=\"end\">0</text>\n",
                     left - 6, top + ph);
  out += fmt::format(
      "<text class=\"axis-label\" transform=\"translate(14 {}) rotate(-90)\" "
      "text-anchor=\"middle\">points</text>\n",
      top + ph / 2);
  out += fmt::format(
      "<text class=\"axis-label\" x=\"{}\" y=\"{}\" text-anchor=\"middle\">signed deviation ({}); "
      "shaded: tolerance band [{:+g}, {:+g}]</text>\n",
      left + pw / 2, H - 6, escape(r.units), sc.band.lower, sc.band.upper);
  // What lies beyond the histogram's range (drawn in the saturated end colours on the map).
  out += fmt::format(
      "<text class=\"tick\" x=\"{}\" y=\"{}\">◀ {} below {:+g}</text>\n<text class=\"tick\" "
      "x=\"{}\" y=\"{}\" text-anchor=\"end\">{} above {:+g} ▶</text>\n",
      left + 4, top - 10, h.under, h.low, left + pw, top - 10, h.over, h.high);
  out += "</svg>\n";
  return out;
}

std::string cell(double value, const std::string& text) {
  if (!std::isfinite(value)) return "<td data-value=\"\">–</td>";
  return fmt::format("<td data-value=\"{}\">{}</td>", value, text);
}

std::string face_table(const InspectionReport& r) {
  std::string out =
      "<table id=\"faces\"><thead><tr>"
      "<th data-sort=\"num\">Face</th><th data-sort=\"text\">Name</th><th "
      "data-sort=\"num\">Points</th>"
      "<th data-sort=\"num\">Mean</th><th data-sort=\"num\">σ</th><th data-sort=\"num\">Min</th>"
      "<th data-sort=\"num\">Max</th><th data-sort=\"num\">p5</th><th data-sort=\"num\">p95</th>"
      "<th data-sort=\"num\">Inside</th></tr></thead><tbody>\n";
  for (const FaceStats& f : r.stats.faces) {
    const DeviationStats& s = f.stats;
    const Rgb c = r.scale.colour(s.mean);
    out += fmt::format("<tr data-face=\"{}\"{}>", f.face, s.points == 0 ? " class=\"empty\"" : "");
    out += fmt::format("<td data-value=\"{}\">{}</td><td data-value=\"{}\">{}</td>", f.face, f.face,
                       escape(f.name), escape(f.name));
    out += fmt::format("<td data-value=\"{}\">{}</td>", s.points, s.points);
    out += s.points == 0 ? std::string("<td data-value=\"\">–</td>")
                         : fmt::format(
                               "<td data-value=\"{}\"><i class=\"chip\" "
                               "style=\"background:rgb({},{},{})\"></i>{}</td>",
                               s.mean, c.r, c.g, c.b, signed_text(s.mean));
    out += cell(s.std, fmt::format("{:.4f}", s.std)) + cell(s.min, signed_text(s.min)) +
           cell(s.max, signed_text(s.max)) + cell(s.p5, signed_text(s.p5)) +
           cell(s.p95, signed_text(s.p95));
    const double inside = s.inside_fraction();
    out += std::isfinite(inside)
               ? fmt::format("<td data-value=\"{}\" class=\"{}\">{}</td>", inside,
                             inside >= r.min_inside ? "ok" : "bad", percent_text(inside))
               : std::string("<td data-value=\"\">–</td>");
    out += "</tr>\n";
  }
  out += "</tbody></table>\n";
  return out;
}

std::string alignment_section(const InspectionReport& r) {
  const io::AlignmentReport& a = r.alignment;
  std::string out = "<table class=\"pose\">";
  for (int i = 0; i < 4; ++i) {
    out += "<tr>";
    for (int j = 0; j < 4; ++j)
      out += fmt::format("<td data-value=\"{}\">{:.6f}</td>", a.pose(i, j), a.pose(i, j));
    out += "</tr>";
  }
  out += "</table>\n<dl class=\"facts\">";
  const auto fact = [&](const std::string& k, const std::string& v) {
    out += "<dt>" + k + "</dt><dd>" + v + "</dd>";
  };
  if (r.pose_given) {
    fact("pose", "given with --pose (no alignment)");
  } else {
    fact("method", escape(a.method));
    fact("rms of inliers", fmt::format("{:.6g} {}", a.rms, escape(r.units)));
    fact("inliers", fmt::format("{} of {}", a.inliers, r.scan_points));
    fact("iterations", fmt::format("{}", a.iterations));
    fact("termination", escape(a.termination));
    if (a.has_fit) {
      const io::FitRecord& f = a.fit;
      // The verdict's noise is the smaller of the scan's own estimate and the distances' at the
      // pose (registration::FitVerdict): when the distances tightened it, both are named.
      const std::string noise =
          f.noise < f.scan_noise
              ? fmt::format("noise {:.4g} of the distances; the scan's own estimate {:.4g}",
                            f.noise, f.scan_noise)
              : fmt::format("estimated noise {:.4g}", f.noise);
      fact("fit", fmt::format("<span data-key=\"fit\">{}</span>: {:.1f} % of the points within "
                              "{:.4g} {} ({}), rms {:.4g}, model coverage {:.1f} %{}",
                              escape(f.fit), 100.0 * f.inlier_fraction, f.tolerance,
                              escape(r.units), noise, f.rms, 100.0 * f.coverage,
                              f.reason.empty() ? "" : " &mdash; " + escape(f.reason)));
    }
    if (a.has_coarse) {
      const io::CoarseRecord& c = a.coarse;
      fact("coarse stage",
           fmt::format("{}: {} hypotheses verified in {:.2f} s; winner {:.1f} % inliers{}",
                       escape(c.method), c.verified, c.seconds, 100.0 * c.winner.inlier_fraction,
                       c.has_runner_up ? fmt::format(", runner-up {:.1f} %",
                                                     100.0 * c.runner_up.inlier_fraction)
                                       : std::string()));
      if (!c.symmetry.empty())
        fact("symmetry", "<b>" + escape(c.symmetry) + "</b> (" +
                             fmt::format("{}", c.alternatives.size()) +
                             " other pose(s) fit as well; inspect.json lists them)");
    }
  }
  fact("degeneracy", r.degeneracy.empty() ? "none: the scan constrains all six degrees of freedom"
                                          : "<b>free directions: " + escape(r.degeneracy) + "</b>");
  fact("times", fmt::format("alignment {:.2f} s, inspection {:.2f} s", r.alignment_seconds,
                            r.inspection_seconds));
  out += "</dl>\n";
  return out;
}

}  // namespace

std::string html_report(const InspectionReport& r, const PointDeviations& dev,
                        const ViewerSubset& subset, const DisplayMesh& mesh) {
  const std::string json = inspection_json(r);
  const std::string title = fmt::format("Inspection: {} against {}", r.scan_file, r.model_file);
  const ColourScale& sc = r.scale;
  std::string out;
  out.reserve(subset.indices.size() * 32 + mesh.positions.size() * 6 +
              embedded::three_module_js().size() * 2);
  out += "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n";
  out += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  out += "<meta name=\"generator\" content=\"nurbsreg inspect\">\n";
  out += "<title>" + escape(title) + "</title>\n<style>\n";
  out += embedded::report_css();
  out += "</style>\n";
  // First of all scripts: every error on the page lands in the self-check element.
  out +=
      "<script>window.__errors=[];addEventListener('error',e=>__errors.push(String(e.message||e)));"
      "addEventListener('unhandledrejection',e=>__errors.push(String(e.reason)));</script>\n";
  out += "</head><body>\n<header>\n";
  out +=
      fmt::format("<div class=\"verdict {0}\" data-key=\"verdict\" data-value=\"{0}\">{1}</div>\n",
                  r.passed() ? "pass" : "fail", r.passed() ? "PASS" : "FAIL");
  out += "<div class=\"titles\"><h1>" + escape(r.scan_file) + "</h1>\n";
  out += fmt::format(
      "<p>against <b>{}</b> · tolerance <b>[{}, {}] {}</b> · pass when at least {} of the points "
      "lie inside</p></div>\n",
      escape(r.model_file),
      number("tolerance_lower", sc.band.lower, fmt::format("{:+g}", sc.band.lower)),
      number("tolerance_upper", sc.band.upper, fmt::format("{:+g}", sc.band.upper)),
      escape(r.units), number("min_inside", r.min_inside, percent_text(r.min_inside)));
  out += "</header>\n<main>\n";
  // A poor fit accepted with --accept-poor: the deviations are measured in a pose nobody can
  // stand behind, so the page says so before any number.
  if (const io::AlignmentReport& a = r.alignment; a.has_fit && a.fit.fit != "good")
    out += "<section class=\"warning\" data-key=\"fit_warning\"><b>Alignment: " +
           escape(a.fit.reason.empty() ? a.fit.fit + " fit" : a.fit.reason) +
           "</b>. The deviations below are measured in that pose (accepted with "
           "--accept-poor).</section>\n";
  out += summary(r);
  out +=
      "<section class=\"view\">\n<div id=\"viewer\"><canvas id=\"canvas\"></canvas>"
      "<div id=\"tooltip\" hidden></div><div id=\"legend\"></div>"
      "<div id=\"view-note\"></div></div>\n";
  out +=
      "<div class=\"controls\"><label><input type=\"checkbox\" id=\"show-model\" checked> model "
      "faces (grey)</label>"
      "<label>point size <input type=\"range\" id=\"point-size\" min=\"1\" max=\"8\" "
      "step=\"0.5\"></label>"
      "<button id=\"reset-view\">reset view</button><button id=\"clear-face\" hidden>show all "
      "faces</button>"
      "<span class=\"hint\">drag: orbit · right-drag or shift: pan · wheel: zoom · hover: a "
      "point's deviation · click a table row: that face</span></div>\n";
  out += fmt::format(
      "<p class=\"subset\" id=\"subset-note\">The view shows <b>{}</b> of the {} points ({}); "
      "every number on this page uses all {} points.</p>\n",
      number("viewer_points", double(subset.indices.size()),
             fmt::format("{}", subset.indices.size())),
      dev.size(), escape(r.viewer_subset), dev.size());
  out += "</section>\n";
  out += "<section class=\"two\"><div><h2>Histogram of signed deviations</h2>\n" +
         histogram_svg(r) + "</div>\n";
  out += "<div><h2>Alignment</h2>\n" + alignment_section(r) + "</div></section>\n";
  out +=
      "<section><h2>Faces</h2><p class=\"hint\">Worst first (share inside the tolerance); click a "
      "column to sort, a row to show that face alone in the view.</p>\n<div class=\"table-box\">";
  out += face_table(r) + "</div></section>\n";
  out += fmt::format(
      "<footer>Signed distance from the exact closest point on the model (positive on the face's "
      "outer side). "
      "Inside: lower ≤ d ≤ upper. σ: sample standard deviation; p5/p95: linear between order "
      "statistics. "
      "Colour scale {}: band colour inside the tolerance, graded to the limits [{:+g}, {:+g}], "
      "saturated beyond. "
      "Picture (deviations.png): {}. Written by nurbsreg inspect.</footer>\n",
      to_string(sc.scheme), sc.lower_limit, sc.upper_limit, escape(r.picture_view));
  out += "<div id=\"selfcheck\" hidden data-status=\"pending\"></div>\n</main>\n";

  // The data of the view: the subset's points, colours, deviations and faces; the model mesh.
  std::vector<float> positions(subset.indices.size() * 3), deviation(subset.indices.size());
  std::vector<std::uint8_t> colours(subset.indices.size() * 3);
  std::vector<std::int32_t> faces(subset.indices.size());
  for (std::size_t k = 0; k < subset.indices.size(); ++k) {
    const std::uint32_t i = subset.indices[k];
    for (int c = 0; c < 3; ++c)
      positions[3 * k + c] = static_cast<float>(dev.points[i][c]);
    const Rgb rgb = sc.colour(dev.signed_distance[i]);
    colours[3 * k] = rgb.r;
    colours[3 * k + 1] = rgb.g;
    colours[3 * k + 2] = rgb.b;
    deviation[k] = static_cast<float>(dev.signed_distance[i]);
    faces[k] = dev.face[i];
  }
  std::string script_json;
  script_json.reserve(json.size());
  for (std::size_t i = 0; i < json.size(); ++i) {
    // "</" would end the script element early.
    if (json[i] == '<' && i + 1 < json.size() && json[i + 1] == '/') {
      script_json += "<\\/";
      ++i;
    } else {
      script_json += json[i];
    }
  }
  out += "<script type=\"application/json\" id=\"report-data\">" + script_json + "</script>\n";
  const ViewDirection view = isometric_view();
  out += fmt::format(
      "<script type=\"application/json\" id=\"view-data\">{{\"eye\":[{},{},{}],\"up\":[{},{},{}],"
      "\"view\":\"{}\",\"band\":[{},{}],\"limits\":[{},{}],\"scheme\":\"{}\",\"units\":\"{}\","
      "\"band_colour\":[{},{},{}]}}</script>\n",
      view.eye.x(), view.eye.y(), view.eye.z(), view.up.x(), view.up.y(), view.up.z(),
      view.description, sc.band.lower, sc.band.upper, sc.lower_limit, sc.upper_limit,
      to_string(sc.scheme), escape(r.units), sc.band_colour().r, sc.band_colour().g,
      sc.band_colour().b);
  // The legend's ramp, sampled by the C++ colour map itself (the page never recomputes colours).
  std::vector<std::uint8_t> ramp(3 * 256);
  for (int k = 0; k < 256; ++k) {
    const Rgb c = sc.colour(sc.lower_limit + (sc.upper_limit - sc.lower_limit) * k / 255.0);
    ramp[3 * k] = c.r;
    ramp[3 * k + 1] = c.g;
    ramp[3 * k + 2] = c.b;
  }
  data_block<std::uint8_t>(out, "legend-ramp", ramp);
  data_block<float>(out, "points-position", positions);
  data_block<std::uint8_t>(out, "points-colour", colours);
  data_block<float>(out, "points-deviation", deviation);
  data_block<std::int32_t>(out, "points-face", faces);
  data_block<float>(out, "mesh-position", mesh.positions);
  data_block<std::uint32_t>(out, "mesh-index", mesh.triangles);
  const std::string_view three = embedded::three_module_js();
  data_block<char>(out, "three-module", std::span<const char>(three.data(), three.size()));
  out += "<script type=\"module\">\n";
  out += embedded::viewer_js();
  out += "</script>\n</body></html>\n";
  return out;
}

void write_html_report(const std::string& path, const InspectionReport& report,
                       const PointDeviations& deviations, const ViewerSubset& subset,
                       const DisplayMesh& mesh) {
  const std::string page = html_report(report, deviations, subset, mesh);
  io::write_atomically(path, [&](std::ostream& out) {
    out.write(page.data(), static_cast<std::streamsize>(page.size()));
  });
}

}  // namespace nurbsreg::inspect
