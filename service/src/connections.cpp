#include "connections.hpp"

#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace nurbsreg::service::detail {
namespace {

// The port and numeric host of a socket address (as httplib reports a request's remote_addr:
// getnameinfo with NI_NUMERICHOST); false for anything but IPv4 / IPv6.
bool numeric_address(const sockaddr_storage& address, socklen_t length, std::string& host,
                     int& port) {
  if (address.ss_family == AF_INET) {
    port = ntohs(reinterpret_cast<const sockaddr_in&>(address).sin_port);
  } else if (address.ss_family == AF_INET6) {
    port = ntohs(reinterpret_cast<const sockaddr_in6&>(address).sin6_port);
  } else {
    return false;
  }
  char text[NI_MAXHOST];
  if (getnameinfo(reinterpret_cast<const sockaddr*>(&address), length, text, sizeof text, nullptr,
                  0, NI_NUMERICHOST) != 0) {
    return false;
  }
  host = text;
  return true;
}

}  // namespace

void ConnectionTracker::begin(const std::string& address, int port) {
  std::lock_guard lock(mutex_);
  ++active_[{address, port}];
}

void ConnectionTracker::end(const std::string& address, int port) {
  std::lock_guard lock(mutex_);
  // A request that never reached routing (a malformed request line) ends without a begin.
  const auto it = active_.find({address, port});
  if (it != active_.end() && --it->second <= 0) active_.erase(it);
}

std::size_t ConnectionTracker::close_idle(int local_port) {
  std::size_t closed = 0;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/fd", error)) {
    const int fd = std::atoi(entry.path().filename().c_str());
    struct stat info {};
    if (fstat(fd, &info) != 0 || !S_ISSOCK(info.st_mode)) continue;
    sockaddr_storage local{}, peer{};
    socklen_t local_length = sizeof local, peer_length = sizeof peer;
    std::string local_host, peer_host;
    int port = 0, peer_port = 0;
    // Connected sockets of the server's port only: not the listening socket (no peer), not a
    // client socket of this process (its local port is its own).
    if (getsockname(fd, reinterpret_cast<sockaddr*>(&local), &local_length) != 0 ||
        !numeric_address(local, local_length, local_host, port) || port != local_port ||
        getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &peer_length) != 0 ||
        !numeric_address(peer, peer_length, peer_host, peer_port)) {
      continue;
    }
    std::lock_guard lock(mutex_);
    if (active_.count({peer_host, peer_port}) > 0) continue;
    if (shutdown(fd, SHUT_RD) == 0) ++closed;
  }
  return closed;
}

}  // namespace nurbsreg::service::detail
