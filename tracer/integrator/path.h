// The per-path stages shared by both backends: generate a camera ray, shade a hit (emission with
// MIS, next-event estimation, BSDF sampling, Russian roulette), and a whole-path loop built from
// them. The CUDA wavefront runs the same stages one kernel per stage; the CPU and the megakernel
// run trace_path. Unidirectional path tracing as in Veach (1997) ch. 9 / pbrt-v4 sec. 13.4.
#pragma once

#include "camera/filter.h"
#include "core/rng.h"
#include "core/sobol.h"
#include "integrator/guide.h"
#include "integrator/manifold.h"
#include "materials/fresnel.h"
#include "integrator/lights.h"
#include "integrator/medium.h"

namespace tracer {

struct IntegratorSettings {
  uint32_t width = 1, height = 1;
  uint32_t max_depth = 8;  // maximum number of path segments; the camera ray is the first
  uint32_t rr_start_depth = 4;
  uint32_t seed = 0;
  uint32_t nee = 1, mis = 1, russian_roulette = 1;
  // Manifold next-event estimation through smooth glass (render.mnee): only code compiled with
  // kFeatureCaustics reads it (the CPU's, the wavefront's caustic shade kernels).
  uint32_t mnee = 0;
  // Light tracing of caustics (render.light_tracing; integrator/light_path.h): the path tracer
  // leaves the paths it covers to it (kPathLightTraced). Needs jittered samples.
  uint32_t light_tracing = 0;
  uint32_t jitter = 1;  // 0: every sample goes through the pixel centre (enables hit caching)
  float clamp = 0.0f;   // > 0: scale each sample down to at most this much per channel (biased)
  // kSamplerRandom (PCG32), kSamplerSobol or kSamplerSobolPairs (core/sobol.h)
  uint32_t sampler = kSamplerSobol;
  // The pixel filter (camera/filter.h) and its radius in pixels, applied to jittered samples.
  PixelFilter filter = PixelFilter::kBox;
  float filter_radius = 0.5f;
  // How next-event estimation chooses a light: kLightSamplerUniform, kLightSamplerPower or
  // kLightSamplerBvh (scene/light_tree_view.h, integrator/lights.h).
  uint32_t light_sampler = kLightSamplerBvh;
  // Path guiding (render.guiding): asked for. The renderer fills `guide` with its guide's state
  // for each sample (integrator/guide.h); only code compiled with kFeatureGuiding reads it.
  uint32_t guiding = 0;
  GuideView guide;
};

// The dimension pairs of the Sobol sampler: each draw of a vertex has its own (a 1D draw takes
// the first coordinate of its pair). The camera vertex is bounce 0, surface vertex k bounce k.
enum CameraDims : uint32_t { kDimJitter = 0, kDimLens = 1 };
// (Pair 0 of a surface vertex is unused: the light point's first coordinate also chooses the
// light, see sample_light_2d, and path guiding splits the BSDF's pair, see shade_path.)
enum VertexDims : uint32_t {
  kDimLightPoint = 1,
  kDimBsdf = 2,
  kDimLobe = 3,
  kDimRoulette = 4,
};

// The random numbers of one surface vertex, from either sampler. The random sampler draws them
// all at once, in this order, from the vertex's PCG32 stream; the Sobol sampler computes each
// only where it is used (a point costs about as much as a ray-box test, and the light, lobe and
// roulette draws are often not needed).
struct VertexSampler {
  bool sobol;
  SobolVertex q;
  float pcg_lobe, pcg_rr;
  vec2 pcg_light, pcg_bsdf;

  TRACER_HD VertexSampler(const IntegratorSettings& cfg, uint32_t pixel, uint32_t sample,
                          uint32_t bounce)
      : sobol(cfg.sampler != kSamplerRandom),
        q(pixel, sample, bounce, cfg.seed, cfg.sampler == kSamplerSobolPairs) {
    if (!sobol) {
      Pcg32 rng = make_path_rng(pixel, sample, bounce, cfg.seed);
      rng.next_float();  // unused, so that each later draw keeps its place in the stream
      pcg_light = rng.next_2d();
      pcg_bsdf = rng.next_2d();
      pcg_lobe = rng.next_float();
      pcg_rr = rng.next_float();
    }
  }
  TRACER_HD vec2 light() const { return sobol ? q.get_2d(kDimLightPoint) : pcg_light; }
  TRACER_HD vec2 bsdf() const { return sobol ? q.get_2d(kDimBsdf) : pcg_bsdf; }
  TRACER_HD float lobe() const { return sobol ? q.get_1d(kDimLobe) : pcg_lobe; }
  TRACER_HD float rr() const { return sobol ? q.get_1d(kDimRoulette) : pcg_rr; }
};

// Whether path guiding samples at a vertex of this BSDF: lobes wide enough for a histogram of
// 0.05 sr bins to help (diffuse ones, rough ones from kGuideMinRoughness up). A narrow glossy lobe
// is sampled better by itself: the guide's directions would mostly miss it, and the BSDF's would
// be weighed by twice their density's inverse.
TRACER_HD TRACER_INLINE bool guide_wide_bsdf(const Material& m, MaterialType type) {
  switch (type) {
    case MaterialType::kDiffuse:
    case MaterialType::kCoatedDiffuse:
    case MaterialType::kDiffuseTransmission: return true;
    case MaterialType::kConductor:
      return glm::min(m.roughness, m.roughness_bitangent()) >= kGuideMinRoughness;
    case MaterialType::kDielectric: return m.roughness >= kGuideMinRoughness;
    default: return false;
  }
}

// Where light tracing (render.light_tracing; integrator/light_path.h) joins its paths to the
// camera, and so which camera vertices' paths it may take: wide lobes (guide_wide_bsdf: diffuse
// ones, rough ones from kGuideMinRoughness up), glossy casters excepted (above). Through a narrow
// glossy lobe a connection's BSDF value is large and rare, a firefly that the camera's own BSDF
// samples avoid.
static_assert(kLightTraceMetalRoughness == kGuideMinRoughness,
              "a metal is a glossy caster exactly where its lobe is not wide");
TRACER_HD TRACER_INLINE bool light_trace_connects(const Material& m, MaterialType type) {
  return guide_wide_bsdf(m, type) && !light_trace_glossy_caster(m, type);
}

// The optional radiance clamp: a sample brighter than `clamp` in any channel is scaled down to
// it. This trades fireflies for bias, so the luminance it removes is returned for reporting.
TRACER_HD TRACER_INLINE vec3 clamp_radiance(vec3 L, float clamp, float* removed) {
  *removed = 0.0f;
  if (clamp <= 0.0f) return L;
  const float m = glm::max(L.x, glm::max(L.y, L.z));
  if (!(m > clamp)) return L;
  const vec3 c = L * (clamp / m);
  *removed = luminance(L - c);
  return c;
}

enum PathFlags : uint32_t {
  kPathPrevSpecular = 1u << 0,  // the last bounce was a delta lobe: no MIS on the next emitter
  kPathInMedium = 1u << 1,      // inside a subsurface medium (PathState::medium)
  kPathWalkCapped = 1u << 2,    // ended: the random walk hit kMaxWalkSteps (counted)
  kPathMediumLeak = 1u << 3,    // ended: left a medium without crossing its boundary (counted)
  // Manifold NEE (cfg.mnee): the last non-delta vertex sampled the lights (its offset origin in
  // PathState::mnee_o); the refractions since (1 or 2: bits 5, 6) and whether anything else (a
  // reflection, a third refraction) came since. Emission reached through exactly one or two
  // refractions, or one reflection, is not added where manifold NEE found that path from the
  // vertex (shade_path).
  kPathMneeFrom = 1u << 4,
  kPathMneeRefract1 = 1u << 5,
  kPathMneeRefract2 = 1u << 6,
  kPathMneeOther = 1u << 7,
  kPathMneeMirror = 1u << 8,  // ... or exactly one reflection (MneeSolver: a mirror sphere, a flat reflector)
  // Light tracing (cfg.light_tracing): the camera's vertex (the first, or the second behind a
  // window the camera ray refracted through: set there at the first, path_behind_window) has a
  // wide lobe (light_trace_connects) and scattered by it, and no subsurface material came since,
  // so emission reached by delta events from a non-delta vertex is the light tracer's
  // (integrator/light_path.h), not added here.
  kPathLightTraced = 1u << 9,
};
// The wavefront keeps the flags in 10 bits beside PathState::prev_normal's 12 (cuda/kernels.h).
static_assert(kPathLightTraced < (1u << 10), "PathFlags must fit in 10 bits");

struct PathState {
  Ray ray;
  vec3 throughput;
  uint32_t pixel;
  vec3 radiance;
  uint32_t sample;
  // Solid-angle pdf of the BSDF sample that produced `ray`; negative where that vertex was a
  // glossy caster on a light-traced path (lt_caster in shade_path: the area light `ray` reaches is
  // the light tracer's; MIS reads the magnitude).
  float prev_pdf;
  uint32_t depth;  // segments traced so far, counting `ray`
  uint32_t flags;
  uint32_t medium;       // material of the medium the path is in, when kPathInMedium
  uint32_t walk_steps;   // scattering events in the current random walk
  uint32_t origin_prim;  // the triangle `ray` leaves from (skipped by its traversal), or kInvalid
  // The geometric normal of the vertex `ray` leaves from, as pack_light_normal codes it (bvh
  // light sampler only): with the ray's origin, the context of the light tree's pmf for MIS.
  uint32_t prev_normal;
  // Manifold NEE (kPathMneeFrom): the offset origin of the last vertex that sampled the lights,
  // and its normal's light-tree code (as prev_normal), from which its light was chosen.
  vec3 mnee_o;
  uint32_t mnee_normal;
};

// A shadow ray for next-event estimation: if nothing blocks it, `contribution` is added.
struct ShadowRequest {
  Ray ray;
  vec3 contribution;
  uint32_t target_prim;  // the light primitive aimed at, ignored by the occlusion test
  uint32_t origin_prim;  // the triangle it leaves from, also ignored (kInvalid for spheres)
  bool valid;
};

template <uint32_t F = kAllFeatures>
TRACER_HD inline void generate_path(const SceneView& s, const IntegratorSettings& cfg,
                                    uint32_t pixel, uint32_t sample, PathState& st) {
  vec2 jitter, lens;
  if (cfg.sampler != kSamplerRandom) {
    const SobolVertex q(pixel, sample, 0, cfg.seed, cfg.sampler == kSamplerSobolPairs);
    jitter = cfg.jitter ? q.get_2d(kDimJitter) : vec2(0.5f);
    lens = q.get_2d(kDimLens);
  } else {
    Pcg32 rng = make_path_rng(pixel, sample, 0, cfg.seed);
    jitter = cfg.jitter ? rng.next_2d() : vec2(0.5f);
    lens = rng.next_2d();
  }
  if (cfg.jitter && (cfg.filter != PixelFilter::kBox || cfg.filter_radius != 0.5f)) {
    // The filter moves the sample about the pixel centre; rejection draws come from a stream
    // of their own (the "bounce" 0xfffe is never a real vertex's).
    Pcg32 extra = make_path_rng(pixel, sample, 0xfffeu, cfg.seed);
    auto next = [&extra]() { return extra.next_float(); };
    jitter = vec2(0.5f + sample_filter_1d(cfg.filter, cfg.filter_radius, jitter.x, next),
                  0.5f + sample_filter_1d(cfg.filter, cfg.filter_radius, jitter.y, next));
  }
  const uint32_t y = divide_small(pixel, cfg.width);
  st.ray = s.camera.template generate_ray<F>(pixel - y * cfg.width, y, jitter, lens);
  st.throughput = vec3(1.0f);
  st.radiance = vec3(0.0f);
  st.pixel = pixel;
  st.sample = sample;
  st.prev_pdf = 0.0f;
  st.depth = 1;
  st.flags = kPathPrevSpecular;  // emitters seen directly count in full
  st.medium = 0;
  st.walk_steps = 0;
  st.origin_prim = kInvalid;
  st.prev_normal = 0;
}

// A ray leaving surface point p (geometric normal ng) in unit direction d, its origin offset to
// the side d goes to so that it cannot re-hit the surface.
TRACER_HD TRACER_INLINE Ray spawn_ray(vec3 p, vec3 ng, vec3 d) {
  Ray r;
  r.o = offset_ray_origin(p, glm::dot(d, ng) > 0.0f ? ng : -ng);
  r.d = d;
  r.tmax = kInfinity;
  r.pad = 0.0f;
  return r;
}

// A shadow ray from p (normal n_p, already facing the target) to point q on a light (normal
// n_q). Both ends are offset off their surfaces, so tmax ends before the light; the occlusion
// test also skips the light primitive itself. No fixed epsilon is involved.
TRACER_HD TRACER_INLINE Ray spawn_ray_to(vec3 p, vec3 n_p, vec3 q, vec3 n_q) {
  const vec3 from = offset_ray_origin(p, n_p);
  const vec3 to = offset_ray_origin(q, glm::dot(n_q, p - q) > 0.0f ? n_q : -n_q);
  const vec3 d = to - from;
  const float len = glm::length(d);
  Ray r;
  r.o = from;
  r.d = len > 0.0f ? d * fast_rcp(len) : vec3(0.0f, 0.0f, 1.0f);
  r.tmax = len;
  r.pad = 0.0f;
  return r;
}

TRACER_HD TRACER_INLINE bool is_black(vec3 c) {
  return c.x <= 0.0f && c.y <= 0.0f && c.z <= 0.0f;
}

// Manifold next-event estimation (render.mnee; integrator/manifold.h): light reaches a
// non-delta vertex through smooth glass or by a smooth reflection, where a shadow ray is blocked
// or turned away and only a BSDF-sampled path could find it. shade_path fills an MneeRequest;
// mnee_resolve runs its solves (MneeSolver: the chains through flat glass, through glass spheres,
// off mirror spheres and planes of flat reflectors), on the CPU right after shading and in the
// wavefront's mnee stage.

// Whether the light at y (primitive light_prim, unit normal ny) emits towards q, the last vertex
// of a chain from o: a one-sided light from its front only. A sphere light's point must also
// face o, whose cone of the sphere is all that sample_light draws points from.
template <uint32_t F>
TRACER_HD inline bool mnee_light_faces(const SceneView& s, uint32_t light_prim, vec3 y, vec3 ny,
                                       vec3 o, vec3 q) {
  const bool sphere = (F & kFeatureSpheres) && light_prim >= s.tri_count;  // as sample_light
  const uint32_t material = sphere ? s.spheres[light_prim - s.tri_count].material
                                   : s.tri_shading[light_prim].material;
  return material_emits(s.materials[material], glm::dot(ny, q - y) > 0.0f) &&
         (!sphere || glm::dot(ny, o - y) > 0.0f);
}

// Manifold NEE through glass spheres and off mirror spheres: the spheres it tries (the first ones
// of the scene's list; a scene of many spheres would pay a solve per sphere at every vertex).
constexpr uint32_t kMneeMaxSpheres = 16;

// Which casters a solve tries: every one, or the one a BSDF-sampled path left (mnee_resolve's
// partition): flat glass, one sphere (its index in s.spheres, below kMneeMaxSpheres) or one plane
// of flat reflectors (kMneeMaxSpheres + its index in s.reflector_planes).
constexpr uint32_t kMneeEveryCaster = kInvalid;
constexpr uint32_t kMneeFlatGlass = kInvalid - 1;
constexpr uint32_t kMneeNoCaster = kInvalid - 2;
constexpr uint32_t kMneeOneRefraction = kInvalid - 3;  // one smooth glass surface (water)

// Manifold NEE's work at one vertex (shade_path fills it; mnee_resolve does it): on the CPU
// right after shading, in the wavefront in a stage of its own (the mnee kernel: the solves and
// their rays in full warps, out of the shade kernel's registers).
struct MneeRequest {
  bool connect = false;    // the connection's arguments follow
  bool partition = false;  // an emission hit whose contribution manifold NEE may own
  bool mirror = false;     // ... reached off a mirror sphere (else through two refractions)
  bool single = false;     // ... reached through one refraction (a receiver under water)
  uint32_t depth = 0;      // the vertex's depth (PathState::depth when it was shaded)
  // connect: the vertex, its viewer's side, the frame's normal and wo in it, its BSDF, the light
  // sample (le: the light's front radiance times the path's throughput) and the segments left
  // before the depth limit.
  vec3 p, ng_viewer, frame_n, wo;
  Material m;
  LightSample ls;
  uint32_t segments = 0;
  // partition: the vertex that sampled the lights (its offset origin and its normal's light-tree
  // code), the light point reached (primitive, geometric normal, the light it belongs to), the
  // origin of the segment that reached it and what the emission adds unless manifold NEE owns it.
  vec3 from_o, hit_p, hit_ng, seg_o, contribution;
  uint32_t from_normal = 0, hit_prim = kInvalid, hit_light = kInvalid;
};

// A ray manifold NEE's solver asks for, and what it needs of the answer: the nearest hit (a
// shadow ray's: only whether there is one before its tmax).
struct MneeRay {
  Ray ray;
  uint32_t skip = kInvalid;  // a primitive the ray ignores (a shadow ray's light)
  bool shadow = false;
};
struct MneeHit {
  bool valid = false;
  uint32_t prim = kInvalid, material = 0;
  vec3 p = vec3(0.0f), ng = vec3(0.0f), ns = vec3(0.0f);
};

template <uint32_t F>
TRACER_HD inline MneeHit mnee_trace(const SceneView& s, const MneeRay& r) {
  MneeHit a;
  const Hit h = intersect_closest<F>(s, r.ray, r.skip);
  a.valid = h.valid();
  a.prim = h.prim;
  if (a.valid && !r.shadow) {
    const SurfaceHit hs = make_surface_hit<F>(s, r.ray, h);
    a.p = hs.p;
    a.ng = hs.ng;
    a.ns = hs.ns;
    a.material = hs.material;
  }
  return a;
}

// Triangle `prim` of the scene (not of an instance) as the one-refraction chain's surface: its
// plane, and its interpolated normals where it has them (SmoothSurface).
TRACER_HD inline SmoothSurface mnee_triangle_surface(const SceneView& s, uint32_t prim) {
  const TriangleVerts tv = load_triangle(s.tri_verts, prim);
  const TriangleShading& ts = s.tri_shading[prim];
  const vec3 z(0.0f);
  const bool normals = ts.has_normals != 0;  // as make_surface_hit
  return smooth_triangle(tv.v0, tv.v1, tv.v2, normals ? ts.n0 : z, normals ? ts.n1 : z,
                         normals ? ts.n2 : z, s.materials[ts.material].ior);
}

// Manifold NEE's solves for one request, as a machine that asks for one ray at a time (next) and
// is handed its hit: the caller traces every ray at one place, so that on the GPU a warp's
// threads trace together whatever each is solving, through one copy of the traversal's code (the
// stage was bound by fetching instructions while each solve inlined its own rays), and Newton's
// method too is written once. For each of the request's two tasks (the partition's solve, then
// the connection's) it finds every chain from o to the light point y (on light_prim, unit normal
// ny) within `segments` of the depth limit, of the casters `only` names:
// - through flat glass (faces of meshes and boxes; 3 segments): the smooth glass the straight
//   segment meets first and the surface where the ray refracted there leaves it (in and out of
//   one piece of glass) seed the chain, Hanika et al.'s seed; seeded from o's side, and where
//   glass is in the way but that fails (a way in through one face of a box that would leave
//   through another by total internal reflection) from the light's. Through parallel faces (a
//   pane, a slab) manifold_slab solves it in one dimension first, then Newton's method in 3D;
// - through one smooth glass surface (2 segments: a receiver under water, or a light in it):
//   where the straight segment's first hit from o is a glass triangle and the ray refracted there
//   does not meet that glass again (it leaves the glass, or is totally reflected), Newton's
//   method on the mesh: each step solved on the current triangle (its interpolated normals,
//   SmoothSurface) and put back on the mesh by a ray from o (Hanika et al.'s
//   re-projection), which may land on another triangle of that glass (a wavy water surface of
//   many small triangles), halved while it does not lower |C|;
// - through each glass sphere of the first kMneeMaxSpheres (3): every chain in the plane of o, y
//   and the centre (SphereChainScan), polished by Newton in 3D;
// - off each mirror sphere (sphere_reflection_chain, polished by Newton) and each plane of flat
//   smooth reflectors (SceneView::reflector_planes: glass's Fresnel reflection, mirrors, smooth
//   conductors; the line to y's mirror image in the plane within the bounds of its triangles:
//   exact) (2): the one reflection.
// Each chain's segments must then be what rays see: each reaches the next vertex, on the same
// material and surface, whose shading normal is the surface's (interpolated normals only on the
// one-refraction chain; no mapped normals; a reflector: a triangle of the plane or the sphere,
// seen first from o), the last one
// free to the light, which must emit towards its last vertex (mnee_light_faces). Its throughput:
// the transmissions as the BSDF weighs them (Fresnel, tint, the eta^2 of radiance, Beer-Lambert
// absorption inside), or the reflectance (a mirror's or smooth conductor's, or glass's Fresnel
// reflection, untinted as the BSDF's). Each chain is a function of (o, y) alone, so that a
// BSDF-sampled path can ask whether this estimator covers it (the partition).
template <uint32_t F>
struct MneeSolver {
  enum Phase : uint8_t {
    kTask, kSeed, kWalk, kCheck, kSingle, kSingleStep, kSingleProject, kCasters, kSphereChains,
    kShadow
  };
  Phase phase = kTask;
  int task = -1;  // 0: the partition's solve, 1: the connection's
  // The task's ends, its segments left and the casters it tries.
  vec3 o = vec3(0.0f), y = vec3(0.0f), ny = vec3(0.0f);
  uint32_t light_prim = kInvalid, segments = 0, only = kMneeEveryCaster;
  float dist = 0.0f;
  // The chain being solved or checked, its surfaces' materials, the ray asked for last.
  ManifoldChain ch;
  uint32_t material[kManifoldMaxChain] = {0, 0};
  Ray ray;
  // The flat glass's seed: from o's side (0) or the light's (1), its ray's step (0, 1), whether
  // that side met glass first.
  int side = 0, seed_step = 0;
  bool glass = false;
  // The one-refraction chain: its seed's triangle and point; whether the chain being solved is
  // it; its walk's constraint values and |C|, Newton step (in the triangle's plane), iterations
  // and the step's halvings.
  uint32_t single_prim = kInvalid, single_it = 0, single_halving = 0;
  vec3 single_p = vec3(0.0f);
  bool single = false;
  float single_c[2] = {0.0f, 0.0f}, single_norm = 0.0f;
  vec2 single_step = vec2(0.0f);
  SmoothChain sch;

  // The chain being checked (the one-refraction chain's or ch): its length, vertex i and the
  // normals there.
  // (Without kFeatureSingleRefraction the one-refraction chain's code is not compiled.)
  static constexpr bool kSingleChain = (F & kFeatureSingleRefraction) != 0;
  TRACER_HD bool on_single() const { return kSingleChain && single; }
  TRACER_HD uint32_t chain_k() const { return on_single() ? 1u : ch.k; }
  TRACER_HD vec3 vertex(uint32_t i) const { return on_single() ? sch.p[0] : ch.p[i]; }
  TRACER_HD vec3 vertex_normal(uint32_t i) const {
    return on_single() ? sch.surface[0].normal(sch.p[0]) : ch.surface[i].normal(ch.p[i]);
  }
  TRACER_HD vec3 vertex_move_normal(uint32_t i) const {
    return on_single() ? sch.surface[0].n : ch.surface[i].move_normal(ch.p[i]);
  }
  // The check: the segment asked for, its origin, the throughput so far; a reflection's caster.
  uint32_t segment = 0, caster = kMneeNoCaster;
  vec3 from = vec3(0.0f), throughput = vec3(1.0f);
  Phase after_check = kCasters;
  bool reflection = false;
  // The casters: the next one, the spheres tried (the first of the list), their number with
  // the planes; a glass sphere's chains.
  uint32_t next_caster = 0, spheres = 0, casters = 0;
  SphereChainScan scan;
  // What the solves give: whether the partition's path is covered, the connection's sum.
  bool covered = false;
  vec3 sum = vec3(0.0f);

  // The request's fixed parts (mnee_begin).
  vec3 o_connect = vec3(0.0f);
  float area_pdf = 0.0f, tol = 0.0f;
  Frame frame;
  uint32_t part_caster = kMneeNoCaster;

  TRACER_HD void ask(MneeRay& out, bool shadow, uint32_t skip) const {
    out.ray = ray;
    out.shadow = shadow;
    out.skip = skip;
  }

  // The straight segment's ray from o to y, or from y to o (the light's side).
  TRACER_HD void seed_ray(int from_light) {
    ray.d = (y - o) / dist;
    ray.tmax = dist * (1.0f - 1e-4f);
    ray.pad = 0.0f;
    ray.o = o;
    if (from_light) {
      ray.o = offset_ray_origin(y, glm::dot(ny, o - y) > 0.0f ? ny : -ny);
      ray.d = -ray.d;
    }
  }

  // The flat glass's seed from the light's side, after o's met glass but gave no chain: asks its
  // first ray.
  TRACER_HD void seed_from_light(MneeRay& out) {
    side = 1;
    seed_step = 0;
    glass = false;
    seed_ray(1);
    phase = kSeed;
    ask(out, false, light_prim);
  }

  // The check of the chain from o (kCheck): asks for the segment to its first vertex; false (the
  // phase unchanged) where they coincide.
  TRACER_HD bool start_check(MneeRay& out) {
    from = o;
    throughput = vec3(1.0f);
    segment = 0;
    if (!segment_ray(vertex(0))) return false;
    phase = kCheck;
    ask(out, false, kInvalid);
    return true;
  }

  // The ray to the chain's next vertex from `from` (false where they coincide).
  TRACER_HD bool segment_ray(vec3 to) {
    const vec3 d = to - from;
    const float len = glm::length(d);
    if (!(len > 0.0f)) return false;
    ray.o = from;
    ray.d = d / len;
    ray.tmax = len * 1.01f;
    ray.pad = 0.0f;
    return true;
  }

  // The ray from o through the one-refraction chain's vertex moved by single_step in its
  // triangle's plane, which finds where that point lies on the mesh (kSingleProject).
  TRACER_HD void single_project(MneeRay& out) {
    const Frame g = Frame::from_normal(sch.surface[0].n);
    const vec3 d = sch.p[0] + single_step.x * g.t + single_step.y * g.b - o;
    const float len = glm::length(d);
    ray.o = o;
    ray.d = len > 0.0f ? d / len : glm::normalize(sch.p[0] - o);
    ray.tmax = 2.0f * (dist + len);
    ray.pad = 0.0f;
    phase = kSingleProject;
    ask(out, false, kInvalid);
  }

  // A chain found (its throughput in `throughput`).
  TRACER_HD void found(const MneeRequest& q) {
    if (task == 0) {
      covered = covered || glm::length(vertex(chain_k() - 1) - q.seg_o) <= tol;
      return;
    }
    const vec3 w1 = glm::normalize(vertex(0) - o);
    if (!(glm::dot(w1, q.ng_viewer) > 0.0f)) return;
    const vec3 wi = frame.to_local(w1);
    const float g = on_single() ? manifold_geometry(sch, o, q.ls.p, q.ls.n)
                                : manifold_geometry(ch, o, q.ls.p, q.ls.n);
    if (g > 0.0f)
      sum += bsdf_eval<F>(q.m, q.wo, wi) * glm::abs(wi.z) * throughput * (g / area_pdf);
  }

  // Runs the solves until they need a ray: true with it in `out`, to be answered by `h` on the
  // next call; false when all are done. (The first call's h is not read.)
  TRACER_HD bool next(const SceneView& s, const MneeRequest& q, const MneeHit& h, MneeRay& out) {
    for (;;) {
      switch (phase) {
        case kTask: {  // the next task
          if (++task == 2) return false;
          const bool part = task == 0;
          if (part ? !q.partition || part_caster == kMneeNoCaster
                   : !q.connect || !(area_pdf > 0.0f))
            continue;
          o = part ? q.from_o : o_connect;
          y = part ? q.hit_p : q.ls.p;
          ny = part ? q.hit_ng : q.ls.n;
          light_prim = part ? q.hit_prim : q.ls.prim;
          segments = part ? 3u : q.segments;
          only = part ? part_caster : kMneeEveryCaster;
          dist = glm::length(y - o);
          next_caster = 0;
          spheres = (F & kFeatureSpheres) ? glm::min(s.sphere_count, kMneeMaxSpheres) : 0u;
          casters = segments >= 2 ? spheres + s.reflector_plane_count : 0u;
          phase = kCasters;
          single_prim = kInvalid;
          single = false;
          if (((segments >= 3 && only == kMneeFlatGlass) ||
               (segments >= 2 && only == kMneeOneRefraction) || only == kMneeEveryCaster) &&
              segments >= 2 && dist > 0.0f) {
            side = seed_step = 0;
            glass = false;
            seed_ray(0);
            phase = kSeed;
            ask(out, false, kInvalid);
            return true;
          }
          continue;
        }
        case kSeed: {  // the flat glass's seed: the hit of the seed's ray
          bool ok = false;
          if (h.valid) {
            const Material& ms = s.materials[h.material];
            // Glass spheres' chains are all found by SphereChainScan instead.
            glass = glass || mnee_glass(ms);
            ok = mnee_glass(ms) && !((F & kFeatureSpheres) && !prim_is_triangle(s, h.prim) &&
                                     h.prim - s.tri_count < s.sphere_count);
            // The one-refraction chain's seed: o's first hit, a glass triangle of the scene's.
            if (ok && side == 0 && seed_step == 0 && h.prim < s.tri_count) {
              single_prim = h.prim;
              single_p = h.p;
            }
            if (ok) {
              const uint32_t i = uint32_t(side ? 1 - seed_step : seed_step);
              SpecularSurface& su = ch.surface[i];
              su.kind = SpecularSurface::kPlane;  // a triangle (also of an instance): its plane
              su.a = h.p;
              su.n = h.ng;
              su.eta = ms.ior;
              material[i] = h.material;
              ch.p[i] = h.p;
              if (seed_step == 0) {  // refracted into the glass (total internal reflection: none)
                const float c = glm::dot(-ray.d, h.ng);
                const vec3 nn = c > 0.0f ? h.ng : -h.ng;
                const vec3 t = glm::refract(ray.d, nn, c > 0.0f ? 1.0f / ms.ior : ms.ior);
                ok = glm::dot(t, t) > 0.0f;
                if (ok) {
                  ray = spawn_ray(h.p, h.ng, glm::normalize(t));
                  seed_step = 1;
                  ask(out, false, kInvalid);
                  return true;
                }
              } else {
                ch.k = 2;
                ok = material[0] == material[1];  // in and out of one glass
                if (ok && side == 0) single_prim = kInvalid;  // it does not leave the glass
                ok = ok && segments >= 3 && only != kMneeOneRefraction;
                // Through parallel faces (a pane, a slab) solved in one dimension first.
                if (ok) {
                  manifold_slab(ch, o, y);
                  after_check = kSingle;
                  reflection = false;
                  phase = kWalk;
                  continue;
                }
              }
            }
          }
          // No seed from this side: from the light's where o's met glass, else no flat chain.
          if (glass && side == 0 && segments >= 3 && only != kMneeOneRefraction) {
            seed_from_light(out);
            return true;
          }
          phase = kSingle;
          continue;
        }
        case kWalk: {  // Newton's method on the chain, then its check (one copy of each)
          if (!manifold_walk(ch, o, y)) {
            // A flat chain that fails from o's side where o's ray met glass: from the light's.
            if (after_check == kSingle && side == 0 && glass) {
              seed_from_light(out);
              return true;
            }
            phase = after_check;
            continue;
          }
          if (start_check(out)) return true;
          phase = after_check;
          continue;
        }
        case kCheck: {  // the hit of the segment to vertex `segment`
          const vec3 n = vertex_normal(segment);
          bool ok = h.valid;
          if (reflection) {
            const bool sphere = caster < kMneeMaxSpheres;
            ok = ok && (sphere ? h.prim == s.tri_count + caster : prim_is_triangle(s, h.prim)) &&
                 !(glm::length(h.p - ch.p[0]) > 1e-3f * (glm::length(ch.p[0] - o) +
                                                          glm::length(y - ch.p[0]))) &&
                 (sphere || (glm::dot(h.ng, n) >= 1.0f - 1e-5f &&
                             glm::abs(glm::dot(h.ns, n)) >= 1.0f - 1e-5f));
            if (ok) {
              const Material& m = s.materials[h.material];
              const float c = glm::dot(-ray.d, n);
              throughput = mnee_glass(m) && !sphere ? vec3(material_fresnel(m, c, m.ior))
                                                    : mnee_mirror_reflectance(m, c);
              ok = !is_black(throughput);
              from = ch.p[0];
            }
          } else {
            ok = ok && !(glm::length(h.p - vertex(segment)) > 1e-3f * dist) &&
                 h.material == material[segment] &&
                 !(glm::abs(glm::dot(h.ns, n)) < 1.0f - 1e-5f);
            // One refraction: o and y on the two sides of the triangle's plane.
            if (on_single())
              ok = ok && glm::dot(o - sch.p[0], sch.surface[0].n) *
                                 glm::dot(y - sch.p[0], sch.surface[0].n) < 0.0f;
            if (ok) {
              // The transmission as the BSDF weighs it (bsdf.h, smooth dielectric), on the side
              // the path arrives from o; after Beer-Lambert's attenuation where the segment ran
              // inside (the second vertex; o under water).
              const Material& mi = s.materials[material[segment]];
              if ((segment > 0 || glm::dot(ray.d, h.ng) > 0.0f) && !is_black(mi.absorption))
                throughput *= glm::exp(-mi.absorption * glm::length(vertex(segment) - from));
              throughput *= smooth_transmission(mi, glm::dot(-ray.d, n));
              from = spawn_ray(h.p, h.ng, ray.d).o;
            }
          }
          if (ok && ++segment < chain_k()) {
            ok = segment_ray(vertex(segment));
            if (ok) {
              ask(out, false, kInvalid);
              return true;
            }
          }
          // The last vertex (`from`; a reflection's: its point): the light must emit towards it
          // and be free from it.
          if (ok && mnee_light_faces<F>(s, light_prim, y, ny, o, from)) {
            const vec3 nl = vertex_move_normal(chain_k() - 1);
            ray = reflection ? spawn_ray_to(ch.p[0], nl, y, ny)
                             : spawn_ray_to(from, glm::dot(y - from, nl) > 0.0f ? nl : -nl, y, ny);
            phase = kShadow;
            ask(out, true, light_prim);
            return true;
          }
          phase = after_check;
          continue;
        }
        case kShadow:
          if (!h.valid) found(q);
          phase = after_check;
          continue;
        case kSingle: {  // the one-refraction chain from its seed
          phase = kCasters;
          if (!kSingleChain || !s.open_glass || single_prim == kInvalid || segments < 2 ||
              (only != kMneeEveryCaster && only != kMneeOneRefraction))
            continue;
          material[0] = s.tri_shading[single_prim].material;
          sch.k = 1;
          sch.surface[0] = mnee_triangle_surface(s, single_prim);
          sch.p[0] = single_p;
          single = true;
          reflection = false;
          after_check = kCasters;
          single_it = 0;
          if (!manifold_constraints(sch, o, y, single_c)) continue;
          single_norm = manifold_norm(single_c, 2);
          phase = kSingleStep;
          continue;
        }
        case kSingleStep: {  // a Newton step on the current triangle, or the end of the walk
          phase = kCasters;
          if (!kSingleChain) continue;
          if (single_norm <= kManifoldTolerance || single_it >= kManifoldIterations) {
            if (single_norm <= kManifoldAccept && start_check(out)) return true;
            continue;
          }
          float J[4][4];
          float r[2 * kManifoldMaxChain] = {-single_c[0], -single_c[1]},
                d[2 * kManifoldMaxChain] = {};
          if (!manifold_jacobian(sch, o, y, J) || !manifold_solve(J, r, 2, d)) continue;
          single_step = vec2(d[0], d[1]);
          single_halving = 0;
          single_project(out);
          return true;
        }
        case kSingleProject: {  // the step's point put back on the mesh by the ray from o
          if (!kSingleChain) {
            phase = kCasters;
            continue;
          }
          bool improved = false;
          if (h.valid && h.material == material[0] && h.prim < s.tri_count) {
            SmoothChain next = sch;
            next.surface[0] = mnee_triangle_surface(s, h.prim);
            next.p[0] = h.p;
            float cn[2 * kManifoldMaxChain] = {};
            if (manifold_constraints(next, o, y, cn) && manifold_norm(cn, 2) < single_norm) {
              const float before = single_norm;
              sch = next;
              single_c[0] = cn[0];
              single_c[1] = cn[1];
              single_norm = manifold_norm(cn, 2);
              ++single_it;
              improved = true;
              // Close enough and no longer converging fast: float's rounding has the rest.
              if (single_norm <= kManifoldAccept && single_norm > 0.25f * before)
                single_it = kManifoldIterations;
            }
          }
          if (improved) {
            phase = kSingleStep;
            continue;
          }
          if (single_norm > kManifoldAccept && ++single_halving < kManifoldHalvings) {
            single_step *= 0.5f;
            single_project(out);
            return true;
          }
          phase = kCasters;
          if (single_norm <= kManifoldAccept && start_check(out)) return true;
          continue;
        }
        case kSphereChains:  // a glass sphere's next chain
          if ((F & kFeatureSpheres) && scan.next(ch)) {
            phase = kWalk;
            continue;
          }
          phase = kCasters;
          continue;
        case kCasters: {  // the next sphere or plane
          single = false;
          if (next_caster >= casters) {
            phase = kTask;
            continue;
          }
          const uint32_t k = next_caster++;
          caster = k < spheres ? k : kMneeMaxSpheres + (k - spheres);
          if (only != kMneeEveryCaster && only != caster) continue;
          after_check = kCasters;
          reflection = true;
          if ((F & kFeatureSpheres) && k < spheres) {
            const Sphere& sph = s.spheres[k];
            const Material& mi = s.materials[sph.material];
            if (mnee_glass(mi)) {
              if (segments >= 3) {
                material[0] = material[1] = sph.material;
                scan.start(sph.center, sph.radius, mi.ior, o, y);
                reflection = false;
                after_check = kSphereChains;
                phase = kSphereChains;
              }
              continue;
            }
            if (is_black(mnee_mirror_reflectance(mi, 1.0f)) ||
                !sphere_reflection_chain(sph.center, sph.radius, o, y, ch))
              continue;
            phase = kWalk;  // polished by Newton
            continue;
          }
          const ReflectorPlane pl = s.reflector_planes[caster - kMneeMaxSpheres];
          const float ho = glm::dot(o - pl.a, pl.n), hy = glm::dot(y - pl.a, pl.n);
          if (!(ho > 0.0f) || !(hy > 0.0f)) continue;  // both in front of it
          const vec3 p = o + (ho / (ho + hy)) * (y - 2.0f * hy * pl.n - o);
          if (!pl.bounds_hold(p, 1e-4f * glm::length(pl.hi - pl.lo))) continue;
          ch.k = 1;
          ch.surface[0].kind = SpecularSurface::kPlane;
          ch.surface[0].a = pl.a;
          ch.surface[0].n = pl.n;
          ch.surface[0].eta = 0.0f;
          ch.p[0] = p;
          if (start_check(out)) return true;  // exact: no Newton
          continue;
        }
        default: return false;
      }
    }
  }
};

// A request's solver, set up: the connection's origin, frame and light sample's density of area
// (where it connects), and the caster the partition's segment left.
template <uint32_t F>
TRACER_HD inline MneeSolver<F> mnee_begin(const SceneView& s, const MneeRequest& q) {
  MneeSolver<F> sv;
  if (q.connect) {
    sv.o_connect = offset_ray_origin(q.p, q.ng_viewer);
    const float d2 = glm::dot(q.ls.p - q.p, q.ls.p - q.p);
    sv.area_pdf = q.ls.pdf * glm::abs(glm::dot(q.ls.n, q.p - q.ls.p)) / (d2 * glm::sqrt(d2));
    sv.frame =
        bsdf_frame(q.m, (F & kFeatureSpecular) ? q.m.type : MaterialType::kDiffuse, q.frame_n);
  }
  // How far seg_o may lie from the chain's last vertex and its caster: a thousandth of the path,
  // and at least the spawn offset that moved seg_o off that vertex (offset_ray_origin: 256 ulps
  // per axis, about 5e-5 of the coordinates), which over a short path (a ceiling just above a
  // lamp's reflection) is the larger: missed, the path would be counted by both estimators.
  const float tol = 1e-3f * glm::length(q.hit_p - q.from_o) +
                    1e-4f * max_component(glm::abs(q.seg_o));
  sv.tol = tol;
  // The caster the partition's segment left: the sphere whose surface seg_o lies on (of those
  // manifold NEE tries) where it is glass, or for a mirror path a mirror; else for a mirror path
  // the plane of flat reflectors it lies on, and otherwise flat glass (kMneeNoCaster: manifold NEE
  // does not own it).
  uint32_t caster = q.mirror ? kMneeNoCaster : q.single ? kMneeOneRefraction : kMneeFlatGlass;
  if ((F & kFeatureSpheres) && q.partition) {
    const uint32_t spheres = glm::min(s.sphere_count, kMneeMaxSpheres);
    for (uint32_t i = 0; i < spheres; ++i) {
      const Sphere& sph = s.spheres[i];
      if (glm::abs(glm::length(q.seg_o - sph.center) - sph.radius) > tol) continue;
      const Material& mi = s.materials[sph.material];
      if (q.single) caster = kMneeNoCaster;  // (one refraction into a sphere: not solved)
      else if (q.mirror ? !is_black(mnee_mirror_reflectance(mi, 1.0f)) : mnee_glass(mi)) caster = i;
      break;
    }
  }
  if (q.partition && q.mirror && caster == kMneeNoCaster) {
    for (uint32_t j = 0; j < s.reflector_plane_count; ++j) {
      const ReflectorPlane& pl = s.reflector_planes[j];
      // (The vertex in front: of a face listed both ways, the side it reflects on.)
      if (!(glm::dot(q.from_o - pl.a, pl.n) > 0.0f) ||
          glm::abs(glm::dot(q.seg_o - pl.a, pl.n)) > tol || !pl.bounds_hold(q.seg_o, tol))
        continue;
      caster = kMneeMaxSpheres + j;
      break;
    }
  }
  sv.part_caster = caster;
  return sv;
}

// The radiance a request adds to its path, once its solver is done.
// - connect: every chain from the vertex's offset origin o to the light sample's point
//   (MneeSolver), each weighed by the BSDF towards its first vertex, its throughput and its
//   generalized geometry term over the light sample's density of area.
// - partition: the emission unless manifold NEE owns that path: the solve from the vertex that
//   sampled the lights finds a chain to this light point whose last vertex is where the segment
//   left (the same path: the chain is fixed by its ends and last vertex), of the caster that
//   segment left, and the vertex could have chosen this light. The two estimators so split the
//   paths exactly, also where the solve fails (no bias).
template <uint32_t F>
TRACER_HD inline vec3 mnee_finish(const SceneView& s, const IntegratorSettings& cfg,
                                  const MneeRequest& q, const MneeSolver<F>& sv) {
  vec3 c(0.0f);
  if (q.connect) {
    const vec3 l = sv.sum * q.ls.le;
    if (is_finite(l)) c += l;
  }
  if (q.partition) {
    bool covered = sv.covered;
    if (covered) {  // and the vertex could have chosen this light
      const bool tree =
          (F & kFeatureLightTree) && cfg.light_sampler == kLightSamplerBvh && s.light_tree.nodes;
      const LightContext from{q.from_o, tree ? unpack_light_normal(q.from_normal) : vec3(0.0f)};
      covered = light_choice_pmf<F>(s, cfg.light_sampler, from, q.hit_light) > 0.0f;
    }
    if (!covered) c += q.contribution;
  }
  return c;
}

// A request's radiance: its solves, every ray they ask for traced here (one copy of the
// traversal). The wavefront's mnee stage runs the same loop over many requests per thread.
template <uint32_t F>
TRACER_HD inline vec3 mnee_resolve(const SceneView& s, const IntegratorSettings& cfg,
                                   const MneeRequest& q) {
  MneeSolver<F> sv = mnee_begin<F>(s, q);
  MneeHit h;
  MneeRay r;
  while (sv.next(s, q, h, r)) h = mnee_trace<F>(s, r);
  return mnee_finish<F>(s, cfg, q, sv);
}

// Light tracing's windows (SceneView::window_planes): whether a hit lies on one (a scene
// triangle in a window plane), and whether the path's vertex at st.depth is the one behind the
// window its camera ray refracted through (kPathLightTraced set there, at the first vertex, by
// that refraction).
TRACER_HD inline bool on_window(const SceneView& s, uint32_t prim, const SurfaceHit& sh) {
  if (!prim_is_triangle(s, prim) || prim >= s.tri_count) return false;
  for (uint32_t k = 0; k < s.window_plane_count; ++k)
    if (s.window_planes[k].holds(sh.p, sh.ng, sh.material, s.window_tol)) return true;
  return false;
}
TRACER_HD inline bool path_behind_window(const PathState& st) {
  return st.depth == 2 && (st.flags & (kPathLightTraced | kPathPrevSpecular)) ==
                              (kPathLightTraced | kPathPrevSpecular);
}

// Shades the hit of st.ray. Adds emission to st.radiance, may fill `shadow`, and returns whether
// the path continues, in which case st.ray is the next segment. Forced inline: nvcc outlines it
// in the specular kernels once the material switch is large, and the call then passes the scene,
// the path state and the hit through local memory (2.6x slower; PERFORMANCE.md).
// Manifold NEE's solves (F with kFeatureCaustics, cfg.mnee) are not run here: *mnee receives
// them, and mnee_resolve gives what they add to st.radiance.
template <uint32_t F = kAllFeatures>
TRACER_HD TRACER_INLINE bool shade_path(const SceneView& s, const IntegratorSettings& cfg,
                                        PathState& st, const Hit& hit, ShadowRequest& shadow,
                                        MneeRequest* mnee = nullptr) {
  shadow.valid = false;
  if ((F & kFeatureCaustics) && mnee) mnee->connect = mnee->partition = false;
  if ((F & kFeatureSubsurface) && (st.flags & kPathInMedium) && hit.valid()) {
    const SurfaceHit b = make_surface_hit<F>(s, st.ray, hit);
    // The walk's last point lay outside the boundary within rounding: the path has in fact left
    // the medium, and this hit is its boundary seen from outside.
    if (b.front && b.material == st.medium) st.flags &= ~kPathInMedium;
  }
  if ((F & kFeatureSubsurface) && (st.flags & kPathInMedium)) {
    // Inside a subsurface medium: scatter before the boundary, or reach it attenuated.
    if (!hit.valid()) {  // the mesh is not closed
      st.flags |= kPathMediumLeak;
      return false;
    }
    const Material& med = s.materials[st.medium];
    // Random-walk steps draw from PCG32 with either sampler: a walk has hundreds of steps, whose
    // dimensions no low-dimensional stratification reaches (Cycles does the same past its
    // first few bounces). The surface vertices around the walk stay stratified.
    Pcg32 rng =
        make_path_rng(st.pixel, st.sample, st.depth + (st.walk_steps + 1u) * 4096u, cfg.seed);
    const float u_channel = rng.next_float(), u_distance = rng.next_float();
    const vec2 u_dir = rng.next_2d();
    const float u_rr = rng.next_float();
    MediumEvent ev = sample_medium(med, st.throughput, hit.t, u_channel, u_distance);
    if (ev.scattered) {
      // hit.t carries the rounding error of the boundary's triangle (it grows with the
      // triangle's coordinates), so a scattering point sampled just before it can lie on the
      // outside. Such an event counts as reaching the boundary (a bias of the order of that
      // error times sigma_t).
      const SurfaceHit b = make_surface_hit<F>(s, st.ray, hit);
      const vec3 outward = b.front ? -b.ng : b.ng;  // the ray leaves through a back face
      if (glm::dot(st.ray.o + ev.t * st.ray.d - b.p, outward) >= 0.0f) {
        ev = medium_boundary_event(med, st.throughput, hit.t);
      }
    }
    st.throughput *= ev.weight;
    if (ev.scattered) {
      if (++st.walk_steps >= kMaxWalkSteps) {
        st.flags |= kPathWalkCapped;
        return false;
      }
      if (cfg.russian_roulette && st.walk_steps > 16) {  // keeps long walks finite in cost
        const float q = glm::min(1.0f, max_component(st.throughput));
        if (u_rr >= q) return false;
        st.throughput /= q;
      }
      st.ray.o = st.ray.o + ev.t * st.ray.d;
      st.ray.d = sample_hg(st.ray.d, med.g, u_dir);
      st.origin_prim = kInvalid;  // a point inside the medium, on no surface
      st.ray.tmax = kInfinity;
      st.flags |= kPathPrevSpecular;  // nothing inside to sample lights from
      return !is_black(st.throughput);
    }
  }
  if (!hit.valid()) {  // escaped: the lights at infinity, if any
    if ((F & kFeatureInfiniteLights) && s.infinite)
      st.radiance +=
          st.throughput * escaped_radiance<F>(s, cfg.nee != 0, cfg.mis != 0, st.ray.d,
                                              glm::abs(st.prev_pdf),
                                              st.depth, (st.flags & kPathPrevSpecular) != 0,
                                              cfg.light_sampler);
    return false;
  }
  SurfaceHit sh = make_surface_hit<F>(s, st.ray, hit);
  Material textured;
  const Material* mp = hit_material<F>(s, hit.prim, sh, textured);
  // A random walk meeting its medium's boundary from inside leaves through the diffuse exit
  // (unless the material asks for the smooth one): a Lambertian sheet, so that light sampling
  // reaches the lights outside from the exit point.
  Material exit_sheet;
  const bool diffuse_exit = (F & kFeatureSubsurface) && (st.flags & kPathInMedium) &&
                            !sh.front && sh.material == st.medium &&
                            mp->type == MaterialType::kSubsurface &&
                            !(mp->flags & kMaterialSmoothExit);
  if (diffuse_exit) {
    exit_sheet = subsurface_exit_material(*mp);
    mp = &exit_sheet;
  }
  const Material& m = *mp;
  // Without specular features in F, the compiler drops every non-diffuse branch below.
  const MaterialType type = (F & kFeatureSpecular) ? m.type : MaterialType::kDiffuse;
  if ((F & kFeatureSubsurface) && (st.flags & kPathInMedium) &&
      (sh.material != st.medium || sh.front)) {
    st.flags |= kPathMediumLeak;  // overlapping or open geometry: the walk cannot continue
    return false;
  }

  // Beer-Lambert attenuation along the segment that just ran inside a dielectric.
  if (type == MaterialType::kDielectric && !sh.front && !is_black(m.absorption)) {
    st.throughput *= glm::exp(-m.absorption * hit.t);
  }

  if (m.is_emissive()) {
    const vec3 le = material_emission(m, sh.front);
    if (!is_black(le)) {
      float w = 1.0f;
      if (cfg.nee && !(st.flags & kPathPrevSpecular) && sh.light != kInvalid) {
        // This emitter could also have been reached by light sampling at the previous vertex,
        // chosen from there (the ray's origin and that vertex's normal, for the bvh sampler).
        if (cfg.mis) {
          const bool tree = (F & kFeatureLightTree) && cfg.light_sampler == kLightSamplerBvh &&
                            s.light_tree.nodes;
          const LightContext prev{st.ray.o,
                                  tree ? unpack_light_normal(st.prev_normal) : vec3(0.0f)};
          const float select = light_choice_pmf<F>(s, cfg.light_sampler, prev, sh.light);
          w = power_heuristic(glm::abs(st.prev_pdf),
                              light_pdf<F>(s, sh.light, select, st.ray.o, sh.p, sh.ng));
        } else {
          w = 0.0f;
        }
      }
      // Reached through exactly two refractions (or one, or one reflection) from a vertex that
      // sampled the lights: manifold NEE's, where from that vertex it finds this path (the chain whose last vertex this
      // segment left from) to this point of a light it could have chosen there. The two
      // estimators so split the paths exactly, also where the solve fails (no bias).
      const uint32_t mnee_bits = st.flags & (kPathMneeFrom | kPathMneeRefract1 |
                                             kPathMneeRefract2 | kPathMneeOther | kPathMneeMirror);
      if ((F & kFeatureSpecular) && cfg.light_tracing && sh.light != kInvalid &&
          (st.flags & kPathLightTraced) &&
          ((st.flags & kPathPrevSpecular) || st.prev_pdf < 0.0f) && !path_behind_window(st) &&
          light_select_pdf(s, sh.light) > 0.0f) {
        // The light tracer's: an area light it emits from, after delta events or glossy casters.
        w = 0.0f;
      } else if ((F & kFeatureCaustics) && cfg.mnee && mnee && sh.light != kInvalid &&
          (mnee_bits == (kPathMneeFrom | kPathMneeRefract2) ||
           mnee_bits == (kPathMneeFrom | kPathMneeRefract1) ||
           mnee_bits == (kPathMneeFrom | kPathMneeMirror))) {
        mnee->partition = w > 0.0f;
        mnee->mirror = (mnee_bits & kPathMneeMirror) != 0;
        mnee->single = (mnee_bits & kPathMneeRefract1) != 0;
        mnee->depth = st.depth;
        mnee->from_o = st.mnee_o;
        mnee->from_normal = st.mnee_normal;
        mnee->hit_p = sh.p;
        mnee->hit_ng = sh.ng;
        mnee->hit_prim = hit.prim;
        mnee->hit_light = sh.light;
        mnee->seg_o = st.ray.o;
        mnee->contribution = st.throughput * le * w;
        w = 0.0f;  // added by mnee_resolve unless manifold NEE owns the path
      }
      st.radiance += st.throughput * le * w;
    }
  }
  if (st.depth >= cfg.max_depth) return false;

  const VertexSampler u(cfg, st.pixel, st.sample, st.depth);

  const vec3 wo_world = -st.ray.d;
  const bool transmits = bsdf_transmits(type);
  // Reflectors are two-sided: their frame faces the viewer. Transmitters keep +z outside.
  const Frame frame = bsdf_frame(m, type, transmits || sh.front ? sh.ns : -sh.ns);
  const vec3 wo = frame.to_local(wo_world);
  const vec3 ng_viewer = sh.front ? sh.ng : -sh.ng;
  const bool light_tree =
      (F & kFeatureLightTree) && cfg.light_sampler == kLightSamplerBvh && s.light_tree.nodes;
  const uint32_t normal_code = light_tree ? pack_light_normal(ng_viewer) : 0u;

  // Path guiding at this vertex (integrator/guide.h): the cell; whether it is learned for this
  // BSDF (a wide non-delta lobe) and the cell's share of the mixture (0: the BSDF alone, while the
  // distribution still gives the training records the guide's density); whether it records.
  const GuideView& gv = cfg.guide;
  const bool guide_here = (F & kFeatureGuiding) && (gv.dist || gv.records) &&
                          !bsdf_is_delta(m, type) && !diffuse_exit;
  const uint32_t gcell = guide_here ? guide_cell(gv, sh.p) : 0u;
  const bool learned = guide_here && guide_wide_bsdf(m, type) && guide_learned(gv, gcell);
  const float mix = learned ? guide_mix(gv, gcell) : 0.0f;
  const bool guided = mix > 0.0f;

  // A glossy caster past the light tracer's camera vertex (light_trace_glossy_caster): on the
  // light tracer's paths its area lights are the light tracer's, so light sampling there skips
  // them and the area light its BSDF sample reaches is not added (prev_pdf < 0); the other lights
  // (point, spot, distant, the environment) it samples as any vertex, with MIS.
  const bool lt_caster = (F & kFeatureSpecular) && cfg.light_tracing &&
                         (st.flags & kPathLightTraced) && st.depth > 1 &&
                         !path_behind_window(st) && light_trace_glossy_caster(m, type);

  if (cfg.nee && !bsdf_is_delta(m, type) && s.light_count > 0) {
    const LightContext ctx = light_tree ? vertex_light_context(sh.p, ng_viewer, normal_code)
                                        : LightContext{sh.p, ng_viewer};
    const LightSample ls = sample_light_2d<F>(s, cfg.light_sampler, ctx, sh.p, sh.ng, u.light());
    const bool ls_delta = (F & (kFeatureInfiniteLights | kFeaturePointLights)) && ls.delta;
    const bool ls_area = !((F & kFeatureInfiniteLights) && ls.infinite) && !ls_delta;
    if (ls.valid && !is_black(ls.le) && !(lt_caster && ls_area)) {
      // (manifold NEE's below also where ls.le is 0)
      // A light at infinity gives a direction; the others a point (point and spot lights: their
      // position, whose shadow ray ends just short of it, as an area light's).
      const bool at_infinity = (F & kFeatureInfiniteLights) && ls.infinite;
      const vec3 wi_world = at_infinity ? ls.p : fast_normalize(ls.p - sh.p);
      const vec3 wi = frame.to_local(wi_world);
      // Reflectors see lights on the viewer's side only; a rough transmitter on either side,
      // as long as the shading and geometric normals agree about which side that is.
      const float geo = glm::dot(wi_world, sh.ng);
      const bool usable = transmits ? (geo > 0.0f) == (wi.z > 0.0f) && geo != 0.0f
                                    : glm::dot(wi_world, ng_viewer) > 0.0f;
      if (usable) {
        const vec3 f = bsdf_eval<F>(m, wo, wi);
        if (!is_black(f)) {
          // MIS weighs light sampling against the density that samples directions here: the
          // BSDF's, or with a guide the mixture's.
          float scatter_pdf = 0.0f;
          if (cfg.mis && !ls_delta) {
            scatter_pdf = bsdf_pdf<F>(m, wo, wi);
            if (guided)
              scatter_pdf = mix * guide_pdf(gv, gcell, wi_world) + (1.0f - mix) * scatter_pdf;
          }
          const float w = cfg.mis && !ls_delta ? power_heuristic(ls.pdf, scatter_pdf) : 1.0f;
          shadow.contribution = st.throughput * f * glm::abs(wi.z) * ls.le * fast_div(w, ls.pdf);
          shadow.ray = at_infinity ? spawn_ray(sh.p, sh.ng, wi_world)
                                   : spawn_ray_to(sh.p, geo > 0.0f ? sh.ng : -sh.ng, ls.p, ls.n);
          shadow.target_prim = ls.prim;
          shadow.origin_prim =
              (F & kFeatureSubsurface) && prim_is_triangle(s, hit.prim) ? hit.prim : kInvalid;
          shadow.valid = shadow.ray.tmax > 0.0f && is_finite(shadow.contribution);
        }
      }
    }
    // Manifold NEE: the same light point through the glass the shadow ray may cross and off
    // mirror spheres (paths of 3 and 2 more segments, within max_depth as the BSDF's would have
    // to be), with the light's radiance towards the chain: also from behind a one-sided light,
    // which the chain may reach from its front (a ceiling lit by the light's image in a ball).
    // (Not where the light tracer owns these paths: a camera vertex, or kPathLightTraced.)
    const bool light_traced =
        (F & kFeatureSpecular) && cfg.light_tracing &&
        (st.depth == 1 || path_behind_window(st) ? !diffuse_exit && light_trace_connects(m, type)
                                                 : (st.flags & kPathLightTraced) != 0);
    if ((F & kFeatureCaustics) && cfg.mnee && mnee && ls.valid && !ls.infinite && !ls.delta &&
        !is_black(ls.emitted) && st.depth + 2 <= cfg.max_depth && !light_traced) {
      mnee->connect = true;
      mnee->depth = st.depth;
      mnee->p = sh.p;
      mnee->ng_viewer = ng_viewer;
      mnee->frame_n = frame.n;
      mnee->wo = wo;
      mnee->m = m;
      mnee->ls = ls;
      mnee->ls.le = st.throughput * ls.emitted;
      mnee->segments = cfg.max_depth - st.depth;
    }
  }

  // Only materials with several lobes draw the number that chooses one. A guided vertex keeps
  // the BSDF's value times the cosine and both densities at the direction for training.
  BsdfSample bs;
  vec3 wi_world;  // the sampled direction in world space (bs.wi's, normalised once)
  float f_cos = 0.0f, pdf_guide = 0.0f, pdf_bsdf = 0.0f;
  // A guided vertex chooses guide or BSDF by the first coordinate of the BSDF's point and
  // stretches that coordinate's part back to [0, 1): each technique gets the Sobol points of its
  // part of the square, as well spread as all of them (a choice by a number of another pair
  // would hand each technique a random subset, and the image would lose the sampler's faster
  // than 1/N convergence wherever the guide is on).
  vec2 ub = u.bsdf();
  const bool from_guide = guided && ub.x < mix;
  if (guided)
    ub.x = glm::min(from_guide ? ub.x / mix : (ub.x - mix) / (1.0f - mix),
                    0.99999994f);  // (the float below 1)
  if (from_guide) {
    // One-sample MIS of guide and BSDF: a direction from the guide, weighed by the mixture.
    const vec3 d = guide_sample(gv, gcell, ub, &pdf_guide);
    bs.wi = frame.to_local(d);
    wi_world = fast_normalize(frame.to_world(bs.wi));
    bs.specular = false;
    pdf_bsdf = bsdf_pdf<F>(m, wo, bs.wi);
    const float pdf = mix * pdf_guide + (1.0f - mix) * pdf_bsdf;
    bs.valid = pdf > 0.0f;
    bs.pdf = pdf;
    const vec3 f = bs.valid ? bsdf_eval<F>(m, wo, bs.wi) * glm::abs(bs.wi.z) : vec3(0.0f);
    f_cos = luminance(f);
    bs.weight = bs.valid ? f / pdf : vec3(0.0f);
  } else {
    bs = bsdf_sample<F>(m, wo, ub, bsdf_chooses_lobe(type) ? u.lobe() : 0.5f);
    wi_world = fast_normalize(frame.to_world(bs.wi));
    if (guided && bs.valid) {
      if (bs.specular) {  // a delta lobe, which the guide cannot sample: chosen with 1 - mix
        bs.weight *= 1.0f / (1.0f - mix);
      } else {
        pdf_guide = guide_pdf(gv, gcell, wi_world);
        pdf_bsdf = bsdf_pdf<F>(m, wo, bs.wi);
        const float pdf = mix * pdf_guide + (1.0f - mix) * pdf_bsdf;
        const vec3 f = bsdf_eval<F>(m, wo, bs.wi) * glm::abs(bs.wi.z);
        f_cos = luminance(f);
        bs.weight = f / pdf;
        bs.pdf = pdf;
      }
    } else if ((F & kFeatureGuiding) && learned && gv.records && bs.valid && !bs.specular) {
      // A cell whose share is 0 while training: the guide's density for the share's statistics.
      pdf_guide = guide_pdf(gv, gcell, wi_world);
      pdf_bsdf = bs.pdf;
      f_cos = luminance(bs.weight) * bs.pdf;
    }
  }
  if (!bs.valid) return false;
  const float side = glm::dot(wi_world, sh.ng);
  // A reflector whose shading normal sends the ray under the true surface would leak light.
  if (!transmits && side * glm::dot(wo_world, sh.ng) <= 0.0f) return false;
  // A rough transmitter whose shading normal disagrees with the true surface about the side of
  // the sample: next-event estimation refuses these directions, so BSDF sampling must too.
  if (transmits && !bs.specular && (side > 0.0f) != (bs.wi.z > 0.0f)) return false;
  if (diffuse_exit && side * glm::dot(wo_world, sh.ng) < 0.0f) {
    st.flags &= ~kPathInMedium;  // transmitted out; reflected back, the walk goes on
  } else if ((F & kFeatureSubsurface) && type == MaterialType::kSubsurface &&
             side * glm::dot(wo_world, sh.ng) < 0.0f) {
    if (sh.front) {  // refracted in: the random walk starts
      st.flags |= kPathInMedium;
      st.medium = sh.material;
      st.walk_steps = 0;
    } else {
      st.flags &= ~kPathInMedium;
    }
  }
  if ((F & kFeatureSpecular) && cfg.light_tracing) {  // the light tracer's paths
    // The camera's vertex: the first, or the second where the camera ray refracted through a
    // window (light_path.h joins the camera through it); at the first, such a refraction.
    const bool camera_vertex = st.depth == 1 || path_behind_window(st);
    if (camera_vertex && !bs.specular && !diffuse_exit && light_trace_connects(m, type))
      st.flags |= kPathLightTraced;
    else if (st.depth == 1 && bs.specular && type == MaterialType::kDielectric &&
             side * glm::dot(wo_world, sh.ng) < 0.0f && on_window(s, hit.prim, sh))
      st.flags |= kPathLightTraced;
    else if (camera_vertex || type == MaterialType::kSubsurface)
      st.flags &= ~kPathLightTraced;  // (the light tracer stops at subsurface materials)
  }
  if ((F & kFeatureCaustics) && cfg.mnee) {  // manifold NEE's partition (kPathMneeFrom)
    if (!bsdf_is_delta(m, type)) {
      st.flags &= ~(kPathMneeRefract1 | kPathMneeRefract2 | kPathMneeOther | kPathMneeMirror);
      if (cfg.nee && s.light_count > 0) {
        st.flags |= kPathMneeFrom;
        st.mnee_o = offset_ray_origin(sh.p, ng_viewer);
        st.mnee_normal = normal_code;
      } else {
        st.flags &= ~kPathMneeFrom;
      }
    } else if (type == MaterialType::kDielectric && side * glm::dot(wo_world, sh.ng) < 0.0f) {
      if (st.flags & (kPathMneeRefract2 | kPathMneeMirror)) st.flags |= kPathMneeOther;
      else if (st.flags & kPathMneeRefract1) st.flags = (st.flags & ~kPathMneeRefract1) | kPathMneeRefract2;
      else st.flags |= kPathMneeRefract1;
    } else if (!(st.flags & (kPathMneeRefract1 | kPathMneeRefract2 | kPathMneeMirror)) &&
               (prim_is_triangle(s, hit.prim)
                    ? s.reflector_plane_count > 0 && mnee_flat_reflector(m)
                    : (F & kFeatureSpheres) && hit.prim - s.tri_count < s.sphere_count &&
                          !is_black(mnee_mirror_reflectance(m, 1.0f)))) {
      st.flags |= kPathMneeMirror;  // off a mirror sphere or a flat reflector (a glass face's too)
    } else {
      st.flags |= kPathMneeOther;
    }
  }
  st.throughput *= bs.weight;
  st.prev_pdf = lt_caster ? -bs.pdf : bs.pdf;
  st.prev_normal = normal_code;
  st.flags = bs.specular ? (st.flags | kPathPrevSpecular) : (st.flags & ~kPathPrevSpecular);
  st.ray = spawn_ray(sh.p, sh.ng, wi_world);
  // Only random walks need the origin triangle skipped (see traverse); elsewhere the offset
  // suffices and the skip would cost a compare per primitive test.
  st.origin_prim = (F & kFeatureSubsurface) && prim_is_triangle(s, hit.prim) ? hit.prim : kInvalid;

  // Russian roulette survives with probability sqrt(max throughput), as Cycles does
  // (path_state_continuation_probability): paths end later than with the throughput itself,
  // which costs time per sample but removes more error than that time would (the variants
  // compared: docs/PERFORMANCE.md, decision log).
  if (cfg.russian_roulette && st.depth >= cfg.rr_start_depth) {
    const float q = glm::min(1.0f, fast_sqrt(max_component(st.throughput)));
    if (u.rr() >= q) return false;
    st.throughput *= fast_rcp(q);  // q in (0, 1]
  }
  // Training: the vertex's direction, density and throughput, and what the path had gathered
  // before it, counting this vertex's shadow ray as if it arrives (it is not along wi).
  if ((F & kFeatureGuiding) && guide_here && gv.records && !bs.specular)
    guide_record(gv, st.pixel, st.sample, st.depth, gcell, wi_world, bs.pdf, st.throughput,
                 luminance(st.radiance) + (shadow.valid ? luminance(shadow.contribution) : 0.0f),
                 f_cos, pdf_guide, pdf_bsdf);
  st.depth += 1;
  return !is_black(st.throughput);
}

// Rays traced by one path, counted by kind for Mrays/s figures.
struct RayCounts {
  uint64_t camera = 0, extension = 0, shadow = 0;
  uint64_t walk_capped = 0, medium_leaks = 0;  // paths ended by a random walk's safety limits
  TRACER_HD RayCounts& operator+=(const RayCounts& o) {
    camera += o.camera;
    extension += o.extension;
    shadow += o.shadow;
    walk_capped += o.walk_capped;
    medium_leaks += o.medium_leaks;
    return *this;
  }
};

TRACER_HD TRACER_INLINE void count_path_end(const PathState& st, RayCounts* counts) {
  if (!counts) return;
  if (st.flags & kPathWalkCapped) counts->walk_capped++;
  if (st.flags & kPathMediumLeak) counts->medium_leaks++;
}

// One whole path, all bounces, in one call: the CPU backend and the CUDA megakernel.
template <uint32_t F = kAllFeatures>
TRACER_HD inline vec3 trace_path(const SceneView& s, const IntegratorSettings& cfg, uint32_t pixel,
                                 uint32_t sample, RayCounts* counts = nullptr) {
  PathState st;
  generate_path<F>(s, cfg, pixel, sample, st);
  MneeRequest mnee;  // once per path: shade_path clears what it asks for at each vertex
  for (;;) {
    const Hit hit = intersect_closest<F>(s, st.ray, st.origin_prim);
    if (counts) (st.depth == 1 ? counts->camera : counts->extension)++;
    ShadowRequest shadow;
    const bool go_on = shade_path<F>(s, cfg, st, hit, shadow, &mnee);
    if ((F & kFeatureCaustics) && (mnee.connect || mnee.partition))
      st.radiance += mnee_resolve<F>(s, cfg, mnee);
    if (shadow.valid) {
      if (counts) counts->shadow++;
      if (!intersect_any<F>(s, shadow.ray, shadow.target_prim, shadow.origin_prim))
        st.radiance += shadow.contribution;
    }
    if (!go_on) break;
  }
  count_path_end(st, counts);
  if (F & kFeatureGuiding) guide_train_path(cfg.guide, pixel, sample, st.radiance);
  return st.radiance;
}

}  // namespace tracer
