#pragma once
// An answer other than 200, thrown by a handler's steps and turned into {"error": "..."} with
// its status (private to service/).

#include <stdexcept>
#include <string>

namespace nurbsreg::service::detail {

class HttpError : public std::runtime_error {
 public:
  HttpError(int status, const std::string& message, int retry_after_seconds = 0)
      : std::runtime_error(message), status_(status), retry_after_(retry_after_seconds) {}
  int status() const { return status_; }
  int retry_after() const { return retry_after_; }  // 0: no Retry-After header

 private:
  int status_;
  int retry_after_;
};

}  // namespace nurbsreg::service::detail
