// The light choice of next-event estimation (render.light_sampler) and the light tree behind
// `bvh`: at random shading points the tree's probabilities sum to one over the lights and reach
// every light that can light the point; its choices follow those probabilities (chi-square); the
// probability a choice reports is the one retraced for MIS; the tree holds every light once in
// bounds and cones that hold its children's; degenerate scenes (no light, one, identical ones,
// lights only at infinity, a light of zero power); and the three samplers render the same image.
#include "scene/light_tree.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "chi_square.h"
#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace test;

constexpr uint32_t kSamplers[] = {kLightSamplerUniform, kLightSamplerPower, kLightSamplerBvh};
// Chi-square tests in this executable, for the Sidak correction.
constexpr int kChiSquareTests = 16;

struct Rng {
  std::mt19937 e;
  explicit Rng(uint32_t seed) : e(seed) {}
  float f() { return chi2::uniform_float(e); }
  float f(float lo, float hi) { return lo + (hi - lo) * f(); }
  vec3 v(float lo, float hi) { return vec3(f(lo, hi), f(lo, hi), f(lo, hi)); }
  vec3 dir() {
    for (;;) {
      const vec3 d = v(-1.0f, 1.0f);
      const float l = glm::length(d);
      if (l > 0.1f && l <= 1.0f) return d / l;
    }
  }
};

// Small triangles and spheres scattered in [-5, 5]^3, facing every way, with radiances
// log-uniform over three orders of magnitude; one light in five emits from both faces.
Scene random_lights(uint32_t seed, int triangles, int spheres) {
  Scene s;
  s.source = "<random lights>";
  Rng rng(seed);
  auto material = [&] {
    const float strength = std::pow(10.0f, rng.f(0.0f, 3.0f));
    const vec3 colour = vec3(0.2f) + 0.8f * vec3(rng.f(), rng.f(), rng.f());
    s.materials.push_back({"lamp " + std::to_string(s.materials.size()),
                           diffuse(vec3(0.0f), strength * colour, rng.f() < 0.2f)});
    return uint32_t(s.materials.size() - 1);
  };
  for (int i = 0; i < triangles; ++i) {
    const vec3 c = rng.v(-5.0f, 5.0f);
    const float size = rng.f(0.05f, 0.5f);
    add_triangle(s.mesh, c + size * rng.dir(), c + size * rng.dir(), c + size * rng.dir(),
                 material());
  }
  for (int i = 0; i < spheres; ++i)
    s.spheres.push_back({rng.v(-5.0f, 5.0f), rng.f(0.02f, 0.3f), material()});
  return s;
}

// Whether light `li` can send light to p (normal n): some of it lies on its emitting side of
// its plane, and not all of it in p's tangent plane. Margins keep rounding out of the verdict.
bool can_light(const SceneView& v, uint32_t li, vec3 p, vec3 n) {
  const Light& l = v.lights[li];
  if (light_at_infinity(l.kind)) return true;
  if (l.prim >= v.tri_count) {
    const Sphere& sph = v.spheres[l.prim - v.tri_count];
    return glm::length(p - sph.center) > sph.radius * 1.01f;
  }
  const TriangleVerts& t = v.tri_verts[l.prim];
  const vec3 ln = glm::normalize(glm::cross(t.v1 - t.v0, t.v2 - t.v0));
  const bool two_sided =
      v.materials[v.tri_shading[l.prim].material].flags & kMaterialTwoSidedEmission;
  bool front = false, off_plane = false;
  for (const vec3 q : {t.v0, t.v1, t.v2}) {
    const float d = glm::dot(ln, p - q) / glm::length(p - q);
    if (d > 1e-3f || (two_sided && d < -1e-3f)) front = true;
    if (std::abs(glm::dot(n, glm::normalize(q - p))) > 1e-3f) off_plane = true;
  }
  return front && off_plane;
}

LightContext random_context(Rng& rng, float extent) {
  return LightContext{rng.v(-extent, extent), rng.dir()};
}

// The probability that the tree's descent from ctx stops at a node none of whose children can
// light the point (then no light is chosen): the lights below it get none, and are the only ones.
double lost_mass(const SceneView& v, const LightContext& ctx) {
  if (!v.light_tree.nodes) return 0.0;  // the power sampler's choice
  const double p_tree = v.light_cdf[v.finite_light_count];
  std::function<double(uint32_t, double)> walk = [&](uint32_t k, double reach) -> double {
    const LightTreeNode& n = v.light_tree.nodes[k];
    if (n.flags & kLightNodeLeaf) return 0.0;
    const double i0 = light_node_importance(v.light_tree.nodes[k + 1], ctx.p, ctx.n);
    const double i1 = light_node_importance(v.light_tree.nodes[n.index], ctx.p, ctx.n);
    if (!(i0 + i1 > 0.0)) return reach;
    return (i0 > 0.0 ? walk(k + 1, reach * i0 / (i0 + i1)) : 0.0) +
           (i1 > 0.0 ? walk(n.index, reach * i1 / (i0 + i1)) : 0.0);
  };
  return p_tree * walk(0, 1.0);
}

// The sum of every light's probability at ctx (one, but for the bvh sampler's lost mass), and
// whether each light that can light the point has one. Returns the lost mass.
double check_pmf_sums(const SceneView& v, uint32_t sampler, const LightContext& ctx,
                      const std::string& what) {
  double sum = 0.0;
  int unreachable = 0;
  for (uint32_t li = 0; li < v.light_count; ++li) {
    const float pmf = light_choice_pmf(v, sampler, ctx, li);
    EXPECT_TRUE(pmf >= 0.0f && pmf <= 1.0f) << what << ": light " << li << " pmf " << pmf;
    sum += pmf;
    if (!(pmf > 0.0f) && v.lights[li].power > 0.0f && can_light(v, li, ctx.p, ctx.n)) ++unreachable;
  }
  const double lost = sampler == kLightSamplerBvh ? lost_mass(v, ctx) : 0.0;
  EXPECT_NEAR(sum + lost, 1.0, 2e-5) << what << " (lost " << lost << ")";
  EXPECT_EQ(unreachable, 0) << what << ": lights that can light the point but are never chosen";
  return lost;
}

const CompiledScene& many_lights() {
  static const CompiledScene* cs = [] {
    Scene s = load_scene(source_dir() + "/assets/scenes/many_lights.json");
    validate_scene(s);
    return new CompiledScene(s, 16, 16);
  }();
  return *cs;
}

TEST(LightTree, PmfSumsToOneAndReachesEveryLightThatCanContribute) {
  Scene s = random_lights(1, 300, 40);
  validate_scene(s);
  const CompiledScene cs(s, 8, 8);
  ASSERT_EQ(cs.view().light_count, 340u);
  Rng rng(2);
  double lost = 0.0;
  for (int i = 0; i < 300; ++i) {
    const LightContext ctx = random_context(rng, 6.0f);
    for (uint32_t sampler : kSamplers)
      lost += check_pmf_sums(cs.view(), sampler, ctx, "random lights, point " + std::to_string(i));
    if (HasFailure()) return;
  }
  // Lost choices are wasted samples, not bias; bounds as tight as pbrt-v4's lose few.
  EXPECT_LT(lost / 300, 0.02);
  // The many-lights hall: points inside it (several lamps face up or their wall).
  const SceneView& v = many_lights().view();
  lost = 0.0;
  for (int i = 0; i < 200; ++i) {
    LightContext ctx{vec3(rng.f(-15.9f, 15.9f), rng.f(0.05f, 3.0f), rng.f(-15.9f, 15.9f)),
                     rng.dir()};
    lost +=
        check_pmf_sums(v, kLightSamplerBvh, ctx, "many_lights.json, point " + std::to_string(i));
    if (HasFailure()) return;
  }
  // More here: a node holding a lamp facing up above the point and one facing down below it
  // has a cone of every direction, though neither lamp can light the point.
  EXPECT_LT(lost / 200, 0.08);
}

TEST(LightTree, ChoicesFollowThePmf) {
  Scene s = random_lights(3, 60, 10);
  validate_scene(s);
  const CompiledScene cs(s, 8, 8);
  const SceneView& v = cs.view();
  Rng rng(4);
  for (int i = 0; i < 4; ++i) {
    const LightContext ctx = random_context(rng, 5.0f);
    for (uint32_t sampler : kSamplers) {
      const size_t n = 200000;
      std::vector<double> observed(v.light_count, 0.0), expected(v.light_count, 0.0);
      for (uint32_t li = 0; li < v.light_count; ++li)
        expected[li] = double(n) * light_choice_pmf(v, sampler, ctx, li);
      for (size_t k = 0; k < n; ++k) {
        const LightChoice c = choose_light(v, sampler, ctx, rng.f());
        if (c.light != kInvalid) observed[c.light] += 1.0;
      }
      const chi2::Result r = chi2::chi_square_test(observed, expected, 0.01, kChiSquareTests);
      EXPECT_TRUE(r.passed) << "sampler " << sampler << ", point " << i << ": " << r.message;
    }
  }
}

TEST(LightTree, ChoiceReportsTheRetracedPmfAndAUniformRemainder) {
  Scene random = random_lights(5, 200, 20);
  validate_scene(random);
  const CompiledScene random_cs(random, 8, 8);
  for (const CompiledScene* cs : {&many_lights(), &random_cs}) {
    const SceneView& v = cs->view();
    Rng rng(6);
    int checked = 0;
    for (int i = 0; i < 20000; ++i) {
      const LightContext ctx = random_context(rng, 6.0f);
      const LightChoice c = choose_light(v, kLightSamplerBvh, ctx, rng.f());
      if (c.light == kInvalid) continue;
      ++checked;
      // The same importances in the same order: equal to the last bit.
      ASSERT_EQ(c.pmf, light_choice_pmf(v, kLightSamplerBvh, ctx, c.light)) << "choice " << i;
      ASSERT_TRUE(c.u >= 0.0f && c.u < 1.0f) << c.u;
    }
    EXPECT_GT(checked, 15000);
  }
  // The remainder of the choosing number, which becomes the first coordinate of the point on the
  // light, is uniform given the light.
  const SceneView& v = many_lights().view();
  const LightContext ctx{vec3(0.5f, 1.0f, 0.5f), vec3(0.0f, 1.0f, 0.0f)};
  Rng rng(7);
  uint32_t light = 0;  // the light chosen most often from ctx
  for (uint32_t li = 1; li < v.light_count; ++li)
    if (light_choice_pmf(v, kLightSamplerBvh, ctx, li) >
        light_choice_pmf(v, kLightSamplerBvh, ctx, light))
      light = li;
  std::vector<double> bins(32, 0.0);
  double n = 0.0;
  for (int i = 0; i < 400000; ++i) {
    const LightChoice c = choose_light(v, kLightSamplerBvh, ctx, rng.f());
    if (c.light != light) continue;
    bins[std::min(31, int(c.u * 32.0f))] += 1.0;
    n += 1.0;
  }
  ASSERT_GT(n, 2000.0);
  const chi2::Result r =
      chi2::chi_square_test(bins, std::vector<double>(32, n / 32.0), 0.01, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
}

// Every light with power in exactly one leaf, its trail leading there; boxes, cones and powers
// of each node holding its children's.
void check_structure(const LightTree& t, const std::vector<LightBounds>& bounds) {
  ASSERT_LE(t.depth, 63u);
  std::vector<int> seen(bounds.size(), 0);
  for (const LightLeafEntry& e : t.leaves) seen[e.light]++;
  for (size_t i = 0; i < bounds.size(); ++i) {
    const bool in_tree = bounds[i].power > 0.0f;
    EXPECT_EQ(seen[i], in_tree ? 1 : 0) << "light " << i;
    EXPECT_EQ(t.trails[i] != kNotInLightTree, in_tree) << "light " << i;
    if (!in_tree) continue;
    uint64_t trail = t.trails[i];
    uint32_t k = 0;
    while (!(t.nodes[k].flags & kLightNodeLeaf)) {
      k = (trail & 1u) ? t.nodes[k].index : k + 1;
      trail >>= 1;
    }
    const LightTreeNode& leaf = t.nodes[k];
    bool found = false;
    for (uint32_t j = 0; j < (leaf.flags >> kLightNodeCountShift); ++j)
      found |= t.leaves[leaf.index + j].light == i;
    EXPECT_TRUE(found) << "light " << i << "'s trail ends in a leaf without it";
  }
  for (size_t k = 0; k < t.nodes.size(); ++k) {
    const LightTreeNode& n = t.nodes[k];
    if (n.flags & kLightNodeLeaf) continue;
    const double theta_o = std::acos(std::clamp(double(n.cos_o), -1.0, 1.0));
    double power = 0.0;
    for (uint32_t c : {uint32_t(k + 1), n.index}) {
      const LightTreeNode& ch = t.nodes[c];
      power += ch.power;
      EXPECT_TRUE(glm::all(glm::lessThanEqual(n.lo, ch.lo)) &&
                  glm::all(glm::greaterThanEqual(n.hi, ch.hi)))
          << "node " << k << " child " << c;
      const double theta_c = std::acos(std::clamp(double(ch.cos_o), -1.0, 1.0));
      // The angle between the axes as 2 asin(|a - b| / 2): acos of a dot product near 1 would
      // make an angle of 4e-4 out of float rounding.
      const double between =
          2.0 * std::asin(std::min(1.0, glm::length(glm::dvec3(n.axis) - glm::dvec3(ch.axis)) / 2));
      if (n.cos_o > -1.0f)
        EXPECT_LE(between + theta_c, theta_o + 1e-5) << "node " << k << " child " << c;
      EXPECT_LE(n.cos_e, ch.cos_e);
    }
    EXPECT_NEAR(n.power, power, 1e-5 * power) << "node " << k;
  }
}

TEST(LightTree, HoldsEveryLightOnceInBoundsThatHoldTheirChildren) {
  Scene s = random_lights(8, 500, 50);
  validate_scene(s);
  const CompiledScene cs(s, 8, 8);
  std::vector<LightBounds> bounds;
  for (uint32_t i = 0; i < cs.view().light_count; ++i)
    bounds.push_back(light_bounds(cs.view(), cs.lights()[i]));
  check_structure(cs.light_tree(), bounds);
  EXPECT_GT(cs.light_tree().leaf_count, 400u);  // random triangles rarely share a leaf
  // The many-lights hall's 108 lamps, 83 quads and 25 spheres: both triangles of a quad in one
  // leaf, each lamp a leaf of its own.
  const LightTree& ml = many_lights().light_tree();
  EXPECT_EQ(ml.leaves.size(), 191u);
  EXPECT_EQ(ml.leaf_count, 108u);
}

TEST(LightTree, StaysWithinItsDepthWhereTheSplitsPeel) {
  // Lights along a line at geometrically growing distances: the splits peel off a few lights at
  // a time. A tree asked to stay shallower halves its nodes from where it must.
  std::vector<LightBounds> bounds;
  for (int i = 0; i < 120; ++i) {
    LightBounds b;
    const float x = std::pow(2.0f, float(i));
    b.box.grow(vec3(x, 0.0f, 0.0f));
    b.box.grow(vec3(x, 1.0f, 1.0f));
    b.axis = vec3(1.0f, 0.0f, 0.0f);
    b.cos_o = 1.0f;
    b.power = 1.0f;
    bounds.push_back(b);
  }
  const LightTree t = build_light_tree(bounds);
  check_structure(t, bounds);
  EXPECT_GT(t.depth, 20u);  // the peeling does happen
  const LightTree shallow = build_light_tree(bounds, 9);
  check_structure(shallow, bounds);
  EXPECT_LE(shallow.depth, 9u);
  EXPECT_THROW(build_light_tree(bounds, 6), std::invalid_argument);  // 120 lights need 7 levels
}

// A floor under square lamps (centre, radiance) facing down.
Scene lights_scene(const std::vector<std::pair<vec3, float>>& quads) {
  Scene s;
  s.source = "<lights>";
  s.materials.push_back({"floor", diffuse(vec3(0.5f))});
  add_quad(s.mesh, vec3(-5, 0, 5), vec3(10, 0, 0), vec3(0, 0, -10), 0);
  for (const auto& [c, strength] : quads) {
    s.materials.push_back({"lamp", diffuse(vec3(0.0f), vec3(strength))});
    add_quad(s.mesh, c - vec3(0.2f, 0.0f, 0.2f), vec3(0.4f, 0, 0), vec3(0, 0, 0.4f),
             uint32_t(s.materials.size() - 1));  // facing down
  }
  return s;
}

TEST(LightTree, DegenerateScenes) {
  Rng rng(9);
  auto points = [&](const SceneView& v, const std::string& what) {
    for (int i = 0; i < 50; ++i) {
      LightContext ctx{vec3(rng.f(-4, 4), rng.f(0.1f, 2.5f), rng.f(-4, 4)), rng.dir()};
      for (uint32_t sampler : kSamplers) check_pmf_sums(v, sampler, ctx, what);
    }
  };
  {  // no light: no choice, and a black image
    Scene s = lights_scene({});
    validate_scene(s);
    const CompiledScene cs(s, 8, 8);
    EXPECT_EQ(cs.view().light_count, 0u);
    EXPECT_EQ(cs.view().light_tree.nodes, nullptr);
    for (uint32_t sampler : kSamplers) {
      const LightChoice c =
          choose_light(cs.view(), sampler, LightContext{vec3(0.0f), vec3(0, 1, 0)}, 0.5f);
      EXPECT_EQ(c.light, kInvalid);
      EXPECT_EQ(c.pmf, 0.0f);
    }
  }
  {  // one light (a quad: two triangles in one leaf at the root)
    Scene s = lights_scene({{vec3(0, 3, 0), 5.0f}});
    validate_scene(s);
    const CompiledScene cs(s, 8, 8);
    EXPECT_EQ(cs.light_tree().nodes.size(), 1u);
    EXPECT_EQ(cs.view().light_tree.nodes, nullptr);  // a single leaf: bvh chooses as power does
    points(cs.view(), "one quad");
    const LightChoice c =
        choose_light(cs.view(), kLightSamplerBvh, LightContext{vec3(0, 1, 0), vec3(0, 1, 0)}, 0.3f);
    EXPECT_FLOAT_EQ(c.pmf, 0.5f);  // two triangles of equal power
  }
  {  // twenty identical lamps in one place: every choice alike
    Scene s = lights_scene(std::vector<std::pair<vec3, float>>(20, {vec3(0, 3, 0), 5.0f}));
    validate_scene(s);
    const CompiledScene cs(s, 8, 8);
    points(cs.view(), "identical lamps");
    const LightContext ctx{vec3(1, 1, 1), vec3(0, 1, 0)};
    for (uint32_t li = 0; li < cs.view().light_count; ++li)
      EXPECT_NEAR(light_choice_pmf(cs.view(), kLightSamplerBvh, ctx, li), 1.0f / 40.0f, 1e-6f);
  }
  {  // lights only at infinity: the tree is empty, and bvh chooses as power does
    Scene s = lights_scene({});
    s.environment.color = vec3(0.3f, 0.4f, 0.5f);
    DistantLightDesc sun;
    sun.direction = vec3(0.3f, 1.0f, 0.2f);
    sun.irradiance = vec3(2.0f);
    s.distant_lights.push_back(sun);
    validate_scene(s);
    const CompiledScene cs(s, 8, 8);
    ASSERT_EQ(cs.view().light_count, 2u);
    EXPECT_EQ(cs.view().finite_light_count, 0u);
    EXPECT_EQ(cs.view().light_tree.nodes, nullptr);
    points(cs.view(), "lights at infinity");
    for (uint32_t li = 0; li < 2; ++li)
      EXPECT_EQ(light_choice_pmf(cs.view(), kLightSamplerBvh, LightContext{}, li),
                light_select_pdf(cs.view(), li));
  }
  {  // a light whose power is zero (an emission below the smallest float once times its area)
    Scene s =
        lights_scene({{vec3(-2, 3, 0), 5.0f}, {vec3(2, 3, 0), 1e-45f}, {vec3(0, 3, 2), 1.0f}});
    validate_scene(s);
    const CompiledScene cs(s, 8, 8);
    const SceneView& v = cs.view();
    ASSERT_EQ(v.light_count, 6u);
    uint32_t zero = 0;
    for (uint32_t li = 0; li < 6; ++li)
      if (!(v.lights[li].power > 0.0f)) {
        ++zero;
        EXPECT_EQ(cs.light_tree().trails[li], kNotInLightTree);
        EXPECT_EQ(
            light_choice_pmf(v, kLightSamplerBvh, LightContext{vec3(0, 1, 0), vec3(0, 1, 0)}, li),
            0.0f);
      }
    EXPECT_EQ(zero, 2u);
    points(v, "a light of zero power");
  }
}

TEST(LightTree, NormalCodeKeepsTheNormalWithinFourDegrees) {
  Rng rng(10);
  float worst = 0.0f;
  for (int i = 0; i < 100000; ++i) {
    const vec3 n = i < 6 ? vec3(0.0f) : rng.dir();
    vec3 m = n;
    if (i < 6) m[i % 3] = i < 3 ? 1.0f : -1.0f;  // the axes
    const uint32_t code = pack_light_normal(m);
    ASSERT_LT(code, 1u << kLightNormalBits);
    const vec3 back = unpack_light_normal(code);
    ASSERT_NEAR(glm::length(back), 1.0f, 1e-5f);
    worst = std::max(worst, std::acos(std::clamp(glm::dot(back, m), -1.0f, 1.0f)));
  }
  EXPECT_LT(glm::degrees(worst), 4.0f);
}

TEST(LightTree, NextEventEstimationAndMisSeeTheSameContext) {
  // A reflected BSDF ray leaves from the point next-event estimation chose its light from, and
  // the path keeps the normal's code: the pmf retraced at the emitter it hits is the one NEE used.
  Rng rng(11);
  for (int i = 0; i < 10000; ++i) {
    const vec3 p = rng.v(-100.0f, 100.0f), ng = rng.dir();
    const bool front = rng.f() < 0.5f;
    const vec3 ng_viewer = front ? ng : -ng;
    vec3 d = rng.dir();
    if (glm::dot(d, ng_viewer) <= 0.0f) d = -d;
    const uint32_t code = pack_light_normal(ng_viewer);
    const LightContext nee = vertex_light_context(p, ng_viewer, code);
    const Ray r = spawn_ray(p, ng, d);
    const LightContext mis{r.o, unpack_light_normal(code)};
    ASSERT_EQ(nee.p, mis.p) << i;
    ASSERT_EQ(nee.n, mis.n) << i;
  }
}

// A floor, a wall and lamps of unequal power (two face away, one is a two-sided sheet, one a
// sphere) under a dim sky and a sun: every sampler converges to the same image.
Scene sampler_scene() {
  Scene s = lights_scene({{vec3(-2, 2, -1), 8.0f},
                          {vec3(1.5f, 2.5f, 1), 0.3f},
                          {vec3(0, 1.5f, 2), 2.0f},
                          {vec3(2, 2, -2), 0.05f}});
  s.materials.push_back({"wall", diffuse(vec3(0.6f, 0.5f, 0.4f))});
  add_quad(s.mesh, vec3(-5, 0, -3), vec3(0, 4, 0), vec3(10, 0, 0),
           uint32_t(s.materials.size() - 1));
  s.materials.push_back({"away", diffuse(vec3(0.0f), vec3(3.0f, 2.0f, 1.0f))});
  add_quad(s.mesh, vec3(-1, 1.2f, -2), vec3(0, 0, 0.5f), vec3(0.5f, 0, 0),
           uint32_t(s.materials.size() - 1));  // faces up, away from the floor
  s.materials.push_back({"sheet", diffuse(vec3(0.0f), vec3(0.5f, 1.0f, 2.0f), true)});
  add_quad(s.mesh, vec3(3, 0.2f, 0), vec3(0, 1, 0), vec3(0, 0, 1),
           uint32_t(s.materials.size() - 1));
  s.materials.push_back({"bulb", diffuse(vec3(0.0f), vec3(20.0f, 15.0f, 8.0f))});
  s.spheres.push_back({vec3(-1.5f, 0.6f, 1.5f), 0.1f, uint32_t(s.materials.size() - 1)});
  s.environment.color = vec3(0.02f, 0.03f, 0.05f);
  DistantLightDesc sun;
  sun.direction = vec3(-0.4f, 1.0f, 0.5f);
  sun.irradiance = vec3(0.4f);
  sun.angular_diameter_deg = 3.0f;
  s.distant_lights.push_back(sun);
  // A point and a spot light: in the tree beside the emitters, before the lights at infinity.
  PointLightDesc lamp;
  lamp.name = "lamp";
  lamp.position = vec3(1.0f, 1.5f, 1.0f);
  lamp.intensity = vec3(2.0f, 1.8f, 1.5f);
  s.point_lights.push_back(lamp);
  PointLightDesc spot;
  spot.name = "spot";
  spot.spot = true;
  spot.position = vec3(-2.0f, 3.0f, 0.0f);
  spot.direction = vec3(0.3f, -1.0f, 0.0f);
  spot.intensity = vec3(5.0f, 4.0f, 3.0f);
  spot.cone_angle_deg = 25.0f;
  spot.cone_delta_angle_deg = 5.0f;
  s.point_lights.push_back(spot);
  s.camera.position = vec3(0.0f, 3.5f, 6.0f);
  s.camera.look_at = vec3(0.0f, 0.5f, 0.0f);
  s.camera.vfov_deg = 60.0f;
  return s;
}

TEST(LightTree, SamplersRenderTheSameImage) {
  Scene s = sampler_scene();
  validate_scene(s);
  RenderSettings rs;
  rs.width = 32;
  rs.height = 24;
  rs.max_depth = 4;
  rs.sampler = kSamplerRandom;  // independent samples for the z-tests
  rs.light_sampler = kLightSamplerPower;
  const PixelStats power = render_pixel_stats(s, rs, 512);
  rs.light_sampler = kLightSamplerBvh;
  const PixelStats bvh = render_pixel_stats(s, rs, 512, 1u << 20);
  rs.light_sampler = kLightSamplerUniform;
  const PixelStats uniform = render_pixel_stats(s, rs, 512, 1u << 21);
  EXPECT_EQ(power.nonfinite + bvh.nonfinite + uniform.nonfinite, 0u);
  expect_same_means(bvh, power, "bvh vs power");
  expect_same_means(uniform, power, "uniform vs power");
}

}  // namespace
