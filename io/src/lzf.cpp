#include "lzf.hpp"

#include <algorithm>
#include <cstring>
#include <vector>

namespace nurbsreg::io::detail {
namespace {

constexpr std::size_t kMaxLiteralRun = 32;  // control bytes 0 .. 31
constexpr std::size_t kMaxDistance = 8192;  // 13 bits of distance - 1
constexpr std::size_t kMinMatch = 3;        // shorter back references save nothing
constexpr std::size_t kMaxMatch = 7 + 255 + 2;
constexpr int kHashBits = 16;

std::uint32_t three_bytes(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) << 16 | static_cast<std::uint32_t>(p[1]) << 8 | p[2];
}

std::size_t slot_of(std::uint32_t v) {
  // Multiplicative hashing: the top bits of the product mix all three bytes.
  return (v * 2654435761u) >> (32 - kHashBits);
}

// The compressed stream, refusing to grow past its capacity.
class Output {
 public:
  Output(std::uint8_t* out, std::size_t capacity) : op_(out), begin_(out), end_(out + capacity) {}
  bool literals(const std::uint8_t* p, std::size_t n) {
    while (n > 0) {
      const std::size_t run = std::min(n, kMaxLiteralRun);
      if (static_cast<std::size_t>(end_ - op_) < run + 1) return false;
      *op_++ = static_cast<std::uint8_t>(run - 1);
      std::memcpy(op_, p, run);
      op_ += run;
      p += run;
      n -= run;
    }
    return true;
  }
  bool reference(std::size_t distance, std::size_t length) {
    const std::size_t code = length - 2;
    const std::size_t back = distance - 1;
    if (static_cast<std::size_t>(end_ - op_) < 3) return false;
    const auto high = static_cast<std::uint8_t>(back >> 8);
    if (code < 7) {
      *op_++ = static_cast<std::uint8_t>(code << 5 | high);
    } else {
      *op_++ = static_cast<std::uint8_t>(7u << 5 | high);
      *op_++ = static_cast<std::uint8_t>(code - 7);
    }
    *op_++ = static_cast<std::uint8_t>(back & 0xff);
    return true;
  }
  std::size_t size() const { return static_cast<std::size_t>(op_ - begin_); }

 private:
  std::uint8_t* op_;
  std::uint8_t* const begin_;
  std::uint8_t* const end_;
};

}  // namespace

std::size_t lzf_compress(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out,
                         std::size_t out_capacity) {
  // Positions are kept in 32 bits (PCD's sizes are 32-bit too).
  if (in_size >= std::size_t{0xffffffff}) return 0;
  Output output(out, out_capacity);
  // Where each hashed 3-byte sequence was last seen, plus one (0: never).
  std::vector<std::uint32_t> last_seen(std::size_t{1} << kHashBits, 0);
  std::size_t literal_start = 0;
  std::size_t ip = 0;
  while (ip + kMinMatch <= in_size) {
    const std::uint32_t key = three_bytes(in + ip);
    std::uint32_t& slot = last_seen[slot_of(key)];
    const std::size_t seen = slot;
    slot = static_cast<std::uint32_t>(ip + 1);
    if (seen != 0 && ip - (seen - 1) <= kMaxDistance && three_bytes(in + seen - 1) == key) {
      const std::size_t ref = seen - 1;
      const std::size_t longest = std::min(kMaxMatch, in_size - ip);
      std::size_t length = kMinMatch;
      while (length < longest && in[ref + length] == in[ip + length])
        ++length;
      if (!output.literals(in + literal_start, ip - literal_start)) return 0;
      if (!output.reference(ip - ref, length)) return 0;
      // The sequences inside the match are not hashed: cheaper, at a small cost in ratio.
      ip += length;
      literal_start = ip;
      continue;
    }
    ++ip;
  }
  if (!output.literals(in + literal_start, in_size - literal_start)) return 0;
  return output.size();
}

bool lzf_decompress(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out,
                    std::size_t out_size) {
  const std::uint8_t* ip = in;
  const std::uint8_t* const in_end = in + in_size;
  std::uint8_t* op = out;
  std::uint8_t* const out_end = out + out_size;
  while (ip < in_end) {
    const unsigned ctrl = *ip++;
    if (ctrl < 32) {
      const std::size_t run = ctrl + 1;
      if (static_cast<std::size_t>(in_end - ip) < run) return false;
      if (static_cast<std::size_t>(out_end - op) < run) return false;
      std::memcpy(op, ip, run);
      ip += run;
      op += run;
      continue;
    }
    std::size_t length = ctrl >> 5;
    if (length == 7) {
      if (ip == in_end) return false;
      length += *ip++;
    }
    if (ip == in_end) return false;
    const std::size_t distance = ((ctrl & 31u) << 8) + *ip++ + 1;
    length += 2;
    if (distance > static_cast<std::size_t>(op - out)) return false;
    if (static_cast<std::size_t>(out_end - op) < length) return false;
    const std::uint8_t* ref = op - distance;
    for (std::size_t k = 0; k < length; ++k)  // byte by byte: the ranges may overlap
      *op++ = *ref++;
  }
  return op == out_end;
}

}  // namespace nurbsreg::io::detail
