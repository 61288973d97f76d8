// The wavefront's ray stages: the intersect stage (through the BVH, one thread per ray or with
// dynamic fetch, or through the flat list), the shadow stage (over every path, or over the shade
// kernel's shadow queue) and the fused trace stage (a bounce's shadow rays with the next
// bounce's extension rays).
#include <stdexcept>

#include "cuda/kernel_common.cuh"

namespace tracer {
namespace {

// The extension ray of path `id`, and the primitive it must skip: hit[id] still holds the hit
// the ray leaves from, and with random walks (where a triangle can be far larger than a mean
// free path) that triangle is skipped.
__device__ __forceinline__ Ray extension_ray(const SceneView& s, const WavefrontState& w,
                                             uint32_t id, bool walks, uint32_t* skip) {
  const float4 o = w.ray_o[id], d = w.ray_d[id];
  Ray ray;
  ray.o = vec3(o.x, o.y, o.z);
  ray.d = vec3(d.x, d.y, d.z);
  ray.tmax = kInfinity;
  ray.pad = 0.0f;
  const uint32_t origin = walks ? __float_as_uint(w.hit[id].y) : kInvalid;
  *skip = prim_is_triangle(s, origin) ? origin : kInvalid;
  return ray;
}

__device__ __forceinline__ void store_hit(const WavefrontState& w, uint32_t id, const Hit& h) {
  w.hit[id] = make_float4(h.t, __uint_as_float(h.prim), h.u, h.v);
}

// The intersect stage through the BVH, one thread per queued ray (without dynamic fetch).
template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) intersect_kernel(SceneView s, WavefrontState w,
                                                           const uint32_t* queue,
                                                           const uint32_t* count, bool walks) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x, total = queue_total(w, queue, count);
  // The ray's index: its slot, or its path's id.
  const uint32_t ri =
      w.rays_at_slots ? (i < total ? i : kInvalid) : queued_path(w, queue, i, total);
  if (ri == kInvalid) return;
  uint32_t skip;
  const Ray ray = extension_ray(s, w, ri, walks, &skip);
  store_hit(w, ri, intersect_closest<features_of<Spec>()>(s, ray, skip));
}

// Rays per lane of the flat list's intersect kernel (intersect_flat_kernel): 4 (64 registers)
// without spheres, 2 (40) with them, where 4 would take 84 registers (PERFORMANCE.md, decision
// log, rows 69-70 and 80).
template <uint32_t Spec>
constexpr int flat_rays() {
#ifdef TRACER_FLAT_RAYS_PER_LANE
  return TRACER_FLAT_RAYS_PER_LANE;
#else
  return (Spec & kSpecSpheres) ? 2 : 4;
#endif
}

// The intersect stage through the flat list: each lane traces flat_rays() queued rays, slots
// kBlock apart (coalesced), in one pass over the entries (flat_closest_multi). One ray per lane
// spent 6 of its ~33 instructions per entry on the entry's constant-bank loads, and those loads
// kept the memory pipes 78% busy (Nsight, bounce 1 of the open box): shared by two rays, the
// loads and the loop's own instructions are paid once per pair.
// kWalks: the scene has random walks, whose rays skip the triangle they leave from.
// The KK rays of a lane: queue slots first + k * kBlock, k < KK (coalesced over a warp); id[k]
// below is the index of the ray and its hit (its slot, or its path's id).
template <uint32_t F, int KK>
__device__ __forceinline__ void intersect_rows(const SceneView& s, const WavefrontState& w,
                                               const uint32_t* queue, uint32_t total,
                                               uint32_t first) {
  constexpr bool kWalks = (F & kFeatureSubsurface) != 0;
  uint32_t id[KK], skip[KK];
  Ray ray[KK];
#pragma unroll
  for (int k = 0; k < KK; ++k) {
    const uint32_t slot = first + k * kBlock;
    id[k] = w.rays_at_slots ? (slot < total ? slot : kInvalid) : queued_path(w, queue, slot, total);
    if (id[k] != kInvalid) {
      ray[k] = extension_ray(s, w, id[k], kWalks, &skip[k]);
    } else {
      ray[k].o = vec3(0.0f);
      ray[k].d = vec3(0.0f, 0.0f, 1.0f);
      ray[k].tmax = 0.0f;  // nothing hits it
      ray[k].pad = 0.0f;
      skip[k] = kInvalid;
    }
  }
  Hit hit[KK];
  flat_closest_multi<F, KK>(s, ray, skip, hit);
#pragma unroll
  for (int k = 0; k < KK; ++k)
    if (id[k] != kInvalid) store_hit(w, id[k], hit[k]);
}

template <uint32_t Spec, bool kWalks>
__global__ void __launch_bounds__(kBlock) intersect_flat_kernel(SceneView view,
                                                                const __grid_constant__ FlatParams flat,
                                                                WavefrontState w,
                                                                const uint32_t* queue,
                                                                const uint32_t* count) {
  constexpr int kFlatRays = flat_rays<Spec>();
  constexpr uint32_t F =
      features_of<Spec>() | kFeatureFlatList | (kWalks ? kFeatureSubsurface : 0u);
  const SceneView s = with_flat_params(view, flat);
  const uint32_t total = queue_total(w, queue, count);
  const uint32_t first = blockIdx.x * (kFlatRays * kBlock) + threadIdx.x;
  if (first >= total) return;
  intersect_rows<F, kFlatRays>(s, w, queue, total, first);
}

// Lanes of the dynamic-fetch kernel refill in batches of 8 (16 is no faster, 4 slower:
// PERFORMANCE.md, decision log, row 32).
constexpr int kFetchBatch = 8;

// The same query with dynamic fetch (Aila & Laine 2009, sec. 5): persistent warps, and a lane
// whose ray is done takes the next queued ray from a global counter between traversal rounds,
// while the rest of its warp goes on, instead of idling until the warp's slowest ray ends. Lanes
// refill together (one atomic per warp) once kFetchBatch of them wait or none is busy.
template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) intersect_fetch_kernel(SceneView s, WavefrontState w,
                                                                 const uint32_t* queue,
                                                                 const uint32_t* count,
                                                                 bool walks) {
  constexpr uint32_t F = features_of<Spec>();
  constexpr unsigned kFull = 0xffffffffu;
  const uint32_t total = queue ? *count : w.n;
  const uint32_t lane = threadIdx.x & 31;
  uint32_t id = kInvalid, skip = kInvalid;
  bool active = false, retired = false;
  Ray ray;
  vec3 inv_d(0.0f);
  RayTriSetup setup;
  float tmax = kInfinity;
  Hit hit;
  uint32_t stack[kBvhStackSize];
  TraversalCursor c{};  // set by traversal_start when the lane takes a ray
  for (;;) {
    const unsigned want = __ballot_sync(kFull, !active && !retired);
    const unsigned busy = __ballot_sync(kFull, active);
    if (want && (__popc(want) >= kFetchBatch || busy == 0)) {
      const int leader = __ffs(want) - 1;
      uint32_t base = 0;
      if (lane == uint32_t(leader)) base = atomicAdd(w.fetch, uint32_t(__popc(want)));
      base = __shfl_sync(kFull, base, leader);
      if (!active && !retired) {
        const uint32_t k = base + __popc(want & ((1u << lane) - 1u));
        if (k >= total) {
          retired = true;
        } else {
          id = queue && !w.rays_at_slots ? queue[k] : k;  // the ray's index
          // (A finished path's lane takes another one next round.)
          if (queue || w.alive[id] == kStatusAlive) {
            ray = extension_ray(s, w, id, walks, &skip);
            inv_d = 1.0f / ray.d;
            setup = RayTriSetup(ray, inv_d);
            tmax = ray.tmax;
            hit = Hit();
            c = traversal_start(s, ray);
            active = true;
          }
        }
      }
    }
    if (__all_sync(kFull, retired)) break;
    if (active &&
        traverse_round<F, false>(s, ray, inv_d, setup, skip, kInvalid, tmax, hit, stack, c)) {
      store_hit(w, id, hit);
      active = false;
    }
  }
}

// Whether the shadow ray (o: origin, tmax; d: direction, target primitive) of path id reaches
// its light; with random walks it also skips the triangle the path's hit names.
template <uint32_t Spec>
__device__ __forceinline__ bool shadow_reaches(const SceneView& s, const WavefrontState& w,
                                               uint32_t id, float4 o, float4 d, bool walks) {
  Ray ray;
  ray.o = vec3(o.x, o.y, o.z);
  ray.tmax = o.w;
  ray.d = vec3(d.x, d.y, d.z);
  ray.pad = 0.0f;
  uint32_t origin = kInvalid;
  if (walks) origin = __float_as_uint(w.hit[id].y);
  return !shadow_blocked<features_of<Spec>() | kFeatureFlatList>(
      s, ray, __float_as_uint(d.w), prim_is_triangle(s, origin) ? origin : kInvalid);
}

template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) shadow_kernel(SceneView view,
                                                        const __grid_constant__ FlatParams flat,
                                                        WavefrontState w, const uint32_t* queue,
                                                        const uint32_t* count, bool first,
                                                        FilmView film, bool walks) {
  const SceneView s = with_flat_params(view, flat);
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= queue_total(w, queue, count)) return;
  const uint32_t id = queue ? queue[i] : i;
  const uint8_t state = w.alive[id];
  if (state == kStatusDone) return;
  const float4 c = w.shadow_c[id];
  float4 r = w.radiance[id];
  if (c.w != 0.0f) {
    if (shadow_reaches<Spec>(s, w, id, w.shadow_o[id], w.shadow_d[id], walks)) {
      r.x += c.x;
      r.y += c.y;
      r.z += c.z;
      if (state == kStatusAlive || film.keep_radiance) w.radiance[id] = r;
    }
  }
  if (state == kStatusEnded)  // the path ended in this bounce: its sample is complete
    finish_path(w, id, vec3(r.x, r.y, r.z), path_flags(w, id), first, film);
}

// The shadow stage over the shadow queue the shade kernel wrote: every lane of the first
// shadow_counts[b] has a ray, and with no choice to make first, the ray, its contribution, the
// path's radiance and state are read at once, one dependent step after the queue slot (the pass
// above waits for the state, then the contribution, then the ray). The lanes after them finish
// the paths that ended without a shadow ray (finish_counts[b], from the queue's far end).
// Minimum resident blocks per SM asked of the compiler for the queued shadow stage: none by
// default (59 registers, 4 blocks per SM); TRACER_SHADOW_MIN_BLOCKS sets one for a build
// variant. Caps of 5 and 6 blocks, and an explicit 1 (which changes the sphere variant's code),
// measured slower (PERFORMANCE.md, decision log, rows 75-76).
#ifdef TRACER_SHADOW_MIN_BLOCKS
#define TRACER_SHADOW_BOUNDS __launch_bounds__(kBlock, TRACER_SHADOW_MIN_BLOCKS)
#else
#define TRACER_SHADOW_BOUNDS __launch_bounds__(kBlock)
#endif
// Lane i of the queued shadow stage of bounce `bounce`: the i-th shadow ray of the shade
// kernel's shadow queue, or (past them) the next path to finish from the queue's far end.
template <uint32_t Spec>
__device__ __forceinline__ void shadow_queued_lane(const SceneView& s, const WavefrontState& w,
                                                   const uint32_t* shadow_queue, uint32_t bounce,
                                                   bool first, const FilmView& film, bool walks,
                                                   uint32_t i) {
  const uint32_t rays = w.shadow_counts[bounce];
  if (i >= rays) {
    const uint32_t k = i - rays;
    if (k >= w.finish_counts[bounce]) return;
    const uint32_t id = shadow_queue[w.n - 1 - k];
    const float4 r = w.radiance[id];
    finish_path(w, id, vec3(r.x, r.y, r.z), path_flags(w, id), first, film);
    return;
  }
  const uint32_t id = shadow_queue[i];
  // The ray at its slot (coalesced); the path's radiance and state at its id.
  const float4 o = w.shadow_o[i], d = w.shadow_d[i], c = w.shadow_c[i];
  float4 r = w.radiance[id];
  const uint8_t state = w.alive[id];
  if (shadow_reaches<Spec>(s, w, id, o, d, walks)) {
    r.x += c.x;
    r.y += c.y;
    r.z += c.z;
    if (state == kStatusAlive || film.keep_radiance) w.radiance[id] = r;
  }
  if (state == kStatusEnded)
    finish_path(w, id, vec3(r.x, r.y, r.z), path_flags(w, id), first, film);
}

template <uint32_t Spec>
__global__ void TRACER_SHADOW_BOUNDS shadow_queued_kernel(SceneView view,
                                                               const __grid_constant__ FlatParams flat,
                                                               WavefrontState w,
                                                               const uint32_t* shadow_queue,
                                                               uint32_t bounce, bool first,
                                                               FilmView film, bool walks) {
  const SceneView s = with_flat_params(view, flat);
  shadow_queued_lane<Spec>(s, w, shadow_queue, bounce, first, film, walks,
                           blockIdx.x * blockDim.x + threadIdx.x);
}

// The fused trace stage: the queued shadow stage of bounce `bounce` and the flat intersect stage
// of bounce + 1 in one launch (both read only what bounce's shade kernel wrote, and neither
// reads what the other writes). A stage over a short queue runs in one or two waves of blocks
// that all wait for memory, then all compute, then all store, and pays a fixed cost however
// short its queue (PERFORMANCE.md, "Short queues"). One grid holds both stages' blocks, so that
// the shadow rays' loads overlap the extension rays' arithmetic, and one launch, fill and drain
// is saved.
// The first blocks trace the extension rays (w's rays: bounce + 1's, at their slots; the longer
// blocks first), the rest are the shadow stage's; blocks past both have nothing to do.
// Only with rays at their slots (hence no random walks) and the flat list.
template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) trace_kernel(SceneView view,
                                                       const __grid_constant__ FlatParams flat,
                                                       WavefrontState w,
                                                       const uint32_t* shadow_queue,
                                                       uint32_t bounce, bool first,
                                                       FilmView film) {
  constexpr int kFlatRays = flat_rays<Spec>();
  constexpr uint32_t kRaysPerBlock = kFlatRays * kBlock;
  constexpr uint32_t F = features_of<Spec>() | kFeatureFlatList;
  const SceneView s = with_flat_params(view, flat);
  const uint32_t rays = w.alive_counts[bounce + 1];
  const uint32_t ray_blocks = (rays + kRaysPerBlock - 1) / kRaysPerBlock;
  if (blockIdx.x < ray_blocks) {
    const uint32_t slot = blockIdx.x * kRaysPerBlock + threadIdx.x;
    if (slot < rays) intersect_rows<F, kFlatRays>(s, w, nullptr, rays, slot);
    return;
  }
  shadow_queued_lane<Spec>(s, w, shadow_queue, bounce, first, film, false,
                           (blockIdx.x - ray_blocks) * kBlock + threadIdx.x);
}

}  // namespace

void launch_intersect(uint32_t spec, const SceneView& s, const FlatParams& flat,
                      const WavefrontState& w, const uint32_t* queue, const uint32_t* count,
                      bool dynamic_fetch, cudaStream_t stream) {
  const bool walks = (s.features & kFeatureSubsurface) != 0;
  // The flat list's uniform loop ends for all lanes of a warp at once: nothing to refill.
  if (dynamic_fetch && !s.use_flat) {
    TRACER_CUDA_CHECK(cudaMemsetAsync(w.fetch, 0, sizeof(uint32_t), stream));
#define CALL(S)                                                                          \
  intersect_fetch_kernel<S><<<persistent_blocks(intersect_fetch_kernel<S>, w.n), kBlock, 0, \
                              stream>>>(s, w, queue, count, walks)
    switch (spec & (kSpecSpheres | kSpecInstances)) {
      case 0: CALL(0); break;
      case kSpecSpheres: CALL(kSpecSpheres); break;
      default: CALL(kInstancesSpec); break;  // instances imply the rest
    }
#undef CALL
    TRACER_CUDA_CHECK_LAUNCH("intersect_fetch_kernel");
    return;
  }
  if (s.use_flat) {
#define CALL(S, W)                                                                   \
  intersect_flat_kernel<S, W>                                                        \
      <<<(w.n + flat_rays<S>() * kBlock - 1) / (flat_rays<S>() * kBlock), kBlock, 0, stream>>>( \
          s, flat, w, queue, count)
    switch ((spec & kSpecSpheres) | (walks ? 2 : 0)) {
      case 0: CALL(0, false); break;
      case 1: CALL(kSpecSpheres, false); break;
      case 2: CALL(0, true); break;
      default: CALL(kSpecSpheres, true); break;
    }
#undef CALL
    TRACER_CUDA_CHECK_LAUNCH("intersect_flat_kernel");
    return;
  }
#define CALL(S) \
  intersect_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, w, queue, count, walks)
  switch (spec & (kSpecSpheres | kSpecInstances)) {
    case 0: CALL(0); break;
    case kSpecSpheres: CALL(kSpecSpheres); break;
    default: CALL(kInstancesSpec); break;  // instances imply the rest
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("intersect_kernel");
}

void launch_shadow(uint32_t spec, const SceneView& s, const FlatParams& flat,
                   const WavefrontState& w, const uint32_t* queue, const uint32_t* count,
                   const uint32_t* shadow_queue, uint32_t bounce, bool first, FilmView film,
                   cudaStream_t stream) {
  const bool walks = (s.features & kFeatureSubsurface) != 0;
  if (shadow_queue) {
#define CALL(S)                                                                               \
  shadow_queued_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, flat, w, shadow_queue, bounce, \
                                                              first, film, walks)
    switch (spec & (kSpecSpheres | kSpecInstances)) {
      case 0: CALL(0); break;
      case kSpecSpheres: CALL(kSpecSpheres); break;
      default: CALL(kInstancesSpec); break;  // instances imply the rest
    }
#undef CALL
    TRACER_CUDA_CHECK_LAUNCH("shadow_queued_kernel");
    return;
  }
#define CALL(S)                                                 \
  shadow_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, flat, w, queue, count, first, film, \
                                                       walks)
  switch (spec & (kSpecSpheres | kSpecInstances)) {
    case 0: CALL(0); break;
    case kSpecSpheres: CALL(kSpecSpheres); break;
    default: CALL(kInstancesSpec); break;  // instances imply the rest
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("shadow_kernel");
}

void launch_trace(uint32_t spec, const SceneView& s, const FlatParams& flat,
                  const WavefrontState& w, const uint32_t* shadow_queue, uint32_t bounce,
                  bool first, FilmView film, cudaStream_t stream) {
  if (!s.use_flat || !w.rays_at_slots || (s.features & kFeatureSubsurface))
    throw std::logic_error("launch_trace: needs the flat list and rays at their queue slots");
  // Enough blocks for every path of the pool as an extension ray and as a shadow-stage lane.
#define CALL(S)                                                                     \
  trace_kernel<S><<<(w.n + flat_rays<S>() * kBlock - 1) / (flat_rays<S>() * kBlock) + \
                        blocks(w.n),                                                 \
                    kBlock, 0, stream>>>(s, flat, w, shadow_queue, bounce, first, film)
  switch (spec & kSpecSpheres) {
    case 0: CALL(0); break;
    default: CALL(kSpecSpheres); break;
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("trace_kernel");
}

}  // namespace tracer
