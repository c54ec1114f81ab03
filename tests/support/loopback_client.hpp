#pragma once
// An HTTP client of a test's server on 127.0.0.1, with time-outs that bound every request (a
// server that stops answering fails the test instead of hanging it). Include after Eigen: glibc's
// <resolv.h>, which httplib includes, defines a macro `_res` that Eigen uses as a parameter name.

#include <httplib.h>

#include <memory>

namespace nurbsreg::test {

inline std::unique_ptr<httplib::Client> loopback_client(int port) {
  auto c = std::make_unique<httplib::Client>("127.0.0.1", port);
  c->set_connection_timeout(10);
  c->set_read_timeout(120);
  c->set_write_timeout(60);
  return c;
}

}  // namespace nurbsreg::test
