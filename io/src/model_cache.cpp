// The converted-model cache: entry encoding, checks and the read-through load (model_cache.hpp).

#include "nurbsreg/io/model_cache.hpp"

#include <spdlog/spdlog.h>

#include <bit>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string_view>

#include "cache_codec.hpp"
#include "nurbsreg/io/atomic_file.hpp"
#include "printable.hpp"

#ifndef NURBSREG_VERSION
#define NURBSREG_VERSION "unknown"
#endif

namespace nurbsreg::io {
namespace {

// Bump when the STEP/IGES conversion (cad_import.cpp, cad_face_conversion.cpp) or the payload
// below changes: entries of other revisions are then stale.
constexpr int kCacheRevision = 1;
constexpr char kMagic[8] = {'N', 'R', 'B', 'M', 'O', 'D', 'E', 'L'};
constexpr std::uint32_t kFormat = 1;

constexpr std::uint64_t kP1 = 0x9e3779b97f4a7c15ull, kP2 = 0xc2b2ae3d27d4eb4full;

std::uint64_t splitmix(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

using detail::hex;
using detail::read_whole_file;
using detail::Reader;
using detail::Writer;

void write_curve(Writer& w, const engine::NurbsCurve& c) {
  w.str(c.name);
  w.i32(c.degree);
  w.i32(c.dimension);
  w.doubles(c.knots);
  w.points(c.control_points);
  w.doubles(c.weights);
}

engine::NurbsCurve read_curve(Reader& r) {
  engine::NurbsCurve c;
  c.name = r.str();
  c.degree = r.i32();
  c.dimension = r.i32();
  c.knots = r.doubles();
  c.control_points = r.points();
  c.weights = r.doubles();
  return c;
}

std::string encode_payload(const engine::Model& m) {
  Writer w;
  w.str(m.units);
  w.u64(m.surfaces.size());
  for (const engine::NurbsSurface& s : m.surfaces) {
    w.str(s.name);
    w.i32(s.degree_u);
    w.i32(s.degree_v);
    w.i32(s.count_u);
    w.i32(s.count_v);
    w.doubles(s.knots_u);
    w.doubles(s.knots_v);
    w.points(s.control_points);
    w.doubles(s.weights);
    w.i32(s.reversed ? 1 : 0);
    w.u64(s.trim_loops.size());
    for (const engine::TrimLoop& loop : s.trim_loops) {
      w.u64(loop.curves.size());
      for (const engine::TrimCurve& c : loop.curves) {
        write_curve(w, c.uv);
        w.i32(c.edge ? 1 : 0);
        if (c.edge) write_curve(w, *c.edge);
      }
    }
  }
  w.u64(m.curves.size());
  for (const engine::NurbsCurve& c : m.curves)
    write_curve(w, c);
  w.u64(m.skipped_faces.size());
  for (const engine::SkippedFace& f : m.skipped_faces) {
    w.i32(f.face);
    w.str(f.reason);
  }
  return std::move(w.bytes());
}

engine::Model decode_payload(std::string_view bytes) {
  Reader r(bytes);
  engine::Model m;
  m.units = r.str();
  m.surfaces.resize(r.count(64));
  for (engine::NurbsSurface& s : m.surfaces) {
    s.name = r.str();
    s.degree_u = r.i32();
    s.degree_v = r.i32();
    s.count_u = r.i32();
    s.count_v = r.i32();
    s.knots_u = r.doubles();
    s.knots_v = r.doubles();
    s.control_points = r.points();
    s.weights = r.doubles();
    s.reversed = r.i32() != 0;
    s.trim_loops.resize(r.count(8));
    for (engine::TrimLoop& loop : s.trim_loops) {
      loop.curves.resize(r.count(16));
      for (engine::TrimCurve& c : loop.curves) {
        c.uv = read_curve(r);
        if (r.i32() != 0) c.edge = read_curve(r);
      }
    }
  }
  m.curves.resize(r.count(40));
  for (engine::NurbsCurve& c : m.curves)
    c = read_curve(r);
  m.skipped_faces.resize(r.count(12));
  for (engine::SkippedFace& f : m.skipped_faces) {
    f.face = r.i32();
    f.reason = r.str();
  }
  if (!r.done()) throw CacheEntryError("bytes after the model (corrupt)");
  return m;
}

}  // namespace

std::string model_cache_version() {
  return std::string("nurbsreg ") + NURBSREG_VERSION + " cache " + std::to_string(kCacheRevision);
}

ModelCacheSettings ModelCacheSettings::from_environment() {
  ModelCacheSettings s;
  const auto env = [](const char* name) -> std::string {
    const char* v = std::getenv(name);
    return v == nullptr ? std::string() : std::string(v);
  };
  if (const std::string dir = env("NURBSREG_CACHE_DIR"); !dir.empty()) {
    s.directory = dir;
  } else if (const std::string xdg = env("XDG_CACHE_HOME"); !xdg.empty()) {
    s.directory = xdg + "/nurbsreg";
  } else if (const std::string home = env("HOME"); !home.empty()) {
    s.directory = home + "/.cache/nurbsreg";
  }
  const std::string off = env("NURBSREG_NO_CACHE");
  s.enabled = !s.directory.empty() && (off.empty() || off == "0");
  return s;
}

ContentHash hash_bytes(std::string_view bytes) {
  std::uint64_t a = 0x243f6a8885a308d3ull ^ bytes.size(), b = 0x13198a2e03707344ull;
  std::size_t k = 0;
  for (; k + 8 <= bytes.size(); k += 8) {
    std::uint64_t w;
    std::memcpy(&w, bytes.data() + k, 8);
    a = std::rotl((a ^ w) * kP1, 29);
    b = std::rotl((b + w) * kP2, 31) ^ a;
  }
  std::uint64_t tail = 0;
  if (k < bytes.size())
    std::memcpy(&tail, bytes.data() + k, bytes.size() - k);  // data() may be null
  a = std::rotl((a ^ tail ^ (std::uint64_t{bytes.size() - k} << 56)) * kP1, 29);
  b = std::rotl((b + tail) * kP2, 31) ^ a;
  return {splitmix(a ^ std::rotl(b, 17)), splitmix(b + kP1 * a)};
}

ContentHash hash_model(const engine::Model& model) {
  return hash_bytes(encode_payload(model));
}

std::string encode_model_entry(const engine::Model& model, const ContentHash& source,
                               std::uint64_t source_size, const std::string& version) {
  const std::string payload = encode_payload(model);
  const ContentHash check = hash_bytes(payload);
  Writer w;
  detail::write_entry_start(w, kMagic, kFormat, version);
  w.u64(source_size);
  w.u64(source.lo);
  w.u64(source.hi);
  w.u64(payload.size());
  w.u64(check.lo);
  w.bytes().append(payload);
  return std::move(w.bytes());
}

engine::Model decode_model_entry(std::string_view bytes, const ContentHash& source,
                                 std::uint64_t source_size, const std::string& version) {
  Reader r = detail::read_entry_start(bytes, kMagic, kFormat, "model cache", version);
  if (r.u64() != source_size || r.u64() != source.lo || r.u64() != source.hi)
    throw CacheEntryError("made from another source file (stale)");
  const std::uint64_t size = r.u64();
  const std::uint64_t check = r.u64();
  const std::size_t header = sizeof kMagic + r.offset();
  if (bytes.size() != header + size)
    throw CacheEntryError("its size does not match its header (truncated or corrupt)");
  const std::string_view payload = bytes.substr(header);
  if (hash_bytes(payload).lo != check) throw CacheEntryError("checksum mismatch (corrupt)");
  engine::Model model = decode_payload(payload);
  // The model's names come from the entry's bytes: shown printable.
  if (auto error = model.validate()) {
    throw CacheEntryError("invalid model (" + text_detail::printable(*error) + ")");
  }
  return model;
}

std::string model_cache_entry_path(const ModelCacheSettings& settings, const ContentHash& source,
                                   std::uint64_t source_size) {
  const std::uint64_t version = hash_bytes(settings.version).lo;
  return (std::filesystem::path(settings.directory) /
          (hex(source.lo ^ source_size) + hex(source.hi) + "-" + hex(version) + ".nrbmodel"))
      .string();
}

engine::Model read_model_through_cache(
    const std::string& path, const ModelCacheSettings& settings,
    const std::function<engine::Model(const std::string&)>& convert, CacheOutcome* outcome) {
  CacheOutcome done = CacheOutcome::disabled;
  const auto finish = [&](engine::Model m) {
    if (outcome != nullptr) *outcome = done;
    return m;
  };
  // An unreadable source is convert's to report (it names the file and the problem).
  const std::optional<std::string> source = settings.enabled ? read_whole_file(path) : std::nullopt;
  // A conversion takes seconds on a large part (OpenCASCADE): said when it is done (and, by the
  // import's own wait for its process, while it runs past a second).
  const auto converted = [&] {
    const auto start = std::chrono::steady_clock::now();
    engine::Model model = convert(path);
    spdlog::info("{}: converted in {:.2f} s ({} surfaces, {} curves)", path,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                 model.surfaces.size(), model.curves.size());
    return model;
  };
  if (!settings.enabled) return finish(converted());
  if (!source) return finish(convert(path));
  const ContentHash key = hash_bytes(*source);
  const std::uint64_t size = source->size();
  const std::string entry = model_cache_entry_path(settings, key, size);
  done = CacheOutcome::miss;
  if (const std::optional<std::string> bytes = read_whole_file(entry)) {
    try {
      engine::Model model = decode_model_entry(*bytes, key, size, settings.version);
      spdlog::debug("{}: read from the model cache ({})", path, entry);
      done = CacheOutcome::hit;
      return finish(std::move(model));
    } catch (const CacheEntryError& e) {
      spdlog::warn("{}: the model cache entry {} is not usable: {}; converting the file again",
                   path, entry, e.what());
      done = CacheOutcome::rebuilt;
    }
  }
  engine::Model model = converted();
  try {
    std::error_code ec;
    std::filesystem::create_directories(settings.directory, ec);
    const std::string bytes = encode_model_entry(model, key, size, settings.version);
    write_atomically(entry, [&](std::ostream& out) { out.write(bytes.data(), bytes.size()); });
    spdlog::debug("{}: converted model stored in the cache ({})", path, entry);
  } catch (const std::exception& e) {
    spdlog::warn("{}: could not store the converted model in the cache: {}", path, e.what());
  }
  return finish(std::move(model));
}

}  // namespace nurbsreg::io
