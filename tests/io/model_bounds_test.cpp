// PreparedModel::geometry_bounds (engine/model_bounds.hpp) on real trimmed CAD parts and exact
// shapes: the box must hold dense samples of every trimmed face and trim edge, and be tight:
// every side within the stated excess (plus the samples' own resolution) of a sampled face point.
// The samples are independent of the bound's search: a grid over each surface's domain kept where
// the face's TrimRegion contains it, the edges at many parameters, then zoomed grids around the
// best samples of each side.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_summary.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg {
namespace {

using engine::Vec3;

struct Sample {
  int surface = -1;  // -1: an edge or curve point
  double u = 0, v = 0;
  Vec3 x = Vec3::Zero();
};

bool in_face(const engine::PreparedModel& pm, int s, double u, double v) {
  const engine::TrimRegion* region = pm.surface_region(s);
  return region == nullptr || region->contains(u, v);
}

// Grid samples of every face (n x n over its domain, kept inside the face), 256 per trim-edge
// and curve piece.
std::vector<Sample> dense_samples(const engine::PreparedModel& pm, int n) {
  std::vector<Sample> out;
  const engine::Model& m = pm.model();
  for (std::size_t s = 0; s < m.surfaces.size(); ++s) {
    const engine::NurbsSurface& f = m.surfaces[s];
    const engine::ParamInterval du = f.domain_u(), dv = f.domain_v();
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; j <= n; ++j) {
        const double u = du.to_parent(double(i) / n), v = dv.to_parent(double(j) / n);
        if (in_face(pm, static_cast<int>(s), u, v))
          out.push_back({static_cast<int>(s), u, v, f.evaluate(u, v)});
      }
    }
  }
  for (std::size_t k = 0; k < pm.edge_piece_count(); ++k) {
    for (int i = 0; i <= 256; ++i)
      out.push_back({-1, 0, 0, pm.edge_piece(k).piece.evaluate(i / 256.0)});
  }
  for (std::size_t k = 0; k < pm.piece_count(); ++k) {
    for (int i = 0; i <= 256; ++i)
      out.push_back({-1, 0, 0, pm.piece(k).piece.evaluate(i / 256.0)});
  }
  return out;
}

// Zooms in on the best face samples of direction (axis, sign): grids of 21 x 21 over +- `half`
// (as a fraction of the domain) around each, three times, each time a tenth of the size.
double refined_extreme(const engine::PreparedModel& pm, std::vector<Sample> best, int axis,
                       double sign, double half) {
  double extreme = -INFINITY;
  for (const Sample& b : best)
    extreme = std::max(extreme, sign * b.x[axis]);
  for (int round = 0; round < 3; ++round, half *= 0.1) {
    std::vector<Sample> next;
    for (const Sample& b : best) {
      if (b.surface < 0) continue;
      const engine::NurbsSurface& f = pm.model().surfaces[static_cast<std::size_t>(b.surface)];
      const engine::ParamInterval du = f.domain_u(), dv = f.domain_v();
      Sample top = b;
      for (int i = -10; i <= 10; ++i) {
        for (int j = -10; j <= 10; ++j) {
          const double u = std::clamp(b.u + i * half / 10 * du.width(), du.lo, du.hi);
          const double v = std::clamp(b.v + j * half / 10 * dv.width(), dv.lo, dv.hi);
          if (!in_face(pm, b.surface, u, v)) continue;
          const Vec3 x = f.evaluate(u, v);
          if (sign * x[axis] > sign * top.x[axis]) top = {b.surface, u, v, x};
        }
      }
      extreme = std::max(extreme, sign * top.x[axis]);
      next.push_back(top);
    }
    best = std::move(next);
  }
  return extreme;
}

struct Case {
  std::string path;
  double max_diagonal;  // the trimmed faces' diagonal is below this (a sanity anchor)
};

class GeometryBounds : public ::testing::TestWithParam<Case> {};

TEST_P(GeometryBounds, HoldsDenseSamplesAndIsTight) {
  const engine::PreparedModel pm(io::read_model_file(GetParam().path));
  const engine::ModelBounds& b = pm.geometry_bounds();
  ASSERT_FALSE(b.box.empty());
  const double diag = b.box.diagonal();
  EXPECT_LT(diag, GetParam().max_diagonal);
  EXPECT_LE(diag, pm.bounds().diagonal() * (1 + 1e-12));
  // Tight by its own account: within 1e-5 of the diagonal, without running out of budget.
  EXPECT_LE(b.excess, 1e-5 * diag) << b.kind();
  EXPECT_FALSE(b.budget_spent);

  const std::vector<Sample> samples = dense_samples(pm, 64);
  ASSERT_GT(samples.size(), 1000u);
  const double rounding = 1e-12 * diag;
  engine::Aabb sampled;
  for (const Sample& s : samples) {
    sampled.extend(s.x);
    ASSERT_TRUE((s.x.array() >= b.box.lo.array() - rounding).all() &&
                (s.x.array() <= b.box.hi.array() + rounding).all())
        << "surface " << s.surface << " (" << s.u << ", " << s.v << ") at " << s.x.transpose()
        << " outside " << b.box.lo.transpose() << " .. " << b.box.hi.transpose();
  }
  // Tightness: each side within the stated excess plus 1e-6 of the diagonal (what the zoomed
  // samples resolve) of a sampled face point.
  for (int d = 0; d < 6; ++d) {
    const int axis = d / 2;
    const double sign = d % 2 == 0 ? 1.0 : -1.0;
    std::vector<Sample> best = samples;
    std::partial_sort(
        best.begin(), best.begin() + 8, best.end(),
        [&](const Sample& p, const Sample& q) { return sign * p.x[axis] > sign * q.x[axis]; });
    best.resize(8);
    const double sampled_side = refined_extreme(pm, best, axis, sign, 1.0 / 64);
    const double side = sign > 0 ? b.box.hi[axis] : -b.box.lo[axis];
    EXPECT_GE(side, sampled_side - rounding) << "direction " << d;
    EXPECT_LE(side - sampled_side, b.excess + 1e-6 * diag) << "direction " << d;
  }
}

const std::string kReal = nurbsreg::test::shared_dir() + "/data/real/";
INSTANTIATE_TEST_SUITE_P(
    RealParts, GeometryBounds,
    ::testing::Values(Case{kReal + "occt/linkrods.step", 6.0},
                      Case{kReal + "occt/bearing.iges", 1e9}, Case{kReal + "occt/screw.step", 1e9},
                      Case{kReal + "dealii/wigley.iges", 1e9},
                      Case{nurbsreg::test::examples_dir() + "/torus.json", 1e9}));

// The exact sphere: its box is [-r, r]^3 around its centre, and the bound says it is exact.
TEST(GeometryBounds, SphereIsExact) {
  const engine::PreparedModel pm(
      io::read_model_file(nurbsreg::test::examples_dir() + "/sphere.json"));
  const engine::ModelBounds& b = pm.geometry_bounds();
  EXPECT_TRUE(b.exact) << b.excess;
  const Vec3 extent = b.box.hi - b.box.lo;
  EXPECT_NEAR(extent.x(), extent.y(), 1e-12 * extent.x());
  EXPECT_NEAR(extent.x(), extent.z(), 1e-12 * extent.x());
}

// linkrods: faces cut from surfaces eight times their size. The control-point box says 46.3; the
// faces lie within about 5.6.
TEST(GeometryBounds, LinkrodsIsTheSizeOfItsFaces) {
  const engine::Model model = io::read_model_file(kReal + "occt/linkrods.step");
  const engine::PreparedModel pm(model);
  EXPECT_GT(pm.bounds().diagonal(), 40.0);
  EXPECT_LT(pm.geometry_bounds().box.diagonal(), 6.0);
  EXPECT_GT(pm.geometry_bounds().box.diagonal(), 5.0);
  // `info` reports that box and says what kind of bound it is; the old box stays, named.
  const io::ModelSummary summary = io::summarize_model(model);
  const nlohmann::json j = nlohmann::json::parse(io::model_summary_to_json(summary));
  EXPECT_EQ(j["bounding_box_kind"], "proven bound");
  EXPECT_LE(j["bounding_box_excess"].get<double>(), 1e-5);
  EXPECT_EQ(j["bounding_box"]["max"][0].get<double>(), pm.geometry_bounds().box.hi.x());
  EXPECT_EQ(j["control_point_box"]["max"][0].get<double>(), pm.bounds().hi.x());
  const std::string text = io::format_model_summary(summary, "linkrods.step");
  EXPECT_NE(text.find("diagonal 5.6"), std::string::npos) << text;
  EXPECT_NE(text.find("(of the faces as trimmed, proven bound: at most "), std::string::npos)
      << text;
  for (std::size_t k = 0; k < summary.surfaces.size(); ++k) {
    const engine::Aabb& face = summary.surfaces[k].geometry.box;
    if (face.empty()) continue;  // a face trimmed away entirely
    EXPECT_TRUE((face.lo.array() >= pm.geometry_bounds().box.lo.array() - 1e-9).all() &&
                (face.hi.array() <= pm.geometry_bounds().box.hi.array() + 1e-9).all())
        << "face " << k;
  }
}

}  // namespace
}  // namespace nurbsreg
