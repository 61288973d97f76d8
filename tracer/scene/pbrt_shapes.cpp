// pbrt-v4 shapes as triangle meshes in object space.
#include "scene/pbrt_shapes.h"

#include <algorithm>
#include <cmath>

#include "core/math.h"

namespace tracer {

namespace {

std::vector<vec3> triples(const std::vector<double>& v) {
  std::vector<vec3> out(v.size() / 3);
  for (size_t i = 0; i < out.size(); ++i)
    out[i] = vec3(float(v[3 * i]), float(v[3 * i + 1]), float(v[3 * i + 2]));
  return out;
}

// Positions, normals and uvs shared by the mesh shapes; drops N or uv (with a warning, as pbrt
// does) when their count does not match P's.
MeshPart mesh_vertices(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings) {
  MeshPart part;
  const std::vector<double>* pos = p.get_numbers("P", "point3");
  if (!pos) throw InputError(loc, p.owner() + " needs \"point3 P\"");
  part.positions = triples(*pos);
  const size_t n = part.positions.size();
  if (const std::vector<double>* normals = p.get_numbers("N", "normal")) {
    if (normals->size() / 3 == n)
      part.normals = triples(*normals);
    else
      warnings.warn(loc, "N count",
                    p.owner() + ": " + std::to_string(normals->size() / 3) + " normals \"N\" for " +
                        std::to_string(n) + " points \"P\"",
                    "ignored the normals");
  }
  // pbrt-v4 writes "point2 uv"; pbrt-v3 files have "float uv" or "float st" (pairs).
  const PbrtParam* uv = p.find("uv", {"point2", "float"});
  if (!uv) uv = p.find("st", {"point2", "float"});
  if (uv) {
    if (uv->numbers.size() / 2 == n && uv->numbers.size() % 2 == 0) {
      part.uvs.resize(n);
      for (size_t i = 0; i < n; ++i)
        part.uvs[i] = vec2(float(uv->numbers[2 * i]), 1.0f - float(uv->numbers[2 * i + 1]));
    } else {
      warnings.warn(loc, "uv count",
                    p.owner() + ": " + std::to_string(uv->numbers.size() / 2) +
                        " texture coordinates for " + std::to_string(n) + " points \"P\"",
                    "ignored the texture coordinates");
    }
  }
  p.ignore({"S", "faceIndices", "emission"});
  return part;
}

// "integer indices", `per` to a face; absent means one face of all the points when there are
// exactly `per` of them.
std::vector<uint32_t> mesh_indices(PbrtParams& p, const SourceLoc& loc, size_t points, size_t per) {
  const std::vector<double>* idx = p.get_numbers("indices", "integer");
  std::vector<uint32_t> out;
  if (!idx) {
    if (points != per)
      throw InputError(loc, p.owner() + " needs \"integer indices\" (it has " +
                                std::to_string(points) + " points, not " + std::to_string(per) +
                                ")");
    for (size_t i = 0; i < per; ++i) out.push_back(uint32_t(i));
    return out;
  }
  if (idx->size() % per != 0)
    throw InputError(loc, p.owner() + ": \"indices\" has " + std::to_string(idx->size()) +
                              " values, not a multiple of " + std::to_string(per));
  out.reserve(idx->size());
  for (size_t i = 0; i < idx->size(); ++i) {
    const double v = (*idx)[i];
    if (v < 0 || v >= double(points))
      throw InputError(loc, p.owner() + ": index " + std::to_string(int64_t(v)) + " (entry " +
                                std::to_string(i) + " of \"indices\") is out of range; \"P\" has " +
                                std::to_string(points) + " points");
    out.push_back(uint32_t(v));
  }
  return out;
}

int segments(float phimax_deg, int full) {
  return std::max(3, int(std::ceil(float(full) * std::min(phimax_deg, 360.0f) / 360.0f)));
}

}  // namespace

MeshPart pbrt_trianglemesh(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings) {
  MeshPart part = mesh_vertices(p, loc, warnings);
  const std::vector<uint32_t> idx = mesh_indices(p, loc, part.positions.size(), 3);
  for (size_t i = 0; i + 2 < idx.size(); i += 3)
    part.indices.push_back(uvec3(idx[i], idx[i + 1], idx[i + 2]));
  return part;
}

MeshPart pbrt_bilinearmesh(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings) {
  MeshPart part = mesh_vertices(p, loc, warnings);
  const std::vector<uint32_t> idx = mesh_indices(p, loc, part.positions.size(), 4);
  for (size_t i = 0; i + 3 < idx.size(); i += 4) {
    // Corners p00 p10 p01 p11; pbrt's normal is cross(p10 - p00, p01 - p00).
    part.indices.push_back(uvec3(idx[i], idx[i + 1], idx[i + 3]));
    part.indices.push_back(uvec3(idx[i], idx[i + 3], idx[i + 2]));
  }
  return part;
}

MeshPart pbrt_loopsubdiv(PbrtParams& p, const SourceLoc& loc, PbrtWarnings& warnings) {
  p.ignore({"levels"});
  return pbrt_trianglemesh(p, loc, warnings);
}

MeshPart pbrt_sphere_mesh(float radius, float zmin, float zmax, float phimax_deg) {
  MeshPart part;
  const float r = std::fabs(radius);
  const float z0 = glm::clamp(std::min(zmin, zmax), -r, r),
              z1 = glm::clamp(std::max(zmin, zmax), -r, r);
  const float theta_lo = std::acos(glm::clamp(z0 / r, -1.0f, 1.0f));  // near pi
  const float theta_hi = std::acos(glm::clamp(z1 / r, -1.0f, 1.0f));  // near 0
  const float phimax = glm::radians(glm::clamp(phimax_deg, 0.0f, 360.0f));
  const int nu = segments(phimax_deg, 96), nv = 48;
  for (int j = 0; j <= nv; ++j) {
    const float v = float(j) / float(nv);
    const float theta = theta_lo + v * (theta_hi - theta_lo);
    for (int i = 0; i <= nu; ++i) {
      const float u = float(i) / float(nu), phi = u * phimax;
      const vec3 n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                   std::cos(theta));
      part.positions.push_back(r * n);
      part.normals.push_back(n);
      part.uvs.push_back(vec2(u, 1.0f - v));
    }
  }
  const uint32_t row = uint32_t(nu + 1);
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const uint32_t a = uint32_t(j) * row + uint32_t(i), b = a + 1, c = a + row, d = c + 1;
      // Rows run from the bottom (-z) up, columns counter-clockwise about +z: (a, b, d) faces
      // out. At a pole one of the two triangles has collapsed to a line: left out.
      if (j > 0 || z0 > -r) part.indices.push_back(uvec3(a, b, d));
      if (j < nv - 1 || z1 < r) part.indices.push_back(uvec3(a, d, c));
    }
  }
  return part;
}

MeshPart pbrt_disk_mesh(float height, float radius, float inner_radius, float phimax_deg) {
  MeshPart part;
  const float phimax = glm::radians(glm::clamp(phimax_deg, 0.0f, 360.0f));
  const int nu = segments(phimax_deg, 96);
  const float ri = glm::clamp(inner_radius, 0.0f, radius);
  for (int ring = 0; ring < 2; ++ring) {
    const float rr = ring == 0 ? radius : ri;
    for (int i = 0; i <= nu; ++i) {
      const float u = float(i) / float(nu), phi = u * phimax;
      part.positions.push_back(vec3(rr * std::cos(phi), rr * std::sin(phi), height));
      part.normals.push_back(vec3(0.0f, 0.0f, 1.0f));
      // pbrt: v = (radius - r) / (radius - innerRadius), 0 at the rim.
      part.uvs.push_back(vec2(u, 1.0f - float(ring)));
    }
  }
  const uint32_t row = uint32_t(nu + 1);
  for (int i = 0; i < nu; ++i) {
    const uint32_t a = uint32_t(i), b = a + 1, c = a + row, d = c + 1;
    // Counter-clockwise seen from +z: rim (a, b) then the inner ring.
    part.indices.push_back(uvec3(a, b, d));
    if (ri > 0.0f) part.indices.push_back(uvec3(a, d, c));
  }
  return part;
}

MeshPart pbrt_cylinder_mesh(float radius, float zmin, float zmax, float phimax_deg) {
  MeshPart part;
  const float phimax = glm::radians(glm::clamp(phimax_deg, 0.0f, 360.0f));
  const int nu = segments(phimax_deg, 96);
  const float z0 = std::min(zmin, zmax), z1 = std::max(zmin, zmax);
  for (int ring = 0; ring < 2; ++ring) {
    for (int i = 0; i <= nu; ++i) {
      const float u = float(i) / float(nu), phi = u * phimax;
      const vec3 n(std::cos(phi), std::sin(phi), 0.0f);
      part.positions.push_back(vec3(radius * n.x, radius * n.y, ring == 0 ? z0 : z1));
      part.normals.push_back(n);
      part.uvs.push_back(vec2(u, 1.0f - float(ring)));
    }
  }
  const uint32_t row = uint32_t(nu + 1);
  for (int i = 0; i < nu; ++i) {
    const uint32_t a = uint32_t(i), b = a + 1, c = a + row, d = c + 1;
    part.indices.push_back(uvec3(a, b, d));
    part.indices.push_back(uvec3(a, d, c));
  }
  return part;
}

void pbrt_orient(MeshPart& part, bool reverse) {
  if (reverse)
    for (vec3& n : part.normals) n = -n;
  const bool normals = part.normals.size() == part.positions.size() && !part.normals.empty();
  for (uvec3& t : part.indices) {
    bool flip = reverse;
    if (normals) {
      const vec3 g = glm::cross(part.positions[t.y] - part.positions[t.x],
                                part.positions[t.z] - part.positions[t.x]);
      flip = glm::dot(g, part.normals[t.x] + part.normals[t.y] + part.normals[t.z]) < 0.0f;
    }
    if (flip) std::swap(t.y, t.z);
  }
}

}  // namespace tracer
