// The best-first search must find exactly the nearest primitive (here: small boxes treated as
// their centre points) whatever the tree, and never visit a primitive it could prune.
#include <gtest/gtest.h>

#include "model/bvh.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

struct Scene {
  std::vector<Vec3> points;
  std::vector<Aabb> boxes;
};

Scene clustered_points(std::uint64_t seed, int count) {
  std::mt19937_64 rng(seed);
  Scene s;
  for (int i = 0; i < count; ++i) {
    // Clusters and exact duplicates stress the median split and tie handling.
    const double cx = std::floor(uniform(rng, 0, 4));
    Vec3 p(cx + uniform(rng, 0, 0.1), uniform(rng, -1, 1), uniform(rng, -1, 1) * 0.01);
    if (i % 17 == 0 && i > 0) p = s.points[i - 1];
    s.points.push_back(p);
    Aabb b;
    b.extend(p);
    s.boxes.push_back(b);
  }
  return s;
}

TEST(Bvh, NearestEqualsBruteForce) {
  for (int leaf_size : {1, 2, 4, 16}) {
    const Scene s = clustered_points(7 + leaf_size, 2000);
    const Bvh bvh(s.boxes, leaf_size);
    Bvh::Scratch scratch;
    std::mt19937_64 rng(99);
    for (int q = 0; q < 500; ++q) {
      const Vec3 p(uniform(rng, -1, 5), uniform(rng, -2, 2), uniform(rng, -1, 1));
      double alpha = std::numeric_limits<double>::infinity();
      int best = -1;
      int visits = 0;
      bvh.nearest(
          p, alpha, scratch,
          [&](std::uint32_t i, const Vec3& x) { return s.boxes[i].squared_distance(x); },
          [&](std::uint32_t i, double& a) {
            ++visits;
            const double d = (s.points[i] - p).squaredNorm();
            if (d < a) {
              a = d;
              best = static_cast<int>(i);
            }
          });
      double expected = std::numeric_limits<double>::infinity();
      for (const Vec3& x : s.points)
        expected = std::min(expected, (x - p).squaredNorm());
      ASSERT_GE(best, 0);
      EXPECT_EQ(alpha, expected);
      EXPECT_LT(visits, 200) << "the search should prune most of 2000 primitives";
    }
  }
}

TEST(Bvh, StartingAlphaPrunesEverything) {
  const Scene s = clustered_points(3, 100);
  const Bvh bvh(s.boxes, 2);
  Bvh::Scratch scratch;
  double alpha = 0.0;  // nothing can beat a zero distance
  int visits = 0;
  bvh.nearest(
      Vec3(1, 0, 0), alpha, scratch,
      [&](std::uint32_t i, const Vec3& x) { return s.boxes[i].squared_distance(x); },
      [&](std::uint32_t, double&) { ++visits; });
  EXPECT_EQ(visits, 0);
}

TEST(Bvh, EveryPrimitiveAppearsOnce) {
  const Scene s = clustered_points(5, 1001);
  const Bvh bvh(s.boxes, 3);
  std::vector<int> seen(s.boxes.size(), 0);
  for (std::uint32_t i : bvh.order())
    ++seen[i];
  for (int count : seen)
    EXPECT_EQ(count, 1);
  // Every node's box contains its leaves' boxes.
  for (const Bvh::Node& node : bvh.nodes()) {
    if (node.count == 0) continue;
    for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
      const Aabb& b = s.boxes[bvh.order()[k]];
      EXPECT_TRUE((b.lo.array() >= node.box.lo.array()).all());
      EXPECT_TRUE((b.hi.array() <= node.box.hi.array()).all());
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine
