#pragma once
// A saddle z = (x^2 - y^2) / 2 over [-1, 1]^2 scaled by 20 (an exact biquadratic Bezier patch,
// units mm): the same after a half turn about z and about the lines y = x and y = -x, so three
// discrete symmetries (the global stage's symmetry tests, the features cache's stored turns).

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::test {

inline engine::Model saddle_model() {
  engine::NurbsSurface s;
  s.name = "saddle";
  s.degree_u = s.degree_v = 2;
  s.knots_u = s.knots_v = {0, 0, 0, 1, 1, 1};
  s.count_u = s.count_v = 3;
  s.control_points.assign(9, engine::Vec3::Zero());
  // Bezier control net of x^2/2 over [-1, 1]: values 0.5, -0.5, 0.5 at t = 0, 0.5, 1.
  const double c[3] = {0.5, -0.5, 0.5};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      s.control_points[static_cast<std::size_t>(i * 3 + j)] =
          engine::Vec3(20.0 * (i - 1), 20.0 * (j - 1), 20.0 * (c[i] - c[j]));
  engine::Model m;
  m.units = "mm";
  m.surfaces.push_back(std::move(s));
  return m;
}

}  // namespace nurbsreg::test
