// Instances of meshes (the second level of the BVH): a mesh's triangles and tree are stored once
// in its own space, and each instance places it with an affine map. Rays enter an instance's
// mesh mapped into that space; distances along the ray stay the same (the direction is mapped
// too, not normalised), so hits from both levels compare directly.
#pragma once

#include "core/math.h"
#include "core/ray.h"

namespace tracer {

// 112 bytes: seven 16-byte loads on the GPU.
struct alignas(16) Instance {
  vec4 object_from_world[3];  // rows of the 3x4 affine map into the mesh's space
  vec4 world_from_object[3];  // rows of its inverse
  uint32_t root;              // the mesh's root node in TraceView::inst_nodes
  uint32_t tri_base;          // the mesh's first triangle in TraceView::inst_tri_verts
  uint32_t prim_base;         // the hit id of the mesh's first triangle under this instance
  uint32_t pad;
};
static_assert(sizeof(Instance) == 112, "Instance must stay 112 bytes");

TRACER_HD TRACER_INLINE vec3 affine_point(const vec4* rows, vec3 p) {
  return vec3(rows[0].x * p.x + rows[0].y * p.y + rows[0].z * p.z + rows[0].w,
              rows[1].x * p.x + rows[1].y * p.y + rows[1].z * p.z + rows[1].w,
              rows[2].x * p.x + rows[2].y * p.y + rows[2].z * p.z + rows[2].w);
}
TRACER_HD TRACER_INLINE vec3 affine_vector(const vec4* rows, vec3 v) {
  return vec3(rows[0].x * v.x + rows[0].y * v.y + rows[0].z * v.z,
              rows[1].x * v.x + rows[1].y * v.y + rows[1].z * v.z,
              rows[2].x * v.x + rows[2].y * v.y + rows[2].z * v.z);
}
// A normal of the mesh's space in the world: the inverse transpose of world_from_object, which
// is the transpose of object_from_world's linear part (not normalised).
TRACER_HD TRACER_INLINE vec3 instance_normal(const Instance& in, vec3 n) {
  const vec4* m = in.object_from_world;
  return vec3(m[0].x * n.x + m[1].x * n.y + m[2].x * n.z,
              m[0].y * n.x + m[1].y * n.y + m[2].y * n.z,
              m[0].z * n.x + m[1].z * n.y + m[2].z * n.z);
}

TRACER_HD TRACER_INLINE Instance load_instance(const Instance* instances, uint32_t i) {
#if defined(__CUDA_ARCH__)
  const float4* p = reinterpret_cast<const float4*>(instances + i);
  Instance in;
#pragma unroll
  for (int k = 0; k < 3; ++k) {
    const float4 a = __ldg(p + k), b = __ldg(p + 3 + k);
    in.object_from_world[k] = vec4(a.x, a.y, a.z, a.w);
    in.world_from_object[k] = vec4(b.x, b.y, b.z, b.w);
  }
  const uint4 c = __ldg(reinterpret_cast<const uint4*>(p + 6));
  in.root = c.x;
  in.tri_base = c.y;
  in.prim_base = c.z;
  in.pad = 0;
  return in;
#else
  return instances[i];
#endif
}

// The instance whose hit ids hold `prim` (>= the first instance's prim_base): the last one whose
// prim_base is <= prim, by binary search over the instances, which are in prim_base order.
TRACER_HD TRACER_INLINE uint32_t find_instance(const Instance* instances, uint32_t count,
                                               uint32_t prim) {
  uint32_t lo = 0, hi = count;  // the answer is in [lo, hi)
  while (hi - lo > 1) {
    const uint32_t mid = (lo + hi) / 2;
    if (instances[mid].prim_base <= prim)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}

}  // namespace tracer
