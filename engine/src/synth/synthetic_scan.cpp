#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "synth/random_streams.hpp"

namespace nurbsreg::engine {
namespace {

// A rectangle of the fixture's plane: origin + a span_a + b span_b for a, b in [0, 1].
struct FixturePlane {
  Vec3 origin = Vec3::Zero();
  Vec3 span_a = Vec3::Zero();
  Vec3 span_b = Vec3::Zero();
  Vec3 up = Vec3::UnitZ();
};

// The plane touches the samples' lowest point along `up`; across it, their extent plus half of
// it on every side.
FixturePlane fixture_plane(const std::vector<SurfaceSample>& samples, const Vec3& up_direction) {
  FixturePlane plane;
  plane.up = up_direction.normalized();
  const Vec3 a = plane.up.unitOrthogonal();
  const Vec3 b = plane.up.cross(a);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double lo_a = kInf, hi_a = -kInf, lo_b = kInf, hi_b = -kInf, lowest = kInf;
  for (const SurfaceSample& s : samples) {
    lo_a = std::min(lo_a, s.point.dot(a));
    hi_a = std::max(hi_a, s.point.dot(a));
    lo_b = std::min(lo_b, s.point.dot(b));
    hi_b = std::max(hi_b, s.point.dot(b));
    lowest = std::min(lowest, s.point.dot(plane.up));
  }
  const double grow_a = 0.5 * (hi_a - lo_a), grow_b = 0.5 * (hi_b - lo_b);
  plane.origin = (lo_a - grow_a) * a + (lo_b - grow_b) * b + lowest * plane.up;
  plane.span_a = (hi_a - lo_a + 2.0 * grow_a) * a;
  plane.span_b = (hi_b - lo_b + 2.0 * grow_b) * b;
  return plane;
}

}  // namespace

std::optional<std::string> SyntheticScanOptions::validate() const {
  if (points == 0) return std::string("points: must be at least 1");
  if (!(noise_sigma >= 0.0) || !std::isfinite(noise_sigma)) {
    return std::string("noise: must be a finite number >= 0");
  }
  if (!(outlier_fraction >= 0.0 && outlier_fraction <= 1.0)) {
    return std::string("outliers: must be a fraction in [0, 1]");
  }
  if (!(fixture_fraction >= 0.0 && fixture_fraction <= 1.0)) {
    return std::string("fixture: must be a fraction in [0, 1]");
  }
  if (!(outlier_fraction + fixture_fraction <= 1.0)) {
    return std::string("outliers and fixture: together at most all the points");
  }
  if (!fixture_up.allFinite() || fixture_up.norm() == 0.0) {
    return std::string("fixture up direction: must be a non-zero finite vector");
  }
  if (!(view_fraction > 0.0 && view_fraction <= 1.0)) {
    return std::string("view fraction: must be in (0, 1]");
  }
  if (!view_direction.allFinite() || view_direction.norm() == 0.0) {
    return std::string("view direction: must be a non-zero finite vector");
  }
  return std::nullopt;
}

Eigen::Isometry3d pose_from_euler_degrees(double rx, double ry, double rz, const Vec3& t) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() =
      (Eigen::AngleAxisd(rz * kDeg, Vec3::UnitZ()) * Eigen::AngleAxisd(ry * kDeg, Vec3::UnitY()) *
       Eigen::AngleAxisd(rx * kDeg, Vec3::UnitX()))
          .toRotationMatrix();
  pose.translation() = t;
  return pose;
}

SyntheticScan make_synthetic_scan(const Model& model, const SyntheticScanOptions& options) {
  // Sample more than needed when only part of the model is in view, then keep the visible part.
  const auto wanted = options.points;
  const auto drawn = static_cast<std::size_t>(std::ceil(wanted / options.view_fraction));
  std::vector<SurfaceSample> samples = sample_surfaces(model, drawn, options.seed);
  if (options.view_fraction < 1.0) {
    const Vec3 dir = options.view_direction.normalized();
    std::vector<std::size_t> order(samples.size());
    std::iota(order.begin(), order.end(), 0);
    // Farthest along the view first, ties in sampling order: a stable sort's order, without
    // its temporary buffer (whose release clang's ASan build reports as a new/free mismatch,
    // libstdc++'s inline code against the sanitizer's allocator).
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const double da = samples[a].point.dot(dir), db = samples[b].point.dot(dir);
      return da > db || (da == db && a < b);
    });
    order.resize(std::min(wanted, order.size()));
    std::sort(order.begin(), order.end());  // keep the sampler's order: deterministic
    std::vector<SurfaceSample> kept;
    kept.reserve(order.size());
    for (std::size_t i : order)
      kept.push_back(samples[i]);
    samples = std::move(kept);
  }
  // The scan's box: the visible samples' (clutter fills the space around what the scanner sees).
  Aabb box;
  for (const SurfaceSample& sample : samples)
    box.extend(sample.point);
  std::mt19937_64 rng(options.seed ^ 0x9e3779b97f4a7c15ull);
  auto unit = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };

  SyntheticScan scan;
  scan.T_model_scan = options.T_scan_model.inverse();
  const std::size_t n = samples.size();
  scan.points.resize(n);
  scan.on_model.assign(n, true);
  scan.surface.resize(n);
  scan.uv.resize(n);
  const auto outliers = static_cast<std::size_t>(std::llround(options.outlier_fraction * n));
  // Noise in fixed chunks, each from its own stream: the same scan for any number of threads.
  const std::size_t chunks = (n + kSampleChunk - 1) / kSampleChunk;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const auto& range) {
    for (std::size_t chunk = range.begin(); chunk != range.end(); ++chunk) {
      std::mt19937_64 noise_rng(chunk_seed(options.seed ^ 0x6a09e667f3bcc909ull, chunk));
      std::normal_distribution<double> gauss(0.0, 1.0);
      const std::size_t end = std::min(n, (chunk + 1) * kSampleChunk);
      for (std::size_t i = chunk * kSampleChunk; i < end; ++i) {
        const SurfaceSample& s = samples[i];
        Vec3 p = s.point;
        if (options.noise_sigma > 0.0) p += options.noise_sigma * gauss(noise_rng) * s.normal;
        scan.points[i] = options.T_scan_model * p;
        scan.surface[i] = s.surface;
        scan.uv[i] = Vec2(s.u, s.v);
      }
    }
  });
  nurbsreg::engine::stop_if_cancelled();
  // Outliers and the fixture replace evenly spaced samples, so they are spread over the scan
  // order; the fixture's share of those places is spread evenly among them.
  const auto fixture = static_cast<std::size_t>(std::llround(options.fixture_fraction * n));
  const std::size_t replaced = std::min(n, outliers + fixture);
  const FixturePlane plane =
      fixture > 0 ? fixture_plane(samples, options.fixture_up) : FixturePlane{};
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (std::size_t k = 0; k < replaced; ++k) {
    const std::size_t i = k * n / replaced;
    const bool on_fixture = (k + 1) * fixture / replaced > k * fixture / replaced;
    Vec3 q;
    if (on_fixture) {
      q = plane.origin + unit() * plane.span_a + unit() * plane.span_b;
      if (options.noise_sigma > 0.0) q += options.noise_sigma * gauss(rng) * plane.up;
    } else {
      q = Vec3(box.lo.x() + unit() * (box.hi.x() - box.lo.x()),
               box.lo.y() + unit() * (box.hi.y() - box.lo.y()),
               box.lo.z() + unit() * (box.hi.z() - box.lo.z()));
    }
    scan.points[i] = options.T_scan_model * q;
    scan.on_model[i] = false;
    scan.surface[i] = -1;
  }
  return scan;
}

}  // namespace nurbsreg::engine
