#pragma once
// Internal to registration: why a failed alignment from any pose may have had no chance. A flat
// scan (a patch of one face) fits every flat face of the model anywhere on it, and a scan along
// a line fits every straight edge: no pose is the answer, and a user reading only "no consistent
// triple" would look for a wrong model or wrong units instead.

#include <optional>
#include <span>
#include <string>

#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::registration::detail {

// One clause when the scan's points lie on a plane or a line to within twice its noise (rms
// distance from the principal plane or line of all its points, `noise` as estimate_noise gives
// it); nothing otherwise (and for fewer than three points).
std::optional<std::string> flat_scan_note(std::span<const engine::Vec3> scan, double noise);

}  // namespace nurbsreg::registration::detail
