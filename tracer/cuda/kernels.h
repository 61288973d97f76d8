// Host-callable launchers for the CUDA kernels (each defined beside its kernels: megakernel.cu,
// wavefront_trace.cu, wavefront_shade.cu, film.cu). Each takes a specialisation index `spec`
// (bits: 1 spheres, 2 depth of field, 4 specular materials) and runs the kernel compiled for
// exactly those features; kGeneralSpec runs the one for all features.
#pragma once

#include <cuda_runtime.h>

#include <vector>

#include "integrator/path.h"

namespace tracer {

// kSpec*, kGeneralSpec, features_of<Spec>() and spec_for_features() are in core/features.h.

// The 64-bit counters the kernels add to (WavefrontState::counters, launch_megakernel's).
enum Counter : uint32_t {
  kCounterShadow,        // shadow rays traced
  kCounterNonfinite,     // samples rejected as NaN or infinite
  kCounterMegaSegments,  // the megakernel's path segments (camera rays included)
  kCounterWalkCapped,    // random walks stopped at their step limit (and paths flushed)
  kCounterMediumLeak,    // paths that left a medium through an open mesh
  kCounterClamped,       // samples the radiance clamp scaled (FilmView::clamped)
  kCounterExtension,     // the wavefront's extension rays (launch_add_alive), the tail's segments
  kCounterCount
};

// A wavefront path's alive flag (WavefrontState::alive).
enum PathStatus : uint8_t {
  kStatusDone = 0,   // its sample is complete (added to the film): the slot is free
  kStatusAlive = 1,  // it goes on to the next bounce
  kStatusEnded = 2,  // it ended this bounce; its radiance is not yet in the film
};

// Structure-of-arrays path pool of `n` paths; path id == pixel index.
struct WavefrontState {
  uint32_t n = 0;
  float4* ray_o = nullptr;       // origin, prev_pdf
  float4* ray_d = nullptr;       // direction, depth - 1 | flags << 10 | prev_normal << 20 (bits)
  float4* throughput = nullptr;  // xyz
  float4* radiance = nullptr;    // xyz
  float4* hit = nullptr;         // t, prim (bits), u, v
  // With rays_at_slots (compaction in the shade kernel, no sorting, no random walks) ray_o,
  // ray_d and hit hold a bounce's rays and hits at the slots of its queue (bounce 0: slot = id),
  // and the shade kernel writes each next ray at its slot in the next queue, into next_ray_o /
  // next_ray_d (the other of two buffers). Otherwise all are at the path's id and next_ray_*
  // are ray_*.
  float4* next_ray_o = nullptr;
  float4* next_ray_d = nullptr;
  bool rays_at_slots = false;
  // Shadow rays: at the path's id, or with a shadow queue at the path's slot in it.
  float4* shadow_o = nullptr;    // origin, tmax
  float4* shadow_d = nullptr;    // direction, target prim (bits)
  float4* shadow_c = nullptr;    // contribution, valid (1 or 0)
  uint8_t* alive = nullptr;      // PathStatus
  uint32_t* sort_keys = nullptr;
  uint32_t* sort_bins = nullptr;       // 8 bins, 8 cursors, [16]: live paths in the sorted queue
  uint32_t* fetch = nullptr;           // the dynamic-fetch intersect kernel's ray counter
  unsigned long long* counters = nullptr;  // [kCounterCount], indexed by Counter
  uint32_t* alive_counts = nullptr;    // paths entering each bounce, [max_depth + 1]
  // With compaction in the shade kernel: the shadow rays of each bounce, the length of the shadow
  // queue its shade kernel wrote (the shadow stage then traces only those).
  uint32_t* shadow_counts = nullptr;
  uint32_t* finish_counts = nullptr;  // ... and its paths that end without one (far end)
  // Manifold NEE (render.mnee; the caustic shade kernels only): each path's PathState::mnee_o
  // and mnee_normal (bits), at its id.
  float4* mnee = nullptr;
  // ... and the shade kernel's MneeRequests for the mnee stage (launch_mnee): kMneeRequestWords
  // arrays of n float4 (word j of path id at [j * n + id]); the ids of the paths with one in
  // mnee_queue, their number per bounce in mnee_counts.
  float4* mnee_requests = nullptr;
  uint32_t* mnee_queue = nullptr;
  uint32_t* mnee_counts = nullptr;
};
constexpr uint32_t kMneeRequestWords = 21;

// The flat primitive list's entries (SceneView::flat_loop) passed by value to the kernels that
// loop over them, at most kFlatMaxCost entries of 48 bytes (3 KiB of the 4 KiB of parameters).
// Every lane of a warp reads the same entry at once; from the L1 cache each such 16-byte load
// still writes 512 bytes of registers through its data pipe, which makes that pipe the limit of
// the loops over the list, while a parameter comes from the constant bank.
struct FlatParams {
  float4 rows[3 * kFlatMaxCost];  // row_u, row_v, row_w of each entry (FlatPrim)
  float4 solids[3 * kFlatMaxSolids];  // the solid boxes' maps (FlatList::solids), likewise
  uint32_t count = 0;
};
// The entries and solid boxes of a scene's list (empty when it has none).
FlatParams make_flat_params(const std::vector<FlatPrim>& prims,
                            const std::vector<FlatPrim>& solids);

// One of the two accumulators (even and odd samples); a launch writes the one of its sample.
struct FilmView {
  float4* accum = nullptr;  // running sum per pixel
  uint32_t n = 0;
  float clamp = 0.0f;                          // the radiance clamp (0: off)
  double* clamped_luminance = nullptr;          // what the clamp removed
  unsigned long long* clamped = nullptr;        // how many samples it scaled
  // The shadow stages store every path's final radiance back into WavefrontState::radiance (not
  // only of the paths that go on), for path guiding's training after the sample.
  bool keep_radiance = false;
};

// The feature buffers (integrator/aov.h) of the two halves: a = albedo rgb and depth, b = the
// normal (w unused); ids = the material and primitive of the first AOV sample.
struct AovFilm {
  float4* a[2] = {nullptr, nullptr};
  float4* b[2] = {nullptr, nullptr};
  uint2* ids = nullptr;
  uint32_t n = 0;
  bool write_ids = false;  // this launch is the first AOV sample
};

// One AOV sample of every pixel (sample `sample`: its half is sample & 1; `first` overwrites
// the half's sums).
void launch_aov(uint32_t spec, const SceneView& s, const FlatParams& flat,
                const IntegratorSettings& cfg, uint32_t sample, bool first, const AovFilm& film,
                cudaStream_t stream);
// The mean albedo and normal as 3 floats per pixel (the denoiser's guides): half h weighted by
// w0 / w1 (0 for a half without samples).
void launch_aov_resolve(const AovFilm& film, float w0, float w1, float* albedo, float* normal,
                        cudaStream_t stream);

// counters[kCounterMegaSegments] receives the path segments traced (camera rays included);
// next_pixel is scratch.
void launch_megakernel(uint32_t spec, const SceneView& s, const FlatParams& flat,
                       const IntegratorSettings& cfg, uint32_t sample, bool first, FilmView film,
                       unsigned long long* counters, uint32_t* next_pixel, cudaStream_t stream);

// Path guiding (integrator/guide.h): after a training sample, each of the n paths adds its
// recorded vertices to the guide's sums (radiance: the pool's final radiance per path id) ...
void launch_guide_train(const GuideView& g, const float4* radiance, uint32_t n, uint32_t sample,
                        cudaStream_t stream);
// ... and after a training pass every cell's distribution is rebuilt; learned[0] (device)
// counts the learned cells, learned[1] those whose share of the guide is not 0 (zeroed first).
void launch_guide_build(float* hist, const uint32_t* counts, float* dist, uint32_t cells,
                        uint32_t* learned, cudaStream_t stream);

// The wavefront's tail: the megakernel over the paths of a queue (count: its device length),
// each taken from the pool's state and run to its end (its segments go to
// counters[kCounterExtension]).
// hits_ready: a fused trace stage traced the queue's rays (hits at their slots in w.hit), so the
// tail starts by shading them (flat list and rays at their slots only; throws otherwise).
void launch_tail(uint32_t spec, const SceneView& s, const FlatParams& flat,
                 const IntegratorSettings& cfg, uint32_t sample, bool first, FilmView film,
                 const WavefrontState& w, const uint32_t* queue, const uint32_t* count,
                 bool hits_ready, cudaStream_t stream);

void launch_generate(uint32_t spec, const SceneView& s, const IntegratorSettings& cfg,
                     uint32_t sample, const WavefrontState& w, cudaStream_t stream);
// queue == nullptr: every path (dead ones are skipped); count: device pointer to queue length.
// dynamic_fetch: persistent warps whose lanes take a new ray between traversal rounds
// (intersect_fetch_kernel); else one thread per queued ray.
void launch_intersect(uint32_t spec, const SceneView& s, const FlatParams& flat,
                      const WavefrontState& w, const uint32_t* queue, const uint32_t* count,
                      bool dynamic_fetch, cudaStream_t stream);
// next_queue (compaction in the shade kernel): each path that goes on is appended to it, in
// slot order within a block, by one atomic per block on alive_counts[bounce + 1]; nullptr: none.
// shadow_queue (nullptr: none; n slots): likewise each path with a shadow ray, from the front,
// counted on shadow_counts[bounce], and each path that ends without one from the back (slot
// n - 1 - k), counted on finish_counts[bounce].
void launch_shade(uint32_t spec, const SceneView& s, const IntegratorSettings& cfg,
                  uint32_t sample, uint32_t bounce, const WavefrontState& w,
                  const uint32_t* queue, const uint32_t* count, uint32_t* next_queue,
                  uint32_t* shadow_queue, cudaStream_t stream);
// Manifold NEE's stage (render.mnee): solves the requests the shade kernel of bounce `bounce`
// queued (w.mnee_requests, mnee_counts[bounce] of them) and adds what they find to the paths'
// radiance (and to their guide records' gathered radiance); between the shade and shadow stages.
void launch_mnee(uint32_t spec, const SceneView& s, const FlatParams& flat,
                 const IntegratorSettings& cfg, uint32_t sample, uint32_t bounce,
                 const WavefrontState& w, cudaStream_t stream);
// Light tracing (render.light_tracing; integrator/light_path.h): the film's n light paths of
// `sample`, their camera connections added to `film` (after the sample's camera paths); their
// segments and connections counted as extension and shadow rays. next_path is scratch.
void launch_light_trace(uint32_t spec, const SceneView& s, const FlatParams& flat,
                        const IntegratorSettings& cfg, uint32_t sample, const FilmView& film,
                        unsigned long long* counters, uint32_t* next_path, cudaStream_t stream);
// Without shadow_queue: over the bounce's queue (every path shaded, with a shadow ray or not);
// with it: the shadow rays, then the paths to finish, of the shade kernel's shadow queue.
void launch_shadow(uint32_t spec, const SceneView& s, const FlatParams& flat,
                   const WavefrontState& w, const uint32_t* queue, const uint32_t* count,
                   const uint32_t* shadow_queue, uint32_t bounce, bool first, FilmView film,
                   cudaStream_t stream);
// The fused trace stage: launch_shadow of bounce `bounce` over its shadow queue and
// launch_intersect of bounce + 1 (w's rays: that bounce's, at their queue slots; its length
// alive_counts[bounce + 1]; also when the tail takes that bounce) in one launch. Needs the flat
// list, rays at their slots and the shadow queue (throws std::logic_error otherwise).
void launch_trace(uint32_t spec, const SceneView& s, const FlatParams& flat,
                  const WavefrontState& w, const uint32_t* shadow_queue, uint32_t bounce,
                  bool first, FilmView film, cudaStream_t stream);
// Counting sort of the queue by the material type at each path's hit (Cycles-style); the live
// paths come first, and their number goes to w.sort_bins[16] (the sorted queue's length).
void launch_sort_by_material(const SceneView& s, const WavefrontState& w, const uint32_t* queue,
                             const uint32_t* count, uint32_t* sorted, cudaStream_t stream);
// CUB select: ids of paths with alive == kStatusAlive, in id order, and their number.
size_t compaction_temp_bytes(uint32_t n);
void launch_compact(const WavefrontState& w, uint32_t* out_queue, uint32_t* out_count,
                    void* temp, size_t temp_bytes, cudaStream_t stream);
// Ends the samples of paths still alive after the last wavefront iteration (counted as capped).
void launch_flush(const WavefrontState& w, bool first, FilmView film, cudaStream_t stream);
// Adds alive_counts[1 .. count) (the sample's extension rays) to *total.
void launch_add_alive(const uint32_t* alive_counts, uint32_t count, unsigned long long* total,
                      cudaStream_t stream);
// Copies the first-bounce hits out of / into the cache.
void launch_copy_hits(const float4* from, float4* to, uint32_t n, cudaStream_t stream);
// Mean radiance as float RGB from the two accumulators: a * wa + b * wb per pixel.
void launch_resolve(const float4* a, float wa, const float4* b, float wb, uint32_t n,
                    float* rgb_out, cudaStream_t stream);
// The display image (exposure, tone map, sRGB) as RGBA8 into `rgba` (e.g. a mapped GL buffer).
void launch_display(const float4* a, const float4* b, float inv_samples, uint32_t n,
                    float exposure_scale, int tone_map, uint32_t* rgba, cudaStream_t stream);

}  // namespace tracer
