// Warm certificates on real trimmed CAD faces (issue 26): a frame certified on anchor points,
// then a frame of moved points hinted by its answers, against a cold projection of the moved
// points. The hard cases are the ones the certificates must not get wrong:
//  - anchors whose feet lie near a trim loop (boxes N must stay inside the face), moved by up to
//    1.5 times what their certificate proves and by 0.9 of its radius, towards and across the
//    boundary;
//  - points on both sides of every face, up to 0.5% of the diagonal off it: inside the blade's
//    thin trailing edge (IEA 15 MW) two sheets are that close; hammer's faces are mostly
//    rational.
// Checked claim by claim, with nothing of the certificate code: every certificate's box N, on
// a dense grid over each patch it covers, maps to points of the face (TrimRegion::contains, the
// exact ray-crossing test); every warm answer equals the cold one (within 1e-9 of the diagonal,
// as the other CAD tests); the warm frame is bit-identical on 1 and 2 threads; and certificates
// really prove answers there (not vacuous). Mutations tried (bench/README.md, issue 26, fourth
// pass): box_in_region always true fails the box check; the proof without the query's move
// (sqrt(f) <= clearance) fails the answers check.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/sampling.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

using engine::Vec3;

struct WarmCase {
  const char* name;
  const char* file;  // under shared/data/real
  std::size_t points;
  double cap;  // the certificate radius cap, a share of the diagonal
};

const WarmCase kCases[] = {
    // ICP's cap (icp::ModelCorrespondenceFinder); on the blade the projector's default, under
    // which its thin sheets still leave certificates something to prove.
    {"bearing", "occt/bearing.iges", 600, 1e-2},
    {"hammer", "occt/hammer.iges", 600, 1e-2},
    {"iea15mw", "iea-15mw/IEA_15MW_CFD.stp", 600, 1e-3},
};

void PrintTo(const WarmCase& c, std::ostream* os) {
  *os << c.name;
}

// Is the sample near a trim loop of its face: does the box of 3% of the domain about it meet a
// loop (the region's grid cannot prove it inside)?
bool near_loop(const engine::PreparedModel& pm, const engine::SurfaceSample& s) {
  const engine::TrimRegion* region = pm.surface_region(s.surface);
  if (region == nullptr) return false;
  const engine::NurbsSurface& surface = pm.model().surfaces[static_cast<std::size_t>(s.surface)];
  const double hu = 0.03 * surface.domain_u().width(), hv = 0.03 * surface.domain_v().width();
  return region->classify(s.u - hu, s.u + hu, s.v - hv, s.v + hv) != engine::RegionClass::inside;
}

// Anchors: face samples offset along the normal by up to 0.5% of the diagonal (both sides: the
// benchmarks' scan noise), half of them near a trim loop.
std::vector<Vec3> anchors(const engine::PreparedModel& pm, std::size_t count, double diagonal,
                          std::uint64_t seed) {
  const std::vector<engine::SurfaceSample> samples =
      engine::sample_surfaces(pm.model(), 8 * count, seed);
  std::vector<const engine::SurfaceSample*> near, far;
  for (const engine::SurfaceSample& s : samples)
    (near_loop(pm, s) ? near : far).push_back(&s);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> offset(-0.005 * diagonal, 0.005 * diagonal);
  std::vector<Vec3> points;
  for (std::size_t i = 0; i < count; ++i) {
    const std::vector<const engine::SurfaceSample*>& from =
        (i % 2 == 0 && !near.empty()) ? near : far;
    const engine::SurfaceSample& s = *from[(i / 2) % from.size()];
    points.push_back(s.point + offset(rng) * s.normal);
  }
  return points;
}

// Every point of a certificate's box N (a grid over each patch it covers, in the anchor patch's
// grid coordinates) is in the face's region. Returns the number of boxes checked.
int check_boxes(const engine::PreparedModel& pm, const engine::ProjectionResults& made,
                const char* name) {
  int checked = 0;
  for (std::size_t i = 0; i < made.size(); ++i) {
    if (made.certificate.empty() || !(made.certificate[i].radius > 0.0f)) continue;
    const engine::WarmCertificate& c = made.certificate[i];
    const std::size_t anchor = static_cast<std::size_t>(c.patch);
    const int surface = pm.patch_surface(anchor);
    const engine::TrimRegion* region = pm.surface_region(surface);
    if (region == nullptr) continue;
    ++checked;
    const engine::PreparedModel::SpanCell at = pm.patch_span(anchor);
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        const double s0 = std::max<double>(c.s0, di), s1 = std::min<double>(c.s1, di + 1.0);
        const double t0 = std::max<double>(c.t0, dj), t1 = std::min<double>(c.t1, dj + 1.0);
        if (!(s1 > s0 && t1 > t0)) continue;
        const std::int64_t k = pm.patch_at(surface, at.a + di, at.b + dj);
        if (k < 0) {
          ADD_FAILURE() << name << ": certificate " << i << " covers no patch";
          return checked;
        }
        const engine::BezierPatch& bp = pm.patch(static_cast<std::size_t>(k)).patch;
        constexpr int kGrid = 12;
        for (int a = 0; a <= kGrid; ++a) {
          for (int b = 0; b <= kGrid; ++b) {
            const double s = s0 + (s1 - s0) * a / kGrid - di;
            const double t = t0 + (t1 - t0) * b / kGrid - dj;
            const double u = bp.param_u.to_parent(s), v = bp.param_v.to_parent(t);
            if (!region->contains(u, v)) {
              ADD_FAILURE() << name << ": certificate " << i << "'s box leaves the face at (" << u
                            << ", " << v << ")";
              return checked;
            }
          }
        }
      }
    }
  }
  return checked;
}

struct WarmOutcome {
  unsigned long long certified = 0;  // warm answers proven by a certificate
  std::size_t near_certified = 0;    // ... of points with an even index (near a trim loop)
};

// Moves every point in a random direction by 0.5, 0.99 and 1.5 times what its certificate serves
// (the move m it proves when the query's distance is at most d + m: (clearance - d) / 2, at most
// the radius) and 0.9 times its radius (inside its ball, mostly beyond what it proves: the check
// must refuse); points without one move by 1e-3 of the diagonal. The moved points, hinted by
// `made`, must get the cold answers, the same bits on 1 and 2 threads.
WarmOutcome warm_equals_cold(const engine::PreparedModel& pm, const std::vector<Vec3>& points,
                             const engine::ProjectionResults& made, const char* name) {
  const double diagonal = pm.geometry_bounds().box.diagonal();
  const double tol = 1e-9 * diagonal;
  std::mt19937_64 rng(0x26b);
  std::normal_distribution<double> gauss;
  std::vector<Vec3> moved(points.size());
  std::vector<engine::ProjectionHint> hints(points.size());
  const double factors[3] = {0.5, 0.99, 1.5};
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 direction = Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const engine::WarmCertificate& w = made.certificate[i];
    const double serves =
        std::min<double>(w.radius, 0.5 * (double(w.clearance) - made.distance[i]));
    const double step = !(w.radius > 0.0f) ? 1e-3 * diagonal
                        : i % 4 == 3       ? 0.9 * w.radius
                                           : factors[i % 4] * serves;
    moved[i] = points[i] + step * direction;
    hints[i] = made.hint(i);
  }
  engine::Projector projector(pm);
  engine::ProjectionResults warm, warm_serial, cold;
  engine::ProjectionCounters counters;
  projector.project(engine::PointView::of(moved), {}, warm, hints, &counters);
  projector.project(engine::PointView::of(moved), {}, cold);
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    engine::Projector serial(pm);
    serial.project(engine::PointView::of(moved), {}, warm_serial, hints);
  }
  WarmOutcome outcome;
  outcome.certified = counters.certified;
  for (std::size_t i = 0; i < moved.size(); ++i) {
    EXPECT_EQ(warm.status[i], cold.status[i]) << name << " point " << i;
    if (warm.status[i] != cold.status[i] || warm.status[i] != engine::ProjectionStatus::ok) {
      continue;
    }
    EXPECT_NEAR(warm.distance[i], cold.distance[i], tol)
        << name << " point " << i << ", certificate radius " << made.certificate[i].radius
        << ", moved by " << (moved[i] - points[i]).norm();
    // 1 and 2 threads: the same bits.
    EXPECT_EQ(warm.distance[i], warm_serial.distance[i]) << name << " point " << i;
    EXPECT_EQ(warm.entity[i], warm_serial.entity[i]);
    EXPECT_EQ(warm.u[i], warm_serial.u[i]);
    EXPECT_EQ(warm.v[i], warm_serial.v[i]);
    const bool proven =
        warm.certificate[i].radius > 0.0f && warm.certificate[i].anchor != moved[i].cast<float>();
    outcome.near_certified += proven && i % 2 == 0;
  }
  return outcome;
}

class CadWarmCertificate : public testing::TestWithParam<WarmCase> {};

TEST_P(CadWarmCertificate, CertifiedAnswersEqualColdOnesNearTrimLoopsAndCloseSheets) {
  const WarmCase& c = GetParam();
  const std::string path = nurbsreg::test::shared_dir() + "/data/real/" + c.file;
  const engine::PreparedModel pm(read_model_file(path));
  const double diagonal = pm.geometry_bounds().box.diagonal();
  const std::vector<Vec3> points = anchors(pm, c.points, diagonal, 0x26a);

  engine::ProjectionOptions certify;
  certify.certify = true;
  certify.certificate_radius = c.cap * diagonal;
  engine::Projector projector(pm);
  engine::ProjectionResults made;
  projector.project(engine::PointView::of(points), certify, made);
  const int boxes = check_boxes(pm, made, c.name);
  if (testing::Test::HasFatalFailure()) return;

  const WarmOutcome warm = warm_equals_cold(pm, points, made, c.name);
  std::printf(
      "[%s] %zu points: %d boxes on trimmed faces checked, %llu warm answers certified (%zu of "
      "them near a trim loop)\n",
      c.name, points.size(), boxes, warm.certified, warm.near_certified);
  // Not vacuous: certificates prove a good share of the moved points, near loops too.
  EXPECT_GT(warm.certified, points.size() / 10) << c.name;
  EXPECT_GT(warm.near_certified, points.size() / 40) << c.name;
}

// The bearing's long thin faces (fillet strips: ruled faces about 30 mm long and 4 mm wide, where
// the scan's points lie a hair off the surface, as in ICP) get certificates, and they hold. Two
// things left every such point without one: boxes N square in the patch's parameters (on a strip
// several times longer in space than wide, the tiles beside N reach back under the foot and their
// Bernstein bounds fall below zero: no clearance), and a certifying walk that gave up as soon as
// two items came within the give-up margin of the best so far (early in a walk that best may be
// a far face's trim edge, whose two pieces meet at their common minimum).
TEST(CadWarmCertificateStrips, LongThinFacesGetCertificatesThatHold) {
  const std::string path = nurbsreg::test::shared_dir() + "/data/real/occt/bearing.iges";
  const engine::PreparedModel pm(read_model_file(path));
  const double diagonal = pm.geometry_bounds().box.diagonal();
  // Samples where the face is at least four times longer in space along one parameter than along
  // the other (the bearing's faces are one Bezier patch each: the domain's widths scale the
  // tangents to the patch's).
  const std::vector<engine::SurfaceSample> samples = engine::sample_surfaces(pm.model(), 40000, 7);
  std::mt19937_64 rng(0x26c);
  std::uniform_real_distribution<double> offset(-1e-4 * diagonal, 1e-4 * diagonal);
  std::vector<Vec3> points;
  for (const engine::SurfaceSample& s : samples) {
    const engine::NurbsSurface& surface = pm.model().surfaces[static_cast<std::size_t>(s.surface)];
    const engine::SurfaceDerivatives der = surface.derivatives(s.u, s.v);
    const double along_u = der.su.norm() * surface.domain_u().width();
    const double along_v = der.sv.norm() * surface.domain_v().width();
    if (!(std::max(along_u, along_v) >= 4.0 * std::min(along_u, along_v))) continue;
    points.push_back(s.point + offset(rng) * s.normal);
    if (points.size() == 400) break;
  }
  ASSERT_EQ(points.size(), 400u);

  engine::ProjectionOptions certify;
  certify.certify = true;
  certify.certificate_radius = 1e-2 * diagonal;  // ICP's cap
  engine::Projector projector(pm);
  engine::ProjectionResults made;
  projector.project(engine::PointView::of(points), certify, made);
  // What each certificate proves: moves up to min(radius, (clearance - d) / 2) (0 for none). ICP
  // borrows certificates across a cell of the full scan, so what one serves counts, not only that
  // it exists.
  std::vector<double> serves;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const engine::WarmCertificate& w = made.certificate[i];
    const bool ok = made.status[i] == engine::ProjectionStatus::ok && w.radius > 0.0f;
    serves.push_back(ok ? std::min<double>(w.radius, 0.5 * (double(w.clearance) - made.distance[i]))
                        : 0.0);
  }
  const std::size_t certificates =
      std::count_if(serves.begin(), serves.end(), [](double x) { return x > 0.0; });
  std::nth_element(serves.begin(), serves.begin() + serves.size() / 2, serves.end());
  const double median_serves = serves[serves.size() / 2] / diagonal;
  check_boxes(pm, made, "bearing strips");
  const WarmOutcome warm = warm_equals_cold(pm, points, made, "bearing strips");
  std::printf(
      "[bearing strips] %zu points: %zu certificates made, serving moves of %.3g of the diagonal "
      "(median), %llu warm answers certified\n",
      points.size(), certificates, median_serves, warm.certified);
  EXPECT_GE(certificates, points.size() * 7 / 10);
  EXPECT_GE(median_serves, 1.25e-3);
  EXPECT_GE(warm.certified, points.size() / 4);
}

INSTANTIATE_TEST_SUITE_P(RealModels, CadWarmCertificate, testing::ValuesIn(kCases),
                         [](const testing::TestParamInfo<WarmCase>& info) {
                           return std::string(info.param.name);
                         });

}  // namespace
}  // namespace nurbsreg::io
