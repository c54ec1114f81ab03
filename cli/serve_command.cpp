// `nurbsreg serve`: the long-running alignment service (CONTRACT.md §4, README "Alignment
// service"). Thin: options in, nurbsreg::service::Service out. SIGTERM / SIGINT stop accepting;
// the requests already read are answered and the command exits 0.

#include <pthread.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "commands.hpp"
#include "common.hpp"
#include "frame_jobs.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/service/service.hpp"

namespace nurbsreg::cli {
namespace {

struct ServeArgs {
  std::vector<std::string> models;
  std::vector<std::string> ids;
  service::ServiceOptions service;
  std::string token_file;
  IcpArgs icp;
  int threads = 0;
};

std::string read_token(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw io::InputError(path, "cannot open the token file");
  std::string token;
  std::getline(in, token);
  while (!token.empty() && (token.back() == '\r' || token.back() == ' '))
    token.pop_back();
  if (token.empty()) throw io::InputError(path, "the token file's first line is empty");
  return token;
}

void run_serve(ServeArgs& args) {
  const auto threads = limit_threads(args.threads);
  if (!args.ids.empty() && args.ids.size() != args.models.size()) {
    throw UsageError("--id: give one per --model, in the same order, or none");
  }
  args.service.icp = icp_options(args.icp);
  if (!args.token_file.empty()) args.service.token = read_token(args.token_file);
  if (auto error = args.service.validate()) throw UsageError(*error);

  // Signals go to one thread that stops the service; every other thread (HTTP workers, TBB)
  // inherits the blocked mask, so a signal never interrupts a frame.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  // A client that hangs up mid-answer is a failed write for that connection, not a signal.
  std::signal(SIGPIPE, SIG_IGN);

  service::Service server(args.service);
  for (std::size_t k = 0; k < args.models.size(); ++k) {
    server.add_model(args.models[k], args.ids.empty() ? std::string() : args.ids[k]);
  }
  const int port = server.bind();
  // The one line scripts read to find the port (with --port 0, an ephemeral one).
  std::cout << "listening on " << args.service.bind << ":" << port << std::endl;
  spdlog::info("serving on http://{}:{} (max {} frames in flight, {} connections)",
               args.service.bind, port, args.service.max_inflight, args.service.connections);

  std::atomic<bool> finished{false};
  std::thread watcher([&] {
    int signal = 0;
    sigwait(&stop_signals, &signal);
    if (finished) return;
    spdlog::info("signal {}: no new connections; answering the requests in flight", signal);
    // Repeated: a stop that lands before the accept loop has started is retried.
    while (!finished) {
      server.stop();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  server.run();
  finished = true;
  // Wake the watcher if no signal came (run() ended by itself).
  pthread_kill(watcher.native_handle(), SIGTERM);
  watcher.join();
  spdlog::info("stopped");
}

}  // namespace

void add_serve_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("serve", "Long-running HTTP alignment service (README)");
  auto args = std::make_shared<ServeArgs>();
  service::ServiceOptions& s = args->service;
  cmd->add_option("--model", args->models, "Model file to load and prepare (repeatable)")
      ->required();
  cmd->add_option("--id", args->ids, "Model ids, one per --model (default: the file's stem)");
  cmd->add_option("--bind", s.bind, "Address to listen on (default 127.0.0.1: loopback only)");
  cmd->add_option("--port", s.port, "Port (0: an ephemeral one, printed)")->required();
  cmd->add_option("--threads", args->threads,
                  "Worker threads for the frames' computation (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--connections", s.connections,
                  "Connections served at once (one worker thread each)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-inflight", s.max_inflight,
                  "Frames computed at once; more get 503 with Retry-After (0 = hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--max-queue", s.max_queue,
                  "Connections waiting for a worker; more get 503 (0 = --connections)");
  cmd->add_option("--max-body", s.max_body, "Largest request body in bytes; larger: 413")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--token-file", args->token_file,
                  "Require 'Authorization: Bearer <token>' with the file's first line");
  cmd->add_option("--model-root", s.model_root,
                  "Allow POST /v1/models to load model files from below this directory");
  cmd->add_option(
         "--time-limit", s.time_limit_seconds,
         "Seconds a request may take in all: its upload (408), its wait for a busy session "
         "(409) and its computation (504)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--session-timeout", s.session_idle_seconds,
                  "Seconds after which an idle session expires")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-sessions", s.max_sessions, "Live sessions at most")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--keep-alive", s.keep_alive_seconds,
                  "Seconds an idle keep-alive connection stays open")
      ->check(CLI::NonNegativeNumber);
  add_icp_options(*cmd, args->icp);
  cmd->callback([args] { run_serve(*args); });
}

}  // namespace nurbsreg::cli
