// Counter-based random numbers: a photon's stream is a pure function of
// (seed, photon index), so results never depend on how work is split.
#pragma once

#include <cstdint>

namespace plm {

inline uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Van der Corput radical inverse in base 2 of i, in [0, 1): every prefix of
// the sequence is stratified, whatever its length.
inline double radical_inverse2(uint64_t i) {
  i = __builtin_bswap64(i);  // the byte order reversed; then the bits of each byte
  i = ((i & 0x0F0F0F0F0F0F0F0Full) << 4) | ((i & 0xF0F0F0F0F0F0F0F0ull) >> 4);
  i = ((i & 0x3333333333333333ull) << 2) | ((i & 0xCCCCCCCCCCCCCCCCull) >> 2);
  i = ((i & 0x5555555555555555ull) << 1) | ((i & 0xAAAAAAAAAAAAAAAAull) >> 1);
  return double(i >> 11) * (1.0 / 9007199254740992.0);
}

// A pseudo-random permutation of [0, n) keyed by key (Kensler 2013: a hash
// that is a bijection on the next power of two, cycle-walked into range).
inline uint32_t permute(uint32_t i, uint32_t n, uint32_t key) {
  if (n <= 1) return 0;
  uint32_t w = n - 1;
  w |= w >> 1;
  w |= w >> 2;
  w |= w >> 4;
  w |= w >> 8;
  w |= w >> 16;
  do {
    i ^= key;
    i *= 0xe170893du;
    i ^= key >> 16;
    i ^= (i & w) >> 4;
    i ^= key >> 8;
    i *= 0x0929eb3fu;
    i ^= key >> 23;
    i ^= (i & w) >> 1;
    i *= 1 | key >> 27;
    i *= 0x6935fa69u;
    i ^= (i & w) >> 11;
    i *= 0x74dcb303u;
    i ^= (i & w) >> 2;
    i *= 0x9e501cc3u;
    i ^= (i & w) >> 2;
    i *= 0xc860a3dfu;
    i &= w;
    i ^= i >> 5;
  } while (i >= n);
  return (i + key) % n;
}

// PCG32 (O'Neill): small state, good statistics, fast.
class Rng {
 public:
  Rng(uint64_t seed, uint64_t stream) : Rng(SeedHash{splitmix64(seed)}, stream) {}
  // The same generator, splitmix64(seed) hashed once by the caller (one
  // stream per photon: the seed's hash is the same for all of them).
  struct SeedHash {
    uint64_t value;
  };
  Rng(SeedHash seed, uint64_t stream) {
    state_ = 0;
    inc_ = (splitmix64(stream ^ 0xDA3E39CB94B95BDBull) << 1u) | 1u;
    next_u32();
    state_ += seed.value;
    next_u32();
  }
  uint32_t next_u32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ull + inc_;
    const uint32_t xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
  }
  // Uniform in [0, 1).
  float next_float() { return static_cast<float>(next_u32() >> 8) * (1.0f / 16777216.0f); }

 private:
  uint64_t state_, inc_;
};

}  // namespace plm
