#pragma once
// Internal to io: the byte-level writer and bounds-checked reader of the cache entries
// (model_cache.cpp, features_cache.cpp). Numbers are written as their in-memory bytes (IEEE-754
// bits, this machine's byte order: each entry's header records it), so a decode gives every
// number back bit for bit.

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "nurbsreg/engine/types.hpp"
#include "nurbsreg/io/model_cache.hpp"
#include "printable.hpp"

namespace nurbsreg::io::detail {

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
  // n values without a count (the caller wrote it, or it follows from another).
  template <class T>
  void array(const T* values, std::size_t n) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (n != 0) out_.append(reinterpret_cast<const char*>(values), n * sizeof(T));
  }
  void doubles(const std::vector<double>& v) {
    u64(v.size());
    array(v.data(), v.size());
  }
  void points(const std::vector<engine::Vec3>& v) {
    u64(v.size());
    for (const engine::Vec3& p : v) {
      raw(p.x());
      raw(p.y());
      raw(p.z());
    }
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

// Bounds-checked reads; any overrun or implausible count is corruption (CacheEntryError). A
// count is checked against the bytes left before anything is allocated for it, so a corrupt
// count can never ask for more memory than the entry's own size.
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
    if (n > left() / std::max<std::size_t>(item_bytes, 1))
      throw CacheEntryError("a count runs past the end of the entry (truncated or corrupt)");
    return static_cast<std::size_t>(n);
  }
  // n values into `out` (the caller checked n with count()).
  template <class T>
  void array(T* out, std::size_t n) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (n > left() / sizeof(T)) throw CacheEntryError("the entry ends early (truncated)");
    // An empty vector's data() may be null, and memcpy's pointers must not be, even for 0 bytes.
    if (n != 0) std::memcpy(out, bytes_.data() + at_, n * sizeof(T));
    at_ += n * sizeof(T);
  }
  std::string str() {
    const std::size_t n = count(1);
    std::string s(bytes_.substr(at_, n));
    at_ += n;
    return s;
  }
  std::vector<double> doubles() {
    std::vector<double> v(count(sizeof(double)));
    array(v.data(), v.size());
    return v;
  }
  std::vector<engine::Vec3> points() {
    std::vector<engine::Vec3> v(count(3 * sizeof(double)));
    for (engine::Vec3& p : v) {
      double xyz[3];
      array(xyz, 3);
      p = engine::Vec3(xyz[0], xyz[1], xyz[2]);
    }
    return v;
  }
  std::size_t offset() const { return at_; }
  std::size_t left() const { return bytes_.size() - at_; }
  bool done() const { return at_ == bytes_.size(); }

 private:
  void need(std::size_t n) const {
    if (left() < n) throw CacheEntryError("the entry ends early (truncated)");
  }
  std::string_view bytes_;
  std::size_t at_ = 0;
};

// Every entry starts with its kind's 8-byte magic, the format, this byte-order mark and the
// version that wrote it.
inline constexpr std::uint32_t kByteOrder = 0x01020304;

inline void write_entry_start(Writer& w, const char (&magic)[8], std::uint32_t format,
                              const std::string& version) {
  w.bytes().append(magic, sizeof magic);
  w.raw(format);
  w.raw(kByteOrder);
  w.str(version);
}

// Checks an entry's start (write_entry_start) and returns a reader at what follows; throws
// CacheEntryError naming what is wrong. `kind` names the cache in the message.
inline Reader read_entry_start(std::string_view bytes, const char (&magic)[8], std::uint32_t format,
                               const char* kind, const std::string& version) {
  if (bytes.size() < sizeof magic || std::memcmp(bytes.data(), magic, sizeof magic) != 0) {
    throw CacheEntryError(std::string("not a nurbsreg ") + kind + " entry (bad magic)");
  }
  Reader r(bytes.substr(sizeof magic));
  if (r.raw<std::uint32_t>() != format) throw CacheEntryError("another entry format (stale)");
  if (r.raw<std::uint32_t>() != kByteOrder)
    throw CacheEntryError("written on a machine of another byte order");
  const std::string written_by = r.str();
  if (written_by != version) {
    // A corrupt entry's bytes: shown printable and short (the message is one log line).
    constexpr std::size_t kShown = 80;
    const std::string shown =
        text_detail::printable(std::string_view(written_by).substr(0, kShown)) +
        (written_by.size() > kShown ? "..." : "");
    throw CacheEntryError("written by \"" + shown + "\", this is \"" + version + "\" (stale)");
  }
  return r;
}

inline std::string hex(std::uint64_t x) {
  static const char* digits = "0123456789abcdef";
  std::string s(16, '0');
  for (int k = 15; k >= 0; --k, x >>= 4)
    s[static_cast<std::size_t>(k)] = digits[x & 15];
  return s;
}

inline std::optional<std::string> read_whole_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return std::nullopt;
  return bytes;
}

}  // namespace nurbsreg::io::detail
