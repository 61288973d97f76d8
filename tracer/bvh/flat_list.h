// The flat primitive list: for scenes of a few dozen primitives, every lane of a warp tests every
// primitive in the same order, instead of walking a BVH on its own path. Rays end their BVH walks
// at different steps, which leaves most lanes of a warp idle (docs/PERFORMANCE.md); a uniform
// loop keeps all 32 busy and loads each primitive once per warp (one address for all lanes). The
// loop is linear in the number of primitives, so only small scenes get one (kFlatMaxCost).
//
// Each entry is an affine map of world space onto a unit triangle or a unit square, the test of
// Woop ("A Ray Tracing Hardware Architecture for Dynamic Scenes", 2004) that Aila & Laine (2009)
// used on GPUs: three rows, each a dot product with the ray's origin and direction. Two
// triangles that share an edge and form a parallelogram (every quad and box face of a scene) are
// one entry, which halves the loop on such scenes; a hit is mapped back to the triangle and its
// barycentrics afterwards, once per query, so shading sees the same hit as from the BVH.
#pragma once

#include <string>
#include <vector>

#include "bvh/geometry.h"

namespace tracer {

// World -> local affine map: local k = dot(row[k].xyz, p) + row[k].w. Local (u, v) are the
// parametric coordinates over edges e1 = v1 - v0 and e2 = v2 - v0, for a parallelogram less
// 1/2 (centred, so that the inside test is |u|, |v| <= 1/2: two comparisons instead of four);
// w is the distance from the plane in units of |e1 x e2|. 48 bytes: three aligned 16-byte loads
// on the GPU.
struct alignas(16) FlatPrim {
  vec4 row_u, row_v, row_w;
};
static_assert(sizeof(FlatPrim) == 48, "FlatPrim must stay 48 bytes");

// Read once per query, for the nearest hit: which triangle(s) the entry stands for and the
// affine maps from (u, v) to each triangle's barycentrics (b1, b2) of its v1 and v2.
// For a lone triangle tri1 is kInvalid and map0 is the identity.
struct alignas(16) FlatPrimInfo {
  uint32_t tri0, tri1;
  uint32_t pad[2];
  float map0[6];  // b1 = map[0] u + map[1] v + map[2], b2 = map[3] u + map[4] v + map[5]
  float map1[6];  // for tri1, the half u + v > 1 of the square
};

// Parametric tolerance at the edges: a hit within 1e-5 of an edge's length outside a primitive
// still counts, so that rounding in the affine test cannot let a ray slip between two
// primitives that share an edge (the BVH path's watertight test needs no tolerance). Where two
// primitives overlap by it, the nearer hit wins as usual.
constexpr float kFlatEdgeTolerance = 1e-5f;

// Scenes whose entries cost at most this many triangle tests get a flat list (a sphere counts
// as two: its test is in double precision). Chosen from the instruction counts: a uniform test
// costs about 40 instructions per lane, and the BVH's closest-hit query on the Cornell box
// about 77 warp instructions per ray (docs/PERFORMANCE.md, decision log, row 33).
constexpr uint32_t kFlatMaxCost = 64;
// Solid boxes a list finds at most (FlatList::solids; further boxes stay six quads each).
constexpr uint32_t kFlatMaxSolids = 8;

// Entries on the scene's convex hull: an entry whose plane has the whole scene on one side (a
// wall, floor or ceiling of a room, within kFlatHullTolerance of the scene's size) cannot block a
// ray between two points of the scene, such as a shadow ray from a surface point to a light
// (both ends offset off their surfaces, towards each other). Each group (quads, triangles) puts
// its hull entries last, and the megakernel's shadow rays skip them: 5 of the open Cornell box's
// 18 quads.
constexpr double kFlatHullTolerance = 1e-6;

struct FlatList {
  std::vector<FlatPrim> prims;         // quads first, then lone triangles
  std::vector<FlatPrimInfo> info;      // one per entry
  std::vector<uint32_t> tri_to_flat;   // triangle -> its entry (kInvalid: degenerate)
  uint32_t quad_count = 0;             // entries [0, quad_count) are parallelograms
  // Entries [0, quad_blockers) and [quad_count, triangle_blockers_end) can block a ray between
  // two points of the scene; the rest of each group lie on the scene's hull.
  uint32_t quad_blockers = 0, triangle_blockers_end = 0;
  // Faces of the scene's bounding box that one quad covers exactly (the walls, floor and ceiling
  // of a room): the last box_faces quads, after the other hull quads. Queries find the face a ray
  // meets with one slab test of the box (traverse.h, flat_box_hit) instead of testing each.
  // box_entry[2 * axis + side] (side 0: the low face, 1: the high one) is the face's entry, or
  // kInvalid where the face is open (no entry covers it whole; what lies there is tested as usual).
  uint32_t box_faces = 0;
  float box_lo[3] = {0, 0, 0}, box_hi[3] = {0, 0, 0};
  uint32_t box_entry[6] = {kInvalid, kInvalid, kInvalid, kInvalid, kInvalid, kInvalid};
  // Solid boxes: six quads that close a parallelepiped (the Cornell box's blocks, any box object
  // rotated or sheared) are its faces, entries [6 g, 6 g + 6) of solid g, f = 2 * axis + side in
  // the order of solids[g]'s rows; solids[g] maps world space onto the centred unit cube (each
  // local coordinate in [-1/2, 1/2]), and queries find the face a ray meets with one slab test
  // in those coordinates (traverse.h, flat_solid_hit) instead of testing the six quads. The
  // loops over the quads start after them, at entry 6 * solids.size(). At most kFlatMaxSolids.
  std::vector<FlatPrim> solids;
  uint32_t degenerate = 0;             // triangles of zero area (no ray hits them)
  bool enabled = false;                // the scene is small enough (see kFlatMaxCost)
};

// "18 entries (18 quads, 0 triangles; 7 on the hull, 5 of them box faces) + 0 spheres", for
// `pathtracer info` and the GPU's specialisation string.
std::string describe_flat_list(const FlatList& list, uint32_t sphere_count);

// Builds the list for a scene of these triangles and spheres; `enabled` is false (and the arrays
// empty) when the scene is too large for it. `open`: shadow rays may leave the scene (lights at
// infinity), so no entry is on the hull (every one can block them) and there are no box faces.
// `light_points`: further points shadow rays end at (point and spot lights), which an entry's
// plane must also have on the scene's side for the entry to be on the hull.
FlatList build_flat_list(const std::vector<TriangleVerts>& tris, const std::vector<Sphere>& spheres,
                         bool open = false, const std::vector<vec3>& light_points = {});

}  // namespace tracer
