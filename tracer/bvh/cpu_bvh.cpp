// SSE traversal of the CPU BVH layout (cpu_bvh.h). Every box and triangle test performs the same
// float operations in the same order as the scalar tests of bvh.h and geometry.h, lane by lane,
// so both traversals find the same hits; tests/bvh_test.cpp checks that on random rays.
#include "bvh/cpu_bvh.h"

#include "bvh/traverse.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#define TRACER_CPU_SIMD 1
#else
#define TRACER_CPU_SIMD 0
#endif

namespace tracer {

CpuBvhView CpuBvh::view() const {
  CpuBvhView v;
  if (nodes.empty()) return v;
  v.nodes = nodes.data();
  v.packets = packets.data();
  v.leaves = leaves.data();
  v.sphere_prims = sphere_prims.data();
  return v;
}

bool cpu_bvh_supported() {
  return TRACER_CPU_SIMD != 0;
}

CpuBvh build_cpu_bvh(const Bvh& bvh, const std::vector<TriangleVerts>& tris, uint32_t tri_count) {
  CpuBvh out;
  if (!TRACER_CPU_SIMD || bvh.nodes.empty()) return out;
  out.nodes.resize(bvh.nodes.size());
  for (size_t n = 0; n < bvh.nodes.size(); ++n) {
    CpuBvhNode& dst = out.nodes[n];
    for (int i = 0; i < kBvhWidth; ++i) {
      const BvhSlot& c = bvh.nodes[n].child[i];
      for (int a = 0; a < 3; ++a) {
        dst.box[a][i] = c.lo[a];
        dst.box[3 + a][i] = c.hi[a];
      }
      dst.ref[i] = c.ref;
      // An unused slot keeps its empty box, which no ray enters, and is never followed.
      if (c.lo.x > c.hi.x || !is_leaf_ref(c.ref)) continue;
      CpuLeaf leaf;
      leaf.first_packet = uint32_t(out.packets.size());
      leaf.first_sphere = uint32_t(out.sphere_prims.size());
      CpuTriPacket packet{};
      int lanes = 0;
      for (uint32_t k = c.ref & ~kBvhLeafBit;; ++k) {
        const uint32_t entry = bvh.prim_indices[k];
        const uint32_t prim = entry & ~kBvhLastPrimBit;
        if (prim < tri_count) {
          const TriangleVerts& t = tris[prim];
          const vec3 v[3] = {t.v0, t.v1, t.v2};
          for (int vi = 0; vi < 3; ++vi)
            for (int a = 0; a < 3; ++a) packet.v[3 * vi + a][lanes] = v[vi][a];
          packet.prim[lanes++] = prim;
          if (lanes == 4) {
            out.packets.push_back(packet);
            packet = CpuTriPacket{};
            lanes = 0;
          }
        } else {
          out.sphere_prims.push_back(prim);
        }
        if (entry & kBvhLastPrimBit) break;
      }
      if (lanes > 0) {
        for (int l = lanes; l < 4; ++l) packet.prim[l] = kInvalid;
        out.packets.push_back(packet);
      }
      leaf.packet_count = uint32_t(out.packets.size()) - leaf.first_packet;
      leaf.sphere_count = uint32_t(out.sphere_prims.size()) - leaf.first_sphere;
      dst.ref[i] = kBvhLeafBit | uint32_t(out.leaves.size());
      out.leaves.push_back(leaf);
    }
  }
  return out;
}

#if TRACER_CPU_SIMD

namespace {

// Per-ray constants of both tests, broadcast to four lanes.
struct SimdRay {
  __m128 o[3], inv[3];
  int near_row[3], far_row[3];  // rows of CpuBvhNode::box holding each axis' near and far planes
  __m128 widen;
  // The watertight test: rows of CpuTriPacket::v for the permuted axes, shear and origin.
  int k[3];
  __m128 sx, sy, sz, po[3];

  SimdRay(const Ray& ray, vec3 inv_d, const RayTriSetup& setup) {
    for (int a = 0; a < 3; ++a) {
      o[a] = _mm_set1_ps(ray.o[a]);
      inv[a] = _mm_set1_ps(inv_d[a]);
      const bool pos = inv_d[a] >= 0.0f;  // as intersect_aabb picks the planes
      near_row[a] = pos ? a : 3 + a;
      far_row[a] = pos ? 3 + a : a;
    }
    widen = _mm_set1_ps(1.0f + 2.0f * gamma_bound(3));
    k[0] = setup.kx;
    k[1] = setup.ky;
    k[2] = setup.kz;
    sx = _mm_set1_ps(setup.sx);
    sy = _mm_set1_ps(setup.sy);
    sz = _mm_set1_ps(setup.sz);
    po[0] = _mm_set1_ps(setup.o.x);
    po[1] = _mm_set1_ps(setup.o.y);
    po[2] = _mm_set1_ps(setup.o.z);
  }
};

// intersect_aabb for four boxes: entry distances in *t_near, a mask of the boxes hit returned.
// _mm_max_ps(a, b) is a > b ? a : b and _mm_min_ps(a, b) is a < b ? a : b, the scalar test's
// selects, NaN handling included.
inline int boxes_hit(const CpuBvhNode& n, const SimdRay& r, float tmax, __m128* t_near) {
  __m128 tn = _mm_setzero_ps(), tf = _mm_set1_ps(tmax);
  for (int a = 0; a < 3; ++a) {
    const __m128 near_t =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[r.near_row[a]]), r.o[a]), r.inv[a]);
    const __m128 far_t = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[r.far_row[a]]), r.o[a]), r.inv[a]);
    tn = _mm_max_ps(near_t, tn);
    tf = _mm_min_ps(far_t, tf);
  }
  tf = _mm_mul_ps(tf, r.widen);
  *t_near = tn;
  return _mm_movemask_ps(_mm_cmple_ps(tn, tf));
}

inline __m128 lane_eq(const uint32_t* prims, uint32_t value) {
  return _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_load_si128(reinterpret_cast<const __m128i*>(prims)),
                                          _mm_set1_epi32(int(value))));
}

// intersect_triangle for the four lanes of a packet. Returns the mask of lanes hit in
// (0, tmax) and their t, b1, b2.
inline int triangles_hit(const CpuTriPacket& p, const SimdRay& r, float tmax, uint32_t skip,
                         uint32_t skip2, __m128* t_out, __m128* b1_out, __m128* b2_out) {
  const __m128 zero = _mm_setzero_ps();
  // Lanes in use and not skipped.
  const __m128 unused = _mm_or_ps(lane_eq(p.prim, kInvalid),
                                  _mm_or_ps(lane_eq(p.prim, skip), lane_eq(p.prim, skip2)));
  __m128 A[3], B[3], C[3];
  for (int a = 0; a < 3; ++a) {
    A[a] = _mm_sub_ps(_mm_load_ps(p.v[r.k[a]]), r.po[a]);
    B[a] = _mm_sub_ps(_mm_load_ps(p.v[3 + r.k[a]]), r.po[a]);
    C[a] = _mm_sub_ps(_mm_load_ps(p.v[6 + r.k[a]]), r.po[a]);
  }
  const __m128 ax = _mm_sub_ps(A[0], _mm_mul_ps(r.sx, A[2]));
  const __m128 ay = _mm_sub_ps(A[1], _mm_mul_ps(r.sy, A[2]));
  const __m128 bx = _mm_sub_ps(B[0], _mm_mul_ps(r.sx, B[2]));
  const __m128 by = _mm_sub_ps(B[1], _mm_mul_ps(r.sy, B[2]));
  const __m128 cx = _mm_sub_ps(C[0], _mm_mul_ps(r.sx, C[2]));
  const __m128 cy = _mm_sub_ps(C[1], _mm_mul_ps(r.sy, C[2]));
  __m128 U = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
  __m128 V = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
  __m128 W = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
  // On an edge the float products can round to exactly zero; those lanes redo them in double.
  const int zero_lanes = _mm_movemask_ps(_mm_andnot_ps(
      unused,
      _mm_or_ps(_mm_cmpeq_ps(U, zero), _mm_or_ps(_mm_cmpeq_ps(V, zero), _mm_cmpeq_ps(W, zero)))));
  if (zero_lanes) {
    alignas(16) float u[4], v[4], w[4], e[6][4];
    _mm_store_ps(u, U);
    _mm_store_ps(v, V);
    _mm_store_ps(w, W);
    const __m128 ev[6] = {ax, ay, bx, by, cx, cy};
    for (int i = 0; i < 6; ++i) _mm_store_ps(e[i], ev[i]);
    for (int l = 0; l < 4; ++l) {
      if (!(zero_lanes >> l & 1)) continue;
      const double dax = e[0][l], day = e[1][l], dbx = e[2][l], dby = e[3][l], dcx = e[4][l],
                   dcy = e[5][l];
      u[l] = float(dcx * dby - dcy * dbx);
      v[l] = float(dax * dcy - day * dcx);
      w[l] = float(dbx * day - dby * dax);
    }
    U = _mm_load_ps(u);
    V = _mm_load_ps(v);
    W = _mm_load_ps(w);
  }
  const __m128 any_neg =
      _mm_or_ps(_mm_cmplt_ps(U, zero), _mm_or_ps(_mm_cmplt_ps(V, zero), _mm_cmplt_ps(W, zero)));
  const __m128 any_pos =
      _mm_or_ps(_mm_cmpgt_ps(U, zero), _mm_or_ps(_mm_cmpgt_ps(V, zero), _mm_cmpgt_ps(W, zero)));
  const __m128 det = _mm_add_ps(_mm_add_ps(U, V), W);
  __m128 reject =
      _mm_or_ps(unused, _mm_or_ps(_mm_and_ps(any_neg, any_pos), _mm_cmpeq_ps(det, zero)));
  if (_mm_movemask_ps(reject) == 0xF) return 0;
  const __m128 az = _mm_mul_ps(r.sz, A[2]), bz = _mm_mul_ps(r.sz, B[2]),
               cz = _mm_mul_ps(r.sz, C[2]);
  const __m128 T = _mm_add_ps(_mm_add_ps(_mm_mul_ps(U, az), _mm_mul_ps(V, bz)), _mm_mul_ps(W, cz));
  const __m128 tmax_det = _mm_mul_ps(_mm_set1_ps(tmax), det);
  const __m128 neg = _mm_cmplt_ps(det, zero);
  // det < 0 ? (T >= 0 || T < tmax det) : (T <= 0 || T > tmax det)
  const __m128 out_neg = _mm_or_ps(_mm_cmpge_ps(T, zero), _mm_cmplt_ps(T, tmax_det));
  const __m128 out_pos = _mm_or_ps(_mm_cmple_ps(T, zero), _mm_cmpgt_ps(T, tmax_det));
  reject = _mm_or_ps(reject, _mm_or_ps(_mm_and_ps(neg, out_neg), _mm_andnot_ps(neg, out_pos)));
  if (_mm_movemask_ps(reject) == 0xF) return 0;
  const __m128 inv_det = _mm_div_ps(_mm_set1_ps(1.0f), det);
  const __m128 t = _mm_mul_ps(T, inv_det);
  const __m128 ok =
      _mm_andnot_ps(reject, _mm_and_ps(_mm_cmpgt_ps(t, zero), _mm_cmplt_ps(t, _mm_set1_ps(tmax))));
  *t_out = t;
  *b1_out = _mm_mul_ps(V, inv_det);
  *b2_out = _mm_mul_ps(W, inv_det);
  return _mm_movemask_ps(ok);
}

inline int lowest_lane(int mask) {
  return __builtin_ctz(unsigned(mask));
}

// Tests a leaf; returns true when an any-hit query may stop.
template <bool kAnyHit>
inline bool leaf_hit(const TraceView& s, const Ray& ray, const SimdRay& r, const CpuLeaf& leaf,
                     uint32_t skip, uint32_t skip2, float& tmax, Hit& hit) {
  const CpuBvhView& b = s.cpu_bvh;
  for (uint32_t i = 0; i < leaf.packet_count; ++i) {
    const CpuTriPacket& p = b.packets[leaf.first_packet + i];
    __m128 tv, b1v, b2v;
    const int mask = triangles_hit(p, r, tmax, skip, skip2, &tv, &b1v, &b2v);
    if (!mask) continue;
    alignas(16) float t[4], b1[4], b2[4];
    _mm_store_ps(t, tv);
    int best = lowest_lane(mask);
    if (!kAnyHit) {  // the nearest lane; the first of equals, as a sequential loop keeps it
      for (int l = best + 1; l < 4; ++l)
        if ((mask >> l & 1) && t[l] < t[best]) best = l;
    }
    _mm_store_ps(b1, b1v);
    _mm_store_ps(b2, b2v);
    tmax = t[best];
    hit.t = t[best];
    hit.prim = p.prim[best];
    hit.u = b1[best];
    hit.v = b2[best];
    if (kAnyHit) return true;
  }
  for (uint32_t i = 0; i < leaf.sphere_count; ++i) {
    const uint32_t prim = b.sphere_prims[leaf.first_sphere + i];
    if (prim == skip || prim == skip2) continue;
    const Sphere sph = s.spheres[prim - s.tri_count];
    float t;
    if (intersect_sphere(ray, sph.center, sph.radius, tmax, t)) {
      tmax = t;
      hit.t = t;
      hit.prim = prim;
      hit.u = hit.v = 0.0f;
      if (kAnyHit) return true;
    }
  }
  return false;
}

// Depth-first traversal: each step tests the four boxes of a node, goes on with the nearest child
// hit (closest-hit queries) or the first (any-hit), and pushes the others, farthest first.
template <bool kAnyHit>
Hit traverse_simd(const TraceView& s, const Ray& ray, uint32_t skip, uint32_t skip2) {
  Hit hit;
  if (s.node_count == 0 || !ray_is_traceable(ray)) return hit;  // as traversal_start decides
  const vec3 inv_d = 1.0f / ray.d;
  const RayTriSetup setup(ray, inv_d);
  const SimdRay r(ray, inv_d, setup);
  float tmax = ray.tmax;
  // Closest-hit entries carry their box's entry distance: an entry that a nearer hit has since
  // put beyond reach (by the test of boxes_hit, widening included) is dropped when popped.
  uint32_t stack[kBvhStackSize];
  float stack_d[kBvhStackSize];
  int sp = 0;
  uint32_t ref = 0;
  const float widen = 1.0f + 2.0f * gamma_bound(3);
  for (;;) {
    if (!is_leaf_ref(ref)) {
      const CpuBvhNode& n = s.cpu_bvh.nodes[ref];
      __m128 tn;
      int mask = boxes_hit(n, r, tmax, &tn);
      if (mask) {
        if ((mask & (mask - 1)) == 0 || kAnyHit) {  // one child hit, or any order will do
          ref = n.ref[lowest_lane(mask)];
          for (mask &= mask - 1; mask; mask &= mask - 1) {
            stack_d[sp] = 0.0f;
            stack[sp++] = n.ref[lowest_lane(mask)];
          }
          continue;
        }
        alignas(16) float d[4];
        _mm_store_ps(d, tn);
        // Sort the hit children by distance, nearest first (insertion sort of at most four).
        float ds[4];
        uint32_t rs[4];
        int m = 0;
        for (; mask; mask &= mask - 1) {
          const int l = lowest_lane(mask);
          int j = m++;
          for (; j > 0 && ds[j - 1] > d[l]; --j) {
            ds[j] = ds[j - 1];
            rs[j] = rs[j - 1];
          }
          ds[j] = d[l];
          rs[j] = n.ref[l];
        }
        for (int j = m - 1; j > 0; --j) {
          stack_d[sp] = ds[j];
          stack[sp++] = rs[j];
        }
        ref = rs[0];
        continue;
      }
    } else if (leaf_hit<kAnyHit>(s, ray, r, s.cpu_bvh.leaves[ref & ~kBvhLeafBit], skip, skip2, tmax,
                                 hit)) {
      return hit;
    }
    do {
      if (sp == 0) return hit;
      --sp;
    } while (!kAnyHit && stack_d[sp] > tmax * widen);
    ref = stack[sp];
  }
}

}  // namespace

TRACER_CPU_MULTIVERSION Hit cpu_intersect_closest(const TraceView& s, const Ray& ray,
                                                  uint32_t skip, uint32_t skip2) {
  return traverse_simd<false>(s, ray, skip, skip2);
}

TRACER_CPU_MULTIVERSION Hit cpu_intersect_any(const TraceView& s, const Ray& ray, uint32_t skip,
                                              uint32_t skip2) {
  return traverse_simd<true>(s, ray, skip, skip2);
}

#else  // no SSE: never called, since build_cpu_bvh leaves the view empty

Hit cpu_intersect_closest(const TraceView&, const Ray&, uint32_t, uint32_t) {
  return Hit();
}
Hit cpu_intersect_any(const TraceView&, const Ray&, uint32_t, uint32_t) {
  return Hit();
}

#endif

}  // namespace tracer
