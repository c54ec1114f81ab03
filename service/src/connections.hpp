#pragma once
// Closing idle keep-alive connections at shutdown (private to service/). httplib 0.11's stop()
// closes the listening socket, but a worker waiting on an idle keep-alive connection only
// notices when the client sends again or the keep-alive time-out passes, so a SIGTERM waited up
// to --keep-alive for every idle client. httplib does not hand out its accepted sockets, so the
// tracker knows the connections by their peer address: a request is active from routing (its
// headers are in) until its answer is written (httplib's logger runs after the write), and at
// shutdown every other connected socket of the server's port (found in /proc/self/fd) has its
// reading side shut down. Its worker then reads end-of-file and closes it; an active request is
// left alone, answered, and its connection closed after the answer (the server is stopped).

#include <cstddef>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace nurbsreg::service::detail {

class ConnectionTracker {
 public:
  // A request from peer (address, port) is being handled / has been answered.
  void begin(const std::string& address, int port);
  void end(const std::string& address, int port);
  // Shuts down the reading side of every connected TCP socket of this process whose local port
  // is `local_port` and whose peer has no active request. Returns how many.
  std::size_t close_idle(int local_port);

 private:
  std::mutex mutex_;
  std::map<std::pair<std::string, int>, int> active_;  // peer -> requests in handling
};

}  // namespace nurbsreg::service::detail
