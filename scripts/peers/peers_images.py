"""Image arithmetic for the peer comparison, run inside Blender (which reads and writes EXR and
brings numpy):

  blender -b --factory-startup --python scripts/peers/peers_images.py -- COMMAND ...

  avg OUT.exr IN.exr...              per-pixel mean of equally weighted images
  png IN.exr OUT.png                 clamp to [0, 1], sRGB encode (as `pathtracer render` PNGs)
  pfm2exr IN.pfm OUT.exr             Embree's float output to EXR
  regions --grid N --csv OUT.csv TA TB RA RB
      mean radiance over an N x N grid of blocks and over the whole image, of the test images
      (TA + TB) / 2 and of the references (RA + RB) / 2, where A and B are independent renders
      (different seeds) of the same settings. The standard error of a block mean comes from the
      per-pixel differences: var((a + b) / 2) = E[(a - b)^2] / 4, summed over the block's pixels
      divided by its pixel count squared.
"""

import sys

import bpy
import numpy as np


def read(path):
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)  # top row first, RGB


def write(path, rgb, fmt):
    h, w, _ = rgb.shape
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[:, :, :3] = rgb
    img = bpy.data.images.new("out", w, h, alpha=False, float_buffer=True)
    img.pixels.foreach_set(rgba[::-1].ravel())
    scn = bpy.context.scene
    scn.view_settings.view_transform = "Standard"
    scn.view_settings.look = "None"
    im = scn.render.image_settings
    im.file_format = fmt
    im.color_mode = "RGB"
    if fmt == "OPEN_EXR":
        im.color_depth = "32"
        im.exr_codec = "ZIP"
    else:
        im.color_depth = "8"
    img.save_render(path, scene=scn)


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = [int(x) for x in f.readline().split()]
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    ch = 3 if kind == b"PF" else 1
    img = data.reshape(h, w, ch)[::-1]  # PFM stores the bottom row first
    return np.repeat(img, 3, axis=2) if ch == 1 else img.astype(np.float64)


def regions(args):
    grid, csv = 4, None
    files = []
    i = 0
    while i < len(args):
        if args[i] == "--grid":
            grid = int(args[i + 1])
            i += 2
        elif args[i] == "--csv":
            csv = args[i + 1]
            i += 2
        else:
            files.append(args[i])
            i += 1
    ta, tb, ra, rb = [read(f) for f in files]
    t, r = (ta + tb) / 2, (ra + rb) / 2
    tvar, rvar = (ta - tb) ** 2 / 4, (ra - rb) ** 2 / 4  # per-pixel variance of the means
    tgvar = (ta - tb).mean(axis=2) ** 2 / 4
    rgvar = (ra - rb).mean(axis=2) ** 2 / 4
    h, w, _ = t.shape
    rows = []

    def block(name, ys, xs):
        n = (ys.stop - ys.start) * (xs.stop - xs.start)
        tm = t[ys, xs].reshape(-1, 3).mean(axis=0)
        rm = r[ys, xs].reshape(-1, 3).mean(axis=0)
        tse = np.sqrt(tvar[ys, xs].reshape(-1, 3).sum(axis=0)) / n
        rse = np.sqrt(rvar[ys, xs].reshape(-1, 3).sum(axis=0)) / n
        tl, rl = tm.mean(), rm.mean()  # grey = mean of RGB
        # s.e. of the grey difference, from the grey per pixel (the channels are correlated)
        dse = np.sqrt(tgvar[ys, xs].sum() + rgvar[ys, xs].sum()) / n
        rows.append((name, tl, rl, tl / rl - 1 if rl > 0 else float("nan"),
                     (tl - rl) / dse if dse > 0 else float("nan"), tm, rm, tse, rse))

    for by in range(grid):
        for bx in range(grid):
            block("r%dc%d" % (by, bx), slice(by * h // grid, (by + 1) * h // grid),
                  slice(bx * w // grid, (bx + 1) * w // grid))
    block("all", slice(0, h), slice(0, w))
    header = "region,test_mean,ref_mean,rel_diff,z,test_r,test_g,test_b,ref_r,ref_g,ref_b," \
             "se_test_r,se_test_g,se_test_b,se_ref_r,se_ref_g,se_ref_b"
    lines = [header]
    for name, tl, rl, rel, z, tm, rm, tse, rse in rows:
        lines.append(",".join([name] + ["%.6g" % x for x in
                                        [tl, rl, rel, z, *tm, *rm, *tse, *rse]]))
    if csv:
        with open(csv, "w") as f:
            f.write("\n".join(lines) + "\n")
    print("region     test mean   ref mean    rel. diff   z (diff / s.e.)")
    for name, tl, rl, rel, z, *_ in rows:
        print("%-9s  %9.5f  %9.5f  %+9.3f%%  %+7.1f" % (name, tl, rl, 100 * rel, z))


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    cmd, args = argv[0], argv[1:]
    if cmd == "avg":
        imgs = [read(p) for p in args[1:]]
        write(args[0], sum(imgs) / len(imgs), "OPEN_EXR")
    elif cmd == "png":
        write(args[1], np.clip(read(args[0]), 0, 1), "PNG")
    elif cmd == "pfm2exr":
        write(args[1], read_pfm(args[0]), "OPEN_EXR")
    elif cmd == "regions":
        regions(args)
    else:
        sys.exit("peers_images.py: unknown command " + cmd)


main()
