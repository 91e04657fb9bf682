#!/usr/bin/env python3
"""Draws the paper's search area from the geometry the search tests dump.

Usage:
  build/tests/search/test_search --gtest_filter=SearchAreaFigure.*   # prints the JSON path
  scripts/plot_search_area.py <search_area_figure.json> docs/img/search_area.png

The JSON (written by tests/search/search_area_test.cc, SearchAreaFigure.DumpGeometryJson) holds
the projected positions x'_k, the query position x'_t, the unit motion direction, the motion-ray
hit p, the perpendicular hit p', the start/end keyframes, the wedge side, alpha and the
candidates. No C++ is called from here.
"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        g = json.load(f)
    pts = g["positions"]
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    t = len(pts) - 1
    eligible = t - g["exclude_recent"]
    pos, d = g["position"], g["direction"]
    side = g["wedge_side"] if g["wedge_side"] != 0 else 1
    a = math.radians(g["alpha_deg"])
    alpha_dir = (math.cos(a) * d[0] - side * math.sin(a) * d[1],
                 side * math.sin(a) * d[0] + math.cos(a) * d[1])
    span = max(max(xs) - min(xs), max(ys) - min(ys))

    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=90)
    ax.plot(xs[: eligible], ys[: eligible], "-", color="0.6", lw=1.5, label="past trajectory x'_k")
    ax.plot(xs[eligible - 1:], ys[eligible - 1:], ":", color="0.6", lw=1.5,
            label="most recent (excluded)")
    cand = g["candidates"]
    ax.plot([xs[k] for k in cand], [ys[k] for k in cand], "o", color="tab:blue", ms=4,
            label="candidates")
    p = g["p"]
    ax.plot([pos[0], p[0]], [pos[1], p[1]], "-", color="tab:red", lw=1.2, label="motion ray -> p")
    ax.annotate("", xy=(pos[0] + 2 * d[0], pos[1] + 2 * d[1]), xytext=(pos[0], pos[1]),
                arrowprops=dict(arrowstyle="->", color="tab:red"))
    if "p_end" in g:
        q = g["p_end"]
        ax.plot([pos[0], q[0]], [pos[1], q[1]], "--", color="tab:red", lw=1.0,
                label="perpendicular h -> p'")
        ax.plot(*q, "s", color="tab:red", ms=6, mfc="none")
        ax.annotate("p'", q, textcoords="offset points", xytext=(5, 5))
    L = 0.6 * span
    ax.plot([pos[0], pos[0] + L * alpha_dir[0]], [pos[1], pos[1] + L * alpha_dir[1]], "-.",
            color="tab:orange", lw=1.0, label=f"alpha line ({g['alpha_deg']:.0f} deg)")
    ax.plot(*p, "s", color="tab:red", ms=6)
    ax.annotate("p", p, textcoords="offset points", xytext=(5, -12))
    ax.plot(*pos, "k^", ms=8, label="x'_t (query)")
    s, e = g["start"], g["end"]
    ax.plot(xs[s], ys[s], "*", color="tab:green", ms=12, label="start (nearest to p)")
    if e >= 0:
        ax.plot(xs[e], ys[e], "*", color="tab:purple", ms=12, label="end (nearest to p')")
    ax.set_aspect("equal")
    ax.set_xlabel("u (plane coordinate)")
    ax.set_ylabel("v (plane coordinate)")
    ax.set_title("Paper search area (strategy 'paper')", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), framealpha=0.9)
    fig.tight_layout()
    fig.savefig(sys.argv[2])
    print(f"wrote {sys.argv[2]}")


if __name__ == "__main__":
    main()
