#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "nurbsreg/icp/model_finder.hpp"

namespace nurbsreg::icp {

// A certificate's ball is proven only as far as the anchor's patch and its neighbours on the same
// surface reach (engine: a box N spans at most certificate_span patches beyond the foot's on each
// side, certificate_span_for; any other item within the ball caps its clearance). A cap far beyond
// that costs certifying searches that give up: the IEA blade's faces are 2,744 Bezier strips each,
// about 5 cm wide against a cap of 1% of its 117 m diagonal, and 73% of its certifying searches
// gave up (bench/README.md, issue 26's ninth pass). So the cap is also held to a few widths of the
// patches where most of the surface lies: the narrow width of a patch taken as the shorter of |S_s|
// and |S_t| at its centre (its local parameters span [0, 1]), weighted by |S_s x S_t| there (its
// area, about). On parts whose faces are single patches this is far above 1% of the diagonal and
// changes nothing. Only for large scans: at 50,000 points the blade's 20,000-point certifying stage
// then made 13,900 certificates instead of 140 and its half views aligned 12% slower, at 1,000,000
// points the full-resolution passes borrow them and the alignment is 11-16% faster
// (bench/README.md).
namespace {
double share_cap(const engine::PreparedModel& model) {
  return 1e-2 * model.geometry_bounds().box.diagonal();
}
}  // namespace

double patch_width_cap(const engine::PreparedModel& model) {
  std::vector<std::pair<double, double>> width_area;  // (narrow width, area) per patch
  width_area.reserve(model.patch_count());
  double total = 0.0;
  for (std::size_t k = 0; k < model.patch_count(); ++k) {
    engine::Vec3 d[6];
    model.patch(k).patch.derivatives(0.5, 0.5, d);
    const double area = d[1].cross(d[2]).norm();
    const double width = std::min(d[1].norm(), d[2].norm());
    if (!std::isfinite(area) || !std::isfinite(width) || !(area > 0.0)) continue;
    width_area.emplace_back(width, area);
    total += area;
  }
  std::sort(width_area.begin(), width_area.end());
  double below = 0.0;
  for (const auto& [width, area] : width_area) {
    below += area;
    if (below >= 0.5 * total) return kCertificateWidths * width;
  }
  return std::numeric_limits<double>::infinity();
}

double certificate_radius_for(const engine::PreparedModel& model, std::size_t scan_size) {
  const double share = share_cap(model);
  return scan_size >= kWidthCapPoints
             ? certificate_radius_for(scan_size, share, patch_width_cap(model))
             : share;
}

}  // namespace nurbsreg::icp
