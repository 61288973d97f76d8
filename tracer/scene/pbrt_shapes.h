// pbrt-v4 shapes as triangles in their object space: one function per shape. Texture coordinates
// come out in our convention (v down the image: pbrt's image textures flip v, so ours is 1 - v).
#pragma once

#include "scene/loader_util.h"
#include "scene/pbrt_params.h"

namespace tracer {

// "trianglemesh": P, indices (optional for a single triangle), N, uv.
MeshPart pbrt_trianglemesh(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings);
// "bilinearmesh": patches of 4 vertices (p00 p10 p01 p11), split into two triangles each.
MeshPart pbrt_bilinearmesh(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings);
// "loopsubdiv": the control mesh, not subdivided (the caller warns).
MeshPart pbrt_loopsubdiv(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings);
// Tessellations of the quadrics, with their analytic normals: a sphere cut at zmin/zmax and
// phimax (degrees), a disk (or annulus) at z = height facing +z, an open cylinder along z.
MeshPart pbrt_sphere_mesh(float radius, float zmin, float zmax, float phimax_deg);
MeshPart pbrt_disk_mesh(float height, float radius, float inner_radius, float phimax_deg);
MeshPart pbrt_cylinder_mesh(float radius, float zmin, float zmax, float phimax_deg);

// Winds every triangle the way pbrt orients its surface (the side a one-sided area light emits
// to): towards the vertex normals when there are any, else counter-clockwise (pbrt's normal is
// cross(p1 - p0, p2 - p0)); ReverseOrientation (`reverse`) flips both the normals and the winding.
// append_part() keeps this orientation through mirroring transforms, as pbrt does.
void pbrt_orient(MeshPart& part, bool reverse);

}  // namespace tracer
