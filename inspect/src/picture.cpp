#include "nurbsreg/inspect/picture.hpp"

#include <cairo.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"

namespace nurbsreg::inspect {
namespace {

using engine::Vec3;

constexpr int kLegendWidth = 380;
constexpr float kFar = std::numeric_limits<float>::infinity();
constexpr std::uint32_t kBackground = 0xffffff;

// Orthographic camera: screen x right, y down, depth increasing away from the eye.
struct Camera {
  Vec3 right, up, forward;
  double scale = 1.0;  // pixels per model unit
  double cx = 0, cy = 0;
  Vec3 centre;
  double x(const Vec3& p) const { return cx + scale * right.dot(p - centre); }
  double y(const Vec3& p) const { return cy - scale * up.dot(p - centre); }
  double depth(const Vec3& p) const { return forward.dot(p - centre); }
};

Camera fit_camera(const PointDeviations& dev, const DisplayMesh& mesh, const ViewDirection& view,
                  int plot_width, int height) {
  Camera cam;
  cam.forward = -view.eye;
  cam.up = view.up;
  cam.right = cam.forward.cross(cam.up).normalized();
  // Frame the scan (the model may be much larger than a partial scan); the model only when
  // there is no scan point.
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  const auto grow = [&](const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  };
  for (const Vec3& p : dev.points)
    grow(p);
  if (dev.points.empty()) {
    for (std::size_t k = 0; k < mesh.vertex_count(); ++k)
      grow(Vec3(mesh.positions[3 * k], mesh.positions[3 * k + 1], mesh.positions[3 * k + 2]));
  }
  if (!(lo.array() <= hi.array()).all()) lo = hi = Vec3::Zero();
  cam.centre = 0.5 * (lo + hi);
  double half_w = 1e-9, half_h = 1e-9;
  for (int c = 0; c < 8; ++c) {
    const Vec3 corner((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(),
                      (c & 4) ? hi.z() : lo.z());
    half_w = std::max(half_w, std::abs(cam.right.dot(corner - cam.centre)));
    half_h = std::max(half_h, std::abs(cam.up.dot(corner - cam.centre)));
  }
  const double margin = 0.9;
  cam.scale = margin * std::min(0.5 * plot_width / half_w, 0.5 * (height - 60) / half_h);
  cam.cx = 0.5 * plot_width;
  cam.cy = 0.5 * height + 20;
  return cam;
}

struct Frame {
  int width, height;
  std::vector<std::uint32_t> rgb;  // 0x00RRGGBB (cairo RGB24)
  std::vector<float> depth;
  std::vector<float> shade;  // Lambert factor of the model surface under each pixel, or 0
  std::vector<float> mesh_depth;
};

std::uint32_t pack(double r, double g, double b) {
  const auto c = [](double x) { return static_cast<std::uint32_t>(std::clamp(x, 0.0, 255.0)); };
  return c(r) << 16 | c(g) << 8 | c(b);
}

// The model in grey, flat-shaded per triangle (light from the eye, both sides lit).
void draw_mesh(Frame& f, const DisplayMesh& mesh, const Camera& cam) {
  const auto vertex = [&](std::uint32_t k) {
    return Vec3(mesh.positions[3 * k], mesh.positions[3 * k + 1], mesh.positions[3 * k + 2]);
  };
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 a = vertex(mesh.triangles[3 * t]), b = vertex(mesh.triangles[3 * t + 1]),
               c = vertex(mesh.triangles[3 * t + 2]);
    const Vec3 n = (b - a).cross(c - a);
    if (n.squaredNorm() == 0.0) continue;
    const float lambert = static_cast<float>(std::abs(n.normalized().dot(cam.forward)));
    const float shade = 0.35f + 0.65f * lambert;
    const double ax = cam.x(a), ay = cam.y(a), bx = cam.x(b), by = cam.y(b), qx = cam.x(c),
                 qy = cam.y(c);
    const double az = cam.depth(a), bz = cam.depth(b), cz = cam.depth(c);
    const double area = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax);
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({ax, bx, qx}))));
    const int x1 = std::min(f.width - 1, static_cast<int>(std::ceil(std::max({ax, bx, qx}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({ay, by, qy}))));
    const int y1 = std::min(f.height - 1, static_cast<int>(std::ceil(std::max({ay, by, qy}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        const double w0 = ((bx - px) * (qy - py) - (by - py) * (qx - px)) / area;
        const double w1 = ((qx - px) * (ay - py) - (qy - py) * (ax - px)) / area;
        const double w2 = 1.0 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const auto z = static_cast<float>(w0 * az + w1 * bz + w2 * cz);
        const std::size_t at = static_cast<std::size_t>(y) * f.width + x;
        if (z >= f.depth[at]) continue;
        f.depth[at] = z;
        f.mesh_depth[at] = z;
        f.shade[at] = shade;
        const double g = 110.0 + 95.0 * shade;
        f.rgb[at] = pack(g, g, g + 4.0);
      }
    }
  }
}

// Square splats of `size` pixels, coloured by the map and shaded like the model under them.
void draw_points(Frame& f, const PointDeviations& dev, const ColourScale& scale, const Camera& cam,
                 int size, float bias) {
  const int lo = -(size - 1) / 2, hi = size / 2;
  for (std::size_t i = 0; i < dev.size(); ++i) {
    const Vec3& p = dev.points[i];
    const int px = static_cast<int>(std::floor(cam.x(p))),
              py = static_cast<int>(std::floor(cam.y(p)));
    const float z = static_cast<float>(cam.depth(p)) - bias;
    const Rgb c = scale.colour(dev.signed_distance[i]);
    for (int y = py + lo; y <= py + hi; ++y) {
      if (y < 0 || y >= f.height) continue;
      for (int x = px + lo; x <= px + hi; ++x) {
        if (x < 0 || x >= f.width) continue;
        const std::size_t at = static_cast<std::size_t>(y) * f.width + x;
        if (z >= f.depth[at]) continue;
        f.depth[at] = z;
        // Points on a face take its shading; points in front of or off the model a fixed one.
        const float s = (f.shade[at] > 0 && std::abs(f.mesh_depth[at] - z) < 4 * bias)
                            ? 0.55f + 0.45f * f.shade[at]
                            : 0.9f;
        f.rgb[at] = pack(c.r * s, c.g * s, c.b * s);
      }
    }
  }
}

// Splat size: about the spacing of the points on the screen (pixels of the model's silhouette
// per front-facing point), so a sparse scan still reads as a surface.
int splat_size(const Frame& f, std::size_t points) {
  std::size_t covered = 0;
  for (const float s : f.shade)
    covered += s > 0;
  if (points == 0 || covered == 0) return 2;
  const double spacing =
      std::sqrt(static_cast<double>(covered) / (0.5 * static_cast<double>(points)));
  return std::clamp(static_cast<int>(std::ceil(1.5 * spacing)), 1, 6);
}

void set_rgb(cairo_t* cr, const Rgb& c) {
  cairo_set_source_rgb(cr, c.r / 255.0, c.g / 255.0, c.b / 255.0);
}

void text(cairo_t* cr, double x, double y, const std::string& s, double size, bool bold = false) {
  cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL,
                         bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
  cairo_move_to(cr, x, y);
  cairo_show_text(cr, s.c_str());
}

std::string percent(double fraction) {
  return std::isfinite(fraction) ? fmt::format("{:.2f} %", 100.0 * fraction) : "-";
}

void draw_legend(cairo_t* cr, const InspectionReport& r, int x0, int height) {
  const ColourScale& sc = r.scale;
  const DeviationStats& s = r.stats.overall;
  cairo_set_source_rgb(cr, 0.97, 0.97, 0.98);
  cairo_rectangle(cr, x0, 0, kLegendWidth, height);
  cairo_fill(cr);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
  double y = 48;
  text(cr, x0 + 24, y, fmt::format("Signed deviation ({})", r.units), 20, true);
  y += 24;
  cairo_set_source_rgb(cr, 0.35, 0.35, 0.4);
  text(cr, x0 + 24, y,
       fmt::format("scale {}, saturated beyond [{:g}, {:g}]", to_string(sc.scheme), sc.lower_limit,
                   sc.upper_limit),
       12.5);
  // The bar: value linear from lower_limit (bottom) to upper_limit (top), with saturated end
  // boxes for what lies beyond.
  const double bar_x = x0 + 28, bar_w = 34, top = y + 34, bar_h = 420, box = 20, gap = 12;
  const double bar_top = top + box + gap;
  const auto value_y = [&](double d) {
    return bar_top + bar_h * (sc.upper_limit - d) / (sc.upper_limit - sc.lower_limit);
  };
  set_rgb(cr, sc.colour(sc.upper_limit));
  cairo_rectangle(cr, bar_x, top, bar_w, box);
  cairo_fill(cr);
  set_rgb(cr, sc.colour(sc.lower_limit));
  cairo_rectangle(cr, bar_x, bar_top + bar_h + gap, bar_w, box);
  cairo_fill(cr);
  for (int k = 0; k < static_cast<int>(bar_h); ++k) {
    const double d = sc.upper_limit - (k + 0.5) / bar_h * (sc.upper_limit - sc.lower_limit);
    set_rgb(cr, sc.colour(d));
    cairo_rectangle(cr, bar_x, bar_top + k, bar_w, 1.0);
    cairo_fill(cr);
  }
  cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
  cairo_set_line_width(cr, 1.0);
  cairo_rectangle(cr, bar_x + 0.5, bar_top + 0.5, bar_w - 1, bar_h - 1);
  cairo_stroke(cr);
  const auto tick = [&](double d, const std::string& label, bool bold) {
    const double ty = value_y(d);
    cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
    cairo_move_to(cr, bar_x + bar_w, ty);
    cairo_line_to(cr, bar_x + bar_w + 8, ty);
    cairo_stroke(cr);
    text(cr, bar_x + bar_w + 12, ty + 4.5, label, 13, bold);
  };
  text(cr, bar_x + bar_w + 12, top + box / 2 + 4.5, fmt::format("> {:+g}", sc.upper_limit), 13);
  text(cr, bar_x + bar_w + 12, bar_top + bar_h + gap + box / 2 + 4.5,
       fmt::format("< {:+g}", sc.lower_limit), 13);
  tick(sc.upper_limit, fmt::format("{:+g}", sc.upper_limit), false);
  tick(sc.lower_limit, fmt::format("{:+g}", sc.lower_limit), false);
  tick(sc.band.upper, fmt::format("{:+g}  upper tolerance", sc.band.upper), true);
  tick(sc.band.lower, fmt::format("{:+g}  lower tolerance", sc.band.lower), true);
  const double mid_hi = 0.5 * (sc.band.upper + sc.upper_limit),
               mid_lo = 0.5 * (sc.band.lower + sc.lower_limit);
  tick(mid_hi, fmt::format("{:+.3g}", mid_hi), false);
  tick(mid_lo, fmt::format("{:+.3g}", mid_lo), false);
  if (sc.band.lower < 0 && sc.band.upper > 0 &&
      value_y(sc.band.lower) - value_y(sc.band.upper) > 40)
    tick(0.0, "0", false);

  y = bar_top + bar_h + gap + box + 46;
  const double lx = x0 + 24;
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
  text(cr, lx, y, r.passed() ? "PASS" : "FAIL", 22, true);
  cairo_set_source_rgb(cr, 0.35, 0.35, 0.4);
  text(cr, lx + 80, y, fmt::format("(pass: >= {} inside)", percent(r.min_inside)), 13);
  y += 28;
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
  const std::vector<std::string> lines = {
      fmt::format("inside tolerance   {}", percent(s.inside_fraction())),
      fmt::format("above / below      {} / {}",
                  percent(s.points ? double(s.above) / double(s.points) : NAN),
                  percent(s.points ? double(s.below) / double(s.points) : NAN)),
      fmt::format("points             {}", s.points),
      fmt::format("mean / std         {:+.4f} / {:.4f}", s.mean, s.std),
      fmt::format("min / max          {:+.4f} / {:+.4f}", s.min, s.max),
      fmt::format("p5 / p95           {:+.4f} / {:+.4f}", s.p5, s.p95),
  };
  std::vector<std::string> all = lines;
  // Clutter left out on request is part of what the verdict stands on: say it on the picture.
  if (r.stats.exclusion_distance > 0.0) {
    all.push_back(
        fmt::format("excluded (|d| > {:g})  {}", r.stats.exclusion_distance, r.stats.excluded));
  }
  for (const std::string& line : all) {
    cairo_select_font_face(cr, "DejaVu Sans Mono", CAIRO_FONT_SLANT_NORMAL,
                           CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, 13.5);
    cairo_move_to(cr, lx, y);
    cairo_show_text(cr, line.c_str());
    y += 21;
  }
}

// A small axis triad in the corner: which way X, Y and Z point in this view.
void draw_triad(cairo_t* cr, const Camera& cam, double ox, double oy) {
  const Vec3 axes[3] = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  const char* names[3] = {"X", "Y", "Z"};
  const double colours[3][3] = {{0.8, 0.1, 0.1}, {0.1, 0.6, 0.1}, {0.1, 0.2, 0.85}};
  cairo_set_line_width(cr, 2.0);
  for (int k = 0; k < 3; ++k) {
    const double dx = 34 * cam.right.dot(axes[k]), dy = -34 * cam.up.dot(axes[k]);
    cairo_set_source_rgb(cr, colours[k][0], colours[k][1], colours[k][2]);
    cairo_move_to(cr, ox, oy);
    cairo_line_to(cr, ox + dx, oy + dy);
    cairo_stroke(cr);
    text(cr, ox + 1.25 * dx - 4, oy + 1.25 * dy + 5, names[k], 13, true);
  }
}

cairo_status_t write_to_stream(void* closure, const unsigned char* data, unsigned int length) {
  auto* out = static_cast<std::ostream*>(closure);
  out->write(reinterpret_cast<const char*>(data), length);
  return out->good() ? CAIRO_STATUS_SUCCESS : CAIRO_STATUS_WRITE_ERROR;
}

}  // namespace

ViewDirection isometric_view() {
  ViewDirection v;
  v.eye = Vec3(1, -1, 1).normalized();
  v.up = (Vec3::UnitZ() - v.eye.z() * v.eye).normalized();
  v.description = "orthographic, from the +X -Y +Z octant (isometric), +Z up";
  return v;
}

void write_deviation_picture(const std::string& path, const PointDeviations& dev,
                             const DisplayMesh& mesh, const InspectionReport& report,
                             const PictureOptions& options) {
  const int width = options.width, height = options.height;
  const int plot_width = width - kLegendWidth;
  cairo_format_t format = CAIRO_FORMAT_RGB24;
  const int stride = cairo_format_stride_for_width(format, width);
  if (stride != width * 4) throw io::OutputError(path, "unexpected image stride");
  Frame f{width,
          height,
          std::vector<std::uint32_t>(std::size_t(width) * height, kBackground),
          std::vector<float>(std::size_t(width) * height, kFar),
          std::vector<float>(std::size_t(width) * height, 0.0f),
          std::vector<float>(std::size_t(width) * height, kFar)};
  const Camera cam = fit_camera(dev, mesh, isometric_view(), plot_width, height);
  draw_mesh(f, mesh, cam);
  // Points lie on the faces up to their deviation and the mesh's chord error: pull them a
  // little towards the eye so the mesh does not hide the ones just behind it.
  const float bias = static_cast<float>(3.0 / cam.scale);
  draw_points(f, dev, report.scale, cam, splat_size(f, dev.size()), bias);
  // The legend covers the right side; the rasteriser drew the plot area only.
  cairo_surface_t* surface = cairo_image_surface_create_for_data(
      reinterpret_cast<unsigned char*>(f.rgb.data()), format, width, height, stride);
  cairo_t* cr = cairo_create(surface);
  draw_legend(cr, report, plot_width, height);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
  text(cr, 24, 36, fmt::format("Deviation map: {}", report.scan_file), 20, true);
  cairo_set_source_rgb(cr, 0.35, 0.35, 0.4);
  text(cr, 24, 60,
       fmt::format("model {}   tolerance [{:+g}, {:+g}] {}", report.model_file,
                   report.stats.tolerance.lower, report.stats.tolerance.upper, report.units),
       13.5);
  text(cr, 24, height - 18, "view: " + isometric_view().description + "; grey: model faces", 12.5);
  draw_triad(cr, cam, plot_width - 70, height - 70);
  cairo_destroy(cr);
  cairo_surface_flush(surface);
  // The surface borrows f.rgb; it is destroyed on every path before f goes.
  const std::unique_ptr<cairo_surface_t, void (*)(cairo_surface_t*)> owner(surface,
                                                                           cairo_surface_destroy);
  io::write_atomically(path, [&](std::ostream& out) {
    const cairo_status_t status = cairo_surface_write_to_png_stream(surface, write_to_stream, &out);
    if (status != CAIRO_STATUS_SUCCESS) {
      throw io::OutputError(path, std::string("PNG: ") + cairo_status_to_string(status));
    }
  });
}

}  // namespace nurbsreg::inspect
