// ModelCorrespondenceFinder's borrowed certificates at full resolution: a point whose borrowed
// atlas certificate did not prove its answer borrows no more and keeps its own previous answer as
// its hint; every other point without a covering certificate of its own still looks the atlas up.
// The oracle replays that rule outside the finder (its own CertificateAtlas filled from the
// certifying queries' answers, the hints it implies, a plain Projector with them) over a
// coarse-to-fine-like sequence on two close sheets (a thin wall, where borrowed proofs fail), and
// the finder must match it bit for bit: the same feet, parameters and certificates and the same
// work counters (a hint that changed, e.g. a lost own hint or a lookup skipped or made wrongly,
// changes the Newton iterations and the visited patches). Every answer is also checked against a
// cold projection.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "finder_checks.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/certificate_atlas.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

constexpr double kUnknown = std::numeric_limits<double>::infinity();

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

class ModelFinderBorrow : public ::testing::Test {
 protected:
  ModelFinderBorrow() : prepared_(model()), reference_(prepared_) {
    // Points within 0.3 of the lower sheet (the upper one lies `kGap` above it) and a few far
    // above both, over a fifth of the domain in u and v: dense enough that most lie within a
    // certificate made on the coarse tenth.
    std::mt19937_64 rng(29);
    const engine::NurbsSurface& s = prepared_.model().surfaces.front();
    for (int i = 0; i < 6000; ++i) {
      const double u = test::uniform(rng, 0.4, 0.6);
      const double v = test::uniform(rng, 0.4, 0.6);
      const double h = i % 10 == 0 ? test::uniform(rng, 1.0, 5.0) : test::uniform(rng, -0.3, 0.3);
      scan_.push_back(s.evaluate(u, v) + Vec3(0, 0, h));
    }
  }
  static constexpr double kGap = 0.6;
  static engine::Model model() {
    engine::Model m;
    m.surfaces.push_back(test::random_surface(23, 3, 3, 9, 9, false));
    engine::NurbsSurface upper = m.surfaces.front();
    for (Vec3& p : upper.control_points)
      p.z() += kGap;
    m.surfaces.push_back(upper);
    return m;
  }

  std::vector<Vec3> moved(const std::vector<std::size_t>& ids, const Vec3& shift) const {
    std::vector<Vec3> points;
    if (ids.empty()) {
      for (const Vec3& p : scan_)
        points.push_back(p + shift);
    } else {
      for (const std::size_t i : ids)
        points.push_back(scan_[i] + shift);
    }
    return points;
  }

  engine::ProjectionCounters find(ModelCorrespondenceFinder& finder,
                                  const std::vector<std::size_t>& ids,
                                  const std::vector<Vec3>& points, double expected_motion,
                                  int later_queries = 0) {
    return find_checked(finder, reference_, 1e-10 * prepared_.bounds().diagonal(), ids, points,
                        expected_motion, 0.0, later_queries);
  }

  // The coarse stage's subsample: every tenth scan point.
  std::vector<std::size_t> coarse_tenth() const {
    std::vector<std::size_t> ids;
    for (std::size_t i = 3; i < scan_.size(); i += 10)
      ids.push_back(i);
    return ids;
  }

  engine::PreparedModel prepared_;
  engine::Projector reference_;
  std::vector<Vec3> scan_;
};

TEST_F(ModelFinderBorrow, FailedBorrowersKeepTheirOwnHintsOthersStillLookUp) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const std::size_t n = scan_.size();
  const std::vector<std::size_t> coarse = coarse_tenth();
  ModelCorrespondenceFinder finder(prepared_);
  finder.reset(n);
  // The coarse stage: a first query, then one that certifies (small expected motion).
  const double small = 1e-5 * prepared_.bounds().diagonal();
  find(finder, coarse, moved(coarse, Vec3::Zero()), kUnknown);
  const std::vector<Vec3> certifying = moved(coarse, Vec3(1e-4, -0.5e-4, 1e-4));
  EXPECT_GT(find(finder, coarse, certifying, small).certificates_made, coarse.size() / 2);

  // The oracle's atlas: the finder inserts a certifying query's certificates anchored at its
  // points, in query order, into cells of half the radius cap, kAtlasHintsPerCell a cell.
  CertificateAtlas atlas;
  atlas.reset(0.5 * finder.certificate_radius(), ModelCorrespondenceFinder::kAtlasHintsPerCell);
  const auto insert_made = [&](const engine::ProjectionResults& made,
                               const std::vector<Vec3>& points) {
    for (std::size_t k = 0; k < points.size(); ++k) {
      const engine::WarmCertificate& c = made.certificate[k];
      if (made.status[k] == engine::ProjectionStatus::ok && c.radius > 0.0f &&
          c.anchor == points[k].cast<float>()) {
        atlas.insert(made.hint(k));
      }
    }
  };
  insert_made(finder.last_results(), certifying);
  ASSERT_GT(atlas.size(), 0u);
  // Each point's own hint for the first full-resolution query: the coarse points' answers.
  std::vector<engine::ProjectionHint> own(n);
  for (std::size_t k = 0; k < coarse.size(); ++k)
    own[coarse[k]] = finder.last_results().hint(k);
  std::vector<std::uint8_t> stopped(n, 0);

  // Full resolution: three passes, the last moved by a third of the radius cap, so that points
  // leave their certificates' balls and look the atlas up again. Then a subsample (every third
  // point, the first hundred of them named twice), whose points the finder tracks by scan index,
  // twice, the second time certifying (a failed borrow then leaves a new certificate, anchored
  // at the point), and a full pass that reads those marks. Last, after a reset() that keeps the
  // atlas, a pass in which every point may borrow again.
  const double cap = finder.certificate_radius();
  std::vector<std::size_t> thirds;
  for (std::size_t i = 1; i < n; i += 3)
    thirds.push_back(i);
  thirds.insert(thirds.end(), thirds.begin(), thirds.begin() + 100);
  struct Pass {
    std::vector<std::size_t> ids;  // empty: every scan point
    Vec3 shift;
    double expected_motion = kUnknown;
    bool reset_first = false;
  };
  const Pass passes[] = {{{}, Vec3(2e-4, -1e-4, 2e-4)},
                         {{}, Vec3(3e-4, -1.5e-4, 3e-4)},
                         {{}, Vec3(0.2 * cap, -0.2 * cap, 0.1 * cap)},
                         {thirds, Vec3(0.1 * cap, 0.2 * cap, -0.1 * cap)},
                         {thirds, Vec3(0.1 * cap, 0.2 * cap, -0.1 * cap), small},
                         {{}, Vec3(-0.1 * cap, 0.1 * cap, 0.1 * cap)},
                         {{}, Vec3(-0.1 * cap, 0.1 * cap, 0.1 * cap), kUnknown, true}};
  std::size_t proven_by_borrowed = 0, failed_borrows = 0, looked_up_again = 0;
  std::size_t subsample_borrows = 0, failed_while_certifying = 0;
  for (const Pass& pass : passes) {
    if (pass.reset_first) {
      finder.keep_certificates(true);
      finder.reset(n);
      for (std::size_t s = 0; s < n; ++s)
        EXPECT_FALSE(finder.stopped_borrowing(s)) << s;
      std::fill(own.begin(), own.end(), engine::ProjectionHint{});
      std::fill(stopped.begin(), stopped.end(), 0);
    }
    const std::vector<Vec3> points = moved(pass.ids, pass.shift);
    const std::size_t m = points.size();
    const auto scan_index = [&](std::size_t k) { return pass.ids.empty() ? k : pass.ids[k]; };
    std::vector<engine::ProjectionHint> hints(m);
    std::vector<const engine::ProjectionHint*> borrowed(m, nullptr);
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t s = scan_index(k);
      if (!stopped[s] && !own[s].certificate.covers(points[k])) {
        borrowed[k] = atlas.find(points[k]);
        if (borrowed[k] != nullptr && own[s].entity >= 0) ++looked_up_again;
        if (borrowed[k] != nullptr && !pass.ids.empty()) ++subsample_borrows;
      }
      hints[k] = borrowed[k] != nullptr ? *borrowed[k] : own[s];
    }
    const bool certify = !pass.ids.empty() && pass.expected_motion < 0.5 * cap;
    engine::ProjectionOptions options;
    options.certificate_radius = cap;
    options.certify = certify;
    engine::ProjectionResults expected;
    engine::ProjectionCounters expected_counters;
    reference_.project(engine::PointView::of(points), options, expected, hints, &expected_counters);

    const engine::ProjectionCounters counters =
        find(finder, pass.ids, points, pass.expected_motion);
    const engine::ProjectionResults& r = finder.last_results();
    EXPECT_EQ(counters.newton_iterations, expected_counters.newton_iterations);
    EXPECT_EQ(counters.patches_visited, expected_counters.patches_visited);
    EXPECT_EQ(counters.certified, expected_counters.certified);
    EXPECT_EQ(counters.certificates_made, expected_counters.certificates_made);
    std::size_t mismatches = 0;
    for (std::size_t k = 0; k < m; ++k) {
      const bool same = r.entity[k] == expected.entity[k] && same_bits(r.u[k], expected.u[k]) &&
                        same_bits(r.v[k], expected.v[k]) &&
                        same_bits(r.distance[k], expected.distance[k]) &&
                        r.certificate[k].anchor == expected.certificate[k].anchor &&
                        r.certificate[k].radius == expected.certificate[k].radius;
      mismatches += same ? 0 : 1;
      if (borrowed[k] != nullptr) {
        const bool proven = expected.certificate[k].radius > 0.0f &&
                            expected.certificate[k].anchor == borrowed[k]->certificate.anchor;
        ++(proven ? proven_by_borrowed : failed_borrows);
        if (!proven) stopped[scan_index(k)] = 1;
        if (!proven && certify && expected.certificate[k].radius > 0.0f) {
          ++failed_while_certifying;
        }
      }
    }
    EXPECT_EQ(mismatches, 0u);
    for (std::size_t s = 0; s < n; ++s)
      EXPECT_EQ(finder.stopped_borrowing(s), stopped[s] != 0) << s;
    if (certify) insert_made(expected, points);
    // The next query's own hints: this one's answers (of the copy named last: the finder's
    // previous position of a scan point); points it did not name have none.
    if (!pass.ids.empty()) std::fill(own.begin(), own.end(), engine::ProjectionHint{});
    for (std::size_t k = 0; k < m; ++k)
      own[scan_index(k)] = expected.hint(k);
  }
  // The sequence exercises every branch: borrowed proofs that held and that failed (also where
  // the failure left a new certificate), points with an own answer that looked the atlas up
  // again, and borrowers named by scan index.
  EXPECT_GT(proven_by_borrowed, n / 10);
  EXPECT_GT(failed_borrows, n / 50);
  EXPECT_GT(looked_up_again, n / 50);
  EXPECT_GT(subsample_borrows, n / 100);
  EXPECT_GT(failed_while_certifying, 0u);
}

// At full resolution, with several passes still to come (the solver's later_queries), a point
// that no borrowed certificate proved gets one of its own, anchored at it, of a radius for the
// expected motion (kOwnCertificateMotions of it): the next pass, moved by less, proves it with
// one Newton. With fewer later passes (making costs more than the one search it saves) only a
// clearance certificate, which costs about the search itself; none when the motion is unknown;
// never lent to other points (the atlas is unchanged). Every answer is checked against a cold
// projection.
TEST_F(ModelFinderBorrow, FullResolutionPassesMakeOwnCertificatesWhenSeveralPassesFollow) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const std::size_t n = scan_.size();
  const std::vector<std::size_t> coarse = coarse_tenth();
  const double motion = 1e-5 * prepared_.bounds().diagonal();
  const auto coarse_stage = [&](ModelCorrespondenceFinder& finder) {
    finder.reset(n);
    find(finder, coarse, moved(coarse, Vec3::Zero()), kUnknown);
    find(finder, coarse, moved(coarse, Vec3(1e-4, -0.5e-4, 1e-4)), motion);
  };
  const Vec3 first(2e-4, -1e-4, 2e-4);
  const Vec3 second = first + Vec3(motion, motion, 0.0);  // moved by sqrt(2) motion

  ModelCorrespondenceFinder quick(prepared_);
  coarse_stage(quick);
  const std::size_t atlas = quick.atlas_size();
  const engine::ProjectionCounters made = find(quick, {}, moved({}, first), motion, 2);
  ASSERT_GT(made.certificates_made, n / 50) << "the thin wall should leave unproven points";
  // Nearly every point is proven or gets its own (the rest: where none could be made).
  EXPECT_GE(made.certificates_made + made.certified, n * 99 / 100);
  const engine::ProjectionResults& r = quick.last_results();
  const std::vector<Vec3> at_first = moved({}, first);
  std::size_t own = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const engine::WarmCertificate& c = r.certificate[k];
    if (c.radius > 0.0f && c.anchor == at_first[k].cast<float>()) {
      ++own;
      // At most the radius asked for (less where convexity holds on a smaller ball only).
      EXPECT_LE(c.radius, kOwnCertificateMotions * motion) << k;
    }
  }
  EXPECT_EQ(own, made.certificates_made);
  EXPECT_EQ(quick.atlas_size(), atlas);
  const engine::ProjectionCounters next = find(quick, {}, moved({}, second), motion, 1);
  // (With one later pass: at most clearance certificates, for the few points still unproven.)
  const std::vector<Vec3> at_second = moved({}, second);
  for (std::size_t k = 0; k < n; ++k) {
    const engine::WarmCertificate& c = quick.last_results().certificate[k];
    if (c.anchor == at_second[k].cast<float>()) {
      EXPECT_TRUE(c.clearance_only()) << k;
    }
  }
  EXPECT_LT(next.certificates_made, n / 100);

  // The same passes with one later query expected: no certificate with a box; the points no
  // borrowed one proved get clearance certificates instead (engine::WarmCertificate::
  // clearance_only, for kClearanceMotions of the motion), their own and never lent, and the next
  // pass proves them by clipping the foot's patch alone. None when the motion is unknown.
  ModelCorrespondenceFinder plain(prepared_);
  coarse_stage(plain);
  const engine::ProjectionCounters clearing = find(plain, {}, moved({}, first), motion, 1);
  const engine::ProjectionResults& c = plain.last_results();
  std::size_t clearance = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (c.certificate[k].anchor != at_first[k].cast<float>()) continue;
    EXPECT_TRUE(c.certificate[k].clearance_only()) << k;
    EXPECT_LE(c.certificate[k].clearance,
              c.distance[k] + 2.0 * kClearanceMotions * motion + 1e-6 * motion)
        << k;
    ++clearance;
  }
  EXPECT_EQ(clearance, clearing.certificates_made);
  EXPECT_GT(clearance, n / 50);
  EXPECT_EQ(plain.atlas_size(), atlas);
  ModelCorrespondenceFinder unknown(prepared_);
  coarse_stage(unknown);
  EXPECT_EQ(find(unknown, {}, moved({}, first), kUnknown, 1).certificates_made, 0u);
  // Moved by a little less than the motion (their margin covers a move of one motion).
  const Vec3 within = first + Vec3(0.7 * motion, 0.7 * motion, 0.0);
  const engine::ProjectionCounters after = find(plain, {}, moved({}, within), motion, 1);
  EXPECT_GE(after.certified, clearing.certified + clearance * 9 / 10);
}

}  // namespace
}  // namespace nurbsreg::icp
