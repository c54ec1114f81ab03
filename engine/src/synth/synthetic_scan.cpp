#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "nurbsreg/engine/bounds.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "synth/random_streams.hpp"

namespace nurbsreg::engine {

std::optional<std::string> SyntheticScanOptions::validate() const {
  if (points == 0) return std::string("points: must be at least 1");
  if (!(noise_sigma >= 0.0) || !std::isfinite(noise_sigma)) {
    return std::string("noise: must be a finite number >= 0");
  }
  if (!(outlier_fraction >= 0.0 && outlier_fraction <= 1.0)) {
    return std::string("outliers: must be a fraction in [0, 1]");
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
  Aabb box;
  for (const NurbsSurface& s : model.surfaces) {
    for (const Vec3& p : s.control_points)
      box.extend(p);
  }
  const Vec3 margin = Vec3::Constant(0.1 * box.diagonal());
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
  // Outliers replace evenly spaced samples so they are spread over the scan order.
  for (std::size_t k = 0; k < outliers; ++k) {
    const std::size_t i = k * n / outliers;
    const Vec3 lo = box.lo - margin;
    const Vec3 hi = box.hi + margin;
    const Vec3 q(lo.x() + unit() * (hi.x() - lo.x()), lo.y() + unit() * (hi.y() - lo.y()),
                 lo.z() + unit() * (hi.z() - lo.z()));
    scan.points[i] = options.T_scan_model * q;
    scan.on_model[i] = false;
    scan.surface[i] = -1;
  }
  return scan;
}

}  // namespace nurbsreg::engine
