#pragma once
// Starts the real `nurbsreg serve` for end-to-end tests: on an ephemeral loopback port (read
// from the "listening on ADDR:PORT" line it prints), killed when the object goes away whatever
// the test did, so no test leaves a server behind. When the test has failed by then, the
// server's log goes to stderr (a sanitizer report or the server's own error is there, and the
// test's scratch directory is removed).

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>
#include "support/source_paths.hpp"
#include "support/test_scale.hpp"

namespace nurbsreg::test {

class ServerProcess {
 public:
  // `args` after `serve` (e.g. "--model m.json"); `--port 0` is added, and in the sanitizer
  // builds `--time-limit 600` unless `args` sets one: they compute a frame several times slower
  // than Release, past the 30 s default on a busy machine, and a 504 there says nothing of what
  // the test checks. `log` receives stderr. `global` goes before `serve` (e.g. "--no-cache").
  ServerProcess(const std::string& args, const std::string& log, const std::string& global = "") {
    log_ = log;
    const std::string limit =
        kReducedTests && args.find("--time-limit") == std::string::npos ? " --time-limit 600" : "";
    int out[2];
    if (::pipe(out) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], STDOUT_FILENO);
      ::close(out[0]);
      ::close(out[1]);
      const std::string command = "exec " + nurbsreg::test::nurbsreg_binary() + " " + global +
                                  " serve " + args + limit + " --port 0 2>" + log;
      ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(out[1]);
    // The first stdout line, within 60 s (model preparation of the small examples takes ms; the
    // sanitizer builds on a busy machine, up to minutes).
    std::string line;
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::seconds(kReducedTests ? 300 : 60);
    while (line.find('\n') == std::string::npos && std::chrono::steady_clock::now() < deadline) {
      pollfd p{out[0], POLLIN, 0};
      if (::poll(&p, 1, 200) <= 0) continue;
      char c;
      if (::read(out[0], &c, 1) != 1) break;
      line.push_back(c);
    }
    ::close(out[0]);
    const std::size_t colon = line.rfind(':');
    if (line.starts_with("listening on ") && colon != std::string::npos) {
      port_ = std::atoi(line.c_str() + colon + 1);
    }
  }
  ~ServerProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    if (::testing::Test::HasFailure()) {
      std::ifstream in(log_);
      const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
      std::cerr << "--- nurbsreg serve's log (" << log_ << "):\n" << text << "\n---\n";
    }
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  int port() const { return port_; }  // 0 when the server did not come up
  pid_t pid() const { return pid_; }

  // Sends SIGTERM and waits up to `seconds` for the exit; its status, or -1 (then killed).
  int terminate(double seconds) {
    ::kill(pid_, SIGTERM);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

 private:
  std::string log_;
  pid_t pid_ = -1;
  int port_ = 0;
  bool exited_ = false;
};

}  // namespace nurbsreg::test
