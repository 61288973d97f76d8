// Host side of the CUDA backend: device memory, the per-bounce wavefront schedule, the megakernel,
// --kernel auto's timing of both designs, and per-stage statistics from CUDA events.
#include "cuda/cuda_renderer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

#include "cuda/device_buffer.h"
#include "cuda/film.h"
#include "cuda/kernels.h"

namespace tracer {

namespace {

template <typename T>
size_t bytes_of(const std::vector<T>& v) {
  return v.size() * sizeof(T);
}

std::string gib(size_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f GiB", double(bytes) / double(size_t(1) << 30));
  return buf;
}

// Throws a message that says what `what` needs and what the device has free, before an
// allocation that would fail (cudaMalloc's "out of memory" names neither). `held` is memory the
// allocation will release first (the buffers it replaces).
void require_device_memory(size_t need, size_t held, const std::string& what,
                           const std::string& parts, const std::string& device) {
  size_t free_bytes = 0, total_bytes = 0;
  if (cudaMemGetInfo(&free_bytes, &total_bytes) != cudaSuccess) return;  // let cudaMalloc say
  // Headroom for CUB's and the driver's own allocations.
  const size_t headroom = size_t(64) << 20;
  if (need + headroom <= free_bytes + held) return;
  throw std::runtime_error(what + " needs " + gib(need) + " of GPU memory (" + parts + "); " +
                           device + " has " + gib(free_bytes + held) + " free of " +
                           gib(total_bytes) + ". Use the CPU backend (--backend cpu), a smaller "
                           "image, or a scene with fewer triangles or smaller textures");
}

enum Stage {
  kGenerate, kIntersect, kSort, kShade, kShadow, kCompact, kMega, kIntersectFirst, kTail,
  kTrace, kMnee, kLight, kStageCount
};
}

struct CudaRenderer::Impl {
  int device = 0;
  cudaDeviceProp prop{};
  cudaStream_t stream = nullptr;

  // Scene.
  DeviceBuffer<BvhNode> nodes;
  DeviceBuffer<uint32_t> prim_indices;
  DeviceBuffer<Bvh8Node> nodes8;  // the 8-wide compressed tree (empty where the scene has none)
  DeviceBuffer<uint32_t> prim_indices8;
  uint32_t node_count4 = 0;
  DeviceBuffer<TriangleVerts> tri_verts;
  DeviceBuffer<TriangleShading> tri_shading;
  DeviceBuffer<Sphere> spheres;
  DeviceBuffer<ReflectorPlane> reflector_planes;
  DeviceBuffer<WindowPlane> window_planes;
  DeviceBuffer<LightTarget> light_targets;
  DeviceBuffer<Material> materials;
  DeviceBuffer<Light> lights;
  DeviceBuffer<float> light_cdf;
  DeviceBuffer<LightTreeNode> light_nodes;  // the light tree (render.light_sampler bvh)
  DeviceBuffer<LightLeafEntry> light_leaves;
  DeviceBuffer<uint64_t> light_trails;
  DeviceBuffer<TriangleUv> tri_uvs;  // empty unless the scene is textured
  // Instances and their meshes (TraceView::inst_*; empty without instances).
  DeviceBuffer<Instance> instances;
  DeviceBuffer<BvhNode> inst_nodes;
  DeviceBuffer<uint32_t> inst_prim_indices;
  DeviceBuffer<TriangleVerts> inst_tri_verts;
  DeviceBuffer<TriangleShading> inst_tri_shading;
  DeviceBuffer<TriangleUv> inst_tri_uvs;
  DeviceBuffer<TextureDesc> textures;
  DeviceBuffer<uint32_t> texels;     // all textures' RGBA8 texels in one allocation
  // The lights at infinity (SceneView::infinite): the map's texels and sampling distribution,
  // the distant lights, and the InfiniteLights struct pointing at them.
  DeviceBuffer<float> env_texels, env_func, env_cond_cdf, env_marg_cdf;
  DeviceBuffer<DistantLight> distant;
  DeviceBuffer<InfiniteLights> infinite;
  DeviceBuffer<PointLight> point_lights;  // SceneView::point_lights
  DeviceBuffer<FlatPrim> flat;       // the flat primitive list, small scenes only
  DeviceBuffer<FlatPrimInfo> flat_info;
  DeviceBuffer<FlatPrim> flat_solids;  // the solid boxes' maps
  DeviceBuffer<uint32_t> tri_to_flat;
  bool flat_available = false;
  bool mnee_casters = false;  // mnee_has_casters(the scene)
  std::string flat_text;             // describe_flat_list of the scene's list
  FlatParams flat_params;            // the same entries, passed to the kernels that loop over them
  SceneView view;
  uint32_t features = 0;

  IntegratorSettings cfg;
  GpuOptions opts;          // as requested
  EffectiveGpuOptions eff;  // as they run on this scene (resolve())
  bool has_scene = false;
  // The CUDA device is current per thread: every entry point that touches the device makes this
  // renderer's current first, so it may be driven from any thread (distributed rendering's rank
  // 0 renders on a thread of its own).
  void use_device() const { TRACER_CUDA_CHECK(cudaSetDevice(device)); }

  // Films for the even and the odd samples, and counters.
  DeviceBuffer<float4> film[2];
  // The feature buffers (while aovs_on; empty otherwise): per half, albedo + depth and normal,
  // and the samples each half holds.
  bool aovs_on = false;
  DeviceBuffer<float4> aov_a[2], aov_b[2];
  DeviceBuffer<uint2> aov_ids;
  uint32_t aov_count[2] = {0, 0};
  // The denoiser's images in device memory (3 floats per pixel; allocated at its first use).
  DeviceBuffer<float> dn_color, dn_albedo, dn_normal, dn_out;
  void allocate_aovs() {
    const uint32_t pixels = aovs_on ? n() : 0;
    for (auto* b : {&aov_a[0], &aov_a[1], &aov_b[0], &aov_b[1]}) b->resize(pixels);
    aov_ids.resize(pixels);
    aov_count[0] = aov_count[1] = 0;
  }
  AovFilm aov_film() {
    AovFilm f;
    for (int h = 0; h < 2; ++h) {
      f.a[h] = aov_a[h].get();
      f.b[h] = aov_b[h].get();
    }
    f.ids = aov_ids.get();
    f.n = n();
    f.write_ids = aov_count[0] + aov_count[1] == 0;
    return f;
  }
  DeviceBuffer<unsigned long long> counters;  // [kCounterCount], indexed by Counter
  uint32_t samples = 0;                // added
  uint32_t next_sample = 0;            // the next sample's number
  uint32_t film_count[2] = {0, 0};     // samples in each film (of even and of odd numbers)
  uint64_t nonfinite = 0;
  // The films holding the mean's samples: both, or the one that holds any (the other holds
  // stale memory until its first sample overwrites it).
  struct MeanFilms {
    const float4* a;
    const float4* b;
    bool both;
  };
  MeanFilms mean_films() const {
    if (film_count[0] > 0 && film_count[1] > 0) return {film[0].get(), film[1].get(), true};
    const int h = film_count[0] > 0 ? 0 : 1;
    return {film[h].get(), film[h].get(), false};
  }
  void clear_counts() { samples = next_sample = film_count[0] = film_count[1] = 0; }

  // Wavefront pool.
  DeviceBuffer<float4> ray_o, ray_d, throughput, radiance, hit, shadow_o, shadow_d, shadow_c;
  // The odd bounces' rays when they are stored at their queue slots (eff.rays_at_slots).
  DeviceBuffer<float4> ray_o_odd, ray_d_odd;
  DeviceBuffer<float4> cached_hits;
  DeviceBuffer<float4> mnee_state;  // WavefrontState::mnee, with render.mnee only
  DeviceBuffer<float4> mnee_requests;  // ... and its mnee_requests
  DeviceBuffer<uint32_t> mnee_queue;
  DeviceBuffer<uint8_t> alive;
  // queue: CUB's output, or (compaction in the shade kernel) the queues of even bounces, and
  // queue_odd those of odd ones: a bounce reads one while its shade kernel fills the other.
  DeviceBuffer<uint32_t> queue, queue_odd, sorted, sort_keys, sort_bins, alive_counts, count, fetch;
  // With compaction in the shade kernel: each bounce's paths with a shadow ray (and at the far
  // end those that end without one), and their numbers per bounce: shadow_counts holds the
  // shadow rays of bounces [0, stride), then the paths to finish, then manifold NEE's requests
  // (WavefrontState).
  DeviceBuffer<uint32_t> shadow_queue, shadow_counts;
  uint32_t shadow_stride = 0;
  DeviceBuffer<uint8_t> cub_temp;
  bool cache_valid = false;
  // Paths entering each bounce in the last timed wavefront sample (zeros from its tail on): the
  // wavefront hands its paths to the tail kernel at the first bounce where these fall below
  // eff.options.tail_fraction of the pixels. Only speed depends on it.
  std::vector<uint32_t> tail_estimate;
  uint32_t tail_from = 0;  // the bounce where the last wavefront sample's tail began (0: none)

  // --kernel auto: time both designs on the first samples and keep the faster.
  KernelMode chosen = KernelMode::kAuto;
  double auto_ms[2] = {0, 0};  // wavefront, megakernel
  int auto_step = 0;

  std::vector<cudaEvent_t> events;

  // Path guiding (render.guiding; integrator/guide.h): the guide's arrays in device memory.
  const CompiledScene* compiled = nullptr;  // (set_scene: the caller keeps it alive)
  GuideGrid grid;  // of the scene at the image's size
  bool guiding = false;
  DeviceBuffer<float> guide_hist, guide_dist;
  DeviceBuffer<uint32_t> guide_counts, guide_learned;
  DeviceBuffer<GuideRecord> guide_records;
  uint32_t guide_builds = 0, guide_learned_cells[2] = {0, 0};  // learned, guiding
  // After training: kept or retired (guide_host.h). An unguided calibration sample runs the
  // stages of eff_plain; the films' sums before the first block and before the current one are
  // kept in calibration_base and calibration_then.
  GuideCalibration calibration;
  EffectiveGpuOptions eff_plain;
  DeviceBuffer<float4> calibration_base, calibration_then;
  uint32_t calibration_base_count = 0;
  DeviceBuffer<double> calibration_sum;
  bool guide_retired() const { return guiding && calibration.retires(); }
  bool kernel_forced = false;  // resolve() forced a kernel (guiding: the wavefront)
  void allocate_guide() {
    guiding = cfg.guiding != 0 && has_scene && compiled;
    grid = guiding ? guide_grid(*compiled, n()) : GuideGrid();
    const size_t cells = guiding ? grid.cells() : 0;
    const size_t records = guiding ? size_t(n()) * kGuideRecords : 0;
    if (guiding)
      require_device_memory(cells * ((kGuideHistFloats + kGuideDistFloats) * sizeof(float) +
                                         sizeof(uint32_t)) +
                                records * sizeof(GuideRecord),
                            guide_hist.bytes() + guide_dist.bytes() + guide_records.bytes(),
                            "path guiding", "its grid of " + std::to_string(cells) +
                                " cells and " + std::to_string(kGuideRecords) +
                                " vertex records per pixel", prop.name);
    guide_hist.resize(cells * kGuideHistFloats);
    guide_dist.resize(cells * kGuideDistFloats);
    guide_counts.resize(cells);
    guide_learned.resize(guiding ? 2 : 0);
    guide_records.resize(records);
    clear_guide();
  }
  void clear_guide() {
    guide_builds = guide_learned_cells[0] = guide_learned_cells[1] = 0;
    const bool was_retired = guide_retired();
    calibration = GuideCalibration();
    calibration_base_count = 0;
    if (was_retired) resolve();  // guided again
    if (!guiding) return;
    TRACER_CUDA_CHECK(cudaMemsetAsync(guide_hist.get(), 0, guide_hist.bytes(), stream));
    TRACER_CUDA_CHECK(cudaMemsetAsync(guide_dist.get(), 0, guide_dist.bytes(), stream));
    TRACER_CUDA_CHECK(cudaMemsetAsync(guide_counts.get(), 0, guide_counts.bytes(), stream));
    // Sample 0xffffffff: no record is of the render's samples yet.
    TRACER_CUDA_CHECK(cudaMemsetAsync(guide_records.get(), 0xff, guide_records.bytes(), stream));
  }
  GuideView guide_view(uint32_t sample) {
    if (!guiding) return GuideView();
    return guide_view_for(
        grid, {guide_dist.get(), guide_hist.get(), guide_counts.get(), guide_records.get()},
        guide_builds, sample, calibration);
  }
  // After a wavefront sample: its paths train the guide, and a pass's end rebuilds it.
  void guide_after_sample(uint32_t sample) {
    if (!guiding || !guide_trains(sample)) return;
    launch_guide_train(cfg.guide, radiance.get(), n(), sample, stream);
    if (guide_builds_after(sample)) {
      launch_guide_build(guide_hist.get(), guide_counts.get(), guide_dist.get(), grid.cells(),
                         guide_learned.get(), stream);
      TRACER_CUDA_CHECK(cudaMemcpyAsync(guide_learned_cells, guide_learned.get(),
                                        sizeof(guide_learned_cells), cudaMemcpyDeviceToHost,
                                        stream));
      TRACER_CUDA_CHECK(cudaStreamSynchronize(stream));
      ++guide_builds;
    }
  }

  ~Impl() {
    for (cudaEvent_t e : events) cudaEventDestroy(e);
    if (stream) cudaStreamDestroy(stream);
  }

  uint32_t n() const { return cfg.width * cfg.height; }
  // What runs, decided in one place (gpu_options.h) for the requested options, the scene and
  // the settings: after each change of any of them.
  void resolve() {
    if (!has_scene) return;
    GpuSceneTraits traits = gpu_scene_traits(view, flat_available, cfg);
    traits.mnee_casters = mnee_casters;
    traits.bvh8_available = nodes8.size() > 0;
    if (guide_retired()) traits.guiding = false;  // the render goes on unguided
    eff = resolve_gpu_options(opts, traits);
    // The unguided calibration samples' stages (guide_host.h): the same options without guiding.
    GpuSceneTraits plain = traits;
    plain.guiding = false;
    eff_plain = traits.guiding ? resolve_gpu_options(opts, plain) : eff;
    // A kernel the resolution forces (path guiding: the wavefront) runs; once no longer forced,
    // the request runs again (--kernel auto times both designs anew).
    const bool forced = eff.options.kernel != opts.kernel;
    if (forced) {
      chosen = eff.options.kernel;
    } else if (kernel_forced) {
      chosen = opts.kernel;
      auto_step = 0;
    }
    kernel_forced = forced;
    view.use_flat = eff.options.flat_list ? 1u : 0u;
    view.nodes8 = eff.bvh8 ? nodes8.get() : nullptr;
    view.prim_indices8 = eff.bvh8 ? prim_indices8.get() : nullptr;
    view.node_count = eff.bvh8 ? uint32_t(nodes8.size()) : node_count4;
  }
  std::string accel_name() const {
    return view.use_flat ? "flat list of " + flat_text
                         : view.nodes8 ? "8-wide compressed BVH" : "4-wide BVH";
  }
  DeviceBuffer<double> clamp_sum;
  FilmView film_view(uint32_t sample) {
    FilmView f;
    f.accum = film[sample & 1].get();
    f.n = n();
    f.clamp = cfg.clamp;
    f.clamped_luminance = clamp_sum.get();
    f.clamped = counters.get() + kCounterClamped;
    f.keep_radiance = guiding && guide_trains(sample);
    return f;
  }

  WavefrontState wavefront() {
    WavefrontState w;
    w.n = n();
    w.ray_o = ray_o.get();
    w.ray_d = ray_d.get();
    w.throughput = throughput.get();
    w.radiance = radiance.get();
    w.hit = hit.get();
    w.next_ray_o = w.ray_o;
    w.next_ray_d = w.ray_d;
    w.shadow_o = shadow_o.get();
    w.shadow_d = shadow_d.get();
    w.shadow_c = shadow_c.get();
    w.alive = alive.get();
    w.sort_keys = sort_keys.get();
    w.sort_bins = sort_bins.get();
    w.fetch = fetch.get();
    w.counters = counters.get();
    w.alive_counts = alive_counts.get();
    w.shadow_counts = shadow_counts.get();
    w.finish_counts = shadow_counts.get() + shadow_stride;
    const bool caustics = (eff.shade_spec & kSpecCaustics) != 0;
    if (caustics && mnee_requests.size() != size_t(kMneeRequestWords) * n())
      require_device_memory(size_t(n()) * ((kMneeRequestWords + 1) * sizeof(float4) + 4),
                            mnee_state.bytes() + mnee_requests.bytes() + mnee_queue.bytes(),
                            "manifold NEE (render.mnee) on a " + std::to_string(cfg.width) + "x" +
                                std::to_string(cfg.height) + " image",
                            "its requests and path state, " +
                                std::to_string((kMneeRequestWords + 1) * sizeof(float4) + 4) +
                                " bytes per pixel",
                            prop.name);
    mnee_state.resize(caustics ? n() : 0);
    mnee_requests.resize(caustics ? size_t(kMneeRequestWords) * n() : 0);
    mnee_queue.resize(caustics ? n() : 0);
    w.mnee = mnee_state.get();
    w.mnee_requests = mnee_requests.get();
    w.mnee_queue = mnee_queue.get();
    w.mnee_counts = shadow_counts.get() + 2 * shadow_stride;
    return w;
  }

  void allocate() {
    const uint32_t count_pixels = n();
    // The two accumulators, ten float4 ray and path arrays, the alive flags and five queues.
    // With AOVs four float4 feature sums and two ids more.
    const size_t per_pixel = (aovs_on ? 16 : 12) * sizeof(float4) + 1 + 5 * sizeof(uint32_t) +
                             (aovs_on ? sizeof(uint2) : 0);
    require_device_memory(size_t(count_pixels) * per_pixel, film[0].size() * per_pixel,
                          "a " + std::to_string(cfg.width) + "x" + std::to_string(cfg.height) +
                              " image",
                          "the accumulators and the wavefront's path state, " +
                              std::to_string(per_pixel) + " bytes per pixel",
                          prop.name);
    film[0].resize(count_pixels);
    film[1].resize(count_pixels);
    allocate_aovs();
    for (auto* b : {&ray_o, &ray_d, &ray_o_odd, &ray_d_odd, &throughput, &radiance, &hit,
                    &shadow_o, &shadow_d, &shadow_c})
      b->resize(count_pixels);
    alive.resize(count_pixels);
    queue.resize(count_pixels);
    queue_odd.resize(count_pixels);
    shadow_queue.resize(count_pixels);
    sorted.resize(count_pixels);
    sort_keys.resize(count_pixels);
    sort_bins.resize(17);
    fetch.resize(1);
    alive_counts.resize(cfg.max_depth + 2);
    shadow_stride = cfg.max_depth + 2;
    shadow_counts.resize(3 * shadow_stride);
    count.resize(1);
    cub_temp.resize(std::max<size_t>(1, compaction_temp_bytes(count_pixels)));
    counters.resize(kCounterCount);
    clamp_sum.resize(1);
    cached_hits.resize(0);
    cache_valid = false;
    clear_counts();
    nonfinite = 0;
  }

  // Records an event after the work of `stage` when timing.
  std::vector<std::pair<cudaEvent_t, int>> marks;
  void mark(bool timed, int stage) {
    if (!timed) return;
    if (marks.size() >= events.size()) {
      cudaEvent_t e;
      TRACER_CUDA_CHECK(cudaEventCreate(&e));
      events.push_back(e);
    }
    cudaEvent_t e = events[marks.size()];
    TRACER_CUDA_CHECK(cudaEventRecord(e, stream));
    marks.push_back({e, stage});
  }
  void collect(StageTimes& t) {
    if (marks.size() < 2) return;
    TRACER_CUDA_CHECK(cudaEventSynchronize(marks.back().first));
    double* slot[kStageCount] = {&t.generate, &t.intersect,  &t.sort,      &t.shade,
                                 &t.shadow,   &t.compact,    &t.megakernel, &t.intersect_first,
                                 &t.tail,     &t.trace,      &t.mnee,       &t.light};
    for (size_t i = 1; i < marks.size(); ++i) {
      float ms = 0.0f;
      TRACER_CUDA_CHECK(cudaEventElapsedTime(&ms, marks[i - 1].first, marks[i].first));
      const int stage = marks[i].second;
      *slot[stage] += ms;
      if (stage == kIntersectFirst) t.intersect += ms;
      // Each bounce starts with its intersect mark (the cache copy's for a cached first one), or
      // the fused trace stage's that traced its rays.
      if (stage == kIntersect || stage == kIntersectFirst || stage == kTrace)
        t.bounces.emplace_back();
      if (t.bounces.empty()) continue;
      BounceTimes& b = t.bounces.back();
      if (stage == kIntersect || stage == kIntersectFirst) b.intersect += ms;
      if (stage == kTrace) b.trace += ms;
      if (stage == kSort) b.sort += ms;
      if (stage == kShade) b.shade += ms;
      if (stage == kShadow) b.shadow += ms;
      if (stage == kCompact) b.compact += ms;
      if (stage == kMnee) b.mnee += ms;
    }
    marks.clear();
  }

  // Light tracing's paths of a sample (render.light_tracing), after its camera paths.
  DeviceBuffer<uint32_t> light_next;  // the light kernel's next path (scratch)
  void light_wave(uint32_t sample, bool timed) {
    if (!cfg.light_tracing) return;
    if (light_next.size() == 0) light_next.resize(1);
    launch_light_trace(eff.spec, view, flat_params, cfg, sample, film_view(sample),
                       counters.get(), light_next.get(), stream);
    mark(timed, kLight);
  }

  void megakernel_wave(uint32_t sample, bool first, bool timed) {
    mark(timed, kMega);  // start
    launch_megakernel(eff.spec, view, flat_params, cfg, sample, first, film_view(sample),
                      counters.get(), count.get(), stream);
    mark(timed, kMega);
  }

  // One sample per pixel through the wavefront; returns paths entering each bounce when asked.
  void wavefront_wave(uint32_t sample, bool first, bool timed) {
    const uint32_t sp = eff.spec;
    WavefrontState w = wavefront();
    mark(timed, kGenerate);
    launch_generate(sp, view, cfg, sample, w, stream);
    mark(timed, kGenerate);
    const bool use_cache = eff.options.first_bounce_cache;
    if (use_cache && cached_hits.size() != n()) {
      cached_hits.resize(n());
      cache_valid = false;
    }
    // Without subsurface every path has ended after max_depth bounces. Random walks do not
    // count towards the depth, so with them the loop runs until no path is left (checked every
    // 8 iterations) or a walk's step limit must have been reached.
    const bool walks = (features & kFeatureSubsurface) != 0;
    const uint32_t iterations = walks ? cfg.max_depth + kMaxWalkSteps : cfg.max_depth;
    if (alive_counts.size() < iterations + 2) alive_counts.resize(iterations + 2);
    if (shadow_stride < iterations + 2) {
      shadow_stride = iterations + 2;
      shadow_counts.resize(3 * shadow_stride);
    }
    w.alive_counts = alive_counts.get();
    w.shadow_counts = shadow_counts.get();
    w.finish_counts = shadow_counts.get() + shadow_stride;
    w.mnee_counts = shadow_counts.get() + 2 * shadow_stride;
    const bool mnee = (eff.shade_spec & kSpecCaustics) != 0;
    TRACER_CUDA_CHECK(cudaMemsetAsync(w.alive_counts, 0, alive_counts.bytes(), stream));
    // Compaction in the shade kernel: bounce b reads the queue its predecessor's shade kernel
    // wrote (its length: alive_counts[b]) and writes the next one into the other buffer.
    const bool queue_in_shade = eff.queues_in_shade();
    // ... and then a shadow queue too.
    if (queue_in_shade || mnee)
      TRACER_CUDA_CHECK(cudaMemsetAsync(w.shadow_counts, 0, shadow_counts.bytes(), stream));
    uint32_t* const shadows = queue_in_shade ? shadow_queue.get() : nullptr;
    auto bounce_queue = [&](uint32_t b) { return (b & 1) ? queue_odd.get() : queue.get(); };
    // The tail (needs a queue): from the first bounce whose estimated queue is short, one
    // megakernel launch runs the remaining bounces of its paths, where each stage of a short
    // queue would cost its launch and one path's latency (PERFORMANCE.md, "Short queues").
    tail_from = eff.compaction() ? wavefront_tail_bounce(tail_estimate, eff.options.tail_fraction,
                                                         n(), iterations)
                                 : 0;
    bool tail_ran = false;
    const bool at_slots = eff.rays_at_slots;
    w.rays_at_slots = at_slots;
    const bool fuse = eff.fused_trace;
    bool traced = false;  // this bounce's rays were traced with the last bounce's shadow rays
    for (uint32_t b = 0; b < iterations; ++b) {
      if (at_slots) {  // bounce b's rays in one buffer, the next bounce's in the other
        w.ray_o = (b & 1) ? ray_o_odd.get() : ray_o.get();
        w.ray_d = (b & 1) ? ray_d_odd.get() : ray_d.get();
        w.next_ray_o = (b & 1) ? ray_o.get() : ray_o_odd.get();
        w.next_ray_d = (b & 1) ? ray_d.get() : ray_d_odd.get();
      }
      const bool compacted = eff.compaction() && b > 0;
      const uint32_t* q = compacted ? (queue_in_shade ? bounce_queue(b) : queue.get()) : nullptr;
      const uint32_t* c =
          compacted ? (queue_in_shade ? w.alive_counts + b : count.get()) : nullptr;
      if (b == tail_from && b > 0) {
        launch_tail(sp, view, flat_params, cfg, sample, first, film_view(sample), w, q, c, traced,
                    stream);
        mark(timed, kTail);
        tail_ran = true;
        break;
      }
      if (!traced) {  // (else the last bounce's trace stage put its hits in place)
        if (b == 0 && use_cache && cache_valid) {
          launch_copy_hits(cached_hits.get(), w.hit, n(), stream);
        } else {
          launch_intersect(sp, view, flat_params, w, q, c, eff.dynamic_fetch, stream);
          if (b == 0 && use_cache) {
            launch_copy_hits(w.hit, cached_hits.get(), n(), stream);
            cache_valid = true;
          }
        }
        mark(timed, b == 0 ? kIntersectFirst : kIntersect);
      }
      if (eff.options.sort_materials) {
        launch_sort_by_material(view, w, q, c, sorted.get(), stream);
        q = sorted.get();
        c = w.sort_bins + 16;  // the live paths among the sorted slots
        mark(timed, kSort);
      }
      launch_shade(eff.shade_spec, view, cfg, sample, b, w, q, c,
                   queue_in_shade && b + 1 < iterations ? bounce_queue(b + 1) : nullptr, shadows,
                   stream);
      mark(timed, kShade);
      if (mnee) {  // manifold NEE's solves, before the shadow stage ends paths in the film
        launch_mnee(eff.shade_spec, view, flat_params, cfg, sample, b, w, stream);
        mark(timed, kMnee);
      }
      // Fused: this bounce's shadow rays with the next bounce's extension rays, if there is a
      // next bounce (also the tail's, with fused_tail: it then starts by shading their hits).
      traced = fuse && b + 1 < iterations && (eff.fused_tail || b + 1 != tail_from);
      if (traced) {
        WavefrontState next = w;  // the next bounce's rays (at their slots)
        next.ray_o = w.next_ray_o;
        next.ray_d = w.next_ray_d;
        launch_trace(sp, view, flat_params, next, shadows, b, first, film_view(sample), stream);
        mark(timed, kTrace);
      } else {
        launch_shadow(sp, view, flat_params, w, q, c, shadows, b, first, film_view(sample),
                      stream);
        mark(timed, kShadow);
      }
      if (b + 1 == iterations) {
        if (walks) launch_flush(w, first, film_view(sample), stream);
        break;
      }
      if (eff.compaction() && !queue_in_shade) {
        launch_compact(w, queue.get(), count.get(), cub_temp.get(), cub_temp.bytes(), stream);
        mark(timed, kCompact);
      }
      // Deep settings: stop once every path has ended (checked every 8 bounces).
      if (b >= 7 && (b + 1) % 8 == 0) {
        uint32_t left = 0;
        TRACER_CUDA_CHECK(cudaMemcpyAsync(&left, w.alive_counts + b + 1, sizeof(uint32_t),
                                          cudaMemcpyDeviceToHost, stream));
        TRACER_CUDA_CHECK(cudaStreamSynchronize(stream));
        if (left == 0) break;
      }
    }
    // (An early stop, every path ended, can come before the bounce chosen for the tail.)
    if (!tail_ran) tail_from = 0;
    // Extension rays of the bounces the stages ran (the tail counts its own).
    launch_add_alive(w.alive_counts, tail_from ? tail_from : iterations + 2,
                     w.counters + kCounterExtension, stream);
  }
};

CudaRenderer::CudaRenderer(int device) : impl_(std::make_unique<Impl>()) {
  impl_->device = device;
  TRACER_CUDA_CHECK(cudaSetDevice(device));
  TRACER_CUDA_CHECK(cudaGetDeviceProperties(&impl_->prop, device));
  TRACER_CUDA_CHECK(cudaStreamCreateWithFlags(&impl_->stream, cudaStreamNonBlocking));
}

CudaRenderer::~CudaRenderer() = default;

std::string CudaRenderer::device_name() const {
  const auto& p = impl_->prop;
  return std::string(p.name) + " (sm_" + std::to_string(p.major) + std::to_string(p.minor) + ", " +
         std::to_string(p.multiProcessorCount) + " SMs)";
}

void CudaRenderer::set_scene(const CompiledScene& scene, const IntegratorSettings& cfg) {
  Impl& m = *impl_;
  m.use_device();
  {
    const size_t bvh = bytes_of(scene.nodes()) + bytes_of(scene.prim_indices()) +
                       bytes_of(scene.bvh8().nodes) + bytes_of(scene.bvh8().prim_indices) +
                       bytes_of(scene.instance_bvh().nodes) +
                       bytes_of(scene.instance_bvh().prim_indices) + bytes_of(scene.instances());
    const size_t tris = bytes_of(scene.tri_verts()) + bytes_of(scene.tri_shading()) +
                        bytes_of(scene.tri_uvs()) + bytes_of(scene.inst_tri_verts()) +
                        bytes_of(scene.inst_tri_shading()) + bytes_of(scene.inst_tri_uvs());
    const InfiniteLightsData& inf = scene.infinite();
    const size_t tex = bytes_of(scene.texels()) +
                       (inf.image ? bytes_of(inf.image->rgba) : 0) + bytes_of(inf.func) +
                       bytes_of(inf.cond_cdf) + bytes_of(inf.marg_cdf);
    const size_t flat = bytes_of(scene.flat_list().prims) + bytes_of(scene.flat_list().info) +
                        bytes_of(scene.flat_list().tri_to_flat);
    const size_t rest = bytes_of(scene.materials()) + bytes_of(scene.lights()) +
                        bytes_of(scene.light_cdf()) + bytes_of(scene.light_tree().nodes) +
                        bytes_of(scene.light_tree().leaves) + bytes_of(scene.light_tree().trails);
    require_device_memory(bvh + tris + tex + flat + rest, scene_bytes(), "the scene",
                          "BVH " + gib(bvh) + ", triangles " + gib(tris) + ", textures and "
                          "environment " + gib(tex) + ", the rest " + gib(flat + rest),
                          device_name());
  }
  m.nodes.upload(scene.nodes());
  m.prim_indices.upload(scene.prim_indices());
  m.nodes8.upload(scene.bvh8().nodes);
  m.prim_indices8.upload(scene.bvh8().prim_indices);
  m.tri_verts.upload(scene.tri_verts());
  m.tri_shading.upload(scene.tri_shading());
  m.spheres.upload(scene.spheres());
  m.reflector_planes.upload(scene.reflector_planes());
  m.window_planes.upload(scene.window_planes());
  m.light_targets.upload(scene.light_targets());
  m.materials.upload(scene.materials());
  m.lights.upload(scene.lights());
  m.light_cdf.upload(scene.light_cdf());
  m.light_nodes.upload(scene.light_tree().nodes);
  m.light_leaves.upload(scene.light_tree().leaves);
  m.light_trails.upload(scene.light_tree().trails);
  m.tri_uvs.upload(scene.tri_uvs());
  m.instances.upload(scene.instances());
  m.inst_nodes.upload(scene.instance_bvh().nodes);
  m.inst_prim_indices.upload(scene.instance_bvh().prim_indices);
  m.inst_tri_verts.upload(scene.inst_tri_verts());
  m.inst_tri_shading.upload(scene.inst_tri_shading());
  m.inst_tri_uvs.upload(scene.inst_tri_uvs());
  m.textures.upload(scene.textures());
  m.texels.upload(scene.texels());
  const FlatList& fl = scene.flat_list();
  m.flat_available = fl.enabled;
  m.mnee_casters = mnee_has_casters(scene);
  m.flat_text = describe_flat_list(fl, uint32_t(scene.spheres().size()));
  m.flat.upload(fl.prims);
  m.flat_info.upload(fl.info);
  m.tri_to_flat.upload(fl.tri_to_flat);
  m.view = scene.view();
  m.flat_solids.upload(fl.solids);
  m.view.flat = m.view.flat_loop = fl.enabled ? m.flat.get() : nullptr;
  m.view.flat_solids = fl.enabled ? m.flat_solids.get() : nullptr;
  m.flat_params = make_flat_params(fl.enabled ? fl.prims : std::vector<FlatPrim>(),
                                   fl.enabled ? fl.solids : std::vector<FlatPrim>());
  m.view.flat_info = fl.enabled ? m.flat_info.get() : nullptr;
  m.view.tri_to_flat = fl.enabled ? m.tri_to_flat.get() : nullptr;
  m.view.nodes = m.nodes.get();
  m.view.prim_indices = m.prim_indices.get();
  m.node_count4 = scene.view().node_count;  // resolve() picks the 4- or the 8-wide tree
  m.view.tri_verts = m.tri_verts.get();
  m.view.tri_shading = m.tri_shading.get();
  m.view.spheres = m.spheres.get();
  m.view.reflector_planes = scene.reflector_planes().empty() ? nullptr : m.reflector_planes.get();
  m.view.window_planes = scene.window_planes().empty() ? nullptr : m.window_planes.get();
  m.view.light_targets = scene.light_targets().empty() ? nullptr : m.light_targets.get();
  m.view.materials = m.materials.get();
  m.view.lights = m.lights.get();
  m.view.light_cdf = m.light_cdf.get();
  m.view.light_tree.nodes = scene.view().light_tree.nodes ? m.light_nodes.get() : nullptr;
  m.view.light_tree.leaves = m.light_leaves.get();
  m.view.light_tree.trails = m.light_trails.get();
  m.view.tri_uvs = scene.tri_uvs().empty() ? nullptr : m.tri_uvs.get();
  m.view.instances = scene.instances().empty() ? nullptr : m.instances.get();
  m.view.inst_nodes = m.inst_nodes.get();
  m.view.inst_prim_indices = m.inst_prim_indices.get();
  m.view.inst_tri_verts = m.inst_tri_verts.get();
  m.view.inst_tri_shading = m.inst_tri_shading.get();
  m.view.inst_tri_uvs = scene.inst_tri_uvs().empty() ? nullptr : m.inst_tri_uvs.get();
  m.view.textures = m.textures.get();
  m.view.texels = m.texels.get();
  m.view.cpu_bvh = CpuBvhView();  // host memory: the device traverses the shared layout
  m.view.infinite = nullptr;
  if (scene.view().infinite) {
    const InfiniteLightsData& inf = scene.infinite();
    InfiniteLights dv = inf.view;
    if (inf.image) {
      m.env_texels.upload(inf.image->rgba);
      m.env_func.upload(inf.func);
      m.env_cond_cdf.upload(inf.cond_cdf);
      m.env_marg_cdf.upload(inf.marg_cdf);
      dv.texels = m.env_texels.get();
      dv.func = m.env_func.get();
      dv.cond_cdf = m.env_cond_cdf.get();
      dv.marg_cdf = m.env_marg_cdf.get();
    }
    m.distant.upload(inf.distant);
    dv.distant = inf.distant.empty() ? nullptr : m.distant.get();
    m.infinite.upload(std::vector<InfiniteLights>{dv});
    m.view.infinite = m.infinite.get();
  }
  m.point_lights.upload(scene.point_lights());
  m.view.point_lights = scene.point_lights().empty() ? nullptr : m.point_lights.get();
  m.features = scene.features();
  m.compiled = &scene;
  m.has_scene = true;
  set_settings(cfg);
}

void CudaRenderer::set_settings(const IntegratorSettings& cfg) {
  Impl& m = *impl_;
  m.use_device();
  m.cfg = cfg;
  m.cfg.guide = GuideView();
  // Light tracing with no path worth tracing or without jitter: none traced.
  const bool light_paths =
      cfg.light_tracing && m.compiled && light_tracing_has_paths(*m.compiled, cfg);
  if (!light_tracing_runs(m.cfg, light_paths)) m.cfg.light_tracing = 0;
  m.view.camera.width = cfg.width;
  m.view.camera.height = cfg.height;
  m.view.camera.aspect = float(cfg.width) / float(cfg.height);
  m.allocate();
  m.allocate_guide();
  m.tail_estimate.clear();
  m.resolve();  // (the first-bounce cache depends on the jitter, the kernel on guiding)
  reset();
}

void CudaRenderer::reset() {
  impl_->use_device();
  // O(1): the next sample overwrites the accumulator instead of adding to it.
  impl_->clear_counts();
  impl_->nonfinite = 0;
  impl_->cache_valid = false;
  impl_->aov_count[0] = impl_->aov_count[1] = 0;
  impl_->clear_guide();  // a new render learns anew
}

GuideStatus CudaRenderer::guide_status() const {
  const Impl& m = *impl_;
  return m.guiding ? GuideStatus::of(m.grid, m.next_sample, m.guide_builds,
                                     m.guide_learned_cells[0], m.guide_learned_cells[1],
                                     m.calibration)
                   : GuideStatus();
}

void CudaRenderer::set_aovs(bool on) {
  Impl& m = *impl_;
  m.use_device();
  if (on == m.aovs_on) return;
  m.aovs_on = on;
  if (m.has_scene) m.allocate_aovs();
}
bool CudaRenderer::aovs() const { return impl_->aovs_on; }
uint32_t CudaRenderer::aov_samples() const { return impl_->aov_count[0] + impl_->aov_count[1]; }

void CudaRenderer::set_gpu_options(const GpuOptions& o) {
  impl_->opts = o;
  impl_->chosen = o.kernel;
  impl_->kernel_forced = false;
  impl_->resolve();  // (may force another kernel: path guiding runs the wavefront)
  impl_->auto_step = 0;
  impl_->auto_ms[0] = impl_->auto_ms[1] = 0.0;
  impl_->cache_valid = false;
  impl_->tail_estimate.clear();
}

uint32_t CudaRenderer::samples_done() const { return impl_->samples; }
uint32_t CudaRenderer::next_sample() const { return impl_->next_sample; }
uint32_t CudaRenderer::half_samples(int half) const { return impl_->film_count[half & 1]; }
void CudaRenderer::set_next_sample(uint32_t index) {
  Impl& m = *impl_;
  if (m.guiding && index != m.next_sample)
    throw std::logic_error("CudaRenderer::set_next_sample: path guiding trains on the samples in "
                           "their order from 0 (sample " + std::to_string(index) +
                           " asked for, " + std::to_string(m.next_sample) + " next)");
  m.next_sample = index;
}
uint32_t CudaRenderer::width_times_height() const { return impl_->n(); }
uint64_t CudaRenderer::nonfinite_total() const { return impl_->nonfinite; }

std::string CudaRenderer::chosen_kernel() const {
  switch (impl_->chosen) {
    case KernelMode::kWavefront: return "wavefront";
    case KernelMode::kMegakernel: return "megakernel";
    case KernelMode::kAuto: return "auto (not decided yet)";
  }
  return "";
}

AutoKernelTimes CudaRenderer::auto_kernel_times() const {
  AutoKernelTimes t;
  t.wavefront_ms = impl_->auto_ms[0];
  t.megakernel_ms = impl_->auto_ms[1];
  return t;
}

size_t CudaRenderer::path_state_bytes_per_pixel() const {
  // 10 float4 arrays (8 + the odd bounces' rays), alive flag, two queues + shadow queue +
  // sorted queue + sort key, cached hit.
  return 10 * sizeof(float4) + 1 + 5 * sizeof(uint32_t) + sizeof(float4);
}

size_t CudaRenderer::scene_bytes() const {
  const Impl& m = *impl_;
  return m.nodes.bytes() + m.prim_indices.bytes() + m.nodes8.bytes() + m.prim_indices8.bytes() +
         m.tri_verts.bytes() + m.tri_shading.bytes() +
         m.spheres.bytes() + m.materials.bytes() + m.lights.bytes() + m.light_cdf.bytes() +
         m.light_nodes.bytes() + m.light_leaves.bytes() + m.light_trails.bytes() +
         m.env_texels.bytes() + m.env_func.bytes() + m.env_cond_cdf.bytes() +
         m.env_marg_cdf.bytes() + m.distant.bytes() + m.infinite.bytes() + m.point_lights.bytes() +
         m.flat.bytes() + m.flat_info.bytes() + m.tri_to_flat.bytes() + m.instances.bytes() +
         m.inst_nodes.bytes() + m.inst_prim_indices.bytes() + m.inst_tri_verts.bytes() +
         m.inst_tri_shading.bytes() + m.inst_tri_uvs.bytes();
}

FrameStats CudaRenderer::render(uint32_t spp) {
  Impl& m = *impl_;
  m.use_device();
  if (!m.has_scene) throw std::logic_error("CudaRenderer::render: no scene set");
  const auto start = std::chrono::steady_clock::now();
  FrameStats st;
  st.spp_added = spp;
  st.specialization = std::string(spec_label(m.eff.spec)) + "; " + m.accel_name();
  if (m.eff.shade_spec != m.eff.spec)
    st.specialization += std::string("; shade kernel: ") + spec_label(m.eff.shade_spec);
  if (const GpuOverride* cache = m.eff.find("first_bounce_cache"))
    st.note = "first-bounce cache disabled: " + cache->reason;
  st.gpu = m.eff;
  m.counters.zero_async(m.stream);
  m.clamp_sum.zero_async(m.stream);
  uint32_t wavefront_samples = 0;
  for (uint32_t k = 0; k < spp; ++k) {
    const uint32_t sample = m.next_sample + k;
    const bool first = m.film_count[sample & 1] == 0;  // it overwrites its film
    KernelMode mode = m.chosen;
    bool calibrating = false;
    if (mode == KernelMode::kAuto) {
      // Steps 0/1 warm both designs up, 2/3 time them; then keep the faster.
      mode = (m.auto_step % 2 == 0) ? KernelMode::kMegakernel : KernelMode::kWavefront;
      calibrating = m.auto_step >= 2;
    }
    // Timed: the first sample of a call, and all of auto's four (its first wavefront sample's
    // alive counts give the second the estimate its tail needs).
    // Path guiding's calibration samples (guide_host.h) are timed; the films' sums are kept
    // before each block.
    const bool calibrating_guide = m.guiding && !m.calibration.done() &&
                                   guide_calibrates(sample) && mode == KernelMode::kWavefront;
    const bool timed = k == 0 || m.chosen == KernelMode::kAuto || calibrating_guide;
    m.cfg.guide = m.guide_view(sample);
    if (calibrating_guide && guide_calibration_block_starts(sample)) {
      m.calibration_then.resize(m.n());
      m.calibration_sum.resize(1);
      launch_sum_films(m.film[0].get(), m.film[1].get(), m.calibration_then.get(), m.n(),
                       m.stream);
      if (sample == kGuideCalibrationStart) {
        m.calibration_base.resize(m.n());
        TRACER_CUDA_CHECK(cudaMemcpyAsync(m.calibration_base.get(), m.calibration_then.get(),
                                          m.calibration_then.bytes(), cudaMemcpyDeviceToDevice,
                                          m.stream));
        m.calibration_base_count = m.film_count[0] + m.film_count[1];
      }
    }
    const bool unguided = calibrating_guide && !guide_calibration_guided(sample);
    if (mode == KernelMode::kMegakernel) {
      m.megakernel_wave(sample, first, timed);
      m.light_wave(sample, timed);
    } else {
      if (unguided) std::swap(m.eff, m.eff_plain);
      m.wavefront_wave(sample, first, timed);
      if (unguided) std::swap(m.eff, m.eff_plain);
      m.light_wave(sample, timed);
      m.guide_after_sample(sample);
    }
    // The feature buffers after the sample's paths (outside its timed stages).
    if (m.aovs_on) {
      launch_aov(m.eff.spec, m.view, m.flat_params, m.cfg, sample, m.aov_count[sample & 1] == 0,
                 m.aov_film(), m.stream);
      ++m.aov_count[sample & 1];
    }
    if (timed) {
      StageTimes t;
      m.collect(t);
      if (k == 0) st.stages = t;
      if (calibrating) m.auto_ms[mode == KernelMode::kWavefront ? 0 : 1] = t.total();
      if (calibrating_guide) {
        m.calibration.add_time(!unguided, t.total() * 1e-3);
        if (guide_calibration_block_ends(sample) && m.calibration_base_count > 0) {
          launch_block_noise(m.film[0].get(), m.film[1].get(), m.calibration_then.get(),
                             m.calibration_base.get(), 1.0f / float(kGuideCalibrationBlock),
                             1.0f / float(m.calibration_base_count), m.n(),
                             m.calibration_sum.get(), m.stream);
          double noise = 0.0;
          TRACER_CUDA_CHECK(cudaMemcpyAsync(&noise, m.calibration_sum.get(), sizeof(double),
                                            cudaMemcpyDeviceToHost, m.stream));
          TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
          m.calibration.noise[!unguided] = noise;
        }
        if (m.guide_retired()) m.resolve();  // unguided from the next sample on
      }
      if (mode == KernelMode::kWavefront) {
        m.alive_counts.download(m.tail_estimate);
        m.tail_estimate[0] = m.n();
        if (k == 0) {
          st.stages.tail_from = m.tail_from;
          st.stages.rays_at_slots = m.eff.rays_at_slots;
          st.stages.fused_trace = m.eff.fused_trace;
          std::vector<uint32_t> alive = m.tail_estimate;
          while (alive.size() > 1 && alive.back() == 0) alive.pop_back();
          st.alive_per_bounce = alive;
          if (m.eff.queues_in_shade()) {
            std::vector<uint32_t> counts;
            m.shadow_counts.download(counts);
            auto trimmed = [](std::vector<uint32_t> v) {
              while (!v.empty() && v.back() == 0) v.pop_back();
              return v;
            };
            st.shadow_per_bounce = trimmed(std::vector<uint32_t>(
                counts.begin(), counts.begin() + m.shadow_stride));
            st.finished_per_bounce = trimmed(std::vector<uint32_t>(
                counts.begin() + m.shadow_stride, counts.begin() + 2 * m.shadow_stride));
          }
          if (m.eff.shade_spec & kSpecCaustics) {
            std::vector<uint32_t> counts;
            m.shadow_counts.download(counts);
            while (counts.size() > 2 * m.shadow_stride && counts.back() == 0) counts.pop_back();
            st.mnee_per_bounce.assign(counts.begin() + 2 * m.shadow_stride, counts.end());
          }
        }
      }
    }
    // The wavefront's extension rays (every path alive after a bounce traces one more segment)
    // are summed on the device (kCounterExtension), so samples run back to back without a wait.
    if (mode == KernelMode::kWavefront) ++wavefront_samples;
    ++m.film_count[sample & 1];
    if (m.chosen == KernelMode::kAuto && ++m.auto_step == 4) {
      m.chosen = m.auto_ms[0] <= m.auto_ms[1] ? KernelMode::kWavefront : KernelMode::kMegakernel;
    }
    st.kernel = mode == KernelMode::kWavefront ? "wavefront" : "megakernel";
  }
  unsigned long long c[kCounterCount] = {};
  TRACER_CUDA_CHECK(cudaMemcpyAsync(c, m.counters.get(), sizeof(c), cudaMemcpyDeviceToHost,
                                    m.stream));
  TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
  st.rays.camera = uint64_t(m.n()) * spp;
  st.rays.shadow = c[kCounterShadow];
  // The megakernel's segments include its camera rays.
  uint64_t mega_samples = 0;
  st.rays.extension = c[kCounterExtension];
  if (c[kCounterMegaSegments] > 0) {
    mega_samples = spp - wavefront_samples;
    st.rays.extension += c[kCounterMegaSegments] - uint64_t(m.n()) * mega_samples;
  }
  st.nonfinite = c[kCounterNonfinite];
  st.rays.walk_capped = c[kCounterWalkCapped];
  st.clamped = c[kCounterClamped];
  TRACER_CUDA_CHECK(cudaMemcpy(&st.clamped_luminance, m.clamp_sum.get(), sizeof(double),
                               cudaMemcpyDeviceToHost));
  st.rays.medium_leaks = c[kCounterMediumLeak];
  m.nonfinite += c[kCounterNonfinite];
  m.samples += spp;
  m.next_sample += spp;
  if (m.chosen != KernelMode::kAuto && m.opts.kernel == KernelMode::kAuto) {
    st.note += std::string(st.note.empty() ? "" : "; ") + "kernel auto chose " + chosen_kernel() +
               " (" + std::to_string(m.auto_ms[0]) + " ms wavefront vs " +
               std::to_string(m.auto_ms[1]) + " ms megakernel per sample)";
  }
  st.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return st;
}

ImageRGB CudaRenderer::image() const {
  Impl& m = *impl_;
  m.use_device();
  ImageRGB img;
  img.width = int(m.cfg.width);
  img.height = int(m.cfg.height);
  img.pixels.assign(size_t(m.n()) * 3, 0.0f);
  if (m.samples == 0) return img;
  DeviceBuffer<float> rgb(size_t(m.n()) * 3);
  const float inv = 1.0f / float(m.samples);
  const Impl::MeanFilms f = m.mean_films();
  launch_resolve(f.a, inv, f.b, f.both ? inv : 0.0f, m.n(), rgb.get(), m.stream);
  TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
  std::vector<float> host;
  rgb.download(host);
  img.pixels = std::move(host);
  return img;
}

double measure_copy_bandwidth_gbs() {
  const size_t bytes = size_t(1) << 30;
  DeviceBuffer<uint8_t> a(bytes), b(bytes);
  TRACER_CUDA_CHECK(cudaMemset(a.get(), 1, bytes));
  cudaEvent_t e0, e1;
  TRACER_CUDA_CHECK(cudaEventCreate(&e0));
  TRACER_CUDA_CHECK(cudaEventCreate(&e1));
  for (int i = 0; i < 2; ++i)  // warm-up
    TRACER_CUDA_CHECK(cudaMemcpy(b.get(), a.get(), bytes, cudaMemcpyDeviceToDevice));
  constexpr int kReps = 10;
  TRACER_CUDA_CHECK(cudaEventRecord(e0));
  for (int i = 0; i < kReps; ++i)
    TRACER_CUDA_CHECK(cudaMemcpyAsync(i % 2 ? a.get() : b.get(), i % 2 ? b.get() : a.get(), bytes,
                                      cudaMemcpyDeviceToDevice));
  TRACER_CUDA_CHECK(cudaEventRecord(e1));
  TRACER_CUDA_CHECK(cudaEventSynchronize(e1));
  float ms = 0.0f;
  TRACER_CUDA_CHECK(cudaEventElapsedTime(&ms, e0, e1));
  cudaEventDestroy(e0);
  cudaEventDestroy(e1);
  return 2.0 * double(bytes) * kReps / (ms * 1e-3) / 1e9;
}

void CudaRenderer::half_images(ImageRGB* even, ImageRGB* odd) const {
  Impl& m = *impl_;
  m.use_device();
  const uint32_t* counts = m.film_count;
  ImageRGB* outs[2] = {even, odd};
  DeviceBuffer<float> rgb(size_t(m.n()) * 3);
  for (int k = 0; k < 2; ++k) {
    if (!outs[k]) continue;
    outs[k]->width = int(m.cfg.width);
    outs[k]->height = int(m.cfg.height);
    outs[k]->pixels.assign(size_t(m.n()) * 3, 0.0f);
    if (counts[k] == 0) continue;
    launch_resolve(m.film[k].get(), 1.0f / float(counts[k]), m.film[k].get(), 0.0f, m.n(),
                   rgb.get(), m.stream);
    TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
    rgb.download(outs[k]->pixels);
  }
}

void CudaRenderer::half_sums(float* even, float* odd) const {
  Impl& m = *impl_;
  m.use_device();
  float* outs[2] = {even, odd};
  const size_t bytes = size_t(m.n()) * 3 * sizeof(float);
  DeviceBuffer<float> rgb(size_t(m.n()) * 3);
  for (int h = 0; h < 2; ++h) {
    if (m.film_count[h] == 0) {  // the film holds stale memory
      std::memset(outs[h], 0, bytes);
      continue;
    }
    launch_resolve(m.film[h].get(), 1.0f, m.film[h].get(), 0.0f, m.n(), rgb.get(), m.stream);
    TRACER_CUDA_CHECK(cudaMemcpyAsync(outs[h], rgb.get(), bytes, cudaMemcpyDeviceToHost, m.stream));
    TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
  }
}

AovImages CudaRenderer::aov_images(int half) const {
  Impl& m = *impl_;
  m.use_device();
  AovImages out;
  const uint32_t* counts = m.aov_count;
  if (!m.aovs_on || counts[0] + counts[1] == 0) return out;
  TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
  const uint32_t count = half < 0 ? counts[0] + counts[1] : counts[half & 1];
  const size_t n = m.n();
  out.albedo = make_image(int(m.cfg.width), int(m.cfg.height));
  out.normal = make_image(int(m.cfg.width), int(m.cfg.height));
  out.depth.assign(n, 0.0f);
  const float inv = count > 0 ? 1.0f / float(count) : 0.0f;
  std::vector<float4> a, b;
  for (int h = 0; h < 2; ++h) {
    // A half that has no sample yet holds stale memory.
    if ((half >= 0 && h != half) || counts[h] == 0) continue;
    m.aov_a[h].download(a);
    m.aov_b[h].download(b);
    for (size_t i = 0; i < n; ++i) {
      out.albedo.pixels[3 * i + 0] += a[i].x * inv;
      out.albedo.pixels[3 * i + 1] += a[i].y * inv;
      out.albedo.pixels[3 * i + 2] += a[i].z * inv;
      out.depth[i] += a[i].w * inv;
      out.normal.pixels[3 * i + 0] += b[i].x * inv;
      out.normal.pixels[3 * i + 1] += b[i].y * inv;
      out.normal.pixels[3 * i + 2] += b[i].z * inv;
    }
  }
  std::vector<uint2> ids;
  m.aov_ids.download(ids);
  out.material.resize(n);
  out.prim.resize(n);
  for (size_t i = 0; i < n; ++i) {
    out.material[i] = ids[i].x;
    out.prim[i] = ids[i].y;
  }
  return out;
}

ImageRGB CudaRenderer::denoised_image(DenoiseInfo* info) const {
  Impl& m = *impl_;
  m.use_device();
  if (m.samples == 0) return Renderer::denoised_image(info);
  const auto start = std::chrono::steady_clock::now();
  const size_t n3 = size_t(m.n()) * 3;
  for (auto* b : {&m.dn_color, &m.dn_out}) b->resize(n3);
  const float inv = 1.0f / float(m.samples);
  const Impl::MeanFilms f = m.mean_films();
  launch_resolve(f.a, inv, f.b, f.both ? inv : 0.0f, m.n(), m.dn_color.get(), m.stream);
  const uint32_t aovs = m.aovs_on ? m.aov_count[0] + m.aov_count[1] : 0;
  if (aovs > 0) {
    for (auto* b : {&m.dn_albedo, &m.dn_normal}) b->resize(n3);
    launch_aov_resolve(m.aov_film(), m.aov_count[0] > 0 ? 1.0f / aovs : 0.0f,
                       m.aov_count[1] > 0 ? 1.0f / aovs : 0.0f, m.dn_albedo.get(),
                       m.dn_normal.get(), m.stream);
  }
  TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
  if (!denoise_device_images(m.dn_color.get(), aovs ? m.dn_albedo.get() : nullptr,
                             aovs ? m.dn_normal.get() : nullptr, m.dn_out.get(), int(m.cfg.width),
                             int(m.cfg.height), info))
    return Renderer::denoised_image(info);  // a CPU denoiser: through the host
  ImageRGB out;
  out.width = int(m.cfg.width);
  out.height = int(m.cfg.height);
  m.dn_out.download(out.pixels);
  if (info)  // the resolves and the copy back included
    info->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                   .count();
  return out;
}

void CudaRenderer::display_to_device(void* rgba8, float exposure_scale, ToneMap op) const {
  Impl& m = *impl_;
  m.use_device();
  const float inv = m.samples > 0 ? 1.0f / float(m.samples) : 0.0f;
  // With one film holding samples, read it twice at half the weight.
  const Impl::MeanFilms f = m.mean_films();
  launch_display(f.a, f.b, f.both ? inv : 0.5f * inv, m.n(), exposure_scale, int(op),
                 static_cast<uint32_t*>(rgba8), m.stream);
  TRACER_CUDA_CHECK(cudaStreamSynchronize(m.stream));
}

void CudaRenderer::display_rgba8(std::vector<uint32_t>& out, float exposure_scale,
                                 ToneMap op) const {
  impl_->use_device();
  DeviceBuffer<uint32_t> dev(impl_->n());
  if (impl_->samples == 0) TRACER_CUDA_CHECK(cudaMemset(dev.get(), 0, dev.bytes()));
  else display_to_device(dev.get(), exposure_scale, op);
  dev.download(out);
}

bool cuda_pin_host(void* ptr, size_t bytes) {
  if (cudaHostRegister(ptr, bytes, cudaHostRegisterPortable) == cudaSuccess) return true;
  cudaGetLastError();
  return false;
}
void cuda_unpin_host(void* ptr) {
  if (cudaHostUnregister(ptr) != cudaSuccess) cudaGetLastError();
}

int cuda_device_count() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();  // clear the sticky error of the failed query
    return 0;
  }
  return count;
}

std::unique_ptr<Renderer> make_cuda_renderer(std::string* why_not, int device) {
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess || count == 0) {
    if (why_not)
      *why_not = err != cudaSuccess ? std::string("no CUDA device (") + cudaGetErrorName(err) +
                                          ": " + cudaGetErrorString(err) + ")"
                                    : "no CUDA device found";
    cudaGetLastError();  // clear the sticky error of the failed query
    return nullptr;
  }
  try {
    if (device < 0 || device >= count) {
      if (why_not)
        *why_not = "CUDA device " + std::to_string(device) + " asked for; this machine has " +
                   std::to_string(count);
      return nullptr;
    }
    return std::make_unique<CudaRenderer>(device);
  } catch (const std::exception& e) {
    if (why_not) *why_not = e.what();
    return nullptr;
  }
}

}  // namespace tracer
