#include "nurbsreg/inspect/deviation_ply.hpp"

#include <spdlog/fmt/fmt.h>

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <vector>

#include "nurbsreg/io/atomic_file.hpp"

namespace nurbsreg::inspect {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the PLY writer copies native values as binary_little_endian");

// Bytes of one vertex record, in header order.
constexpr std::size_t kRecord = 3 * 4 + 3 + 4 + 4 + 2 * 8 + 4 + 4 + 4 + 4;
constexpr std::size_t kBlockPoints = 4096;

template <class T>
char* put(char* at, T value) {
  std::memcpy(at, &value, sizeof value);
  return at + sizeof value;
}

}  // namespace

void write_deviation_ply(const std::string& path, const PointDeviations& dev,
                         const ColourScale& scale) {
  io::write_atomically(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n"
        << "comment nurbsreg inspect: signed deviation from the model (> 0 on the outer side)\n"
        << fmt::format("comment tolerance {} {} colour scale {} limits {} {}\n", scale.band.lower,
                       scale.band.upper, to_string(scale.scheme), scale.lower_limit,
                       scale.upper_limit)
        << "element vertex " << dev.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        << "property float signed_distance\nproperty int face\n"
        << "property double u\nproperty double v\n"
        << "property int tolerance\nproperty int index\nproperty float quality\n"
        << "property float scalar_signed_distance\n"
        << "end_header\n";
    std::vector<char> block(kBlockPoints * kRecord);
    for (std::size_t begin = 0; begin < dev.size(); begin += kBlockPoints) {
      const std::size_t end = std::min(dev.size(), begin + kBlockPoints);
      char* at = block.data();
      for (std::size_t i = begin; i < end; ++i) {
        const engine::Vec3& p = dev.points[i];
        const double d = dev.signed_distance[i];
        const Rgb c = scale.colour(d);
        at = put(at, static_cast<float>(p.x()));
        at = put(at, static_cast<float>(p.y()));
        at = put(at, static_cast<float>(p.z()));
        at = put(at, c.r);
        at = put(at, c.g);
        at = put(at, c.b);
        at = put(at, static_cast<float>(d));
        at = put(at, static_cast<std::int32_t>(dev.face[i]));
        at = put(at, dev.u[i]);
        at = put(at, dev.v[i]);
        const std::int32_t side = d < scale.band.lower ? -1 : (d > scale.band.upper ? 1 : 0);
        at = put(at, side);
        at = put(at, static_cast<std::int32_t>(dev.source_index[i]));
        at = put(at, static_cast<float>(d));
        at = put(at, static_cast<float>(d));
      }
      out.write(block.data(), at - block.data());
    }
  });
}

}  // namespace nurbsreg::inspect
