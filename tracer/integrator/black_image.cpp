// explain_black_image: a handful of ray casts through the CPU traversal, run once after a render
// whose image is entirely black.
#include "integrator/black_image.h"

#include <cmath>
#include <map>

#include "bvh/traverse.h"

namespace tracer {
namespace {

// n points spread evenly over the unit sphere (a Fibonacci lattice).
vec3 sphere_point(int i, int n) {
  const float z = 1.0f - (2.0f * float(i) + 1.0f) / float(n);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = float(i) * 2.39996323f;  // the golden angle
  return vec3(r * std::cos(phi), r * std::sin(phi), z);
}

// The object that owns triangle t (objects list their triangles in order), or "".
std::string object_of(const Scene& scene, uint32_t prim, uint32_t tri_count) {
  for (const ObjectInfo& o : scene.objects) {
    if (prim < tri_count && o.is_triangles() && prim >= o.first && prim - o.first < o.count)
      return o.name;
    if (prim >= tri_count && o.is_sphere && prim - tri_count == o.first) return o.name;
  }
  return "";
}

vec3 geometric_normal(const TriangleVerts& t) { return glm::cross(t.v1 - t.v0, t.v2 - t.v0); }

}  // namespace

std::string explain_black_image(const Scene& scene, const CompiledScene& cs) {
  const SceneView& v = cs.view();
  if (cs.lights().empty())
    return "the scene has no light: no object uses an emissive material, and there is no "
           "environment and no light in \"lights\" (or they are all black)";

  // Inside a closed object: every ray from the camera hits the back of a surface.
  const vec3 eye = scene.camera.position;
  constexpr int kRays = 256;
  int inside = 0;
  std::map<std::string, int> owners;
  for (int i = 0; i < kRays; ++i) {
    Ray ray{eye, kInfinity, sphere_point(i, kRays), 0.0f};
    const Hit hit = intersect_closest(v, ray);
    if (!hit.valid()) continue;
    // The back of a triangle, or a sphere from inside.
    const bool back = !make_surface_hit(v, ray, hit).front;
    if (back) {
      ++inside;
      ++owners[object_of(scene, hit.prim, v.tri_count)];
    }
  }
  if (inside >= kRays * 9 / 10) {
    std::string name;
    int most = 0;
    for (const auto& [n, count] : owners)
      if (count > most) name = n, most = count;
    return "the camera at " + vec3_str(eye, 4) + " is inside a closed object" +
           (name.empty() ? "" : " (\"" + name + "\")") +
           ": every ray from it meets the inside of a surface; move the camera out (camera.position)";
  }

  // Lights facing away: one-sided emitters whose front side sees neither the camera nor any
  // surface (a light with reversed winding above a model, pointing at the sky).
  const std::vector<Light>& lights = cs.lights();
  const size_t step = std::max<size_t>(1, lights.size() / 64);
  bool any_faces_in = false;
  for (size_t l = 0; l < lights.size() && !any_faces_in; l += step) {
    // Lights at infinity, point and spot lights have no side to face away with.
    if (lights[l].kind != kLightPrimitive) {
      any_faces_in = true;
      break;
    }
    const uint32_t prim = lights[l].prim;
    if (prim >= v.tri_count) {
      any_faces_in = true;  // spheres emit outwards, all around
      break;
    }
    const uint32_t mat = cs.tri_shading()[prim].material;
    if (mat < cs.materials().size() && (cs.materials()[mat].flags & kMaterialTwoSidedEmission)) {
      any_faces_in = true;
      break;
    }
    const TriangleVerts& t = cs.tri_verts()[prim];
    const vec3 n = glm::normalize(geometric_normal(t));
    const vec3 c = (t.v0 + t.v1 + t.v2) / 3.0f;
    if (glm::dot(eye - c, n) > 0.0f) {
      any_faces_in = true;
      break;
    }
    const float offset = 1e-4f * std::max(1.0f, max_component(glm::abs(c)));
    for (int i = 0; i < 64 && !any_faces_in; ++i) {
      vec3 d = sphere_point(i, 64);
      if (glm::dot(d, n) < 0.0f) d = -d;
      Ray ray{c + offset * n, kInfinity, d, 0.0f};
      any_faces_in = intersect_closest(v, ray, prim).valid();
    }
  }
  if (!any_faces_in)
    return "every light faces away from the camera and from every surface (emission leaves the "
           "front side only, the side from which the vertices run counter-clockwise): reverse "
           "the lights' winding or make their material \"two_sided\"";
  std::string why = "no light reaches the camera: the lights may be enclosed or blocked, or the "
                    "camera looks away from everything they light";
  if (scene.settings.max_depth <= 1)
    why += "; render.max_depth is " + std::to_string(scene.settings.max_depth) +
           ", so only lights seen directly can show";
  return why;
}

}  // namespace tracer
