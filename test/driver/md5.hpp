// MD5 (RFC 1321), incremental, for comparing decoded arrays with reference digests. Written from
// the RFC's description: 64-byte blocks, four rounds of 16 steps, the sine-derived constants.
// Not for security.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>

namespace lidartag::testing {

class Md5 {
 public:
  Md5() {
    for (size_t i = 0; i < 64; ++i)
      k_[i] = static_cast<uint32_t>(std::floor(std::abs(std::sin(double(i + 1))) * 4294967296.0));
  }

  void update(const void* data, size_t n) {
    const auto* p = static_cast<const uint8_t*>(data);
    length_ += n;
    while (n > 0) {
      const size_t take = std::min(n, size_t{64} - fill_);
      std::memcpy(block_.data() + fill_, p, take);
      fill_ += take;
      p += take;
      n -= take;
      if (fill_ == 64) {
        compress();
        fill_ = 0;
      }
    }
  }
  template <class T>
  void update_value(T v) {  // little-endian hosts only (as the project's targets)
    update(&v, sizeof v);
  }

  // The digest as 32 lowercase hex digits; the object is spent.
  std::string hex() {
    const uint64_t bits = length_ * 8;
    const uint8_t one = 0x80;
    update(&one, 1);
    const uint8_t zero = 0;
    while (fill_ != 56) update(&zero, 1);
    std::array<uint8_t, 8> len{};
    for (size_t i = 0; i < 8; ++i) len[i] = static_cast<uint8_t>(bits >> (8 * i));
    update(len.data(), 8);
    static const char* digits = "0123456789abcdef";
    std::string out;
    for (uint32_t word : state_)
      for (int i = 0; i < 4; ++i) {
        const auto byte = static_cast<uint8_t>(word >> (8 * i));
        out += digits[byte >> 4];
        out += digits[byte & 15];
      }
    return out;
  }

 private:
  static uint32_t rotl(uint32_t x, unsigned s) { return (x << s) | (x >> (32 - s)); }

  void compress() {
    static constexpr std::array<unsigned, 16> kShift = {7, 12, 17, 22, 5, 9,  14, 20,
                                                        4, 11, 16, 23, 6, 10, 15, 21};
    std::array<uint32_t, 16> m{};
    for (size_t i = 0; i < 16; ++i) {
      m[i] = static_cast<uint32_t>(block_[4 * i]) | static_cast<uint32_t>(block_[4 * i + 1]) << 8 |
             static_cast<uint32_t>(block_[4 * i + 2]) << 16 |
             static_cast<uint32_t>(block_[4 * i + 3]) << 24;
    }
    uint32_t a = state_[0], b = state_[1], c = state_[2], d = state_[3];
    for (size_t i = 0; i < 64; ++i) {
      uint32_t f = 0;
      size_t g = 0;
      const size_t round = i / 16;
      if (round == 0) {
        f = (b & c) | (~b & d);
        g = i;
      } else if (round == 1) {
        f = (d & b) | (~d & c);
        g = (5 * i + 1) % 16;
      } else if (round == 2) {
        f = b ^ c ^ d;
        g = (3 * i + 5) % 16;
      } else {
        f = c ^ (b | ~d);
        g = (7 * i) % 16;
      }
      const uint32_t next = b + rotl(a + f + k_[i] + m[g], kShift[round * 4 + i % 4]);
      a = d;
      d = c;
      c = b;
      b = next;
    }
    state_[0] += a;
    state_[1] += b;
    state_[2] += c;
    state_[3] += d;
  }

  std::array<uint32_t, 4> state_ = {0x67452301u, 0xefcdab89u, 0x98badcfeu, 0x10325476u};
  std::array<uint32_t, 64> k_{};
  std::array<uint8_t, 64> block_{};
  size_t fill_ = 0;
  uint64_t length_ = 0;
};

}  // namespace lidartag::testing
