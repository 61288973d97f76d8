"""Turns the renders of run-peers.sh into results.csv and a Markdown table on stdout: for every
sweep image its render time and relMSE against each renderer's reference, and the time to
relMSE 1e-2 interpolated in log-log between the two sweep points around it.

  python3 scripts/peers/peers_table.py OUT_DIR PATHTRACER "1 2 4 ..."

The references are means of two independent renders (seeds 1 and 2); their own error is about
relMSE(a, b) / 4, which is listed and also subtracted in the "corrected" columns.
"""

import json
import math
import os
import subprocess
import sys

TARGET = 1e-2


def compare(pt, test, ref):
    out = subprocess.run([pt, "compare", "--json", test, ref], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out)["relmse"]


def crossing(points):
    """Time at which relMSE falls to TARGET, log-log between the bracketing sweep points."""
    for (t0, e0), (t1, e1) in zip(points, points[1:]):
        if e0 >= TARGET >= e1 and e0 > 0 and e1 > 0 and e0 != e1:
            a = (math.log(TARGET) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + a * (math.log(t1) - math.log(t0)))
    return float("nan")


def main():
    out, pt, sweep = sys.argv[1], sys.argv[2], [int(s) for s in sys.argv[3].split()]
    cyc = json.load(open(os.path.join(out, "cycles.json")))
    cyc_time = {r["spp"]: r["render_s"] for r in cyc["runs"]}
    refs = {"ours": os.path.join(out, "ours_ref.exr"), "cycles": os.path.join(out, "cycles_ref.exr")}
    floor = {r: compare(pt, os.path.join(out, r + "_ref_a.exr"), os.path.join(out, r + "_ref_b.exr")) / 4
             for r in refs}
    rows = []
    for name in ("ours", "cycles"):
        for spp in sweep:
            img = os.path.join(out, "%s_spp%d.exr" % (name, spp))
            if name == "ours":
                t = json.load(open(img + ".json"))["wall_time_s"]
            else:
                t = cyc_time[spp]
            e = {r: compare(pt, img, path) for r, path in refs.items()}
            rows.append({"renderer": name, "spp": spp, "time_s": t, "relmse_vs_ours": e["ours"],
                         "relmse_vs_cycles": e["cycles"]})
    with open(os.path.join(out, "results.csv"), "w") as f:
        f.write("renderer,spp,time_s,relmse_vs_ours_ref,relmse_vs_cycles_ref\n")
        for r in rows:
            f.write("%s,%d,%.4f,%.6g,%.6g\n" % (r["renderer"], r["spp"], r["time_s"],
                                                r["relmse_vs_ours"], r["relmse_vs_cycles"]))

    print("| renderer | spp | time (s) | relMSE vs ours ref | relMSE vs Cycles ref |")
    print("|---|---:|---:|---:|---:|")
    for r in rows:
        print("| %s | %d | %.3f | %.4g | %.4g |" % (r["renderer"], r["spp"], r["time_s"],
                                                    r["relmse_vs_ours"], r["relmse_vs_cycles"]))
    print()
    print("Reference noise (relMSE(a, b) / 4): ours %.3g, Cycles %.3g" % (floor["ours"], floor["cycles"]))
    print()
    print("| renderer | time to relMSE 1e-2, own ref (s) | corrected for ref noise (s) "
          "| vs the other's ref (s) |")
    print("|---|---:|---:|---:|")
    summary = {}
    for name, other in (("ours", "cycles"), ("cycles", "ours")):
        mine = [r for r in rows if r["renderer"] == name]
        own = crossing([(r["time_s"], r["relmse_vs_" + name]) for r in mine])
        corr = crossing([(r["time_s"], r["relmse_vs_" + name] - floor[name]) for r in mine])
        cross = crossing([(r["time_s"], r["relmse_vs_" + other]) for r in mine])
        summary[name] = (own, corr, cross)
        print("| %s | %.2f | %.2f | %.2f |" % (name, own, corr, cross))
    print()
    ratio = summary["ours"][0] / summary["cycles"][0]
    print("Ours / Cycles time to relMSE 1e-2 (own references): %.2f (target <= 0.5: %s)"
          % (ratio, "met" if ratio <= 0.5 else "not met"))
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump({"time_to_1e-2_s": summary, "reference_noise": floor,
                   "ours_over_cycles": ratio}, f, indent=1)


main()
