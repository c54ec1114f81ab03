#pragma once
// Warm certificates (engine::WarmCertificate) by where their anchors are: a point that has none
// of its own may borrow one made for a neighbouring point, since a certificate proves the answer
// for every query within its radius of its anchor, whichever scan point asks. ICP's
// coarse-to-fine schedule makes certificates on a subsample and the full-resolution pass borrows
// them (ModelCorrespondenceFinder).
//
// A hash table over a cubic grid (open addressing, linear probing) keeping, per cell, the hint
// (foot and certificate) of the anchor inserted there with the largest clearance (the newest of
// equals): near a patch edge clearances are short, and a borrowed certificate proves a query only
// when the query's distance plus its distance from the anchor stays below the clearance. Built and
// read by the owner's thread; `find` is const and may be called from many threads at once while
// nothing is inserted.

#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/projection.hpp"

namespace nurbsreg::icp {

class CertificateAtlas {
 public:
  // Forget everything; cells of side `cell` (> 0) from now on.
  void reset(double cell);
  // Adds a hint whose certificate has radius > 0 (others are ignored).
  void insert(const engine::ProjectionHint& hint);
  // A hint kept for p's cell or one of its 26 neighbours whose certificate covers p
  // (|p - anchor| <= radius), else null: p's own cell's when it leaves at least half a cell side
  // of slack (clearance - |p - anchor|), else the first ring of neighbours (faces, then edges,
  // then corners) whose best covering one does, else the covering one with the most slack.
  const engine::ProjectionHint* find(const engine::Vec3& p) const;
  std::size_t size() const { return hints_.size(); }
  // An order of `points` (indices into it) in which the points of one cell lie close together,
  // within the run of one hash bucket of about eight points: a counting sort by a hash of the
  // cell. A lookup probes up to 27 cells; in a random scan order each probe misses the cache, in
  // this one the points after the first of a cell find its cells there. `bucket` is scratch (no
  // allocation once grown).
  void lookup_order(std::span<const engine::Vec3> points, bool parallel,
                    std::vector<std::uint32_t>& order, std::vector<std::uint32_t>& bucket) const;

 private:
  struct Cell {
    std::int64_t x, y, z;
  };
  Cell cell_of(const engine::Vec3& p) const;
  static std::uint64_t key(const Cell& c);
  // The cell's hint if its certificate covers p, with its slack for p (clearance - |p - anchor|,
  // from the same distance the cover test used), else null.
  const engine::ProjectionHint* find_in_cell(const engine::Vec3& p, const Cell& cell,
                                             double& slack) const;
  void grow();
  struct Slot {
    std::uint64_t key = 0;  // 0: empty (keys are never 0, see key())
    std::uint32_t hint = 0;
  };
  double inverse_cell_ = 1.0;
  std::vector<Slot> slots_;  // size a power of two, at most half full
  std::vector<engine::ProjectionHint> hints_;
};

}  // namespace nurbsreg::icp
