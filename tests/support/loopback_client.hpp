#pragma once
// An HTTP client of a test's server on 127.0.0.1, with time-outs that bound every request (a
// server that stops answering fails the test instead of hanging it; longer in the sanitizer
// builds). Include after Eigen: glibc's <resolv.h>, which httplib includes, defines a macro `_res`
// that Eigen uses as a parameter name.

#include <httplib.h>

#include <memory>

#include "support/test_scale.hpp"

namespace nurbsreg::test {

inline std::unique_ptr<httplib::Client> loopback_client(int port) {
  auto c = std::make_unique<httplib::Client>("127.0.0.1", port);
  c->set_connection_timeout(10);
  // A 60,000-point alignment under ThreadSanitizer on a busy 2-core machine takes minutes.
  c->set_read_timeout(test_size(120, 900));
  c->set_write_timeout(60);
  return c;
}

}  // namespace nurbsreg::test
