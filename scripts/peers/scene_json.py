"""Reads the project's JSON scene format (docs/SCENE_FORMAT.md) into plain Python data for the
peer renderers: camera, render settings, materials and objects flattened to world-space triangle
meshes or analytic spheres. Standard library only, so that both Blender's Python
(cycles_scene.py) and the system python3 (embree_scene.py) can import it.

Covered: sphere, box, quad and mesh (OBJ: v/f lines, fans) objects with the transform block
(scale, rotate X then Y then Z in degrees, translate, or a row-major matrix); diffuse materials
with emission, emission_strength and two_sided. Other material types are reported, not
approximated silently.
"""

import json
import math
import os

DEFAULT_CAMERA = {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov": 40.0,
                  "aperture": 0.0, "focus_distance": 0.0}
DEFAULT_RENDER = {"width": 512, "height": 512, "spp": 64, "max_depth": 8, "nee": True,
                  "mis": True, "russian_roulette": True, "rr_start_depth": 3, "seed": 0,
                  "jitter": True, "clamp": 0.0, "time_limit_s": 0.0}


# ---- 4x4 row-major matrices as lists of rows -------------------------------------------------

def mat_identity():
    return [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]


def mat_mul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def mat_translate(t):
    m = mat_identity()
    for i in range(3):
        m[i][3] = float(t[i])
    return m


def mat_scale(s):
    m = mat_identity()
    for i in range(3):
        m[i][i] = float(s[i])
    return m


def mat_rotate(axis, degrees):
    """Right-handed rotation about a coordinate axis (0 = x, 1 = y, 2 = z), as glm::rotate."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    m = mat_identity()
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[i][i], m[i][j], m[j][i], m[j][j] = c, -s, s, c
    return m


def xform_point(m, p):
    return tuple(m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3] for r in range(3))


def det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def read_transform(obj):
    """M = T * Rz * Ry * Rx * S, or the row-major "matrix" (docs/SCENE_FORMAT.md, transform)."""
    t = obj.get("transform")
    if not t:
        return mat_identity()
    if "matrix" in t:
        v = [float(x) for x in t["matrix"]]
        return [v[0:4], v[4:8], v[8:12], v[12:16]]
    s = t.get("scale", 1.0)
    s = [s, s, s] if isinstance(s, (int, float)) else s
    r = t.get("rotate", [0, 0, 0])
    m = mat_translate(t.get("translate", [0, 0, 0]))
    m = mat_mul(m, mat_rotate(2, r[2]))
    m = mat_mul(m, mat_rotate(1, r[1]))
    m = mat_mul(m, mat_rotate(0, r[0]))
    return mat_mul(m, mat_scale(s))


# ---- geometry -------------------------------------------------------------------------------

def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def quad_mesh(corner, e1, e2):
    """corner, corner + e1, corner + e1 + e2, corner + e2; normal cross(e1, e2), CCW."""
    v = [tuple(corner), add(corner, e1), add(add(corner, e1), e2), add(corner, e2)]
    return v, [(0, 1, 2), (0, 2, 3)]


def box_mesh(lo, hi):
    """12 triangles, 4 vertices per face, wound counter-clockwise seen from outside."""
    verts, tris = [], []
    for axis in range(3):
        for side in (0, 1):
            u, w = (axis + 1) % 3, (axis + 2) % 3
            if side == 0:  # the face at lo[axis], normal -axis: edges w then u
                u, w = w, u
            base = [0.0, 0.0, 0.0]
            base[axis] = (lo, hi)[side][axis]
            corners = []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                p = list(base)
                p[u] = (lo, hi)[a][u]
                p[w] = (lo, hi)[b][w]
                corners.append(tuple(p))
            n = len(verts)
            verts += corners
            tris += [(n, n + 1, n + 2), (n, n + 2, n + 3)]
    return verts, tris


def read_obj(path):
    """Positions and fan-triangulated faces of an OBJ file (materials ignored)."""
    verts, tris = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append(tuple(float(x) for x in parts[1:4]))
            elif parts[0] == "f":
                idx = []
                for c in parts[1:]:
                    i = int(c.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
    return verts, tris


class Scene:
    def __init__(self):
        self.camera = dict(DEFAULT_CAMERA)
        self.render = dict(DEFAULT_RENDER)
        self.materials = {}  # name -> {"type", "albedo", "emission" (x strength), "two_sided"}
        self.meshes = []     # {"name", "material", "vertices": [(x,y,z)], "triangles": [(i,j,k)]}
        self.spheres = []    # {"name", "material", "center": (x,y,z), "radius"}
        self.notes = []      # what a peer cannot represent exactly


def load(path):
    with open(path) as f:
        data = json.load(f)
    sc = Scene()
    sc.camera.update(data.get("camera", {}))
    sc.render.update(data.get("render", {}))
    for name, m in data.get("materials", {}).items():
        mtype = m.get("type", "diffuse")
        albedo = m.get("albedo", [1, 1, 1] if mtype == "dielectric" else [0.8, 0.8, 0.8])
        strength = float(m.get("emission_strength", 1.0))
        emission = [float(c) * strength for c in m.get("emission", [0, 0, 0])]
        sc.materials[name] = {"type": mtype, "albedo": [float(c) for c in albedo],
                              "emission": emission, "two_sided": bool(m.get("two_sided", False)),
                              "ior": float(m.get("ior", 1.5)),
                              "roughness": float(m.get("roughness", 0.0))}
        if mtype != "diffuse":
            sc.notes.append("material %r has type %r; only diffuse is mapped exactly" % (name, mtype))
    base = os.path.dirname(os.path.abspath(path))
    for i, o in enumerate(data["objects"]):
        kind = o["type"]
        name = o.get("name", "%s %d" % (kind, i))
        m = read_transform(o)
        mat = o.get("material")
        if kind == "sphere":
            c = xform_point(m, o.get("center", [0, 0, 0]))
            scale = math.sqrt(m[0][0] ** 2 + m[1][0] ** 2 + m[2][0] ** 2)
            sc.spheres.append({"name": name, "material": mat, "center": c,
                               "radius": float(o.get("radius", 1.0)) * scale})
            continue
        if kind == "quad":
            v, t = quad_mesh(o["corner"], o["edge1"], o["edge2"])
        elif kind == "box":
            v, t = box_mesh(o.get("min", [-0.5] * 3), o.get("max", [0.5] * 3))
        elif kind == "mesh":
            v, t = read_obj(os.path.join(base, o["file"]))
            if mat is None:
                mat = "__default_grey"
                sc.materials.setdefault(mat, {"type": "diffuse", "albedo": [0.8] * 3,
                                              "emission": [0.0] * 3, "two_sided": False,
                                              "ior": 1.5, "roughness": 0.0})
                sc.notes.append("mesh %r: the file's own materials are not read; grey" % name)
        else:
            raise ValueError("%s: object %r has unknown type %r" % (path, name, kind))
        v = [xform_point(m, p) for p in v]
        if det3(m) < 0:  # a mirroring transform keeps front faces front (as the loader does)
            t = [(a, c, b) for a, b, c in t]
        sc.meshes.append({"name": name, "material": mat, "vertices": v, "triangles": t})
    return sc


def camera_basis(cam):
    """forward, right, up of the project's camera: right = forward x up (camera.h)."""
    def sub(a, b):
        return (a[0] - b[0], a[1] - b[1], a[2] - b[2])

    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    def norm(a):
        n = math.sqrt(sum(x * x for x in a))
        return tuple(x / n for x in a)

    f = norm(sub(cam["look_at"], cam["position"]))
    r = norm(cross(f, cam["up"]))
    u = cross(r, f)
    return f, r, u
