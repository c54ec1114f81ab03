// The 4-wide query form of the BVH: it must hold every primitive exactly once under boxes that
// contain it, and its search must visit primitives in order of their bound, never one whose bound
// cannot beat alpha, and every one whose bound can (exactness), for any tree size and leaf size.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "model/bvh.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::engine {
namespace {

using test::uniform;

// Small random spheres (centre, radius) with their boxes; some coincide (ties) and some are
// flat or degenerate boxes.
struct Balls {
  std::vector<Vec3> centers;
  std::vector<double> radii;
  std::vector<Aabb> boxes;
};

Balls random_balls(std::uint64_t seed, int count) {
  std::mt19937_64 rng(seed);
  Balls b;
  for (int i = 0; i < count; ++i) {
    Vec3 c(uniform(rng, -3, 3), uniform(rng, -1, 1), uniform(rng, -0.2, 0.2));
    double r = i % 5 == 0 ? 0.0 : uniform(rng, 0, 0.3);
    if (i % 7 == 3 && i > 0) {
      c = b.centers[i - 1];
      r = b.radii[i - 1];
    }
    b.centers.push_back(c);
    b.radii.push_back(r);
    Aabb box;
    box.extend(Vec3(c - Vec3::Constant(r)));
    box.extend(Vec3(c + Vec3::Constant(r)));
    b.boxes.push_back(box);
  }
  return b;
}

double ball_distance_sq(const Balls& b, std::uint32_t i, const Vec3& p) {
  const double d = std::max(0.0, (p - b.centers[i]).norm() - b.radii[i]);
  return d * d;
}

bool contains(const Bvh::WideNode& node, int k, const Aabb& box) {
  return node.lo_x[k] <= box.lo.x() && node.lo_y[k] <= box.lo.y() && node.lo_z[k] <= box.lo.z() &&
         node.hi_x[k] >= box.hi.x() && node.hi_y[k] >= box.hi.y() && node.hi_z[k] >= box.hi.z();
}

TEST(BvhWide, EveryPrimitiveOnceUnderContainingBoxes) {
  for (int count : {1, 2, 3, 4, 5, 7, 16, 17, 64, 333}) {
    for (int leaf_size : {1, 2, 3, 16}) {
      const Balls b = random_balls(static_cast<std::uint64_t>(count * 31 + leaf_size), count);
      const Bvh bvh(b.boxes, leaf_size);
      ASSERT_FALSE(bvh.wide_nodes().empty());
      std::vector<int> seen(count, 0);
      std::vector<int> entered(bvh.wide_nodes().size(), 0);
      // Walk from the root; every slot box must contain every primitive box below it.
      std::function<void(std::int32_t, std::vector<std::pair<std::int32_t, int>>&)> walk =
          [&](std::int32_t index, std::vector<std::pair<std::int32_t, int>>& path) {
            ++entered[static_cast<std::size_t>(index)];
            const Bvh::WideNode& node = bvh.wide_nodes()[static_cast<std::size_t>(index)];
            for (int k = 0; k < Bvh::WideNode::kWidth; ++k) {
              const std::int32_t child = node.child[k];
              path.emplace_back(index, k);
              if (child >= 0) {
                walk(child, path);
              } else if (node.lo_x[k] <= node.hi_x[k]) {  // a live primitive slot
                const auto prim = static_cast<std::uint32_t>(~child);
                ASSERT_LT(prim, static_cast<std::uint32_t>(count));
                ++seen[prim];
                for (const auto& [w, slot] : path) {
                  EXPECT_TRUE(
                      contains(bvh.wide_nodes()[static_cast<std::size_t>(w)], slot, b.boxes[prim]));
                }
              }
              path.pop_back();
            }
          };
      std::vector<std::pair<std::int32_t, int>> path;
      walk(0, path);
      for (int s : seen)
        EXPECT_EQ(s, 1) << count << " primitives, leaf size " << leaf_size;
      for (int e : entered)
        EXPECT_EQ(e, 1) << "every wide node is reachable exactly once";
    }
  }
}

TEST(BvhWide, VisitsInBoundOrderAndNeverMissesACloserPrimitive) {
  for (int count : {1, 3, 6, 50, 400}) {
    const Balls b = random_balls(static_cast<std::uint64_t>(1000 + count), count);
    const Bvh bvh(b.boxes, 2);
    Bvh::Scratch scratch;
    std::mt19937_64 rng(17);
    for (int q = 0; q < 300; ++q) {
      const Vec3 p(uniform(rng, -5, 5), uniform(rng, -2, 2), uniform(rng, -1, 1));
      // A bound looser than the exact distance (the ball's centre minus twice its radius), so
      // that the search must refine alpha through visits, as with Bézier patches.
      auto bound = [&](std::uint32_t i, const Vec3& x) {
        const double d = std::max(0.0, (x - b.centers[i]).norm() - 2.0 * b.radii[i]);
        return d * d;
      };
      double alpha = q % 3 == 0 ? 4.0 : std::numeric_limits<double>::infinity();
      const double start = alpha;
      std::vector<int> visits(count, 0);
      double last = -1.0;
      bvh.nearest(p, alpha, scratch, bound, [&](std::uint32_t i, double& a) {
        ++visits[i];
        const double key = std::max(b.boxes[i].squared_distance(p), bound(i, p));
        EXPECT_LT(key, a) << "a primitive that cannot beat alpha was visited";
        EXPECT_GE(key, last) << "visits out of bound order";
        last = key;
        a = std::min(a, ball_distance_sq(b, i, p));
      });
      double expected = start;
      for (int i = 0; i < count; ++i)
        expected = std::min(expected, ball_distance_sq(b, static_cast<std::uint32_t>(i), p));
      for (int i = 0; i < count; ++i) {
        EXPECT_LE(visits[i], 1);
        const double key =
            std::max(b.boxes[i].squared_distance(p), bound(static_cast<std::uint32_t>(i), p));
        if (key < expected) {
          // It could hold something closer than the answer: it must have been examined.
          EXPECT_EQ(visits[i], 1) << "primitive " << i << " skipped";
        }
      }
      EXPECT_EQ(alpha, expected);
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine
