// The flat primitive list (bvh/flat_list.h) that the GPU uses for small scenes: it must pair
// quads correctly, find what the BVH finds (the same triangle, t and hit point, up to the
// rounding of a different test), never let a ray slip through a shared edge, be built only for
// small scenes, and render the image the BVH renders. All of it runs here, on the CPU, through
// the shared code the GPU compiles.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "cpu/cpu_backend.h"
#include "integrator/path.h"
#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace test;

SceneView flat_view(const CompiledScene& cs) {
  SceneView v = cs.view();
  v.use_flat = 1;
  return v;
}

// A ray between two random points of the box, of length tmax.
Ray random_ray(const Aabb& box, std::mt19937& rng, float tmax) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const vec3 ext = box.hi - box.lo;
  Ray r;
  r.o = box.lo + ext * vec3(u(rng), u(rng), u(rng));
  r.d = glm::normalize(box.lo + ext * vec3(u(rng), u(rng), u(rng)) - r.o);
  r.tmax = tmax;
  r.pad = 0.0f;
  return r;
}

SceneView bvh_view(const CompiledScene& cs) {
  SceneView v = cs.view();
  v.use_flat = 0;
  v.cpu_bvh = CpuBvhView();  // the shared traversal the GPU runs
  return v;
}

vec3 hit_point(const CompiledScene& cs, const Ray& r, const Hit& h) {
  if (h.prim >= cs.view().tri_count) return r.o + h.t * r.d;
  const TriangleVerts& tv = cs.tri_verts()[h.prim];
  return (1.0f - h.u - h.v) * tv.v0 + h.u * tv.v1 + h.v * tv.v2;
}

// Random rays from in and around the scene's box: the flat list against the BVH.
void check_agreement(const CompiledScene& cs, int rays, const std::string& what) {
  ASSERT_TRUE(cs.flat_list().enabled) << what;
  const SceneView flat = flat_view(cs), bvh = bvh_view(cs);
  const Aabb box = scene_bounds(cs);
  const vec3 ext = box.hi - box.lo;
  const float scale = glm::length(ext);
  std::mt19937 rng(4321);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int hits = 0, validity = 0, far = 0, any_differ = 0, grazes = 0;
  for (int i = 0; i < rays; ++i) {
    Ray r;
    r.o = box.lo - 0.1f * ext + 1.2f * ext * vec3(u(rng), u(rng), u(rng));
    r.d = glm::normalize(box.lo + ext * vec3(u(rng), u(rng), u(rng)) - r.o);
    r.tmax = kInfinity;
    r.pad = 0.0f;
    const Hit a = intersect_closest(flat, r), b = intersect_closest(bvh, r);
    if (b.valid()) ++hits;
    if (a.valid() && !b.valid() && a.prim < cs.view().tri_count &&
        std::min({a.u, a.v, 1.0f - a.u - a.v}) > -2.0f * kFlatEdgeTolerance) {
      ++grazes;  // within the edge tolerance of a triangle the BVH's exact test misses
      continue;
    }
    if (a.valid() != b.valid()) {
      if (validity++ < 5)
        ADD_FAILURE() << what << ": ray " << i << " flat prim " << a.prim << " t " << a.t
                      << " vs bvh prim " << b.prim << " t " << b.t;
      continue;
    }
    if (!b.valid()) continue;
    // The same t, and the same point from the barycentrics (which checks the quad -> triangle
    // maps); a different triangle only where two tie (coplanar halves, edges).
    const vec3 pa = hit_point(cs, r, a), pb = hit_point(cs, r, b);
    if (std::fabs(a.t - b.t) > 1e-4f * b.t + 1e-5f * scale || glm::length(pa - pb) > 1e-4f * scale) {
      if (far++ < 5)
        ADD_FAILURE() << what << ": ray " << i << " flat prim " << a.prim << " t " << a.t
                      << " uv " << a.u << "," << a.v << " vs bvh prim " << b.prim << " t " << b.t
                      << " uv " << b.u << "," << b.v;
    }
    if (a.prim == b.prim && a.prim < cs.view().tri_count) {
      EXPECT_NEAR(a.u, b.u, 1e-3f) << what << ": ray " << i;
      EXPECT_NEAR(a.v, b.v, 1e-3f) << what << ": ray " << i;
    }
    // Skipping the primitive a ray leaves from, and occlusion before and beyond the hit.
    const Hit a2 = intersect_closest(flat, r, b.prim), b2 = intersect_closest(bvh, r, b.prim);
    if (a2.valid() != b2.valid() ||
        (b2.valid() && std::fabs(a2.t - b2.t) > 1e-4f * b2.t + 1e-5f * scale))
      ++any_differ;
    Ray s = r;
    s.tmax = b.t * 1.5f;
    if (intersect_any(flat, s, kInvalid) != intersect_any(bvh, s, kInvalid)) ++any_differ;
    s.tmax = b.t * 0.5f;
    if (intersect_any(flat, s, kInvalid) != intersect_any(bvh, s, kInvalid)) ++any_differ;
  }
  EXPECT_EQ(validity, 0) << what;
  EXPECT_LE(grazes, rays / 5000) << what;
  EXPECT_EQ(far, 0) << what;
  // Skipped quads: the flat list skips the whole quad a ray leaves from (its two coplanar
  // halves), the BVH only the one triangle; a ray can meet the other half only in its plane.
  EXPECT_LE(any_differ, rays / 1000) << what;
  EXPECT_GT(hits, rays / 10) << what;
}

TEST(FlatList, PairQueryEqualsTheTwoQueries) {
  // The GPU megakernel traces a shadow ray and an extension ray in one pass over the list; it
  // must give exactly what the two separate queries give (the same arithmetic), also with the
  // light skipped and with the "no ray" stand-in (tmax = 0) on either side. Its shadow rays run
  // between two points inside the scene (it skips the hull's entries, which they cannot cross):
  // here between points of the scene's triangles pulled 1% towards the centre of its box.
  for (const char* name : {"cornell_box", "cornell_spheres", "smallpt"}) {
    const Scene scene = load_scene(source_dir() + "/assets/scenes/" + name + ".json");
    const CompiledScene cs(scene, 16, 16);
    const SceneView v = flat_view(cs);
    const Aabb box = scene_bounds(cs);
    const vec3 ext = box.hi - box.lo;
    std::mt19937 rng(77);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    auto ray = [&] { return random_ray(box, rng, kInfinity); };
    const auto& tris = cs.tri_verts();
    auto inner_point = [&] {
      if (tris.empty()) return box.lo + ext * vec3(u(rng), u(rng), u(rng));
      const TriangleVerts& tv = tris[rng() % tris.size()];
      float b1 = u(rng), b2 = u(rng);
      if (b1 + b2 > 1.0f) {
        b1 = 1.0f - b1;
        b2 = 1.0f - b2;
      }
      const vec3 p = (1.0f - b1 - b2) * tv.v0 + b1 * tv.v1 + b2 * tv.v2;
      const vec3 c = 0.5f * (box.lo + box.hi);
      return c + 0.99f * (p - c);
    };
    auto segment = [&] {
      Ray r;
      r.o = inner_point();
      const vec3 to = inner_point() - r.o;
      r.tmax = glm::length(to);
      r.d = r.tmax > 0.0f ? to / r.tmax : vec3(0.0f, 0.0f, 1.0f);
      r.pad = 0.0f;
      return r;
    };
    Ray none;
    none.o = vec3(0.0f);
    none.d = vec3(0.0f, 0.0f, 1.0f);
    none.tmax = 0.0f;
    none.pad = 0.0f;
    int mismatches = 0, blocked_count = 0;
    const uint32_t light = cs.lights().empty() ? kInvalid : cs.lights()[0].prim;
    for (int i = 0; i < 5000; ++i) {
      const Ray e = (i % 7 == 6) ? none : ray();
      const Ray sh = (i % 5 == 4) ? none : segment();
      const uint32_t skip = (i % 3 == 0) ? light : kInvalid;
      bool blocked;
      const Hit h = flat_closest_and_any<kAllFeatures>(v, e, kInvalid, sh, skip, kInvalid, blocked);
      const Hit h1 = intersect_closest(v, e);
      const bool b1 = intersect_any(v, sh, skip);
      blocked_count += blocked;
      if (h.prim != h1.prim || h.t != h1.t || h.u != h1.u || h.v != h1.v || blocked != b1) {
        if (mismatches++ < 5)
          ADD_FAILURE() << name << ": ray pair " << i << " pair " << h.prim << " " << h.t << " "
                        << blocked << " vs " << h1.prim << " " << h1.t << " " << b1;
      }
      if (e.tmax == 0.0f) EXPECT_FALSE(h.valid());
      if (sh.tmax == 0.0f) EXPECT_FALSE(blocked);
    }
    EXPECT_EQ(mismatches, 0) << name;
    EXPECT_GT(blocked_count, 100) << name;
  }
}

TEST(FlatList, MultiRayQueryEqualsTheSingleQueries) {
  // The wavefront's intersect kernel traces two (or four) queued rays per lane in one pass over
  // the list: each must get exactly the hit of its own query (the same arithmetic and order),
  // with a skipped triangle (random walks), and with the "no ray" stand-in (tmax = 0) of a lane
  // whose second slot lies past the queue's end.
  for (const char* name : {"cornell_box", "cornell_closed", "cornell_spheres", "smallpt"}) {
    const Scene scene = load_scene(source_dir() + "/assets/scenes/" + name + ".json");
    const CompiledScene cs(scene, 16, 16);
    const SceneView v = flat_view(cs);
    const Aabb box = scene_bounds(cs);
    std::mt19937 rng(31);
    auto ray = [&](int i) { return random_ray(box, rng, (i % 9 == 8) ? 0.0f : kInfinity); };
    const uint32_t tri_count = uint32_t(cs.tri_verts().size());
    int mismatches = 0, hits = 0;
    auto check = [&](const Ray* rays, const uint32_t* skip, const Hit* multi, int k, int i) {
      const Hit one = intersect_closest(v, rays[k], skip[k]);
      hits += one.valid();
      if (one.prim != multi[k].prim || one.t != multi[k].t || one.u != multi[k].u ||
          one.v != multi[k].v) {
        if (mismatches++ < 5)
          ADD_FAILURE() << name << ": rays " << i << " lane ray " << k << ": " << multi[k].prim
                        << " " << multi[k].t << " vs " << one.prim << " " << one.t;
      }
      if (rays[k].tmax == 0.0f) EXPECT_FALSE(multi[k].valid());
    };
    for (int i = 0; i < 3000; ++i) {
      Ray rays[4];
      uint32_t skip[4];
      for (int k = 0; k < 4; ++k) {
        rays[k] = ray(i + k);
        skip[k] = (tri_count && (i + k) % 4 == 1) ? uint32_t(rng() % tri_count) : kInvalid;
      }
      Hit two[2], four[4], plain[4];
      flat_closest_multi<kAllFeatures, 2>(v, rays, skip, two);
      flat_closest_multi<kAllFeatures, 4>(v, rays, skip, four);
      for (int k = 0; k < 2; ++k) check(rays, skip, two, k, i);
      for (int k = 0; k < 4; ++k) check(rays, skip, four, k, i);
      // Without random walks no ray skips a triangle, and the loop makes no skip test.
      const uint32_t none[4] = {kInvalid, kInvalid, kInvalid, kInvalid};
      flat_closest_multi<kAllFeatures & ~kFeatureSubsurface, 4>(v, rays, none, plain);
      for (int k = 0; k < 4; ++k) check(rays, none, plain, k, i);
    }
    EXPECT_EQ(mismatches, 0) << name;
    EXPECT_GT(hits, 3000) << name;
  }
}

TEST(FlatList, HullEntriesNeverBlockLightSamples) {
  // The walls, floor and ceiling of the boxes have the whole scene on one side: the megakernel's
  // shadow rays skip them. Next-event rays built as the integrator builds them (spawn_ray_to,
  // from a point of any surface to a point of the light) must then see what the BVH's exact
  // any-hit query sees, to the rounding of the two tests (rays grazing an edge).
  struct Case {
    const char* name;
    uint32_t hull;
  };
  // The hull: five walls (six when closed). The blocks' bottoms lie on the floor too, but they
  // are faces of solid boxes (tested by the solids' slab tests, which every query makes).
  for (const Case& c : {Case{"cornell_box", 5}, Case{"cornell_closed", 6},
                        Case{"cornell_spheres", 5}}) {
    const Scene scene = load_scene(source_dir() + "/assets/scenes/" + c.name + ".json");
    const CompiledScene cs(scene, 16, 16);
    const FlatList& fl = cs.flat_list();
    ASSERT_TRUE(fl.enabled) << c.name;
    EXPECT_EQ(fl.quad_count - fl.quad_blockers, c.hull) << c.name;
    EXPECT_EQ(fl.triangle_blockers_end, fl.prims.size()) << c.name << ": no lone triangles";
    EXPECT_NE(describe_flat_list(fl, 0).find(std::to_string(c.hull) + " on the hull"),
              std::string::npos);
    const SceneView flat = flat_view(cs), bvh = bvh_view(cs);
    ASSERT_FALSE(cs.lights().empty());
    const uint32_t light = cs.lights()[0].prim;
    const auto& tris = cs.tri_verts();
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    auto point_on = [&](uint32_t t, vec3& n) {
      const TriangleVerts& tv = tris[t];
      float b1 = u(rng), b2 = u(rng);
      if (b1 + b2 > 1.0f) {
        b1 = 1.0f - b1;
        b2 = 1.0f - b2;
      }
      n = glm::normalize(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
      return (1.0f - b1 - b2) * tv.v0 + b1 * tv.v1 + b2 * tv.v2;
    };
    Ray none;
    none.o = vec3(0.0f);
    none.d = vec3(0.0f, 0.0f, 1.0f);
    none.tmax = 0.0f;
    none.pad = 0.0f;
    const int rays = 50000;
    int differ = 0, blocked_count = 0;
    for (int i = 0; i < rays; ++i) {
      const uint32_t from = uint32_t(rng() % tris.size());
      // (A light's own triangles see it edge-on: the integrator samples no light from them.)
      if (std::any_of(cs.lights().begin(), cs.lights().end(),
                      [&](const auto& l) { return l.prim == from; }))
        continue;
      vec3 np, nq;
      const vec3 p = point_on(from, np), q = point_on(light, nq);
      if (glm::dot(np, q - p) < 0.0f) np = -np;
      const Ray sh = spawn_ray_to(p, np, q, nq);
      bool blocked;
      flat_closest_and_any<kAllFeatures>(flat, none, kInvalid, sh, light, kInvalid, blocked);
      const bool exact = intersect_any(bvh, sh, light);
      // The wavefront's shadow stage asks the same of the list alone.
      EXPECT_EQ(shadow_blocked(flat, sh, light), blocked) << c.name << " ray " << i;
      blocked_count += exact;
      differ += blocked != exact;
    }
    EXPECT_LE(differ, rays / 5000) << c.name;
    EXPECT_GT(blocked_count, rays / 50) << c.name;
  }
}

TEST(FlatList, CornellBoxIsEighteenQuads) {
  const Scene s = load_scene(source_dir() + "/assets/scenes/cornell_box.json");
  const CompiledScene cs(s, 16, 16);
  const FlatList& fl = cs.flat_list();
  ASSERT_TRUE(fl.enabled);
  // Five walls, the light and two boxes of six faces: 36 triangles, all paired.
  EXPECT_EQ(cs.tri_verts().size(), 36u);
  EXPECT_EQ(fl.quad_count, 18u);
  EXPECT_EQ(fl.prims.size(), 18u);
  EXPECT_EQ(fl.degenerate, 0u);
  for (uint32_t t = 0; t < 36; ++t) {
    const uint32_t e = fl.tri_to_flat[t];
    ASSERT_LT(e, 18u);
    EXPECT_TRUE(fl.info[e].tri0 == t || fl.info[e].tri1 == t) << t;
  }
  EXPECT_EQ(cs.view().use_flat, 0u) << "the CPU keeps its BVH unless told";
}

TEST(FlatList, AgreesWithTheBvh) {
  for (const char* name : {"cornell_box", "cornell_closed", "cornell_spheres", "smallpt"}) {
    const Scene s = load_scene(source_dir() + "/assets/scenes/" + name + ".json");
    const CompiledScene cs(s, 16, 16);
    check_agreement(cs, 20000, name);
  }
  // Lone triangles (no pairs) and quads of every orientation and winding.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f), small(-1.5f, 1.5f);
  Scene soup;
  soup.materials.push_back({"m", diffuse(vec3(0.5f))});
  for (int i = 0; i < 20; ++i) {
    const vec3 c(u(rng), u(rng), u(rng));
    add_triangle(soup.mesh, c + vec3(small(rng), small(rng), small(rng)),
                 c + vec3(small(rng), small(rng), small(rng)),
                 c + vec3(small(rng), small(rng), small(rng)), 0);
  }
  for (int i = 0; i < 12; ++i) {
    const vec3 c(u(rng), u(rng), u(rng));
    const vec3 e1(small(rng), small(rng), small(rng)), e2(small(rng), small(rng), small(rng));
    if (i % 2) add_quad(soup.mesh, c, e1, e2, 0);
    else add_quad(soup.mesh, c, e2, e1, 0);
  }
  const CompiledScene cs(soup, 16, 16);
  EXPECT_EQ(cs.flat_list().quad_count, 12u);
  EXPECT_EQ(cs.flat_list().prims.size(), 32u);
  check_agreement(cs, 20000, "triangles and quads");
}

// The quads that cover a face of the scene's box exactly (the walls, floor and ceiling) are
// found by one slab test instead of being tested one by one; an open face (the Cornell box's
// front) has none, and a face covered by two quads is left to the loop.
vec3 face_normal_of(const CompiledScene& cs, uint32_t entry) {
  const TriangleVerts& tv = cs.tri_verts()[cs.flat_list().info[entry].tri0];
  return glm::normalize(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
}

TEST(FlatList, BoxFacesAreFoundByTheSlabTest) {
  struct Case {
    const char* name;
    uint32_t faces;
    uint32_t open_face;  // 2 * axis + side, or 6 for none
  };
  for (const Case& c : {Case{"cornell_box", 5, 4}, Case{"cornell_closed", 6, 6},
                        Case{"cornell_spheres", 5, 4}, Case{"smallpt", 0, 6}}) {
    const Scene s = load_scene(source_dir() + "/assets/scenes/" + c.name + ".json");
    const CompiledScene cs(s, 16, 16);
    const FlatList& fl = cs.flat_list();
    ASSERT_TRUE(fl.enabled) << c.name;
    EXPECT_EQ(fl.box_faces, c.faces) << c.name;
    EXPECT_EQ(cs.view().flat_box_faces, c.faces) << c.name;
    if (c.faces == 0) continue;
    EXPECT_NE(describe_flat_list(fl, 0).find(std::to_string(c.faces) + " of them box faces"),
              std::string::npos);
    const Aabb box = scene_bounds(cs);
    for (uint32_t f = 0; f < 6; ++f) {
      const uint32_t e = fl.box_entry[f];
      if (f == c.open_face) {
        EXPECT_EQ(e, kInvalid) << c.name << " face " << f;
        continue;
      }
      // The face's entry is one of the last box_faces quads and lies in the face's plane.
      ASSERT_NE(e, kInvalid) << c.name << " face " << f;
      EXPECT_GE(e, fl.quad_count - fl.box_faces) << c.name;
      EXPECT_LT(e, fl.quad_count) << c.name;
      const int a = int(f / 2);
      const TriangleVerts& tv = cs.tri_verts()[fl.info[e].tri0];
      const float plane = f % 2 ? box.hi[a] : box.lo[a];
      EXPECT_EQ(tv.v0[a], plane) << c.name << " face " << f;
      EXPECT_NEAR(std::fabs(face_normal_of(cs, e)[a]), 1.0f, 1e-6f) << c.name;
    }
  }
  // A room whose back wall is two quads and whose floor is one: the floor is a box face, the
  // wall is not (each half is tested in the loop), and queries still agree with the BVH.
  Scene room;
  room.materials.push_back({"m", diffuse(vec3(0.5f))});
  add_quad(room.mesh, vec3(0, 0, 0), vec3(0, 0, 2), vec3(2, 0, 0), 0);        // floor y = 0
  add_quad(room.mesh, vec3(0, 0, 2), vec3(0, 2, 0), vec3(1, 0, 0), 0);        // back wall, left
  add_quad(room.mesh, vec3(1, 0, 2), vec3(0, 2, 0), vec3(1, 0, 0), 0);        // and right half
  add_quad(room.mesh, vec3(0.5f, 0, 0.5f), vec3(0, 1, 0), vec3(1, 0, 0), 0);  // a panel inside
  const CompiledScene cr(room, 16, 16);
  EXPECT_EQ(cr.flat_list().box_faces, 1u);
  EXPECT_NE(cr.flat_list().box_entry[2], kInvalid) << "the floor (low y face)";
  EXPECT_EQ(cr.flat_list().box_entry[5], kInvalid) << "the back wall is two quads";
  check_agreement(cr, 20000, "room with a split wall");
}

// Six quads that close a parallelepiped (a box object, rotated or sheared) are found as one
// solid box: its faces come first among the entries, six per solid, and its map takes each
// face's corners to that face of the centred unit cube; queries test it with one slab test and
// still find what the BVH finds, also from inside a box. An open box (five faces) and a box with
// a face split in two stay quads.
TEST(FlatList, SolidBoxesAreFoundBySlabTests) {
  auto local = [](const FlatPrim& m, vec3 p) {
    return vec3(flat_affine(m.row_u, p), flat_affine(m.row_v, p), flat_affine(m.row_w, p));
  };
  auto check_faces = [&](const CompiledScene& cs, const std::string& what) {
    const FlatList& fl = cs.flat_list();
    for (uint32_t g = 0; g < fl.solids.size(); ++g)
      for (uint32_t f = 0; f < 6; ++f) {
        const uint32_t e = 6 * g + f;
        ASSERT_LT(e, fl.quad_count) << what;
        for (uint32_t tri : {fl.info[e].tri0, fl.info[e].tri1}) {
          ASSERT_NE(tri, kInvalid) << what;
          const TriangleVerts& tv = cs.tri_verts()[tri];
          for (vec3 p : {tv.v0, tv.v1, tv.v2}) {
            const vec3 l = local(fl.solids[g], p);
            const int a = int(f / 2);
            EXPECT_NEAR(l[a], f % 2 ? 0.5f : -0.5f, 1e-4f) << what << " solid " << g << " face " << f;
            for (int b = 0; b < 3; ++b) EXPECT_LE(std::fabs(l[b]), 0.5f + 1e-4f) << what;
          }
        }
      }
    EXPECT_EQ(cs.view().flat_solid_count, fl.solids.size()) << what;
  };
  {
    const Scene s = load_scene(source_dir() + "/assets/scenes/cornell_box.json");
    const CompiledScene cs(s, 16, 16);
    ASSERT_EQ(cs.flat_list().solids.size(), 2u) << "the two blocks";
    check_faces(cs, "cornell_box");
    EXPECT_NE(describe_flat_list(cs.flat_list(), 0).find("12 the faces of 2 solid boxes"),
              std::string::npos)
        << describe_flat_list(cs.flat_list(), 0);
    // The blocks' twelve faces are blockers (shadow rays test them).
    EXPECT_GE(cs.flat_list().quad_blockers, 12u);
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Scene scene;
  scene.materials.push_back({"m", diffuse(vec3(0.5f))});
  // A parallelepiped at c with edges e1, e2, e3 (random, sheared): faces as quads, skipping
  // face `skip` (6: none), the face 5 split in two when `split`.
  auto add_solid = [&](vec3 c, int skip, bool split) {
    const vec3 e1(1.5f + 0.3f * u(rng), 0.4f * u(rng), 0.4f * u(rng));
    const vec3 e2(0.4f * u(rng), 1.2f + 0.3f * u(rng), 0.4f * u(rng));
    const vec3 e3(0.4f * u(rng), 0.4f * u(rng), 1.0f + 0.3f * u(rng));
    const vec3 p = c - 0.5f * (e1 + e2 + e3);
    const vec3 corner[6] = {p, p + e1, p, p + e2, p, p + e3};
    const vec3 ea[6] = {e2, e2, e1, e1, e1, e1}, eb[6] = {e3, e3, e3, e3, e2, e2};
    for (int f = 0; f < 6; ++f) {
      if (f == skip) continue;
      if (f == 5 && split) {
        add_quad(scene.mesh, corner[f], 0.5f * ea[f], eb[f], 0);
        add_quad(scene.mesh, corner[f] + 0.5f * ea[f], 0.5f * ea[f], eb[f], 0);
      } else {
        add_quad(scene.mesh, corner[f], ea[f], eb[f], 0);
      }
    }
  };
  add_solid(vec3(-4, 0, 0), 6, false);
  add_solid(vec3(0, 0, 0), 6, false);
  add_solid(vec3(4, 0.5f, 0.3f), 6, false);
  add_solid(vec3(0, 4, 0), 2, false);   // open: no floor
  add_solid(vec3(0, -4, 0), 6, true);   // a face in two halves
  // A room around them, so that the boxes' faces are blockers, not on the scene's hull (a box
  // alone is the scene's box: its faces are then box faces).
  add_box(scene.mesh, vec3(-8.0f), vec3(8.0f), 0);
  const CompiledScene cs(scene, 16, 16);
  ASSERT_TRUE(cs.flat_list().enabled);
  EXPECT_EQ(cs.flat_list().solids.size(), 3u) << describe_flat_list(cs.flat_list(), 0);
  EXPECT_EQ(cs.flat_list().quad_count, 36u);
  EXPECT_EQ(cs.flat_list().box_faces, 6u);
  check_faces(cs, "sheared boxes");
  check_agreement(cs, 40000, "sheared boxes");
  // Rays from inside each solid meet one of its faces, the one the BVH finds.
  const SceneView flat = flat_view(cs), bvh = bvh_view(cs);
  int wrong = 0;
  for (uint32_t g = 0; g < 3; ++g) {
    for (int i = 0; i < 2000; ++i) {
      // A point inside: between the centroids of triangles on two opposite faces.
      const TriangleVerts& f0 = cs.tri_verts()[cs.flat_list().info[6 * g + 4].tri0];
      Ray r;
      r.o = (f0.v0 + f0.v1 + f0.v2) / 3.0f;
      const TriangleVerts& f1 = cs.tri_verts()[cs.flat_list().info[6 * g + 5].tri0];
      r.o += (0.2f + 0.6f * 0.5f * (u(rng) + 1.0f)) * ((f1.v0 + f1.v1 + f1.v2) / 3.0f - r.o);
      r.d = glm::normalize(vec3(u(rng), u(rng), u(rng)) + vec3(1e-3f));
      r.tmax = kInfinity;
      r.pad = 0.0f;
      const Hit a = intersect_closest(flat, r), b = intersect_closest(bvh, r);
      if (!a.valid() || !b.valid() || a.prim / 12 != b.prim / 12 ||
          std::fabs(a.t - b.t) > 1e-4f * b.t + 1e-5f) {
        if (wrong++ < 5)
          ADD_FAILURE() << "solid " << g << " ray " << i << " flat prim " << a.prim << " t "
                        << a.t << " vs bvh prim " << b.prim << " t " << b.t;
      }
      // The ray leaving through the face it hit, skipping it: nothing more of this solid.
      if (a.valid()) {
        Ray out = r;
        out.o = r.o + a.t * r.d;
        const Hit c = intersect_closest(flat, out, a.prim);
        if (c.valid() && c.prim / 12 == a.prim / 12 && c.t < 1e-3f) ++wrong;
      }
    }
  }
  EXPECT_EQ(wrong, 0);
}

TEST(FlatList, ClosedBoxDoesNotLeak) {
  // Rays from inside the closed box aimed at the points where faces meet (edges and corners of
  // the walls and of the blocks) must all hit something: the edge tolerance closes the seams.
  const Scene s = load_scene(source_dir() + "/assets/scenes/cornell_closed.json");
  const CompiledScene cs(s, 16, 16);
  ASSERT_TRUE(cs.flat_list().enabled);
  const SceneView flat = flat_view(cs);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const auto& tris = cs.tri_verts();
  int misses = 0;
  const int rays = 100000;
  for (int i = 0; i < rays; ++i) {
    const TriangleVerts& tv = tris[rng() % tris.size()];
    const vec3 a = (rng() % 2) ? tv.v0 : tv.v1, b = (rng() % 2) ? tv.v2 : tv.v1;
    const vec3 target = a + u(rng) * (b - a);  // on an edge of a triangle
    Ray r;
    r.o = vec3(20.0f, 20.0f, 20.0f) + vec3(515.0f, 500.0f, 515.0f) * vec3(u(rng), u(rng), u(rng));
    const vec3 dir = target - r.o;
    if (glm::length(dir) < 1e-3f) continue;
    r.d = glm::normalize(dir);
    r.tmax = kInfinity;
    r.pad = 0.0f;
    if (!intersect_closest(flat, r).valid()) ++misses;
  }
  EXPECT_EQ(misses, 0) << "rays escaped the closed box through a seam";
}

TEST(FlatList, OnlySmallScenes) {
  auto quads = [](int n) {
    Scene s;
    s.materials.push_back({"m", diffuse(vec3(0.5f))});
    for (int i = 0; i < n; ++i)
      add_quad(s.mesh, vec3(float(i), 0, 0), vec3(0.5f, 0, 0), vec3(0, 0.5f, 0), 0);
    return s;
  };
  EXPECT_TRUE(CompiledScene(quads(int(kFlatMaxCost)), 4, 4).flat_list().enabled);
  EXPECT_FALSE(CompiledScene(quads(int(kFlatMaxCost) + 1), 4, 4).flat_list().enabled);
  // A trapezoid is two lone triangles; a degenerate triangle is counted and left out.
  Scene t;
  t.materials.push_back({"m", diffuse(vec3(0.5f))});
  t.mesh.positions = {vec3(0, 0, 0), vec3(2, 0, 0), vec3(1.5f, 1, 0), vec3(0.5f, 1, 0)};
  t.mesh.indices = {uvec3(0, 1, 2), uvec3(0, 2, 3)};
  t.mesh.materials = {0, 0};
  add_triangle(t.mesh, vec3(0, 0, 1), vec3(1, 1, 1), vec3(2, 2, 1), 0);
  const CompiledScene ct(t, 4, 4);
  ASSERT_TRUE(ct.flat_list().enabled);
  EXPECT_EQ(ct.flat_list().quad_count, 0u);
  EXPECT_EQ(ct.flat_list().prims.size(), 2u);
  EXPECT_EQ(ct.flat_list().degenerate, 1u);
  EXPECT_EQ(ct.flat_list().tri_to_flat[2], kInvalid);
  // Spheres count twice: 33 spheres are too many.
  Scene sp;
  sp.materials.push_back({"m", diffuse(vec3(0.5f))});
  for (int i = 0; i < 33; ++i) sp.spheres.push_back({vec3(float(3 * i), 0, 0), 1.0f, 0});
  EXPECT_FALSE(CompiledScene(sp, 4, 4).flat_list().enabled);
  sp.spheres.pop_back();
  EXPECT_TRUE(CompiledScene(sp, 4, 4).flat_list().enabled);
}

TEST(FlatList, RendersTheImageOfTheBvh) {
  // The CPU backend with the flat list against its BVH, same seed: the same paths, so pixels
  // agree to rounding except where a path grazes an edge; and the same mean brightness.
  const Scene s = load_scene(source_dir() + "/assets/scenes/cornell_box.json");
  RenderSettings rs = s.settings;
  rs.width = 64;
  rs.height = 64;
  const CompiledScene cs(s, rs.width, rs.height);
  const IntegratorSettings cfg = make_integrator_settings(rs);
  CpuRenderer a(2), b(2);
  a.set_scene(cs, cfg);
  b.set_scene(cs, cfg);
  a.set_flat_list(true);
  const FrameStats sa = a.render(32);
  b.render(32);
  const ImageRGB ia = a.image(), ib = b.image();
  size_t close = 0;
  double suma = 0, sumb = 0;
  for (size_t i = 0; i < ia.pixels.size(); ++i) {
    const float x = ia.pixels[i], y = ib.pixels[i];
    if (std::fabs(x - y) <= 1e-3f * std::max(1.0f, std::fabs(y))) ++close;
    suma += x;
    sumb += y;
  }
  const double frac = double(close) / double(ia.pixels.size());
  std::printf("flat list vs BVH, same seed: %.4f of values agree to 1e-3, means %.5f / %.5f\n",
              frac, suma / ia.pixels.size(), sumb / ia.pixels.size());
  EXPECT_GT(frac, 0.99);
  EXPECT_NEAR(suma / sumb, 1.0, 0.002);
  EXPECT_EQ(sa.nonfinite, 0u);
}

}  // namespace
