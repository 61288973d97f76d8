#!/usr/bin/env python3
"""Splits the megakernel's executed instructions by stage.

Joins Nsight Compute's per-instruction source counters (`ncu -i R --page source --csv
--print-source sass`) with a line-info disassembly (`nvdisasm -c -gi`), whose comments give each
instruction's chain of inlined call sites, and sums warp and thread instructions per stage.
Usage: sass_split.py disasm.txt sass.csv [kernel-substring] [--detail]
"""
import csv
import re
import sys
from collections import defaultdict

LOC = re.compile(r'"([^"]+)", line (\d+)')
INSN = re.compile(r'/\*([0-9a-f]{4,})\*/\s+(.*?)\s*;')
FUNC = re.compile(r'^\s*\.text\.(\S+):')


def read_disasm(path, want):
    """Instructions of the first function whose name holds `want`: (offset, text, chain)."""
    out, chain, inside, in_chain = [], [], False, False
    for line in open(path, errors="replace"):
        m = FUNC.match(line)
        if m:
            if inside:
                break
            inside = want in m.group(1) and "ILj0E" in m.group(1)
            continue
        if not inside:
            continue
        if "//##" in line:
            # One comment line per inlining level, innermost first: "A, line a inlined at B".
            loc = LOC.findall(line)[0]
            chain = (chain if in_chain else []) + [(loc[0].split("/")[-1], int(loc[1]))]
            in_chain = True
            continue
        in_chain = False
        m = INSN.search(line)
        if m:
            out.append((int(m.group(1), 16), m.group(2), chain))
    return out


def read_counts(path):
    rows = list(csv.reader(open(path, errors="replace")))
    hdr_i = next(i for i, r in enumerate(rows) if any("Instructions Executed" in c for c in r))
    hdr = rows[hdr_i]
    col = lambda name: next(i for i, c in enumerate(hdr) if c.strip() == name)
    a, s = col("Address"), col("Source")
    w, t = col("Instructions Executed"), col("Thread Instructions Executed")
    num = lambda x: float(x.replace(",", "") or 0)
    out = []
    for r in rows[hdr_i + 1:]:
        if len(r) <= max(a, s, w, t):
            continue
        try:
            out.append((r[a], r[s], num(r[w]), num(r[t])))
        except ValueError:
            continue
    return out


# Call sites in the megakernel (megakernel.cu) and the files below them, in order of precedence.
def classify(chain, sites):
    files = [f for f, _ in chain]
    outer = next(((f, n) for f, n in reversed(chain) if f == "megakernel.cu"), None)
    site = sites.get(outer[1], "kernel loop") if outer else "kernel loop"
    if site in ("closest traversal", "shadow traversal"):
        if "geometry.h" in files:
            return site + ": triangle test"
        if "bvh.h" in files:
            return site + ": box tests"
        return site + ": loop, stack, leaf fetch"
    if site in ("shade", "generate"):
        if "rng.h" in files:
            return site + ": RNG"
        for f, name in (("lights.h", "light sampling"), ("bsdf.h", "BSDF"),
                        ("camera.h", "camera ray"), ("sampling.h", "sampling/MIS")):
            if f in files:
                return site + ": " + name
        inner = chain[0] if chain else ("?", 0)
        if inner[0] == "scene_view.h":
            return site + ": surface hit"
        return site + ": other (" + inner[0] + ")"
    return site


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    detail = "--detail" in sys.argv
    insns = read_disasm(args[0], args[2] if len(args) > 2 else "megakernel")
    counts = read_counts(args[1])
    print(f"disasm: {len(insns)} instructions; counters: {len(counts)} rows")
    # Join by position; check that the opcodes agree.
    n = min(len(insns), len(counts))
    bad = sum(1 for i in range(n)
              if insns[i][1].split()[0].lstrip("@!P0123456789T") not in counts[i][1])
    print(f"joined {n} by position, {bad} opcode mismatches")
    # The megakernel's call sites, from a copy of megakernel.cu beside this script or tracer/'s.
    import os
    here = os.path.dirname(os.path.abspath(__file__))
    src = next(p for p in (os.path.join(here, "megakernel.cu"), os.path.join(here, "..", "tracer",
               "cuda", "megakernel.cu")) if os.path.exists(p))
    named, in_mk = {}, False
    for ln, text in enumerate(open(src), 1):
        in_mk = in_mk or "megakernel(SceneView" in text
        if not in_mk:
            continue
        for pat, name in (("generate_path<F>(", "generate"), ("intersect_closest<F>(", "closest traversal"),
                          ("shade_path<F>(", "shade"), ("intersect_any<F>(", "shadow traversal"),
                          ("add_to_film(", "film")):
            if pat in text and name not in named.values():
                named[ln] = name
        if "warp_add(&counters[0]" in text:
            break
    print("call sites:", named)
    tot_w = tot_t = 0.0
    by = defaultdict(lambda: [0.0, 0.0, 0])
    lines = defaultdict(lambda: [0.0, 0.0])
    for i in range(n):
        _, _, chain = insns[i]
        _, _, w, t = counts[i]
        k = classify(chain, named)
        by[k][0] += w
        by[k][1] += t
        by[k][2] += 1
        tot_w += w
        tot_t += t
        if chain:
            lines[f"{chain[0][0]}:{chain[0][1]} <- {'/'.join(f'{f}:{l}' for f, l in chain[1:])}"][1] += t
    print(f"total warp insts {tot_w:.4g}, thread insts {tot_t:.4g}, lanes {tot_t / max(tot_w, 1):.1f}")
    print(f"{'stage':48s} {'thread insts':>12s} {'share':>6s} {'warp insts':>11s} {'lanes':>5s} {'static':>6s}")
    for k, (w, t, c) in sorted(by.items(), key=lambda kv: -kv[1][1]):
        print(f"{k:48s} {t:12.4g} {100 * t / tot_t:5.1f}% {w:11.4g} {t / max(w, 1):5.1f} {c:6d}")
    if detail:
        print("\ntop source lines (innermost <- call chain), thread instructions:")
        for k, (_, t) in sorted(lines.items(), key=lambda kv: -kv[1][1])[:60]:
            print(f"{t:12.4g} {100 * t / tot_t:5.1f}%  {k}")


main()
