#!/usr/bin/env python3
"""Turns scripts/bench-suite.sh's suite.jsonl into the Markdown table of docs/BENCHMARKS.md.

usage: scripts/suite_table.py OUT/suite.jsonl
"""
import json
import sys


def fmt(v, spec="{:,.0f}", none="-"):
    return none if v is None else spec.format(v)


def row_named(rows, config):
    return next((r for r in rows if r.get("config") == config), None)


def main():
    recs = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
    device = next((r.get("device") for r in recs if r.get("device")), "no GPU")
    print(f"Device: {device}. 1920x1080, depth 8, {recs and 16} timed spp per row; relMSE against "
          "a reference of the same renderer (independent seed).\n")
    print("| scene | triangles | BVH build | bytes / tri: BVH, all on the GPU | first image | "
          "camera / bounce / shadow Mrays/s | M segments/s: auto, CPU | time to relMSE 1e-2 |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in recs:
        if r.get("skipped"):
            print(f"| {r['name']} | skipped: {r['skipped']} ||||||")
            continue
        bvh = r.get("bvh") or {}
        tris = r.get("triangles") or 0
        ms = bvh.get("build_ms")
        build = (f"{ms / 1000:.2f} s ({tris / (ms * 1e3):.1f} M tri/s)" if ms and tris else "-")
        rows = r.get("rows") or []
        wf = row_named(rows, "wavefront") or {}
        rates = wf.get("ray_rates_M_per_s") or {}
        rr = " / ".join(fmt(rates.get(k)) for k in ("camera", "bounce", "shadow"))
        auto = row_named(rows, "auto") or {}
        seg = fmt(auto.get("M_segments_per_s"))
        if auto.get("note"):
            seg += f" ({auto['kernel']})"
        cpu = next((x for x in rows if x.get("kernel") == "cpu"), {})
        seg += ", " + fmt(cpu.get("M_segments_per_s"), "{:,.1f}")
        err = (r.get("error") or {}).get("configs") or [{}]
        t = err[0].get("time_to_1e-2_s")
        ext = err[0].get("extrapolated_1e-2")
        last = (err[0].get("checkpoints") or [{}])[-1]
        if t is None or t < 0:
            tt = "-"
        elif ext and last.get("seconds") and t > 10 * last["seconds"]:
            # Far past the sweep: say where it stopped instead of an extrapolation.
            tt = f"not reached: {last['relmse']:.2g} at {last['seconds']:.3g} s"
        else:
            tt = ("~" if ext else "") + f"{t:.3g} s"
        mem = r.get("scene_device_bytes")
        per_tri = (f"{bvh['bytes'] / tris:.1f}" if tris and bvh.get("bytes") else "-") + ", " + \
            (f"{mem / tris:.1f} ({mem / 2**20:,.1f} MiB)" if tris and mem else "-")
        print(f"| {r['name']} | {tris:,} | {build} | {per_tri} | {r['first_image_s']:.2f} s | "
              f"{rr} | {seg} | {tt} |")


if __name__ == "__main__":
    main()
