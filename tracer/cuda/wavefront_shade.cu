// The wavefront's path stages: camera rays (generate), shading (with the shade kernel's queues),
// material sorting, CUB's compaction, and the end of a sample (flush, the extension-ray count).
#include <cub/device/device_select.cuh>
#include <thrust/iterator/counting_iterator.h>

#include "cuda/kernel_common.cuh"

namespace tracer {
namespace {

template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) generate_kernel(SceneView s, IntegratorSettings cfg,
                                                          uint32_t sample, WavefrontState w,
                                                          bool walks) {
  const uint32_t id = blockIdx.x * blockDim.x + threadIdx.x;
  if (id >= w.n) return;
  PathState st;
  generate_path<features_of<Spec>()>(s, cfg, id, sample, st);
  store_state(w, id, st);
  w.alive[id] = kStatusAlive;
  if (walks) w.hit[id].y = __uint_as_float(kInvalid);  // camera rays leave from no surface
}

// A shadow ray into slot k of the shadow arrays (the path's id, or its shadow queue slot).
__device__ __forceinline__ void store_shadow_ray(const WavefrontState& w, uint32_t k,
                                                 const ShadowRequest& sr) {
  w.shadow_o[k] = make_float4(sr.ray.o.x, sr.ray.o.y, sr.ray.o.z, sr.ray.tmax);
  w.shadow_d[k] = make_float4(sr.ray.d.x, sr.ray.d.y, sr.ray.d.z, __uint_as_float(sr.target_prim));
  w.shadow_c[k] = make_float4(sr.contribution.x, sr.contribution.y, sr.contribution.z, 1.0f);
}

// Path id's manifold NEE request (path.h, MneeRequest) into w.mnee_requests (layout below); only
// the words of its parts.
__device__ __forceinline__ void store_mnee_request(const WavefrontState& w, uint32_t id,
                                                   const MneeRequest& q) {
  float4* r = w.mnee_requests + id;
  const size_t n = w.n;
  auto put = [&](uint32_t j, vec3 v, uint32_t x) {
    r[j * n] = make_float4(v.x, v.y, v.z, __uint_as_float(x));
  };
  const uint32_t bits = q.depth | (q.connect ? 1u << 28 : 0u) | (q.partition ? 1u << 29 : 0u) |
                        (q.mirror ? 1u << 30 : 0u) | (q.single ? 1u << 31 : 0u);
  put(0, q.p, 0u);
  put(1, q.ng_viewer, bits);
  if (q.connect) {
    put(2, q.frame_n, q.segments);
    put(3, q.wo, q.ls.prim);
    r[4 * n] = make_float4(q.ls.p.x, q.ls.p.y, q.ls.p.z, q.ls.pdf);
    put(5, q.ls.n, 0u);
    put(6, q.ls.le, 0u);
    float4 m[sizeof(Material) / 16];
    memcpy(m, &q.m, sizeof(Material));
#pragma unroll
    for (uint32_t j = 0; j < sizeof(Material) / 16; ++j) r[(7 + j) * n] = m[j];
  }
  if (q.partition) {
    put(16, q.from_o, q.from_normal);
    put(17, q.hit_p, q.hit_prim);
    put(18, q.hit_ng, q.hit_light);
    put(19, q.seg_o, 0u);
    put(20, q.contribution, 0u);
  }
}
static_assert(7 + sizeof(Material) / 16 == 16 && kMneeRequestWords == 21,
              "the request's words: 0-6, the material's 7-15, the partition's 16-20");

__device__ __forceinline__ MneeRequest load_mnee_request(const WavefrontState& w, uint32_t id) {
  const float4* r = w.mnee_requests + id;
  const size_t n = w.n;
  MneeRequest q;
  auto get = [&](uint32_t j, vec3& v) {
    const float4 x = r[j * n];
    v = vec3(x.x, x.y, x.z);
    return __float_as_uint(x.w);
  };
  get(0, q.p);
  const uint32_t bits = get(1, q.ng_viewer);
  q.depth = bits & 0x0fffffffu;
  q.connect = (bits >> 28) & 1u;
  q.partition = (bits >> 29) & 1u;
  q.mirror = (bits >> 30) & 1u;
  q.single = (bits >> 31) & 1u;
  if (q.connect) {
    q.segments = get(2, q.frame_n);
    q.ls.prim = get(3, q.wo);
    q.ls.pdf = __uint_as_float(get(4, q.ls.p));
    get(5, q.ls.n);
    get(6, q.ls.le);
    q.ls.valid = true;
    q.ls.infinite = q.ls.delta = false;
    float4 m[sizeof(Material) / 16];
#pragma unroll
    for (uint32_t j = 0; j < sizeof(Material) / 16; ++j) m[j] = r[(7 + j) * n];
    memcpy(&q.m, m, sizeof(Material));
  }
  if (q.partition) {
    q.from_normal = get(16, q.from_o);
    q.hit_prim = get(17, q.hit_p);
    q.hit_light = get(18, q.hit_ng);
    get(19, q.seg_o);
    get(20, q.contribution);
  }
  return q;
}

// Shades the queued paths; with next_queue (compaction in the shade kernel) each block appends
// its paths that go on to the next bounce's queue, in slot order, with one atomic on the next
// bounce's path count (alive_counts[bounce + 1]). The block's 8 warp counts are summed in shared
// memory first, so that one atomic per block, not per warp, waits on that count (per-warp atomics
// on one address serialise where nearly every path goes on). With shadow_queue the block appends
// its paths that have a shadow ray to it the same way (shadow_counts[bounce]), so that the shadow
// stage traces full warps of rays instead of every path of the bounce (on later bounces many
// paths have none), and stores the rays at their slots (shadow_o/d/c[slot]), where the stage
// reads them in whole sectors instead of scattered over the pool; the paths that end without a
// shadow ray go to the queue's far end (slot n - 1 - k, counted on finish_counts[bounce]), where
// the shadow stage's last warps add them to the film. (Adding them to the film here would stall
// the shade kernel's loads and barrier on bounces where many paths end: PERFORMANCE.md, decision
// log, row 72.)
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
  constexpr bool kCaustics = (features_of<Spec>() & kFeatureCaustics) != 0;
  bool go_on = false, shadow_valid = false, mnee_asks = false;
  ShadowRequest sr;
  PathState st;
  MneeRequest mq;  // manifold NEE's solves, left to the mnee stage (launch_mnee)
  if (id != kInvalid) {
    st = load_state(w, id, ri, sample);
    if (kCaustics && (st.flags & kPathMneeFrom)) {
      const float4 m = w.mnee[id];
      st.mnee_o = vec3(m.x, m.y, m.z);
      st.mnee_normal = __float_as_uint(m.w);
    }
    const Hit hit = load_hit(w, ri);
    go_on = shade_path<features_of<Spec>()>(s, cfg, st, hit, sr, &mq);
    mnee_asks = kCaustics && (mq.connect || mq.partition);
    if (mnee_asks) store_mnee_request(w, id, mq);  // at its id: mq's registers free from here
    store_path(w, id, st);
    // This vertex sampled the lights (no refraction since): its origin, for the paths' later
    // emission hits (path.h).
    if (kCaustics && go_on && (st.flags & kPathMneeFrom) &&
        !(st.flags & (kPathMneeRefract1 | kPathMneeRefract2 | kPathMneeOther | kPathMneeMirror)))
      w.mnee[id] = make_float4(st.mnee_o.x, st.mnee_o.y, st.mnee_o.z,
                               __uint_as_float(st.mnee_normal));

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
    w.alive[id] = go_on ? kStatusAlive : kStatusEnded;
  }
  // Warp-aggregated statistics: shadow rays traced and paths entering the next bounce.
  const unsigned ballot_shadow = __ballot_sync(0xffffffffu, shadow_valid);
  const unsigned ballot_alive = __ballot_sync(0xffffffffu, go_on);
  // Paths that end without a shadow ray (only counted with a shadow queue).
  const bool finish = id != kInvalid && !go_on && !shadow_valid;
  const unsigned ballot_finish = __ballot_sync(0xffffffffu, finish);
  const uint32_t lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  const unsigned below = (1u << lane) - 1u;
  if (lane == 0 && ballot_shadow)
    atomicAdd(&w.counters[kCounterShadow], (unsigned long long)__popc(ballot_shadow));
  if (kCaustics) {  // the paths with a request, into the mnee queue (one atomic per warp)
    const unsigned ballot_mnee = __ballot_sync(0xffffffffu, mnee_asks);
    if (ballot_mnee) {
      uint32_t base = 0;
      if (lane == 0) base = atomicAdd(&w.mnee_counts[bounce], uint32_t(__popc(ballot_mnee)));
      base = __shfl_sync(0xffffffffu, base, 0);
      if (mnee_asks) w.mnee_queue[base + __popc(ballot_mnee & below)] = id;
    }
  }
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

// Manifold NEE's stage: one thread per request of the bounce (launch_mnee), which runs its
// request's solver and traces the rays it asks for at one place (path.h, mnee_resolve). One
// block per multiprocessor with up to 255 registers runs it faster than two with 128, where the
// solver's state, which lives across the rays, would spill (PERFORMANCE.md rows 115, 122).
template <uint32_t Spec, bool Single>
__global__ void __launch_bounds__(kBlock, 1)
    mnee_kernel(SceneView view, const __grid_constant__ FlatParams flat, IntegratorSettings cfg,
                uint32_t sample, uint32_t bounce, WavefrontState w) {
  const uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= w.mnee_counts[bounce]) return;
  const SceneView s = with_flat_params(view, flat);
  const uint32_t id = w.mnee_queue[k];
  const MneeRequest q = load_mnee_request(w, id);
  const vec3 c = mnee_resolve<features_of<Spec>() | kFeatureFlatList |
                              (Single ? kFeatureSingleRefraction : 0u)>(s, cfg, q);
  if (is_black(c)) return;
  float4 r = w.radiance[id];  // (one request per path and bounce)
  r.x += c.x;
  r.y += c.y;
  r.z += c.z;
  w.radiance[id] = r;
  guide_add_gathered(cfg.guide, id, sample, q.depth, luminance(c));
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
  if (id >= w.n || w.alive[id] == kStatusDone) return;
  const float4 r = w.radiance[id];
  add_to_film(film, id, vec3(r.x, r.y, r.z), first, &w.counters[kCounterNonfinite]);
  w.alive[id] = kStatusDone;
  atomicAdd(&w.counters[kCounterWalkCapped], 1ull);
}

__global__ void sort_keys_kernel(SceneView s, WavefrontState w, const uint32_t* queue,
                                 const uint32_t* count) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= (queue ? *count : w.n)) return;
  const uint32_t id = queue ? queue[i] : i;
  uint32_t key = 7;  // dead paths last
  if (w.alive[id] == kStatusAlive) {
    const uint32_t prim = __float_as_uint(w.hit[id].y);
    if (prim == kInvalid) {
      key = 6;  // escaped
    } else {
      const uint32_t mat = prim_is_triangle(s, prim)
                               ? triangle_shading(s, triangle_ref(s, prim)).material
                               : s.spheres[prim - s.tri_count].material;
      // Keys 6 and 7 are taken: the types past 5 share key 5.
      key = min(uint32_t(s.materials[mat].type), 5u);
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

// Path guiding's training (integrator/guide.h): one thread per path, after its sample.
__global__ void guide_train_kernel(GuideView g, const float4* radiance, uint32_t n,
                                   uint32_t sample) {
  const uint32_t id = blockIdx.x * blockDim.x + threadIdx.x;
  if (id >= n) return;
  const float4 r = radiance[id];
  guide_train_path(g, id, sample, vec3(r.x, r.y, r.z));
}

// ... and the rebuild of every cell's distribution, one thread per cell.
__global__ void guide_build_kernel(float* hist, const uint32_t* counts, float* dist,
                                   uint32_t cells, uint32_t* learned) {
  const uint32_t cell = blockIdx.x * blockDim.x + threadIdx.x;
  const bool ok = cell < cells && guide_build_cell(hist, counts, dist, cell);
  const bool guides = ok && dist[size_t(cell) * kGuideDistFloats] > 0.0f;
  const unsigned ballot = __ballot_sync(0xffffffffu, ok);
  const unsigned guiding = __ballot_sync(0xffffffffu, guides);
  if ((threadIdx.x & 31) == 0 && ballot) atomicAdd(learned, uint32_t(__popc(ballot)));
  if ((threadIdx.x & 31) == 0 && guiding) atomicAdd(learned + 1, uint32_t(__popc(guiding)));
}

struct IsAlive {
  const uint8_t* alive;
  __host__ __device__ bool operator()(uint32_t id) const { return alive[id] == kStatusAlive; }
};

}  // namespace

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

void launch_shade(uint32_t spec, const SceneView& s, const IntegratorSettings& cfg,
                  uint32_t sample, uint32_t bounce, const WavefrontState& w,
                  const uint32_t* queue, const uint32_t* count, uint32_t* next_queue,
                  uint32_t* shadow_queue, cudaStream_t stream) {
  // The block's 108 bytes of shared memory (compaction) must not take L1 from the shading's
  // scene reads: asked for the smallest carveout, once per variant.
  static bool carveout_set[kSpecCount] = {};
#define CALL(S)                                                                           \
  if (!carveout_set[S]) {                                                                 \
    TRACER_CUDA_CHECK(cudaFuncSetAttribute(shade_kernel<S>,                               \
                                           cudaFuncAttributePreferredSharedMemoryCarveout, \
                                           int(cudaSharedmemCarveoutMaxL1)));             \
    carveout_set[S] = true;                                                               \
  }                                                                                       \
  shade_kernel<S><<<blocks(w.n), kBlock, 0, stream>>>(s, cfg, sample, bounce, w, queue, count, \
                                                      next_queue, shadow_queue)
  if (spec & kSpecCaustics) {  // manifold NEE (features.h, caustic_shade_spec)
    TRACER_CAUSTIC_SWITCH(spec, CALL)
  } else if (spec & kSpecGuiding) {  // path guiding (features.h, guided_shade_spec)
    switch (spec) {
      case kSpecGuiding: CALL(kSpecGuiding); break;
      case kSpecGuiding | kSpecSpheres: CALL(kSpecGuiding | kSpecSpheres); break;
      case kSpecGuiding | kSpecSpecular: CALL(kSpecGuiding | kSpecSpecular); break;
      case kSpecGuiding | kSpecSpheres | kSpecSpecular:
        CALL(kSpecGuiding | kSpecSpheres | kSpecSpecular);
        break;
      default: CALL(kGuidedSpec); break;
    }
  } else if (spec & kSpecInstances) {  // instances imply every other feature (features.h)
    CALL(kInstancesSpec);
  } else {
    switch (spec & (kSpecSpheres | kSpecSpecular | kSpecLights)) {
      case 0: CALL(0); break;
      case kSpecSpheres: CALL(kSpecSpheres); break;
      case kSpecSpecular: CALL(kSpecSpecular); break;
      case kSpecSpheres | kSpecSpecular: CALL(kSpecSpheres | kSpecSpecular); break;
      case kSpecSpecular | kSpecLights: CALL(kSpecSpecular | kSpecLights); break;
      default: CALL(kSpecSpheres | kSpecSpecular | kSpecLights); break;
    }
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("shade_kernel");
}

void launch_mnee(uint32_t spec, const SceneView& s, const FlatParams& flat,
                 const IntegratorSettings& cfg, uint32_t sample, uint32_t bounce,
                 const WavefrontState& w, cudaStream_t stream) {
#define CALL(S) \
  mnee_kernel<S, false><<<blocks(w.n), kBlock, 0, stream>>>(s, flat, cfg, sample, bounce, w)
  // Scenes with open glass: the one-refraction chain's variants (triangles and specular
  // materials alone, as the pool or a tank; else the general one); other scenes the caustic
  // shade kernels' variants without it.
  constexpr uint32_t kPlain = kSpecCaustics | kSpecGuiding | kSpecSpecular;
  if (s.open_glass && spec == kPlain)
    mnee_kernel<kPlain, true><<<blocks(w.n), kBlock, 0, stream>>>(s, flat, cfg, sample, bounce, w);
  else if (s.open_glass)
    mnee_kernel<kGuidedSpec | kSpecCaustics, true>
        <<<blocks(w.n), kBlock, 0, stream>>>(s, flat, cfg, sample, bounce, w);
  else
    TRACER_CAUSTIC_SWITCH(spec, CALL)  // the caustic shade kernels' variants
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("mnee_kernel");
}

void launch_guide_train(const GuideView& g, const float4* radiance, uint32_t n, uint32_t sample,
                        cudaStream_t stream) {
  guide_train_kernel<<<blocks(n), kBlock, 0, stream>>>(g, radiance, n, sample);
  TRACER_CUDA_CHECK_LAUNCH("guide_train_kernel");
}

void launch_guide_build(float* hist, const uint32_t* counts, float* dist, uint32_t cells,
                        uint32_t* learned, cudaStream_t stream) {
  TRACER_CUDA_CHECK(cudaMemsetAsync(learned, 0, 2 * sizeof(uint32_t), stream));
  guide_build_kernel<<<blocks(cells), kBlock, 0, stream>>>(hist, counts, dist, cells, learned);
  TRACER_CUDA_CHECK_LAUNCH("guide_build_kernel");
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

}  // namespace tracer
