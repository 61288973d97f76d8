// Device helpers shared by the CUDA kernels' files (megakernel.cu, wavefront_trace.cu,
// wavefront_shade.cu, film.cu): film sums, the path pool's loads and stores, queue slots,
// warp-aggregated atomics; and the launchers' helpers (grids, dispatch on the specialisation).
#pragma once

#include <algorithm>

#include "cuda/cuda_check.h"
#include "cuda/kernels.h"

namespace tracer {

constexpr int kBlock = 256;

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
  // stalls the lane on the read. Launches run in
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
  return w.rays_at_slots ? 0u : (__float_as_uint(w.ray_d[id].w) >> 10) & 0x3ffu;
}

// A wavefront path whose sample is complete: its radiance goes to the film, its flags to the
// counters, and its slot is free (kStatusDone).
__device__ __forceinline__ void finish_path(const WavefrontState& w, uint32_t id, vec3 L,
                                            uint32_t flags, bool first, const FilmView& film) {
  add_to_film(film, id, L, first, &w.counters[kCounterNonfinite]);
  w.alive[id] = kStatusDone;
  // Rare: plain atomics.
  if (flags & kPathWalkCapped) atomicAdd(&w.counters[kCounterWalkCapped], 1ull);
  if (flags & kPathMediumLeak) atomicAdd(&w.counters[kCounterMediumLeak], 1ull);
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

// The path's ray (with its pdf, depth, flags and previous normal) into slot k of the ray
// arrays o, d: depth - 1 in bits 0-9 (a stored ray's depth is 1 to render.max_depth, at most
// 1024), flags in 10-19, prev_normal's 12 bits in 20-31.
__device__ __forceinline__ void store_ray(float4* o, float4* d, uint32_t k, const PathState& st) {
  o[k] = make_float4(st.ray.o.x, st.ray.o.y, st.ray.o.z, st.prev_pdf);
  d[k] = make_float4(st.ray.d.x, st.ray.d.y, st.ray.d.z,
                     __uint_as_float((st.depth - 1u) | (st.flags << 10) | (st.prev_normal << 20)));
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
  st.depth = (bits & 0x3ffu) + 1u;
  st.flags = (bits >> 10) & 0x3ffu;
  st.prev_normal = bits >> 20;
  st.throughput = vec3(t.x, t.y, t.z);
  st.radiance = vec3(r.x, r.y, r.z);
  st.pixel = id;
  st.sample = sample;
  st.medium = __float_as_uint(t.w);
  st.walk_steps = __float_as_uint(r.w);
  st.origin_prim = kInvalid;  // set by shade_path when it spawns the next ray
  return st;
}

// The path a queue slot refers to, or kInvalid when the slot is empty or the path is done. A
// queue (either compaction) holds only paths with alive == kStatusAlive, so only the pass over
// every path reads the flag: for a queued path it would be one more dependent load before the
// state's.
__device__ __forceinline__ uint32_t queued_path(const WavefrontState& w, const uint32_t* queue,
                                                uint32_t i, uint32_t total) {
  if (i >= total) return kInvalid;
  if (queue) return queue[i];
  return w.alive[i] == kStatusAlive ? i : kInvalid;
}

__device__ __forceinline__ uint32_t queue_total(const WavefrontState& w, const uint32_t* queue,
                                                const uint32_t* count) {
  return queue ? *count : w.n;
}

inline uint32_t blocks(uint32_t n) { return (n + kBlock - 1) / kBlock; }

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
    case 7: CALL(7); break;                                 \
    case 12: CALL(12); break;                               \
    case 13: CALL(13); break;                               \
    case 14: CALL(14); break;                               \
    default: CALL(15); break;                               \
  }

// Runs F<Spec> for the caustic variant spec (features.h, caustic_shade_spec): the shade and
// mnee stages' three.
#define TRACER_CAUSTIC_SWITCH(spec, CALL)                               \
  switch (spec) {                                                       \
    case kSpecCaustics | kSpecGuiding | kSpecSpecular:                  \
      CALL(kSpecCaustics | kSpecGuiding | kSpecSpecular);               \
      break;                                                            \
    case kSpecCaustics | kSpecGuiding | kSpecSpheres | kSpecSpecular:   \
      CALL(kSpecCaustics | kSpecGuiding | kSpecSpheres | kSpecSpecular); \
      break;                                                            \
    default: CALL(kGuidedSpec | kSpecCaustics); break;                  \
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

}  // namespace tracer
