// PCG32 random numbers (O'Neill 2014, pcg-random.org, "minimal C" variant). Each (pixel, sample,
// bounce) triple seeds its own stream so CPU and GPU draw the same numbers for the same path
// vertex, whatever order or thread computes it.
#pragma once

#include "core/hd.h"

namespace tracer {

// Murmur3's 64-bit finaliser: decorrelates neighbouring seeds.
TRACER_HD TRACER_INLINE uint64_t mix64(uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdull;
  k ^= k >> 33;
  k *= 0xc4ceb9fe1a85ec53ull;
  k ^= k >> 33;
  return k;
}

struct Pcg32 {
  uint64_t state = 0;
  uint64_t inc = 1;

  TRACER_HD Pcg32() {}
  TRACER_HD Pcg32(uint64_t seed, uint64_t stream) { seed_with(seed, stream); }

  TRACER_HD void seed_with(uint64_t seed, uint64_t stream) {
    state = 0;
    inc = (stream << 1u) | 1u;
    next_u32();
    state += seed;
    next_u32();
  }

  TRACER_HD uint32_t next_u32() {
    const uint64_t old = state;
    state = old * 6364136223846793005ull + inc;
    const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = uint32_t(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31u));
  }

  // Uniform in [0, 1): 24 random mantissa bits, so 1.0 is never returned.
  TRACER_HD float next_float() { return float(next_u32() >> 8) * 0x1p-24f; }
  TRACER_HD vec2 next_2d() {
    const float a = next_float();
    return vec2(a, next_float());
  }
};

// The stream for one path vertex. `seed` is the user's --seed.
TRACER_HD TRACER_INLINE Pcg32 make_path_rng(uint32_t pixel, uint32_t sample, uint32_t bounce,
                                            uint32_t seed) {
  const uint64_t key = mix64((uint64_t(pixel) << 32) | uint64_t(sample)) ^ mix64(~uint64_t(seed));
  return Pcg32(key, mix64(uint64_t(bounce) * 0x9e3779b97f4a7c15ull + seed));
}

}  // namespace tracer
