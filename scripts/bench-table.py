#!/usr/bin/env python3
"""Prints the summary.csv of `pathtracer bench --error` as a Markdown table (for docs).

    scripts/bench-table.py bench-out/summary.csv
"""
import csv
import sys


def fmt_time(value, extrapolated):
    t = float(value)
    if t < 0:
        return "never"
    return ("~" if extrapolated == "1" else "") + f"{t:.3g}"


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    rows = list(csv.DictReader(open(sys.argv[1], newline="")))
    print("| configuration | spp | time (s) | relMSE | RMSE | mean FLIP | t to 1e-2 (s) | "
          "t to 1e-3 (s) | 1/(relMSE x t) | slope | verdict |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for r in rows:
        flip = f"{float(r['flip']):.4f}" if float(r["flip"]) >= 0 else "-"
        print(f"| {r['config']} | {r['final_spp']} | {float(r['seconds']):.3g} | "
              f"{float(r['relmse']):.3g} | {float(r['rmse']):.3g} | {flip} | "
              f"{fmt_time(r['time_to_1e-2_s'], r['extrapolated_1e-2'])} | "
              f"{fmt_time(r['time_to_1e-3_s'], r['extrapolated_1e-3'])} | "
              f"{float(r['efficiency']):.3g} | {float(r['slope']):.2f} | {r['verdict']} |")


if __name__ == "__main__":
    main()
