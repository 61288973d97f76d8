// Scene flattening: world-space triangles and spheres into flat arrays, the BVH over both, the
// power-proportional light CDF (emitters, lights at infinity, point and spot lights), the light
// tree and the scene's feature flags.
#include "scene/compiled_scene.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

#include "bvh/traverse.h"
#include "materials/bsdf.h"

namespace tracer {

Camera make_camera(const CameraDesc& d, int width, int height) {
  return make_camera(d.position, d.look_at, d.up, d.vfov_deg, d.aperture_radius,
                     d.focus_distance, uint32_t(width), uint32_t(height));
}

std::string describe_features(uint32_t f) {
  static const struct {
    uint32_t bit;
    const char* name;
  } kNames[] = {
      {kFeatureDepthOfField, "depth of field"},    {kFeatureDielectric, "dielectrics"},
      {kFeatureAbsorption, "absorption"},          {kFeatureMirror, "conductors, plastics and sheets"},
      {kFeatureSubsurface, "subsurface"},          {kFeatureTextures, "textures"},
      {kFeatureEmissiveMeshes, "emissive meshes"}, {kFeatureSpheres, "spheres"},
      {kFeatureShadingNormals, "shading normals"}, {kFeatureInfiniteLights, "lights at infinity"},
      {kFeaturePointLights, "point lights"},
      {kFeatureLightTree, "light tree"},          {kFeatureInstances, "instances"}};
  std::string out;
  for (const auto& n : kNames) {
    if (!(f & n.bit)) continue;
    if (!out.empty()) out += ", ";
    out += n.name;
  }
  return out.empty() ? "none (diffuse only)" : out;
}

namespace {

// Whether a triangle (unit geometric normal n) is flat shaded: no vertex normals, or each zero
// (make_surface_hit then shades by n) or within 1e-5 of n.
bool flat_shaded(const TriangleShading& ts, vec3 n) {
  if (!ts.has_normals) return true;
  for (const vec3 v : {ts.n0, ts.n1, ts.n2})
    if (glm::dot(v, v) != 0.0f && glm::abs(glm::dot(glm::normalize(v), n)) < 1.0f - 1e-5f)
      return false;
  return true;
}

// The planes of the scene's flat smooth reflectors (scene_view.h, ReflectorPlane): triangles of
// smooth glass or of a smooth reflector, flat shaded, grouped by plane (normals within 1e-5 of
// each other, offsets within tol, 1e-5 of the scene's size: one plane is one entry, or a chain
// through it would be found twice). None when there are more than kMaxReflectorPlanes.
std::vector<ReflectorPlane> reflector_planes_of(const std::vector<TriangleVerts>& verts,
                                                const std::vector<TriangleShading>& shading,
                                                const std::vector<Material>& materials,
                                                uint32_t tri_count, float tol, bool* too_many) {
  *too_many = false;
  bool any = false;  // (no pass over the triangles where no material reflects)
  for (const Material& m : materials) any = any || mnee_flat_reflector(m);
  if (!any) return {};
  std::vector<ReflectorPlane> planes;
  for (uint32_t i = 0; i < tri_count; ++i) {
    const Material& m = materials[shading[i].material];
    if (!mnee_flat_reflector(m)) continue;
    const TriangleVerts& t = verts[i];
    const vec3 c = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
    const float len = glm::length(c);
    if (!(len > 0.0f)) continue;
    const vec3 n = c / len;
    if (!flat_shaded(shading[i], n)) continue;
    auto same = [&](const ReflectorPlane& p) {
      return glm::dot(p.n, n) > 1.0f - 1e-5f && glm::abs(glm::dot(t.v0 - p.a, p.n)) <= tol &&
             glm::abs(glm::dot(t.v1 - p.a, p.n)) <= tol && glm::abs(glm::dot(t.v2 - p.a, p.n)) <= tol;
    };
    ReflectorPlane* p = nullptr;
    for (ReflectorPlane& q : planes)
      if (same(q)) p = &q;
    if (!p) {
      if (planes.size() == kMaxReflectorPlanes) {
        *too_many = true;
        return {};
      }
      planes.push_back({t.v0, 0.0f, n, 0.0f, t.v0, t.v0});
      p = &planes.back();
    }
    for (const vec3 v : {t.v0, t.v1, t.v2}) {
      p->lo = glm::min(p->lo, v);
      p->hi = glm::max(p->hi, v);
    }
  }
  return planes;
}


// Whether glass triangle i sees something other than its own glass: from its centre into the
// glass, five rays (along the normal and tilted 45 degrees four ways).
bool glass_sees_out(const SceneView& s, uint32_t i) {
  const TriangleVerts& t = s.tri_verts[i];
  const vec3 c = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
  const float len = glm::length(c);
  if (!(len > 0.0f)) return false;
  const vec3 n = c / len, centre = (t.v0 + t.v1 + t.v2) / 3.0f;
  const uint32_t material = s.tri_shading[i].material;
  const Frame f = Frame::from_normal(-n);
  for (int d = 0; d < 5; ++d) {
    const vec3 dir =
        d == 0 ? -n : glm::normalize(f.n + ((d & 1) ? 1.0f : -1.0f) * (d < 3 ? f.t : f.b));
    Ray r;
    r.o = offset_ray_origin(centre, -n);
    r.d = dir;
    r.tmax = kInfinity;
    r.pad = 0.0f;
    const Hit h = intersect_closest(static_cast<const TraceView&>(s), r, i);
    if (!h.valid()) continue;
    const uint32_t hm = h.prim < s.tri_count
                            ? s.tri_shading[h.prim].material
                            : (h.prim - s.tri_count < s.sphere_count
                                   ? s.spheres[h.prim - s.tri_count].material
                                   : kInvalid);
    if (hm != material) return true;
  }
  return false;
}

// Whether any of 256 triangles of smooth glass, spread evenly over them, sees out
// (glass_sees_out).
bool open_glass_of(const SceneView& s, uint32_t tri_count) {
  std::vector<uint32_t> glass;
  for (uint32_t i = 0; i < tri_count; ++i)
    if (mnee_glass(s.materials[s.tri_shading[i].material])) glass.push_back(i);
  const size_t tries = std::min<size_t>(glass.size(), 256);
  for (size_t j = 0; j < tries; ++j)
    if (glass_sees_out(s, glass[j * glass.size() / tries])) return true;
  return false;
}

// Light tracing's targets (scene_view.h, LightTarget): each sphere of a material where a light
// path may start (light_path_may_start_at), and a sphere around the triangles of each such
// material; more than kMaxLightTargets become one around them all. None with instances (whose
// materials this does not look into).
std::vector<LightTarget> light_targets_of(const SceneView& s, uint32_t tri_count) {
  std::vector<LightTarget> targets;
  if (s.instance_count > 0) return targets;
  std::vector<char> starts(s.material_count);
  for (uint32_t m = 0; m < s.material_count; ++m)
    starts[m] = light_path_may_start_at(s.materials[m]) ? 1 : 0;
  std::vector<Aabb> boxes;  // per material: the triangles', then the spheres' one by one
  std::vector<uint32_t> slot(s.material_count, kInvalid);
  for (uint32_t i = 0; i < tri_count; ++i) {
    const uint32_t m = s.tri_shading[i].material;
    if (!starts[m]) continue;
    if (slot[m] == kInvalid) {
      slot[m] = uint32_t(boxes.size());
      boxes.emplace_back();
    }
    const TriangleVerts& t = s.tri_verts[i];
    for (const vec3 v : {t.v0, t.v1, t.v2}) boxes[slot[m]].grow(v);
  }
  auto around = [](const Aabb& b) -> LightTarget {
    return {0.5f * (b.lo + b.hi), 0.5f * glm::length(b.hi - b.lo)};
  };
  for (const Aabb& b : boxes) targets.push_back(around(b));
  Aabb all;
  for (const Aabb& b : boxes) all.grow(b);
  for (uint32_t i = 0; i < s.sphere_count; ++i) {
    const Sphere& sp = s.spheres[i];
    if (!starts[sp.material]) continue;
    targets.push_back({sp.center, sp.radius});
    all.grow(sp.center - vec3(sp.radius));
    all.grow(sp.center + vec3(sp.radius));
  }
  if (targets.size() > kMaxLightTargets) targets.assign(1, around(all));
  // A light reaching into a target (a lamp inside its glass) leaves by the cosine, and the scene
  // keeps one light path per pixel: none then. (A light without power starts no light path.)
  for (uint32_t l = 0; l < s.light_count; ++l) {
    if (s.lights[l].kind != kLightPrimitive) continue;
    const Aabb box = light_bounds(s, s.lights[l]).box;
    if (box.lo.x > box.hi.x) continue;
    for (const LightTarget& t : targets) {
      const vec3 q = glm::clamp(t.center, box.lo, box.hi);  // the box's point nearest the centre
      if (glm::dot(q - t.center, q - t.center) <= t.radius * t.radius) return {};
    }
  }
  // A little wider, against the rounding of the cone's test.
  for (LightTarget& t : targets) t.radius *= 1.0f + 1e-4f;
  return targets;
}

// The window planes (scene_view.h, WindowPlane): triangles of smooth glass, flat shaded, grouped
// by plane and material (normals within 1e-5, offsets within tol), through which something
// other than that glass is seen (a ray into the glass from one of the plane's first triangles
// meets another surface first: a tank's front, not a glass slab's faces, whose paths behind
// them are all inside the glass), the kMaxWindowPlanes of the largest area (a tank's front; not
// the few flat triangles of a water surface's calm patches). Triangles meet their plane through
// a hash of its quantised normal and offset; a plane split between two cells merges when the
// largest are kept, so no plane is listed twice (light tracing would count its paths twice).
std::vector<WindowPlane> window_planes_of(const SceneView& s, uint32_t tri_count) {
  struct Candidate {
    WindowPlane plane;
    float area;
    bool open;
  };
  const float tol = s.window_tol;
  std::vector<Candidate> candidates;
  std::unordered_map<uint64_t, size_t> cell;
  const float step = glm::max(100.0f * tol, 1e-30f);
  for (uint32_t i = 0; i < tri_count; ++i) {
    const TriangleShading& ts = s.tri_shading[i];
    const Material& m = s.materials[ts.material];
    if (!mnee_glass(m)) continue;
    const TriangleVerts& t = s.tri_verts[i];
    const vec3 c = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
    const float len = glm::length(c);
    if (!(len > 0.0f)) continue;
    const vec3 n = c / len;
    if (!flat_shaded(ts, n)) continue;
    uint64_t key = ts.material;
    for (const float q : {n.x * 1e3f, n.y * 1e3f, n.z * 1e3f, glm::dot(n, t.v0) / step})
      key = key * 1000003u + uint64_t(int64_t(glm::floor(q)));
    auto it = cell.find(key);
    if (it == cell.end()) {
      it = cell.emplace(key, candidates.size()).first;
      candidates.push_back({{t.v0, m.ior, n, ts.material, t.v0, t.v0}, 0.0f, false});
    }
    Candidate& cd = candidates[it->second];
    // Open: the first triangles of the plane, until one sees out.
    if (!cd.open && cd.area < 64.0f * 0.5f * len) cd.open = glass_sees_out(s, i);
    cd.area += 0.5f * len;
    for (const vec3 v : {t.v0, t.v1, t.v2}) {
      cd.plane.lo = glm::min(cd.plane.lo, v);
      cd.plane.hi = glm::max(cd.plane.hi, v);
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& x, const Candidate& y) { return x.area > y.area; });
  std::vector<WindowPlane> kept;
  for (const Candidate& cd : candidates) {
    const WindowPlane& q = cd.plane;
    WindowPlane* same = nullptr;
    for (WindowPlane& k : kept)
      if (k.material == q.material && glm::dot(k.n, q.n) > 1.0f - 1e-5f &&
          glm::abs(glm::dot(q.a - k.a, k.n)) <= tol)
        same = &k;
    if (same) {
      same->lo = glm::min(same->lo, q.lo);
      same->hi = glm::max(same->hi, q.hi);
    } else if (cd.open && kept.size() < kMaxWindowPlanes) {
      kept.push_back(q);
    }
  }
  return kept;
}

}  // namespace

CompiledScene::CompiledScene(const Scene& scene, int width, int height,
                             const CompiledScene* same_geometry) {
  materials_.reserve(scene.materials.size());
  for (const auto& nm : scene.materials) materials_.push_back(nm.material);

  const TriangleMesh& mesh = scene.mesh;
  const bool has_normals = mesh.normals.size() == mesh.positions.size() && !mesh.normals.empty();
  const uint32_t tri_count = uint32_t(mesh.indices.size());
  tri_verts_.resize(tri_count);
  tri_shading_.resize(tri_count);
  std::vector<Aabb> bounds;
  bounds.reserve(tri_count + scene.spheres.size());
  uint32_t features = 0;
  Aabb tri_bounds;  // (its size gives the tolerance of the planes of reflectors and windows)
  for (uint32_t i = 0; i < tri_count; ++i) {
    const uvec3 idx = mesh.indices[i];
    TriangleVerts& tv = tri_verts_[i];
    tv.v0 = mesh.positions[idx.x];
    tv.v1 = mesh.positions[idx.y];
    tv.v2 = mesh.positions[idx.z];
    TriangleShading& ts = tri_shading_[i];
    ts.material = mesh.materials[i];
    ts.light = kInvalid;
    ts.has_normals = has_normals ? 1u : 0u;
    if (has_normals) {
      ts.n0 = mesh.normals[idx.x];
      ts.n1 = mesh.normals[idx.y];
      ts.n2 = mesh.normals[idx.z];
      features |= kFeatureShadingNormals;
    } else {
      ts.n0 = ts.n1 = ts.n2 = vec3(0.0f);
    }
    Aabb b;
    b.grow(tv.v0);
    b.grow(tv.v1);
    b.grow(tv.v2);
    bounds.push_back(b);
    tri_bounds.grow(b);
  }
  const float plane_tol = tri_count ? 1e-5f * glm::length(tri_bounds.hi - tri_bounds.lo) : 0.0f;
  spheres_.reserve(scene.spheres.size());
  for (const auto& sd : scene.spheres) {
    Sphere s{};
    s.center = sd.center;
    s.radius = sd.radius;
    s.material = sd.material;
    s.light = kInvalid;
    spheres_.push_back(s);
    Aabb b;
    b.grow(sd.center - vec3(sd.radius));
    b.grow(sd.center + vec3(sd.radius));
    bounds.push_back(b);
    features |= kFeatureSpheres;
  }

  // Instances: each instanced mesh's triangles once (inst_tri_*), its tree over them, and one
  // entry per instance in the first level's tree, bounded by its mesh's box mapped to the world.
  std::vector<Aabb> mesh_boxes;
  std::vector<uint32_t> mesh_tri_base;
  if (!scene.instances.empty()) {
    for (const InstancedMesh& im : scene.instanced_meshes) {
      const TriangleMesh& m = im.mesh;
      const bool normals = m.normals.size() == m.positions.size() && !m.normals.empty();
      mesh_tri_base.push_back(uint32_t(inst_tri_verts_.size()));
      Aabb box;
      for (size_t t = 0; t < m.indices.size(); ++t) {
        const uvec3 idx = m.indices[t];
        TriangleVerts tv{};
        tv.v0 = m.positions[idx.x];
        tv.v1 = m.positions[idx.y];
        tv.v2 = m.positions[idx.z];
        TriangleShading ts{};
        ts.material = m.materials[t];
        ts.light = kInvalid;
        ts.has_normals = normals ? 1u : 0u;
        if (normals) {
          ts.n0 = m.normals[idx.x];
          ts.n1 = m.normals[idx.y];
          ts.n2 = m.normals[idx.z];
          features |= kFeatureShadingNormals;
        }
        if (materials_[ts.material].is_emissive())
          throw std::invalid_argument("instanced mesh \"" + im.name +
                                      "\" has an emissive material; emitters must be flattened "
                                      "(flatten_instances)");
        box.grow(tv.v0);
        box.grow(tv.v1);
        box.grow(tv.v2);
        inst_tri_verts_.push_back(tv);
        inst_tri_shading_.push_back(ts);
      }
      mesh_boxes.push_back(box);
    }
    uint64_t prim_base = uint64_t(tri_count) + scene.spheres.size();
    for (const MeshInstance& mi : scene.instances) {
      const uint32_t count = uint32_t(scene.instanced_meshes[mi.mesh].mesh.indices.size());
      if (count == 0) continue;
      const glm::mat4 to_object = glm::inverse(mi.world_from_object);
      Instance in{};
      for (int r = 0; r < 3; ++r) {
        const glm::mat4& a = mi.world_from_object;
        in.world_from_object[r] = vec4(a[0][r], a[1][r], a[2][r], a[3][r]);
        in.object_from_world[r] = vec4(to_object[0][r], to_object[1][r], to_object[2][r],
                                       to_object[3][r]);
      }
      in.tri_base = mesh_tri_base[mi.mesh];
      in.prim_base = uint32_t(prim_base);
      in.root = mi.mesh;  // the mesh until its tree is placed below
      prim_base += count;
      if (prim_base >= kBvhLeafBit)
        throw std::invalid_argument("the scene's instances place more than 2^31 triangles");
      const Aabb& mb = mesh_boxes[mi.mesh];
      Aabb b;
      for (int c = 0; c < 8; ++c) {
        const vec3 corner((c & 1) ? mb.hi.x : mb.lo.x, (c & 2) ? mb.hi.y : mb.lo.y,
                          (c & 4) ? mb.hi.z : mb.lo.z);
        b.grow(affine_point(in.world_from_object, corner));
      }
      bounds.push_back(b);
      instances_.push_back(in);
      features |= kFeatureInstances;
    }
  }

  // Lights: every primitive whose material emits, chosen in proportion to luminance x area.
  auto add_light = [&](uint32_t prim, float area, const Material& m) {
    Light l;
    l.prim = prim;
    l.area = area;
    l.power = luminance(m.emission) * area;
    if (m.flags & kMaterialTwoSidedEmission) l.power *= 2.0f;
    l.kind = kLightPrimitive;
    if (!(l.power > 0.0f)) l.power = max_component(m.emission) * area;
    lights_.push_back(l);
    return uint32_t(lights_.size() - 1);
  };
  for (uint32_t i = 0; i < tri_count; ++i) {
    const Material& m = materials_[tri_shading_[i].material];
    if (!m.is_emissive()) continue;
    const TriangleVerts& tv = tri_verts_[i];
    const float area = 0.5f * glm::length(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
    if (!(area > 0.0f)) continue;
    tri_shading_[i].light = add_light(i, area, m);
    features |= kFeatureEmissiveMeshes;
  }
  for (uint32_t i = 0; i < spheres_.size(); ++i) {
    const Material& m = materials_[spheres_[i].material];
    if (!m.is_emissive()) continue;
    const float area = 4.0f * kPi * spheres_[i].radius * spheres_[i].radius;
    spheres_[i].light = add_light(tri_count + i, area, m);
  }
  // Point and spot lights, chosen in proportion to their flux (pbrt-v4's Phi; Light::power is
  // flux / pi like the others'). Black ones light nothing and are left out. Before the lights at
  // infinity, which the light choice expects last (integrator/lights.h, choose_light).
  std::vector<vec3> light_points;
  for (const PointLightDesc& d : scene.point_lights) {
    double lum = double(luminance(d.intensity));
    if (!(lum > 0.0)) lum = double(max_component(d.intensity));
    if (!(lum > 0.0)) continue;
    PointLight pl = make_point_light(d);
    Light l;
    l.prim = uint32_t(point_lights_.size());
    l.area = 0.0f;
    l.power = float(lum * point_light_solid_angle(d) / M_PI);
    l.kind = d.spot ? kLightSpot : kLightPoint;
    lights_.push_back(l);
    pl.light = uint32_t(lights_.size() - 1);
    point_lights_.push_back(pl);
    light_points.push_back(d.position);
    features |= kFeaturePointLights;
  }
  // The lights at infinity: the environment's map (read here only when the scene's copy is
  // missing or stale, e.g. a scene built in code) and the distant lights. Their power is pbrt-v4's
  // estimate (PowerLightSampler): the flux through the disc of the scene's bounding sphere,
  // pi R^2 times the radiance integrated over the sphere (a distant light: its irradiance).
  infinite_ = std::make_unique<InfiniteLightsData>();
  {
    std::shared_ptr<const EnvironmentImage> image = scene.environment_image;
    const std::string& file = scene.environment.file;
    if (!file.empty() && (!image || image->path != file)) image = read_environment_image(file);
    build_infinite_lights(scene.environment, image, scene.distant_lights, infinite_.get());
  }
  if (infinite_->any()) {
    features |= kFeatureInfiniteLights;
    Aabb box;
    for (const Aabb& b : bounds) box.grow(b);
    const float radius = box.empty() ? 1.0f : 0.5f * glm::length(box.hi - box.lo);
    const double r2 = std::max(double(radius) * radius, 1e-30);
    auto add_infinite = [&](uint32_t kind, uint32_t index, double power) {
      Light l;
      l.prim = index;
      l.area = 0.0f;
      l.power = float(power);
      l.kind = kind;
      lights_.push_back(l);
      return uint32_t(lights_.size() - 1);
    };
    InfiniteLights& inf = infinite_->view;
    if (inf.env != kEnvNone)
      inf.env_light = add_infinite(kLightEnvironment, 0, r2 * infinite_->env_luminance_integral);
    for (size_t i = 0; i < infinite_->distant.size(); ++i)
      infinite_->distant[i].light =
          add_infinite(kLightDistant, uint32_t(i), r2 * infinite_->distant_luminance[i]);
  }
  double total = 0.0;
  for (const Light& l : lights_) total += l.power;
  light_cdf_.resize(lights_.size() + 1);
  light_cdf_[0] = 0.0f;
  double acc = 0.0;
  for (size_t i = 0; i < lights_.size(); ++i) {
    acc += total > 0.0 ? lights_[i].power : 1.0;  // no power at all: every light alike
    light_cdf_[i + 1] = float(acc / (total > 0.0 ? total : double(lights_.size())));
  }
  if (!lights_.empty()) light_cdf_.back() = 1.0f;

  for (const Material& m : materials_) {
    if (m.type == MaterialType::kDielectric) features |= kFeatureDielectric;
    if (m.type == MaterialType::kDielectric && max_component(m.absorption) > 0.0f)
      features |= kFeatureAbsorption;
    // Every other non-diffuse reflector (and the thin diffuse transmitter) counts as a mirror:
    // the bit only has to pull in the kernels' specular code (kFeatureSpecular).
    if (m.type == MaterialType::kMirror || m.type == MaterialType::kConductor ||
        m.type == MaterialType::kCoatedDiffuse || m.type == MaterialType::kDiffuseTransmission)
      features |= kFeatureMirror;
    if (m.type == MaterialType::kSubsurface) features |= kFeatureSubsurface;
  }
  if (scene.camera.aperture_radius > 0.0f) features |= kFeatureDepthOfField;

  // Textures: one flat texel array for all of them, uploaded once. Only scenes whose materials
  // use a texture get the feature (and pay for texture code and uvs).
  bool textured = false;
  for (const Material& m : materials_) {
    if (!m.has_textures()) continue;
    textured = true;
    // A metallic-roughness map can turn a diffuse material into a conductor per texel.
    if (m.metal_rough_tex != kInvalid) features |= kFeatureMirror;
  }
  if (textured) {
    features |= kFeatureTextures;
    size_t total = 0;
    for (const TextureImage& t : scene.textures) total += size_t(t.width) * size_t(t.height);
    texels_.reserve(total);
    for (const TextureImage& t : scene.textures) {
      TextureDesc d;
      d.offset = uint32_t(texels_.size());
      d.width = uint32_t(t.width);
      d.height = uint32_t(t.height);
      d.flags = uint32_t(t.wrap_s) | uint32_t(t.wrap_t) << 2 | (t.srgb ? kTextureSrgb : 0u);
      d.uv_transform = t.uv_transform;
      const size_t n = size_t(t.width) * size_t(t.height);
      for (size_t i = 0; i < n; ++i) {
        const uint8_t* c = &t.rgba8[4 * i];
        texels_.push_back(uint32_t(c[0]) | uint32_t(c[1]) << 8 | uint32_t(c[2]) << 16 |
                          uint32_t(c[3]) << 24);
      }
      textures_.push_back(d);
    }
    if (mesh.uvs.size() == mesh.positions.size() && !mesh.uvs.empty()) {
      tri_uvs_.resize(tri_count);
      for (uint32_t i = 0; i < tri_count; ++i) {
        const uvec3 idx = mesh.indices[i];
        tri_uvs_[i] = {mesh.uvs[idx.x], mesh.uvs[idx.y], mesh.uvs[idx.z]};
      }
    }    // Instanced meshes: uvs for all their triangles when any has some ((0, 0) for the others).
    bool inst_uvs = false;
    for (const InstancedMesh& im : scene.instanced_meshes)
      inst_uvs |= !im.mesh.uvs.empty() && im.mesh.uvs.size() == im.mesh.positions.size();
    if (inst_uvs && !instances_.empty()) {
      inst_tri_uvs_.reserve(inst_tri_verts_.size());
      for (const InstancedMesh& im : scene.instanced_meshes) {
        const TriangleMesh& m = im.mesh;
        const bool has = !m.uvs.empty() && m.uvs.size() == m.positions.size();
        for (const uvec3& idx : m.indices)
          inst_tri_uvs_.push_back(has ? TriangleUv{m.uvs[idx.x], m.uvs[idx.y], m.uvs[idx.z]}
                                      : TriangleUv{vec2(0.0f), vec2(0.0f), vec2(0.0f)});
      }
    }
  }

  if (same_geometry && same_geometry->view().tri_count == tri_count &&
      same_geometry->view().sphere_count == spheres_.size() &&
      same_geometry->instances_.size() == instances_.size() &&
      same_geometry->inst_tri_verts_.size() == inst_tri_verts_.size() && same_geometry->bvh_) {
    bvh_ = same_geometry->bvh_;
    cpu_bvh_ = same_geometry->cpu_bvh_;
    bvh8_ = same_geometry->bvh8_;
    inst_bvh_ = same_geometry->inst_bvh_;
    mesh_roots_ = same_geometry->mesh_roots_;
    shared_bvh_ = true;
  } else {
    auto bvh = std::make_shared<Bvh>(build_bvh(bounds));
    // The CPU's SSE walk knows triangles and spheres only: with instances it walks the shared
    // tree (an empty CpuBvh).
    cpu_bvh_ = std::make_shared<const CpuBvh>(
        instances_.empty() ? build_cpu_bvh(*bvh, tri_verts_, tri_count) : CpuBvh());
    bvh8_ = std::make_shared<const Bvh8>(kBvh8Build ? build_bvh8(*bvh) : Bvh8());
    bvh_ = std::move(bvh);
    // Each instanced mesh's tree, appended to one node and index array: child references and
    // leaf entries are moved by where the mesh's tree starts.
    auto inst = std::make_shared<Bvh>();
    mesh_roots_.assign(scene.instanced_meshes.size(), kInvalid);
    if (!instances_.empty()) {
      for (size_t m = 0; m < scene.instanced_meshes.size(); ++m) {
        const uint32_t n = uint32_t(scene.instanced_meshes[m].mesh.indices.size());
        if (n == 0) continue;
        std::vector<Aabb> tb(n);
        for (uint32_t t = 0; t < n; ++t) {
          const TriangleVerts& tv = inst_tri_verts_[mesh_tri_base[m] + t];
          tb[t].grow(tv.v0);
          tb[t].grow(tv.v1);
          tb[t].grow(tv.v2);
        }
        const Bvh mb = build_bvh(tb);
        const uint32_t node_base = uint32_t(inst->nodes.size());
        const uint32_t entry_base = uint32_t(inst->prim_indices.size());
        mesh_roots_[m] = node_base;
        for (BvhNode node : mb.nodes) {
          for (BvhSlot& slot : node.child)
            slot.ref = is_leaf_ref(slot.ref) ? slot.ref + entry_base : slot.ref + node_base;
          inst->nodes.push_back(node);
        }
        for (uint32_t e : mb.prim_indices)
          inst->prim_indices.push_back(e + mesh_tri_base[m]);  // keeps kBvhLastPrimBit
        inst->stats.node_count += mb.stats.node_count;
        inst->stats.leaf_count += mb.stats.leaf_count;
        inst->stats.build_ms += mb.stats.build_ms;
      }
    }
    inst_bvh_ = std::move(inst);
  }
  for (Instance& in : instances_) in.root = mesh_roots_[in.root];
  // With lights at infinity shadow rays leave the scene, so no entry may be skipped as hull.
  // Point lights are ends of shadow rays too: a wall with one behind it is no hull. Scenes with
  // instances have no list (its loops know triangles and spheres only).
  if (instances_.empty())
    flat_ = build_flat_list(tri_verts_, spheres_, infinite_->any(), light_points);

  view_.nodes = bvh_->nodes.data();
  view_.prim_indices = bvh_->prim_indices.data();
  view_.tri_verts = tri_verts_.data();
  view_.tri_shading = tri_shading_.data();
  view_.spheres = spheres_.data();
  view_.materials = materials_.data();
  view_.lights = lights_.data();
  view_.light_cdf = light_cdf_.data();
  view_.tri_uvs = tri_uvs_.empty() ? nullptr : tri_uvs_.data();
  view_.instances = instances_.empty() ? nullptr : instances_.data();
  view_.instance_count = uint32_t(instances_.size());
  view_.inst_nodes = inst_bvh_->nodes.data();
  view_.inst_prim_indices = inst_bvh_->prim_indices.data();
  view_.inst_tri_verts = inst_tri_verts_.data();
  view_.inst_tri_shading = inst_tri_shading_.data();
  view_.inst_tri_uvs = inst_tri_uvs_.empty() ? nullptr : inst_tri_uvs_.data();
  view_.textures = textures_.data();
  view_.texels = texels_.data();
  view_.infinite = infinite_->any() ? &infinite_->view : nullptr;
  view_.point_lights = point_lights_.empty() ? nullptr : point_lights_.data();
  view_.point_light_count = uint32_t(point_lights_.size());
  reflector_planes_ =
      reflector_planes_of(tri_verts_, tri_shading_, materials_, tri_count, plane_tol,
                          &too_many_reflectors_);
  view_.reflector_planes = reflector_planes_.empty() ? nullptr : reflector_planes_.data();
  view_.reflector_plane_count = uint32_t(reflector_planes_.size());
  view_.texture_count = uint32_t(textures_.size());
  view_.node_count = uint32_t(bvh_->nodes.size());
  view_.tri_count = tri_count;
  view_.sphere_count = uint32_t(spheres_.size());
  view_.material_count = uint32_t(materials_.size());
  view_.light_count = uint32_t(lights_.size());
  // The light tree over every light but those at infinity, which the light choice expects last
  // (integrator/lights.h, choose_light: they take the tail of the power CDF).
  uint32_t finite = 0;
  while (finite < lights_.size() && !light_at_infinity(lights_[finite].kind)) ++finite;
  for (size_t i = finite; i < lights_.size(); ++i)
    if (!light_at_infinity(lights_[i].kind))
      throw std::logic_error("CompiledScene: a light of kind " + std::to_string(lights_[i].kind) +
                             " follows the lights at infinity");
  std::vector<LightBounds> light_bounds_list;
  light_bounds_list.reserve(lights_.size());
  for (const Light& l : lights_) light_bounds_list.push_back(light_bounds(view_, l));
  light_tree_ = build_light_tree(light_bounds_list);
  // A tree of one leaf chooses by power: bvh then runs the power sampler (integrator/lights.h).
  view_.light_tree.nodes = light_tree_.nodes.size() > 1 ? light_tree_.nodes.data() : nullptr;
  view_.light_tree.leaves = light_tree_.leaves.data();
  view_.light_tree.trails = light_tree_.trails.data();
  view_.finite_light_count = finite;
  if (view_.light_tree.nodes) features |= kFeatureLightTree;
  view_.features = features;
  view_.camera = make_camera(scene.camera, width, height);
  view_.cpu_bvh = cpu_bvh_->view();
  if (flat_.enabled) {
    view_.flat = view_.flat_loop = flat_.prims.data();
    view_.flat_info = flat_.info.data();
    view_.tri_to_flat = flat_.tri_to_flat.data();
    view_.flat_count = uint32_t(flat_.prims.size());
    view_.flat_quads = flat_.quad_count;
    view_.flat_quad_blockers = flat_.quad_blockers;
    view_.flat_triangle_blockers_end = flat_.triangle_blockers_end;
    view_.flat_box_faces = flat_.box_faces;
    view_.flat_box_lo = vec3(flat_.box_lo[0], flat_.box_lo[1], flat_.box_lo[2]);
    view_.flat_box_hi = vec3(flat_.box_hi[0], flat_.box_hi[1], flat_.box_hi[2]);
    for (int f = 0; f < 6; ++f) view_.flat_box_entry[f] = flat_.box_entry[f];
    view_.flat_solids = flat_.solids.data();
    view_.flat_solid_count = uint32_t(flat_.solids.size());
  }
  // Light tracing's windows, once rays can be traced.
  view_.window_tol = plane_tol;
  window_planes_ = window_planes_of(view_, tri_count);
  view_.open_glass = open_glass_of(view_, tri_count) ? 1u : 0u;
  view_.window_planes = window_planes_.empty() ? nullptr : window_planes_.data();
  view_.window_plane_count = uint32_t(window_planes_.size());
  light_targets_ = light_targets_of(view_, tri_count);
  view_.light_targets = light_targets_.empty() ? nullptr : light_targets_.data();
  view_.light_target_count = uint32_t(light_targets_.size());
}

}  // namespace tracer
