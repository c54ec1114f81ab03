#pragma once
// The message of the InputError that parsing a JSON model text throws, for io tests.

#include <gtest/gtest.h>

#include <string>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"

namespace nurbsreg::test {

// "" if `text` parses; the error must name the file "m.json".
inline std::string parse_error(const std::string& text) {
  try {
    io::parse_model(text, "m.json");
  } catch (const io::InputError& e) {
    EXPECT_EQ(e.file(), "m.json");
    return e.what();
  }
  return "";
}

}  // namespace nurbsreg::test
