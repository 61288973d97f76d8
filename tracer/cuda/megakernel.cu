// The megakernels: each thread runs whole paths (persistent threads with path regeneration),
// through the BVH or the flat list, from new camera paths or from a wavefront queue (the tail).
#include <stdexcept>
#include <string>

#include "cuda/kernel_common.cuh"

namespace tracer {
namespace {

// Minimum resident blocks per SM asked of the compiler for the megakernel (caps its registers).
#ifndef TRACER_MEGA_MIN_BLOCKS
#define TRACER_MEGA_MIN_BLOCKS 4  // 64 registers: the fastest cap measured (PERFORMANCE.md, row 4)
#endif
// The flat megakernel: 64 registers for diffuse-only scenes, 80 for the specular variants (whose
// shading spills at 64): of the caps measured, each the faster for its scenes (PERFORMANCE.md,
// decision log, rows 36-37).
#ifndef TRACER_MEGA_FLAT_DIFFUSE_BLOCKS
#define TRACER_MEGA_FLAT_DIFFUSE_BLOCKS 4
#endif
#ifndef TRACER_MEGA_FLAT_SPECULAR_BLOCKS
#define TRACER_MEGA_FLAT_SPECULAR_BLOCKS 3
#endif
#define TRACER_MEGA_FLAT_MIN_BLOCKS(spec) \
  (((spec) & kSpecSpecular) ? TRACER_MEGA_FLAT_SPECULAR_BLOCKS : TRACER_MEGA_FLAT_DIFFUSE_BLOCKS)

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
    st.origin_prim = prim_is_triangle(s, prim) ? prim : kInvalid;
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
      add_to_film(film, st.pixel, st.radiance, first, &counters[kCounterNonfinite]);
      // Rare: plain atomics.
      if (st.flags & kPathWalkCapped) atomicAdd(&counters[kCounterWalkCapped], 1ull);
      if (st.flags & kPathMediumLeak) atomicAdd(&counters[kCounterMediumLeak], 1ull);
      alive = false;
    }
  }
  // The tail's segments are all extension rays, as the wavefront counts them.
  warp_add(&counters[FromQueue ? kCounterExtension : kCounterMegaSegments], segments);
  warp_add(&counters[kCounterShadow], shadows);
}

// The megakernel for scenes with a flat primitive list (bvh/flat_list.h). Each lane's shadow
// ray is traced together with the next extension ray of its path, in one pass over the list
// (flat_closest_and_any): the loads and the loop are paid once, and no loop runs for only the
// lanes that have a shadow ray (a separate shadow query would run with only those lanes). A
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
      add_to_film(film, done_pixel, done_L, first, &counters[kCounterNonfinite]);
      done_pixel = kInvalid;
    }
    if (!alive) continue;
    ++segments;
    const bool go_on = shade_path<F>(s, cfg, st, hit, sr);
    if (!go_on) {
      // Rare: plain atomics.
      if (st.flags & kPathWalkCapped) atomicAdd(&counters[kCounterWalkCapped], 1ull);
      if (st.flags & kPathMediumLeak) atomicAdd(&counters[kCounterMediumLeak], 1ull);
      if (sr.valid) {
        done_pixel = st.pixel;
        done_L = st.radiance;
      } else {
        add_to_film(film, st.pixel, st.radiance, first, &counters[kCounterNonfinite]);
      }
      alive = false;
    }
  }
  warp_add(&counters[FromQueue ? kCounterExtension : kCounterMegaSegments], segments);
  warp_add(&counters[kCounterShadow], shadows);
}

}  // namespace

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
    TRACER_SPEC_SWITCH(spec, 15u, CALL)
#undef CALL
    if (FromQueue) TRACER_CUDA_CHECK_LAUNCH("megakernel_flat (tail)");
    else TRACER_CUDA_CHECK_LAUNCH("megakernel_flat");
    return;
  }
#define CALL(S)                                                                            \
  megakernel<S, FromQueue><<<persistent_blocks(megakernel<S, FromQueue>, film.n), kBlock, 0, \
                             stream>>>(s, cfg, sample, first, film, counters, next_pixel, src)
  if (spec & kSpecInstances) {  // scenes with instances have no flat list
    CALL(kInstancesSpec);
  } else {
    TRACER_SPEC_SWITCH(spec, 15u, CALL)
  }
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

}  // namespace tracer
