#pragma once
// Clutter in an inspection: a scan of a part on its fixture, or with another object in view,
// has points that are not on the part. Counted as deviations they fail any verdict; left out
// silently they would hide a missing or misplaced feature. So they are left out only on request
// (`inspect --exclude-beyond D`), counted and named in every output, and when not requested the
// user is told how many points lie far off and which option would leave them out.

#include <optional>
#include <string>

#include "nurbsreg/inspect/deviations.hpp"
#include "nurbsreg/inspect/statistics.hpp"

namespace nurbsreg::inspect {

// An error naming `option` when `distance` is not a finite number beyond the tolerance band
// (excluding points inside or near the band would pass a part by dropping its deviations).
std::optional<std::string> validate_exclusion(double distance, const Tolerance& band,
                                              const std::string& option);

// With nothing excluded: a hint when the points farther than 10 x the band from the model are
// numerous enough to decide the verdict alone (more than 1 - min_inside of the points); names
// their share, the distance and `option`. Nothing otherwise.
std::optional<std::string> clutter_hint(const PointDeviations& deviations, const Tolerance& band,
                                        double min_inside, const std::string& option);

}  // namespace nurbsreg::inspect
