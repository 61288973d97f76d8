// Manifold next-event estimation's solver (Hanika, Droske, Fascione 2015, "Manifold Next Event
// Estimation"; the half-vector constraints of Zeltner, Georgiev, Jakob 2020, "Specular Manifold
// Sampling"): the path from a receiver point x to a light point y through a chain of up to
// kManifoldMaxChain smooth specular vertices (a mirror's reflection or a smooth dielectric's
// refraction), found by Newton's method on the specular surfaces, and the generalized geometry
// term that turns the light sample's area density into a density of directions at x.
//
// Used by path.h's MneeSolver and mnee_resolve (render.mnee:
// the CPU and the wavefront's mnee stage). The surfaces are a plane (a flat face of a box or
// mesh) and a sphere (SpecularSurface), and for the one-refraction chain a triangle with
// interpolated vertex normals (SmoothSurface: a water surface), whose vertex moves in the
// triangle's plane; the solver puts each step back on the mesh by a ray (Hanika et al.'s
// re-projection), so the walk crosses from triangle to triangle. Through one sphere the chains are found exactly instead (sphere_refraction_chains,
// sphere_reflection_chain, at the end): Newton from one seed finds one chain of several, or none
// near the sphere's rim, and what it misses stays BSDF sampling's noise.
//
// The constraint at vertex i with neighbours a (towards x) and b (towards y): with wi and wo the
// unit directions to them and eta_i, eta_o the indices of refraction on their sides (1 and 1 for
// a mirror), the tangential part of eta_i wi + eta_o wo is zero: the law of reflection, or
// Snell's law (eta_i sin = eta_o sin, on opposite sides). Newton moves each vertex in its tangent
// plane by the solve of J d = -C (J analytic: 2k x 2k, k <= 2) and puts it back on
// its surface (the plane itself, or the sphere along its radius), halving a step that does not
// lower |C|.
#pragma once

#include "core/math.h"

namespace tracer {

constexpr uint32_t kManifoldMaxChain = 2;
constexpr uint32_t kManifoldIterations = 12;
// Tries of a Newton step, each half the last, before the walk gives up. Chains that need a
// step shortened more than twice were never accepted on the lamp and the balls: 4 tries give
// the same images as 8 (2 change the balls'), and a failing walk, which a GPU warp waits for,
// stops sooner.
constexpr uint32_t kManifoldHalvings = 4;
// |C| (a sum of unit vectors' tangential parts) that ends the iteration, and the most a solution
// may keep when float's rounding stops the iteration before it.
constexpr float kManifoldTolerance = 1e-6f;
constexpr float kManifoldAccept = 2e-5f;

struct SpecularSurface {
  enum Kind : uint8_t { kPlane, kSphere };
  Kind kind = kPlane;
  vec3 a = vec3(0.0f);  // plane: a point on it; sphere: its centre
  vec3 n = vec3(0.0f, 0.0f, 1.0f);  // plane: its unit normal (the outside)
  float radius = 0.0f;  // sphere
  float eta = 0.0f;     // index of refraction inside (outside: 1); 0: a mirror
  static constexpr bool kMovesInTangent = true;
  // The outward unit normal at p (on the surface).
  TRACER_HD vec3 normal(vec3 p) const { return kind == kPlane ? n : (p - a) / radius; }
  // The normal of the plane a vertex moves in (manifold_moved): the tangent plane.
  TRACER_HD vec3 move_normal(vec3 p) const { return normal(p); }
  // p moved back onto the surface: the plane's nearest point, or along the sphere's radius.
  TRACER_HD vec3 project(vec3 p) const {
    if (kind == kPlane) return p - glm::dot(p - a, n) * n;
    const vec3 d = p - a;
    const float l = glm::length(d);
    return l > 0.0f ? a + d * (radius / l) : a + vec3(0.0f, 0.0f, radius);
  }
  // The constraint frame's turn with the normal (manifold_jacobian): -(h.n) t_r.dn for a move
  // along the move frame's axis c; on a sphere of radius r dn = dp / r, on a plane none.
  TRACER_HD void turn(vec3, float hn, const Frame&, const Frame&, float out[2][2]) const {
    const float t = kind == kSphere ? hn / radius : 0.0f;
    out[0][0] = out[1][1] = t;
    out[0][1] = out[1][0] = 0.0f;
  }
};

// A triangle whose shading normal is interpolated from its vertices' (a water surface of a mesh
// with normals), as make_surface_hit does: N = n0 + b1 dn1 + b2 dn2 at barycentrics
// b1 = (p - a).d1, b2 = (p - a).d2 (d1, d2: the dual basis of the edges), normalised and turned
// to n's side (n: the unit geometric normal, the outside; a: the first vertex). Its vertex moves
// in the triangle's plane; beyond its edges the interpolation goes on linearly, and the solver
// puts each step back on the mesh by a ray (path.h, the one-refraction chain). Kept apart from
// SpecularSurface so that the two-vertex chains keep their size in the GPU's registers.
struct SmoothSurface {
  vec3 a = vec3(0.0f), n = vec3(0.0f, 0.0f, 1.0f);
  float eta = 0.0f;
  static constexpr bool kMovesInTangent = false;
  vec3 n0 = vec3(0.0f, 0.0f, 1.0f), dn1 = vec3(0.0f), dn2 = vec3(0.0f), d1 = vec3(0.0f),
       d2 = vec3(0.0f);
  // The interpolated normal before normalising, turned to n's side (sign: the turn).
  TRACER_HD vec3 raw(vec3 p, float* sign) const {
    const vec3 q = p - a;
    const vec3 m = n0 + glm::dot(q, d1) * dn1 + glm::dot(q, d2) * dn2;
    *sign = glm::dot(m, n) < 0.0f ? -1.0f : 1.0f;
    return *sign * m;
  }
  TRACER_HD vec3 normal(vec3 p) const {
    float sign;
    const vec3 m = raw(p, &sign);
    const float l = glm::length(m);
    return l > 0.0f ? m / l : n;
  }
  TRACER_HD vec3 move_normal(vec3) const { return n; }
  TRACER_HD vec3 project(vec3 p) const { return p - glm::dot(p - a, n) * n; }
  // dn = (I - n n^T) (dn1 dp.d1 + dn2 dp.d2) / |N| (turned with N).
  TRACER_HD void turn(vec3 p, float hn, const Frame& T, const Frame& G, float out[2][2]) const {
    float sign;
    const float l = glm::length(raw(p, &sign));
    const float k = l > 0.0f ? sign * hn / l : 0.0f;
    const vec3 g[2] = {G.t, G.b}, t[2] = {T.t, T.b};
    for (int c = 0; c < 2; ++c) {
      const vec3 dm = k * (glm::dot(g[c], d1) * dn1 + glm::dot(g[c], d2) * dn2);
      for (int r = 0; r < 2; ++r) out[r][c] = glm::dot(t[r], dm);
    }
  }
};

// A triangle (vertices v0, v1, v2, vertex normals m0, m1, m2, all zero where it has none: then
// its own normal) of index eta as a smooth surface.
TRACER_HD inline SmoothSurface smooth_triangle(vec3 v0, vec3 v1, vec3 v2, vec3 m0, vec3 m1,
                                               vec3 m2, float eta) {
  SmoothSurface s;
  const vec3 e1 = v1 - v0, e2 = v2 - v0, c = glm::cross(e1, e2);
  const float area2 = glm::length(c);
  s.a = v0;
  s.n = area2 > 0.0f ? c / area2 : vec3(0.0f, 0.0f, 1.0f);
  s.eta = eta;
  s.n0 = s.n;
  if (!(area2 > 0.0f) || glm::dot(m0, m0) == 0.0f) return s;
  s.n0 = m0;
  s.dn1 = m1 - m0;
  s.dn2 = m2 - m0;
  s.d1 = glm::cross(e2, s.n) / area2;
  s.d2 = glm::cross(s.n, e1) / area2;
  return s;
}

// A chain between x and y: its surfaces in order from x and the vertices on them (up to K).
template <class Surface, uint32_t K>
struct ManifoldChainOf {
  static constexpr uint32_t kMax = K;
  // Whether a vertex moves in its surface's tangent plane (not so a smooth triangle's: in its
  // own plane, while its normal is the interpolated one).
  static constexpr bool kMovesInTangent = Surface::kMovesInTangent;
  uint32_t k = 0;
  Surface surface[K];
  vec3 p[K];
};
using ManifoldChain = ManifoldChainOf<SpecularSurface, kManifoldMaxChain>;
// The one-refraction chain through a smooth triangle (path.h).
using SmoothChain = ManifoldChainOf<SmoothSurface, 1>;


// The 2 constraint values of vertex i of the chain, between a (towards x) and b (towards y); false
// where the vertex's directions are on sides its kind cannot join (a mirror's: both outside; a
// refraction's: opposite sides).
template <class Surface>
TRACER_HD inline bool manifold_constraint(const Surface& s, vec3 p, vec3 a, vec3 b, float* c) {
  const vec3 n = s.normal(p);
  const vec3 wi = glm::normalize(a - p), wo = glm::normalize(b - p);
  const float ci = glm::dot(wi, n), co = glm::dot(wo, n);
  vec3 h;
  if (s.eta == 0.0f) {
    if (!(ci > 0.0f && co > 0.0f)) return false;
    h = wi + wo;
  } else {
    if (!(ci * co < 0.0f)) return false;
    h = (ci > 0.0f ? 1.0f : s.eta) * wi + (co > 0.0f ? 1.0f : s.eta) * wo;
  }
  const Frame f = Frame::from_normal(n);
  c[0] = glm::dot(h, f.t);
  c[1] = glm::dot(h, f.b);
  return true;
}

// All 2k constraint values of the chain between x and y; false where a vertex is invalid.
// (The loops over a chain's vertices run to kManifoldMaxChain and stop at k, unrolled, so that
// every index is a constant and the GPU keeps the chain in registers, not in local memory.)
template <class Chain>
TRACER_HD inline bool manifold_constraints(const Chain& ch, vec3 x, vec3 y, float* c) {
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t i = 0; i < Chain::kMax; ++i) {
    if (i >= ch.k) break;
    const vec3 a = i == 0 ? x : ch.p[i - 1], b = i + 1 == ch.k ? y : ch.p[i + 1];
    if (!manifold_constraint(ch.surface[i], ch.p[i], a, b, c + 2 * i)) return false;
  }
  return true;
}

// The chain with vertex i moved by (du, dv) in its tangent frame and put back on its surface.
template <class Chain>
TRACER_HD inline Chain manifold_moved(const Chain& ch, const float* step) {
  Chain m = ch;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t i = 0; i < Chain::kMax; ++i) {
    if (i >= ch.k) break;
    const Frame f = Frame::from_normal(ch.surface[i].move_normal(ch.p[i]));
    m.p[i] = ch.surface[i].project(ch.p[i] + step[2 * i] * f.t + step[2 * i + 1] * f.b);
  }
  return m;
}

// Solves the 2x2 system [a b; c d] z = r; false when it is singular.
TRACER_HD inline bool manifold_solve2(float a, float b, float c, float d, float r0, float r1,
                                      float* z0, float* z1) {
  const float det = a * d - b * c;
  if (!(glm::abs(det) > 0.0f)) return false;
  const float inv = 1.0f / det;
  *z0 = (d * r0 - b * r1) * inv;
  *z1 = (a * r1 - c * r0) * inv;
  return glm::abs(*z0) < 1e30f && glm::abs(*z1) < 1e30f;
}

// Solves J z = r for n = 2 or 4 unknowns (one or two vertices): for two by the 2x2 blocks
// [A B; C D] (A, D a vertex's own derivatives, nonsingular at a regular vertex): S = D - C A^-1 B,
// z2 = S^-1 (r2 - C A^-1 r1), z1 = A^-1 (r1 - B z2). False when a block is singular.
TRACER_HD inline bool manifold_solve(const float J[4][4], const float* r, uint32_t n, float* z) {
  if (n == 2) return manifold_solve2(J[0][0], J[0][1], J[1][0], J[1][1], r[0], r[1], &z[0], &z[1]);
  float x00, x10, x01, x11, y0, y1;  // X = A^-1 B (by columns), y = A^-1 r1
  if (!manifold_solve2(J[0][0], J[0][1], J[1][0], J[1][1], J[0][2], J[1][2], &x00, &x10) ||
      !manifold_solve2(J[0][0], J[0][1], J[1][0], J[1][1], J[0][3], J[1][3], &x01, &x11) ||
      !manifold_solve2(J[0][0], J[0][1], J[1][0], J[1][1], r[0], r[1], &y0, &y1))
    return false;
  const float s00 = J[2][2] - (J[2][0] * x00 + J[2][1] * x10);
  const float s01 = J[2][3] - (J[2][0] * x01 + J[2][1] * x11);
  const float s10 = J[3][2] - (J[3][0] * x00 + J[3][1] * x10);
  const float s11 = J[3][3] - (J[3][0] * x01 + J[3][1] * x11);
  const float t0 = r[2] - (J[2][0] * y0 + J[2][1] * y1);
  const float t1 = r[3] - (J[3][0] * y0 + J[3][1] * y1);
  if (!manifold_solve2(s00, s01, s10, s11, t0, t1, &z[2], &z[3])) return false;
  z[0] = y0 - (x00 * z[2] + x01 * z[3]);
  z[1] = y1 - (x10 * z[2] + x11 * z[3]);
  return true;
}

// The weights of vertex i's half vector h = eta_a wa + eta_b wb (1 and 1 for a mirror; for a
// refraction the index on each direction's side), as manifold_constraint forms it.
template <class Surface>
TRACER_HD inline vec2 manifold_etas(const Surface& s, vec3 n, vec3 wa, vec3 wb) {
  if (s.eta == 0.0f) return vec2(1.0f);
  return vec2(glm::dot(wa, n) > 0.0f ? 1.0f : s.eta, glm::dot(wb, n) > 0.0f ? 1.0f : s.eta);
}

// The derivative of the 2 components T^T v (T: the frame at vertex i) of eta P (q - p) / L for a
// unit direction w = (q - p) / L (P = I - w w^T, the change of w) along the frame G of another
// vertex: the 2x2 block T^T (eta P / L) G.
TRACER_HD inline void manifold_block(const Frame& T, vec3 w, float eta_over_l, const Frame& G,
                                     float out[2][2]) {
  const vec3 g[2] = {G.t, G.b}, t[2] = {T.t, T.b};
  for (int c = 0; c < 2; ++c) {
    const vec3 pg = eta_over_l * (g[c] - glm::dot(w, g[c]) * w);
    for (int r = 0; r < 2; ++r) out[r][c] = glm::dot(t[r], pg);
  }
}

// The constraint Jacobian of the chain (2k x 2k) for steps of each vertex in its move frame
// (manifold_moved), analytically (Zeltner et al. 2020, sec. 4.3, in half-vector form): with
// dh_i = eta_a P_a (da - dp_i) / L_a + eta_b P_b (db - dp_i) / L_b, and the constraint frame
// turning with the normal, which where h is along n adds -(h.n) t_r.dn: on a sphere of radius r
// dn = dp / r; on a smooth triangle dn = (I - n n^T) (dn1 dp.d1 + dn2 dp.d2) / |N|.
// The frame's turn is exact at a solution (the geometry term's Jacobian) and off it by a term of
// the size of the residual, which keeps Newton's convergence quadratic. Also dC/dy, the last
// vertex's 2x3 derivative by the light point (dcdy, optional). False where a vertex is invalid.
template <class Chain>
TRACER_HD inline bool manifold_jacobian(const Chain& ch, vec3 x, vec3 y, float J[4][4],
                                        vec3* dcdy = nullptr) {
  constexpr uint32_t K = Chain::kMax;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t i = 0; i < 4; ++i)
#if defined(__CUDACC__)
#pragma unroll
#endif
    for (uint32_t j = 0; j < 4; ++j) J[i][j] = 0.0f;
  Frame frames[K], moves[K];
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t i = 0; i < K; ++i)
    if (i < ch.k) {
      frames[i] = Frame::from_normal(ch.surface[i].normal(ch.p[i]));
      moves[i] = Chain::kMovesInTangent ? frames[i]
                                        : Frame::from_normal(ch.surface[i].move_normal(ch.p[i]));
    }
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t i = 0; i < K; ++i) {
    if (i >= ch.k) break;
    const auto& s = ch.surface[i];
    const vec3 a = i == 0 ? x : ch.p[i - 1], b = i + 1 == ch.k ? y : ch.p[i + 1];
    const vec3 da = a - ch.p[i], db = b - ch.p[i];
    const float la = glm::length(da), lb = glm::length(db);
    if (!(la > 0.0f) || !(lb > 0.0f)) return false;
    const vec3 wa = da / la, wb = db / lb;
    const vec3 nrm = frames[i].n;
    const vec2 eta = manifold_etas(s, nrm, wa, wb);
    const Frame& T = frames[i];
    float block[2][2];
    // d/dp_i: -(eta_a P_a / L_a + eta_b P_b / L_b), and the turning frame.
    float self[2][2], turn[2][2];
    manifold_block(T, wa, eta.x / la, moves[i], self);
    manifold_block(T, wb, eta.y / lb, moves[i], block);
    s.turn(ch.p[i], glm::dot(eta.x * wa + eta.y * wb, nrm), T, moves[i], turn);
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 2; ++c)
        J[2 * i + r][2 * i + c] = -(self[r][c] + block[r][c]) - turn[r][c];
    if (i > 0) {  // a = p_{i-1}
      manifold_block(T, wa, eta.x / la, moves[i - 1], block);
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) J[2 * i + r][2 * (i - 1) + c] = block[r][c];
    }
    if (i + 1 < ch.k) {  // b = p_{i+1}
      manifold_block(T, wb, eta.y / lb, moves[i + 1], block);
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) J[2 * i + r][2 * (i + 1) + c] = block[r][c];
    } else if (dcdy) {  // b = y: eta_b P_b / L_b, projected on the frame
      const vec3 t[2] = {T.t, T.b};
      for (int r = 0; r < 2; ++r)
        dcdy[r] = (eta.y / lb) * (t[r] - glm::dot(wb, t[r]) * wb);
    }
  }
  return true;
}

TRACER_HD inline float manifold_norm(const float* c, uint32_t n) {
  float s = 0.0f;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t i = 0; i < 2 * kManifoldMaxChain; ++i)
    if (i < n) s += c[i] * c[i];
  return glm::sqrt(s);
}

// Newton's method from the chain's current vertices (the seed) to a chain that joins x and y by
// its specular laws; false when it does not converge (or a vertex ends on a side its kind cannot
// join).
template <class Chain>
TRACER_HD inline bool manifold_walk(Chain& ch, vec3 x, vec3 y) {
  const uint32_t n = 2 * ch.k;
  float c[2 * kManifoldMaxChain] = {};
  if (n == 0 || !manifold_constraints(ch, x, y, c)) return false;
  float norm = manifold_norm(c, n);
  for (uint32_t it = 0; it < kManifoldIterations && norm > kManifoldTolerance; ++it) {
    float J[4][4];
    if (!manifold_jacobian(ch, x, y, J)) return false;
    float r[2 * kManifoldMaxChain], d[2 * kManifoldMaxChain] = {};
#if defined(__CUDACC__)
#pragma unroll
#endif
    for (uint32_t i = 0; i < 2 * kManifoldMaxChain; ++i) r[i] = i < n ? -c[i] : 0.0f;
    if (!manifold_solve(J, r, n, d)) return false;
    // A step that does not lower |C| is shortened by halves (kManifoldHalvings tries in all).
    bool improved = false;
    for (uint32_t halving = 0; halving < kManifoldHalvings && !improved; ++halving) {
      const Chain next = manifold_moved(ch, d);
      float cn[2 * kManifoldMaxChain] = {};
      if (manifold_constraints(next, x, y, cn) && manifold_norm(cn, n) < norm) {
        ch = next;
#if defined(__CUDACC__)
#pragma unroll
#endif
        for (uint32_t i = 0; i < 2 * kManifoldMaxChain; ++i) c[i] = cn[i];
        const float before = norm;
        norm = manifold_norm(cn, n);
        improved = true;
        // Close enough and no longer converging fast: float's rounding has the rest.
        if (norm <= kManifoldAccept && norm > 0.25f * before) return true;
      }
      // Already acceptable: a full step that does not lower |C| meets float's rounding, which
      // shorter steps do not beat either.
      if (!improved && norm <= kManifoldAccept) return true;
#if defined(__CUDACC__)
#pragma unroll
#endif
      for (uint32_t i = 0; i < 2 * kManifoldMaxChain; ++i) d[i] *= 0.5f;
    }
    if (!improved) break;  // at float's limit: accepted when close enough
  }
  return norm <= kManifoldAccept;
}

// A chain through two parallel faces of one glass (a pane, a slab, a box's opposite faces)
// solved exactly instead of by Newton in 3D: the path leaves such glass parallel to the way it
// came in, so it lies in the plane of the faces' normal n and y's offset from x along the faces,
// and there it is a function of one number, the tangent tau of the angle of incidence:
//   (h_x + h_y) tau + t g(tau) = D,   g(tau) = tau / sqrt(eta^2 + (eta^2 - 1) tau^2)
// (h_x, h_y: x's and y's distances from the faces they see, t: the glass's thickness, D: the
// offset's length, g: the tangent inside, by Snell's law). For eta > 1 the left side increases
// and is concave in tau, and tau = D / (h_x + h_y + t / eta) lies below the root (g(tau) <=
// tau / eta), so Newton's method from there climbs to the root without overshooting: a few steps
// of a few operations, the same for every vertex, where the walk in 3D takes 4-5 steps of 4x4
// Jacobians and halvings. Sets ch.p on the faces (manifold_walk then verifies and polishes);
// false, leaving ch as it was, where the chain is not such a crossing (other surfaces, faces not
// parallel or of other indices, x or y not outside the faces they see, eta <= 1).
TRACER_HD inline bool manifold_slab(ManifoldChain& ch, vec3 x, vec3 y) {
  const SpecularSurface &s0 = ch.surface[0], &s1 = ch.surface[1];
  if (ch.k != 2 || s0.kind != SpecularSurface::kPlane || s1.kind != SpecularSurface::kPlane ||
      !(s0.eta > 1.0f) || s0.eta != s1.eta || !(glm::abs(glm::dot(s0.n, s1.n)) > 1.0f - 1e-6f))
    return false;
  const vec3 xy = y - x;
  const vec3 n = glm::dot(xy, s0.n) > 0.0f ? s0.n : -s0.n;  // from x's side towards y's
  const float hx = glm::dot(s0.a - x, n), t = glm::dot(s1.a - s0.a, n), hy = glm::dot(y - s1.a, n);
  // In through face 0 from its outside, out through face 1 to its outside.
  if (!(hx > 0.0f) || !(t > 0.0f) || !(hy > 0.0f) || !(glm::dot(s0.n, n) < 0.0f) ||
      !(glm::dot(s1.n, n) > 0.0f))
    return false;
  const vec3 lateral = xy - glm::dot(xy, n) * n;
  const float d = glm::length(lateral), h = hx + hy, e2 = s0.eta * s0.eta;
  float tau = 0.0f, g = 0.0f;
  vec3 u(0.0f);
  if (d > 0.0f) {
    u = lateral / d;
    tau = d / (h + t / s0.eta);
    for (int it = 0; it < 8; ++it) {
      const float q = e2 + (e2 - 1.0f) * tau * tau, sq = glm::sqrt(q);
      g = tau / sq;
      const float f = h * tau + t * g - d;
      const float step = -f / (h + t * e2 / (q * sq));
      if (!(step > 1e-7f * tau)) break;  // at the root to float's precision (f >= 0 there)
      tau += step;
    }
    g = tau / glm::sqrt(e2 + (e2 - 1.0f) * tau * tau);
  }
  const vec3 p0 = x + hx * (n + tau * u);
  ch.p[0] = s0.project(p0);
  ch.p[1] = s1.project(p0 + t * (n + g * u));
  return true;
}

// The generalized geometry term of a solved chain: the solid angle at x that a unit of area at
// y (in the plane of the light's normal ny) maps to, |d omega_x / d A_y|. By the implicit
// function theorem: the chain's steps move with y as dP/dy = -J^-1 dC/dy (J the constraint
// Jacobian at the solution), and omega_x follows the first vertex. For an empty chain it is the
// usual cos_y / r^2.
template <class Chain>
TRACER_HD inline float manifold_geometry(const Chain& ch, vec3 x, vec3 y, vec3 ny) {
  const Frame f = Frame::from_normal(ny);
  if (ch.k == 0) {
    const vec3 d = y - x;
    const float l2 = glm::dot(d, d);
    return glm::abs(glm::dot(ny, d)) / (l2 * glm::sqrt(l2));
  }
  const uint32_t n = 2 * ch.k;
  float J[4][4];
  vec3 dcdy[2] = {vec3(0.0f), vec3(0.0f)};
  if (!manifold_jacobian(ch, x, y, J, dcdy)) return 0.0f;
  const vec3 d0 = ch.p[0] - x;
  const float l0 = glm::length(d0);
  const vec3 w0 = d0 / l0;
  const Frame f0 = Frame::from_normal(ch.surface[0].move_normal(ch.p[0]));
  vec3 dw[2];
  for (int axis = 0; axis < 2; ++axis) {
    const vec3 t = axis == 0 ? f.t : f.b;
    float r[2 * kManifoldMaxChain] = {}, step[2 * kManifoldMaxChain];
    if (ch.k == 1) {
      r[0] = -glm::dot(dcdy[0], t);
      r[1] = -glm::dot(dcdy[1], t);
    } else {
      r[2] = -glm::dot(dcdy[0], t);
      r[3] = -glm::dot(dcdy[1], t);
    }
    if (!manifold_solve(J, r, n, step)) return 0.0f;
    const vec3 dp = step[0] * f0.t + step[1] * f0.b;  // the first vertex's move per unit of y
    dw[axis] = (dp - glm::dot(dp, w0) * w0) / l0;
  }
  return glm::length(glm::cross(dw[0], dw[1]));
}

// Chains through one sphere, found exactly instead of by Newton from a seed. A path reflected or
// refracted by a sphere stays in the plane of its two end points and the centre, so there the
// chain is a function of one angle (of incidence for a refraction, of the reflection point's
// normal for a mirror), and its roots can all be looked for. In that plane (origin at the centre,
// x's direction along +u, y on the side of +v):
struct SpherePlane {
  vec3 u = vec3(0.0f), v = vec3(0.0f);
  vec2 x = vec2(0.0f), y = vec2(0.0f);
};

// False where x, y and the centre c are (nearly) in a line: the plane is not defined, and the
// chains there form a ring of measure zero.
TRACER_HD inline bool sphere_plane(vec3 c, vec3 x, vec3 y, SpherePlane& pl) {
  const vec3 a = x - c, b = y - c;
  const float la = glm::length(a);
  if (!(la > 0.0f)) return false;
  pl.u = a / la;
  const vec3 w = b - glm::dot(b, pl.u) * pl.u;
  const float lw = glm::length(w);
  if (!(lw > 1e-5f * glm::length(b))) return false;
  pl.v = w / lw;
  pl.x = vec2(la, 0.0f);
  pl.y = vec2(glm::dot(b, pl.u), lw);
  return true;
}

TRACER_HD inline float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }

// The ray from x refracted into the sphere (radius r, index eta) and out again, by its angle of
// incidence: (cos, sin) = ci (sin < 0: passing the centre on the -v side). By symmetry it leaves
// along a line as far from the centre as it came in (b = r sin), turned towards the centre by
// twice the angle between incidence and refraction. Returns the signed distance of y from that
// line (zero at a chain) and the leaving direction; false where it leaves away from y.
TRACER_HD inline bool sphere_refraction_miss(const SpherePlane& pl, float r, float eta, vec2 ci,
                                             vec2& d, vec2& t, float& miss) {
  const float b = r * ci.y;
  const float sa = b / pl.x.x;  // the direction from x: (-cos a, sin a), b = cross2(x, d)
  d = vec2(-glm::sqrt(glm::max(0.0f, 1.0f - sa * sa)), sa);
  const float si = glm::abs(ci.y), st = si / eta;
  if (!(st < 1.0f)) return false;  // reflected, not refracted, into a sphere of index below 1
  const float ct = glm::sqrt(1.0f - st * st);
  const float c = ci.x * ct + si * st, s = si * ct - ci.x * st;  // the angle i - t
  const vec2 towards = ci.y >= 0.0f ? vec2(-d.y, d.x) : vec2(d.y, -d.x);
  t = (c * c - s * s) * d + (2.0f * s * c) * towards;
  if (!(glm::dot(t, pl.y) > r * ci.x)) return false;  // y beyond the exit point
  miss = cross2(pl.y, t) - b;
  return true;
}

// The number of angles of incidence, over (-90, 90) degrees, where sphere_refraction_chains
// looks for changes of sign, and for a fold of the caustic (a pair of chains between two angles:
// the miss's extremum between them crossing zero). Chains it still misses stay BSDF sampling's
// in manifold NEE's split.
constexpr int kSphereScan = 16;
// Bisection steps on a sign change before Newton's method (manifold_walk) takes over: the root
// to within 1/256 of a scan step, where Newton converges in a step or two; and golden-section
// steps that look for a fold's extremum.
constexpr int kSphereBisections = 8;
constexpr int kSphereFoldSteps = 10;

// Every two-refraction chain from x to y through the sphere (centre c, radius r, index eta inside;
// x and y outside): the sign changes of sphere_refraction_miss over the angles of incidence and
// the folds' pairs, each narrowed by bisection, one chain at a time (next: its surfaces set, to be
// polished by manifold_walk), so that a solver can trace rays between two chains (path.h,
// MneeSolver) and sphere_refraction_chains below can call a function for each.
struct SphereChainScan {
  SpherePlane pl;
  vec3 c = vec3(0.0f);
  float r = 0.0f, eta = 1.0f;
  float th = 0.0f, step = 0.0f;  // the scan's first angle (-th) and step
  vec2 rot = vec2(1.0f, 0.0f), ci = vec2(1.0f, 0.0f);  // its rotation by a step; (cos, sin) of i
  float m1 = 0.0f, m2 = 0.0f;  // the misses one and two steps back
  bool ok1 = false, ok2 = false;
  int i = kSphereScan + 1;  // the next angle of the scan (past the end: none)
  // Brackets of roots still to narrow (a fold gives two): [a, b] with a's miss m_a.
  int pending = 0, taken = 0;
  float pa[2] = {0.0f, 0.0f}, pb[2] = {0.0f, 0.0f}, pm[2] = {0.0f, 0.0f};

  TRACER_HD void start(vec3 centre, float radius, float index, vec3 x, vec3 y) {
    c = centre;
    r = radius;
    eta = index;
    pending = taken = 0;
    ok1 = ok2 = false;
    i = kSphereScan + 1;
    if (!sphere_plane(c, x, y, pl) || !(pl.x.x > r) || !(glm::length(pl.y) > r)) return;
    // The scan's (cos, sin) of incidence by rotation, one step at a time (no trigonometry).
    th = 0.5f * kPi * (1.0f - 1e-4f);
    step = 2.0f * th / float(kSphereScan);
    fast_sincos(step, &rot.y, &rot.x);
    fast_sincos(th, &ci.y, &ci.x);
    ci.y = -ci.y;
    i = 0;
  }

  TRACER_HD bool miss_at(float a, vec2& d, vec2& t, float& m) const {
    vec2 cs;
    fast_sincos(a, &cs.y, &cs.x);
    return sphere_refraction_miss(pl, r, eta, cs, d, t, m);
  }

  // The chain between angles a (miss m_a) and b, whose misses differ in sign.
  TRACER_HD bool root(float a, float b, float m_a, ManifoldChain& ch) const {
    vec2 d, t;
    float m;
    for (int it = 0; it < kSphereBisections; ++it) {
      const float mid = 0.5f * (a + b);
      if (!miss_at(mid, d, t, m)) return false;
      if ((m > 0.0f) == (m_a > 0.0f)) {
        a = mid;
        m_a = m;
      } else {
        b = mid;
      }
    }
    const float mid = 0.5f * (a + b);
    if (!miss_at(mid, d, t, m)) return false;
    // The vertices: where the lines in and out meet the circle (at distance b from the centre).
    float sm, cm;
    fast_sincos(mid, &sm, &cm);
    const float dist = r * sm, half = r * cm;
    const vec2 p1 = dist * vec2(d.y, -d.x) - half * d, p2 = dist * vec2(t.y, -t.x) + half * t;
    ch.k = 2;
    for (int j = 0; j < 2; ++j) {
      ch.surface[j].kind = SpecularSurface::kSphere;
      ch.surface[j].a = c;
      ch.surface[j].radius = r;
      ch.surface[j].eta = eta;
    }
    ch.p[0] = c + p1.x * pl.u + p1.y * pl.v;
    ch.p[1] = c + p2.x * pl.u + p2.y * pl.v;
    return true;
  }

  // One angle of the scan: brackets of roots where the miss changes sign, or a fold's pair.
  TRACER_HD void scan_one() {
    const float a = -th + step * float(i);
    vec2 d, t;
    float m = 0.0f;
    const bool ok = sphere_refraction_miss(pl, r, eta, ci, d, t, m);
    if (ok && ok1 && (m > 0.0f) != (m1 > 0.0f)) {
      pa[0] = a - step;
      pb[0] = a;
      pm[0] = m1;
      pending = 1;
    } else if (ok && ok1 && ok2 && (m > 0.0f) == (m1 > 0.0f) && (m1 > 0.0f) == (m2 > 0.0f) &&
               (m1 > 0.0f ? m1 < glm::min(m, m2) : m1 > glm::max(m, m2))) {
      // |miss| smallest one step back: a fold, if its extremum crosses zero. Golden section for
      // the extremum of s * miss (s: the sign), then a root on either side.
      const float sgn = m1 > 0.0f ? 1.0f : -1.0f, g = 0.381966f;
      float lo = a - 2.0f * step, hi = a, x1 = lo + g * (hi - lo), x2 = hi - g * (hi - lo), f1, f2;
      bool fine = miss_at(x1, d, t, f1) && miss_at(x2, d, t, f2);
      for (int it = 0; it < kSphereFoldSteps && fine && sgn * f1 > 0.0f && sgn * f2 > 0.0f; ++it) {
        if (sgn * f1 < sgn * f2) {
          hi = x2;
          x2 = x1;
          f2 = f1;
          x1 = lo + g * (hi - lo);
          fine = miss_at(x1, d, t, f1);
        } else {
          lo = x1;
          x1 = x2;
          f1 = f2;
          x2 = hi - g * (hi - lo);
          fine = miss_at(x2, d, t, f2);
        }
      }
      if (fine && (sgn * f1 <= 0.0f || sgn * f2 <= 0.0f)) {
        const float xm = sgn * f1 <= sgn * f2 ? x1 : x2, fm = sgn * f1 <= sgn * f2 ? f1 : f2;
        pa[0] = a - 2.0f * step;
        pb[0] = xm;
        pm[0] = m2;
        pa[1] = xm;
        pb[1] = a;
        pm[1] = fm;
        pending = 2;
      }
    }
    m2 = m1;
    ok2 = ok1;
    m1 = m;
    ok1 = ok;
    ci = vec2(ci.x * rot.x - ci.y * rot.y, ci.x * rot.y + ci.y * rot.x);
    ++i;
  }

  // The next chain; false when the scan has no more.
  TRACER_HD bool next(ManifoldChain& ch) {
    for (;;) {
      while (taken < pending) {
        const int j = taken++;
        if (root(pa[j], pb[j], pm[j], ch)) return true;
      }
      pending = taken = 0;
      if (i > kSphereScan) return false;
      scan_one();
    }
  }
};

// Calls found(chain) for every chain SphereChainScan finds.
template <typename Found>
TRACER_HD inline void sphere_refraction_chains(vec3 c, float r, float eta, vec3 x, vec3 y,
                                               Found&& found) {
  SphereChainScan scan;
  scan.start(c, r, eta, x, y);
  ManifoldChain ch;
  while (scan.next(ch)) found(ch);
}

// The reflection off a mirror sphere (centre c, radius r) from x to y (both outside): on the arc
// between the directions of x and y the normal halves the directions to x and y at exactly one
// point, narrowed by bisection, to be polished by manifold_walk (which refuses it where x or y
// does not see it).
TRACER_HD inline bool sphere_reflection_chain(vec3 c, float r, vec3 x, vec3 y, ManifoldChain& ch) {
  SpherePlane pl;
  if (!sphere_plane(c, x, y, pl) || !(pl.x.x > r)) return false;
  const float ly = glm::length(pl.y);
  if (!(ly > r)) return false;
  auto miss = [&](vec2 n) {
    const vec2 p = r * n;
    return cross2(n, glm::normalize(pl.x - p)) + cross2(n, glm::normalize(pl.y - p));
  };
  // Bisection on the arc from x's direction (miss >= 0) to y's (<= 0; y on the side of +v, so
  // the arc is under pi), its midpoint the normalised sum of its ends.
  vec2 lo(1.0f, 0.0f), hi = pl.y / ly;
  for (int it = 0; it < kSphereBisections; ++it) {
    const vec2 mid = glm::normalize(lo + hi);
    if (miss(mid) > 0.0f) lo = mid;
    else hi = mid;
  }
  const vec2 n = glm::normalize(lo + hi);
  ch.k = 1;
  ch.surface[0].kind = SpecularSurface::kSphere;
  ch.surface[0].a = c;
  ch.surface[0].radius = r;
  ch.surface[0].eta = 0.0f;
  ch.p[0] = c + r * (n.x * pl.u + n.y * pl.v);
  return true;
}

}  // namespace tracer
