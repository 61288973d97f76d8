// Randomized quasi-Monte Carlo samples: Owen-scrambled Sobol points in 2D, padded to any number
// of dimensions by shuffling the sample index per dimension pair (Burley 2020, "Practical
// Hash-based Owen Scrambling", JCGT 9(4)). Stateless, like make_path_rng: every number is a
// function of (pixel, sample, bounce, dimension, seed), so CPU and GPU draw the same ones.
#pragma once

#include "core/rng.h"

namespace tracer {

// IntegratorSettings::sampler and RenderSettings::sampler.
constexpr uint32_t kSamplerRandom = 0;  // independent PCG32 numbers (core/rng.h)
constexpr uint32_t kSamplerSobol = 1;   // this file

TRACER_HD TRACER_INLINE uint32_t reverse_bits32(uint32_t x) {
#if defined(__CUDA_ARCH__)
  return __brev(x);
#else
#if defined(__GNUC__)
  x = __builtin_bswap32(x);
#else
  x = (x << 16) | (x >> 16);
  x = ((x & 0x00ff00ffu) << 8) | ((x & 0xff00ff00u) >> 8);
#endif
  x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
  x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
  x = ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
  return x;
#endif
}

// The first two Sobol dimensions as 32-bit fractions (bit 31 is the 1/2 digit). Dimension 0 is
// the van der Corput sequence (the identity generator matrix, bits reversed); dimension 1 has
// the Pascal matrix mod 2 as generator, whose column k+1 is column k xor itself shifted by one.
// Together they form a (0,2)-sequence: every aligned block of 2^m points is a (0,m,2)-net.
TRACER_HD TRACER_INLINE uint32_t sobol_dim0(uint32_t index) {
  return reverse_bits32(index);
}

TRACER_HD TRACER_INLINE uint32_t sobol_dim1(uint32_t index) {
  uint32_t v = 0x80000000u, x = 0;
  for (; index; index >>= 1, v ^= v >> 1)
    if (index & 1u) x ^= v;
  return x;
}

// sobol_dim1(index) with its bits reversed, without a loop. Column k of the Pascal matrix mod 2,
// reversed, has bit j set when C(k, j) is odd, that is (Lucas) when the bits of j are a subset
// of those of k. So bit j of the result is the parity of the index bits k that are supersets
// of j: a superset-sum transform over the five bits of the position, one shift-xor per bit.
TRACER_HD TRACER_INLINE uint32_t sobol_dim1_reversed(uint32_t x) {
  x ^= (x >> 1) & 0x55555555u;
  x ^= (x >> 2) & 0x33333333u;
  x ^= (x >> 4) & 0x0f0f0f0fu;
  x ^= (x >> 8) & 0x00ff00ffu;
  x ^= (x >> 16) & 0x0000ffffu;
  return x;
}

// A nested uniform (Owen) scramble of a 32-bit fraction. In bit-reversed order, the hash below
// changes each bit as a function of the seed and of the bits below it only (additions carry
// upwards, and multiplying by an even constant moves bits upwards), so in the original order
// each digit is permuted according to the digits above it: Owen's nested scramble. The
// operations and constants are the Laine-Karras style hash of Burley 2020, sec. 3.
TRACER_HD TRACER_INLINE uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

TRACER_HD TRACER_INLINE uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits32(laine_karras_permutation(reverse_bits32(x), seed));
}

// [0, 1) with 24 bits, as Pcg32::next_float.
TRACER_HD TRACER_INLINE float fraction_to_float(uint32_t x) {
  return float(x >> 8) * 0x1p-24f;
}

// The point of sequence index `index` for one dimension pair, whose scrambles come from `key`;
// `index_reversed` is reverse_bits32(index), shared by every pair of a vertex. Shuffling the
// index by a nested scramble maps the first 2^m indices onto one aligned block of 2^m indices,
// so each pair's first 2^m points still form a (0,m,2)-net, while different pairs visit the
// block in unrelated orders (Burley 2020, sec. 4: padding by shuffling).
//
// Written out, x = scramble(sobol_dim0(shuffle(index))) is
// rev(LK(rev(rev(rev(LK(rev(index))))))); the inner reversals cancel, which leaves three
// reversals per 2D point (two for a 1D draw) instead of six.
TRACER_HD TRACER_INLINE uint32_t shuffled_index(uint32_t index_reversed, uint64_t key) {
  return reverse_bits32(laine_karras_permutation(index_reversed, uint32_t(key)));
}
TRACER_HD TRACER_INLINE uint32_t owen_sobol_x(uint32_t shuffled, uint64_t key) {
  return reverse_bits32(laine_karras_permutation(shuffled, uint32_t(key >> 32)));
}
TRACER_HD TRACER_INLINE uint32_t owen_sobol_y(uint32_t shuffled, uint64_t key) {
  const uint32_t seed = uint32_t(mix64(key ^ 0x5851f42d4c957f2dull));
  return reverse_bits32(laine_karras_permutation(sobol_dim1_reversed(shuffled), seed));
}

// The samples of one path vertex: dimension pair d of sample n at (pixel, bounce) is a point of
// its own randomization of the sequence. Sample n uses sequence index n >> 1, and the parity
// n & 1 picks one of two independent randomizations: the even- and odd-numbered samples are two
// independent, identically distributed estimates, which the half-buffer noise estimates
// (relMSE between halves, bench --error's noise/bias split) assume. A single sequence would
// not give that: its even and odd points interleave to fill each other's gaps.
struct SobolVertex {
  uint32_t index_reversed;
  uint64_t key;

  TRACER_HD SobolVertex(uint32_t pixel, uint32_t sample, uint32_t bounce, uint32_t seed) {
    index_reversed = reverse_bits32(sample >> 1);
    key = mix64((uint64_t(pixel) << 32 | bounce) ^
                mix64((uint64_t(seed) << 1 | (sample & 1u)) + 0x9e3779b97f4a7c15ull));
  }

  TRACER_HD uint64_t pair_key(uint32_t pair) const {
    return mix64(key + (uint64_t(pair) + 1u) * 0xbf58476d1ce4e5b9ull);
  }
  TRACER_HD vec2 get_2d(uint32_t pair) const {
    const uint64_t k = pair_key(pair);
    const uint32_t shuffled = shuffled_index(index_reversed, k);
    return vec2(fraction_to_float(owen_sobol_x(shuffled, k)),
                fraction_to_float(owen_sobol_y(shuffled, k)));
  }
  // A 1D draw is the first coordinate of its own pair (a (0,1)-sequence, stratified alone).
  TRACER_HD float get_1d(uint32_t pair) const {
    const uint64_t k = pair_key(pair);
    return fraction_to_float(owen_sobol_x(shuffled_index(index_reversed, k), k));
  }
};

}  // namespace tracer
