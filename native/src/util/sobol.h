// Owen-scrambled Sobol points (low discrepancy with an unbiased, randomised
// estimate), after Burley 2020, "Practical Hash-based Owen Scrambling":
// a path draws its numbers in groups of up to four dimensions; each group is
// a 4D Sobol point whose index is shuffled and whose coordinates are
// scrambled with keys of their own, so groups do not correlate with each
// other while each group stays a well-stratified net.
//
// Randomisation makes every set of points keyed alike an independent replicate:
// photon batch b uses key hash(seed, b), so batches stay independent and the
// spread of their means still measures the error.
#pragma once

#include <array>
#include <cstdint>

#include "util/rng.h"

namespace plm {

namespace sobol_detail {

inline uint32_t reverse_bits(uint32_t x) {
  x = __builtin_bswap32(x);
  x = ((x & 0x0F0F0F0Fu) << 4) | ((x & 0xF0F0F0F0u) >> 4);
  x = ((x & 0x33333333u) << 2) | ((x & 0xCCCCCCCCu) >> 2);
  return ((x & 0x55555555u) << 1) | ((x & 0xAAAAAAAAu) >> 1);
}

// Direction numbers of Sobol dimensions 2-4 (Joe & Kuo 2008: degree s,
// coefficients a, initial m_k); dimension 1 is the van der Corput sequence.
constexpr std::array<uint32_t, 32> directions(uint32_t s, uint32_t a, std::array<uint32_t, 3> m) {
  std::array<uint32_t, 32> v{};
  for (uint32_t k = 0; k < 32; ++k) {
    if (k < s) {
      v[k] = m[k] << (31 - k);
    } else {
      uint32_t x = v[k - s] ^ (v[k - s] >> s);
      for (uint32_t j = 1; j < s; ++j)
        if ((a >> (s - 1 - j)) & 1u) x ^= v[k - j];
      v[k] = x;
    }
  }
  return v;
}

constexpr std::array<std::array<uint32_t, 32>, 3> kDirections = {
    directions(1, 0, {1, 0, 0}), directions(2, 1, {1, 3, 0}), directions(3, 1, {1, 3, 1})};

constexpr uint32_t reverse_constexpr(uint32_t x) {
  uint32_t r = 0;
  for (int bit = 0; bit < 32; ++bit) r |= ((x >> bit) & 1u) << (31 - bit);
  return r;
}

// The XOR of the direction numbers selected by each byte value at each byte
// position of the index: a coordinate is then four lookups, not a loop over
// the (shuffled, so ~32-bit) index's bits. 12 KiB for dimensions 2-4.
// reversed: the same coordinates bit-reversed, looked up by the bytes of the
// bit-reversed index (bit 8 byte + bit of it is bit 31 - (8 byte + bit) of the
// index): reverse_bits(sobol(reverse_bits(r), dim)). The scramble works on
// reversed bits, so a point needs no reversal between the index shuffle and
// the coordinates' scrambles.
constexpr std::array<std::array<uint32_t, 1024>, 3> byte_tables(bool reversed) {
  std::array<std::array<uint32_t, 1024>, 3> t{};
  for (int d = 0; d < 3; ++d)
    for (int byte = 0; byte < 4; ++byte)
      for (uint32_t value = 0; value < 256; ++value) {
        uint32_t x = 0;
        for (int bit = 0; bit < 8; ++bit)
          if ((value >> bit) & 1u)
            x ^= reversed ? reverse_constexpr(kDirections[d][31 - (8 * byte + bit)]) : kDirections[d][8 * byte + bit];
        t[d][256 * byte + value] = x;
      }
  return t;
}
inline constexpr std::array<std::array<uint32_t, 1024>, 3> kByteTables = byte_tables(false);
inline constexpr std::array<std::array<uint32_t, 1024>, 3> kReversedByteTables = byte_tables(true);

// Sobol coordinate `dim` (0-3) of point `index`, as a 32-bit fraction: the
// XOR of the direction numbers of the index's set bits.
inline uint32_t sobol(uint32_t index, int dim) {
  if (dim == 0) return reverse_bits(index);
  const uint32_t* t = kByteTables[dim - 1].data();
  return t[index & 255u] ^ t[256 + ((index >> 8) & 255u)] ^ t[512 + ((index >> 16) & 255u)] ^ t[768 + (index >> 24)];
}

// Nested uniform scrambling (an Owen scramble) of a 32-bit fraction: each bit
// is flipped by a hash of the bits above it (Vegdahl's Laine-Karras-style hash
// on the reversed bits).
// On reversed bits, the hash flips each bit by the bits below it.
inline uint32_t scramble_reversed(uint32_t x, uint32_t key) {
  x ^= x * 0x3d20adeau;
  x += key;
  x *= (key >> 16) | 1u;
  x ^= x * 0x05526c56u;
  x ^= x * 0x53a22864u;
  return x;
}

inline uint32_t owen_scramble(uint32_t x, uint32_t key) { return reverse_bits(scramble_reversed(reverse_bits(x), key)); }

// reverse_bits(sobol(reverse_bits(r), dim)), dim 1-3.
inline uint32_t sobol_reversed(uint32_t r, int dim) {
  const uint32_t* t = kReversedByteTables[dim - 1].data();
  return t[r & 255u] ^ t[256 + ((r >> 8) & 255u)] ^ t[512 + ((r >> 16) & 255u)] ^ t[768 + (r >> 24)];
}

inline uint32_t hash(uint32_t a, uint32_t b) { return uint32_t(splitmix64((uint64_t(a) << 32) | b)); }

inline float to_float(uint32_t x) { return float(x >> 8) * (1.0f / 16777216.0f); }

}  // namespace sobol_detail

// One group of up to four dimensions of the Sobol set keyed by `key`: its
// scrambling keys, hashed once so that drawing many points of a group is cheap.
// Within one key, points 0 .. 2^m - 1 of a group form a scrambled
// (t, m, 4)-net; the index shuffle keeps that (an Owen scramble of the index
// maps each aligned block of 2^m indices onto one).
class SobolGroup {
 public:
  SobolGroup(uint32_t key, uint32_t group) {
    using sobol_detail::hash;
    index_key_ = hash(key, group);
    for (uint32_t d = 0; d < 4; ++d) dim_key_[d] = hash(index_key_, d + 1);
  }
  // Coordinate d is owen_scramble(sobol(i, d), dim key) of the shuffled index
  // i = owen_scramble(index, index key), computed on reversed bits: with
  // r = reverse_bits(i), reverse_bits(sobol(i, 0)) = i and
  // reverse_bits(sobol(i, d)) = sobol_reversed(r, d).
  void point(uint32_t index, int dims, float* out) const {
    using namespace sobol_detail;
    const uint32_t r = scramble_reversed(reverse_bits(index), index_key_);
    out[0] = to_float(reverse_bits(scramble_reversed(reverse_bits(r), dim_key_[0])));
    for (int d = 1; d < dims; ++d) out[d] = to_float(reverse_bits(scramble_reversed(sobol_reversed(r, d), dim_key_[d])));
  }

 private:
  uint32_t index_key_, dim_key_[4];
};

// Point `index` of group `group` of the set keyed by `key` (dims <= 4).
inline void sobol_group(uint32_t index, uint32_t key, uint32_t group, int dims, float* out) {
  SobolGroup(key, group).point(index, dims, out);
}

}  // namespace plm
