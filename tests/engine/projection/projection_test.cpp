// The batch projector over a prepared multi-surface model: exact (equal to the best of the
// single-surface projectors, and to an independent brute force on a subset), the same for any
// thread count and with or without hints (even wrong ones), and NaN points skipped.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <limits>
#include <stdexcept>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// Three touching and overlapping surfaces: a freeform sheet, a sphere resting on it and a torus
// around the sphere, so many points are nearly equidistant from two entities.
Model mixed_model() {
  Model m;
  NurbsSurface sheet = test::random_surface(11, 3, 3, 8, 8, true);
  for (Vec3& p : sheet.control_points)
    p = Vec3(p.x() - 3.5, p.y() - 3.5, 0.3 * p.z());
  sheet.name = "sheet";
  m.surfaces.push_back(sheet);
  m.surfaces.push_back(make_sphere(Vec3(0, 0, 1.5), 1.5));
  m.surfaces.push_back(make_torus(Vec3(0, 0, 1.5), 2.5, 0.5));
  m.curves.push_back(make_circle(Vec3(0, 0, 3.0), 2.0));
  m.curves.push_back(test::random_curve(5, 3, 12, true));
  return m;
}

std::vector<Vec3> query_points(const Aabb& box, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Vec3 lo = box.lo - 0.2 * (box.hi - box.lo);
  const Vec3 hi = box.hi + 0.2 * (box.hi - box.lo);
  std::vector<Vec3> points(n);
  for (Vec3& p : points)
    p = test::uniform_point(rng, lo, hi);
  return points;
}

// Entry i of two result sets is bit-identical: every field, the certificate's too (the answer's
// fields only for points answered `ok`).
::testing::AssertionResult same_entry(const ProjectionResults& a, const ProjectionResults& b,
                                      std::size_t i) {
  const WarmCertificate& x = a.certificate[i];
  const WarmCertificate& y = b.certificate[i];
  const bool same_certificate = x.anchor == y.anchor && x.radius == y.radius &&
                                x.clearance == y.clearance && x.patch == y.patch && x.s0 == y.s0 &&
                                x.s1 == y.s1 && x.t0 == y.t0 && x.t1 == y.t1 && x.model == y.model;
  const bool same_answer =
      a.status[i] != ProjectionStatus::ok ||
      (a.distance[i] == b.distance[i] && a.signed_distance[i] == b.signed_distance[i] &&
       a.entity[i] == b.entity[i] && a.u[i] == b.u[i] && a.v[i] == b.v[i] &&
       a.foot[i] == b.foot[i] && a.normal[i] == b.normal[i] &&
       a.on_trim_edge[i] == b.on_trim_edge[i]);
  if (a.status[i] == b.status[i] && same_answer && same_certificate) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure()
         << "entry " << i << " differs: distance " << a.distance[i] << " vs " << b.distance[i]
         << (same_certificate ? "" : " (certificates differ)");
}

// The hints of `results` read in place: point i's is results.hint(i).
HintView hints_of(const ProjectionResults& results) {
  return HintView(&results, results.size(), [](const void* d, std::size_t i) {
    return static_cast<const ProjectionResults*>(d)->hint(i);
  });
}

class ProjectionTest : public ::testing::Test {
 protected:
  ProjectionTest() : prepared_(mixed_model()), points_(query_points(prepared_.bounds(), 3000, 7)) {}
  void foot_sink_case(std::vector<Vec3> points);
  PreparedModel prepared_;
  std::vector<Vec3> points_;
};

TEST_F(ProjectionTest, EqualsTheBestSingleSurfaceProjection) {
  Projector projector(prepared_);
  ProjectionResults results;
  projector.project(PointView::of(points_), {}, results);
  std::vector<SurfaceProjector> singles;
  for (const NurbsSurface& s : prepared_.model().surfaces)
    singles.emplace_back(s);
  SurfaceScratch scratch;
  const double tolerance = 1e-9 * prepared_.bounds().diagonal();
  for (std::size_t i = 0; i < points_.size(); ++i) {
    ASSERT_EQ(results.status[i], ProjectionStatus::ok);
    double best = std::numeric_limits<double>::infinity();
    for (const SurfaceProjector& single : singles) {
      best = std::min(
          best, std::sqrt(single.project(points_[i], SurfaceStrategy::spherical_clipping, scratch)
                              .distance_sq));
    }
    EXPECT_NEAR(results.distance[i], best, tolerance) << "point " << i;
    // The reported foot is on the reported surface at the reported parameters.
    const NurbsSurface& s = prepared_.model().surfaces[results.entity[i]];
    EXPECT_LT((s.evaluate(results.u[i], results.v[i]) - results.foot[i]).norm(), tolerance);
    EXPECT_NEAR((points_[i] - results.foot[i]).norm(), results.distance[i], tolerance);
    EXPECT_NEAR(results.normal[i].norm(), 1.0, 1e-12);
    EXPECT_NEAR(std::abs(results.signed_distance[i]), results.distance[i], 0.0);
  }
}

TEST_F(ProjectionTest, SameResultsForAnyThreadCountAndSerial) {
  ProjectionResults serial;
  ProjectionResults one;
  ProjectionResults two;
  {
    Projector projector(prepared_);
    projector.project_serial(PointView::of(points_), {}, serial);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    Projector projector(prepared_);
    projector.project(PointView::of(points_), {}, one);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    Projector projector(prepared_);
    ProjectionOptions options;
    options.grain = 7;  // many small tasks: maximal interleaving
    projector.project(PointView::of(points_), options, two);
  }
  for (std::size_t i = 0; i < points_.size(); ++i) {
    ASSERT_EQ(serial.distance[i], one.distance[i]);
    ASSERT_EQ(serial.distance[i], two.distance[i]);
    ASSERT_EQ(serial.u[i], two.u[i]);
    ASSERT_EQ(serial.v[i], two.v[i]);
    ASSERT_EQ(serial.entity[i], two.entity[i]);
  }
}

// A frame large enough to be processed in locality order (ProjectionOptions::locality_order,
// 8192 points and more): every point is projected once, with the same answer as in index order.
TEST_F(ProjectionTest, LocalityOrderChangesNoResult) {
  std::vector<Vec3> frame = query_points(prepared_.bounds(), 12000, 31);
  // Non-finite points mixed in (the ordering puts them first; they must stay skipped).
  for (std::size_t i = 0; i < frame.size(); i += 997)
    frame[i] = Vec3(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);
  ProjectionOptions options;
  options.certify = true;  // the certificates must follow their points too
  ProjectionResults in_order;
  ProjectionResults ordered;
  Projector projector(prepared_);
  {
    ProjectionOptions plain = options;
    plain.locality_order = false;
    projector.project(PointView::of(frame), plain, in_order);
  }
  {
    // Stale answers for other points first: a point the ordered pass skipped would keep one.
    const std::vector<Vec3> other = query_points(prepared_.bounds(), frame.size(), 32);
    projector.project(PointView::of(other), options, ordered);
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    ProjectionOptions small_tasks = options;
    small_tasks.grain = 7;
    projector.project(PointView::of(frame), small_tasks, ordered);
  }
  std::size_t skipped = 0;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    ASSERT_TRUE(same_entry(in_order, ordered, i));
    if (in_order.status[i] != ProjectionStatus::ok) ++skipped;
  }
  EXPECT_EQ(skipped, (frame.size() + 996) / 997);
}

TEST_F(ProjectionTest, WarmStartsStayExactEvenWithWrongHints) {
  Projector projector(prepared_);
  ProjectionResults cold;
  projector.project(PointView::of(points_), {}, cold);
  // Good hints: the feet of slightly perturbed points (as in ICP).
  std::mt19937_64 rng(3);
  std::vector<Vec3> moved(points_);
  for (Vec3& p : moved)
    p += Vec3(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)) * 1e-3;
  ProjectionResults previous;
  projector.project(PointView::of(moved), {}, previous);
  std::vector<ProjectionHint> good(points_.size());
  std::vector<ProjectionHint> wrong(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) {
    good[i] = previous.hint(i);
    wrong[i] = {static_cast<std::int32_t>(rng() % 3), uniform(rng, 0, 1), uniform(rng, 0, 1)};
  }
  ProjectionCounters cold_counters;
  ProjectionCounters warm_counters;
  projector.project(PointView::of(points_), {}, cold, {}, &cold_counters);
  ProjectionResults warm;
  projector.project(PointView::of(points_), {}, warm, good, &warm_counters);
  ProjectionResults misled;
  projector.project(PointView::of(points_), {}, misled, wrong);
  const double tolerance = 1e-9 * prepared_.bounds().diagonal();
  for (std::size_t i = 0; i < points_.size(); ++i) {
    EXPECT_NEAR(warm.distance[i], cold.distance[i], tolerance) << i;
    EXPECT_NEAR(misled.distance[i], cold.distance[i], tolerance) << i;
  }
  // The hint's tight alpha never makes the walk visit more patches; with a good cold visiting
  // order (best-first by each patch's own bound) it visits as few, and the gain is in Newton.
  EXPECT_LE(warm_counters.patches_visited, cold_counters.patches_visited);
  EXPECT_LT(warm_counters.newton_iterations, cold_counters.newton_iterations);
}

// HintView: hints read in place from the very results being written (the previous pass's
// answers, ProjectionResults::hint) give the same answers, certificates and work as the same
// hints copied into an array first; with 2 threads and small tasks, so a point reading another
// point's entry (or one already overwritten) would show.
TEST_F(ProjectionTest, HintsReadInPlaceFromTheResultsEqualCopiedHints) {
  // Certificates need polynomial patches: a sheet like mixed_model's, not rational.
  Model sheet;
  sheet.surfaces.push_back(test::random_surface(11, 3, 3, 8, 8, false));
  const PreparedModel prepared(std::move(sheet));
  const std::vector<Vec3> points = query_points(prepared.bounds(), 3000, 9);
  ProjectionOptions options;
  options.certify = true;
  options.grain = 5;
  Projector projector(prepared);
  ProjectionResults first;
  projector.project(PointView::of(points), options, first);
  std::mt19937_64 rng(5);
  std::vector<Vec3> moved(points);
  for (Vec3& p : moved)
    p += Vec3(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)) * 1e-4;
  std::vector<ProjectionHint> copied(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    copied[i] = first.hint(i);

  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  ProjectionResults from_array;
  ProjectionCounters array_counters;
  projector.project(PointView::of(moved), options, from_array, copied, &array_counters);
  ProjectionResults in_place = first;
  const HintView own = hints_of(in_place);
  ProjectionCounters in_place_counters;
  projector.project(PointView::of(moved), options, in_place, own, &in_place_counters);
  // The same on the calling thread only.
  ProjectionResults serial_in_place = first;
  const HintView serial_own = hints_of(serial_in_place);
  projector.project_serial(PointView::of(moved), options, serial_in_place, serial_own);

  ASSERT_GT(array_counters.certified, points.size() / 4);  // the certificates were used
  EXPECT_EQ(in_place_counters.certified, array_counters.certified);
  EXPECT_EQ(in_place_counters.certificates_made, array_counters.certificates_made);
  EXPECT_EQ(in_place_counters.patches_visited, array_counters.patches_visited);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_TRUE(same_entry(in_place, from_array, i));
    ASSERT_TRUE(same_entry(serial_in_place, from_array, i));
  }
}

// FootSink: feet and normals go to the caller's records instead of the results (which keep no
// foot or normal), bit for bit the same values, once per point answered `ok` and never for the
// others; every other field unchanged. Surfaces and curves, NaN points, 2 threads; a frame in
// index order and one large enough for the locality order (whose blocks are projected apart and
// must tell the sink each point's own index).
TEST_F(ProjectionTest, FootSinkGetsTheFeetAndNormalsOfAnsweredPoints) {
  for (const std::size_t n : {points_.size(), std::size_t{12000}}) {
    foot_sink_case(n == points_.size() ? points_ : query_points(prepared_.bounds(), n, 41));
  }
}

void ProjectionTest::foot_sink_case(std::vector<Vec3> points) {
  for (std::size_t i = 0; i < points.size(); i += 97)
    points[i] = Vec3(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);
  struct Record {
    Vec3 foot = Vec3::Constant(-7.0);
    Vec3 normal = Vec3::Constant(-7.0);
    int calls = 0;
  };
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  Projector projector(prepared_);
  for (const ProjectionTarget target : {ProjectionTarget::surfaces, ProjectionTarget::curves}) {
    ProjectionOptions options;
    options.target = target;
    options.grain = 5;
    ProjectionResults plain;
    projector.project(PointView::of(points), options, plain);
    std::vector<Record> records(points.size());
    options.foot_sink = {records.data(),
                         [](void* data, std::size_t i, const Vec3& foot, const Vec3& normal) {
                           Record& r = static_cast<Record*>(data)[i];
                           r.foot = foot;
                           r.normal = normal;
                           ++r.calls;
                         }};
    ProjectionResults sunk = plain;  // stale feet must not survive
    projector.project(PointView::of(points), options, sunk);
    EXPECT_TRUE(sunk.foot.empty());
    EXPECT_TRUE(sunk.normal.empty());
    ASSERT_EQ(sunk.size(), points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_EQ(sunk.status[i], plain.status[i]) << i;
      if (plain.status[i] != ProjectionStatus::ok) {
        EXPECT_EQ(records[i].calls, 0) << i;
        continue;
      }
      ASSERT_EQ(records[i].calls, 1) << i;
      EXPECT_EQ(records[i].foot, plain.foot[i]) << i;
      EXPECT_EQ(records[i].normal, plain.normal[i]) << i;
      EXPECT_EQ(sunk.distance[i], plain.distance[i]) << i;
      EXPECT_EQ(sunk.signed_distance[i], plain.signed_distance[i]) << i;
      EXPECT_EQ(sunk.entity[i], plain.entity[i]) << i;
      EXPECT_EQ(sunk.u[i], plain.u[i]) << i;
      EXPECT_EQ(sunk.v[i], plain.v[i]) << i;
    }
  }
}

// The certificate array exists only for frames that can have certificates (certifying, or with
// hints that may carry them); hint(i) of a frame without one carries none.
TEST_F(ProjectionTest, CertificatesAreKeptOnlyWhenAFrameCanHaveThem) {
  Projector projector(prepared_);
  ProjectionResults cold;
  projector.project(PointView::of(points_), {}, cold);
  EXPECT_TRUE(cold.certificate.empty());
  EXPECT_EQ(cold.hint(0).certificate.radius, 0.0f);
  EXPECT_EQ(cold.hint(0).entity, cold.entity[0]);
  std::vector<ProjectionHint> hints(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i)
    hints[i] = cold.hint(i);
  ProjectionResults warm;
  projector.project(PointView::of(points_), {}, warm, hints);
  EXPECT_EQ(warm.certificate.size(), points_.size());
  ProjectionOptions certify;
  certify.certify = true;
  ProjectionResults certifying = cold;
  projector.project(PointView::of(points_), certify, certifying);
  EXPECT_EQ(certifying.certificate.size(), points_.size());
  // Warm starts reach the same minima by other Newton paths: equal to rounding.
  const double tolerance = 1e-9 * prepared_.bounds().diagonal();
  for (std::size_t i = 0; i < points_.size(); ++i) {
    EXPECT_NEAR(warm.distance[i], cold.distance[i], tolerance) << i;
    EXPECT_EQ(certifying.distance[i], cold.distance[i]) << i;
  }
}

TEST_F(ProjectionTest, HintCountMustMatchThePoints) {
  Projector projector(prepared_);
  ProjectionResults out;
  const std::vector<ProjectionHint> hints(points_.size() - 1);
  EXPECT_THROW(projector.project(PointView::of(points_), {}, out, hints), std::invalid_argument);
  EXPECT_THROW(projector.project_serial(PointView::of(points_), {}, out, hints),
               std::invalid_argument);
}

TEST_F(ProjectionTest, CertificateSpanOutsideItsRangeIsRejected) {
  Projector projector(prepared_);
  ProjectionResults out;
  for (const int span : {0, kMaxCertificateSpan + 1}) {
    ProjectionOptions options;
    options.certify = true;
    options.certificate_span = span;
    try {
      projector.project(PointView::of(points_), options, out);
      ADD_FAILURE() << "span " << span << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("certificate_span"), std::string::npos) << e.what();
    }
  }
  ProjectionOptions widest;
  widest.certify = true;
  widest.certificate_span = kMaxCertificateSpan;
  EXPECT_NO_THROW(projector.project(PointView::of(points_), widest, out));
}

TEST_F(ProjectionTest, NonFinitePointsAreSkippedAndCounted) {
  std::vector<Vec3> points(points_.begin(), points_.begin() + 10);
  points[3].x() = std::numeric_limits<double>::quiet_NaN();
  points[7].z() = std::numeric_limits<double>::infinity();
  Projector projector(prepared_);
  ProjectionResults results;
  ProjectionCounters counters;
  projector.project(PointView::of(points), {}, results, {}, &counters);
  EXPECT_EQ(counters.points, 10u);
  EXPECT_EQ(counters.skipped, 2u);
  EXPECT_EQ(results.status[3], ProjectionStatus::skipped_nonfinite);
  EXPECT_EQ(results.status[7], ProjectionStatus::skipped_nonfinite);
  EXPECT_EQ(results.status[4], ProjectionStatus::ok);
}

TEST_F(ProjectionTest, CurvesTargetEqualsBestSingleCurve) {
  Projector projector(prepared_);
  ProjectionOptions options;
  options.target = ProjectionTarget::curves;
  ProjectionResults results;
  projector.project(PointView::of(points_), options, results);
  std::vector<CurveProjector> singles;
  for (const NurbsCurve& c : prepared_.model().curves)
    singles.emplace_back(c);
  const double tolerance = 1e-9 * prepared_.bounds().diagonal();
  for (std::size_t i = 0; i < points_.size(); i += 3) {
    double best = std::numeric_limits<double>::infinity();
    for (const CurveProjector& single : singles) {
      best = std::min(best, std::sqrt(single.project(points_[i]).distance_sq));
    }
    EXPECT_NEAR(results.distance[i], best, tolerance);
    EXPECT_EQ(results.v[i], 0.0);
  }
}

TEST_F(ProjectionTest, MaxDistanceLeavesFarPointsOut) {
  Projector projector(prepared_);
  ProjectionResults all;
  projector.project(PointView::of(points_), {}, all);
  ProjectionOptions options;
  options.max_distance = 0.5;
  ProjectionResults near;
  std::vector<ProjectionHint> hints(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i)
    hints[i] = all.hint(i);  // hints beyond too
  projector.project(PointView::of(points_), options, near, hints);
  std::size_t beyond = 0;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    if (all.distance[i] < 0.5 * (1 - 1e-9)) {
      ASSERT_EQ(near.status[i], ProjectionStatus::ok) << i;
      EXPECT_NEAR(near.distance[i], all.distance[i], 1e-9 * prepared_.bounds().diagonal());
    } else if (all.distance[i] > 0.5 * (1 + 1e-9)) {
      EXPECT_EQ(near.status[i], ProjectionStatus::beyond_max_distance) << i;
      ++beyond;
    }
  }
  EXPECT_GT(beyond, 100u);
}

TEST(PreparedModel, RejectsInvalidModels) {
  Model empty;
  EXPECT_THROW(PreparedModel{empty}, std::invalid_argument);
}

// A few entries projected again go back in place: every field the results hold, feet kept
// where the part has none, certificates cleared where it has none; sizes are checked.
TEST(ProjectionResults, ScatterFromPutsEachEntryAtItsIndex) {
  ProjectionResults into;
  into.resize(5);
  for (std::size_t i = 0; i < 5; ++i) {
    into.distance[i] = static_cast<double>(i);
    into.foot[i] = Vec3::Constant(static_cast<double>(i));
    into.certificate[i].patch = static_cast<std::int32_t>(i);
  }
  ProjectionResults part;
  part.resize(2, /*feet=*/false, /*certificates=*/false);
  part.distance[0] = 30.0;
  part.distance[1] = 10.0;
  part.entity[0] = 7;
  part.u[1] = 0.25;
  part.status[0] = ProjectionStatus::ok;
  const std::size_t ids[] = {3, 1};
  into.scatter_from(part, ids);
  EXPECT_EQ(into.distance[3], 30.0);
  EXPECT_EQ(into.distance[1], 10.0);
  EXPECT_EQ(into.distance[2], 2.0);
  EXPECT_EQ(into.entity[3], 7);
  EXPECT_EQ(into.u[1], 0.25);
  EXPECT_EQ(into.status[3], ProjectionStatus::ok);
  EXPECT_EQ(into.foot[3], Vec3::Constant(3.0));  // the part has no feet: kept
  EXPECT_EQ(into.certificate[3].patch, -1);      // no certificate for the new answer
  EXPECT_EQ(into.certificate[2].patch, 2);
  const std::size_t too_far[] = {3, 5};
  EXPECT_THROW(into.scatter_from(part, too_far), std::logic_error);
  const std::size_t one[] = {0};
  EXPECT_THROW(into.scatter_from(part, one), std::logic_error);
}

}  // namespace
}  // namespace nurbsreg::engine
