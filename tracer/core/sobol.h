// Randomized quasi-Monte Carlo samples: Owen-scrambled Sobol points in 2D, padded to any number
// of dimensions by shuffling the sample index per dimension pair (Burley 2020, "Practical
// Hash-based Owen Scrambling", JCGT 9(4)). Stateless, like make_path_rng: every number is a
// function of (pixel, sample, bounce, dimension, seed), so CPU and GPU draw the same ones.
#pragma once

#include "core/rng.h"

namespace tracer {

// IntegratorSettings::sampler and RenderSettings::sampler.
constexpr uint32_t kSamplerRandom = 0;  // independent PCG32 numbers (core/rng.h)
constexpr uint32_t kSamplerSobol = 1;   // this file: one sequence per pixel and dimension pair
constexpr uint32_t kSamplerSobolPairs = 2;  // this file: two independent sequences (even, odd)

// Whether the even- and odd-numbered samples are independent estimates, so that half-buffer
// statistics (noise, the noise/bias split, a variance image) are exact. The single Sobol
// sequence's halves are anti-correlated and overstate the noise (SobolVertex below).
constexpr bool independent_halves(uint32_t sampler) { return sampler != kSamplerSobol; }

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

// A 32-bit integer hash with low avalanche bias: Wellons' lowbias32 with the constants his
// hash-prospector found later (bias 0.107; nullprogram.com/blog/2018/07/31). Two 32-bit
// multiplies, which a GPU does natively (a 64-bit multiply takes several 32-bit ones).
TRACER_HD TRACER_INLINE uint32_t hash32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x21f0aaadu;
  x ^= x >> 15;
  x *= 0x735a2d97u;
  x ^= x >> 15;
  return x;
}
constexpr uint32_t kGolden32 = 0x9e3779b9u;  // 2^32 / golden ratio, odd

// Bits reversed in both halves of a 64-bit word, which also swaps the halves: two 32-bit
// reversals for the price of about one on the CPU (the device has __brev).
TRACER_HD TRACER_INLINE uint64_t reverse_bits64(uint64_t x) {
#if defined(__CUDA_ARCH__)
  return __brevll(x);
#else
#if defined(__GNUC__)
  x = __builtin_bswap64(x);
#else
  x = (x << 32) | (x >> 32);
  x = ((x & 0x0000ffff0000ffffull) << 16) | ((x & 0xffff0000ffff0000ull) >> 16);
  x = ((x & 0x00ff00ff00ff00ffull) << 8) | ((x & 0xff00ff00ff00ff00ull) >> 8);
#endif
  x = ((x & 0x0f0f0f0f0f0f0f0full) << 4) | ((x & 0xf0f0f0f0f0f0f0f0ull) >> 4);
  x = ((x & 0x3333333333333333ull) << 2) | ((x & 0xccccccccccccccccull) >> 2);
  x = ((x & 0x5555555555555555ull) << 1) | ((x & 0xaaaaaaaaaaaaaaaaull) >> 1);
  return x;
#endif
}

// The point of sequence index `index` for one dimension pair. Shuffling the index by a nested
// scramble maps the first 2^m indices onto one aligned block of 2^m indices, so each pair's
// first 2^m points still form a (0,m,2)-net, while different pairs visit the block in unrelated
// orders (Burley 2020, sec. 4: padding by shuffling). `index_reversed` is
// reverse_bits32(index), shared by every pair of a vertex.
//
// Written out, x = scramble(sobol_dim0(shuffle(index))) is
// rev(LK(rev(rev(rev(LK(rev(index))))))); the inner reversals cancel, which leaves three
// reversals per 2D point (two for a 1D draw) instead of six, and on the CPU the last two are
// one 64-bit reversal.
TRACER_HD TRACER_INLINE uint32_t shuffled_index(uint32_t index_reversed, uint32_t seed) {
  return reverse_bits32(laine_karras_permutation(index_reversed, seed));
}
TRACER_HD TRACER_INLINE uint32_t owen_sobol_x(uint32_t shuffled, uint32_t seed) {
  return reverse_bits32(laine_karras_permutation(shuffled, seed));
}
TRACER_HD TRACER_INLINE uint32_t owen_sobol_y(uint32_t shuffled, uint32_t seed) {
  return reverse_bits32(laine_karras_permutation(sobol_dim1_reversed(shuffled), seed));
}

// The samples of one path vertex: dimension pair d of sample n at (pixel, bounce) is a point of
// its own randomization of the sequence.
//
// kSamplerSobol (the default): sample n is point n of one randomized sequence, so every aligned
// block of 2^m samples (the first 2^m among them) is one (0,m,2)-net per pair. The even- and
// odd-numbered samples then interleave to fill each other's gaps: their means are negatively
// correlated, and half-buffer noise estimates (relMSE between halves, a noise/bias split, a
// variance image) read high, 2-3x at 16-4,096 spp on the Cornell box: conservative, never
// optimistic, but too loose for a bias test, so bench --error skips the split for this sampler
// (independent_halves above).
// kSamplerSobolPairs: sample n is point n >> 1 of one of two independent randomizations picked
// by the parity n & 1, so the two halves are independent, identically distributed estimates and
// the half-buffer statistics are exact; each half is a net of its own, which leaves the whole
// about 10% noisier at 32-64 spp. The bench renders its references with it.
//
// Seeds: one 32-bit vertex seed hashes (user seed, bounce, stream) and then the pixel, where the
// stream is 2 for the single sequence and the parity for the pairs, so the samplers draw
// unrelated points (a reference rendered with one is independent of a test with the other at
// the same seed); each pair takes its own seed from it as SplitMix32 does, hash32(vertex seed +
// (pair + 1) * golden ratio) (Steele et al. 2014, "Fast splittable pseudorandom number
// generators"), and its three scrambles rotations of that (pair_seed below). All 32-bit, so the
// device needs no 64-bit multiplies.
struct SobolVertex {
  uint32_t index_reversed;
  uint32_t seed;

  TRACER_HD SobolVertex(uint32_t pixel, uint32_t sample, uint32_t bounce, uint32_t user_seed,
                        bool pairs = false) {
    index_reversed = reverse_bits32(pairs ? sample >> 1 : sample);
    const uint32_t stream = pairs ? (sample & 1u) : 2u;
    seed = hash32(pixel ^ hash32(user_seed + ((bounce << 2) | stream) * kGolden32));
  }

  // One hash per pair, hash32(vertex seed + (pair + 1) * golden ratio); its three scrambles
  // (k = 0, 1, 2: the index shuffle, x and y) take it rotated by 0, 11 and 22 bits. A scramble's
  // leading digits depend most on its seed's low bits, which the rotations take from different
  // bits of the hash: independent bits for the first 10 or 11 digits of each, at one
  // instruction per scramble instead of a hash's eight (tests/sobol_test.cpp checks nets,
  // uniformity and the absence of correlation).
  TRACER_HD uint32_t pair_seed(uint32_t pair) const { return hash32(seed + (pair + 1u) * kGolden32); }
  TRACER_HD static uint32_t sub_seed(uint32_t h, uint32_t k) {
    const uint32_t r = 11u * k;
    return r == 0 ? h : (h << r) | (h >> (32u - r));
  }
  TRACER_HD uint32_t scramble_seed(uint32_t pair, uint32_t k) const {
    return sub_seed(pair_seed(pair), k);
  }
  TRACER_HD vec2 get_2d(uint32_t pair) const {
    const uint32_t h = pair_seed(pair);
    const uint32_t shuffled = shuffled_index(index_reversed, h);
    const uint32_t x = laine_karras_permutation(shuffled, sub_seed(h, 1));
    const uint32_t y = laine_karras_permutation(sobol_dim1_reversed(shuffled), sub_seed(h, 2));
    const uint64_t xy = reverse_bits64(uint64_t(y) << 32 | x);  // rev(x) high, rev(y) low
    return vec2(fraction_to_float(uint32_t(xy >> 32)), fraction_to_float(uint32_t(xy)));
  }
  // A 1D draw is the first coordinate of its own pair (a (0,1)-sequence, stratified alone).
  TRACER_HD float get_1d(uint32_t pair) const {
    const uint32_t h = pair_seed(pair);
    return fraction_to_float(owen_sobol_x(shuffled_index(index_reversed, h), sub_seed(h, 1)));
  }
};

}  // namespace tracer
