#include <tbb/parallel_for.h>

#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>
#include <unordered_set>

#include "coarse_detail.hpp"
#include "grid_cell.hpp"
#include "nurbsreg/engine/cancellation.hpp"

namespace nurbsreg::registration::detail {
namespace {

using engine::Vec3;

constexpr int kChunks = 32;
constexpr std::size_t kSupportSample = 256;
constexpr std::size_t kSupportRun = 32;
constexpr int kThirdAttempts = 64;
constexpr std::size_t kOverlapProbes = 256;

// Which cells of side `cell` lie within one cell of a model keypoint: a scan keypoint moved into
// such a cell has model surface within about two cells. One hash lookup per probe, where a
// nearest-neighbour query would look at 27 cells.
class Occupancy {
 public:
  Occupancy(std::span<const Vec3> model, double cell) : inv_(1.0 / cell) {
    cells_.reserve(model.size() * 27);
    for (const Vec3& p : model) {
      const auto c = cell_of(p);
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
          for (std::int64_t dz = -1; dz <= 1; ++dz)
            cells_.insert(pack(c[0] + dx, c[1] + dy, c[2] + dz));
    }
  }
  bool near(const Vec3& p) const {
    const auto c = cell_of(p);
    return cells_.count(pack(c[0], c[1], c[2])) != 0;
  }

 private:
  std::array<std::int64_t, 3> cell_of(const Vec3& p) const {
    return {cell_index(p.x() * inv_), cell_index(p.y() * inv_), cell_index(p.z() * inv_)};
  }
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    const auto b = [](std::int64_t v) {
      return static_cast<std::uint64_t>(v + (std::int64_t{1} << 20)) & ((1ull << 21) - 1);
    };
    return (b(x) << 42) | (b(y) << 21) | b(z);
  }
  double inv_;
  std::unordered_set<std::uint64_t> cells_;
};

// How many probes land near the model under T (Open3D's RANSAC "fitness", on a sample): on a
// part of repeated features (a plate with pockets), matches on its flat faces support many wrong
// poses about as well as the right one, which alone puts the whole scan onto the model.
std::size_t overlap_of(const Eigen::Isometry3d& T, std::span<const Vec3> probes,
                       const Occupancy& occupancy) {
  std::size_t n = 0;
  for (const Vec3& p : probes)
    n += occupancy.near(T * p);
  return n;
}

// The matches' points as float columns about their centroids (the scan's and the model's),
// for the consistency test of one match against all others: the coarse stage's inner loop (a
// seed against every match), written so that the compiler vectorises it. Float is ample: edge
// lengths are compared within inlier_distance, a voxel or two.
class MatchPoints {
 public:
  MatchPoints(std::span<const Vec3> scan, std::span<const Vec3> model,
              std::span<const Match> matches) {
    const std::size_t m = matches.size();
    for (auto* v : {&sx_, &sy_, &sz_, &mx_, &my_, &mz_})
      v->resize(m);
    Vec3 cs = Vec3::Zero(), cm = Vec3::Zero();
    for (const Match& k : matches) {
      cs += scan[k.scan];
      cm += model[k.model];
    }
    cs /= static_cast<double>(std::max<std::size_t>(m, 1));
    cm /= static_cast<double>(std::max<std::size_t>(m, 1));
    for (std::size_t k = 0; k < m; ++k) {
      const Vec3 s = scan[matches[k].scan] - cs;
      const Vec3 d = model[matches[k].model] - cm;
      sx_[k] = static_cast<float>(s.x());
      sy_[k] = static_cast<float>(s.y());
      sz_[k] = static_cast<float>(s.z());
      mx_[k] = static_cast<float>(d.x());
      my_[k] = static_cast<float>(d.y());
      mz_[k] = static_cast<float>(d.z());
    }
  }
  // mask[b] = 1 when matches a and b keep their distance (RansacParams): edge length ls on the
  // scan >= min_edge, |ls - lm| <= inlier_distance and min/max >= edge_similarity.
  void consistent_with(std::uint32_t a, const RansacParams& p,
                       std::vector<std::uint8_t>& mask) const {
    const std::size_t m = sx_.size();
    mask.resize(m);
    const float ax = sx_[a], ay = sy_[a], az = sz_[a];
    const float bx = mx_[a], by = my_[a], bz = mz_[a];
    const float min_edge2 = static_cast<float>(p.min_edge * p.min_edge);
    const float tol = static_cast<float>(p.inlier_distance);
    const float sim = static_cast<float>(p.edge_similarity);
    const float* sx = sx_.data();
    const float* sy = sy_.data();
    const float* sz = sz_.data();
    const float* mx = mx_.data();
    const float* my = my_.data();
    const float* mz = mz_.data();
    std::uint8_t* out = mask.data();
    for (std::size_t b = 0; b < m; ++b) {
      const float dx = sx[b] - ax, dy = sy[b] - ay, dz = sz[b] - az;
      const float ex = mx[b] - bx, ey = my[b] - by, ez = mz[b] - bz;
      const float ls2 = dx * dx + dy * dy + dz * dz;
      const float lm2 = ex * ex + ey * ey + ez * ez;
      const float ls = std::sqrt(ls2), lm = std::sqrt(lm2);
      // Bitwise on ints, not && on bools: no branch, so the loop vectorises.
      const int ok = int(ls2 >= min_edge2) & int(std::abs(ls - lm) <= tol) &
                     int(std::min(ls, lm) >= sim * std::max(ls, lm));
      out[b] = static_cast<std::uint8_t>(ok);
    }
  }

 private:
  std::vector<float> sx_, sy_, sz_, mx_, my_, mz_;
};

bool ranks_before(const Hypothesis& a, const Hypothesis& b) {
  return a.overlap != b.overlap ? a.overlap > b.overlap : a.support > b.support;
}

// Adds h to the best-first list `kept` unless a kept pose within the distinctness limits has at
// least its support (then h is a duplicate of it); replaces the weaker duplicates otherwise.
void keep_best(std::vector<Hypothesis>& kept, const Hypothesis& h, const RansacParams& p) {
  for (auto it = kept.begin(); it != kept.end();) {
    const bool same = rotation_between(it->T_model_scan, h.T_model_scan) <= p.distinct_angle &&
                      (it->T_model_scan.translation() - h.T_model_scan.translation()).norm() <=
                          p.distinct_translation;
    if (!same) {
      ++it;
      continue;
    }
    if (!ranks_before(h, *it)) return;
    it = kept.erase(it);
  }
  const auto pos = std::find_if(kept.begin(), kept.end(),
                                [&](const Hypothesis& k) { return ranks_before(h, k); });
  kept.insert(pos, h);
  if (kept.size() > static_cast<std::size_t>(p.keep)) kept.pop_back();
}

// Point pairs (scan, model) as columns of doubles: T * s - m for every pair in one loop the
// compiler vectorises, each component summed left to right (the rotation's row times s, then
// the translation, then less m), as a per-pair Eigen expression would.
class PairColumns {
 public:
  void clear() {
    for (auto* v : {&sx_, &sy_, &sz_, &mx_, &my_, &mz_})
      v->clear();
  }
  void push_back(const Vec3& s, const Vec3& m) {
    sx_.push_back(s.x());
    sy_.push_back(s.y());
    sz_.push_back(s.z());
    mx_.push_back(m.x());
    my_.push_back(m.y());
    mz_.push_back(m.z());
  }
  std::size_t size() const { return sx_.size(); }
  // How many of the pairs [begin, end) T brings within sqrt(d2max).
  std::size_t within(const Eigen::Isometry3d& T, double d2max, std::size_t begin,
                     std::size_t end) const {
    const Eigen::Matrix3d& R = T.linear();
    const Vec3& t = T.translation();
    const double r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
    const double r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
    const double r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
    const double tx = t.x(), ty = t.y(), tz = t.z();
    const double* sx = sx_.data();
    const double* sy = sy_.data();
    const double* sz = sz_.data();
    const double* mx = mx_.data();
    const double* my = my_.data();
    const double* mz = mz_.data();
    // A count in a double (exact: whole numbers far below 2^53), which SSE2 vectorises with the
    // comparisons; a 64-bit integer count it does not.
    double count = 0.0;
    for (std::size_t k = begin; k < end; ++k) {
      const double dx = r00 * sx[k] + r01 * sy[k] + r02 * sz[k] + tx - mx[k];
      const double dy = r10 * sx[k] + r11 * sy[k] + r12 * sz[k] + ty - my[k];
      const double dz = r20 * sx[k] + r21 * sy[k] + r22 * sz[k] + tz - mz[k];
      count += dx * dx + dy * dy + dz * dz <= d2max ? 1.0 : 0.0;
    }
    return static_cast<std::size_t>(count);
  }
  bool within_one(const Eigen::Isometry3d& T, double d2max, std::size_t k) const {
    return within(T, d2max, k, k + 1) != 0;
  }

 private:
  std::vector<double> sx_, sy_, sz_, mx_, my_, mz_;
};

// How many matches T brings within sqrt(d2max); their indices into `supporters` if given.
std::size_t support_of(const Eigen::Isometry3d& T, const PairColumns& pairs, double d2max,
                       std::vector<std::uint32_t>* supporters) {
  if (!supporters) return pairs.within(T, d2max, 0, pairs.size());
  std::size_t count = 0;
  for (std::uint32_t k = 0; k < pairs.size(); ++k) {
    if (pairs.within_one(T, d2max, k)) {
      ++count;
      supporters->push_back(k);
    }
  }
  return count;
}

}  // namespace

double rotation_between(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
}

bool same_pose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double voxel) {
  return rotation_between(a, b) < 2.0 * std::numbers::pi / 180.0 &&
         (a.translation() - b.translation()).norm() < 1.0 * voxel;
}

bool fit_rigid(std::span<const Vec3> src, std::span<const Vec3> dst, Eigen::Isometry3d& T) {
  const std::size_t n = src.size();
  if (n < 3) return false;
  Vec3 ms = Vec3::Zero(), md = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    ms += src[i];
    md += dst[i];
  }
  ms /= static_cast<double>(n);
  md /= static_cast<double>(n);
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i)
    C.noalias() += (dst[i] - md) * (src[i] - ms).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(C, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vec3 s = svd.singularValues();
  // Collinear points leave the rotation about their line free.
  if (!(s(1) > 1e-12 * s(0))) return false;
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0) S(2, 2) = -1.0;
  T.linear() = svd.matrixU() * S * svd.matrixV().transpose();
  T.translation() = md - T.linear() * ms;
  return T.matrix().allFinite();
}

std::vector<Hypothesis> ransac_hypotheses(std::span<const Vec3> scan, std::span<const Vec3> model,
                                          std::span<const Match> matches, const RansacParams& p,
                                          std::span<const Vec3> model_surface) {
  std::vector<Hypothesis> kept;
  if (matches.size() < 3) return kept;
  const double d2max = p.inlier_distance * p.inlier_distance;
  const std::size_t m = matches.size();
  // Seeds: every match, or a seeded subset of p.seeds of them.
  std::vector<std::uint32_t> seeds(m);
  std::iota(seeds.begin(), seeds.end(), std::uint32_t{0});
  if (m > static_cast<std::size_t>(p.seeds)) {
    std::mt19937_64 rng(p.seed);
    for (std::size_t i = 0; i < static_cast<std::size_t>(p.seeds); ++i)
      std::swap(seeds[i], seeds[i + static_cast<std::size_t>(rng() % (m - i))]);
    seeds.resize(static_cast<std::size_t>(p.seeds));
    std::sort(seeds.begin(), seeds.end());
  }
  const auto compatible = [&](std::uint32_t a, std::uint32_t b) {
    const double ls = (scan[matches[a].scan] - scan[matches[b].scan]).norm();
    const double lm = (model[matches[a].model] - model[matches[b].model]).norm();
    return ls >= p.min_edge && std::abs(ls - lm) <= p.inlier_distance &&
           std::min(ls, lm) >= p.edge_similarity * std::max(ls, lm);
  };
  const MatchPoints points(scan, model, matches);
  PairColumns all_pairs;
  for (const Match& k : matches)
    all_pairs.push_back(scan[k.scan], model[k.model]);
  std::vector<Vec3> probes;
  const std::size_t probe_step = std::max<std::size_t>(1, scan.size() / kOverlapProbes);
  for (std::size_t i = 0; i < scan.size(); i += probe_step)
    probes.push_back(scan[i]);
  const Occupancy occupancy(model_surface, p.overlap_cell);
  const std::size_t chunks = std::min<std::size_t>(kChunks, seeds.size());
  std::vector<std::vector<Hypothesis>> chunk_best(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t chunk) {
    std::vector<Hypothesis>& best = chunk_best[chunk];
    std::vector<std::uint32_t> consistent_with_a(m);  // room for every match, written per seed
    std::vector<std::uint8_t> mask;
    PairColumns sampled;
    for (std::size_t si = chunk; si < seeds.size(); si += chunks) {
      const std::uint32_t a = seeds[si];
      // The matches consistent with a: if a is right, every right match is among them.
      points.consistent_with(a, p, mask);
      // Compacted without a branch (the mask is random: a branch per match mispredicted).
      std::size_t consistent = 0;
      for (std::uint32_t b = 0; b < m; ++b) {
        consistent_with_a[consistent] = b;
        consistent += static_cast<std::size_t>(mask[b] & static_cast<std::uint8_t>(b != a));
      }
      const std::span<const std::uint32_t> with_a(consistent_with_a.data(), consistent);
      if (with_a.size() < 2) continue;
      std::mt19937_64 rng(p.seed * 0x9E3779B97F4A7C15ull + a);
      Hypothesis seed_best;
      // Support is counted on at most kSupportSample of a's consistent matches (evenly spread),
      // their points gathered once for all of a's draws.
      const std::size_t step = std::max<std::size_t>(1, with_a.size() / kSupportSample);
      sampled.clear();
      for (std::size_t i = 0; i < with_a.size(); i += step) {
        const Match& k = matches[with_a[i]];
        sampled.push_back(scan[k.scan], model[k.model]);
      }
      const std::size_t sample_size = sampled.size();
      for (int draw = 0; draw < p.draws_per_seed; ++draw) {
        const std::uint32_t b = with_a[static_cast<std::size_t>(rng() % with_a.size())];
        // c: consistent with a (drawn from with_a) and with b (rejection: a few tries).
        std::uint32_t c = b;
        for (int attempt = 0; attempt < kThirdAttempts && c == b; ++attempt) {
          const std::uint32_t k = with_a[static_cast<std::size_t>(rng() % with_a.size())];
          if (k != b && compatible(b, k)) c = k;
        }
        if (c == b) continue;
        const std::array<Vec3, 3> s{scan[matches[a].scan], scan[matches[b].scan],
                                    scan[matches[c].scan]};
        const std::array<Vec3, 3> d{model[matches[a].model], model[matches[b].model],
                                    model[matches[c].model]};
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        if (!fit_rigid(s, d, T)) continue;
        // The triple itself must fit: equal edge lengths still allow a mirrored triangle.
        bool fits = true;
        for (int k = 0; k < 3 && fits; ++k)
          fits = (T * s[k] - d[k]).squaredNorm() <= d2max;
        if (!fits) continue;
        // Support among a's consistent matches (where every right match lies), cheap. Only a
        // draw with more support than the seed's best so far is kept: once even all the matches
        // left could not give it more, the count stops (the same draw wins as with a full count).
        // Counted in runs of kSupportRun (vectorised), the stop tested between runs.
        std::size_t support = 1;
        for (std::size_t i = 0; i < sample_size; i += kSupportRun) {
          if (support + (sample_size - i) <= seed_best.support) break;
          support += sampled.within(T, d2max, i, std::min(sample_size, i + kSupportRun));
        }
        if (support > seed_best.support) seed_best = {T, support, 0};
      }
      if (seed_best.support < 3) continue;
      seed_best.overlap = overlap_of(seed_best.T_model_scan, probes, occupancy);
      // Hypotheses rank by overlap first: one below the last of a full list ranks after every
      // kept one, so keep_best drops it whatever its support (no need to count it on all
      // matches).
      if (!best.empty() && best.size() >= static_cast<std::size_t>(p.keep) &&
          seed_best.overlap < best.back().overlap) {
        continue;
      }
      seed_best.support = support_of(seed_best.T_model_scan, all_pairs, d2max, nullptr);
      keep_best(best, seed_best, p);
    }
  });
  nurbsreg::engine::stop_if_cancelled();
  for (const auto& chunk : chunk_best) {
    for (const Hypothesis& h : chunk)
      keep_best(kept, h, p);
  }
  // Refit each on its supporters (twice: the refit gains supporters), then order again.
  std::vector<Hypothesis> refined;
  std::vector<std::uint32_t> supporters;
  std::vector<Vec3> src, dst;
  for (const Hypothesis& h : kept) {
    Hypothesis r = h;
    for (int round = 0; round < 2; ++round) {
      supporters.clear();
      support_of(r.T_model_scan, all_pairs, d2max, &supporters);
      src.clear();
      dst.clear();
      for (std::uint32_t k : supporters) {
        src.push_back(scan[matches[k].scan]);
        dst.push_back(model[matches[k].model]);
      }
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      if (!fit_rigid(src, dst, T)) break;
      const std::size_t support = support_of(T, all_pairs, d2max, nullptr);
      const std::size_t overlap = overlap_of(T, probes, occupancy);
      if (support < r.support || overlap < r.overlap) break;
      r = {T, support, overlap};
    }
    refined.push_back(r);
  }
  std::vector<Hypothesis> out;
  for (const Hypothesis& h : refined)
    keep_best(out, h, p);
  return out;
}

}  // namespace nurbsreg::registration::detail
