// Manifold next-event estimation's solver (Hanika, Droske, Fascione 2015, "Manifold Next Event
// Estimation"; the half-vector constraints of Zeltner, Georgiev, Jakob 2020, "Specular Manifold
// Sampling"): the path from a receiver point x to a light point y through a chain of up to
// kManifoldMaxChain smooth specular vertices (a mirror's reflection or a smooth dielectric's
// refraction), found by Newton's method on the specular surfaces, and the generalized geometry
// term that turns the light sample's area density into a density of directions at x.
//
// Used by path.h's mnee_connect (an experiment: CPU only, IntegratorSettings::mnee). The
// surfaces are the two analytic kinds the target scenes' casters are made of, a plane (a flat
// face of a box or mesh) and a sphere; a mesh with interpolated normals needs its vertices moved
// along the mesh (re-projected by a ray, as Hanika does).
//
// The constraint at vertex i with neighbours a (towards x) and b (towards y): with wi and wo the
// unit directions to them and eta_i, eta_o the indices of refraction on their sides (1 and 1 for
// a mirror), the tangential part of eta_i wi + eta_o wo is zero: the law of reflection, or
// Snell's law (eta_i sin = eta_o sin, on opposite sides). Newton moves each vertex in its tangent
// plane by the solve of J d = -C (J by forward differences: 2k x 2k, k <= 2) and puts it back on
// its surface (the plane itself, or the sphere along its radius), halving a step that does not
// lower |C|.
#pragma once

#include "core/math.h"

namespace tracer {

constexpr uint32_t kManifoldMaxChain = 2;
constexpr uint32_t kManifoldIterations = 24;
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
  // The outward unit normal at p (on the surface).
  TRACER_HD vec3 normal(vec3 p) const { return kind == kPlane ? n : (p - a) / radius; }
  // p moved back onto the surface: the plane's nearest point, or along the sphere's radius.
  TRACER_HD vec3 project(vec3 p) const {
    if (kind == kPlane) return p - glm::dot(p - a, n) * n;
    const vec3 d = p - a;
    const float l = glm::length(d);
    return l > 0.0f ? a + d * (radius / l) : a + vec3(0.0f, 0.0f, radius);
  }
};

// A chain between x and y: its surfaces in order from x and the vertices on them.
struct ManifoldChain {
  uint32_t k = 0;
  SpecularSurface surface[kManifoldMaxChain];
  vec3 p[kManifoldMaxChain];
};

// The 2 constraint values of vertex i of the chain, between a (towards x) and b (towards y); false
// where the vertex's directions are on sides its kind cannot join (a mirror's: both outside; a
// refraction's: opposite sides).
TRACER_HD inline bool manifold_constraint(const SpecularSurface& s, vec3 p, vec3 a, vec3 b,
                                          float* c) {
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
TRACER_HD inline bool manifold_constraints(const ManifoldChain& ch, vec3 x, vec3 y, float* c) {
  for (uint32_t i = 0; i < ch.k; ++i) {
    const vec3 a = i == 0 ? x : ch.p[i - 1], b = i + 1 == ch.k ? y : ch.p[i + 1];
    if (!manifold_constraint(ch.surface[i], ch.p[i], a, b, c + 2 * i)) return false;
  }
  return true;
}

// The chain with vertex i moved by (du, dv) in its tangent frame and put back on its surface.
TRACER_HD inline ManifoldChain manifold_moved(const ManifoldChain& ch, const float* step) {
  ManifoldChain m = ch;
  for (uint32_t i = 0; i < ch.k; ++i) {
    const Frame f = Frame::from_normal(ch.surface[i].normal(ch.p[i]));
    m.p[i] = ch.surface[i].project(ch.p[i] + step[2 * i] * f.t + step[2 * i + 1] * f.b);
  }
  return m;
}

// Solves A z = r for n <= 4 unknowns by Gaussian elimination with partial pivoting; false when
// A is singular. A and r are overwritten.
TRACER_HD inline bool manifold_solve(float A[4][4], float* r, uint32_t n, float* z) {
  for (uint32_t col = 0; col < n; ++col) {
    uint32_t pivot = col;
    for (uint32_t row = col + 1; row < n; ++row)
      if (glm::abs(A[row][col]) > glm::abs(A[pivot][col])) pivot = row;
    if (!(glm::abs(A[pivot][col]) > 1e-20f)) return false;
    if (pivot != col) {
      for (uint32_t j = 0; j < n; ++j) {
        const float t = A[col][j];
        A[col][j] = A[pivot][j];
        A[pivot][j] = t;
      }
      const float t = r[col];
      r[col] = r[pivot];
      r[pivot] = t;
    }
    for (uint32_t row = col + 1; row < n; ++row) {
      const float f = A[row][col] / A[col][col];
      for (uint32_t j = col; j < n; ++j) A[row][j] -= f * A[col][j];
      r[row] -= f * r[col];
    }
  }
  for (uint32_t i = n; i-- > 0;) {
    float s = r[i];
    for (uint32_t j = i + 1; j < n; ++j) s -= A[i][j] * z[j];
    z[i] = s / A[i][i];
  }
  return true;
}

// The constraint Jacobian of the chain at its vertices (2k x 2k, by differences of each vertex's
// tangent-plane step: central, or forward from c, the constraints at the chain, where Newton's
// direction needs no more); false where a moved chain is invalid.
TRACER_HD inline bool manifold_jacobian(const ManifoldChain& ch, vec3 x, vec3 y, float h,
                                        float J[4][4], const float* c = nullptr) {
  const uint32_t n = 2 * ch.k;
  for (uint32_t j = 0; j < n; ++j) {
    float step[2 * kManifoldMaxChain] = {};
    float cp[2 * kManifoldMaxChain], cm[2 * kManifoldMaxChain];
    step[j] = h;
    if (!manifold_constraints(manifold_moved(ch, step), x, y, cp)) return false;
    if (c) {
      for (uint32_t i = 0; i < n; ++i) J[i][j] = (cp[i] - c[i]) / h;
      continue;
    }
    step[j] = -h;
    if (!manifold_constraints(manifold_moved(ch, step), x, y, cm)) return false;
    for (uint32_t i = 0; i < n; ++i) J[i][j] = (cp[i] - cm[i]) / (2.0f * h);
  }
  return true;
}

TRACER_HD inline float manifold_norm(const float* c, uint32_t n) {
  float s = 0.0f;
  for (uint32_t i = 0; i < n; ++i) s += c[i] * c[i];
  return glm::sqrt(s);
}

// Newton's method from the chain's current vertices (the seed) to a chain that joins x and y by
// its specular laws; false when it does not converge (or a vertex ends on a side its kind cannot
// join). `scale`: the scene's length scale for the finite differences (|y - x| serves).
TRACER_HD inline bool manifold_walk(ManifoldChain& ch, vec3 x, vec3 y, float scale) {
  const uint32_t n = 2 * ch.k;
  float c[2 * kManifoldMaxChain];
  if (n == 0 || !manifold_constraints(ch, x, y, c)) return false;
  float norm = manifold_norm(c, n);
  const float h = 1e-3f * scale;
  for (uint32_t it = 0; it < kManifoldIterations && norm > kManifoldTolerance; ++it) {
    float J[4][4];
    if (!manifold_jacobian(ch, x, y, h, J, c)) return false;
    float r[2 * kManifoldMaxChain], d[2 * kManifoldMaxChain];
    for (uint32_t i = 0; i < n; ++i) r[i] = -c[i];
    if (!manifold_solve(J, r, n, d)) return false;
    // A step that does not lower |C| is halved (up to 8 times).
    bool improved = false;
    for (uint32_t halving = 0; halving < 8 && !improved; ++halving) {
      const ManifoldChain next = manifold_moved(ch, d);
      float cn[2 * kManifoldMaxChain];
      if (manifold_constraints(next, x, y, cn) && manifold_norm(cn, n) < norm) {
        ch = next;
        for (uint32_t i = 0; i < n; ++i) c[i] = cn[i];
        const float before = norm;
        norm = manifold_norm(cn, n);
        improved = true;
        // Close enough and no longer converging fast: float's rounding has the rest.
        if (norm <= kManifoldAccept && norm > 0.25f * before) return true;
      }
      for (uint32_t i = 0; i < n; ++i) d[i] *= 0.5f;
    }
    if (!improved) break;  // at float's limit: accepted when close enough
  }
  return norm <= kManifoldAccept;
}

// The generalized geometry term of a solved chain: the solid angle at x that a unit of area at
// y (in the plane of the light's normal ny) maps to, |d omega_x / d A_y|. By the implicit
// function theorem: the chain's steps move with y as dP/dy = -J^-1 dC/dy (J the constraint
// Jacobian at the solution, dC/dy by central differences along the light's tangents), and
// omega_x follows the first vertex. For an empty chain it is the usual cos_y / r^2.
TRACER_HD inline float manifold_geometry(const ManifoldChain& ch, vec3 x, vec3 y, vec3 ny,
                                         float scale) {
  const Frame f = Frame::from_normal(ny);
  const float e = 1e-3f * scale;
  if (ch.k == 0) {
    vec3 w[4];
    const vec3 offsets[4] = {f.t * e, -f.t * e, f.b * e, -f.b * e};
    for (int i = 0; i < 4; ++i) w[i] = glm::normalize(y + offsets[i] - x);
    return glm::length(glm::cross((w[0] - w[1]) / (2.0f * e), (w[2] - w[3]) / (2.0f * e)));
  }
  const uint32_t n = 2 * ch.k;
  float J[4][4];
  if (!manifold_jacobian(ch, x, y, e, J)) return 0.0f;
  const vec3 d0 = ch.p[0] - x;
  const float l0 = glm::length(d0);
  const vec3 w0 = d0 / l0;
  const Frame f0 = Frame::from_normal(ch.surface[0].normal(ch.p[0]));
  vec3 dw[2];
  for (int axis = 0; axis < 2; ++axis) {
    const vec3 t = axis == 0 ? f.t : f.b;
    float cp[2 * kManifoldMaxChain], cm[2 * kManifoldMaxChain];
    if (!manifold_constraints(ch, x, y + e * t, cp) || !manifold_constraints(ch, x, y - e * t, cm))
      return 0.0f;
    float r[2 * kManifoldMaxChain], step[2 * kManifoldMaxChain];
    for (uint32_t i = 0; i < n; ++i) r[i] = -(cp[i] - cm[i]) / (2.0f * e);
    float A[4][4];
    for (uint32_t i = 0; i < 4; ++i)
      for (uint32_t j = 0; j < 4; ++j) A[i][j] = J[i][j];
    if (!manifold_solve(A, r, n, step)) return 0.0f;
    const vec3 dp = step[0] * f0.t + step[1] * f0.b;  // the first vertex's move per unit of y
    dw[axis] = (dp - glm::dot(dp, w0) * w0) / l0;
  }
  return glm::length(glm::cross(dw[0], dw[1]));
}

}  // namespace tracer
