#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "coarse_detail.hpp"
#include "cpu_dispatch.hpp"
#include "nurbsreg/engine/cancellation.hpp"

namespace nurbsreg::registration::detail {
namespace {

// The model's descriptors in panels of kPanel: panel p holds, for each k, the k-th values of
// descriptors kPanel p .. kPanel p + kPanel - 1 side by side, so that one vector load gives a
// value of kPanel descriptors. The last panel is padded with zeros and an infinite squared norm
// (its distances are infinite: never a nearest).
constexpr int kPanel = 8;
// Scan descriptors a task takes (its best distance per model descriptor is merged in order).
constexpr Eigen::Index kBlock = 256;
// Scan descriptors a kernel step takes together (each panel's values are loaded once for them).
constexpr int kRows = 4;

// |a|^2, summed in index order (the kernel's dot products are summed in the same order).
float squared_norm(const float* a) {
  float s = 0.0f;
  for (int k = 0; k < kDescriptorSize; ++k)
    s += a[k] * a[k];
  return s;
}

struct Panels {
  std::vector<float> values;   // panels x kDescriptorSize x kPanel
  std::vector<float> squared;  // panels x kPanel
  Eigen::Index count = 0;
};

Panels panels_of(const ModelDescriptors& model) {
  Panels p;
  p.count = (model.rows() + kPanel - 1) / kPanel;
  const auto slots = static_cast<std::size_t>(p.count * kPanel);
  p.values.assign(slots * kDescriptorSize, 0.0f);
  p.squared.assign(slots, std::numeric_limits<float>::infinity());
  for (Eigen::Index j = 0; j < model.rows(); ++j) {
    const float* row = model.row(j).data();
    const auto panel = static_cast<std::size_t>(j / kPanel);
    const auto lane = static_cast<std::size_t>(j % kPanel);
    for (int k = 0; k < kDescriptorSize; ++k)
      p.values[(panel * kDescriptorSize + static_cast<std::size_t>(k)) * kPanel + lane] = row[k];
    p.squared[static_cast<std::size_t>(j)] = squared_norm(row);
  }
  return p;
}

// One task's scan rows against every model descriptor: the nearest model descriptor of each
// row (first minimum), and for each model descriptor the nearest of these rows (first minimum).
struct BlockTask {
  const float* scan = nullptr;          // rows x kDescriptorSize, row-major
  const float* scan_squared = nullptr;  // rows
  int rows = 0;
  std::uint32_t first_row = 0;  // the rows' index in the whole scan
  const Panels* panels = nullptr;
  std::uint32_t* row_nearest = nullptr;  // rows
  float* column_best = nullptr;          // panels x kPanel, infinity on entry
  std::uint32_t* column_nearest = nullptr;
};

// Distances |s|^2 + |m|^2 - 2 s.m, each dot product summed in index order and each lane holding
// one model descriptor: every value is the same IEEE float whatever W (lanes a vector), so the
// SSE2 (W = 4) and AVX2 (W = 8) versions give the same matches. Inlined into each target's
// function (a vector argument of a call would change the ABI between them).
template <int W>
struct Lanes {
  typedef float F __attribute__((vector_size(sizeof(float) * W)));
  typedef std::int32_t I __attribute__((vector_size(sizeof(std::int32_t) * W)));
};

template <int W>
[[gnu::always_inline]] inline void match_block(const BlockTask& t) {
  using F = typename Lanes<W>::F;
  using I = typename Lanes<W>::I;
  constexpr int kParts = kPanel / W;  // vectors a panel
  static_assert(kPanel % W == 0);
  const float inf = std::numeric_limits<float>::infinity();
  const auto load = [](const auto* from, auto& v) { std::memcpy(&v, from, sizeof v); };
  const auto store = [](auto* to, const auto& v) { std::memcpy(to, &v, sizeof v); };
  I lane_index;
  for (int l = 0; l < W; ++l)
    lane_index[l] = l;
  for (int r0 = 0; r0 < t.rows; r0 += kRows) {
    // The step's rows; past the block's end a row of zeros with an infinite squared norm.
    float s[kRows][kDescriptorSize];
    float sq[kRows];
    for (int r = 0; r < kRows; ++r) {
      if (r0 + r < t.rows) {
        std::memcpy(s[r], t.scan + static_cast<std::ptrdiff_t>(r0 + r) * kDescriptorSize,
                    sizeof s[r]);
        sq[r] = t.scan_squared[r0 + r];
      } else {
        std::fill(s[r], s[r] + kDescriptorSize, 0.0f);
        sq[r] = inf;
      }
    }
    // Per row and lane, the best distance so far and its model descriptor (each lane sees its
    // descriptors in ascending order: strict comparisons keep the first minimum).
    F row_best[kRows][kParts];
    I row_index[kRows][kParts];
    for (int r = 0; r < kRows; ++r) {
      for (int h = 0; h < kParts; ++h) {
        row_best[r][h] = F{} + inf;
        row_index[r][h] = I{};
      }
    }
    for (Eigen::Index p = 0; p < t.panels->count; ++p) {
      const float* m = t.panels->values.data() + p * kDescriptorSize * kPanel;
      for (int h = 0; h < kParts; ++h) {
        F acc[kRows] = {};
        for (int k = 0; k < kDescriptorSize; ++k) {
          F mk;
          load(m + k * kPanel + h * W, mk);
          for (int r = 0; r < kRows; ++r)
            acc[r] += s[r][k] * mk;
        }
        const std::ptrdiff_t column = p * kPanel + h * W;
        F mq, cb;
        I ci;
        load(t.panels->squared.data() + column, mq);
        load(t.column_best + column, cb);
        load(t.column_nearest + column, ci);
        const I j = lane_index + static_cast<std::int32_t>(column);
        for (int r = 0; r < kRows; ++r) {
          const F d = (sq[r] + mq) - 2.0f * acc[r];
          const I closer = d < row_best[r][h];
          row_best[r][h] = closer ? d : row_best[r][h];
          row_index[r][h] = closer ? j : row_index[r][h];
          // Rows in ascending order: the strict comparison keeps each column's first minimum.
          const I nearer = d < cb;
          cb = nearer ? d : cb;
          ci = nearer ? I{} + static_cast<std::int32_t>(t.first_row + r0 + r) : ci;
        }
        store(t.column_best + column, cb);
        store(t.column_nearest + column, ci);
      }
    }
    for (int r = 0; r < kRows && r0 + r < t.rows; ++r) {
      float best = inf;
      std::int32_t index = 0;
      for (int h = 0; h < kParts; ++h) {
        for (int l = 0; l < W; ++l) {
          const float d = row_best[r][h][l];
          const std::int32_t j = row_index[r][h][l];
          if (d < best || (d == best && j < index)) {
            best = d;
            index = j;
          }
        }
      }
      t.row_nearest[r0 + r] = static_cast<std::uint32_t>(index);
    }
  }
}

#if NURBSREG_HOT_VERSIONS
NURBSREG_TARGET_V3 void match_rows(const BlockTask& t) {
  match_block<8>(t);
}
NURBSREG_TARGET_DEFAULT void match_rows(const BlockTask& t) {
  match_block<4>(t);
}
#else
void match_rows(const BlockTask& t) {
#if defined(__AVX__)
  match_block<8>(t);
#else
  match_block<4>(t);
#endif
}
#endif

}  // namespace

std::vector<Match> match_descriptors(const DescriptorMatrix& scan, const ModelDescriptors& model) {
  const Eigen::Index ns = scan.rows();
  const Eigen::Index nm = model.rows();
  std::vector<Match> out;
  if (scan.cols() != kDescriptorSize || model.cols() != kDescriptorSize)
    throw std::invalid_argument("match_descriptors: descriptors of another length");
  if (ns == 0 || nm == 0) return out;
  const Panels panels = panels_of(model);
  std::vector<float> scan_squared(static_cast<std::size_t>(ns));
  for (Eigen::Index i = 0; i < ns; ++i)
    scan_squared[static_cast<std::size_t>(i)] = squared_norm(scan.row(i).data());
  const Eigen::Index blocks = (ns + kBlock - 1) / kBlock;
  std::vector<std::uint32_t> forward(static_cast<std::size_t>(ns));
  // Per block, each model descriptor's nearest scan row in the block and its distance.
  const auto slots = static_cast<std::size_t>(panels.count * kPanel);
  std::vector<std::vector<float>> block_best(static_cast<std::size_t>(blocks));
  std::vector<std::vector<std::uint32_t>> block_nearest(static_cast<std::size_t>(blocks));
  tbb::parallel_for(Eigen::Index{0}, blocks, [&](Eigen::Index b) {
    const Eigen::Index begin = b * kBlock;
    auto& best = block_best[static_cast<std::size_t>(b)];
    auto& nearest = block_nearest[static_cast<std::size_t>(b)];
    best.assign(slots, std::numeric_limits<float>::infinity());
    nearest.assign(slots, 0u);
    BlockTask t;
    t.scan = scan.row(begin).data();
    t.scan_squared = scan_squared.data() + begin;
    t.rows = static_cast<int>(std::min(kBlock, ns - begin));
    t.first_row = static_cast<std::uint32_t>(begin);
    t.panels = &panels;
    t.row_nearest = forward.data() + begin;
    t.column_best = best.data();
    t.column_nearest = nearest.data();
    match_rows(t);
  });
  nurbsreg::engine::stop_if_cancelled();
  out.reserve(static_cast<std::size_t>(ns + nm));
  for (Eigen::Index i = 0; i < ns; ++i)
    out.push_back({static_cast<std::uint32_t>(i), forward[static_cast<std::size_t>(i)]});
  for (Eigen::Index j = 0; j < nm; ++j) {
    const auto jj = static_cast<std::size_t>(j);
    float best = std::numeric_limits<float>::infinity();
    std::uint32_t nearest = 0;
    for (std::size_t b = 0; b < block_best.size(); ++b) {
      if (block_best[b][jj] < best) {
        best = block_best[b][jj];
        nearest = block_nearest[b][jj];
      }
    }
    out.push_back({nearest, static_cast<std::uint32_t>(j)});
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace nurbsreg::registration::detail
