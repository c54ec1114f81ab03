// Certificates in ICP's closest-point step: icp::CertificateAtlas on its own (covering, cells,
// growth), and ModelCorrespondenceFinder answers with made and borrowed certificates checked
// against a finder that never sees one (a fresh finder per query, no hints): the same feet and
// distances, while most full-resolution points really are answered through a certificate.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/icp/certificate_atlas.hpp"
#include "nurbsreg/icp/model_finder.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::icp {
namespace {

using engine::Vec3;

engine::ProjectionHint hint_at(const Vec3& anchor, double radius, int patch,
                               double clearance = 1.0) {
  engine::WarmCertificate c;
  c.anchor = anchor.cast<float>();
  c.radius = static_cast<float>(radius);
  c.clearance = static_cast<float>(clearance);
  c.patch = patch;
  return engine::ProjectionHint(0, 0.5, 0.5, c);
}

TEST(CertificateAtlas, ReturnsOnlyCertificatesThatCoverThePoint) {
  CertificateAtlas atlas;
  atlas.reset(0.25);
  EXPECT_EQ(atlas.find(Vec3(0.1, 0.1, 0.1)), nullptr);
  atlas.insert(hint_at(Vec3(0.1, 0.1, 0.1), 0.2, 7));
  atlas.insert(hint_at(Vec3(5, 5, 5), 0.0, 8));  // no certificate: ignored
  EXPECT_EQ(atlas.size(), 1u);
  const engine::ProjectionHint* h = atlas.find(Vec3(0.2, 0.15, 0.1));
  ASSERT_NE(h, nullptr);
  EXPECT_EQ(h->certificate.patch, 7);
  // Same cell, beyond the radius.
  EXPECT_EQ(atlas.find(Vec3(0.1, 0.1, 0.1) + Vec3(0.0, 0.0, 0.14) * 1.5), nullptr);
  // A face-neighbour cell within the radius.
  h = atlas.find(Vec3(0.1, 0.1, 0.27));
  ASSERT_NE(h, nullptr);
  EXPECT_EQ(h->certificate.patch, 7);
  // Far away (and beyond the key's 21-bit range, where keys wrap): never a wrong certificate.
  EXPECT_EQ(atlas.find(Vec3(0.1 + 0.25 * (1 << 21), 0.1, 0.1)), nullptr);
  // A newer anchor of the cell with at least the same clearance replaces the older one.
  atlas.insert(hint_at(Vec3(0.12, 0.1, 0.1), 0.2, 9));
  EXPECT_EQ(atlas.size(), 1u);
  EXPECT_EQ(atlas.find(Vec3(0.12, 0.1, 0.1))->certificate.patch, 9);
}

// Near a patch edge certificates have short clearances, and a borrowed one proves a query only
// if the query's distance plus its distance from the anchor stays below the clearance: a cell
// keeps its anchor with the larger clearance, and a point whose own cell offers little slack
// (clearance - distance from the anchor) takes a face neighbour's certificate with more.
TEST(CertificateAtlas, PrefersCertificatesWithMoreSlack) {
  CertificateAtlas atlas;
  atlas.reset(0.25);
  atlas.insert(hint_at(Vec3(0.1, 0.1, 0.1), 0.4, 1, 0.8));
  atlas.insert(hint_at(Vec3(0.12, 0.1, 0.1), 0.4, 2, 0.05));  // same cell, shorter: not kept
  EXPECT_EQ(atlas.find(Vec3(0.1, 0.1, 0.1))->certificate.patch, 1);
  atlas.insert(hint_at(Vec3(0.11, 0.1, 0.1), 0.4, 3, 0.8));  // same clearance, newer: kept
  EXPECT_EQ(atlas.find(Vec3(0.1, 0.1, 0.1))->certificate.patch, 3);

  // Cell (0, 0, 0) with a short clearance, its +x neighbour with a long one.
  atlas.reset(0.25);
  atlas.insert(hint_at(Vec3(0.2, 0.1, 0.1), 0.4, 4, 0.1));
  atlas.insert(hint_at(Vec3(0.3, 0.1, 0.1), 0.4, 5, 0.9));
  // Slack in the own cell 0.1 - 0.05 < one cell: the neighbour's 0.9 - 0.05 wins.
  EXPECT_EQ(atlas.find(Vec3(0.25 - 1e-3, 0.1, 0.1))->certificate.patch, 5);
  // Enough slack in the own cell (long clearance): kept without looking further.
  atlas.insert(hint_at(Vec3(0.21, 0.1, 0.1), 0.4, 6, 0.7));
  EXPECT_EQ(atlas.find(Vec3(0.2, 0.1, 0.1))->certificate.patch, 6);
  // "Enough" is a quarter of a cell (0.0625 here): an own-cell slack of 0.1 is kept although a
  // neighbour offers more (the query's own distance, about the scan's noise, is far below it).
  atlas.reset(0.25);
  atlas.insert(hint_at(Vec3(0.2, 0.1, 0.1), 0.4, 10, 0.1));
  atlas.insert(hint_at(Vec3(0.3, 0.1, 0.1), 0.4, 11, 0.9));
  EXPECT_EQ(atlas.find(Vec3(0.2, 0.1, 0.1))->certificate.patch, 10);
  // The neighbour does not cover the point: the own cell's certificate even with little slack.
  atlas.reset(0.25);
  atlas.insert(hint_at(Vec3(0.2, 0.1, 0.1), 0.4, 7, 0.1));
  atlas.insert(hint_at(Vec3(0.4, 0.1, 0.1), 0.1, 8, 0.9));
  EXPECT_EQ(atlas.find(Vec3(0.1, 0.1, 0.1))->certificate.patch, 7);
}

// Several hints a cell: the first `per_cell` anchors are all kept and each covers its own
// neighbourhood (small certificates, a cell of several anchors); of two that cover a point the one
// with more slack answers; a full cell then replaces its shortest clearance by a longer (or equal,
// newer) one, never a longer one by a shorter.
TEST(CertificateAtlas, KeepsSeveralAnchorsACellEachForItsOwnPoints) {
  CertificateAtlas atlas;
  atlas.reset(1.0, 4);
  // Three small certificates in cell (0, 0, 0), apart by more than their radius.
  atlas.insert(hint_at(Vec3(0.2, 0.5, 0.5), 0.1, 1, 0.5));
  atlas.insert(hint_at(Vec3(0.5, 0.5, 0.5), 0.1, 2, 0.3));
  atlas.insert(hint_at(Vec3(0.8, 0.5, 0.5), 0.1, 3, 0.4));
  EXPECT_EQ(atlas.size(), 3u);
  EXPECT_EQ(atlas.find(Vec3(0.22, 0.5, 0.5))->certificate.patch, 1);
  EXPECT_EQ(atlas.find(Vec3(0.5, 0.52, 0.5))->certificate.patch, 2);
  EXPECT_EQ(atlas.find(Vec3(0.8, 0.5, 0.47))->certificate.patch, 3);
  EXPECT_EQ(atlas.find(Vec3(0.35, 0.5, 0.5)), nullptr);  // between them: none covers it
  // A fourth beside the second: at (0.5, 0.5, 0.5) both cover, the slacks 0.3 and 0.33.
  atlas.insert(hint_at(Vec3(0.52, 0.5, 0.5), 0.1, 4, 0.35));
  EXPECT_EQ(atlas.size(), 4u);
  EXPECT_EQ(atlas.find(Vec3(0.5, 0.5, 0.5))->certificate.patch, 4);
  EXPECT_EQ(atlas.find(Vec3(0.41, 0.5, 0.5))->certificate.patch, 2);  // beyond the fourth's ball
  // Full: a shorter clearance than every kept one is dropped, a longer one replaces the
  // shortest (patch 2, 0.3).
  atlas.insert(hint_at(Vec3(0.45, 0.5, 0.5), 0.1, 5, 0.2));
  EXPECT_EQ(atlas.size(), 4u);
  EXPECT_EQ(atlas.find(Vec3(0.41, 0.5, 0.5))->certificate.patch, 2);
  atlas.insert(hint_at(Vec3(0.21, 0.5, 0.5), 0.1, 6, 0.5));
  EXPECT_EQ(atlas.size(), 4u);
  EXPECT_EQ(atlas.find(Vec3(0.41, 0.5, 0.5)), nullptr);  // patch 2 gave way
  EXPECT_EQ(atlas.find(Vec3(0.8, 0.5, 0.5))->certificate.patch, 3);
  EXPECT_EQ(atlas.find(Vec3(0.52, 0.5, 0.5))->certificate.patch, 4);
  // With one a cell the same inserts keep only the longest clearance, the newest of equals.
  atlas.reset(1.0);
  atlas.insert(hint_at(Vec3(0.2, 0.5, 0.5), 0.1, 1, 0.5));
  atlas.insert(hint_at(Vec3(0.8, 0.5, 0.5), 0.1, 3, 0.4));
  EXPECT_EQ(atlas.size(), 1u);
  EXPECT_EQ(atlas.find(Vec3(0.8, 0.5, 0.5)), nullptr);
  atlas.insert(hint_at(Vec3(0.21, 0.5, 0.5), 0.1, 6, 0.5));
  EXPECT_EQ(atlas.find(Vec3(0.2, 0.5, 0.5))->certificate.patch, 6);
}

TEST(CertificateAtlas, GrowsAndFindsEveryAnchor) {
  CertificateAtlas atlas;
  atlas.reset(0.1);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  std::vector<Vec3> anchors;
  for (int k = 0; k < 20000; ++k) {
    // One anchor per cell (cell centres), so none replaces another.
    const Vec3 cell(std::floor(u(rng) / 0.1), std::floor(u(rng) / 0.1), std::floor(u(rng) / 0.1));
    anchors.push_back((cell + Vec3::Constant(0.5)) * 0.1);
    atlas.insert(hint_at(anchors.back(), 0.01, k));
  }
  for (std::size_t k = 0; k < anchors.size(); ++k) {
    const engine::ProjectionHint* h = atlas.find(anchors[k]);
    ASSERT_NE(h, nullptr) << k;
    EXPECT_EQ(h->certificate.anchor, anchors[k].cast<float>());
  }
}

const engine::PreparedModel& panel() {
  static const engine::PreparedModel model(
      io::read_model_json(nurbsreg::test::examples_dir() + "/panel.json"));
  return model;
}

// The order the finder looks points up in: every wanted point once, with its coordinates, and
// the points of one cell close together (so that the first of them brings the cell's
// neighbourhood into the cache).
TEST(CertificateAtlas, TheLookupOrderIsAPermutationThatKeepsEachCellClose) {
  CertificateAtlas atlas;
  atlas.reset(0.5);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  std::vector<Vec3> points(20000);
  for (Vec3& p : points)
    p = Vec3(u(rng), u(rng), u(rng));
  // All points, or every third one.
  std::vector<std::uint8_t> thirds(points.size());
  for (std::size_t k = 0; k < points.size(); ++k)
    thirds[k] = k % 3 == 0;
  for (const bool filtered : {false, true}) {
    for (const bool parallel : {false, true}) {
      CertificateAtlas::LookupOrder order;
      atlas.lookup_order(
          points,
          filtered ? std::span<const std::uint8_t>(thirds) : std::span<const std::uint8_t>(),
          parallel, order);
      const std::size_t expected = filtered ? (points.size() + 2) / 3 : points.size();
      ASSERT_EQ(order.index.size(), expected);
      ASSERT_EQ(order.points.size(), expected);
      std::vector<int> seen(points.size(), 0);
      for (std::size_t i = 0; i < order.index.size(); ++i) {
        const std::uint32_t k = order.index[i];
        ++seen[k];
        EXPECT_TRUE(!filtered || thirds[k]) << k;
        EXPECT_EQ(order.points[i], points[k]);
      }
      EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(expected));
      // A cell's points lie within one run of its hash bucket (about eight points a bucket): the
      // first and the last of them are a few positions apart, where the scan's own order
      // spreads them over the whole frame.
      const auto cell = [](const Vec3& p) {
        return std::array<long, 3>{static_cast<long>(std::floor(p.x() / 0.5)),
                                   static_cast<long>(std::floor(p.y() / 0.5)),
                                   static_cast<long>(std::floor(p.z() / 0.5))};
      };
      std::map<std::array<long, 3>, std::pair<std::size_t, std::size_t>> span;
      for (std::size_t i = 0; i < order.index.size(); ++i) {
        auto [it, added] = span.try_emplace(cell(order.points[i]), i, i);
        if (!added) it->second.second = i;
      }
      std::size_t widest = 0;
      for (const auto& [c, s] : span)
        widest = std::max(widest, s.second - s.first);
      EXPECT_LT(widest, 64u);
    }
  }
  // The empty frame.
  CertificateAtlas::LookupOrder order;
  order.index = {7};
  atlas.lookup_order({}, {}, true, order);
  EXPECT_TRUE(order.index.empty());
  EXPECT_TRUE(order.points.empty());
}

TEST(ModelFinderCertificates, BorrowedAndCarriedCertificatesGiveTheExactFeet) {
  const engine::PreparedModel& model = panel();
  const double diagonal = model.bounds().diagonal();
  engine::SyntheticScanOptions so;
  so.points = 80000;
  so.noise_sigma = 1e-4 * diagonal;
  so.seed = 5;
  const engine::SyntheticScan scan = engine::make_synthetic_scan(model.model(), so);
  const std::size_t n = scan.points.size();

  ModelCorrespondenceFinder finder(model);
  finder.reset(n);
  // A coarse stage: every 4th point, small expected moves: certificates are made.
  std::vector<std::size_t> coarse;
  std::vector<Vec3> coarse_points;
  for (std::size_t i = 0; i < n; i += 4) {
    coarse.push_back(i);
    coarse_points.push_back(scan.points[i]);
  }
  std::vector<Correspondence> out(coarse.size());
  CorrespondenceQuery query;
  query.points = coarse_points;
  query.scan_indices = coarse;
  query.expected_motion = 1e-6 * diagonal;
  finder.find(query, out);
  EXPECT_GT(finder.last_counters().certificates_made, coarse.size() / 2);
  const std::size_t atlas = finder.atlas_size();

  // Two full-resolution passes, the points moved a little each time (as ICP's pose updates do).
  std::mt19937_64 rng(11);
  std::normal_distribution<double> gauss(0.0, 1e-5 * diagonal);
  std::vector<Vec3> moved = scan.points;
  std::vector<std::size_t> all(n);
  for (std::size_t i = 0; i < n; ++i)
    all[i] = i;
  for (int pass = 0; pass < 2; ++pass) {
    for (Vec3& p : moved)
      p += Vec3(gauss(rng), gauss(rng), gauss(rng));
    out.assign(n, Correspondence{});
    query.points = moved;
    query.scan_indices = all;
    finder.find(query, out);
    const engine::ProjectionCounters counters = finder.last_counters();
    // Most points are answered through a certificate (borrowed in the first pass).
    EXPECT_GT(counters.certified, n / 2) << "pass " << pass;
    // At full resolution only clearance certificates are made (for the points no borrowed one
    // proved), anchored at the point itself, and never lent.
    const engine::ProjectionResults& r = finder.last_results();
    std::size_t clearance = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const engine::WarmCertificate& c = r.certificate[i];
      if (c.anchor != moved[i].cast<float>() || !(c.clearance > 0.0f)) continue;
      EXPECT_TRUE(c.clearance_only()) << "point " << i;
      ++clearance;
    }
    EXPECT_EQ(counters.certificates_made, clearance);
    EXPECT_EQ(finder.atlas_size(), atlas) << "a full-resolution pass lent its certificates";
    // The reference: a fresh finder, no hints, no certificates.
    ModelCorrespondenceFinder cold(model);
    cold.reset(n);
    std::vector<Correspondence> expected(n);
    CorrespondenceQuery plain;
    plain.points = moved;
    cold.find(plain, expected);
    EXPECT_EQ(cold.last_counters().certified, 0u);
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_TRUE(out[i].valid);
      ASSERT_NEAR(out[i].distance, expected[i].distance, 1e-12 * diagonal) << "point " << i;
      ASSERT_LE((out[i].foot - expected[i].foot).norm(), 1e-7 * diagonal) << "point " << i;
    }
    std::printf("[ report ] pass %d: %llu of %zu points certified\n", pass,
                static_cast<unsigned long long>(counters.certified), n);
  }
}

}  // namespace
}  // namespace nurbsreg::icp
