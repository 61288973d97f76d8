"""Converts one of the project's JSON scenes for Embree's tutorial path tracer (Debian
embree-tools, /usr/bin/pathtracer): an OBJ + MTL of the non-emitting triangles, and an XML scene
that includes the OBJ and turns every emissive quad into a <QuadLight>. Prints the matching
command-line options (camera, size) on stdout.

  python3 scripts/peers/embree_scene.py SCENE.json OUT_DIR

Why emitters become lights and not geometry: that path tracer takes light only from its light
list (next-event estimation); emissive materials are not read, and an area light is not hit by
camera or bounce rays, so the emitter itself renders black (here: the ceiling shows through it).
The limits this leaves are listed in docs/BENCHMARKS.md ("Peers").
"""

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import scene_json  # noqa: E402


def is_quad(mesh):
    return len(mesh["vertices"]) == 4 and len(mesh["triangles"]) == 2


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: embree_scene.py SCENE.json OUT_DIR")
    sc = scene_json.load(sys.argv[1])
    out = sys.argv[2]
    os.makedirs(out, exist_ok=True)
    lights = []
    with open(os.path.join(out, "scene.mtl"), "w") as f:
        for name, m in sc.materials.items():
            f.write("newmtl %s\nKd %g %g %g\nKs 0 0 0\nNs 1\nd 1\n\n"
                    % (name.replace(" ", "_"), *m["albedo"]))
    with open(os.path.join(out, "scene.obj"), "w") as f:
        f.write("mtllib scene.mtl\n")
        base = 1
        for mesh in sc.meshes:
            m = sc.materials[mesh["material"]]
            if any(c > 0 for c in m["emission"]):
                if not is_quad(mesh):
                    sys.exit("embree_scene.py: emitter %r is not a quad" % mesh["name"])
                lights.append((mesh, m))
                continue
            f.write("o %s\nusemtl %s\n" % (mesh["name"].replace(" ", "_"),
                                           mesh["material"].replace(" ", "_")))
            for v in mesh["vertices"]:
                f.write("v %.9g %.9g %.9g\n" % v)
            for t in mesh["triangles"]:
                f.write("f %d %d %d\n" % tuple(base + i for i in t))
            base += len(mesh["vertices"])
    if sc.spheres:
        sys.exit("embree_scene.py: spheres are not converted")
    with open(os.path.join(out, "scene.xml"), "w") as f:
        f.write('<?xml version="1.0"?>\n<scene>\n  <extern src="scene.obj"/>\n')
        for mesh, m in lights:
            p0, p1, _, p3 = mesh["vertices"]
            e1 = [p1[i] - p0[i] for i in range(3)]
            e2 = [p3[i] - p0[i] for i in range(3)]
            # The loader maps (0,0,0) -> p0, (1,0,0) -> p0 + vx, (0,1,0) -> p0 + vy; the columns
            # of the 3x4 row-major body are vx, vy, vz, translation. vx = edge2 and vy = edge1
            # make Embree's one-sided emission go along cross(edge1, edge2), as in the project.
            vz = [0.0, 0.0, 0.0]
            rows = [[e2[r], e1[r], vz[r], p0[r]] for r in range(3)]
            f.write("  <QuadLight>\n    <AffineSpace>%s</AffineSpace>\n    <L>%g %g %g</L>\n"
                    "  </QuadLight>\n" % ("  ".join(" ".join("%.9g" % x for x in row)
                                                    for row in rows), *m["emission"]))
            if m["two_sided"]:
                print("embree_scene.py: note: %r is two-sided; Embree's QuadLight is one-sided"
                      % mesh["name"], file=sys.stderr)
        f.write("</scene>\n")
    cam = sc.camera
    args = ["--vp", *cam["position"], "--vi", *cam["look_at"], "--vu", *cam["up"],
            "--fov", cam["vfov"], "--righthanded"]
    print(" ".join(str(a) for a in args))


main()
