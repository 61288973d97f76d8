"""Builds one of the project's JSON scenes in Blender and renders it with Cycles on the CPU, for
the side-by-side comparison in docs/BENCHMARKS.md. Run headless:

  blender -b --factory-startup --python scripts/peers/cycles_scene.py -- SCENE.json \
      --width 512 --height 512 --max-depth 8 --threads 2 --seed 0 --spp 1,2,4 --out DIR/cycles

writes DIR/cycles_spp<N>.exr (linear, 32-bit float) for every sample count and DIR/cycles.json
with the time of each render. The time is wall time around bpy.ops.render.render() (scene sync,
BVH build and path tracing), measured inside one Blender process after a 1-sample warm-up, so
Blender's start-up and the scene building here are left out.

Settings chosen to match `pathtracer render` (see docs/BENCHMARKS.md, "Peers"):
- camera: same position, look-at, up and vertical field of view (sensor fit vertical);
- film: box pixel filter 1 px wide (the project jitters uniformly inside each pixel), Standard
  view transform, no denoising, no adaptive sampling, no clamping, no caustic blur, fixed seed;
- materials: Diffuse BSDF (Lambert at roughness 0) with the albedo; emission shader with
  strength 1 and colour = emission x emission_strength (Cycles' emission strength 1 is radiance
  1, checked by --emission-test); one-sided emitters are black on the back face;
- bounces: the project's --max-depth counts path segments, the camera ray included, so a
  direct-lighting path (camera ray + shadow ray) has 2; Cycles' max bounces 0 is direct light.
  max_bounces = max_depth - 2 (checked by run-peers.sh --check-depth).
"""

import json
import math
import os
import sys
import time

import bpy
import mathutils

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import scene_json  # noqa: E402


def parse_args(argv):
    argv = argv[argv.index("--") + 1:] if "--" in argv else []
    opts = {"scene": None, "width": None, "height": None, "max_depth": None, "threads": 2,
            "seed": 0, "spp": "16", "out": "out/cycles", "emission_test": False,
            "sphere_segments": 128, "save_blend": None}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--emission-test":
            opts["emission_test"] = True
        elif a.startswith("--"):
            key = a[2:].replace("-", "_")
            if key not in opts:
                sys.exit("cycles_scene.py: unknown option %s" % a)
            i += 1
            opts[key] = argv[i]
        else:
            opts["scene"] = a
        i += 1
    return opts


def clear_scene():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras):
        for block in list(coll):
            coll.remove(block)


def make_material(name, m):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*m["albedo"], 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert
    shader = diffuse.outputs["BSDF"]
    if any(c > 0 for c in m["emission"]):
        emit = nt.nodes.new("ShaderNodeEmission")
        emit.inputs["Color"].default_value = (*m["emission"], 1.0)
        emit.inputs["Strength"].default_value = 1.0
        emitted = emit.outputs["Emission"]
        if not m["two_sided"]:
            # Cycles' emission shader emits from both faces; the project's emits from the front
            # face only unless two_sided, so the back face gets no emission.
            geo = nt.nodes.new("ShaderNodeNewGeometry")
            black = nt.nodes.new("ShaderNodeEmission")
            black.inputs["Strength"].default_value = 0.0
            mix = nt.nodes.new("ShaderNodeMixShader")
            nt.links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
            nt.links.new(emitted, mix.inputs[1])
            nt.links.new(black.outputs["Emission"], mix.inputs[2])
            emitted = mix.outputs["Shader"]
        if any(c > 0 for c in m["albedo"]):
            add = nt.nodes.new("ShaderNodeAddShader")
            nt.links.new(shader, add.inputs[0])
            nt.links.new(emitted, add.inputs[1])
            shader = add.outputs["Shader"]
        else:
            shader = emitted
    nt.links.new(shader, out.inputs["Surface"])
    return mat


def add_mesh(name, verts, tris, mat):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(t) for t in tris])
    me.update()
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def uv_sphere(center, radius, segments):
    """A UV sphere of `segments` x segments/2 quads (as triangles); Cycles has no analytic sphere
    for meshes, so spheres are tessellated and shaded smooth."""
    rings = max(segments // 2, 4)
    verts = [(center[0], center[1] + radius, center[2])]
    for i in range(1, rings):
        th = math.pi * i / rings
        for j in range(segments):
            ph = 2 * math.pi * j / segments
            verts.append((center[0] + radius * math.sin(th) * math.cos(ph),
                          center[1] + radius * math.cos(th),
                          center[2] - radius * math.sin(th) * math.sin(ph)))
    verts.append((center[0], center[1] - radius, center[2]))
    tris = []
    last = len(verts) - 1
    for j in range(segments):
        j2 = (j + 1) % segments
        tris.append((0, 1 + j, 1 + j2))
        base = 1 + (rings - 2) * segments
        tris.append((last, base + j2, base + j))
    for i in range(rings - 2):
        for j in range(segments):
            j2 = (j + 1) % segments
            a, b = 1 + i * segments + j, 1 + i * segments + j2
            c, d = a + segments, b + segments
            tris += [(a, c, d), (a, d, b)]
    return verts, tris


def build(sc, width, height, sphere_segments):
    clear_scene()
    mats = {name: make_material(name, m) for name, m in sc.materials.items()}
    for mesh in sc.meshes:
        add_mesh(mesh["name"], mesh["vertices"], mesh["triangles"], mats[mesh["material"]])
    for s in sc.spheres:
        v, t = uv_sphere(s["center"], s["radius"], sphere_segments)
        ob = add_mesh(s["name"], v, t, mats[s["material"]])
        for p in ob.data.polygons:
            p.use_smooth = True

    cam = sc.camera
    f, r, u = scene_json.camera_basis(cam)
    cd = bpy.data.cameras.new("camera")
    cd.type = "PERSP"
    cd.sensor_fit = "VERTICAL"
    cd.angle_y = math.radians(float(cam["vfov"]))
    cd.clip_start = 1e-4 * max(1.0, max(abs(x) for x in cam["position"]))
    cd.clip_end = 1e12
    if float(cam.get("aperture", 0)) > 0:
        sc.notes.append("depth of field is not mapped; pinhole camera")
    co = bpy.data.objects.new("camera", cd)
    # Blender cameras look down local -Z with +Y up and +X right.
    rot = mathutils.Matrix(((r[0], u[0], -f[0]), (r[1], u[1], -f[1]), (r[2], u[2], -f[2])))
    co.matrix_world = mathutils.Matrix.Translation(cam["position"]) @ rot.to_4x4()
    bpy.context.scene.collection.objects.link(co)
    bpy.context.scene.camera = co

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    bpy.context.scene.world = world

    rs = bpy.context.scene.render
    rs.resolution_x, rs.resolution_y, rs.resolution_percentage = width, height, 100


def setp(struct, name, value):
    """Sets an RNA property, failing on a misspelt name (bpy silently accepts new attributes)."""
    if name not in struct.bl_rna.properties:
        sys.exit("cycles_scene.py: %s has no property %r (Blender %s)"
                 % (struct.bl_rna.identifier, name, bpy.app.version_string))
    setattr(struct, name, value)


def configure(max_depth, threads, seed):
    scn = bpy.context.scene
    setp(scn.render, "engine", "CYCLES")
    cy = scn.cycles
    bounces = max(max_depth - 2, 0)
    for name, value in [
            ("device", "CPU"), ("feature_set", "SUPPORTED"),
            ("use_adaptive_sampling", False), ("use_denoising", False),
            ("use_preview_denoising", False), ("seed", seed), ("use_animated_seed", False),
            ("sampling_pattern", "PROGRESSIVE_MULTI_JITTER"), ("scrambling_distance", 1.0),
            ("auto_scrambling_distance", False), ("sample_offset", 0), ("time_limit", 0.0),
            ("direct_light_sampling_type", "MULTIPLE_IMPORTANCE_SAMPLING"),
            ("use_guiding", False),
            ("max_bounces", bounces), ("diffuse_bounces", bounces), ("glossy_bounces", bounces),
            ("transmission_bounces", bounces), ("volume_bounces", bounces),
            ("transparent_max_bounces", bounces), ("min_light_bounces", 0),
            ("min_transparent_bounces", 0), ("sample_clamp_direct", 0.0),
            ("sample_clamp_indirect", 0.0), ("blur_glossy", 0.0),
            ("caustics_reflective", True), ("caustics_refractive", True),
            ("light_sampling_threshold", 0.0),  # no light skipped for being dim
            ("pixel_filter_type", "BOX"), ("filter_width", 1.0), ("film_exposure", 1.0),
            ("use_camera_cull", False), ("use_distance_cull", False), ("use_fast_gi", False)]:
        setp(cy, name, value)
    if "use_light_tree" in cy.bl_rna.properties:  # Blender >= 3.5
        setp(cy, "use_light_tree", False)
    for name, value in [("film_transparent", False), ("threads_mode", "FIXED"),
                        ("threads", threads), ("use_compositing", False),
                        ("use_sequencer", False), ("use_persistent_data", False)]:
        setp(scn.render, name, value)
    vs = scn.view_settings
    for name, value in [("view_transform", "Standard"), ("look", "None"), ("exposure", 0.0),
                        ("gamma", 1.0)]:
        setp(vs, name, value)
    im = scn.render.image_settings
    for name, value in [("file_format", "OPEN_EXR"), ("color_depth", "32"),
                        ("exr_codec", "ZIP"), ("color_mode", "RGB")]:
        setp(im, name, value)


def render(spp, path):
    bpy.context.scene.cycles.samples = spp
    bpy.context.scene.render.filepath = path
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    dt = time.perf_counter() - t0
    bpy.data.images["Render Result"].save_render(path)
    return dt


def emission_test(out_prefix):
    """A quad of emission (0.25, 0.5, 1) x strength 1, filling the whole view of the camera."""
    sc = scene_json.Scene()
    sc.camera.update({"position": [0, 0, 1], "look_at": [0, 0, 0], "vfov": 40})
    sc.materials["glow"] = {"type": "diffuse", "albedo": [0, 0, 0],
                            "emission": [0.25, 0.5, 1.0], "two_sided": False}
    v, t = scene_json.quad_mesh([-10, -10, 0], [20, 0, 0], [0, 20, 0])  # normal +z, at camera
    sc.meshes.append({"name": "glow", "material": "glow", "vertices": v, "triangles": t})
    build(sc, 64, 64, 16)
    configure(2, 2, 0)
    path = out_prefix + "_emission_test.exr"
    render(4, path)
    px = bpy.data.images.load(path).pixels[:]
    n = len(px) // 4
    mean = [sum(px[c::4]) / n for c in range(3)]
    print("emission test: emission (0.25, 0.5, 1) strength 1 renders mean %.6f %.6f %.6f" % tuple(mean))
    ok = all(abs(m - e) < 1e-4 for m, e in zip(mean, (0.25, 0.5, 1.0)))
    print("emission test: %s" % ("radiance = colour x strength" if ok else "MISMATCH"))
    return 0 if ok else 1


def main():
    opts = parse_args(sys.argv)
    out = opts["out"]
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    if opts["emission_test"]:
        sys.exit(emission_test(out))
    sc = scene_json.load(opts["scene"])
    width = int(opts["width"] or sc.render["width"])
    height = int(opts["height"] or sc.render["height"])
    depth = int(opts["max_depth"] or sc.render["max_depth"])
    if depth < 2:
        sys.exit("cycles_scene.py: --max-depth must be >= 2 (Cycles always adds direct light)")
    t0 = time.perf_counter()
    build(sc, width, height, int(opts["sphere_segments"]))
    configure(depth, int(opts["threads"]), int(opts["seed"]))
    build_s = time.perf_counter() - t0
    if opts["save_blend"]:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(opts["save_blend"]))
    for note in sc.notes:
        print("cycles_scene.py: note: " + note)
    render(1, out + "_warmup.exr")  # first render pays one-off set-up; not timed
    os.remove(out + "_warmup.exr")
    runs = []
    for spp in [int(s) for s in opts["spp"].split(",")]:
        path = "%s_spp%d.exr" % (out, spp)
        dt = render(spp, path)
        runs.append({"spp": spp, "render_s": round(dt, 4), "file": os.path.basename(path)})
        print("cycles_scene.py: %d spp in %.3f s -> %s" % (spp, dt, path), flush=True)
    info = {"blender": bpy.app.version_string, "scene": opts["scene"], "width": width,
            "height": height, "max_depth": depth, "max_bounces": bpy.context.scene.cycles.max_bounces,
            "threads": int(opts["threads"]), "seed": int(opts["seed"]),
            "build_s": round(build_s, 4), "notes": sc.notes, "runs": runs,
            "timing": "wall time around bpy.ops.render.render(), after a 1-spp warm-up"}
    with open(out + ".json", "w") as f:
        json.dump(info, f, indent=1)


main()
