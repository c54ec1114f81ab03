#pragma once
// Sessions: one client's stream of frames (private to service/). A session keeps its own
// registration::Aligner (warm buffers) and the pose of its last good frame, which is the next
// frame's starting pose unless the request gives `init`. A session belongs to one model.
//
// Bounded: at most `max_sessions` live at once; one idle longer than `idle_seconds` expires
// (checked whenever a session is opened). When the table is full, the least recently used idle
// session gives way; when every session is in use, opening a new one fails (503).
// Frames of one session run one at a time (Session::busy, a FrameLock); the store's mutex guards
// the table and the bookkeeping fields, never a frame's computation.

#include <Eigen/Geometry>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "frame_lock.hpp"
#include "models.hpp"
#include "nurbsreg/service/request_options.hpp"

namespace nurbsreg::service::detail {

struct Session {
  std::string id;
  std::shared_ptr<ServedModel> model;
  FrameLock busy;  // held for a frame
  // Guarded by `busy`:
  std::unique_ptr<registration::Aligner> aligner;
  IcpOverrides overrides;
  std::optional<Eigen::Isometry3d> pose;  // the last good frame's T_model_scan
  std::uint64_t frames = 0;
  // Guarded by the store's mutex:
  int users = 0;
  std::chrono::steady_clock::time_point last_used;
};

class SessionStore {
 public:
  SessionStore(std::size_t max_sessions, double idle_seconds)
      : max_sessions_(max_sessions), idle_(idle_seconds) {}

  enum class OpenError { none, full, other_model };
  // The session `id` (created for `model` when new), marked in use; nullptr and the reason
  // when it cannot be had.
  std::shared_ptr<Session> open(const std::string& id, const std::shared_ptr<ServedModel>& model,
                                OpenError& error);
  // Ends a use started by open().
  void close(const std::shared_ptr<Session>& session);
  std::size_t size() const;

 private:
  void expire(std::chrono::steady_clock::time_point now);

  const std::size_t max_sessions_;
  const std::chrono::duration<double> idle_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
};

}  // namespace nurbsreg::service::detail
