#pragma once
// Batch projection of point frames onto a prepared model: exact closest point, parameters,
// distance and normal for every point, in parallel (TBB).
//
// Trimmed faces (NurbsSurface::trim_loops): the closest point of the face, i.e. the best of its
// interior points inside the trimmed region and the points of its boundary edges (the 3-D trim
// edges, projected with the curve projector). A foot on an edge reports (u, v) = uv(t) of its
// trim curve at the edge's parameter t, and the surface normal there. A warm-start hint on a
// trimmed face seeds the search only with face points.
//
// Threads: `Projector::project` runs a tbb::parallel_for in the caller's task arena; the number
// of threads belongs to the application (tbb::global_control / task_arena). Results are written
// by index and each point is computed independently, so they are bit-identical for any thread
// count and equal to `project_serial`.
// Allocation: a Projector owns per-thread scratch that grows during the first frame and is then
// reused; the hot path allocates nothing per point. ProjectionResults are caller-owned and only
// resized.

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "nurbsreg/engine/prepared_model.hpp"

namespace nurbsreg::engine {

enum class ProjectionTarget : std::uint8_t { surfaces, curves };

enum class ProjectionStatus : std::uint8_t {
  ok,                   // exact closest point found
  skipped_nonfinite,    // the input point had a NaN or infinite coordinate
  no_geometry,          // the model has no entity of the requested target kind
  beyond_max_distance,  // nothing of the model within ProjectionOptions::max_distance
};

// Where a point's closest point was last time (e.g. the previous ICP iteration): entity index
// and parameters. entity < 0 means no hint. A hint only speeds the search up: the answer is
// exact whatever it says.
struct ProjectionHint {
  std::int32_t entity = -1;
  double u = 0.0;
  double v = 0.0;
};

// Structure of arrays, one entry per input point, written by index.
struct ProjectionResults {
  std::vector<Vec3> foot;
  std::vector<double> distance;         // >= 0, Euclidean
  std::vector<double> signed_distance;  // positive on the side the normal points to (0 side: +)
  std::vector<std::int32_t> entity;     // surface (or curve) index in the model, -1 if none
  std::vector<double> u;
  std::vector<double> v;  // 0 for curves
  // Unit surface normal at the foot: Su x Sv, or -(Su x Sv) for a reversed face
  // (NurbsSurface::reversed); 0 for curves.
  std::vector<Vec3> normal;
  std::vector<ProjectionStatus> status;
  // 1 when the foot lies on a trim edge of its face (a trimmed face's boundary, where the
  // closest point need not be an orthogonal projection); 0 otherwise.
  std::vector<std::uint8_t> on_trim_edge;

  std::size_t size() const { return status.size(); }
  void resize(std::size_t n);
  // Copies `part` into entries [offset, offset + part.size()) (frames projected in blocks).
  void copy_from(const ProjectionResults& part, std::size_t offset);
  ProjectionHint hint(std::size_t i) const {
    return status[i] == ProjectionStatus::ok ? ProjectionHint{entity[i], u[i], v[i]}
                                             : ProjectionHint{};
  }
};

struct ProjectionOptions {
  ProjectionTarget target = ProjectionTarget::surfaces;
  // Points per parallel task.
  std::size_t grain = 256;
  // Points with nothing of the model within this distance get status beyond_max_distance
  // without an exact foot: the search starts with alpha = max_distance^2, so far points (ICP
  // outliers) cost almost nothing. Infinity: every point gets its exact closest point.
  double max_distance = std::numeric_limits<double>::infinity();
};

// Work counters summed over a frame (for benchmarks and progress logs).
struct ProjectionCounters {
  std::uint64_t points = 0;
  std::uint64_t skipped = 0;
  std::uint64_t patches_visited = 0;
  std::uint64_t subdivisions = 0;
  std::uint64_t newton_iterations = 0;  // of the per-patch box-constrained Newton (surfaces)
};

// A frame of points without copying: any container that can hand out point i.
struct PointView {
  const void* data = nullptr;
  std::size_t count = 0;
  Vec3 (*at)(const void* data, std::size_t i) = nullptr;

  std::size_t size() const { return count; }
  Vec3 operator[](std::size_t i) const { return at(data, i); }

  static PointView of(std::span<const Vec3> points) {
    return {points.data(), points.size(),
            [](const void* d, std::size_t i) { return static_cast<const Vec3*>(d)[i]; }};
  }
};

class Projector {
 public:
  explicit Projector(const PreparedModel& model);
  ~Projector();
  Projector(const Projector&) = delete;
  Projector& operator=(const Projector&) = delete;

  // Projects every point; `hints` is empty or has one entry per point.
  void project(PointView points, const ProjectionOptions& options, ProjectionResults& out,
               std::span<const ProjectionHint> hints = {}, ProjectionCounters* counters = nullptr);
  // The same on the calling thread only (debugging, and the reference for "parallel == serial").
  void project_serial(PointView points, const ProjectionOptions& options, ProjectionResults& out,
                      std::span<const ProjectionHint> hints = {},
                      ProjectionCounters* counters = nullptr);

  const PreparedModel& model() const { return model_; }

 private:
  struct ThreadState;
  struct Impl;
  void project_range(PointView points, const ProjectionOptions& options, ProjectionResults& out,
                     std::span<const ProjectionHint> hints, std::size_t begin, std::size_t end,
                     ThreadState& state) const;
  const PreparedModel& model_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace nurbsreg::engine
