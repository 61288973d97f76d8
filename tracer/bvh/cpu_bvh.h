// The CPU backend's own copy of the BVH, laid out for SSE: each 4-wide node stores its children's
// boxes axis by axis (so one ray meets four boxes in six vector subtractions and multiplications)
// and each leaf's triangles are packed four to a packet (one watertight test for four
// triangles). This is the layout of Embree's BVH4 and triangle4 (Wald et al., "Embree: A Kernel
// Framework for Efficient CPU Ray Tracing", SIGGRAPH 2014); the GPU keeps the shared child-by-child
// layout of bvh.h, whose traversal holds fewer registers. Both are built from the same tree and
// compute bit-identical box and triangle tests, so they find the same hits.
#pragma once

#include <cstdint>
#include <vector>

#include "bvh/bvh.h"
#include "bvh/geometry.h"

namespace tracer {

// Boxes of the four children: lo x, lo y, lo z, hi x, hi y, hi z, four lanes each. A child
// reference as in bvh.h, except that a leaf reference holds the index of a CpuLeaf.
struct alignas(16) CpuBvhNode {
  float box[6][4];
  uint32_t ref[4];
};

// Up to four triangles: vertex k's axis a in v[3k + a], lane i; unused lanes have prim kInvalid.
struct alignas(16) CpuTriPacket {
  float v[9][4];
  uint32_t prim[4];
};

// A leaf: its triangles as packets, then its spheres (unified primitive ids).
struct CpuLeaf {
  uint32_t first_packet, packet_count;
  uint32_t first_sphere, sphere_count;
};

// What traversal reads; null `nodes` means "no CPU BVH: use the shared traversal".
struct CpuBvhView {
  const CpuBvhNode* nodes = nullptr;
  const CpuTriPacket* packets = nullptr;
  const CpuLeaf* leaves = nullptr;
  const uint32_t* sphere_prims = nullptr;
};

struct CpuBvh {
  std::vector<CpuBvhNode> nodes;
  std::vector<CpuTriPacket> packets;
  std::vector<CpuLeaf> leaves;
  std::vector<uint32_t> sphere_prims;
  CpuBvhView view() const;
};

// True when this build has the SIMD traversal (x86-64 with SSE2); elsewhere build_cpu_bvh
// returns an empty CpuBvh and the CPU backend uses the shared traversal.
bool cpu_bvh_supported();

// The CPU layout of `bvh`. Primitive ids below tri_count are triangles of `tris`.
CpuBvh build_cpu_bvh(const Bvh& bvh, const std::vector<TriangleVerts>& tris, uint32_t tri_count);

struct TraceView;
// Nearest hit / any hit in (0, ray.tmax) through the CPU layout, ignoring primitives skip and
// skip2, with the results of the shared traversal (traverse.h). Out of line on purpose: the
// shared traversal calls them from host code compiled by both g++ and nvcc, which must not see
// different inline bodies.
Hit cpu_intersect_closest(const TraceView& s, const Ray& ray, uint32_t skip, uint32_t skip2);
Hit cpu_intersect_any(const TraceView& s, const Ray& ray, uint32_t skip, uint32_t skip2);

}  // namespace tracer
