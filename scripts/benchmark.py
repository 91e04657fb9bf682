#!/usr/bin/env python3
"""Runs every experiment of docs/BENCHMARKS.md and regenerates it (numbers, tables and plots).

Usage (normally through scripts/benchmark, which builds Release first):
  benchmark.py --build BUILD_DIR [--quick | --family] [--out DIR] [--jobs N] [--reuse] [--docs DIR]

Experiments: the paper's Table 1 (loop detected +/- and recall at 100% precision for a
sweep of K) on rendered street sequences along KITTI GT trajectories and aerial flights, plus the
real sets; ablations (search area, feature ranking, extraction area); the full-global and full-ann
baselines on the same frames; trajectory accuracy (KITTI metric and ATE, raw vs corrected); a
robustness curve (image degradation, trajectory drift); micro-benchmarks (detector stages,
search, pose graph, retrieval) and the soak run. Every number in BENCHMARKS.md comes from this
script's output folder (OUT/results.json keeps them all).

Sequences are rendered with fixed seeds (deterministic). Experiments run --jobs at a time (one per
core); timing comparisons against baselines are made between runs of the same batch.
"""
import argparse
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench.common import DATA, RESULTS, ROOT  # noqa: E402
from bench.experiments import run_all, run_family  # noqa: E402
from bench.markdown import write_family_markdown, write_markdown  # noqa: E402
from bench.plots import (plot_accuracy, plot_family, plot_robustness, plot_scaling,  # noqa: E402
                         plot_soak, plot_table1, scaling_series)
from bench.runner import Runner, machine  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", required=True, help="build folder with bin/sparseloop")
    ap.add_argument("--quick", action="store_true", help="the <10 minute subset")
    ap.add_argument("--family", action="store_true",
                    help="only the drift family at full size (docs/BENCHMARKS_DRIFT.md)")
    ap.add_argument("--out", help="output folder (default out/bench-quick or out/bench-full)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--reuse", action="store_true", help="skip experiments whose output exists")
    ap.add_argument("--docs", default=str(ROOT / "docs"), help="where BENCHMARKS.md goes")
    ap.add_argument("--smoke", type=int, default=0,
                    help="test the script itself: every sequence cut to this many frames")
    args = ap.parse_args()
    if not DATA.exists():
        sys.exit(f"benchmark: data folder {DATA} not found (set SPARSELOOP_DATA)")
    if args.family and args.quick:
        sys.exit("benchmark: --family and --quick exclude each other")
    default_out = "bench-family" if args.family else "bench-quick" if args.quick else "bench-full"
    out = Path(args.out or ROOT / "out" / default_out)
    r = Runner(args.build, out, args.jobs, args.reuse)
    r.smoke_frames = args.smoke
    docs = Path(args.docs)
    img = docs / "img"
    img.mkdir(parents=True, exist_ok=True)
    if args.family:
        res = run_family(r)
        res["machine"] = machine()
        res["command"] = " ".join(sys.argv)
        (r.out / "results.json").write_text(json.dumps(res, indent=1, default=str))
        plot_family(res, img / "bench_family.png")
        write_family_markdown(res, args, docs)
        print(f"wrote {docs / 'BENCHMARKS_DRIFT.md'} ({res['timings']['total_s']:.0f} s)")
        return
    res = run_all(r, args.quick)
    rec = RESULTS / "soak_100k.json"
    if rec.exists():
        res["soak_record"] = json.loads(rec.read_text())
    res["machine"] = machine()
    res["command"] = " ".join(sys.argv)
    (r.out / "results.json").write_text(json.dumps(res, indent=1, default=str))
    plot_table1(res, img / "bench_table1.png")
    plot_accuracy(res, img / "bench_accuracy.png")
    plot_robustness(res, img / "bench_robustness.png")
    series = scaling_series(res)
    if series:
        plot_scaling(series, img / "bench_query_scaling.png")
    if (r.out / "soak.csv").exists():
        plot_soak(r.out / "soak.csv", img / "bench_soak.png")
    if res.get("soak_record"):
        runs = res["soak_record"]["runs"]
        plot_soak([(RESULTS / r["csv"], "default" if r.get("release_memory_after_solve", True)
                    else "--keep-heap") for r in runs], img / "bench_soak_100k.png")
    write_markdown(res, args, docs)
    print(f"wrote {docs / 'BENCHMARKS.md'} ({res['timings']['total_s']:.0f} s)")


if __name__ == "__main__":
    main()
