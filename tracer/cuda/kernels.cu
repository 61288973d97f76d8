// CUDA kernels: the megakernel (one thread runs a whole path) and the wavefront stages (one
// kernel per stage per bounce over a structure-of-arrays path pool), all built from the shared
// per-path stage functions and specialised at compile time on the scene's features.
#include <cub/device/device_select.cuh>
#include <thrust/iterator/counting_iterator.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "cuda/cuda_check.h"
#include "cuda/kernels.h"
#include "image/display.h"

namespace tracer {
namespace {

constexpr int kBlock = 256;
// Minimum resident blocks per SM asked of the compiler for the megakernel (caps its registers).
#ifndef TRACER_MEGA_MIN_BLOCKS
#define TRACER_MEGA_MIN_BLOCKS 4  // 64 registers: measured fastest on an H200 (PERFORMANCE.md)
#endif
// The flat megakernel: 64 registers for diffuse-only scenes (48 and 80 measured slower), 80 for
// the specular variants (whose shading spills at 64): each the faster on an H200 (PERFORMANCE.md).
#ifndef TRACER_MEGA_FLAT_DIFFUSE_BLOCKS
#define TRACER_MEGA_FLAT_DIFFUSE_BLOCKS 4
#endif
#ifndef TRACER_MEGA_FLAT_SPECULAR_BLOCKS
#define TRACER_MEGA_FLAT_SPECULAR_BLOCKS 3
#endif
#define TRACER_MEGA_FLAT_MIN_BLOCKS(spec) \
  (((spec) & kSpecSpecular) ? TRACER_MEGA_FLAT_SPECULAR_BLOCKS : TRACER_MEGA_FLAT_DIFFUSE_BLOCKS)


// The view with its loops reading the flat list from the kernel's parameters (FlatParams).
__device__ __forceinline__ SceneView with_flat_params(const SceneView& s, const FlatParams& flat) {
  SceneView v = s;
  v.flat_loop = reinterpret_cast<const FlatPrim*>(flat.rows);
  v.flat_solids = reinterpret_cast<const FlatPrim*>(flat.solids);
  return v;
}

__device__ __forceinline__ void add_to_film(FilmView film, uint32_t pixel, vec3 L, bool first,
                                            unsigned long long* nonfinite) {
  if (!is_finite(L)) {  // counted and reported, never added
    atomicAdd(nonfinite, 1ull);
    L = vec3(0.0f);
  }
  float cut;
  L = clamp_radiance(L, film.clamp, &cut);
  if (cut > 0.0f) {  // rare when the clamp is set sensibly: plain atomics
    atomicAdd(film.clamped_luminance, double(cut));
    atomicAdd(film.clamped, 1ull);
  }
  // Each pixel gets one sample per launch from one thread, so the sum needs no atomicity; but an
  // atomic add that returns nothing is sent to memory without waiting, where a read-modify-write
  // stalls the lane on the read (3% of the flat megakernel's stall samples). Launches run in
  // order, so the sums are the same.
  if (first) {
    film.accum[pixel] = make_float4(L.x, L.y, L.z, 0.0f);
  } else {
#if __CUDA_ARCH__ >= 900
    atomicAdd(&film.accum[pixel], make_float4(L.x, L.y, L.z, 0.0f));
#else
    atomicAdd(&film.accum[pixel].x, L.x);
    atomicAdd(&film.accum[pixel].y, L.y);
    atomicAdd(&film.accum[pixel].z, L.z);
#endif
  }
}

// The flags of path id for finish_path: with rays at their slots (never with random walks,
// the only source of the flags it counts) none are kept by id.
__device__ __forceinline__ uint32_t path_flags(const WavefrontState& w, uint32_t id) {
  return w.rays_at_slots ? 0u : __float_as_uint(w.ray_d[id].w) >> 16;
}

// A wavefront path whose sample is complete: its radiance goes to the film, its flags to the
// counters, and its slot is free (alive 0).
__device__ __forceinline__ void finish_path(const WavefrontState& w, uint32_t id, vec3 L,
                                            uint32_t flags, bool first, const FilmView& film) {
  add_to_film(film, id, L, first, &w.counters[1]);
  w.alive[id] = 0;
  if (flags & kPathWalkCapped) atomicAdd(&w.counters[3], 1ull);  // rare: plain atomics
  if (flags & kPathMediumLeak) atomicAdd(&w.counters[4], 1ull);
}

// One atomic per warp for a per-thread count (warp-aggregated over the active lanes).
__device__ __forceinline__ void warp_add(unsigned long long* target, uint32_t value) {
  const unsigned mask = __activemask();
  const uint32_t sum = __reduce_add_sync(mask, value);
  if ((threadIdx.x & 31) == uint32_t(__ffs(mask) - 1)) atomicAdd(target, (unsigned long long)sum);
}

// The next pixel for a lane of `need` (the lanes that want one): one atomic per warp.
__device__ __forceinline__ uint32_t take_pixel(unsigned need, uint32_t* next_pixel) {
  const uint32_t lane = threadIdx.x & 31;
  const int leader = __ffs(need) - 1;
  uint32_t base = 0;
  if (int(lane) == leader) base = atomicAdd(next_pixel, uint32_t(__popc(need)));
  base = __shfl_sync(need, base, leader);
  return base + __popc(need & ((1u << lane) - 1u));
}

// The path's ray (with its pdf, depth and flags) into slot k of the ray arrays o, d.
__device__ __forceinline__ void store_ray(float4* o, float4* d, uint32_t k, const PathState& st) {
  o[k] = make_float4(st.ray.o.x, st.ray.o.y, st.ray.o.z, st.prev_pdf);
  d[k] = make_float4(st.ray.d.x, st.ray.d.y, st.ray.d.z,
                     __uint_as_float(st.depth | (st.flags << 16)));
}

// Throughput and radiance, always at the path's id.
__device__ __forceinline__ void store_path(const WavefrontState& w, uint32_t id,
                                           const PathState& st) {
  w.throughput[id] = make_float4(st.throughput.x, st.throughput.y, st.throughput.z,
                                 __uint_as_float(st.medium));
  w.radiance[id] = make_float4(st.radiance.x, st.radiance.y, st.radiance.z,
                               __uint_as_float(st.walk_steps));
}

__device__ __forceinline__ void store_state(const WavefrontState& w, uint32_t id,
                                            const PathState& st) {
  store_ray(w.ray_o, w.ray_d, id, st);
  store_path(w, id, st);
}

// The hit stored at index i of w.hit (its queue slot with rays_at_slots, else its path's id).
__device__ __forceinline__ Hit load_hit(const WavefrontState& w, uint32_t i) {
  const float4 h4 = w.hit[i];
  Hit hit;
  hit.t = h4.x;
  hit.prim = __float_as_uint(h4.y);
  hit.u = h4.z;
  hit.v = h4.w;
  return hit;
}

// Path id's state; its ray at index ri of the ray arrays (its queue slot with rays_at_slots,
// else its id).
__device__ __forceinline__ PathState load_state(const WavefrontState& w, uint32_t id, uint32_t ri,
                                                uint32_t sample) {
  PathState st;
  const float4 o = w.ray_o[ri], d = w.ray_d[ri], t = w.throughput[id], r = w.radiance[id];
  st.ray.o = vec3(o.x, o.y, o.z);
  st.ray.d = vec3(d.x, d.y, d.z);
  st.ray.tmax = kInfinity;
  st.ray.pad = 0.0f;
  st.prev_pdf = o.w;
  const uint32_t bits = __float_as_uint(d.w);
  st.depth = bits & 0xffffu;
  st.flags = bits >> 16;
  st.throughput = vec3(t.x, t.y, t.z);
  st.radiance = vec3(r.x, r.y, r.z);
  st.pixel = id;
  st.sample = sample;
  st.medium = __float_as_uint(t.w);
  st.walk_steps = __float_as_uint(r.w);
  st.origin_prim = kInvalid;  // set by shade_path when it spawns the next ray
  return st;
}

// Where a megakernel's threads take their paths: new camera paths, one per pixel (FromQueue
// false), or the paths of a wavefront queue, whose state the stages left in the pool (the
// wavefront's tail: the last bounces of its few remaining paths in one launch).
struct TailSource {
  WavefrontState w;
  const uint32_t* queue = nullptr;
  const uint32_t* count = nullptr;
  // The first bounce's rays were traced by the stages (a fused trace stage): each path's hit is
  // at its queue slot in w.hit, and its first pass only shades (megakernel_flat only).
  bool hits_ready = false;
};

template <bool FromQueue>
__device__ __forceinline__ uint32_t path_count(const FilmView& film, const TailSource& src) {
  return FromQueue ? *src.count : film.n;
}

// Path k of the launch (k < path_count) into st.
template <uint32_t F, bool FromQueue>
__device__ __forceinline__ void start_path(const SceneView& s, const IntegratorSettings& cfg,
                                           uint32_t k, uint32_t sample, const TailSource& src,
                                           PathState& st) {
  if (!FromQueue) {
    generate_path<F>(s, cfg, k, sample, st);
    return;
  }
  const uint32_t id = src.queue[k];
  st = load_state(src.w, id, src.w.rays_at_slots ? k : id, sample);
  // As extension_ray: with random walks the ray skips the triangle it leaves from. (With rays at
  // their slots the pool keeps no hit by id; the scene then has no random walks, and the stages'
  // rays skip no triangle either. The specular kernels compile the walks' code for such scenes.)
  if ((F & kFeatureSubsurface) && !src.w.rays_at_slots) {
    const uint32_t prim = __float_as_uint(src.w.hit[id].y);
    st.origin_prim = prim < s.tri_count ? prim : kInvalid;
  }
}

// Persistent megakernel with path regeneration: each thread runs whole paths, and a thread
// whose path ends takes the next pixel from a global counter (one atomic per warp), so warps stay
// full while path lengths differ (Aila & Laine 2009's persistent threads, Novak et al. 2010's
// path regeneration). Every pixel gets exactly one sample per launch.
template <uint32_t Spec, bool FromQueue>
__global__ void __launch_bounds__(kBlock, TRACER_MEGA_MIN_BLOCKS) megakernel(SceneView s, IntegratorSettings cfg,
                                                     uint32_t sample, bool first, FilmView film,
                                                     unsigned long long* counters,
                                                     uint32_t* next_pixel, TailSource src) {
  constexpr uint32_t F = features_of<Spec>();
  const uint32_t paths = path_count<FromQueue>(film, src);
  PathState st;
  bool alive = false;
  uint32_t segments = 0, shadows = 0;
  for (;;) {
    const unsigned active = __activemask();
    const unsigned need = __ballot_sync(active, !alive);
    if (!alive) {
      const uint32_t k = take_pixel(need, next_pixel);
      if (k >= paths) break;
      start_path<F, FromQueue>(s, cfg, k, sample, src, st);
      alive = true;
    }
    const Hit hit = intersect_closest<F>(s, st.ray, st.origin_prim);
    ++segments;
    ShadowRequest sr;
    const bool go_on = shade_path<F>(s, cfg, st, hit, sr);
    if (sr.valid) {
      ++shadows;
      if (!intersect_any<F>(s, sr.ray, sr.target_prim, sr.origin_prim))
        st.radiance += sr.contribution;
    }
    if (!go_on) {
      add_to_film(film, st.pixel, st.radiance, first, &counters[1]);
      if (st.flags & kPathWalkCapped) atomicAdd(&counters[3], 1ull);  // rare: plain atomics
      if (st.flags & kPathMediumLeak) atomicAdd(&counters[4], 1ull);
      alive = false;
    }
  }
  // The tail's segments are all extension rays, as the wavefront counts them (counters[6]).
  warp_add(&counters[FromQueue ? 6 : 2], segments);
  warp_add(&counters[0], shadows);
}

// The megakernel for scenes with a flat primitive list (bvh/flat_list.h). Each lane's shadow
// ray is traced together with the next extension ray of its path, in one pass over the list
// (flat_closest_and_any): the loads and the loop are paid once, and no loop runs for only the
// lanes that have a shadow ray (which left half the lanes idle in the separate shadow query). A
// lane whose path ended with a shadow ray in flight keeps that path's pixel and radiance until
// the next pass, already tracing its new path's camera ray in it.
template <uint32_t Spec, bool FromQueue>
__global__ void __launch_bounds__(kBlock, TRACER_MEGA_FLAT_MIN_BLOCKS(Spec))
    megakernel_flat(SceneView view, const __grid_constant__ FlatParams flat,
                    IntegratorSettings cfg, uint32_t sample, bool first, FilmView film,
                    unsigned long long* counters, uint32_t* next_pixel, TailSource src) {
  constexpr uint32_t F = features_of<Spec>();
  const SceneView s = with_flat_params(view, flat);
  const uint32_t paths = path_count<FromQueue>(film, src);
  PathState st;
  ShadowRequest sr;
  sr.valid = false;
  st.ray.o = sr.ray.o = vec3(0.0f);
  st.ray.d = sr.ray.d = vec3(0.0f, 0.0f, 1.0f);
  st.origin_prim = sr.target_prim = sr.origin_prim = kInvalid;
  bool alive = false, exhausted = false;
  uint32_t done_pixel = kInvalid;  // a finished path whose shadow ray is in flight
  vec3 done_L(0.0f);
  uint32_t segments = 0, shadows = 0;
  // The tail after a fused trace stage: the queue slot whose hit the stages traced for the
  // lane's new path (kInvalid: none), taken instead of tracing its first ray.
  uint32_t ready = kInvalid;
  for (;;) {
    const unsigned active = __activemask();
    const bool want = !alive && !exhausted;
    const unsigned need = __ballot_sync(active, want);
    if (want) {
      const uint32_t k = take_pixel(need, next_pixel);
      if (k < paths) {
        start_path<F, FromQueue>(s, cfg, k, sample, src, st);
        alive = true;
        if (FromQueue && src.hits_ready) ready = k;
      } else {
        exhausted = true;
      }
    }
    if (!alive && !sr.valid) break;
    // A lane without a ray of one kind passes a copy with tmax = 0, which nothing hits. (Copies,
    // not a choice between references: a reference to either of two structs would put both in
    // local memory.)
    Ray ext = st.ray, sh = sr.ray;
    ext.tmax = alive && (!FromQueue || ready == kInvalid) ? ext.tmax : 0.0f;
    sh.tmax = sr.valid ? sh.tmax : 0.0f;
    bool blocked = true;
    Hit hit;
    // (A tail's first pass, whose lanes all start from traced hits, has no ray to trace.)
    if (!FromQueue || !src.hits_ready || __any_sync(__activemask(), ext.tmax > 0.0f || sr.valid))
      hit = flat_closest_and_any<F>(s, ext, st.origin_prim, sh, sr.target_prim, sr.origin_prim,
                                    blocked);
    if (FromQueue && ready != kInvalid) {
      hit = load_hit(src.w, ready);
      ready = kInvalid;
    }
    if (sr.valid) {
      ++shadows;
      if (!blocked) {
        if (done_pixel != kInvalid) done_L += sr.contribution;
        else st.radiance += sr.contribution;
      }
      sr.valid = false;
    }
    if (done_pixel != kInvalid) {
      add_to_film(film, done_pixel, done_L, first, &counters[1]);
      done_pixel = kInvalid;
    }
    if (!alive) continue;
    ++segments;
    const bool go_on = shade_path<F>(s, cfg, st, hit, sr);
    if (!go_on) {
      if (st.flags & kPathWalkCapped) atomicAdd(&counters[3], 1ull);  // rare: plain atomics
      if (st.flags & kPathMediumLeak) atomicAdd(&counters[4], 1ull);
      if (sr.valid) {
        done_pixel = st.pixel;
        done_L = st.radiance;
      } else {
        add_to_film(film, st.pixel, st.radiance, first, &counters[1]);
      }
      alive = false;
    }
  }
  warp_add(&counters[FromQueue ? 6 : 2], segments);
  warp_add(&counters[0], shadows);
}

// The path a queue slot refers to, or kInvalid when the slot is empty or the path is done. A
// queue (either compaction) holds only paths with alive == 1, so only the pass over every path
// reads the flag: for a queued path it would be one more dependent load before the state's.
__device__ __forceinline__ uint32_t queued_path(const WavefrontState& w, const uint32_t* queue,
                                                uint32_t i, uint32_t total) {
  if (i >= total) return kInvalid;
  if (queue) return queue[i];
  return w.alive[i] == 1 ? i : kInvalid;
}

__device__ __forceinline__ uint32_t queue_total(const WavefrontState& w, const uint32_t* queue,
                                                const uint32_t* count) {
  return queue ? *count : w.n;
}

template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) generate_kernel(SceneView s, IntegratorSettings cfg,
                                                          uint32_t sample, WavefrontState w,
                                                          bool walks) {
  const uint32_t id = blockIdx.x * blockDim.x + threadIdx.x;
  if (id >= w.n) return;
  PathState st;
  generate_path<features_of<Spec>()>(s, cfg, id, sample, st);
  store_state(w, id, st);
  w.alive[id] = 1;
  if (walks) w.hit[id].y = __uint_as_float(kInvalid);  // camera rays leave from no surface
}

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
  *skip = origin < s.tri_count ? origin : kInvalid;
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
// without spheres, 2 (40) with them, where 4 took 84 registers and ran slower (PERFORMANCE.md).
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

// Lanes of the dynamic-fetch kernel refill in batches of 8: measured on an H100 as fast as 16
// and ahead of one thread per ray by 31-34% on the bunny box's bounce rays (PERFORMANCE.md).
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
  TraversalCursor c = traversal_start(s);
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
          if (queue || w.alive[id] == 1) {  // a finished path takes another one next round
            ray = extension_ray(s, w, id, walks, &skip);
            inv_d = 1.0f / ray.d;
            setup = RayTriSetup(ray, inv_d);
            tmax = ray.tmax;
            hit = Hit();
            c = traversal_start(s);
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

// A shadow ray into slot k of the shadow arrays (the path's id, or its shadow queue slot).
__device__ __forceinline__ void store_shadow_ray(const WavefrontState& w, uint32_t k,
                                                 const ShadowRequest& sr) {
  w.shadow_o[k] = make_float4(sr.ray.o.x, sr.ray.o.y, sr.ray.o.z, sr.ray.tmax);
  w.shadow_d[k] = make_float4(sr.ray.d.x, sr.ray.d.y, sr.ray.d.z, __uint_as_float(sr.target_prim));
  w.shadow_c[k] = make_float4(sr.contribution.x, sr.contribution.y, sr.contribution.z, 1.0f);
}

// Shades the queued paths; with next_queue (compaction in the shade kernel) each block appends
// its paths that go on to the next bounce's queue, in slot order, with one atomic on the next
// bounce's path count (alive_counts[bounce + 1]). One atomic per warp that waits for its result
// cost 20 us per bounce where nearly every path goes on (the closed box: 65,000 atomics on one
// address); the block's 8 warp counts are summed in shared memory first. With shadow_queue the
// block appends its paths that have a shadow ray to it the same way (shadow_counts[bounce]), so
// that the shadow stage traces full warps of rays instead of every path of the bounce (in the
// open box 63% of them have none), and stores the rays at their slots (shadow_o/d/c[slot]),
// where the stage reads them in whole sectors instead of scattered over the pool; the paths that end without a shadow ray go to the queue's
// far end (slot n - 1 - k, counted on finish_counts[bounce]), where the shadow stage's last
// warps add them to the film. (Adding them here instead cost the shade kernel 40-80% more on
// bounces where many paths end: its film reductions stalled its loads and its barrier.)
template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) shade_kernel(SceneView s, IntegratorSettings cfg,
                                                       uint32_t sample, uint32_t bounce,
                                                       WavefrontState w, const uint32_t* queue,
                                                       const uint32_t* count,
                                                       uint32_t* next_queue,
                                                       uint32_t* shadow_queue) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  const uint32_t id = queued_path(w, queue, i, queue_total(w, queue, count));
  const uint32_t ri = w.rays_at_slots ? i : id;  // where its ray and hit are
  bool go_on = false, shadow_valid = false;
  ShadowRequest sr;
  PathState st;
  if (id != kInvalid) {
    st = load_state(w, id, ri, sample);
    const Hit hit = load_hit(w, ri);
    go_on = shade_path<features_of<Spec>()>(s, cfg, st, hit, sr);
    store_path(w, id, st);
    // With rays at their slots the next ray goes to its slot in the next queue, below.
    if (!w.rays_at_slots) store_ray(w.next_ray_o, w.next_ray_d, id, st);
    // A medium scatter continues from no surface; a surface bounce leaves from the triangle that
    // hit[id] already names, which the next intersect and this bounce's shadow ray skip.
    // (With rays at their slots hit[] is indexed by slot and read by no later stage.)
    if ((features_of<Spec>() & kFeatureSubsurface) && !w.rays_at_slots && go_on &&
        st.origin_prim == kInvalid)
      w.hit[id].y = __uint_as_float(kInvalid);
    shadow_valid = sr.valid;
    // With a shadow queue the ray is stored at its queue slot, below.
    if (sr.valid && !shadow_queue) {
      store_shadow_ray(w, id, sr);
    } else if (!shadow_queue) {
      w.shadow_c[id].w = 0.0f;
    }
    w.alive[id] = go_on ? 1 : 2;
  }
  // Warp-aggregated statistics: shadow rays traced and paths entering the next bounce.
  const unsigned ballot_shadow = __ballot_sync(0xffffffffu, shadow_valid);
  const unsigned ballot_alive = __ballot_sync(0xffffffffu, go_on);
  // Paths that end without a shadow ray (only counted with a shadow queue).
  const bool finish = id != kInvalid && !go_on && !shadow_valid;
  const unsigned ballot_finish = __ballot_sync(0xffffffffu, finish);
  const uint32_t lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  if (lane == 0 && ballot_shadow)
    atomicAdd(&w.counters[0], (unsigned long long)__popc(ballot_shadow));
  uint32_t* next_count = &w.alive_counts[bounce + 1];
  if (!next_queue && !shadow_queue) {
    if (lane == 0 && ballot_alive) atomicAdd(next_count, uint32_t(__popc(ballot_alive)));
    return;
  }
  // [k]: where warp k's paths go in the block's share; [kBlock / 32]: the block's start.
  constexpr int kWarps = kBlock / 32;
  __shared__ uint32_t warp_start[kWarps + 1], shadow_start[kWarps + 1], finish_start[kWarps + 1];
  if (lane == 0) {
    warp_start[warp] = __popc(ballot_alive);
    shadow_start[warp] = __popc(ballot_shadow);
    finish_start[warp] = __popc(ballot_finish);
  }
  __syncthreads();
  if (threadIdx.x == 0) {
    uint32_t sum = 0, shadows = 0, finished = 0;
    for (int k = 0; k < kWarps; ++k) {
      const uint32_t c = warp_start[k], cs = shadow_start[k], cf = finish_start[k];
      warp_start[k] = sum;
      shadow_start[k] = shadows;
      finish_start[k] = finished;
      sum += c;
      shadows += cs;
      finished += cf;
    }
    if (next_queue) {
      warp_start[kWarps] = sum ? atomicAdd(next_count, sum) : 0;
    } else if (sum) {
      atomicAdd(next_count, sum);
    }
    if (shadow_queue) {
      shadow_start[kWarps] = shadows ? atomicAdd(&w.shadow_counts[bounce], shadows) : 0;
      finish_start[kWarps] = finished ? atomicAdd(&w.finish_counts[bounce], finished) : 0;
    }
  }
  __syncthreads();
  const unsigned below = (1u << lane) - 1u;
  if (next_queue && go_on) {
    const uint32_t slot = warp_start[kWarps] + warp_start[warp] + __popc(ballot_alive & below);
    next_queue[slot] = id;
    if (w.rays_at_slots) store_ray(w.next_ray_o, w.next_ray_d, slot, st);  // whole sectors
  }
  if (shadow_queue && shadow_valid) {
    const uint32_t slot = shadow_start[kWarps] + shadow_start[warp] + __popc(ballot_shadow & below);
    shadow_queue[slot] = id;
    store_shadow_ray(w, slot, sr);  // consecutive slots: whole sectors, read so by the stage
  }
  if (shadow_queue && finish)
    shadow_queue[w.n - 1 - (finish_start[kWarps] + finish_start[warp] +
                            __popc(ballot_finish & below))] = id;
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
      s, ray, __float_as_uint(d.w), origin < s.tri_count ? origin : kInvalid);
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
  if (state == 0) return;
  const float4 c = w.shadow_c[id];
  float4 r = w.radiance[id];
  if (c.w != 0.0f) {
    if (shadow_reaches<Spec>(s, w, id, w.shadow_o[id], w.shadow_d[id], walks)) {
      r.x += c.x;
      r.y += c.y;
      r.z += c.z;
      if (state == 1) w.radiance[id] = r;
    }
  }
  if (state == 2)  // the path ended in this bounce: its sample is complete
    finish_path(w, id, vec3(r.x, r.y, r.z), path_flags(w, id), first, film);
}

// The shadow stage over the shadow queue the shade kernel wrote: every lane of the first
// shadow_counts[b] has a ray, and with no choice to make first, the ray, its contribution, the
// path's radiance and state are read at once, one dependent step after the queue slot (the pass
// above waits for the state, then the contribution, then the ray). The lanes after them finish
// the paths that ended without a shadow ray (finish_counts[b], from the queue's far end).
// Minimum resident blocks per SM asked of the compiler for the queued shadow stage: none (59
// registers, 4 blocks); 5 (48 registers) and 6 (40) were 0-3% and 2-6% slower, and even an
// explicit 1 changes the sphere variant's code and cost smallpt 1.5% (PERFORMANCE.md).
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
    if (state == 1) w.radiance[id] = r;
  }
  if (state == 2)
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
// that all wait for memory, then all compute, then all store; its time is about 11 us + 13 us
// per million rays (PERFORMANCE.md). One grid holds both stages' blocks, so that the shadow
// rays' loads overlap the extension rays' arithmetic, and one launch, fill and drain is saved.
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

// The sample's extension rays, the paths that entered a bounce after the first (alive_counts[1..
// count)), added to *total by one warp: summed on the device, so that samples can run back to
// back without the host reading the counts after each.
__global__ void add_alive_kernel(const uint32_t* alive_counts, uint32_t count,
                                 unsigned long long* total) {
  unsigned long long sum = 0;
  for (uint32_t i = 1 + threadIdx.x; i < count; i += 32) sum += alive_counts[i];
  for (int d = 16; d > 0; d /= 2) sum += __shfl_down_sync(0xffffffffu, sum, d);
  if (threadIdx.x == 0) atomicAdd(total, sum);
}

// Paths still alive when the wavefront's iteration limit is reached (only random walks can get
// there): their samples end now, are added to the film, and are counted as capped walks.
__global__ void flush_kernel(WavefrontState w, bool first, FilmView film) {
  const uint32_t id = blockIdx.x * blockDim.x + threadIdx.x;
  if (id >= w.n || w.alive[id] == 0) return;
  const float4 r = w.radiance[id];
  add_to_film(film, id, vec3(r.x, r.y, r.z), first, &w.counters[1]);
  w.alive[id] = 0;
  atomicAdd(&w.counters[3], 1ull);
}

__global__ void sort_keys_kernel(SceneView s, WavefrontState w, const uint32_t* queue,
                                 const uint32_t* count) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= (queue ? *count : w.n)) return;
  const uint32_t id = queue ? queue[i] : i;
  uint32_t key = 7;  // dead paths last
  if (w.alive[id] == 1) {
    const uint32_t prim = __float_as_uint(w.hit[id].y);
    if (prim == kInvalid) {
      key = 6;  // escaped
    } else {
      const uint32_t mat = prim < s.tri_count ? s.tri_shading[prim].material
                                              : s.spheres[prim - s.tri_count].material;
      key = uint32_t(s.materials[mat].type);
    }
  }
  w.sort_keys[i] = key;
  // Warp-aggregated histogram: one atomic per distinct key in the warp.
  const unsigned peers = __match_any_sync(__activemask(), key);
  if ((threadIdx.x & 31) == __ffs(peers) - 1) atomicAdd(&w.sort_bins[key], __popc(peers));
}

__global__ void sort_scatter_kernel(WavefrontState w, const uint32_t* queue, const uint32_t* count,
                                    uint32_t* sorted) {
  __shared__ uint32_t offsets[8];
  if (threadIdx.x == 0) {
    // Each block needs the exclusive prefix of the bins; bins[8..15] hold running cursors.
    uint32_t acc = 0;
    for (int k = 0; k < 8; ++k) {
      offsets[k] = acc;
      acc += w.sort_bins[k];
    }
    // The live paths (keys 0-6) come first: the stages after the sort take only them, so that
    // a queue never holds a dead path (queued_path reads no alive flag).
    if (blockIdx.x == 0) w.sort_bins[16] = offsets[7];
  }
  __syncthreads();
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= (queue ? *count : w.n)) return;
  const uint32_t id = queue ? queue[i] : i;
  const uint32_t key = w.sort_keys[i];
  const unsigned peers = __match_any_sync(__activemask(), key);
  const int leader = __ffs(peers) - 1;
  uint32_t base = 0;
  if ((threadIdx.x & 31) == leader) base = atomicAdd(&w.sort_bins[8 + key], __popc(peers));
  base = __shfl_sync(peers, base, leader);
  const uint32_t rank = __popc(peers & ((1u << (threadIdx.x & 31)) - 1));
  sorted[offsets[key] + base + rank] = id;
}

struct IsAlive {
  const uint8_t* alive;
  __host__ __device__ bool operator()(uint32_t id) const { return alive[id] == 1; }
};

__global__ void resolve_kernel(const float4* a, float wa, const float4* b, float wb, uint32_t n,
                               float* rgb) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const float4 x = a[i], y = b[i];
  rgb[3 * i + 0] = x.x * wa + y.x * wb;
  rgb[3 * i + 1] = x.y * wa + y.y * wb;
  rgb[3 * i + 2] = x.z * wa + y.z * wb;
}

__global__ void display_kernel(const float4* a, const float4* b, float inv, uint32_t n,
                               float exposure_scale, int op, uint32_t* rgba) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const float4 x = a[i], y = b[i];
  const vec3 mean = vec3(x.x + y.x, x.y + y.y, x.z + y.z) * inv;
  rgba[i] = display_rgba8(mean, exposure_scale, ToneMap(op));
}

__global__ void copy_kernel(const float4* from, float4* to, uint32_t n) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) to[i] = from[i];
}

uint32_t blocks(uint32_t n) { return (n + kBlock - 1) / kBlock; }

}  // namespace



// Runs F<Spec> for the runtime value spec; only the bits in `relevant` select a variant, so a
// kernel that ignores a feature is compiled once for it.
#define TRACER_SPEC_SWITCH(spec, relevant, CALL)            \
  switch ((spec) & (relevant)) {                            \
    case 0: CALL(0); break;                                 \
    case 1: CALL(1); break;                                 \
    case 2: CALL(2); break;                                 \
    case 3: CALL(3); break;                                 \
    case 4: CALL(4); break;                                 \
    case 5: CALL(5); break;                                 \
    case 6: CALL(6); break;                                 \
    default: CALL(7); break;                                \
  }

// Enough resident blocks to fill every multiprocessor once (persistent threads).
template <typename Kernel>
uint32_t persistent_blocks(Kernel kernel, uint32_t n) {
  static int sms = 0;
  if (sms == 0) {
    int dev = 0;
    TRACER_CUDA_CHECK(cudaGetDevice(&dev));
    TRACER_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev));
  }
  int per_sm = 0;
  TRACER_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kernel, kBlock, 0));
  return std::min<uint32_t>(uint32_t(std::max(1, per_sm) * sms), blocks(n));
}

FlatParams make_flat_params(const std::vector<FlatPrim>& prims,
                            const std::vector<FlatPrim>& solids) {
  FlatParams p;
  if (prims.size() > kFlatMaxCost)
    throw std::runtime_error("flat list of " + std::to_string(prims.size()) + " entries, more than " +
                             std::to_string(kFlatMaxCost));
  if (solids.size() > kFlatMaxSolids)
    throw std::runtime_error("flat list of " + std::to_string(solids.size()) +
                             " solid boxes, more than " + std::to_string(kFlatMaxSolids));
  auto put = [](float4* rows, size_t i, const FlatPrim& f) {
    rows[3 * i + 0] = make_float4(f.row_u.x, f.row_u.y, f.row_u.z, f.row_u.w);
    rows[3 * i + 1] = make_float4(f.row_v.x, f.row_v.y, f.row_v.z, f.row_v.w);
    rows[3 * i + 2] = make_float4(f.row_w.x, f.row_w.y, f.row_w.z, f.row_w.w);
  };
  for (size_t i = 0; i < prims.size(); ++i) put(p.rows, i, prims[i]);
  for (size_t i = 0; i < solids.size(); ++i) put(p.solids, i, solids[i]);
  p.count = uint32_t(prims.size());
  return p;
}

// The megakernels from pixels (queue == nullptr) or from a wavefront queue (the tail).
template <bool FromQueue>
void launch_mega(uint32_t spec, const SceneView& s, const FlatParams& flat,
                 const IntegratorSettings& cfg, uint32_t sample, bool first, FilmView film,
                 unsigned long long* counters, uint32_t* next_pixel, const TailSource& src,
                 cudaStream_t stream) {
  TRACER_CUDA_CHECK(cudaMemsetAsync(next_pixel, 0, sizeof(uint32_t), stream));
  if (s.use_flat) {
#define CALL(S)                                                                       \
  megakernel_flat<S, FromQueue>                                                       \
      <<<persistent_blocks(megakernel_flat<S, FromQueue>, film.n), kBlock, 0, stream>>>( \
          s, flat, cfg, sample, first, film, counters, next_pixel, src)
    TRACER_SPEC_SWITCH(spec, 7u, CALL)
#undef CALL
    if (FromQueue) TRACER_CUDA_CHECK_LAUNCH("megakernel_flat (tail)");
    else TRACER_CUDA_CHECK_LAUNCH("megakernel_flat");
    return;
  }
#define CALL(S)                                                                            \
  megakernel<S, FromQueue><<<persistent_blocks(megakernel<S, FromQueue>, film.n), kBlock, 0, \
                             stream>>>(s, cfg, sample, first, film, counters, next_pixel, src)
  TRACER_SPEC_SWITCH(spec, 7u, CALL)
#undef CALL
  if (FromQueue) TRACER_CUDA_CHECK_LAUNCH("megakernel (tail)");
  else TRACER_CUDA_CHECK_LAUNCH("megakernel");
}

void launch_megakernel(uint32_t spec, const SceneView& s, const FlatParams& flat,
                       const IntegratorSettings& cfg, uint32_t sample, bool first, FilmView film,
                       unsigned long long* counters, uint32_t* next_pixel, cudaStream_t stream) {
  launch_mega<false>(spec, s, flat, cfg, sample, first, film, counters, next_pixel, TailSource(),
                     stream);
}

void launch_tail(uint32_t spec, const SceneView& s, const FlatParams& flat,
                 const IntegratorSettings& cfg, uint32_t sample, bool first, FilmView film,
                 const WavefrontState& w, const uint32_t* queue, const uint32_t* count,
                 bool hits_ready, cudaStream_t stream) {
  if (hits_ready && (!s.use_flat || !w.rays_at_slots))
    throw std::logic_error("launch_tail: traced hits need the flat list and rays at their slots");
  TailSource src;
  src.w = w;
  src.queue = queue;
  src.count = count;
  src.hits_ready = hits_ready;
  launch_mega<true>(spec, s, flat, cfg, sample, first, film, w.counters, w.fetch, src, stream);
}

void launch_generate(uint32_t spec, const SceneView& s, const IntegratorSettings& cfg,
                     uint32_t sample, const WavefrontState& w, cudaStream_t stream) {
#define CALL(S)                                                    \
  generate_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, cfg, sample, w, \
                                                         (s.features & kFeatureSubsurface) != 0)
  switch (spec & kSpecDepthOfField) {
    case 0: CALL(0); break;
    default: CALL(kSpecDepthOfField); break;
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("generate_kernel");
}

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
    switch (spec & kSpecSpheres) {
      case 0: CALL(0); break;
      default: CALL(kSpecSpheres); break;
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
  switch (spec & kSpecSpheres) {
    case 0: CALL(0); break;
    default: CALL(kSpecSpheres); break;
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("intersect_kernel");
}

void launch_shade(uint32_t spec, const SceneView& s, const IntegratorSettings& cfg,
                  uint32_t sample, uint32_t bounce, const WavefrontState& w,
                  const uint32_t* queue, const uint32_t* count, uint32_t* next_queue,
                  uint32_t* shadow_queue, cudaStream_t stream) {
  // The block's 108 bytes of shared memory (compaction) must not take L1 from the shading's
  // scene reads: asked for the smallest carveout, once per variant.
  static bool carveout_set[8] = {};
#define CALL(S)                                                                           \
  if (!carveout_set[S]) {                                                                 \
    TRACER_CUDA_CHECK(cudaFuncSetAttribute(shade_kernel<S>,                               \
                                           cudaFuncAttributePreferredSharedMemoryCarveout, \
                                           int(cudaSharedmemCarveoutMaxL1)));             \
    carveout_set[S] = true;                                                               \
  }                                                                                       \
  shade_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, cfg, sample, bounce, w, queue, count, \
                                                      next_queue, shadow_queue)
  switch (spec & (kSpecSpheres | kSpecSpecular)) {
    case 0: CALL(0); break;
    case kSpecSpheres: CALL(kSpecSpheres); break;
    case kSpecSpecular: CALL(kSpecSpecular); break;
    default: CALL(kSpecSpheres | kSpecSpecular); break;
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("shade_kernel");
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
    switch (spec & kSpecSpheres) {
      case 0: CALL(0); break;
      default: CALL(kSpecSpheres); break;
    }
#undef CALL
    TRACER_CUDA_CHECK_LAUNCH("shadow_queued_kernel");
    return;
  }
#define CALL(S)                                                 \
  shadow_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, flat, w, queue, count, first, film, \
                                                       walks)
  switch (spec & kSpecSpheres) {
    case 0: CALL(0); break;
    default: CALL(kSpecSpheres); break;
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

void launch_sort_by_material(const SceneView& s, const WavefrontState& w, const uint32_t* queue,
                             const uint32_t* count, uint32_t* sorted, cudaStream_t stream) {
  TRACER_CUDA_CHECK(cudaMemsetAsync(w.sort_bins, 0, 17 * sizeof(uint32_t), stream));
  sort_keys_kernel<<<blocks(w.n), kBlock, 0, stream>>>(s, w, queue, count);
  TRACER_CUDA_CHECK_LAUNCH("sort_keys_kernel");
  sort_scatter_kernel<<<blocks(w.n), kBlock, 0, stream>>>(w, queue, count, sorted);
  TRACER_CUDA_CHECK_LAUNCH("sort_scatter_kernel");
}

size_t compaction_temp_bytes(uint32_t n) {
  size_t bytes = 0;
  TRACER_CUDA_CHECK(cub::DeviceSelect::If(nullptr, bytes, thrust::counting_iterator<uint32_t>(0),
                                          (uint32_t*)nullptr, (uint32_t*)nullptr, n,
                                          IsAlive{nullptr}));
  return bytes;
}

void launch_compact(const WavefrontState& w, uint32_t* out_queue, uint32_t* out_count,
                    void* temp, size_t temp_bytes, cudaStream_t stream) {
  TRACER_CUDA_CHECK(cub::DeviceSelect::If(temp, temp_bytes, thrust::counting_iterator<uint32_t>(0),
                                          out_queue, out_count, w.n, IsAlive{w.alive}, stream));
}

void launch_flush(const WavefrontState& w, bool first, FilmView film, cudaStream_t stream) {
  flush_kernel<<<blocks(w.n), kBlock, 0, stream>>>(w, first, film);
  TRACER_CUDA_CHECK_LAUNCH("flush_kernel");
}

void launch_add_alive(const uint32_t* alive_counts, uint32_t count, unsigned long long* total,
                      cudaStream_t stream) {
  add_alive_kernel<<<1, 32, 0, stream>>>(alive_counts, count, total);
  TRACER_CUDA_CHECK_LAUNCH("add_alive_kernel");
}

void launch_copy_hits(const float4* from, float4* to, uint32_t n, cudaStream_t stream) {
  copy_kernel<<<blocks(n), kBlock, 0, stream>>>(from, to, n);
  TRACER_CUDA_CHECK_LAUNCH("copy_kernel");
}

void launch_resolve(const float4* a, float wa, const float4* b, float wb, uint32_t n,
                    float* rgb_out, cudaStream_t stream) {
  resolve_kernel<<<blocks(n), kBlock, 0, stream>>>(a, wa, b, wb, n, rgb_out);
  TRACER_CUDA_CHECK_LAUNCH("resolve_kernel");
}

void launch_display(const float4* a, const float4* b, float inv_samples, uint32_t n,
                    float exposure_scale, int tone_map, uint32_t* rgba, cudaStream_t stream) {
  display_kernel<<<blocks(n), kBlock, 0, stream>>>(a, b, inv_samples, n, exposure_scale,
                                                   tone_map, rgba);
  TRACER_CUDA_CHECK_LAUNCH("display_kernel");
}

}  // namespace tracer
