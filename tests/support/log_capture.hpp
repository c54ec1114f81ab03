#pragma once
// The log lines one call writes through spdlog's default logger at `level` and above: the
// default logger is swapped for a capturing one for the call and restored afterwards, also when
// the call throws.

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <string>
#include <vector>

namespace nurbsreg::test {

template <typename F>
std::vector<std::string> log_lines_of(spdlog::level::level_enum level, F&& call,
                                      std::size_t capacity = 100000) {
  const auto sink = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(capacity);
  const auto capture = std::make_shared<spdlog::logger>("capture", sink);
  capture->set_level(level);
  const auto previous = spdlog::default_logger();
  spdlog::set_default_logger(capture);
  try {
    call();
  } catch (...) {
    spdlog::set_default_logger(previous);
    throw;
  }
  spdlog::set_default_logger(previous);
  std::vector<std::string> lines;
  for (const auto& m : sink->last_raw())
    lines.emplace_back(m.payload.begin(), m.payload.end());
  return lines;
}

}  // namespace nurbsreg::test
