// CRC-32 (IEEE 802.3, the reflected polynomial 0xEDB88320, as zlib and MCAP compute it).
//
// MCAP checks every chunk's uncompressed records against a CRC-32: at zlib's table speed (about
// 4 GB/s here) that pass alone cost about as much as reading the same packets from a pcap. On
// x86-64 with PCLMULQDQ the bulk of a buffer is folded with carry-less multiplies instead (Gopal et
// al., "Fast CRC Computation for Generic Polynomials Using PCLMULQDQ Instruction", Intel, 2009):
// four 128-bit lanes folded 64 bytes at a time (four 256-bit lanes, 128 bytes at a time, where the
// CPU has VPCLMULQDQ), then into one lane, then reduced to 32 bits by Barrett reduction. The
// folding constants are x^n mod P(x) for the n the paper gives (computed below, in the
// bit-reflected form of its reflected variant). The bytes left over (fewer than 16 at the end, or a
// buffer under 64 bytes) go through zlib, which continues the same CRC.
#include <zlib.h>

#include "internal.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define LIDARTAG_CRC32_CLMUL 1
#endif

namespace lidartag::driver::bag::detail {

namespace {

uint32_t crc32_zlib(std::span<const uint8_t> bytes, uint32_t crc) {
  // crc32_z takes a size_t length: no 4 GiB limit.
  return static_cast<uint32_t>(::crc32_z(crc, bytes.data(), bytes.size()));
}

#ifdef LIDARTAG_CRC32_CLMUL
// x^n mod P(x) (P = 0x104C11DB7), its 32 bits reflected and shifted left by one: the form in
// which the reflected folding multiplies. The constants below are its values.
constexpr int64_t x_pow_mod_p(int n) {
  uint64_t r = 1;
  for (int i = 0; i < n; ++i) {
    r <<= 1;
    if ((r >> 32) & 1) r ^= 0x104C11DB7;
  }
  uint64_t reflected = 0;
  for (int i = 0; i < 32; ++i)
    if ((r >> i) & 1) reflected |= uint64_t{1} << (31 - i);
  return static_cast<int64_t>(reflected << 1);
}
// x^(4*128+32) and x^(4*128-32) mod P: folding a lane 512 bits on (four 128-bit lanes).
constexpr int64_t kK1 = x_pow_mod_p(4 * 128 + 32), kK2 = x_pow_mod_p(4 * 128 - 32);
// x^(128+32) and x^(128-32) mod P: folding a lane 128 bits on.
constexpr int64_t kK3 = x_pow_mod_p(128 + 32), kK4 = x_pow_mod_p(128 - 32);
// x^64 mod P: 64 bits to 32 bits with 32 zero bits appended.
constexpr int64_t kK5 = x_pow_mod_p(64);
// x^(8*128+32) and x^(8*128-32) mod P: folding a lane 1024 bits on (four 256-bit lanes).
constexpr int64_t kK1x8 = x_pow_mod_p(8 * 128 + 32), kK2x8 = x_pow_mod_p(8 * 128 - 32);
// The paper's published values (its reflected variant's k1 .. k5).
static_assert(kK1 == 0x154442bd4 && kK2 == 0x1c6e41596 && kK3 == 0x1751997d0 &&
              kK4 == 0x0ccaa009e && kK5 == 0x163cd6124);
// P(x) itself and floor(x^64 / P(x)) (Barrett's mu), both reflected.
constexpr int64_t kPoly = 0x1db710641, kMu = 0x1f7011641;

// One lane `x` folded over 128 * k bits onto `next`: x.low * K.low ^ x.high * K.high ^ next.
__attribute__((target("pclmul,sse4.1"))) inline __m128i fold(__m128i x, __m128i k, __m128i next) {
  const __m128i low = _mm_clmulepi64_si128(x, k, 0x00);
  const __m128i high = _mm_clmulepi64_si128(x, k, 0x11);
  return _mm_xor_si128(_mm_xor_si128(low, high), next);
}

__attribute__((target("pclmul,sse4.1"))) inline __m128i load(const uint8_t* p) {
  return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
}

// Folds the 16-byte blocks left after `x` (n a multiple of 16) and reduces to the CRC state.
__attribute__((target("pclmul,sse4.1"))) uint32_t finish(__m128i x, const uint8_t* p, size_t n) {
  const __m128i k34 = _mm_set_epi64x(kK4, kK3);
  for (; n >= 16; n -= 16, p += 16) x = fold(x, k34, load(p));
  // 128 bits to 64 (with 32 zero bits appended): x.low * K4 ^ x.high.
  x = _mm_xor_si128(_mm_srli_si128(x, 8), _mm_clmulepi64_si128(x, k34, 0x10));
  // 64 bits to 32 bits and a remainder: the low 32 bits times K5, added to the rest.
  const __m128i mask32 = _mm_set_epi32(0, 0, 0, -1);
  const __m128i k5 = _mm_set_epi64x(0, kK5);
  x = _mm_xor_si128(_mm_srli_si128(x, 4), _mm_clmulepi64_si128(_mm_and_si128(x, mask32), k5, 0x00));
  // Barrett reduction: q = (low 32 bits * mu) mod x^32, remainder = x ^ q * P.
  const __m128i poly_mu = _mm_set_epi64x(kMu, kPoly);
  __m128i q = _mm_clmulepi64_si128(_mm_and_si128(x, mask32), poly_mu, 0x10);
  q = _mm_clmulepi64_si128(_mm_and_si128(q, mask32), poly_mu, 0x00);
  return static_cast<uint32_t>(_mm_extract_epi32(_mm_xor_si128(x, q), 1));
}

// The CRC state (not inverted) continued over `n` bytes: n >= 64 and a multiple of 16. Four
// 128-bit lanes, 64 bytes a step.
__attribute__((target("pclmul,sse4.1"))) uint32_t fold_blocks(uint32_t state, const uint8_t* p,
                                                              size_t n) {
  __m128i x0 = _mm_xor_si128(load(p), _mm_cvtsi32_si128(static_cast<int>(state)));
  __m128i x1 = load(p + 16), x2 = load(p + 32), x3 = load(p + 48);
  p += 64;
  n -= 64;
  const __m128i k12 = _mm_set_epi64x(kK2, kK1);
  while (n >= 64) {
    x0 = fold(x0, k12, load(p));
    x1 = fold(x1, k12, load(p + 16));
    x2 = fold(x2, k12, load(p + 32));
    x3 = fold(x3, k12, load(p + 48));
    p += 64;
    n -= 64;
  }
  const __m128i k34 = _mm_set_epi64x(kK4, kK3);
  return finish(fold(fold(fold(x0, k34, x1), k34, x2), k34, x3), p, n);
}

__attribute__((target("avx2,vpclmulqdq,pclmul,sse4.1"))) inline __m256i fold(__m256i x, __m256i k,
                                                                             __m256i next) {
  const __m256i low = _mm256_clmulepi64_epi128(x, k, 0x00);
  const __m256i high = _mm256_clmulepi64_epi128(x, k, 0x11);
  return _mm256_xor_si256(_mm256_xor_si256(low, high), next);
}

__attribute__((target("avx2,vpclmulqdq,pclmul,sse4.1"))) inline __m256i load256(const uint8_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// As fold_blocks, for n >= 256, where the CPU has VPCLMULQDQ: four 256-bit lanes (eight 128-bit
// ones), 128 bytes a step; the eight are then folded into one, in the order of the bytes.
__attribute__((target("avx2,vpclmulqdq,pclmul,sse4.1"))) uint32_t fold_blocks_wide(uint32_t state,
                                                                                   const uint8_t* p,
                                                                                   size_t n) {
  __m256i y0 =
      _mm256_xor_si256(load256(p), _mm256_set_epi32(0, 0, 0, 0, 0, 0, 0, static_cast<int>(state)));
  __m256i y1 = load256(p + 32), y2 = load256(p + 64), y3 = load256(p + 96);
  p += 128;
  n -= 128;
  const __m256i k = _mm256_set_epi64x(kK2x8, kK1x8, kK2x8, kK1x8);
  while (n >= 128) {
    y0 = fold(y0, k, load256(p));
    y1 = fold(y1, k, load256(p + 32));
    y2 = fold(y2, k, load256(p + 64));
    y3 = fold(y3, k, load256(p + 96));
    p += 128;
    n -= 128;
  }
  const __m128i k34 = _mm_set_epi64x(kK4, kK3);
  __m128i x = _mm256_castsi256_si128(y0);
  x = fold(x, k34, _mm256_extracti128_si256(y0, 1));
  for (const __m256i y : {y1, y2, y3}) {
    x = fold(x, k34, _mm256_castsi256_si128(y));
    x = fold(x, k34, _mm256_extracti128_si256(y, 1));
  }
  return finish(x, p, n);
}

bool have_clmul() {
  static const bool have = [] {
    __builtin_cpu_init();  // idempotent; needed if the first CRC ran before constructors
    return __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
  }();
  return have;
}

bool have_vpclmul() {
  static const bool have =
      have_clmul() && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("vpclmulqdq");
  return have;
}
#endif

}  // namespace

uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc) {
#ifdef LIDARTAG_CRC32_CLMUL
  return crc32_by(have_vpclmul() ? Crc32Method::kFolded256
                  : have_clmul() ? Crc32Method::kFolded128
                                 : Crc32Method::kZlib,
                  bytes, crc);
#else
  return crc32_zlib(bytes, crc);
#endif
}

bool crc32_available(Crc32Method method) {
  switch (method) {
    case Crc32Method::kZlib:
      return true;
#ifdef LIDARTAG_CRC32_CLMUL
    case Crc32Method::kFolded128:
      return have_clmul();
    case Crc32Method::kFolded256:
      return have_vpclmul();
#else
    default:
      break;
#endif
  }
  return false;
}

uint32_t crc32_by(Crc32Method method, std::span<const uint8_t> bytes, uint32_t crc) {
#ifdef LIDARTAG_CRC32_CLMUL
  if (bytes.size() >= 64 && method != Crc32Method::kZlib && crc32_available(method)) {
    const size_t bulk = bytes.size() & ~size_t{15};
    crc = method == Crc32Method::kFolded256 && bulk >= 256
              ? ~fold_blocks_wide(~crc, bytes.data(), bulk)
              : ~fold_blocks(~crc, bytes.data(), bulk);
    bytes = bytes.subspan(bulk);
  }
#endif
  return crc32_zlib(bytes, crc);
}

}  // namespace lidartag::driver::bag::detail
