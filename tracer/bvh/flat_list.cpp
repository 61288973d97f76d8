// Builds the flat primitive list (bvh/flat_list.h): pairs triangles into parallelograms and
// inverts each entry's frame in double precision.
#include "bvh/flat_list.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

namespace tracer {
namespace {

struct DVec {
  double x, y, z;
};
DVec dv(vec3 v) { return {v.x, v.y, v.z}; }
DVec sub(DVec a, DVec b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
DVec cross(DVec a, DVec b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(DVec a, DVec b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
double length(DVec a) { return std::sqrt(dot(a, a)); }

// The map world -> (u, v, w) of the frame p0 + u e1 + v e2 + w (e1 x e2); false if degenerate.
bool make_prim(vec3 p0, vec3 p1, vec3 p2, FlatPrim& out) {
  const DVec o = dv(p0), e1 = sub(dv(p1), o), e2 = sub(dv(p2), o);
  const DVec n = cross(e1, e2);
  const double det = dot(n, n);  // det [e1 e2 n] = |e1 x e2|^2
  if (!(det > 0.0) || !std::isfinite(det)) return false;
  const DVec ru = cross(e2, n), rv = cross(n, e1);
  auto row = [&](DVec r) {
    const DVec s = {r.x / det, r.y / det, r.z / det};
    return vec4(float(s.x), float(s.y), float(s.z), float(-dot(s, o)));
  };
  out.row_u = row(ru);
  out.row_v = row(rv);
  out.row_w = row(n);
  return true;
}

// Barycentrics (b1, b2) of a point (u, v) in the triangle whose corners have local coordinates
// c[0..2] (in the triangle's own vertex order), as an affine map of (u, v).
void barycentric_map(const vec2 c[3], float m[6]) {
  const double e00 = c[1].x - c[0].x, e10 = c[1].y - c[0].y;
  const double e01 = c[2].x - c[0].x, e11 = c[2].y - c[0].y;
  const double det = e00 * e11 - e01 * e10;
  const double m0 = e11 / det, m1 = -e01 / det, m3 = -e10 / det, m4 = e00 / det;
  m[0] = float(m0);
  m[1] = float(m1);
  m[2] = float(-(m0 * c[0].x + m1 * c[0].y));
  m[3] = float(m3);
  m[4] = float(m4);
  m[5] = float(-(m3 * c[0].x + m4 * c[0].y));
}

const vec3& corner(const TriangleVerts& t, int k) { return k == 0 ? t.v0 : (k == 1 ? t.v1 : t.v2); }

// If triangles a and b share an edge and form a parallelogram, its corner p (a's vertex off the
// shared edge) and the shared corners q, r, in a's winding order p -> q -> r.
bool parallelogram(const TriangleVerts& a, const TriangleVerts& b, int& ip, int& iq, int& ir,
                   int& is) {
  int shared_a[3] = {-1, -1, -1};  // for each corner of a, the equal corner of b
  int count = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (corner(a, i) == corner(b, j)) {
        shared_a[i] = j;
        ++count;
      }
  if (count != 2) return false;
  ip = shared_a[0] < 0 ? 0 : (shared_a[1] < 0 ? 1 : 2);
  iq = (ip + 1) % 3;
  ir = (ip + 2) % 3;
  is = 3 - shared_a[iq] - shared_a[ir];
  const DVec p = dv(corner(a, ip)), q = dv(corner(a, iq)), r = dv(corner(a, ir));
  const DVec s = dv(corner(b, is));
  const DVec want = {q.x + r.x - p.x, q.y + r.y - p.y, q.z + r.z - p.z};
  const double size = std::max(length(sub(q, p)), length(sub(r, p)));
  return length(sub(s, want)) <= 1e-5 * size;
}

// Whether the plane of triangle (p0, p1, p2) has every vertex and sphere of the scene, and every
// point light, on one side, within kFlatHullTolerance of the scene's size.
bool on_hull(vec3 p0, vec3 p1, vec3 p2, const std::vector<TriangleVerts>& tris,
             const std::vector<Sphere>& spheres, const std::vector<vec3>& points, double size) {
  const DVec o = dv(p0);
  DVec n = cross(sub(dv(p1), o), sub(dv(p2), o));
  const double len = length(n);
  if (!(len > 0.0)) return false;
  n = {n.x / len, n.y / len, n.z / len};
  const double tol = kFlatHullTolerance * size;
  bool above = false, below = false;
  auto see = [&](DVec p, double r) {
    const double d = dot(n, sub(p, o));
    above |= d + r > tol;
    below |= d - r < -tol;
  };
  for (const TriangleVerts& t : tris) {
    see(dv(t.v0), 0.0);
    see(dv(t.v1), 0.0);
    see(dv(t.v2), 0.0);
  }
  for (const Sphere& sp : spheres) see(dv(sp.center), double(sp.radius));
  for (const vec3& p : points) see(dv(p), 0.0);
  return !(above && below);
}

}  // namespace

std::string describe_flat_list(const FlatList& list, uint32_t sphere_count) {
  const size_t entries = list.prims.size();
  const size_t hull = (list.quad_count - list.quad_blockers) +
                      (entries - list.triangle_blockers_end);
  std::string solids;
  if (!list.solids.empty())
    solids = "; " + std::to_string(6 * list.solids.size()) + " the faces of " +
             std::to_string(list.solids.size()) +
             (list.solids.size() == 1 ? " solid box" : " solid boxes");
  return std::to_string(entries) + " entries (" + std::to_string(list.quad_count) + " quads, " +
         std::to_string(entries - list.quad_count) + " triangles; " + std::to_string(hull) +
         " on the hull, " + std::to_string(list.box_faces) + " of them box faces" + solids +
         ") + " + std::to_string(sphere_count) + " spheres";
}

FlatList build_flat_list(const std::vector<TriangleVerts>& tris, const std::vector<Sphere>& spheres,
                         bool open, const std::vector<vec3>& light_points) {
  FlatList out;
  const size_t n = tris.size();
  const size_t sphere_count = spheres.size();
  // Each entry is at least one triangle test, each sphere two: larger scenes cannot qualify.
  if (n + 2 * size_t(sphere_count) > 2 * size_t(kFlatMaxCost) || n + sphere_count == 0)
    return out;
  std::vector<FlatPrim> quads, singles;
  std::vector<FlatPrimInfo> quad_info, single_info;
  // Each entry's class: 0 a blocker, 1 on the hull, 2 (quads, below) a face of the scene's box.
  std::vector<int> quad_class, single_class;
  std::vector<std::array<DVec, 4>> quad_corners;  // p, q, r, q + r - p of each quad
  // The scene's size, for the hull test's tolerance.
  DVec lo = {1e300, 1e300, 1e300}, hi = {-1e300, -1e300, -1e300};
  auto grow = [&](DVec p, double r) {
    lo = {std::min(lo.x, p.x - r), std::min(lo.y, p.y - r), std::min(lo.z, p.z - r)};
    hi = {std::max(hi.x, p.x + r), std::max(hi.y, p.y + r), std::max(hi.z, p.z + r)};
  };
  for (const TriangleVerts& t : tris) {
    grow(dv(t.v0), 0.0);
    grow(dv(t.v1), 0.0);
    grow(dv(t.v2), 0.0);
  }
  for (const Sphere& sp : spheres) grow(dv(sp.center), double(sp.radius));
  const double size = length(sub(hi, lo));
  std::vector<bool> used(n, false);
  std::vector<uint32_t> entry_of(n, kInvalid);  // before quads and singles are joined
  std::vector<bool> is_single(n, false);
  uint32_t degenerate = 0;
  for (size_t i = 0; i < n; ++i) {
    if (used[i]) continue;
    used[i] = true;
    FlatPrim probe;
    if (!make_prim(tris[i].v0, tris[i].v1, tris[i].v2, probe)) {
      ++degenerate;
      continue;
    }
    bool paired = false;
    for (size_t j = i + 1; j < n && !paired; ++j) {
      int ip, iq, ir, is;
      if (used[j] || !parallelogram(tris[i], tris[j], ip, iq, ir, is)) continue;
      FlatPrim fp;
      if (!make_prim(corner(tris[i], ip), corner(tris[i], iq), corner(tris[i], ir), fp)) continue;
      FlatPrimInfo fi{};
      fi.tri0 = uint32_t(i);
      fi.tri1 = uint32_t(j);
      // Local coordinates: p (0,0), q (1,0), r (0,1), s (1,1).
      vec2 ca[3], cb[3];
      ca[ip] = vec2(0, 0);
      ca[iq] = vec2(1, 0);
      ca[ir] = vec2(0, 1);
      for (int k = 0; k < 3; ++k) {
        const vec3& v = corner(tris[j], k);
        cb[k] = k == is ? vec2(1, 1) : (v == corner(tris[i], iq) ? vec2(1, 0) : vec2(0, 1));
      }
      barycentric_map(ca, fi.map0);
      barycentric_map(cb, fi.map1);
      used[j] = true;
      entry_of[i] = entry_of[j] = uint32_t(quads.size());
      quad_class.push_back(
          open ? 0
               : on_hull(tris[i].v0, tris[i].v1, tris[i].v2, tris, spheres, light_points, size));
      {
        const DVec p = dv(corner(tris[i], ip)), q = dv(corner(tris[i], iq)),
                   r = dv(corner(tris[i], ir));
        quad_corners.push_back({p, q, r, {q.x + r.x - p.x, q.y + r.y - p.y, q.z + r.z - p.z}});
      }
      fp.row_u.w -= 0.5f;  // centred: the inside test is |u|, |v| <= 1/2
      fp.row_v.w -= 0.5f;
      quads.push_back(fp);
      quad_info.push_back(fi);
      paired = true;
    }
    if (!paired) {
      FlatPrimInfo fi{};
      fi.tri0 = uint32_t(i);
      fi.tri1 = kInvalid;
      const float identity[6] = {1, 0, 0, 0, 1, 0};
      std::copy(identity, identity + 6, fi.map0);
      std::copy(identity, identity + 6, fi.map1);
      entry_of[i] = uint32_t(singles.size());
      is_single[i] = true;
      single_class.push_back(
          open ? 0
               : on_hull(tris[i].v0, tris[i].v1, tris[i].v2, tris, spheres, light_points, size));
      singles.push_back(probe);
      single_info.push_back(fi);
    }
  }
  const size_t entries = quads.size() + singles.size();
  if (entries + 2 * size_t(sphere_count) > kFlatMaxCost) return out;
  // A hull quad that covers a face of the scene's box exactly (its four corners are the face's,
  // within the hull tolerance) becomes class 2; the first quad per face.
  const double tol = kFlatHullTolerance * size;
  const double blo[3] = {lo.x, lo.y, lo.z}, bhi[3] = {hi.x, hi.y, hi.z};
  const bool solid = size > 0.0 && bhi[0] - blo[0] > tol && bhi[1] - blo[1] > tol &&
                     bhi[2] - blo[2] > tol;
  int face_quad[6] = {-1, -1, -1, -1, -1, -1};
  for (size_t k = 0; k < quads.size(); ++k) {
    if (quad_class[k] != 1 || !solid) continue;
    for (int f = 0; f < 6 && quad_class[k] == 1; ++f) {
      const int a = f / 2, b = (a + 1) % 3, c = (a + 2) % 3;
      const double plane = f % 2 ? bhi[a] : blo[a];
      bool on_face = true;
      int seen = 0;  // which of the face's four corners the quad's corners are
      for (const DVec& v : quad_corners[k]) {
        const double x[3] = {v.x, v.y, v.z};
        const bool at_b_lo = std::fabs(x[b] - blo[b]) <= tol, at_b_hi = std::fabs(x[b] - bhi[b]) <= tol;
        const bool at_c_lo = std::fabs(x[c] - blo[c]) <= tol, at_c_hi = std::fabs(x[c] - bhi[c]) <= tol;
        on_face = on_face && std::fabs(x[a] - plane) <= tol && (at_b_lo || at_b_hi) &&
                  (at_c_lo || at_c_hi);
        seen |= 1 << (int(at_b_hi) * 2 + int(at_c_hi));
      }
      if (on_face && seen == 15 && face_quad[f] < 0) {
        face_quad[f] = int(k);
        quad_class[k] = 2;
      }
    }
  }
  // Solid boxes: six quads (blockers or hull quads, not box faces) that close a parallelepiped,
  // each face in the order of the solid's local axes (FlatList::solids).
  std::vector<std::array<uint32_t, 6>> solid_faces;
  std::vector<FlatPrim> solids;
  {
    std::vector<bool> in_solid(quads.size(), false);
    // Blockers and hull quads (a block's bottom lies in the floor's plane), not box faces.
    auto free_blocker = [&](size_t k) { return quad_class[k] != 2 && !in_solid[k]; };
    // Whether every corner of a is one of b's (within tol); both ways: the same four points.
    auto covered = [&](const std::array<DVec, 4>& a, const std::array<DVec, 4>& b) {
      for (const DVec& x : a) {
        bool found = false;
        for (const DVec& y : b) found = found || length(sub(x, y)) <= tol;
        if (!found) return false;
      }
      return true;
    };
    auto same = [&](const std::array<DVec, 4>& a, const std::array<DVec, 4>& b) {
      return covered(a, b) && covered(b, a);
    };
    auto add = [](DVec a, DVec b) { return DVec{a.x + b.x, a.y + b.y, a.z + b.z}; };
    auto find_free = [&](const std::array<DVec, 4>& want, size_t not1, size_t not2) -> int {
      for (size_t k = 0; k < quads.size(); ++k)
        if (k != not1 && k != not2 && free_blocker(k) && same(quad_corners[k], want))
          return int(k);
      return -1;
    };
    for (size_t a = 0; a < quads.size() && solids.size() < kFlatMaxSolids; ++a) {
      if (!free_blocker(a)) continue;
      const auto& c = quad_corners[a];  // p, q, r, s = q + r - p
      const DVec p = c[0], q = c[1], r = c[2], s4 = c[3];
      const DVec e1 = sub(q, p), e2 = sub(r, p), n = cross(e1, e2);
      const double n_len = length(n);
      for (size_t b = 0; b < quads.size(); ++b) {
        if (b == a || !free_blocker(b)) continue;
        bool done = false;
        for (const DVec& cb : quad_corners[b]) {
          // The opposite face: quad a moved by e3 (off its plane), corner p onto cb.
          const DVec e3 = sub(cb, p);
          if (!(std::fabs(dot(e3, n)) > tol * n_len)) continue;
          if (!same({add(p, e3), add(q, e3), add(r, e3), add(s4, e3)}, quad_corners[b])) continue;
          // The four sides, in the order of the local axes: e1 low / high, e2 low / high.
          const std::array<DVec, 4> sides[4] = {{p, r, add(p, e3), add(r, e3)},
                                                {q, s4, add(q, e3), add(s4, e3)},
                                                {p, q, add(p, e3), add(q, e3)},
                                                {r, s4, add(r, e3), add(s4, e3)}};
          std::array<uint32_t, 6> faces{};
          bool all = true;
          for (int k = 0; k < 4 && all; ++k) {
            const int f = find_free(sides[k], a, b);
            // A quad cannot be two sides (the sides are distinct planes).
            for (int j = 0; j < k && f >= 0; ++j) all = all && faces[size_t(j)] != uint32_t(f);
            all = all && f >= 0;
            if (all) faces[size_t(k)] = uint32_t(f);
          }
          if (!all) continue;
          faces[4] = uint32_t(a);
          faces[5] = uint32_t(b);
          // World -> centred local coordinates: x = p + (l0 + 1/2) e1 + (l1 + 1/2) e2 +
          // (l2 + 1/2) e3, through the inverse of [e1 e2 e3] (its rows: the cross products of
          // the other two columns over the determinant).
          const double det = dot(e1, cross(e2, e3));
          const DVec rows[3] = {cross(e2, e3), cross(e3, e1), cross(e1, e2)};
          FlatPrim m;
          vec4* out_rows[3] = {&m.row_u, &m.row_v, &m.row_w};
          for (int k = 0; k < 3; ++k) {
            const DVec rk = {rows[k].x / det, rows[k].y / det, rows[k].z / det};
            *out_rows[k] = vec4(float(rk.x), float(rk.y), float(rk.z), float(-dot(rk, p) - 0.5));
          }
          for (uint32_t f : faces) in_solid[f] = true;
          solid_faces.push_back(faces);
          solids.push_back(m);
          done = true;
          break;
        }
        if (done) break;
      }
    }
  }
  // Each group's blockers first (solids' faces at the very front, six per solid in face order),
  // then its hull entries, box faces last (stable otherwise).
  std::vector<int> solid_slot(quads.size(), -1);  // quad -> its position among solid faces
  for (size_t g = 0; g < solid_faces.size(); ++g)
    for (int f = 0; f < 6; ++f) solid_slot[solid_faces[g][size_t(f)]] = int(6 * g) + f;
  const uint32_t solid_entries = uint32_t(6 * solid_faces.size());
  auto order = [&](const std::vector<int>& cls, bool quads_group, uint32_t& blockers,
                   uint32_t& faces) {
    std::vector<uint32_t> perm;  // new position -> old
    if (quads_group) {
      perm.resize(solid_entries);
      for (uint32_t k = 0; k < cls.size(); ++k)
        if (solid_slot[k] >= 0) perm[uint32_t(solid_slot[k])] = k;
    }
    blockers = uint32_t(perm.size());  // the solids' faces are blockers, whatever their class
    for (int pass = 0; pass < 3; ++pass)
      for (uint32_t k = 0; k < cls.size(); ++k)
        if (cls[k] == pass && !(quads_group && solid_slot[k] >= 0)) {
          perm.push_back(k);
          if (pass == 0) ++blockers;
        }
    faces = uint32_t(std::count(cls.begin(), cls.end(), 2));
    std::vector<uint32_t> where(perm.size());  // old -> new
    for (uint32_t k = 0; k < perm.size(); ++k) where[perm[k]] = k;
    return std::make_pair(perm, where);
  };
  uint32_t quad_blockers = 0, single_blockers = 0, box_faces = 0, no_faces = 0;
  const auto [quad_perm, quad_where] = order(quad_class, true, quad_blockers, box_faces);
  const auto [single_perm, single_where] = order(single_class, false, single_blockers, no_faces);
  out.solids = solids;
  out.box_faces = box_faces;
  for (int a = 0; a < 3; ++a) {
    out.box_lo[a] = float(blo[a]);
    out.box_hi[a] = float(bhi[a]);
  }
  for (int f = 0; f < 6; ++f)
    out.box_entry[f] = face_quad[f] < 0 ? kInvalid : quad_where[uint32_t(face_quad[f])];
  out.quad_count = uint32_t(quads.size());
  out.quad_blockers = quad_blockers;
  out.triangle_blockers_end = out.quad_count + single_blockers;
  out.degenerate = degenerate;
  for (uint32_t k : quad_perm) {
    out.prims.push_back(quads[k]);
    out.info.push_back(quad_info[k]);
  }
  for (uint32_t k : single_perm) {
    out.prims.push_back(singles[k]);
    out.info.push_back(single_info[k]);
  }
  out.tri_to_flat.assign(n, kInvalid);
  for (size_t i = 0; i < n; ++i)
    if (entry_of[i] != kInvalid)
      out.tri_to_flat[i] = is_single[i] ? out.quad_count + single_where[entry_of[i]]
                                        : quad_where[entry_of[i]];
  out.enabled = true;
  return out;
}

}  // namespace tracer
