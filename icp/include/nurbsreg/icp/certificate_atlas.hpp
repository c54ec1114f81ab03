#pragma once
// Warm certificates (engine::WarmCertificate) by where their anchors are: a point that has none
// of its own may borrow one made for a neighbouring point, since a certificate proves the answer
// for every query within its radius of its anchor, whichever scan point asks. ICP's
// coarse-to-fine schedule makes certificates on a subsample and the full-resolution pass borrows
// them (ModelCorrespondenceFinder).
//
// A hash table over a cubic grid (open addressing, linear probing) keeping, per cell, the hints
// (foot and certificate) of up to `per_cell` anchors inserted there: the first ones, then those
// with the largest clearances (a newer one replaces the shortest of equal or shorter clearance):
// near a patch edge clearances are short, and a borrowed certificate proves a query only when the
// query's distance plus its distance from the anchor stays below the clearance. More than one a
// cell where certificates are small against the cell (convexity caps their radius on small bores
// and tori): each covers only the points near its own anchor. Built and read by the owner's
// thread; `find` is const and may be called from many threads at once while nothing is inserted.

#include <cstdint>
#include <span>
#include <vector>

#include "nurbsreg/engine/projection.hpp"

namespace nurbsreg::icp {

class CertificateAtlas {
 public:
  static constexpr int kMaxPerCell = 8;
  // Forget everything; cells of side `cell` (> 0), each keeping up to `per_cell` hints (1 ..
  // kMaxPerCell), from now on.
  void reset(double cell, int per_cell = 1);
  // Adds a hint whose certificate has radius > 0 (others are ignored).
  void insert(const engine::ProjectionHint& hint);
  // A hint kept for p's cell or one of its 26 neighbours whose certificate covers p
  // (|p - anchor| <= radius), else null: p's own cell's covering one with the most slack
  // (clearance - |p - anchor|) when that is at least a quarter of a cell side, else the first ring
  // of neighbours (faces, then edges, then corners) whose best covering one does, else the covering
  // one with the most slack.
  const engine::ProjectionHint* find(const engine::Vec3& p) const;
  // The hints of one cell and its neighbours, gathered by the lookups that needed them: find()
  // with a Neighbourhood answers the next point of the same cell without probing the table again
  // (lookup_order puts a cell's points one after another). The same answer as find(p).
  struct Neighbourhood;
  const engine::ProjectionHint* find(const engine::Vec3& p, Neighbourhood& near) const;
  std::size_t size() const { return count_; }  // hints kept
  // An order of the points p with wanted[p] != 0 (all of them when `wanted` is empty) in which
  // the points of one cell lie close together, within the run of one hash bucket of about eight
  // points: a counting sort by a hash of the cell. A lookup probes up to 27 cells; in a random
  // scan order each probe misses the cache, in this one the points after the first of a cell
  // find its cells there. Their coordinates are copied in that order too: read through the
  // indices, each was a cache miss of its own.
  struct LookupOrder {
    std::vector<std::uint32_t> index;   // into `points`
    std::vector<engine::Vec3> points;   // points[index[i]]
    std::vector<std::uint32_t> bucket;  // scratch (no allocation once grown)
    std::vector<std::uint32_t> start;   // scratch
  };
  void lookup_order(std::span<const engine::Vec3> points, std::span<const std::uint8_t> wanted,
                    bool parallel, LookupOrder& out) const;

  struct Cell {
    std::int64_t x, y, z;
    bool operator==(const Cell&) const = default;
  };
  struct Neighbourhood {
    // The certificates of the cell and of its 26 neighbours, in find()'s order (the cell, then
    // the rings of faces, edges and corners, each cell's hints in table order), compact: what
    // a lookup compares, side by side instead of in 27 cells' hints. levels rings of the 4
    // gathered so far for `cell`; ring r's entries end at ends[r].
    struct Entry {
      Eigen::Vector3f anchor;
      float radius, clearance;
      const engine::ProjectionHint* hint;
    };
    Cell cell{0, 0, 0};
    int levels = 0;
    int ends[4] = {0, 0, 0, 0};
    Entry entries[27 * kMaxPerCell];
  };

 private:
  Cell cell_of(const engine::Vec3& p) const;
  static std::uint64_t key(const Cell& c);
  // Appends the cell's certificates to `near`'s entries (one probe sequence of the table).
  void gather(const Cell& cell, Neighbourhood& near, int& end) const;
  void grow();
  std::size_t cells() const { return per_cell_ > 0 ? hints_.size() / per_cell_ : 0; }
  struct Slot {
    std::uint64_t key = 0;    // 0: empty (keys are never 0, see key())
    std::uint32_t first = 0;  // the cell's hints: hints_[first, first + count)
    std::uint32_t count = 0;
  };
  double inverse_cell_ = 1.0;
  std::vector<Slot> slots_;  // size a power of two, at most half full
  std::uint32_t per_cell_ = 1;
  std::size_t count_ = 0;  // hints kept
  // per_cell_ entries a cell, in the order of the cells' first insertions.
  std::vector<engine::ProjectionHint> hints_;
  // What a lookup compares of hints_[i], side by side: a cell's gathering reads these 20 bytes a
  // hint instead of the whole hint (about 72 bytes, most of a cache line each).
  struct Cover {
    Eigen::Vector3f anchor;
    float radius, clearance;
    static Cover of(const engine::ProjectionHint& h) {
      return {h.certificate.anchor, h.certificate.radius, h.certificate.clearance};
    }
  };
  std::vector<Cover> covers_;
};

}  // namespace nurbsreg::icp
