// The converted-model cache: entry encoding, checks and the read-through load (model_cache.hpp).

#include "nurbsreg/io/model_cache.hpp"

#include <spdlog/spdlog.h>

#include <bit>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>

#include "nurbsreg/io/atomic_file.hpp"

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
constexpr std::uint32_t kByteOrder = 0x01020304;

constexpr std::uint64_t kP1 = 0x9e3779b97f4a7c15ull, kP2 = 0xc2b2ae3d27d4eb4full;

std::uint64_t splitmix(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// --- writing ------------------------------------------------------------------------------

class Writer {
 public:
  template <class T>
  void raw(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const char*>(&value);
    out_.append(p, sizeof(T));
  }
  void u64(std::uint64_t v) { raw(v); }
  void i32(std::int32_t v) { raw(v); }
  void str(const std::string& s) {
    u64(s.size());
    out_.append(s);
  }
  void doubles(const std::vector<double>& v) {
    u64(v.size());
    out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
  }
  void points(const std::vector<engine::Vec3>& v) {
    u64(v.size());
    for (const engine::Vec3& p : v) {
      raw(p.x());
      raw(p.y());
      raw(p.z());
    }
  }
  void curve(const engine::NurbsCurve& c) {
    str(c.name);
    i32(c.degree);
    i32(c.dimension);
    doubles(c.knots);
    points(c.control_points);
    doubles(c.weights);
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

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
        w.curve(c.uv);
        w.i32(c.edge ? 1 : 0);
        if (c.edge) w.curve(*c.edge);
      }
    }
  }
  w.u64(m.curves.size());
  for (const engine::NurbsCurve& c : m.curves)
    w.curve(c);
  w.u64(m.skipped_faces.size());
  for (const engine::SkippedFace& f : m.skipped_faces) {
    w.i32(f.face);
    w.str(f.reason);
  }
  return std::move(w.bytes());
}

// --- reading ------------------------------------------------------------------------------

// Bounds-checked reads; any overrun or implausible count is corruption.
class Reader {
 public:
  explicit Reader(std::string_view bytes) : bytes_(bytes) {}

  template <class T>
  T raw() {
    need(sizeof(T));
    T value;
    std::memcpy(&value, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  std::uint64_t u64() { return raw<std::uint64_t>(); }
  std::int32_t i32() { return raw<std::int32_t>(); }
  // A count of items of at least `item_bytes` each that must fit in what is left.
  std::size_t count(std::size_t item_bytes) {
    const std::uint64_t n = u64();
    if (n > (bytes_.size() - at_) / std::max<std::size_t>(item_bytes, 1))
      throw CacheEntryError("a count runs past the end of the entry (truncated or corrupt)");
    return static_cast<std::size_t>(n);
  }
  std::string str() {
    const std::size_t n = count(1);
    std::string s(bytes_.substr(at_, n));
    at_ += n;
    return s;
  }
  std::vector<double> doubles() {
    const std::size_t n = count(sizeof(double));
    std::vector<double> v(n);
    // An empty vector's data() may be null, and memcpy's pointers must not be, even for 0 bytes.
    if (n != 0) std::memcpy(v.data(), bytes_.data() + at_, n * sizeof(double));
    at_ += n * sizeof(double);
    return v;
  }
  std::vector<engine::Vec3> points() {
    const std::size_t n = count(3 * sizeof(double));
    std::vector<engine::Vec3> v(n);
    for (engine::Vec3& p : v) {
      double xyz[3];
      std::memcpy(xyz, bytes_.data() + at_, sizeof xyz);
      at_ += sizeof xyz;
      p = engine::Vec3(xyz[0], xyz[1], xyz[2]);
    }
    return v;
  }
  engine::NurbsCurve curve() {
    engine::NurbsCurve c;
    c.name = str();
    c.degree = i32();
    c.dimension = i32();
    c.knots = doubles();
    c.control_points = points();
    c.weights = doubles();
    return c;
  }
  bool done() const { return at_ == bytes_.size(); }

 private:
  void need(std::size_t n) const {
    if (bytes_.size() - at_ < n) throw CacheEntryError("the entry ends early (truncated)");
  }
  std::string_view bytes_;
  std::size_t at_ = 0;
};

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
        c.uv = r.curve();
        if (r.i32() != 0) c.edge = r.curve();
      }
    }
  }
  m.curves.resize(r.count(40));
  for (engine::NurbsCurve& c : m.curves)
    c = r.curve();
  m.skipped_faces.resize(r.count(12));
  for (engine::SkippedFace& f : m.skipped_faces) {
    f.face = r.i32();
    f.reason = r.str();
  }
  if (!r.done()) throw CacheEntryError("bytes after the model (corrupt)");
  return m;
}

std::string hex(std::uint64_t x) {
  static const char* digits = "0123456789abcdef";
  std::string s(16, '0');
  for (int k = 15; k >= 0; --k, x >>= 4)
    s[static_cast<std::size_t>(k)] = digits[x & 15];
  return s;
}

std::optional<std::string> read_whole_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return std::nullopt;
  return bytes;
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

std::string encode_model_entry(const engine::Model& model, const ContentHash& source,
                               std::uint64_t source_size, const std::string& version) {
  const std::string payload = encode_payload(model);
  const ContentHash check = hash_bytes(payload);
  Writer w;
  w.bytes().append(kMagic, sizeof kMagic);
  w.raw(kFormat);
  w.raw(kByteOrder);
  w.str(version);
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
  if (bytes.size() < sizeof kMagic || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    throw CacheEntryError("not a nurbsreg model cache entry (bad magic)");
  Reader r(bytes.substr(sizeof kMagic));
  if (r.raw<std::uint32_t>() != kFormat) throw CacheEntryError("another entry format (stale)");
  if (r.raw<std::uint32_t>() != kByteOrder)
    throw CacheEntryError("written on a machine of another byte order");
  const std::string written_by = r.str();
  if (written_by != version)
    throw CacheEntryError("written by \"" + written_by + "\", this is \"" + version + "\" (stale)");
  if (r.u64() != source_size || r.u64() != source.lo || r.u64() != source.hi)
    throw CacheEntryError("made from another source file (stale)");
  const std::uint64_t size = r.u64();
  const std::uint64_t check = r.u64();
  const std::size_t header = sizeof kMagic + 4 + 4 + 8 + written_by.size() + 8 * 5;
  if (bytes.size() != header + size)
    throw CacheEntryError("its size does not match its header (truncated or corrupt)");
  const std::string_view payload = bytes.substr(header);
  if (hash_bytes(payload).lo != check) throw CacheEntryError("checksum mismatch (corrupt)");
  engine::Model model = decode_payload(payload);
  if (auto error = model.validate()) throw CacheEntryError("invalid model (" + *error + ")");
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
  engine::Model model = convert(path);
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
