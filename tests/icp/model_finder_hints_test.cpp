// ModelCorrespondenceFinder's warm starts without a hint array: a query that repeats the previous
// one reads the previous answers in place, a query with other scan points carries the answers of
// the points the two share. Checked through a coarse-to-fine-like sequence of queries (a
// subsample, the same again, a superset, all points, all again, one naming a point twice, a new
// scan after reset): every answer equals an independent cold projection, and the hints were
// used (certificates reused in place, carried with their own points, borrowed, forgotten at
// reset).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <limits>
#include <random>
#include <vector>

#include "finder_checks.hpp"
#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

class ModelFinderHints : public ::testing::Test {
 protected:
  ModelFinderHints() : prepared_(model()), reference_(prepared_) {
    // Points near the sheet (within 0.3 of it) and a few far above it.
    std::mt19937_64 rng(17);
    const engine::NurbsSurface& s = prepared_.model().surfaces.front();
    for (int i = 0; i < 4000; ++i) {
      const double u = test::uniform(rng, s.domain_u().lo, s.domain_u().hi);
      const double v = test::uniform(rng, s.domain_v().lo, s.domain_v().hi);
      const double h = i % 10 == 0 ? test::uniform(rng, 1.0, 5.0) : test::uniform(rng, -0.3, 0.3);
      scan_.push_back(s.evaluate(u, v) + Vec3(0, 0, h));
    }
  }
  static engine::Model model() {
    engine::Model m;
    m.surfaces.push_back(test::random_surface(23, 3, 3, 9, 9, false));
    return m;
  }

  // The scan points `ids` (all when empty) moved by `shift`, answered by `finder`; checks every
  // answer against a cold projection and returns the finder's counters.
  engine::ProjectionCounters find_and_check(ModelCorrespondenceFinder& finder,
                                            const std::vector<std::size_t>& ids, double shift,
                                            double expected_motion) {
    std::vector<Vec3> points;
    if (ids.empty()) {
      for (const Vec3& p : scan_)
        points.push_back(p + Vec3(shift, -0.5 * shift, shift));
    } else {
      for (const std::size_t i : ids)
        points.push_back(scan_[i] + Vec3(shift, -0.5 * shift, shift));
    }
    return find_checked(finder, reference_, 1e-10 * prepared_.bounds().diagonal(), ids, points,
                        expected_motion, 1e-7);
  }

  std::vector<std::size_t> every(std::size_t step, std::size_t offset) const {
    std::vector<std::size_t> ids;
    for (std::size_t i = offset; i < scan_.size(); i += step)
      ids.push_back(i);
    return ids;
  }

  static constexpr double kUnknown = std::numeric_limits<double>::infinity();
  engine::PreparedModel prepared_;
  engine::Projector reference_;
  std::vector<Vec3> scan_;
};

// Without certificates: the previous feet seed the search (engine warm start), in place for a
// repeated query and carried for the shared points of a superset. A warm start changes the work
// (the Newton iterations), never the answers, so the counters tell whether hints arrived: they
// must differ from a finder without history on the same query.
TEST_F(ModelFinderHints, PreviousFeetSeedRepeatedAndSupersetQueries) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const std::vector<std::size_t> coarse = every(10, 3);
  const std::vector<std::size_t> superset = every(2, 1);  // odd: holds coarse
  const auto fresh_counters = [&](const std::vector<std::size_t>& ids, double shift) {
    ModelCorrespondenceFinder fresh(prepared_);
    fresh.reset(scan_.size());
    return find_and_check(fresh, ids, shift, kUnknown);
  };
  ModelCorrespondenceFinder finder(prepared_);
  finder.reset(scan_.size());
  find_and_check(finder, coarse, 0.0, kUnknown);
  EXPECT_NE(find_and_check(finder, coarse, 1e-4, kUnknown).newton_iterations,
            fresh_counters(coarse, 1e-4).newton_iterations);
  EXPECT_NE(find_and_check(finder, superset, 2e-4, kUnknown).newton_iterations,
            fresh_counters(superset, 2e-4).newton_iterations);
  EXPECT_NE(find_and_check(finder, {}, 3e-4, kUnknown).newton_iterations,
            fresh_counters({}, 3e-4).newton_iterations);
  EXPECT_NE(find_and_check(finder, {}, 4e-4, kUnknown).newton_iterations,
            fresh_counters({}, 4e-4).newton_iterations);
  // After reset() the same work as without history.
  finder.reset(scan_.size());
  EXPECT_EQ(find_and_check(finder, coarse, 1e-4, kUnknown).newton_iterations,
            fresh_counters(coarse, 1e-4).newton_iterations);
}

// Certificates (small expected motion on a subsample) are made, reused in place, carried to a
// superset query (each point its own: the anchor is its own earlier position; the atlas could
// supply the same, so the bare-hint test above is the one that catches a lost carry), kept through
// full-resolution queries, and forgotten at reset().
TEST_F(ModelFinderHints, CertificatesAreReusedInPlaceCarriedAndForgotten) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const std::vector<std::size_t> coarse = every(10, 3);
  const std::vector<std::size_t> superset = every(2, 1);      // odd: holds coarse
  const double small = 1e-5 * prepared_.bounds().diagonal();  // below half the radius cap
  ModelCorrespondenceFinder finder(prepared_);
  finder.reset(scan_.size());
  EXPECT_EQ(find_and_check(finder, coarse, 0.0, kUnknown).certified, 0u);
  const engine::ProjectionCounters made = find_and_check(finder, coarse, 1e-4, small);
  EXPECT_GT(made.certificates_made, coarse.size() * 3 / 4);
  // In place: certificates anchored at the previous query's points prove most answers.
  const engine::ProjectionCounters proven = find_and_check(finder, coarse, 2e-4, kUnknown);
  EXPECT_GT(proven.certified, coarse.size() * 3 / 4);
  // Carried: the superset's coarse points are proven by their own certificates.
  find_and_check(finder, superset, 3e-4, kUnknown);
  const engine::ProjectionResults& r = finder.last_results();
  std::size_t own = 0, coarse_certified = 0;
  for (std::size_t k = 0, c = 0; k < superset.size(); ++k) {
    if (c == coarse.size() || superset[k] != coarse[c]) continue;
    ++c;
    if (r.certificate[k].radius <= 0.0f) continue;
    ++coarse_certified;
    const Vec3 made_at = scan_[superset[k]] + Vec3(1e-4, -0.5e-4, 1e-4);
    if (r.certificate[k].anchor == made_at.cast<float>()) ++own;
  }
  EXPECT_GT(coarse_certified, coarse.size() * 3 / 4);
  EXPECT_EQ(own, coarse_certified);
  // Borrowed: the even points (none of them certified) from the atlas, then kept through all
  // points (scan_indices empty) and all again in place, then a query naming scan point 7 twice.
  const engine::ProjectionCounters borrowed = find_and_check(finder, every(2, 0), 4e-4, kUnknown);
  EXPECT_GT(borrowed.certified, 0u);
  // (Only the previous query's answers carry over: the odd points borrow from the atlas too.)
  const engine::ProjectionCounters all = find_and_check(finder, {}, 5e-4, kUnknown);
  EXPECT_GT(all.certified, coarse.size() / 2);
  const engine::ProjectionCounters all_again = find_and_check(finder, {}, 6e-4, kUnknown);
  EXPECT_GT(all_again.certified, all.certified * 9 / 10);
  find_and_check(finder, {7, 7, 8}, 7e-4, kUnknown);
  // A new scan: no certificate survives reset().
  finder.reset(scan_.size());
  EXPECT_EQ(find_and_check(finder, coarse, 2e-4, kUnknown).certified, 0u);
}

// A session's frames (keep_certificates): after reset() for a new scan, the first query borrows
// the certificates made for the scan before (a cold finder proves none; the sheet is large for
// 400 anchors, so only some points lie in a borrowed ball), and every answer is
// still the exact closest point; a finder that stops keeping them forgets them at the next reset.
TEST_F(ModelFinderHints, KeptCertificatesProveTheNextScansFirstQuery) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const std::vector<std::size_t> coarse = every(10, 3);
  const double small = 1e-5 * prepared_.bounds().diagonal();
  ModelCorrespondenceFinder finder(prepared_);
  finder.keep_certificates(true);
  finder.reset(scan_.size());
  find_and_check(finder, coarse, 0.0, kUnknown);
  EXPECT_GT(find_and_check(finder, coarse, 1e-4, small).certificates_made, coarse.size() * 3 / 4);
  // The next frame: other scan points (the odd ones, none of them in `coarse`), a new pose.
  finder.reset(scan_.size());
  const engine::ProjectionCounters next = find_and_check(finder, every(2, 0), 2e-4, kUnknown);
  EXPECT_GT(next.certified, 0u);
  finder.keep_certificates(false);
  finder.reset(scan_.size());
  EXPECT_EQ(find_and_check(finder, every(2, 0), 3e-4, kUnknown).certified, 0u);
}

}  // namespace
}  // namespace nurbsreg::icp
