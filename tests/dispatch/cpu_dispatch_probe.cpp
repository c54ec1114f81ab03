// Runs a fixed set of projections and prints a digest of every result bit, for
// cpu_dispatch_check.cmake: built twice, once with the normal runtime CPU dispatch (the AVX2
// clones of the hot kernels on a CPU that has AVX2, engine/src/platform/cpu_dispatch.hpp) and once
// with baseline_cpu_model.cpp (every dispatch picks the x86-64 baseline clone). The two digests
// must be equal: the clones compute bit-identical results.
//
// The cases cover the cloned paths: cold projection (hierarchy walk, clipping of bicubic and
// rational biquadratic patches, trimmed faces and their edges, Newton) and the certified warm
// path of ICP (hints with certificates, on the untrimmed polynomial models:
// newton_to_proven_point). Hard cases: points on the surface and off it on both sides, near the
// trim loops, far away. With the registration module, also its dispatched kernel: the coarse
// stage's descriptor matching (each model descriptor a vector lane, 4 or 8 a vector).

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/engine/shapes.hpp"
#include "support/example_surface.hpp"
#include "support/polygon_loop.hpp"
#if NURBSREG_PROBE_REGISTRATION
#include "../../registration/src/coarse_detail.hpp"
#endif

namespace {

using namespace nurbsreg::engine;

// FNV-1a over the bytes of every value.
struct Digest {
  std::uint64_t h = 1469598103934665603ull;
  void add(const void* data, std::size_t size) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  }
  void add(double x) { add(&x, sizeof x); }
  void add(const Vec3& v) {
    for (int k = 0; k < 3; ++k)
      add(v[k]);
  }
};

void add_results(Digest& d, const ProjectionResults& r, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    d.add(r.foot[i]);
    d.add(r.distance[i]);
    d.add(r.signed_distance[i]);
    d.add(r.u[i]);
    d.add(r.v[i]);
    d.add(r.normal[i]);
    const auto status = static_cast<std::uint8_t>(r.status[i]);
    d.add(&status, 1);
    d.add(&r.entity[i], sizeof r.entity[i]);
    d.add(&r.on_trim_edge[i], sizeof r.on_trim_edge[i]);
    if (!r.certificate.empty()) d.add(r.certificate[i].radius);
  }
}

using nurbsreg::test::polygon_loop;

Model single(NurbsSurface s) {
  Model m;
  m.surfaces.push_back(std::move(s));
  return m;
}

// Cold frame, then a warm frame from its hints (with certificates) on points moved slightly, as
// ICP's next iteration does. Prints one digest line per model.
void run(const char* name, const Model& model, std::size_t n, std::uint64_t seed) {
  const PreparedModel prepared(model);
  Projector projector(prepared);
  const Aabb& box = prepared.bounds();
  const Vec3 lo = box.lo, size = box.hi - box.lo;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> jitter(0.0, 1e-3 * size.norm());
  std::vector<Vec3> points(n), moved(n);
  for (std::size_t i = 0; i < n; ++i) {
    // Within the box grown by a fifth on each side: points on and off the surface, both sides.
    for (int k = 0; k < 3; ++k)
      points[i][k] = lo[k] + (unit(rng) * 1.4 - 0.2) * size[k];
  }
  ProjectionOptions options;
  options.certify = true;
  ProjectionResults cold, warm;
  projector.project_serial(PointView::of(points), options, cold);
  // Half the frame pulled onto the surface (near points, where the clipping is hardest and the
  // certified warm path runs), all of it moved slightly for the warm frame.
  for (std::size_t i = 0; i < n; ++i) {
    if (i % 2 == 0 && cold.status[i] == ProjectionStatus::ok) points[i] = cold.foot[i];
    moved[i] = points[i] + Vec3(jitter(rng), jitter(rng), jitter(rng));
  }
  projector.project_serial(PointView::of(points), options, cold);
  std::vector<ProjectionHint> hints(n);
  for (std::size_t i = 0; i < n; ++i)
    hints[i] = cold.hint(i);
  ProjectionCounters counters;
  projector.project_serial(PointView::of(moved), options, warm, hints, &counters);
  Digest d;
  add_results(d, cold, n);
  add_results(d, warm, n);
  // The counters too: the clones must take the same paths (subdivisions, Newton iterations).
  d.add(&counters, sizeof counters);
  std::printf("%s: %zu points, %llu certified, digest %016llx\n", name, n,
              static_cast<unsigned long long>(counters.certified),
              static_cast<unsigned long long>(d.h));
}

#if NURBSREG_PROBE_REGISTRATION
// Random descriptors with ties (duplicated rows) and a model count that leaves the last panel
// part empty; the digest of every match.
void run_matching() {
  using nurbsreg::registration::detail::DescriptorMatrix;
  using nurbsreg::registration::detail::kDescriptorSize;
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<float> bin(0.0f, 10.0f);
  DescriptorMatrix scan(1500, kDescriptorSize), model(1237, kDescriptorSize);
  for (DescriptorMatrix* m : {&scan, &model})
    for (Eigen::Index r = 0; r < m->rows(); ++r)
      for (Eigen::Index c = 0; c < m->cols(); ++c)
        (*m)(r, c) = bin(rng);
  model.row(900) = model.row(12);
  scan.row(700) = model.row(12);
  scan.row(701) = scan.row(700);
  const auto matches = nurbsreg::registration::detail::match_descriptors(scan, model);
  Digest d;
  for (const auto& m : matches) {
    d.add(&m.scan, sizeof m.scan);
    d.add(&m.model, sizeof m.model);
  }
  std::printf("descriptor matches: %zu, digest %016llx\n", matches.size(),
              static_cast<unsigned long long>(d.h));
}
#endif

}  // namespace

int main() {
  // Which code the dispatch picks here (the baseline build reports no AVX2 on any CPU).
  std::printf("avx2 %d\n", __builtin_cpu_supports("avx2") ? 1 : 0);
  run("panel1369", single(nurbsreg::test::read_example_surface("panel_1369.json")), 4000, 1);
  run("folded", single(nurbsreg::test::read_example_surface("folded.json")), 3000, 2);
  run("sphere", single(make_sphere(Vec3(1.0, -2.0, 0.5), 5.0)), 3000, 3);
  run("torus", single(make_torus(Vec3(0.0, 0.0, 0.0), 4.0, 1.5)), 3000, 4);
  NurbsSurface trimmed = make_sphere(Vec3(1.0, -2.0, 0.5), 5.0);
  trimmed.trim_loops.push_back(
      polygon_loop({{0.15, 0.08}, {0.6, 0.08}, {0.6, 0.47}, {0.15, 0.47}}));
  trimmed.trim_loops.push_back(polygon_loop({{0.3, 0.2}, {0.45, 0.25}, {0.35, 0.35}}));
  run("trimmed sphere", single(trimmed), 3000, 5);
#if NURBSREG_PROBE_REGISTRATION
  run_matching();
#endif
  return 0;
}
