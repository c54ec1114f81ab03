#include "sessions.hpp"

namespace nurbsreg::service::detail {

void SessionStore::expire(std::chrono::steady_clock::time_point now) {
  for (auto it = sessions_.begin(); it != sessions_.end();) {
    const Session& s = *it->second;
    if (s.users == 0 && now - s.last_used > idle_) {
      it = sessions_.erase(it);
    } else {
      ++it;
    }
  }
}

std::shared_ptr<Session> SessionStore::open(const std::string& id,
                                            const std::shared_ptr<ServedModel>& model,
                                            OpenError& error) {
  error = OpenError::none;
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard lock(mutex_);
  expire(now);
  if (const auto it = sessions_.find(id); it != sessions_.end()) {
    if (it->second->model != model) {
      error = OpenError::other_model;
      return nullptr;
    }
    ++it->second->users;
    it->second->last_used = now;
    return it->second;
  }
  if (sessions_.size() >= max_sessions_) {
    auto victim = sessions_.end();
    for (auto it = sessions_.begin(); it != sessions_.end(); ++it) {
      if (it->second->users == 0 &&
          (victim == sessions_.end() || it->second->last_used < victim->second->last_used)) {
        victim = it;
      }
    }
    if (victim == sessions_.end()) {
      error = OpenError::full;
      return nullptr;
    }
    sessions_.erase(victim);
  }
  auto session = std::make_shared<Session>();
  session->id = id;
  session->model = model;
  session->users = 1;
  session->last_used = now;
  sessions_.emplace(id, session);
  return session;
}

void SessionStore::close(const std::shared_ptr<Session>& session) {
  std::lock_guard lock(mutex_);
  --session->users;
  session->last_used = std::chrono::steady_clock::now();
}

std::size_t SessionStore::size() const {
  std::lock_guard lock(mutex_);
  return sessions_.size();
}

}  // namespace nurbsreg::service::detail
