// Scenes built in code for the analytic and geometric tests: furnaces, closed meshes, quads,
// and a per-pixel mean/variance renderer with z-tests for statistical image comparisons.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <glm/gtc/matrix_transform.hpp>
#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "integrator/path.h"
#include "integrator/renderer.h"
#include "scene/compiled_scene.h"
#include "scene/scene.h"

namespace test {
using namespace tracer;

inline void add_triangle(TriangleMesh& m, vec3 a, vec3 b, vec3 c, uint32_t material) {
  const uint32_t base = uint32_t(m.positions.size());
  m.positions.insert(m.positions.end(), {a, b, c});
  m.indices.push_back(uvec3(base, base + 1, base + 2));
  m.materials.push_back(material);
}

// A quad with shared vertices, front face along cross(e1, e2).
inline void add_quad(TriangleMesh& m, vec3 corner, vec3 e1, vec3 e2, uint32_t material) {
  const uint32_t b = uint32_t(m.positions.size());
  m.positions.insert(m.positions.end(), {corner, corner + e1, corner + e1 + e2, corner + e2});
  m.indices.push_back(uvec3(b, b + 1, b + 2));
  m.indices.push_back(uvec3(b, b + 2, b + 3));
  m.materials.insert(m.materials.end(), {material, material});
}

// The box around every triangle and sphere of a compiled scene.
inline Aabb scene_bounds(const CompiledScene& cs) {
  Aabb box;
  for (const auto& tv : cs.tri_verts()) {
    box.grow(tv.v0);
    box.grow(tv.v1);
    box.grow(tv.v2);
  }
  for (const auto& s : cs.spheres()) {
    box.grow(s.center - vec3(s.radius));
    box.grow(s.center + vec3(s.radius));
  }
  return box;
}

// A closed axis-aligned box with shared vertices and outward-facing triangles.
inline void add_box(TriangleMesh& m, vec3 lo, vec3 hi, uint32_t material) {
  const uint32_t b = uint32_t(m.positions.size());
  for (int i = 0; i < 8; ++i)
    m.positions.push_back(vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z));
  const int faces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& f : faces) {
    m.indices.push_back(uvec3(b + f[0], b + f[1], b + f[2]));
    m.indices.push_back(uvec3(b + f[0], b + f[2], b + f[3]));
    m.materials.insert(m.materials.end(), {material, material});
  }
}

// A closed icosphere (shared vertices, outward winding), `levels` subdivisions.
inline void add_icosphere(TriangleMesh& m, vec3 center, float radius, int levels,
                          uint32_t material) {
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                         {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                         {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<uvec3> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p = glm::normalize(p);
  for (int l = 0; l < levels; ++l) {
    std::vector<uvec3> nf;
    std::vector<std::pair<uint64_t, uint32_t>> cache;
    auto mid = [&](uint32_t a, uint32_t b) {
      const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
      for (auto& c : cache)
        if (c.first == key) return c.second;
      v.push_back(glm::normalize(v[a] + v[b]));
      cache.push_back({key, uint32_t(v.size() - 1)});
      return uint32_t(v.size() - 1);
    };
    for (const auto& tri : f) {
      const uint32_t a = mid(tri.x, tri.y), b = mid(tri.y, tri.z), c = mid(tri.z, tri.x);
      nf.insert(nf.end(), {{tri.x, a, c}, {tri.y, b, a}, {tri.z, c, b}, {a, b, c}});
    }
    f = nf;
  }
  const uint32_t base = uint32_t(m.positions.size());
  for (const auto& p : v) m.positions.push_back(center + radius * p);
  for (const auto& tri : f) {
    m.indices.push_back(tri + uvec3(base));
    m.materials.push_back(material);
  }
}

// A closed box whose six faces are each an n x n grid of shared vertices.
inline void add_grid_box(TriangleMesh& m, vec3 lo, vec3 hi, int n, uint32_t material) {
  auto face = [&](vec3 o, vec3 a, vec3 b) {  // front side: cross(b, a)
    const uint32_t base = uint32_t(m.positions.size());
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) m.positions.push_back(o + a * (float(i) / n) + b * (float(j) / n));
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint32_t v = base + uint32_t(j * (n + 1) + i);
        m.indices.push_back(uvec3(v, v + n + 2, v + 1));
        m.indices.push_back(uvec3(v, v + n + 1, v + n + 2));
        m.materials.insert(m.materials.end(), {material, material});
      }
  };
  const vec3 e = hi - lo;
  face(lo, vec3(0, 0, e.z), vec3(e.x, 0, 0));                       // bottom, -y
  face(vec3(lo.x, hi.y, lo.z), vec3(e.x, 0, 0), vec3(0, 0, e.z));   // top, +y
  face(lo, vec3(e.x, 0, 0), vec3(0, e.y, 0));                       // front, -z
  face(vec3(lo.x, lo.y, hi.z), vec3(0, e.y, 0), vec3(e.x, 0, 0));   // back, +z
  face(lo, vec3(0, e.y, 0), vec3(0, 0, e.z));                       // left, -x
  face(vec3(hi.x, lo.y, lo.z), vec3(0, 0, e.z), vec3(0, e.y, 0));   // right, +x
}

inline Material diffuse(vec3 albedo, vec3 emission = vec3(0.0f), bool two_sided = false) {
  Material m;
  m.type = MaterialType::kDiffuse;
  m.albedo = albedo;
  m.emission = emission;
  m.flags = two_sided ? kMaterialTwoSidedEmission : 0u;
  return m;
}

// The scene's material `name` made a plain one of `type` with albedo 0.9 (the lamp's glass box
// made a mirror, say).
inline void retype_material(Scene& scene, const std::string& name, MaterialType type) {
  for (NamedMaterial& nm : scene.materials)
    if (nm.name == name) {
      nm.material = Material();
      nm.material.type = type;
      nm.material.albedo = vec3(0.9f);
    }
}

// The slab: 400 x 200 x 400 mean free paths, top face at y = 0. Walks that matter stay within a
// few tens of mean free paths, so this is semi-infinite to well under 1e-4 in R, while keeping
// coordinates small enough that the boundary's rounding error is far below a mean free path.
constexpr float kSlabHalf = 200.0f;

// The random walk leaves through the smooth boundary or the diffuse exit (integrator/medium.h):
// index-matched under a uniform sky the two reflect the same total (only the exit's direction
// differs, and every direction sees the same sky), so the analytic albedos hold for both.
// Every other kind of light beside a Cornell-sized box's area light (coordinates 0-555, open
// at -z): a point light, a spot, a sun of 5 degrees through the open front (wide: a narrower
// one's highlight on a near-mirror is a sub-pixel spike that a test's samples do not bound) and
// a constant sky.
inline void add_other_lights(Scene& scene) {
  PointLightDesc point;
  point.name = "point";
  point.position = vec3(150.0f, 420.0f, 250.0f);
  point.intensity = vec3(15000.0f);
  PointLightDesc spot = point;
  spot.name = "spot";
  spot.spot = true;
  spot.position = vec3(420.0f, 450.0f, 150.0f);
  spot.direction = vec3(-0.3f, -1.0f, 0.2f);
  DistantLightDesc sun;
  sun.name = "sun";
  sun.direction = vec3(0.2f, 0.6f, -1.0f);
  sun.irradiance = vec3(1.5f);
  sun.angular_diameter_deg = 5.0f;
  scene.point_lights = {point, spot};
  scene.distant_lights = {sun};
  scene.environment.color = vec3(0.3f, 0.4f, 0.5f);
  refresh_environment(scene);
}

inline Scene slab_scene(float albedo, int grid, bool smooth_exit = true) {
  Scene s;
  Material slab;
  slab.type = MaterialType::kSubsurface;
  slab.flags = smooth_exit ? kMaterialSmoothExit : 0u;
  slab.albedo = vec3(1.0f);  // boundary tint
  slab.ior = 1.0f;           // index-matched: the boundary neither reflects nor bends
  slab.scattering = vec3(albedo);
  slab.absorption = vec3(1.0f - albedo);
  s.materials.push_back({"slab", slab});
  s.materials.push_back({"sky", diffuse(vec3(0.0f), vec3(1.0f), true)});
  if (grid > 1) add_grid_box(s.mesh, vec3(-kSlabHalf, -kSlabHalf, -kSlabHalf), vec3(kSlabHalf, 0.0f, kSlabHalf), grid, 0);
  else add_box(s.mesh, vec3(-kSlabHalf, -kSlabHalf, -kSlabHalf), vec3(kSlabHalf, 0.0f, kSlabHalf), 0);
  s.spheres.push_back({vec3(0.0f), 1e6f, 1});  // everything that leaves lands on the sky
  return s;
}

struct PixelStats {
  int width = 0, height = 0;
  uint32_t spp = 0;
  std::vector<vec3> mean, var;  // per pixel: sample mean and unbiased sample variance
  uint64_t nonfinite = 0;
  vec3 image_mean() const {
    vec3 s(0.0f);
    for (const auto& m : mean) s += m;
    return s / float(mean.size());
  }
};

// Per-pixel statistics of samples [first_sample, first_sample + spp) of a compiled scene with the
// given settings (cfg.width x cfg.height), by the shared trace_path on all cores.
inline PixelStats pixel_stats_of(const CompiledScene& cs, const IntegratorSettings& cfg,
                                 uint32_t spp, uint32_t first_sample = 0) {
  PixelStats ps;
  ps.width = int(cfg.width);
  ps.height = int(cfg.height);
  ps.spp = spp;
  const size_t n = size_t(cfg.width) * cfg.height;
  ps.mean.assign(n, vec3(0.0f));
  ps.var.assign(n, vec3(0.0f));
  std::atomic<uint32_t> next{0};
  std::atomic<uint64_t> bad{0};
  auto work = [&] {
    for (uint32_t p; (p = next.fetch_add(1)) < n;) {
      glm::dvec3 s(0.0), s2(0.0);
      uint32_t good = 0;
      for (uint32_t k = 0; k < spp; ++k) {
        const vec3 L = trace_path(cs.view(), cfg, p, first_sample + k);
        if (!is_finite(L)) {
          bad++;
          continue;
        }
        s += glm::dvec3(L);
        s2 += glm::dvec3(L) * glm::dvec3(L);
        ++good;
      }
      const glm::dvec3 m = s / double(good);
      ps.mean[p] = vec3(m);
      ps.var[p] = vec3(glm::max((s2 - double(good) * m * m) / double(good - 1), glm::dvec3(0.0)));
    }
  };
  std::vector<std::thread> pool;
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& th : pool) th.join();
  ps.nonfinite = bad;
  return ps;
}

// The summed per-pixel variance of b against a at equal samples: plain (.x) and relative to a's
// mean as relMSE weighs it (.y: var / (mean^2 + 0.01)); .z and .w the relative sums of b and a.
inline glm::dvec4 variance_ratios(const PixelStats& b, const PixelStats& a) {
  double va = 0.0, vb = 0.0, ra = 0.0, rb = 0.0;
  for (size_t i = 0; i < a.var.size(); ++i) {
    va += luminance(a.var[i]);
    vb += luminance(b.var[i]);
    const double m = luminance(a.mean[i]);
    ra += luminance(a.var[i]) / (m * m + 1e-2);
    rb += luminance(b.var[i]) / (m * m + 1e-2);
  }
  return glm::dvec4(vb / va, rb / ra, rb, ra);
}

// Renders with the shared trace_path and keeps per-pixel sample variance, for z-tests.
inline PixelStats render_pixel_stats(const Scene& scene, const RenderSettings& rs, uint32_t spp,
                                     uint32_t first_sample = 0) {
  const CompiledScene cs(scene, rs.width, rs.height);
  return pixel_stats_of(cs, make_integrator_settings(rs), spp, first_sample);
}

// A room (scene mesh), a light, a sphere and three instanced meshes placed eleven times: moved,
// rotated, scaled unevenly, mirrored and nested inside each other's boxes (the balls glass on
// request). For the two-level BVH's tests.
inline Scene instanced_scene(bool glass_balls = false) {
  Scene s;
  const uint32_t white = s.add_material("white", diffuse(vec3(0.7f)));
  Material glass;
  glass.type = MaterialType::kDielectric;
  glass.ior = 1.5f;
  const uint32_t red =
      s.add_material("red", glass_balls ? glass : diffuse(vec3(0.7f, 0.1f, 0.1f)));
  const uint32_t green = s.add_material("green", diffuse(vec3(0.1f, 0.7f, 0.1f)));
  const uint32_t light = s.add_material("light", diffuse(vec3(0.0f), vec3(12.0f)));
  add_box(s.mesh, vec3(-4.0f, -1.0f, -4.0f), vec3(4.0f, 5.0f, 4.0f), white);
  // The room's faces point out; the camera is inside, so flip them.
  for (uvec3& t : s.mesh.indices) std::swap(t.y, t.z);
  add_quad(s.mesh, vec3(-1.0f, 4.9f, -1.0f), vec3(2.0f, 0.0f, 0.0f), vec3(0.0f, 0.0f, 2.0f), light);
  s.spheres.push_back({vec3(2.5f, 0.0f, 2.5f), 0.6f, green});

  InstancedMesh ball{"ball", {}};
  add_icosphere(ball.mesh, vec3(0.0f), 0.5f, 2, red);  // smooth normals
  InstancedMesh crate{"crate", {}};
  add_grid_box(crate.mesh, vec3(-0.5f), vec3(0.5f), 3, white);  // no normals
  InstancedMesh empty{"empty", {}};
  s.instanced_meshes = {ball, crate, empty};
  auto place = [&](uint32_t mesh, glm::mat4 m) { s.instances.push_back({mesh, m}); };
  const glm::mat4 id(1.0f);
  place(0, glm::translate(id, vec3(-2.0f, 0.0f, 0.0f)));
  place(2, glm::translate(id, vec3(0.0f, 1.0f, 0.0f)));  // no triangles: no entry
  place(0, glm::scale(glm::translate(id, vec3(0.0f, 0.5f, 0.0f)), vec3(1.0f, 2.0f, 0.5f)));
  place(1, glm::rotate(glm::translate(id, vec3(2.0f, 0.0f, -1.0f)), 0.7f, vec3(0.3f, 1.0f, 0.2f)));
  place(1, glm::scale(glm::translate(id, vec3(-2.0f, 2.0f, -2.0f)), vec3(-1.0f, 1.0f, 1.5f)));
  place(0, glm::scale(glm::translate(id, vec3(1.0f, 2.5f, 1.0f)), vec3(-0.8f, 0.8f, 0.8f)));
  for (int i = 0; i < 6; ++i)  // a row of small crates that overlap each other (no face shared)
    place(1, glm::scale(glm::translate(id, vec3(-3.0f + 0.35f * i, -0.6f + 0.01f * i,
                                                 3.0f + 0.013f * i)),
                        vec3(0.4f + 0.007f * i)));
  ObjectInfo o;
  o.name = "things";
  o.kind = "instances";
  o.is_instances = true;
  o.first = 0;
  o.count = uint32_t(s.instances.size());
  s.objects.push_back(o);
  s.camera.position = vec3(0.0f, 1.5f, 3.9f);
  s.camera.look_at = vec3(0.0f, 1.0f, 0.0f);
  return s;
}

// The |z| above which one of n independent normal tests fails with overall probability alpha
// (Sidak correction), by bisection on the normal tail.
inline double sidak_z(double alpha, size_t n) {
  const double per_test = 1.0 - std::pow(1.0 - alpha, 1.0 / double(n));
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (std::erfc(mid / std::sqrt(2.0)) > per_test) lo = mid; else hi = mid;
  }
  return hi;
}

// Means of 4x4-pixel blocks of two independent renders, z-tested against each other.
inline void expect_same_means(const PixelStats& a, const PixelStats& b, const std::string& what) {
  constexpr int k = 4;
  std::vector<double> zs;
  for (int by = 0; by + k <= a.height; by += k)
    for (int bx = 0; bx + k <= a.width; bx += k)
      for (int c = 0; c < 3; ++c) {
        double ma = 0, va = 0, mb = 0, vb = 0;
        for (int y = by; y < by + k; ++y)
          for (int x = bx; x < bx + k; ++x) {
            const size_t i = size_t(y) * a.width + x;
            ma += a.mean[i][c];
            mb += b.mean[i][c];
            va += a.var[i][c] / a.spp;
            vb += b.var[i][c] / b.spp;
          }
        zs.push_back((ma - mb) / std::sqrt(std::max(va + vb, 1e-20)));
      }
  const double zmax = sidak_z(1e-3, zs.size());
  int failures = 0;
  for (size_t i = 0; i < zs.size(); ++i)
    if (std::abs(zs[i]) > zmax && failures++ < 5)
      ADD_FAILURE() << what << ": block " << i / 3 << " channel " << i % 3 << " z = " << zs[i];
  EXPECT_NEAR(a.image_mean().y, b.image_mean().y, 0.02 * b.image_mean().y) << what;
}

// Bounds a caller may hand the BVH builder, `rounds` times eight: a unit box, the whole float
// range, denormal, empty, NaN, infinite in x, at the top of the float range and a point (x runs
// over 0..period-1).
inline std::vector<Aabb> degenerate_boxes(int rounds, int period) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::nanf("");
  const float big = std::numeric_limits<float>::max();
  const float tiny = std::numeric_limits<float>::denorm_min();
  std::vector<Aabb> boxes;
  auto box = [&](vec3 lo, vec3 hi) {
    Aabb b;
    b.lo = lo;
    b.hi = hi;
    boxes.push_back(b);
  };
  for (int i = 0; i < rounds; ++i) {
    const float x = float(i % period);
    box(vec3(x), vec3(x + 1));
    box(vec3(-big), vec3(big));
    box(vec3(x * tiny), vec3((x + 1) * tiny));
    boxes.push_back(Aabb());  // empty
    box(vec3(nan), vec3(nan));
    box(vec3(-inf, x, x), vec3(inf, x + 1, x + 1));
    box(vec3(big - x, 0, 0), vec3(big, 1, 1));
    box(vec3(3.0f), vec3(3.0f));  // coincident points
  }
  return boxes;
}

}  // namespace test
