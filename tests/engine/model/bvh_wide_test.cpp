// The 4-wide query form of the BVH: it must hold every primitive exactly once under boxes that
// contain it, and its search must visit primitives in order of their bound, never one whose bound
// cannot beat alpha, and every one whose bound can (exactness), for any tree size and leaf size.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <vector>

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

// The reference walk: one frontier kept sorted by increasing bound, the last inserted first among
// equal bounds (the order the split frontier of Bvh::nearest promises), over the same wide nodes.
// Returns the primitives visited, in order.
template <typename Bound, typename Refine>
std::vector<std::uint32_t> reference_visits(const Bvh& bvh, const Vec3& p, double alpha,
                                            Bound&& bound, Refine&& refine) {
  struct Entry {
    double bound;
    std::int32_t ref;
  };
  std::vector<Entry> frontier;  // by decreasing bound: the nearest, last inserted, at the back
  const auto insert = [&frontier](double b, std::int32_t ref) {
    auto at = frontier.begin();
    while (at != frontier.end() && at->bound >= b)
      ++at;
    frontier.insert(at, Entry{b, ref});
  };
  std::vector<std::uint32_t> visits;
  insert(bvh.nodes()[0].box.squared_distance(p), 0);
  while (!frontier.empty()) {
    const Entry e = frontier.back();
    frontier.pop_back();
    if (e.bound >= alpha) break;
    if (e.ref < 0) {
      visits.push_back(static_cast<std::uint32_t>(~e.ref));
      alpha = std::min(alpha, refine(static_cast<std::uint32_t>(~e.ref)));
      continue;
    }
    const Bvh::WideNode& node = bvh.wide_nodes()[static_cast<std::size_t>(e.ref)];
    for (int k = 0; k < Bvh::WideNode::kWidth; ++k) {
      Aabb box;
      box.lo = Vec3(node.lo_x[k], node.lo_y[k], node.lo_z[k]);
      box.hi = Vec3(node.hi_x[k], node.hi_y[k], node.hi_z[k]);
      double b = node.lo_x[k] <= node.hi_x[k] ? box.squared_distance(p)
                                              : std::numeric_limits<double>::infinity();
      if (!(b < alpha)) continue;
      if (node.child[k] < 0) b = std::max(b, bound(static_cast<std::uint32_t>(~node.child[k])));
      if (b < alpha) insert(b, node.child[k]);
    }
  }
  return visits;
}

// Bvh::nearest keeps a part of its frontier unsorted until needed; its visits must still be
// exactly those of one sorted frontier, ties included (bound 0 wherever boxes hold the query,
// coincident balls), from a first threshold or from none.
TEST(BvhWide, SplitFrontierVisitsAsOneSortedFrontier) {
  for (int count : {5, 50, 400}) {
    // Every ball three times over: equal bounds in every part of the frontier.
    Balls b = random_balls(static_cast<std::uint64_t>(2000 + count), count);
    for (int copy = 0; copy < 2; ++copy) {
      for (int i = 0; i < count; ++i) {
        b.centers.push_back(b.centers[i]);
        b.radii.push_back(b.radii[i]);
        b.boxes.push_back(b.boxes[i]);
      }
    }
    const Bvh bvh(b.boxes, 2);
    Bvh::Scratch scratch;
    std::mt19937_64 rng(23);
    for (int q = 0; q < 300; ++q) {
      const Vec3 p(uniform(rng, -3, 3), uniform(rng, -1, 1), uniform(rng, -0.3, 0.3));
      const auto bound = [&](std::uint32_t i) {
        const double d = std::max(0.0, (p - b.centers[i]).norm() - 3.0 * b.radii[i]);
        return d * d;
      };
      const auto refine = [&](std::uint32_t i) { return ball_distance_sq(b, i, p); };
      const double start =
          q % 2 == 0 ? uniform(rng, 0.01, 2.0) : std::numeric_limits<double>::infinity();
      double alpha = start;
      std::vector<std::uint32_t> visits;
      bvh.nearest(
          p, alpha, scratch, [&](std::uint32_t i, const Vec3&) { return bound(i); },
          [&](std::uint32_t i, double& a) {
            visits.push_back(i);
            a = std::min(a, refine(i));
          });
      EXPECT_EQ(visits, reference_visits(bvh, p, start, bound, refine))
          << count << " primitives, query " << q << ", first threshold " << start;
    }
  }
}

}  // namespace
}  // namespace nurbsreg::engine
