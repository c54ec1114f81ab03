#include "nurbsreg/icp/certificate_atlas.hpp"

#include "blocks.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>

namespace nurbsreg::icp {

namespace {

// 64-bit finaliser of MurmurHash3: spreads neighbouring cells over the table.
std::uint64_t mix(std::uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

}  // namespace

void CertificateAtlas::reset(double cell, int per_cell) {
  inverse_cell_ = 1.0 / cell;
  per_cell_ = static_cast<std::uint32_t>(std::clamp(per_cell, 1, kMaxPerCell));
  slots_.assign(1024, Slot{});
  hints_.clear();
  covers_.clear();
  count_ = 0;
}

CertificateAtlas::Cell CertificateAtlas::cell_of(const engine::Vec3& p) const {
  return {static_cast<std::int64_t>(std::floor(p.x() * inverse_cell_)),
          static_cast<std::int64_t>(std::floor(p.y() * inverse_cell_)),
          static_cast<std::int64_t>(std::floor(p.z() * inverse_cell_))};
}

std::uint64_t CertificateAtlas::key(const Cell& c) {
  // 21 bits per axis, offset so that every coordinate is positive; the top bit makes 0 unused.
  // Cells beyond +-2^20 of the origin wrap around: such a cell may share a key with another,
  // which costs a miss or a certificate that does not cover p (find checks), never a wrong answer.
  const auto axis = [](std::int64_t x) {
    return static_cast<std::uint64_t>(x + (1 << 20)) & ((1u << 21) - 1);
  };
  return (1ULL << 63) | (axis(c.x) << 42) | (axis(c.y) << 21) | axis(c.z);
}

void CertificateAtlas::grow() {
  std::vector<Slot> old(slots_.size() * 2);
  old.swap(slots_);
  const std::size_t mask = slots_.size() - 1;
  for (const Slot& s : old) {
    if (s.key == 0) continue;
    std::size_t i = mix(s.key) & mask;
    while (slots_[i].key != 0)
      i = (i + 1) & mask;
    slots_[i] = s;
  }
}

void CertificateAtlas::insert(const engine::ProjectionHint& hint) {
  if (!(hint.certificate.radius > 0.0) || slots_.empty()) return;
  const std::uint64_t k = key(cell_of(hint.certificate.anchor.cast<double>()));
  std::size_t mask = slots_.size() - 1;
  std::size_t i = mix(k) & mask;
  while (slots_[i].key != 0 && slots_[i].key != k)
    i = (i + 1) & mask;
  if (slots_[i].key == k) {
    Slot& slot = slots_[i];
    if (slot.count < per_cell_) {
      covers_[slot.first + slot.count] = Cover::of(hint);
      hints_[slot.first + slot.count++] = hint;
      ++count_;
      return;
    }
    // A full cell keeps its anchors with the larger clearances (the newer one on a tie): near a
    // patch edge clearances are short, and a borrowed certificate proves a query only when the
    // query's distance plus its distance from the anchor stays below it.
    engine::ProjectionHint* shortest = &hints_[slot.first];
    for (std::uint32_t j = 1; j < slot.count; ++j) {
      engine::ProjectionHint& h = hints_[slot.first + j];
      if (h.certificate.clearance <= shortest->certificate.clearance) shortest = &h;
    }
    if (hint.certificate.clearance >= shortest->certificate.clearance) {
      *shortest = hint;
      covers_[static_cast<std::size_t>(shortest - hints_.data())] = Cover::of(hint);
    }
    return;
  }
  if (2 * (cells() + 1) > slots_.size()) {
    grow();
    mask = slots_.size() - 1;
    i = mix(k) & mask;
    while (slots_[i].key != 0)
      i = (i + 1) & mask;
  }
  // A new cell reserves room for per_cell_ hints, side by side (a lookup reads them together).
  slots_[i] = Slot{k, static_cast<std::uint32_t>(hints_.size()), 1};
  hints_.resize(hints_.size() + per_cell_);
  covers_.resize(hints_.size());
  hints_[slots_[i].first] = hint;
  covers_[slots_[i].first] = Cover::of(hint);
  ++count_;
}

void CertificateAtlas::lookup_order(std::span<const engine::Vec3> points,
                                    std::span<const std::uint8_t> wanted, bool parallel,
                                    LookupOrder& out) const {
  const std::size_t n = points.size();
  const bool all = wanted.empty();
  std::size_t count = n;
  if (!all)
    count = static_cast<std::size_t>(
        std::count_if(wanted.begin(), wanted.end(), [](std::uint8_t w) { return w != 0; }));
  // About eight points a bucket: a bucket holds one cell's points, or a few cells'.
  std::size_t buckets = 1;
  while (buckets < count / 8)
    buckets *= 2;
  const std::uint64_t mask = buckets - 1;
  constexpr std::uint32_t kUnwanted = 0xffffffffu;
  out.bucket.resize(n);
  detail::for_each_block(n, parallel, [&](std::size_t begin, std::size_t end, std::size_t) {
    for (std::size_t k = begin; k < end; ++k) {
      out.bucket[k] = all || wanted[k] != 0
                          ? static_cast<std::uint32_t>(mix(key(cell_of(points[k]))) & mask)
                          : kUnwanted;
    }
  });
  out.start.assign(buckets + 1, 0);
  for (std::size_t k = 0; k < n; ++k) {
    if (out.bucket[k] != kUnwanted) ++out.start[out.bucket[k] + 1];
  }
  for (std::size_t b = 0; b < buckets; ++b)
    out.start[b + 1] += out.start[b];
  out.index.resize(count);
  out.points.resize(count);
  for (std::size_t k = 0; k < n; ++k) {
    if (out.bucket[k] == kUnwanted) continue;
    const std::uint32_t at = out.start[out.bucket[k]]++;
    out.index[at] = static_cast<std::uint32_t>(k);
    out.points[at] = points[k];
  }
}

void CertificateAtlas::gather(const Cell& cell, Neighbourhood& near, int& end) const {
  const std::uint64_t k = key(cell);
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t i = mix(k) & mask; slots_[i].key != 0; i = (i + 1) & mask) {
    if (slots_[i].key != k) continue;
    for (std::uint32_t j = 0; j < slots_[i].count; ++j) {
      const std::size_t at = slots_[i].first + j;
      const Cover& c = covers_[at];
      near.entries[end++] = {c.anchor, c.radius, c.clearance, &hints_[at]};
    }
    return;
  }
}

namespace {
// The 26 neighbours of a cell, nearest first: the 6 faces, the 12 edges, the 8 corners (|dx| +
// |dy| + |dz| = 1, 2, 3), each ring in (dx, dy, dz) order. A table: the lookup runs for most
// points of a full pass, and looping over the 27 offsets per ring to pick a ring's ones cost more
// than the lookups themselves.
struct Offset {
  int dx, dy, dz;
};
struct Ring {
  int begin, end;
};
constexpr std::array<Offset, 26> neighbour_table() {
  std::array<Offset, 26> table{};
  int n = 0;
  for (int ring = 1; ring <= 3; ++ring) {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          if ((dx < 0 ? -dx : dx) + (dy < 0 ? -dy : dy) + (dz < 0 ? -dz : dz) == ring) {
            table[static_cast<std::size_t>(n++)] = {dx, dy, dz};
          }
        }
      }
    }
  }
  return table;
}
constexpr std::array<Offset, 26> kNeighbours = neighbour_table();
constexpr std::array<Ring, 3> kRings = {{{0, 6}, {6, 18}, {18, 26}}};
}  // namespace

const engine::ProjectionHint* CertificateAtlas::find(const engine::Vec3& p) const {
  Neighbourhood near;
  return find(p, near);
}

const engine::ProjectionHint* CertificateAtlas::find(const engine::Vec3& p,
                                                     Neighbourhood& near) const {
  if (hints_.empty()) return nullptr;
  // Enough slack for the query's own distance (about the scan's noise, far below a quarter of a
  // cell, an eighth of the radius cap): take it. Otherwise (p's cell is empty, or its anchor's
  // foot is near a patch edge) the 26 neighbours, nearest first (faces, edges, corners), until
  // one leaves that much. Cells of half the radius cap hold about one anchor of a 10% subsample
  // each, so many are empty: the own cell and its faces alone left half of a full scan's points
  // without a certificate. Half a cell as "enough" sent more lookups into the rings (a 1 M-point
  // pass probed 11.4 M cells instead of 9.5 M) for the same certificates in the end.
  const double enough = 0.25 / inverse_cell_;
  const Cell c = cell_of(p);
  if (!(near.cell == c)) {
    near.cell = c;
    near.levels = 0;
  }
  // The covering certificate with the most slack (clearance - |p - anchor|: it proves p's answer
  // when p's distance is at most that), the first of equals in find()'s order; the slack kept
  // with it, from the same distance as the cover test (one root a certificate).
  double best_slack = 0.0;
  const engine::ProjectionHint* best = nullptr;
  int begin = 0;
  for (int level = 0; level < 4; ++level) {
    if (near.levels == level) {
      int end = begin;
      if (level == 0) {
        gather(c, near, end);
      } else {
        const Ring& ring = kRings[static_cast<std::size_t>(level - 1)];
        for (int k = ring.begin; k < ring.end; ++k) {
          const Offset& o = kNeighbours[static_cast<std::size_t>(k)];
          gather({c.x + o.dx, c.y + o.dy, c.z + o.dz}, near, end);
        }
      }
      near.ends[level] = end;
      near.levels = level + 1;
    }
    const int end = near.ends[level];
    for (int e = begin; e < end; ++e) {
      const Neighbourhood::Entry& x = near.entries[e];
      const double d = (p - x.anchor.cast<double>()).norm();
      if (!(x.radius > 0.0f && d <= x.radius)) continue;
      const double slack = static_cast<double>(x.clearance) - d;
      if (best == nullptr || slack > best_slack) {
        best = x.hint;
        best_slack = slack;
      }
    }
    if (best != nullptr && best_slack >= enough) return best;
    begin = end;
  }
  return best;
}

}  // namespace nurbsreg::icp
