#pragma once
// The first surface of an examples/*.json model (polynomial: degree, knots, control point grid),
// read with nlohmann::json directly, for engine tests (they do not link io).

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nurbsreg/engine/nurbs_surface.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {

inline engine::NurbsSurface read_example_surface(const std::string& file) {
  std::ifstream in(nurbsreg::test::examples_dir() + "/" + file);
  EXPECT_TRUE(in.good()) << "examples/" << file;
  const nlohmann::json j = nlohmann::json::parse(in).at("surfaces").at(0);
  engine::NurbsSurface s;
  s.name = j.at("name").get<std::string>();
  s.degree_u = j.at("degree").at(0).get<int>();
  s.degree_v = j.at("degree").at(1).get<int>();
  s.knots_u = j.at("knots_u").get<std::vector<double>>();
  s.knots_v = j.at("knots_v").get<std::vector<double>>();
  const nlohmann::json& grid = j.at("control_points");
  s.count_u = static_cast<int>(grid.size());
  s.count_v = static_cast<int>(grid.at(0).size());
  for (const nlohmann::json& row : grid) {
    for (const nlohmann::json& p : row)
      s.control_points.emplace_back(p.at(0).get<double>(), p.at(1).get<double>(),
                                    p.at(2).get<double>());
  }
  return s;
}

}  // namespace nurbsreg::test
