#!/usr/bin/python3
"""Plot bench_soak CSVs: peak / current RSS and time per keyframe against the keyframe count.

usage: /usr/bin/python3 scripts/plot_soak.py SOAK.csv [SOAK2.csv ...] OUT.png
Each CSV is one run (header: keyframes,peak_rss_kib,rss_kib,mean_ms,p99_ms,loops,solves,
record_bytes); its file name is the legend label.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path}: no data rows")
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    *inputs, out = argv[1:]
    fig, (ax_mem, ax_time) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
    for path in inputs:
        d = read(path)
        label = os.path.splitext(os.path.basename(path))[0]
        kf = d["keyframes"]
        line, = ax_mem.plot(kf, [v / 1024 for v in d["peak_rss_kib"]], label=f"{label} peak (VmHWM)")
        ax_mem.plot(kf, [v / 1024 for v in d["rss_kib"]], "--", color=line.get_color(),
                    label=f"{label} current (VmRSS)")
        ax_mem.plot(kf, [v / 2**20 for v in d["record_bytes"]], ":", color=line.get_color(),
                    label=f"{label} detector records")
        ax_time.plot(kf, d["mean_ms"], color=line.get_color(), label=f"{label} mean")
        ax_time.plot(kf, d["p99_ms"], "--", color=line.get_color(), label=f"{label} p99")
    ax_mem.set_ylabel("MiB")
    ax_mem.set_title("bench_soak: memory")
    ax_mem.grid(True, alpha=0.3)
    ax_mem.legend(fontsize=7)
    ax_time.set_ylabel("ms per keyframe (window)")
    ax_time.set_xlabel("keyframes")
    ax_time.set_yscale("log")
    ax_time.grid(True, alpha=0.3)
    ax_time.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv)
