#include "features.hpp"
#include "nurbsreg/engine/cancellation.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

namespace nurbsreg::registration::detail {
namespace {

using engine::Vec3;

struct Moments3 {
  Vec3 sum = Vec3::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  int count = 0;
  void add(const Vec3& p) {
    sum += p;
    outer.noalias() += p * p.transpose();
    ++count;
  }
  // Covariance about the mean; points are taken relative to the query point, so the sums stay
  // small and the subtraction loses no digits.
  Eigen::Matrix3d covariance() const {
    const Vec3 mean = sum / count;
    return outer / count - mean * mean.transpose();
  }
};

// Adds one pair's value to block `block` of h: x in [0, 1] is the angle (as a fraction of a
// right angle) on a square-root scale, which spreads the small angles of smooth surfaces over
// several bins instead of one; soft (linear) binning, so that a value near a bin edge does not
// jump between two descriptors.
void add_to_bins(float* h, int block, double angle_fraction) {
  const double x = std::sqrt(std::clamp(angle_fraction, 0.0, 1.0)) * kBinsPerFeature - 0.5;
  // x lies in [-0.5, kBinsPerFeature - 0.5]: truncation is the floor there except below 0 (no
  // call to floor in the coarse stage's innermost loop). An end bin takes both weights, the
  // lower one's first: float sums depend on their order, and the descriptors on these.
  const int lo = x < 0.0 ? -1 : static_cast<int>(x);
  const double t = x - lo;
  const auto up = static_cast<float>(t);
  const auto down = static_cast<float>(1.0 - t);
  float* b = h + block * kBinsPerFeature;
  if (lo < 0) {
    b[0] += up;
    b[0] += down;
  } else if (lo + 1 >= kBinsPerFeature) {
    b[kBinsPerFeature - 1] += down;
    b[kBinsPerFeature - 1] += up;
  } else {
    b[lo] += down;
    b[lo + 1] += up;
  }
}

// |cos| -> the angle of a direction from a plane (asin) or between two lines (acos), as a
// fraction of a right angle.
double from_plane(double abs_cos) {
  return std::asin(std::min(1.0, abs_cos)) / (0.5 * std::numbers::pi);
}
double between(double abs_cos) {
  return std::acos(std::min(1.0, abs_cos)) / (0.5 * std::numbers::pi);
}

// The residual variance of the least-squares quadric h = a x^2 + b xy + c y^2 + d x + e y + f
// through the neighbours of q within the probe's radius, in the PCA frame `axes` (column 0: the
// normal): a plane's residuals also hold the surface's curvature (r^4 k^2 / 8 at a radius r: on
// fillets and holes it exceeds the noise and biased the estimate high, on flat parts it was
// right), a quadric's only the noise. Uniform outliers close to a thin part fall inside most
// neighbourhoods (a plate's box is thin), so the fit is repeated four times on the points within
// 2.5 standard deviations of the previous fit (Gaussian noise loses 1.2% of its points and 8.9% of
// its variance to that cut, which is given back). Divided by count - 6 (the fit takes six degrees
// of freedom). -1 when the fit is degenerate.
//
// `offsets` are the neighbours' p - q in the grid's order (gathered once per probe: the five fits
// and the PCA before them read the same neighbourhood, which walking the grid again for each cost
// more than the fits). The sums are taken in the same order and with the same operations as a
// per-neighbour rank update, so the estimate does not depend on how the neighbours are held.
// Gaussian noise keeps this share of its variance inside the 2.5-sigma cut; dividing by it gives
// back what the cut took.
constexpr double kVarianceKeptByTheCut = 0.91126;

double quadric_residual_variance(std::span<const Vec3> offsets, double radius,
                                 const Eigen::Matrix3d& axes, std::vector<Vec3>& local,
                                 std::vector<std::uint8_t>& kept) {
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  const double inv = 1.0 / radius;  // unit-sized coordinates keep the normal equations balanced
  local.resize(offsets.size());
  for (std::size_t k = 0; k < offsets.size(); ++k)
    local[k] = axes.transpose() * (offsets[k] * inv);
  kept.assign(offsets.size(), 1);  // the first fit takes every neighbour
  Vec6 coef = Vec6::Zero();
  double cut2 = std::numeric_limits<double>::infinity();  // squared residual bound (unit scale)
  double variance = -1.0, unit_variance = 0.0;
  constexpr int kFits = 5;
  for (int fit = 0; fit < kFits; ++fit) {
    if (fit > 0) {
      // The neighbours this fit keeps. The same ones as the fit before: its sums would be the
      // same operations on the same values in the same order, so its solution, cut and variance
      // the same (at the second fit, the first's variance with the cut's correction), and every
      // later fit's too: the fits have converged, and the rest would change nothing.
      bool same = true;
      for (std::size_t k = 0; k < local.size(); ++k) {
        const Vec3& l = local[k];
        const double x = l.y(), y = l.z(), h = l.x();
        const Vec6 a(x * x, x * y, y * y, x, y, 1.0);
        const double r = h - a.dot(coef);
        const std::uint8_t in = r * r > cut2 ? 0 : 1;
        same &= in == kept[k];
        kept[k] = in;
      }
      if (same)
        return fit == 1 ? unit_variance * radius * radius / kVarianceKeptByTheCut : variance;
    }
    Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
    Vec6 atb = Vec6::Zero();
    double btb = 0.0;
    int count = 0;
    for (std::size_t k = 0; k < local.size(); ++k) {
      if (!kept[k]) continue;
      const Vec3& l = local[k];
      const double x = l.y(), y = l.z(), h = l.x();
      const Vec6 a(x * x, x * y, y * y, x, y, 1.0);
      // The lower triangle of a a^T (as selfadjointView<Lower>().rankUpdate(a)).
      for (int c = 0; c < 6; ++c) {
        for (int r = c; r < 6; ++r)
          ata(r, c) += a(c) * a(r);
      }
      atb += a * h;
      btb += h * h;
      ++count;
    }
    if (count < 10) return fit == 0 ? -1.0 : variance;
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(ata.selfadjointView<Eigen::Lower>());
    if (ldlt.info() != Eigen::Success) return fit == 0 ? -1.0 : variance;
    const Vec6 next = ldlt.solve(atb);
    if (!next.allFinite()) return fit == 0 ? -1.0 : variance;
    coef = next;
    unit_variance = std::max(0.0, btb - coef.dot(atb)) / static_cast<double>(count - 6);
    cut2 = 6.25 * unit_variance;
    variance = unit_variance * radius * radius / (fit > 0 ? kVarianceKeptByTheCut : 1.0);
  }
  return variance;
}

}  // namespace

PcaNormals pca_normals(std::span<const Vec3> points, const PointGrid& grid, double radius,
                       int min_neighbours) {
  PcaNormals out;
  out.normals.assign(points.size(), Vec3::UnitZ());
  out.valid.assign(points.size(), 0);
  tbb::parallel_for(std::size_t{0}, points.size(), [&](std::size_t i) {
    Moments3 m;
    const Vec3& q = points[i];
    grid.for_each_within(q, radius, [&](std::uint32_t j, double) { m.add(points[j] - q); });
    if (m.count < min_neighbours) return;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m.covariance());
    const Vec3 l = eig.eigenvalues();
    // A surface: the smallest spread clearly below the middle one (a line has two small ones).
    if (!(l(1) > 0.0) || l(0) > 0.25 * l(1)) return;
    out.normals[i] = eig.eigenvectors().col(0).normalized();
    out.valid[i] = 1;
  });
  nurbsreg::engine::stop_if_cancelled();
  return out;
}

DescriptorMatrix describe(std::span<const Vec3> points, std::span<const Vec3> normals,
                          const PointGrid& grid, double radius) {
  const std::size_t n = points.size();
  DescriptorMatrix spfh = DescriptorMatrix::Zero(static_cast<Eigen::Index>(n), kDescriptorSize);
  std::vector<std::uint32_t> neighbours_count(n, 0);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    const Vec3& p = points[i];
    const Vec3& ni = normals[i];
    std::array<float, kDescriptorSize> h{};
    std::uint32_t count = 0;
    grid.for_each_within(p, radius, [&](std::uint32_t j, double d2) {
      if (j == i || !(d2 > 0.0)) return;
      const Vec3 d = (points[j] - p) / std::sqrt(d2);
      const Vec3& nj = normals[j];
      Vec3 v = ni.cross(d);
      const double vn = v.norm();
      const double alpha = vn > 1e-12 ? std::abs(v.dot(nj)) / vn : 0.0;
      add_to_bins(h.data(), 0, from_plane(std::abs(ni.dot(d))));
      add_to_bins(h.data(), 1, from_plane(std::abs(nj.dot(d))));
      add_to_bins(h.data(), 2, between(std::abs(ni.dot(nj))));
      add_to_bins(h.data(), 3, from_plane(alpha));
      ++count;
    });
    neighbours_count[i] = count;
    if (count == 0) return;
    const float scale = 100.0f / static_cast<float>(count);
    for (int k = 0; k < kDescriptorSize; ++k)
      spfh(static_cast<Eigen::Index>(i), k) = h[static_cast<std::size_t>(k)] * scale;
  });
  nurbsreg::engine::stop_if_cancelled();
  DescriptorMatrix out = DescriptorMatrix::Zero(static_cast<Eigen::Index>(n), kDescriptorSize);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    Eigen::Matrix<float, 1, kDescriptorSize> sum = Eigen::Matrix<float, 1, kDescriptorSize>::Zero();
    int count = 0;
    grid.for_each_within(points[i], radius, [&](std::uint32_t j, double) {
      if (j == i || neighbours_count[j] == 0) return;
      sum += spfh.row(j);
      ++count;
    });
    const auto row = static_cast<Eigen::Index>(i);
    if (count > 0) {
      out.row(row) = 0.5f * spfh.row(row) + (0.5f / static_cast<float>(count)) * sum;
    } else {
      out.row(row) = spfh.row(row);
    }
  });
  nurbsreg::engine::stop_if_cancelled();
  return out;
}

double estimate_noise(std::span<const Vec3> scan, double voxel, std::uint64_t seed) {
  if (scan.size() < 16) return 0.0;
  // A seeded subset (at most 40000 points) and its mean spacing on the scanned surface; the
  // area hint is the scan's surface area (occupied voxels x voxel^2).
  constexpr std::size_t kSubset = 40000;
  std::vector<Vec3> subset;
  if (scan.size() <= kSubset) {
    subset.assign(scan.begin(), scan.end());
  } else {
    std::mt19937_64 rng(seed);
    subset.reserve(kSubset);
    for (std::size_t i = 0; i < kSubset; ++i)
      subset.push_back(scan[static_cast<std::size_t>(rng() % scan.size())]);
  }
  // The scanned surface's area: its voxels times the voxel's face. A uniform outlier is mostly
  // alone in its voxel, but clutter dense around a part (outliers in the scan's own box) leaves
  // two or three in many: the surface's voxels are those about as full as a typical point's
  // (surface_voxel_count), else the area, the spacing and the radius grow with the clutter and
  // so does the estimate (NIST CTC-02 with 30% outliers: 7 times the noise).
  const std::vector<std::uint32_t> counts = voxel_counts(subset, voxel);
  const std::uint32_t surface_count = surface_voxel_count(counts, 2);
  const auto occupied = static_cast<std::size_t>(std::count_if(
      counts.begin(), counts.end(), [&](std::uint32_t c) { return c >= surface_count; }));
  const double area = static_cast<double>(std::max<std::size_t>(occupied, 1)) * voxel * voxel;
  const double spacing = std::sqrt(area / static_cast<double>(subset.size()));
  // About 16 neighbours, but never beyond the voxel (curvature) nor below the spacing.
  const double radius = std::clamp(2.3 * spacing, 0.25 * voxel, voxel);
  const PointGrid grid(subset, radius);
  // Probe at most 3000 points (every k-th of the subset: it is already random).
  const std::size_t probes = std::min<std::size_t>(3000, subset.size());
  const std::size_t stride = subset.size() / probes;
  std::vector<double> variances(probes, -1.0);
  // Per thread: the probe's neighbourhood (grown to the largest one, then reused).
  struct Neighbourhood {
    std::vector<Vec3> offsets, local;
    std::vector<std::uint8_t> kept;
  };
  tbb::enumerable_thread_specific<Neighbourhood> scratch;
  tbb::parallel_for(std::size_t{0}, probes, [&](std::size_t k) {
    const Vec3& q = subset[k * stride];
    Neighbourhood& near = scratch.local();
    near.offsets.clear();
    grid.for_each_within(q, radius,
                         [&](std::uint32_t j, double) { near.offsets.push_back(subset[j] - q); });
    Moments3 m;
    for (const Vec3& d : near.offsets)
      m.add(d);
    if (m.count < 10) return;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m.covariance());
    const Vec3 l = eig.eigenvalues();
    if (l(0) > 0.25 * l(1)) return;  // not a surface: an outlier blob or an edge
    variances[k] =
        quadric_residual_variance(near.offsets, radius, eig.eigenvectors(), near.local, near.kept);
  });
  nurbsreg::engine::stop_if_cancelled();
  std::vector<double> valid;
  for (double v : variances) {
    if (v >= 0.0) valid.push_back(v);
  }
  if (valid.size() < 10) return 0.0;
  const auto mid = valid.begin() + static_cast<std::ptrdiff_t>(valid.size() / 2);
  std::nth_element(valid.begin(), mid, valid.end());
  return std::sqrt(*mid);
}

}  // namespace nurbsreg::registration::detail
