// Hits, primitives and their intersection routines with rays (core/ray.h), shared by CPU and CUDA.
// Triangles use the watertight test of Woop, Benthin & Wald (JCGT 2(1), 2013); spheres the
// cancellation-free quadratic of Haines et al., Ray Tracing Gems (2019), ch. 7.
#pragma once

#include "core/math.h"
#include "core/ray.h"

namespace tracer {

struct Hit {
  float t = kInfinity;
  uint32_t prim = kInvalid;  // unified primitive id: triangles first, then spheres
  float u = 0.0f, v = 0.0f;  // barycentrics of v1 and v2 for triangles
  TRACER_HD bool valid() const { return prim != kInvalid; }
};

// 48 bytes so that a triangle is three aligned 16-byte loads on the GPU.
struct alignas(16) TriangleVerts {
  vec3 v0;
  float pad0;
  vec3 v1;
  float pad1;
  vec3 v2;
  float pad2;
};

TRACER_HD TRACER_INLINE TriangleVerts load_triangle(const TriangleVerts* tris, uint32_t i) {
#if defined(__CUDA_ARCH__)
  const float4* p = reinterpret_cast<const float4*>(tris + i);
  const float4 a = __ldg(p), b = __ldg(p + 1), c = __ldg(p + 2);
  TriangleVerts t;
  t.v0 = vec3(a.x, a.y, a.z);
  t.v1 = vec3(b.x, b.y, b.z);
  t.v2 = vec3(c.x, c.y, c.z);
  t.pad0 = t.pad1 = t.pad2 = 0.0f;
  return t;
#else
  return tris[i];
#endif
}

struct alignas(16) Sphere {
  vec3 center;
  float radius;
  uint32_t material;
  uint32_t light;  // index into the light list, kInvalid when not emissive
  uint32_t pad[2];
};

TRACER_HD TRACER_INLINE Sphere load_sphere(const Sphere* spheres, uint32_t i) {
#if defined(__CUDA_ARCH__)
  const float4* p = reinterpret_cast<const float4*>(spheres + i);
  const float4 a = __ldg(p), b = __ldg(p + 1);
  Sphere s;
  s.center = vec3(a.x, a.y, a.z);
  s.radius = a.w;
  s.material = __float_as_uint(b.x);
  s.light = __float_as_uint(b.y);
  s.pad[0] = s.pad[1] = 0;
  return s;
#else
  return spheres[i];
#endif
}

// v[k] for a run-time k in {0, 1, 2}, as two selects. GLM's operator[] is a switch, which nvcc
// compiles to branches, and a warp whose rays have different dominant axes splits on them; the
// selects keep its lanes together (docs/PERFORMANCE.md, decision log).
TRACER_HD TRACER_INLINE float pick(vec3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

// Per-ray constants of the watertight test: the axis permutation and shear that map the ray
// direction to +z, and the origin in permuted order. inv_d is 1/d, as the box tests use it.
struct RayTriSetup {
  int kx, ky, kz;
  float sx, sy, sz;
  vec3 o;  // (o[kx], o[ky], o[kz])
  RayTriSetup() = default;
  TRACER_HD RayTriSetup(const Ray& ray, vec3 inv_d) {
    const vec3 d = ray.d;
    const vec3 a = glm::abs(d);
    kz = (a.x > a.y) ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2);
    kx = (kz + 1) % 3;
    ky = (kx + 1) % 3;
    if (pick(d, kz) < 0.0f) {  // keep the winding so that U, V, W signs stay meaningful
      const int tmp = kx;
      kx = ky;
      ky = tmp;
    }
    sx = pick(d, kx) / pick(d, kz);
    sy = pick(d, ky) / pick(d, kz);
    sz = pick(inv_d, kz);  // 1 / d[kz], the same float
    o = permute(ray.o);
  }
  // (v[kx], v[ky], v[kz]).
  TRACER_HD vec3 permute(vec3 v) const { return vec3(pick(v, kx), pick(v, ky), pick(v, kz)); }
};

// Returns true and fills t, b1, b2 when the ray hits the triangle at 0 < t < tmax.
// Edges shared by two triangles are hit by exactly one or both of them, never neither.
// Coordinates are permuted before the origin is subtracted: the same floats as (p - o)[k].
TRACER_HD inline bool intersect_triangle(const RayTriSetup& s, vec3 p0, vec3 p1, vec3 p2,
                                         float tmax, float& t_out, float& b1_out, float& b2_out) {
  const vec3 A = s.permute(p0) - s.o, B = s.permute(p1) - s.o, C = s.permute(p2) - s.o;
  const float ax = A.x - s.sx * A.z, ay = A.y - s.sy * A.z;
  const float bx = B.x - s.sx * B.z, by = B.y - s.sy * B.z;
  const float cx = C.x - s.sx * C.z, cy = C.y - s.sy * C.z;
  float U = cx * by - cy * bx;
  float V = ax * cy - ay * cx;
  float W = bx * ay - by * ax;
  // On an edge the float products can round to exactly zero; redo them in double (sec. 3.3).
  if (U == 0.0f || V == 0.0f || W == 0.0f) {
    U = float(double(cx) * double(by) - double(cy) * double(bx));
    V = float(double(ax) * double(cy) - double(ay) * double(cx));
    W = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return false;
  const float det = U + V + W;
  if (det == 0.0f) return false;
  const float az = s.sz * A.z, bz = s.sz * B.z, cz = s.sz * C.z;
  const float T = U * az + V * bz + W * cz;
  if (det < 0.0f ? (T >= 0.0f || T < tmax * det) : (T <= 0.0f || T > tmax * det)) return false;
  const float inv_det = 1.0f / det;
  t_out = T * inv_det;
  b1_out = V * inv_det;
  b2_out = W * inv_det;
  return t_out > 0.0f && t_out < tmax;
}

// Nearest root of |o + t d - c| = r in (0, tmax).
TRACER_HD inline bool intersect_sphere(const Ray& ray, vec3 center, float radius, float tmax,
                                       float& t_out) {
  // Double precision: with the huge spheres used as walls (smallpt's are of radius 1e5, 100
  // units from the camera) |f|^2 - r^2 cancels 1e10-sized terms, and in float the hit lands up to
  // 0.01 units off the surface, below the ray offset's reach: walls show self-hit bands. Hopper
  // runs FP64 at half the FP32 rate, and this is a few dozen operations per sphere test.
  const double fx = double(ray.o.x) - double(center.x), fy = double(ray.o.y) - double(center.y),
               fz = double(ray.o.z) - double(center.z);
  const double dx = ray.d.x, dy = ray.d.y, dz = ray.d.z;
  const double dd = dx * dx + dy * dy + dz * dz;  // directions are unit length up to rounding
  const double b = -(fx * dx + fy * dy + fz * dz) / dd;
  // f minus its projection on d, computed without cancellation (Haines et al., Ray Tracing Gems
  // ch. 7): the discriminant is r^2 - |l|^2.
  const double lx = fx + b * dx, ly = fy + b * dy, lz = fz + b * dz;
  const double r2 = double(radius) * double(radius);
  const double disc = r2 - (lx * lx + ly * ly + lz * lz);
  if (disc < 0.0) return false;
  const double c = (fx * fx + fy * fy + fz * fz - r2) / dd;
  const double q = b + (b >= 0.0 ? sqrt(disc / dd) : -sqrt(disc / dd));  // never cancels
  if (q == 0.0) return false;
  double t0 = c / q, t1 = q;
  if (t0 > t1) {
    const double tmp = t0;
    t0 = t1;
    t1 = tmp;
  }
  if (t0 > 0.0 && t0 < double(tmax)) {
    t_out = float(t0);
    return true;
  }
  if (t1 > 0.0 && t1 < double(tmax)) {
    t_out = float(t1);
    return true;
  }
  return false;
}

}  // namespace tracer
