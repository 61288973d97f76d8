// Path guiding, the shared core: a regular grid of cells over the scene, each with a histogram of
// incident radiance over directions (16 x 16 bins of equal solid angle, the equal-area octahedral
// map of core/equal_area.h), learned while rendering from the radiance the paths themselves carry
// back to their vertices, and sampled together with the BSDF by one-sample MIS.
//
// The design follows "Practical Path Guiding" (Mueller, Gross, Novak 2017) with a flat structure
// in place of its SD-tree, so that every cell and bin sits at a fixed address the GPU updates with
// plain atomics and no tree is rebuilt: training in passes of doubling length (1, 2, 4, ... 128
// samples per pixel); after each pass every cell's distribution is rebuilt from all the radiance
// recorded so far; after kGuideTrainSamples samples the guide is frozen and the records stop.
// Every pass renders with a valid mixture density, so every sample is unbiased and all of them
// are kept (the early passes are merely noisier).
//
// What a vertex records: the luminance of the radiance its path gathered after it (emission hit
// with its MIS weight, and next-event estimation at later vertices), divided by the throughput
// up to the next vertex and by the density the direction was sampled with: an unbiased estimate
// of the bin's integral of incident radiance (PPG's L / p). Next-event estimation at the vertex
// itself is not along the sampled direction and is left out, so direct light is learned only in
// the share BSDF sampling gets of it by MIS: the guide learns mostly what light sampling misses.
//
// Sampling: with the cell's share of the guide, a direction from its histogram (a row by the
// rows' cumulative distribution, a bin by the row's, a uniform point inside it), else the BSDF's;
// the weight divides by the mixture density s * p_guide + (1 - s) * p_bsdf, which is also the
// density MIS weighs against light sampling with. Cells with too few records, delta BSDFs
// (mirrors, smooth glass, a smooth coat's specular lobe) and random walks sample the BSDF alone.
//
// The share s is learned per cell, as "Practical Path Guiding in Production" (Mueller 2019)
// learns its selection probability, but by choice among a few candidates instead of by gradient
// descent: each training pass estimates, from the vertices of learned cells, the second moment
// of the vertex's estimate f cos L / p under every candidate share (the recorded sample
// reweighted by the ratio of the densities), and the build gives the cell the candidate with the
// least (the last pass decides: earlier passes' densities are stale). Where the
// BSDF already samples what arrives (a diffuse wall lit evenly, a glossy lobe), the share drops to
// 0 and the vertex costs what an unguided one does; where the guide knows a bright direction the
// BSDF misses, it rises to 3/4.
#pragma once

#include "core/equal_area.h"
#include "core/math.h"
#include "core/rng.h"

namespace tracer {

constexpr uint32_t kGuideSide = 16;                      // bins per side of the square map
constexpr uint32_t kGuideBins = kGuideSide * kGuideSide;  // 256, 0.049 sr each
constexpr uint32_t kGuideRecords = 8;  // path vertices recorded per sample (the first 8)
constexpr float kGuideMix = 0.5f;      // a cell's guide share until it has learned its own
constexpr uint32_t kGuideTrainSamples = 255;  // passes of 1 + 2 + ... + 128 samples per pixel
constexpr uint32_t kGuideMinRecords = 16;     // records a cell needs before it guides
constexpr float kGuideUniform = 0.05f;        // share of a uniform density in each learned cell
constexpr uint32_t kGuideMaxSide = 24;        // cells along the scene's longest axis
constexpr float kGuideMinRoughness = 0.3f;    // rougher lobes are guided (path.h, guide_wide_bsdf)
// The guide's share of the mixture is learned per cell among kGuideShares candidates
// (guide_share): 0 (the BSDF alone), 1/4, 1/2 and 3/4.
constexpr uint32_t kGuideShares = 4;
constexpr uint32_t kGuideMinShareRecords = 64;  // guided records a cell needs to choose its share
// A cell guides only where its best share is estimated to cut the vertex's second moment by at
// least this much against the BSDF alone: enough to pay for a guided vertex's extra lookups.
constexpr float kGuideMinGain = 0.25f;
// A cell's training sums (GuideView::hist): the bins' L / p, then per candidate share the
// estimated second moment of the vertex's estimate, then the number of guided records.
constexpr uint32_t kGuideHistFloats = kGuideBins + kGuideShares + 1;
// A cell's distribution (GuideView::dist): [0] the guide's share (0: sample the BSDF alone),
// [1 + r] for r < 15 the cumulative probability of rows 0..r (row 15 ends at 1), then each row's
// cumulative distribution over its 16 bins: a bin is sampled from two cache lines.
constexpr uint32_t kGuideDistFloats = kGuideSide + kGuideBins;

TRACER_HD constexpr float guide_share(uint32_t candidate) { return 0.25f * float(candidate); }

// One path vertex's record for training (guide_record).
struct alignas(16) GuideRecord {
  uint32_t key;     // cell * kGuideBins + bin
  float weight;     // 1 / (density * luminance of the throughput after the vertex)
  float gathered;   // luminance of the radiance the path had gathered before it
  uint32_t sample;  // the sample it belongs to (another sample's records are stale)
  // For the cell's share of the guide: the luminance of the BSDF times the cosine, and the
  // densities of the guide and of the BSDF at the direction (pdf_guide 0: the vertex was not
  // guided and only trains the histogram); the density it was sampled with is the mixture's.
  float f_cos, pdf_guide, pdf_bsdf, pdf;
};

// The guide as the integrator sees it (IntegratorSettings::guide). All null: no guiding.
struct GuideView {
  // cells * kGuideDistFloats: each cell's distribution (kGuideDistFloats). Null before the
  // first build.
  const float* dist = nullptr;
  // Training (null when not training): hist (cells * kGuideHistFloats) sums the records' L / p
  // and the share's statistics, counts (cells) counts the records, records (pixels *
  // kGuideRecords) holds each path's vertices until its sample ends (guide_train_path).
  float* hist = nullptr;
  uint32_t* counts = nullptr;
  GuideRecord* records = nullptr;
  vec3 lo = vec3(0.0f);        // the grid's lower corner
  vec3 inv_cell = vec3(1.0f);  // cells per unit length on each axis
  uint32_t nx = 1, ny = 1, nz = 1;
};

// The grid cell of point p (points outside fall into the nearest cell).
TRACER_HD TRACER_INLINE uint32_t guide_cell(const GuideView& g, vec3 p) {
  const vec3 c = (p - g.lo) * g.inv_cell;
  const uint32_t x = uint32_t(glm::clamp(int32_t(c.x), 0, int32_t(g.nx) - 1));
  const uint32_t y = uint32_t(glm::clamp(int32_t(c.y), 0, int32_t(g.ny) - 1));
  const uint32_t z = uint32_t(glm::clamp(int32_t(c.z), 0, int32_t(g.nz) - 1));
  return (z * g.ny + y) * g.nx + x;
}

// The bin of unit direction d.
TRACER_HD TRACER_INLINE uint32_t guide_bin(vec3 d) {
  const vec2 q = equal_area_sphere_to_square(d);
  const uint32_t x = glm::min(uint32_t(glm::max(q.x, 0.0f) * kGuideSide), kGuideSide - 1);
  const uint32_t y = glm::min(uint32_t(glm::max(q.y, 0.0f) * kGuideSide), kGuideSide - 1);
  return y * kGuideSide + x;
}

// Whether cell `cell` has a distribution (built from enough records); its share may still be 0.
TRACER_HD TRACER_INLINE bool guide_learned(const GuideView& g, uint32_t cell) {
  return g.dist && g.dist[size_t(cell) * kGuideDistFloats + kGuideSide - 1] > 0.0f;
}
// The guide's share of the mixture the cell samples with (0 where it is not learned).
TRACER_HD TRACER_INLINE float guide_mix(const GuideView& g, uint32_t cell) {
  return g.dist ? g.dist[size_t(cell) * kGuideDistFloats] : 0.0f;
}

// Row r's cumulative probability (rows 0..r) and bin (r, x)'s within its row, in block d.
TRACER_HD TRACER_INLINE float guide_row_cdf(const float* d, int r) {
  return r < 0 ? 0.0f : r >= int(kGuideSide) - 1 ? 1.0f : d[1 + r];
}
TRACER_HD TRACER_INLINE float guide_col_cdf(const float* d, uint32_t r, int x) {
  return x < 0 ? 0.0f : d[kGuideSide + r * kGuideSide + uint32_t(x)];
}

// Solid-angle density of the cell's distribution at unit direction d (cell learned).
TRACER_HD TRACER_INLINE float guide_pdf(const GuideView& g, uint32_t cell, vec3 d) {
  const float* c = g.dist + size_t(cell) * kGuideDistFloats;
  const uint32_t b = guide_bin(d), r = b / kGuideSide, x = b % kGuideSide;
  const float pr = guide_row_cdf(c, int(r)) - guide_row_cdf(c, int(r) - 1);
  const float px = guide_col_cdf(c, r, int(x)) - guide_col_cdf(c, r, int(x) - 1);
  return glm::max(pr * px, 0.0f) * (float(kGuideBins) / (4.0f * kPi));
}

// A direction from the cell's distribution (cell learned): u.x chooses the row and, rescaled,
// the point's second coordinate inside the bin; u.y the bin in the row and the first coordinate.
// *pdf: guide_pdf of the result.
TRACER_HD inline vec3 guide_sample(const GuideView& g, uint32_t cell, vec2 u, float* pdf) {
  const float* c = g.dist + size_t(cell) * kGuideDistFloats;
  // The first row whose cumulative value exceeds u.x: the count of those that do not (the
  // cumulative values rise, row 15's is 1), from one cache line without branches.
  uint32_t r = 0;
  for (uint32_t k = 1; k < kGuideSide; ++k) r += c[k] <= u.x ? 1u : 0u;
  const float r0 = guide_row_cdf(c, int(r) - 1), pr = guide_row_cdf(c, int(r)) - r0;
  const float ty = pr > 0.0f ? glm::clamp((u.x - r0) / pr, 0.0f, 0.99999994f) : 0.5f;
  const float* row = c + kGuideSide + r * kGuideSide;
  uint32_t x = 0;
  for (uint32_t k = 0; k + 1 < kGuideSide; ++k) x += row[k] <= u.y ? 1u : 0u;
  const float x0 = x > 0 ? row[x - 1] : 0.0f, px = row[x] - x0;
  const float tx = px > 0.0f ? glm::clamp((u.y - x0) / px, 0.0f, 0.99999994f) : 0.5f;
  const vec2 q((float(x) + tx) * (1.0f / kGuideSide), (float(r) + ty) * (1.0f / kGuideSide));
  const vec3 d = glm::normalize(equal_area_square_to_sphere(q));
  *pdf = guide_pdf(g, cell, d);
  return d;
}

// Records a path vertex: its cell, the sampled direction d and the density it was sampled with,
// the throughput after the vertex, the luminance gathered before it (vertices past kGuideRecords
// are not recorded), and for the cell's share: the luminance of the BSDF times the cosine and
// the guide's and the BSDF's densities at d (pdf_guide 0 where the cell has no distribution).
TRACER_HD TRACER_INLINE void guide_record(const GuideView& g, uint32_t pixel, uint32_t sample,
                                          uint32_t depth, uint32_t cell, vec3 d, float pdf,
                                          vec3 throughput, float gathered, float f_cos,
                                          float pdf_guide, float pdf_bsdf) {
  if (!g.records || depth == 0 || depth > kGuideRecords) return;
  const float t = luminance(throughput);
  if (!(t > 0.0f) || !(pdf > 0.0f)) return;
  const uint32_t key = cell * kGuideBins + guide_bin(d);
  g.records[size_t(pixel) * kGuideRecords + (depth - 1)] =
      GuideRecord{key, 1.0f / (pdf * t), gathered, sample, f_cos, pdf_guide, pdf_bsdf, pdf};
}

// Radiance (luminance lum) that the path's vertex at `depth` gathered after guide_record wrote
// its record (manifold NEE's deferred stage): counted as gathered before the vertex's direction,
// as it would have been had it been added in time.
TRACER_HD TRACER_INLINE void guide_add_gathered(const GuideView& g, uint32_t pixel,
                                                uint32_t sample, uint32_t depth, float lum) {
  if (!g.records || depth == 0 || depth > kGuideRecords) return;
  GuideRecord& r = g.records[size_t(pixel) * kGuideRecords + (depth - 1)];
  if (r.sample == sample) r.gathered += lum;
}

// x += v for a float that other threads also add to.
TRACER_HD TRACER_INLINE void guide_atomic_add(float* x, float v) {
#if defined(__CUDA_ARCH__)
  atomicAdd(x, v);
#else
  uint32_t* bits = reinterpret_cast<uint32_t*>(x);
  uint32_t old = __atomic_load_n(bits, __ATOMIC_RELAXED);
  for (;;) {
    float f;
    __builtin_memcpy(&f, &old, 4);
    f += v;
    uint32_t next;
    __builtin_memcpy(&next, &f, 4);
    if (__atomic_compare_exchange_n(bits, &old, next, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED))
      return;
  }
#endif
}
TRACER_HD TRACER_INLINE void guide_atomic_inc(uint32_t* x) {
#if defined(__CUDA_ARCH__)
  atomicAdd(x, 1u);
#else
  __atomic_fetch_add(x, 1u, __ATOMIC_RELAXED);
#endif
}

// The end of a training sample: each recorded vertex of the pixel's path adds the radiance
// gathered after it (total - before it), over its density and throughput, to its bin. A vertex
// whose cell has a distribution also adds, for each candidate share s, its estimate X = f cos L / p
// squared and reweighted to the mixture of share s: X^2 p / p_s, whose mean is the second moment
// of the vertex's estimate had it sampled with share s (the variance up to a constant that no
// share changes), so that the build can pick the share with the least.
TRACER_HD inline void guide_train_path(const GuideView& g, uint32_t pixel, uint32_t sample,
                                       vec3 total) {
  if (!g.hist || !g.records) return;
  const float all = luminance(total);
  if (!is_finite(all)) return;
  for (uint32_t k = 0; k < kGuideRecords; ++k) {
    const GuideRecord r = g.records[size_t(pixel) * kGuideRecords + k];
    if (r.sample != sample) continue;
    const uint32_t cell = r.key / kGuideBins;
    float* h = g.hist + size_t(cell) * kGuideHistFloats;
    const float v = glm::max(all - r.gathered, 0.0f) * r.weight;
    if (!is_finite(v)) continue;
    if (v > 0.0f) guide_atomic_add(&h[r.key % kGuideBins], v);
    guide_atomic_inc(&g.counts[cell]);
    if (!(r.pdf_guide > 0.0f)) continue;
    const float x = v * r.f_cos;
    const float x2p = x * x * r.pdf;
    if (!is_finite(x2p)) continue;
    if (x2p > 0.0f)
      for (uint32_t i = 0; i < kGuideShares; ++i) {
        const float s = guide_share(i);
        const float ps = s * r.pdf_guide + (1.0f - s) * r.pdf_bsdf;
        guide_atomic_add(&h[kGuideBins + i], ps > 0.0f ? x2p / ps : 3.0e38f);
      }
    guide_atomic_add(&h[kGuideBins + kGuideShares], 1.0f);
  }
}

// Rebuilds cell `cell`'s distribution (kGuideDistFloats at dist) from the sums so far: learned
// where it has at least kGuideMinRecords records and some radiance, with kGuideUniform of a
// uniform density mixed in (a bin no record reached keeps a little density, so one noisy pass
// cannot shut out a direction). Its share: the candidate with the least estimated second moment
// once kGuideMinShareRecords guided records are in (0 unless that is kGuideMinGain below the
// BSDF's alone), kGuideMix before. Returns whether the cell is learned.
TRACER_HD inline bool guide_build_cell(float* hist, const uint32_t* counts, float* dist,
                                       uint32_t cell) {
  float* h = hist + size_t(cell) * kGuideHistFloats;
  float* d = dist + size_t(cell) * kGuideDistFloats;
  float sum = 0.0f;
  for (uint32_t b = 0; b < kGuideBins; ++b) sum += h[b];
  if (counts[cell] < kGuideMinRecords || !(sum > 0.0f) || !is_finite(sum)) {
    for (uint32_t b = 0; b < kGuideDistFloats; ++b) d[b] = 0.0f;
    return false;
  }
  const float a = (1.0f - kGuideUniform) / sum, u = kGuideUniform / float(kGuideBins);
  float rows = 0.0f;
  for (uint32_t r = 0; r < kGuideSide; ++r) {
    float* c = d + kGuideSide + r * kGuideSide;
    float run = 0.0f;
    for (uint32_t x = 0; x < kGuideSide; ++x) {
      run += h[r * kGuideSide + x] * a + u;
      c[x] = run;
    }
    for (uint32_t x = 0; x < kGuideSide; ++x) c[x] /= run;  // exactly 1 at the row's end
    c[kGuideSide - 1] = 1.0f;
    rows += run;
    if (r + 1 < kGuideSide) d[1 + r] = rows;  // divided by the total below
  }
  for (uint32_t r = 0; r + 1 < kGuideSide; ++r) d[1 + r] = glm::min(d[1 + r] / rows, 1.0f);
  float share = kGuideMix;
  if (h[kGuideBins + kGuideShares] >= float(kGuideMinShareRecords)) {
    float best = h[kGuideBins];
    share = guide_share(0);
    for (uint32_t i = 1; i < kGuideShares; ++i)
      if (h[kGuideBins + i] < best) {
        best = h[kGuideBins + i];
        share = guide_share(i);
      }
    if (!(best < (1.0f - kGuideMinGain) * h[kGuideBins])) share = 0.0f;
  }
  d[0] = share;
  for (uint32_t i = 0; i <= kGuideShares; ++i) h[kGuideBins + i] = 0.0f;  // the next pass's own
  return true;
}

// The training schedule, by sample index: samples below kGuideTrainSamples record, and the guide
// is rebuilt after samples 0, 2, 6, 14, ... 254 (the ends of passes of 1, 2, 4, ... 128).
TRACER_HD TRACER_INLINE bool guide_trains(uint32_t sample) {
  return sample < kGuideTrainSamples;
}
TRACER_HD TRACER_INLINE bool guide_builds_after(uint32_t sample) {
  return sample < kGuideTrainSamples && ((sample + 2) & (sample + 1)) == 0;
}

}  // namespace tracer
