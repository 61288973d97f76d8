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
// Sampling: with probability kGuideMix a direction from the cell's histogram (a bin by its
// cumulative distribution, a uniform point inside it), else the BSDF's; the weight divides by the
// mixture density kGuideMix * p_guide + (1 - kGuideMix) * p_bsdf, which is also the density MIS
// weighs against light sampling with. Cells with too few records, delta BSDFs (mirrors, smooth
// glass, a smooth coat's specular lobe) and random walks sample the BSDF alone.
#pragma once

#include "core/equal_area.h"
#include "core/math.h"
#include "core/rng.h"

namespace tracer {

constexpr uint32_t kGuideSide = 16;                      // bins per side of the square map
constexpr uint32_t kGuideBins = kGuideSide * kGuideSide;  // 256, 0.049 sr each
constexpr uint32_t kGuideRecords = 8;  // path vertices recorded per sample (the first 8)
constexpr float kGuideMix = 0.5f;      // probability of sampling the guide where it is learned
constexpr uint32_t kGuideTrainSamples = 255;  // passes of 1 + 2 + ... + 128 samples per pixel
constexpr uint32_t kGuideMinRecords = 16;     // records a cell needs before it guides
constexpr float kGuideUniform = 0.05f;        // share of a uniform density in each learned cell
constexpr uint32_t kGuideMaxSide = 24;        // cells along the scene's longest axis
constexpr float kGuideMinRoughness = 0.3f;    // rougher lobes are guided (path.h, guide_wide_bsdf)

// The guide as the integrator sees it (IntegratorSettings::guide). All null: no guiding.
// One path vertex's record for training (guide_record).
struct alignas(16) GuideRecord {
  uint32_t key;     // cell * kGuideBins + bin
  float weight;     // 1 / (density * luminance of the throughput after the vertex)
  float gathered;   // luminance of the radiance the path had gathered before it
  uint32_t sample;  // the sample it belongs to (another sample's records are stale)
};

struct GuideView {
  // cells * kGuideBins: each cell's cumulative distribution over its bins (inclusive). A cell's
  // last entry is 1 where it is learned and 0 where it is not. Null before the first build.
  const float* cdf = nullptr;
  // Training (null when not training): hist (cells * kGuideBins) sums the records' L / p,
  // counts (cells) counts them, records (pixels * kGuideRecords) holds each path's vertices
  // until its sample ends (guide_train_path).
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

TRACER_HD TRACER_INLINE bool guide_learned(const GuideView& g, uint32_t cell) {
  return g.cdf && g.cdf[size_t(cell) * kGuideBins + kGuideBins - 1] > 0.0f;
}

// Solid-angle density of the cell's distribution at unit direction d (cell learned).
TRACER_HD TRACER_INLINE float guide_pdf(const GuideView& g, uint32_t cell, vec3 d) {
  const float* c = g.cdf + size_t(cell) * kGuideBins;
  const uint32_t b = guide_bin(d);
  const float p = c[b] - (b > 0 ? c[b - 1] : 0.0f);
  return glm::max(p, 0.0f) * (float(kGuideBins) / (4.0f * kPi));
}

// A direction from the cell's distribution (cell learned): u.x chooses the bin and, rescaled,
// the point's first coordinate inside it; u.y the second. *pdf: guide_pdf of the result.
TRACER_HD inline vec3 guide_sample(const GuideView& g, uint32_t cell, vec2 u, float* pdf) {
  const float* c = g.cdf + size_t(cell) * kGuideBins;
  uint32_t lo = 0, hi = kGuideBins - 1;  // the first bin whose cumulative value exceeds u.x
  while (lo < hi) {
    const uint32_t mid = (lo + hi) >> 1;
    if (c[mid] > u.x) {
      hi = mid;
    } else {
      lo = mid + 1;
    }
  }
  const float before = lo > 0 ? c[lo - 1] : 0.0f;
  const float p = c[lo] - before;
  const float t = p > 0.0f ? glm::clamp((u.x - before) / p, 0.0f, 0.99999994f) : 0.5f;
  const vec2 q((float(lo % kGuideSide) + t) * (1.0f / kGuideSide),
               (float(lo / kGuideSide) + u.y) * (1.0f / kGuideSide));
  const vec3 d = glm::normalize(equal_area_square_to_sphere(q));
  *pdf = guide_pdf(g, cell, d);
  return d;
}

// Records a path vertex: its cell, the sampled direction d and its density, the throughput after
// the vertex and the luminance gathered before it (vertices past kGuideRecords are not recorded).
TRACER_HD TRACER_INLINE void guide_record(const GuideView& g, uint32_t pixel, uint32_t sample,
                                          uint32_t depth, uint32_t cell, vec3 d, float pdf,
                                          vec3 throughput, float gathered) {
  if (!g.records || depth == 0 || depth > kGuideRecords) return;
  const float t = luminance(throughput);
  if (!(t > 0.0f) || !(pdf > 0.0f)) return;
  const uint32_t key = cell * kGuideBins + guide_bin(d);
  g.records[size_t(pixel) * kGuideRecords + (depth - 1)] =
      GuideRecord{key, 1.0f / (pdf * t), gathered, sample};
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
// gathered after it (total - before it), over its density and throughput, to its bin.
TRACER_HD inline void guide_train_path(const GuideView& g, uint32_t pixel, uint32_t sample,
                                       vec3 total) {
  if (!g.hist || !g.records) return;
  const float all = luminance(total);
  if (!is_finite(all)) return;
  for (uint32_t k = 0; k < kGuideRecords; ++k) {
    const GuideRecord r = g.records[size_t(pixel) * kGuideRecords + k];
    if (r.sample != sample) continue;
    const float v = glm::max(all - r.gathered, 0.0f) * r.weight;
    if (v > 0.0f && is_finite(v)) guide_atomic_add(&g.hist[r.key], v);
    guide_atomic_inc(&g.counts[r.key / kGuideBins]);
  }
}

// Rebuilds cell `cell`'s distribution from the sums so far: learned where it has at least
// kGuideMinRecords records and some radiance, with kGuideUniform of a uniform density mixed in
// (a bin no record reached keeps a little density, so one noisy pass cannot shut out a direction).
// Returns whether the cell is learned.
TRACER_HD inline bool guide_build_cell(const float* hist, const uint32_t* counts, float* cdf,
                                       uint32_t cell) {
  const float* h = hist + size_t(cell) * kGuideBins;
  float* c = cdf + size_t(cell) * kGuideBins;
  float sum = 0.0f;
  for (uint32_t b = 0; b < kGuideBins; ++b) sum += h[b];
  if (counts[cell] < kGuideMinRecords || !(sum > 0.0f) || !is_finite(sum)) {
    for (uint32_t b = 0; b < kGuideBins; ++b) c[b] = 0.0f;
    return false;
  }
  const float a = (1.0f - kGuideUniform) / sum, u = kGuideUniform / float(kGuideBins);
  float run = 0.0f;
  for (uint32_t b = 0; b < kGuideBins; ++b) {
    run += h[b] * a + u;
    c[b] = run;
  }
  for (uint32_t b = 0; b < kGuideBins; ++b) c[b] /= run;  // exactly 1 at the end
  c[kGuideBins - 1] = 1.0f;
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
