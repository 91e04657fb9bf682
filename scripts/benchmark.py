#!/usr/bin/env python3
"""Runs every experiment of docs/BENCHMARKS.md and regenerates it (numbers, tables and plots).

Usage (normally through scripts/benchmark, which builds Release first):
  benchmark.py --build BUILD_DIR [--quick] [--out DIR] [--jobs N] [--reuse] [--docs DIR]

Experiments (issue #6): the paper's Table 1 (loop detected +/- and recall at 100% precision for a
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
import concurrent.futures as cf
import csv
import datetime
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(os.environ.get("SPARSELOOP_DATA", ROOT.parent / "shared" / "data"))
RESULTS = ROOT / "bench" / "results"  # long runs recorded by scripts/soak

# Ground-truth loop definition per world (see BENCHMARKS.md, "How loops are scored").
#   revisit_m: a query frame has a GT revisit when an earlier frame is closer than this,
#   gap_m:     ... and at least this much path was travelled in between (not a neighbour),
#   angle_deg: ... and the optical axes differ by less than this (the views can overlap);
#   correct_m: a detection is correct when its frames are closer than this.
GT_RULES = {
    "street": {"revisit_m": 10.0, "gap_m": 100.0, "angle_deg": 60.0, "correct_m": 20.0},
    "aerial": {"revisit_m": 20.0, "gap_m": 100.0, "angle_deg": 180.0, "correct_m": 35.0},
}


# --------------------------------------------------------------------------------------------
# Experiment plan


def plan(quick):
    """Sequences to render: name -> (world, render args)."""
    kitti = DATA / "kitti_gt_poses"
    seqs = {
        "street07": ("street", ["--world", "street", "--trajectory", str(kitti / "07.txt"),
                                "--kitti-sequence", "7", "--step", "2", "--seed", "1"]),
        "aerial_circuit": ("aerial", ["--world", "aerial", "--plan", "circuit", "--laps", "2",
                                      "--frames", "600" if quick else "1500", "--seed", "1"]),
        "aerial_figure8": ("aerial", ["--world", "aerial", "--plan", "figure8", "--laps", "2",
                                      "--frames", "400" if quick else "1200", "--seed", "2"]),
    }
    if not quick:
        for s in ("00", "05", "06"):
            seqs["street" + s] = ("street", ["--world", "street", "--trajectory",
                                             str(kitti / f"{s}.txt"), "--kitti-sequence",
                                             str(int(s)), "--step", "2", "--seed", "1"])
    return seqs


SOAK_KEYFRAMES_QUICK = 5000

# Loop-correction drift family (issue #18): each sequence fully re-rendered per drift scale (the
# mapped pixels' depths are in the raw trajectory's units, so a poses-only drift would hand the
# detector depths of another scale), run with today's defaults and with the loop options before
# session 8 in the same benchmark run (the gate's path and prior along the loop graph are code,
# not options: both variants have them).
OLD_LOOP_DEFAULTS = {
    # Fixed loop sigmas (0.5 raw steps, 0.01 rad, 0.05, weight = score), odometry 2 % / 0.002 rad
    # / 0.002 per step, rotation gate 0.1 deg per keyframe. The old gate counted keyframes since
    # the last accepted loop anywhere; 0.1 along the loop graph is never wider than that.
    "odometry": {"translation_fraction": 0.02, "rotation_sigma_rad": 0.002, "scale_sigma": 0.002},
    "loop_information_from_estimate": False,
    "detector": {"consistency_per_keyframe_deg": 0.1},
}


def drift_family(quick):
    """(sequence, drift scales) of the loop-correction family."""
    if quick:
        return [("aerial_circuit", [1.0, 4.0]), ("street07", [1.0, 4.0])]
    return [("aerial_circuit", [1.0, 4.0])] + [(s, [1.0, 2.0, 4.0])
                                              for s in ("street00", "street05", "street06")]


def k_sweep(quick):
    return [8, 12, 15, 18, 32, 64] if quick else list(range(8, 19)) + [32, 64]


# --------------------------------------------------------------------------------------------
# Running things


class Runner:
    def __init__(self, build, out, jobs, reuse):
        self.build = Path(build).resolve()
        self.bin = self.build / "bin" / "sparseloop"
        self.out = Path(out).resolve()
        self.jobs = jobs
        self.reuse = reuse
        self.out.mkdir(parents=True, exist_ok=True)
        self.log_dir = self.out / "logs"
        self.log_dir.mkdir(exist_ok=True)
        if not self.bin.exists():
            sys.exit(f"benchmark: {self.bin} not found (build the sparseloop_cli target first)")

    def call(self, name, args, done_marker=None):
        """Runs a command (list) with its output in logs/NAME.log; returns seconds taken."""
        if self.reuse and done_marker is not None and Path(done_marker).exists():
            return 0.0
        log = self.log_dir / f"{name}.log"
        t0 = time.time()
        with open(log, "w") as f:
            f.write(" ".join(str(a) for a in args) + "\n")
            f.flush()
            rc = subprocess.call([str(a) for a in args], stdout=f, stderr=subprocess.STDOUT)
        if rc != 0:
            tail = log.read_text().splitlines()[-15:]
            raise RuntimeError(f"{name} failed (exit {rc}); log {log}:\n" + "\n".join(tail))
        return time.time() - t0

    def parallel(self, tasks):
        """tasks: list of (name, args, done_marker). Runs them self.jobs at a time."""
        with cf.ThreadPoolExecutor(max_workers=self.jobs) as pool:
            futures = {pool.submit(self.call, n, a, m): n for n, a, m in tasks}
            for fut in cf.as_completed(futures):
                fut.result()  # re-raise the first failure

    def bench_exe(self, name):
        p = self.build / "bin" / name
        if not p.exists():
            p = self.build / "bench" / name
        return p if p.exists() else None


SMOKE_FRAMES = 0  # --smoke: cut every sequence (tests the script, numbers are meaningless)


def with_frames(args, frames):
    """Render arguments with --frames set to `frames` (replacing an existing value)."""
    args = list(args)
    if "--frames" in args:
        args[args.index("--frames") + 1] = str(frames)
    else:
        args += ["--frames", str(frames)]
    return args


def render_tasks(r, seqs, threads):
    tasks = []
    for name, (_, args) in seqs.items():
        if SMOKE_FRAMES:
            args = with_frames(args, SMOKE_FRAMES)
        out = r.out / "seq" / name
        tasks.append((f"render_{name}", [r.bin, "render", *args, "--threads", threads,
                                         "--out", out], out / "times.txt"))
    return tasks


def run_task(r, seq, variant, config, poses=None, extra=()):
    """A `sparseloop run` on a rendered sequence with a JSON config; returns (task, run dir)."""
    seq_dir = r.out / "seq" / seq
    run_dir = r.out / "runs" / seq / variant
    run_dir.mkdir(parents=True, exist_ok=True)
    cfg = run_dir / "config.json"
    cfg.write_text(json.dumps(config, indent=1))
    args = [r.bin, "run", "--dataset", f"kitti:{seq_dir}", "--poses",
            poses or seq_dir / "poses_raw.txt", "--gt", seq_dir / "poses_gt.txt",
            "--config", cfg, "--out", run_dir, "--quiet", *extra]
    return (f"run_{seq}_{variant}", args, run_dir / "summary.json"), run_dir


def detector_config(k=None, **detector):
    d = dict(detector)
    if k is not None:
        d.setdefault("features", {})["max_features"] = k
    return {"detector": d} if d else {}


# --------------------------------------------------------------------------------------------
# Scoring loops against GT


def read_kitti_positions(path):
    a = np.loadtxt(path, comments="#").reshape(-1, 12)
    return a[:, [3, 7, 11]], a[:, [2, 6, 10]]  # positions, optical axes (3rd rotation column)


def read_loops_csv(path):
    with open(path) as f:
        return [{"q": int(row["query"]), "m": int(row["match"]), "score": float(row["score"]),
                 "accepted": row.get("accepted", "1") == "1"} for row in csv.DictReader(f)]


def gt_revisits(pos, axis, rule):
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(step)])
    cos_max = math.cos(math.radians(rule["angle_deg"])) if rule["angle_deg"] < 180 else -2.0
    queries = []
    for i in range(len(pos)):
        d = np.linalg.norm(pos[:i] - pos[i], axis=1)
        ok = (d < rule["revisit_m"]) & (cum[i] - cum[:i] > rule["gap_m"])
        ok &= (axis[:i] @ axis[i]) > cos_max
        if ok.any():
            queries.append(i)
    return cum, queries


def group_events(queries, max_gap=10):
    events = []
    for q in queries:
        if events and q - events[-1][1] <= max_gap:
            events[-1][1] = q
        else:
            events.append([q, q])
    return events


def score_loops(run_dir, seq_dir, world, gt_cache):
    rule = GT_RULES[world]
    key = str(seq_dir)
    if key not in gt_cache:
        pos, axis = read_kitti_positions(seq_dir / "poses_gt.txt")
        cum, queries = gt_revisits(pos, axis, rule)
        gt_cache[key] = (pos, cum, queries, group_events(queries))
    pos, cum, queries, events = gt_cache[key]
    loops = read_loops_csv(run_dir / "loops.csv")
    scored = []
    trivial = 0
    for l in loops:
        d = float(np.linalg.norm(pos[l["q"]] - pos[l["m"]]))
        gap = cum[l["q"]] - cum[l["m"]]
        if d < rule["correct_m"] and gap <= rule["gap_m"]:
            trivial += 1  # the same place seen moments ago: not a loop, not an error
            continue
        scored.append((l["score"], d < rule["correct_m"], l["q"], l["accepted"]))
    qset = set(queries)

    def recall_at_full_precision(items):
        found = set()
        for _, correct, q, _ in sorted(items, key=lambda x: -x[0]):
            if not correct:
                break
            if q in qset:
                found.add(q)
        return len(found) / len(qset) if qset else float("nan")

    accepted = [s for s in scored if s[3]]
    detected_events = 0
    for a, b in events:
        if any(c and a - 2 <= q <= b + 2 for _, c, q, _ in accepted):
            detected_events += 1
    return {
        "gt_queries": len(qset),
        "events": len(events),
        "events_detected": detected_events,
        "loops": len(scored),
        "trivial": trivial,
        "false_detected": sum(1 for s in scored if not s[1]),
        "false_accepted": sum(1 for s in accepted if not s[1]),
        "recall_100p": recall_at_full_precision(scored),
        "recall_100p_accepted": recall_at_full_precision(accepted),
    }


def num(v):
    return float("nan") if v is None else v


def status(value, ok):
    """Target status: n/a when the value could not be measured."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "not measured"
    return "met" if ok else "**missed**"


def run_metrics(run_dir, seq_dir, world, gt_cache):
    s = json.loads((run_dir / "summary.json").read_text())
    m = score_loops(run_dir, seq_dir, world, gt_cache)
    t = s.get("timing_ms", {})
    m["timing_ms"] = t
    m["ms_total_median"] = t.get("total", {}).get("median", float("nan"))
    m["ms_total_p99"] = t.get("total", {}).get("p99", float("nan"))
    m["bytes_per_keyframe"] = s.get("bytes_per_keyframe", float("nan"))
    m["keyframes"] = s.get("keyframes", 0)
    ev = s.get("eval", {})
    for which in ("raw", "corrected"):
        e = ev.get(which, {})
        m[f"{which}_t_err_pct"] = num(e.get("kitti_t_err_pct"))
        m[f"{which}_r_err"] = num(e.get("kitti_r_err_deg_per_100m"))
        m[f"{which}_ate_m"] = num(e.get("ate_rmse_m"))
        m[f"{which}_per_length"] = e.get("kitti", {}).get("per_length", [])
    m["optimizer_ms"] = 1000 * s.get("optimizer", {}).get("solve_seconds", float("nan"))
    return m


# --------------------------------------------------------------------------------------------
# External producers (executables that print one JSON object) and Google Benchmarks


def json_exe(r, exe_name, args, name):
    exe = r.bench_exe(exe_name)
    if exe is None:
        return {"missing": f"{exe_name} was not built"}
    out = r.out / f"{name}.json"
    if not (r.reuse and out.exists()):
        log = r.log_dir / f"{name}.log"
        with open(out, "w") as fo, open(log, "w") as fe:
            rc = subprocess.call([str(exe), *map(str, args)], stdout=fo, stderr=fe)
        if rc != 0:
            return {"missing": f"{exe_name} exited {rc} (log {log.name})"}
    try:
        return json.loads(out.read_text())
    except json.JSONDecodeError as e:
        return {"missing": f"{exe_name} printed invalid JSON: {e}"}


def google_bench(r, exe_name, name, extra=()):
    exe = r.bench_exe(exe_name)
    if exe is None:
        return None
    out = r.out / f"{name}.json"
    if not (r.reuse and out.exists()):
        r.call(name, [exe, f"--benchmark_out={out}", "--benchmark_out_format=json", *extra])
    return json.loads(out.read_text())


def gb_rows(result):
    rows = []
    for b in (result or {}).get("benchmarks", []):
        if b.get("run_type") == "aggregate":
            continue
        unit = b.get("time_unit", "ns")
        scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[unit]
        row = {"name": b["name"], "ms": b["real_time"] * scale, "cpu_ms": b["cpu_time"] * scale}
        for k, v in b.items():
            if k not in row and isinstance(v, (int, float)) and k not in (
                    "real_time", "cpu_time", "iterations", "repetitions", "repetition_index",
                    "threads", "family_index", "per_family_instance_index"):
                row[k] = v
        rows.append(row)
    return rows


# --------------------------------------------------------------------------------------------
# Formatting


def fmt(v, digits=2):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(c) if not isinstance(c, str) else c for c in row) + " |"
              for row in rows]
    return "\n".join(lines)


def machine():
    cpu = "unknown"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = 0
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = int(line.split()[1]) / 1024 / 1024
    except OSError:
        pass
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip() or "unknown"
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    return {"cpu": cpu, "cores": os.cpu_count(), "mem_gib": round(mem, 1),
            "os": platform.platform(), "commit": commit + ("+dirty" if dirty else ""),
            "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M")}


# --------------------------------------------------------------------------------------------
# The experiments


def ablation_variants():
    """name -> (group, detector config, pipeline-level config)."""
    f = lambda **kw: {"features": kw}  # noqa: E731
    s = lambda **kw: {"search": kw}  # noqa: E731
    return {
        "default": ("", {}, {}),
        "search_paper_drift": ("search area", s(drift_tolerance=0.05), {}),
        "search_radius": ("search area", s(strategy="radius", radius=20.0), {}),
        "search_global": ("search area", s(strategy="global"), {}),
        "rank_popcount": ("feature ranking", f(ranking="popcount"), {}),
        "rank_grid": ("feature ranking", f(ranking="grid"), {}),
        "area_whole": ("extraction area", f(use_gradient_mask=False), {"use_mapped_pixels": False}),
        "area_gradient": ("extraction area", f(use_gradient_mask=True),
                          {"use_mapped_pixels": False}),
    }


# Issue #19: K = 15 stored per keyframe, the ways to make it recall (docs/DETECTOR.md, "Sparse
# K = 15"), beside the symmetric K = 15 of the paper and the default. name -> (label, detector).
def sparse_variants():
    k15 = {"features": {"max_features": 15}}
    return {
        "sparse_sym": ("K = 15 symmetric (the paper)", k15),
        "sparse_asym": ("K = 15 asymmetric", {**k15, "asymmetric_matching": True}),
        "sparse_rep2": ("K = 15 repeatability (2)", {**k15, "repeatability_window": 2}),
        "sparse_asym_weak": ("K = 15 asymmetric + weak pairs (6)",
                             {**k15, "asymmetric_matching": True, "weak_pairs": True}),
        "sparse_rep4_weak": ("K = 15 repeatability (4) + weak pairs (6)",
                             {**k15, "repeatability_window": 4, "weak_pairs": True}),
        "sparse_preset": ("bench/configs/sparse_k15.json (+ appearance fallback)", json.loads(
            (ROOT / "bench" / "configs" / "sparse_k15.json").read_text())["detector"]),
    }


ABLATION_LABELS = {
    "default": "default (paper search, response ranking, mapped pixels)",
    "search_paper_drift": "paper + drift tolerance 5 %",
    "search_radius": "radius 20 (raw units)",
    "search_global": "global (every past keyframe)",
    "rank_popcount": "popcount ranking (the paper's)",
    "rank_grid": "grid-spread response ranking",
    "area_whole": "whole image",
    "area_gradient": "high-gradient mask (no mapped pixels)",
}


def run_all(r, quick):
    seqs = plan(quick)
    timings = {}
    t0 = time.time()
    threads = "1" if r.jobs > 1 else "2"

    # Robustness renders: a short aerial flight, one degradation at a time.
    robust_base = ["--world", "aerial", "--plan", "figure8", "--laps", "2", "--frames",
                   "240" if quick else "800", "--seed", "3"]
    degradations = ({"noise": [1.5, 20], "blur": [3.0], "photometric": [3.0]} if quick
                    else {"noise": [1.5, 4, 8, 14, 20, 30], "blur": [0.8, 1.5, 2.5, 3.5],
                          "photometric": [2.0, 3.0, 4.0, 5.0]})
    robust = {}
    for kind, values in degradations.items():
        for v in values:
            name = f"robust_{kind}_{v:g}"
            robust[name] = (kind, v)
            seqs[name] = ("aerial", robust_base + [f"--{kind}", str(v)])
    r.parallel(render_tasks(r, seqs, threads))
    drift_scales = [0.0, 1.0, 4.0] if quick else [0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0]
    drift_tasks = []
    for d in drift_scales:
        out = r.out / "seq" / f"street07_drift{d:g}"
        base = with_frames(seqs["street07"][1], SMOKE_FRAMES) if SMOKE_FRAMES else seqs["street07"][1]
        drift_tasks.append((f"drift_{d:g}", [r.bin, "render", *base, "--poses-only",
                                             "--drift", str(d), "--out", out],
                            out / "poses_raw.txt"))
    r.parallel(drift_tasks)
    family_tasks, family = [], []
    for seq, scales in drift_family(quick):
        for d in scales:
            name = seq if d == 1.0 else f"{seq}_df{d:g}"  # the base render has drift 1
            family.append((seq, d, name))
            if d != 1.0:
                family_tasks += render_tasks(r, {name: (seqs[seq][0], seqs[seq][1] +
                                                        ["--drift", str(d)])}, threads)
    r.parallel(family_tasks)
    timings["render_s"] = time.time() - t0

    # Accuracy runs: Table 1 (K sweep), ablations, robustness.
    t1 = time.time()
    tasks, runs = [], {}
    main_seqs = [n for n in seqs if not n.startswith("robust_")]
    for seq in main_seqs:
        for k in k_sweep(quick) + ["default"]:
            variant = f"k{k}"
            task, d = run_task(r, seq, variant, detector_config(None if k == "default" else k))
            tasks.append(task)
            runs[(seq, variant)] = d
    for seq in ("street07", "aerial_circuit"):
        for name, (_, det, pipe) in ablation_variants().items():
            if name == "default":
                continue
            task, d = run_task(r, seq, name, {**({"detector": det} if det else {}), **pipe})
            tasks.append(task)
            runs[(seq, name)] = d
    for seq in ("street07", "aerial_circuit", "aerial_figure8"):
        for name, (_, det) in sparse_variants().items():
            task, d = run_task(r, seq, name, {"detector": det})
            tasks.append(task)
            runs[(seq, name)] = d
    for name in robust:
        task, d = run_task(r, name, "default", {})
        tasks.append(task)
        runs[(name, "default")] = d
    for d in drift_scales:
        poses = r.out / "seq" / f"street07_drift{d:g}" / "poses_raw.txt"
        for variant, det in (("paper", {}), ("paper_drift", {"search": {"drift_tolerance": 0.05}})):
            task, rd = run_task(r, "street07", f"drift{d:g}_{variant}",
                                detector_config(**det), poses=poses)
            tasks.append(task)
            runs[("street07", f"drift{d:g}_{variant}")] = rd
    for seq, d, name in family:
        for variant, cfg in (("new", {}), ("old", OLD_LOOP_DEFAULTS)):
            task, rd = run_task(r, name, f"family_{variant}", cfg)
            tasks.append(task)
            runs[(name, f"family_{variant}")] = rd
    r.parallel(tasks)
    timings["accuracy_runs_s"] = time.time() - t1

    # Baselines: the same frames, sparseloop and the two classic detectors, one at a time (so the
    # time ratios are not disturbed by a neighbour).
    t2 = time.time()
    base_seq = "street07"
    baseline_cfgs = {}
    for b in ("full_global", "full_global_24", "full_ann"):
        p = ROOT / "bench" / "configs" / f"{b}.json"
        if p.exists():
            baseline_cfgs[b] = json.loads(p.read_text())
    base_runs = {}
    for variant, cfg in [("sparseloop_default", {}), ("sparseloop_k15", detector_config(15)),
                         ("sparseloop_k32", detector_config(32))] + list(baseline_cfgs.items()):
        task, d = run_task(r, base_seq, f"baseline_{variant}", cfg)
        r.call(*task)
        base_runs[variant] = d
    timings["baseline_runs_s"] = time.time() - t2

    # External producers and micro-benchmarks, alone on the machine.
    t3 = time.time()
    ext = {
        "detector_accuracy": json_exe(r, "detector_accuracy", ["--data", DATA],
                                      "detector_accuracy"),
        "posegraph_accuracy": json_exe(r, "posegraph_accuracy", ["--data", DATA],
                                       "posegraph_accuracy"),
        # K = 15 (the paper's K): the memory budget of issue #7 is per keyframe record + graph.
        "soak": json_exe(r, "bench_soak", ["--keyframes", SOAK_KEYFRAMES_QUICK if quick else
                                           100000, "--k", 15, "--out", r.out / "soak.csv"],
                         "soak"),
    }
    min_time = ["--benchmark_min_time=0.2"] if quick else []
    # Building the full-ann index of 1,000 keyframes x 1,000 descriptors alone takes ~5 minutes:
    # only the full run measures it.
    extra = {"bench_retrieval": ["--benchmark_filter=-BM_FullAnnQuery/1000"] if quick else []}
    micro = {name: google_bench(r, exe, name, min_time + extra.get(name, [])) for name, exe in (
        ("bench_detector", "bench_detector"), ("bench_search", "bench_search"),
        ("bench_posegraph", "bench_posegraph"), ("bench_retrieval", "bench_retrieval"))}
    timings["micro_s"] = time.time() - t3
    timings["total_s"] = time.time() - t0

    gt_cache = {}
    metrics = {}
    for (seq, variant), d in runs.items():
        world = "street" if seq.startswith("street") else "aerial"
        seq_dir = r.out / "seq" / seq
        metrics.setdefault(seq, {})[variant] = run_metrics(d, seq_dir, world, gt_cache)
    baselines = {v: run_metrics(d, r.out / "seq" / base_seq, "street", gt_cache)
                 for v, d in base_runs.items()}
    return {"sequences": {n: {"world": w, "render_args": a} for n, (w, a) in seqs.items()},
            "k_sweep": k_sweep(quick), "metrics": metrics, "baselines": baselines,
            "baseline_sequence": base_seq, "robust": robust, "drift_scales": drift_scales,
            "drift_family": family,
            "external": ext, "micro": {k: gb_rows(v) for k, v in micro.items()},
            "timings": timings}


# --------------------------------------------------------------------------------------------
# Plots


def plot_table1(res, path):
    fig, ax = plt.subplots(figsize=(7, 4))
    ks = res["k_sweep"]
    for seq, variants in res["metrics"].items():
        if seq.startswith("robust_"):
            continue
        ys = [variants.get(f"k{k}", {}).get("recall_100p", float("nan")) for k in ks]
        ax.plot(ks, ys, marker="o", label=seq)
    ax.set_xscale("log", base=2)
    ax.set_xticks(ks)
    ax.set_xticklabels([str(k) for k in ks])
    ax.set_xlabel("K (features kept per keyframe)")
    ax.set_ylabel("recall at 100% precision")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_accuracy(res, path):
    seqs = [s for s in res["metrics"] if not s.startswith("robust_")]
    fig, axes = plt.subplots(1, len(seqs), figsize=(3.4 * len(seqs), 3.3), squeeze=False)
    for ax, seq in zip(axes[0], seqs):
        m = res["metrics"][seq].get("kdefault", {})
        for which, style in (("raw", "o--"), ("corrected", "o-")):
            pl = m.get(f"{which}_per_length", [])
            ax.plot([p["length_m"] for p in pl], [p["t_err_pct"] for p in pl], style, label=which)
        ax.set_title(seq, fontsize=9)
        ax.set_xlabel("segment length (m)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("KITTI translation error (%)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_robustness(res, path):
    kinds = {}
    for name, (kind, v) in res["robust"].items():
        m = res["metrics"][name]["default"]
        kinds.setdefault(kind, []).append((v, m["recall_100p_accepted"], m["false_accepted"]))
    drift = []
    for d in res["drift_scales"]:
        for variant in ("paper", "paper_drift"):
            m = res["metrics"]["street07"].get(f"drift{d:g}_{variant}")
            if m:
                drift.append((variant, d, m["recall_100p_accepted"], m["false_accepted"]))
    fig, axes = plt.subplots(1, len(kinds) + 1, figsize=(3.3 * (len(kinds) + 1), 3.2))
    units = {"noise": "noise std-dev (gray levels)", "blur": "blur std-dev (px)",
             "photometric": "exposure/gamma change (x default)"}
    for ax, (kind, pts) in zip(axes, sorted(kinds.items())):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label="recall@100%P")
        ax2 = ax.twinx()
        ax2.bar([p[0] for p in pts], [p[2] for p in pts], width=0.05 * max(p[0] for p in pts),
                color="tab:red", alpha=0.4, label="false accepted")
        ax2.set_ylim(0, max(3, max(p[2] for p in pts) + 1))
        ax.set_xlabel(units.get(kind, kind))
        ax.set_ylim(0, 1.02)
        ax.set_title(f"aerial: {kind}", fontsize=9)
        ax.grid(alpha=0.3)
    ax = axes[-1]
    for variant, style in (("paper", "o-"), ("paper_drift", "s--")):
        pts = [(d, rc) for v, d, rc, _ in drift if v == variant]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], style, label=variant)
    ax.set_xlabel("raw drift (x default drift rates)")
    ax.set_title("street07: trajectory drift", fontsize=9)
    ax.set_ylim(0, 1.02)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    axes[0].set_ylabel("recall at 100% precision")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def scaling_series(res):
    """Query micro-benchmarks against the number of stored keyframes N -> {name: [(N, ms)]}.

    Rows are named BM_X/N[/other args]; the series key keeps the other args (e.g. K). For
    BM_FullGlobal the whole-query time is `query_ms_extrapolated` (it matches a capped number of
    candidates and scales linearly, see bench_retrieval.cc)."""
    series = {}
    for exe, rows in res["micro"].items():
        for row in rows:
            parts = [p for p in row["name"].split("/") if not p.startswith("iterations:")]
            idx = next((i for i, p in enumerate(parts) if i > 0 and p.isdigit()), None)
            if idx is None:
                continue
            base = "/".join(parts[:idx])
            if not any(w in base for w in ("Query", "PaperArea", "FullGlobal")):
                continue
            n = int(parts[idx])
            if n < 100:
                continue
            ms = row.get("query_ms_extrapolated", row["ms"]) if "FullGlobal" in base else row["ms"]
            rest = [] if "FullGlobal" in base else parts[idx + 1:]
            key = f"{exe}:{base}" + "".join(f"/K={a}" for a in rest)
            series.setdefault(key, []).append((n, ms))
    return {k: sorted(v) for k, v in series.items() if len(v) >= 2}


def plot_scaling(series, path):
    fig, ax = plt.subplots(figsize=(9, 4.2))
    for name, pts in series.items():
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", label=name.split(":", 1)[1])
    ax.set_xlabel("stored keyframes")
    ax.set_ylabel("query time (ms)")
    ax.set_title("Query time against map size (full-global: 1,000 x 1,000 matching per candidate)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_soak(runs, path):
    """runs: a CSV path, or a list of (CSV path, label). Two panels: RSS (current and peak, MiB)
    and mean wall ms per keyframe, against the keyframes pushed."""
    if not isinstance(runs, list):
        runs = [(runs, None)]
    fig, (ax_mem, ax_time) = plt.subplots(2, 1, figsize=(7.5, 6), sharex=True)
    drawn = False
    for csv_path, label in runs:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
        if not rows:
            continue
        drawn = True
        kf = [float(r["keyframes"]) for r in rows]
        tag = f"{label}: " if label else ""
        line, = ax_mem.plot(kf, [float(r["rss_kib"]) / 1024 for r in rows], "-",
                            label=f"{tag}RSS")
        ax_mem.plot(kf, [float(r["peak_rss_kib"]) / 1024 for r in rows], ":",
                    color=line.get_color(), label=f"{tag}peak RSS")
        ax_time.plot(kf, [float(r["mean_ms"]) for r in rows], "-", color=line.get_color(),
                     label=f"{tag}mean ms / keyframe")
    if not drawn:
        plt.close(fig)
        return False
    ax_mem.set_ylabel("MiB")
    ax_mem.grid(alpha=0.3)
    ax_mem.legend(fontsize=7)
    ax_time.set_ylabel("ms per keyframe (wall)")
    ax_time.set_xlabel("keyframes pushed")
    ax_time.grid(alpha=0.3)
    ax_time.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


# --------------------------------------------------------------------------------------------
# BENCHMARKS.md


def json_md(obj, title=None, depth=4):
    """A readable rendering of a producer's JSON: scalars in a key/value table, lists of objects
    as tables, nested objects as subsections."""
    out = []
    if title:
        out.append("#" * depth + " " + title)
    if isinstance(obj, dict):
        scalars = [(k, v) for k, v in obj.items() if not isinstance(v, (dict, list))]
        if scalars:
            out.append(table(["key", "value"], [[k, v if not isinstance(v, bool) else str(v)]
                                                for k, v in scalars]))
        for k, v in obj.items():
            if isinstance(v, (dict, list)):
                out.append(json_md(v, k, min(depth + 1, 6)))
    elif isinstance(obj, list):
        if obj and all(isinstance(x, dict) for x in obj):
            keys = []
            for x in obj:
                keys += [k for k, v in x.items() if k not in keys and not isinstance(v, (dict, list))]
            out.append(table(keys, [[x.get(k, "") if not isinstance(x.get(k), bool)
                                     else str(x.get(k)) for k in keys] for x in obj]))
        else:
            out.append(", ".join(fmt(x) for x in obj))
    return "\n\n".join(s for s in out if s)


def stage_row(label, m, base_total=None):
    t = m.get("timing_ms", {})
    g = lambda stage, q: t.get(stage, {}).get(q, float("nan"))  # noqa: E731
    row = [label, m["recall_100p_accepted"], m["false_detected"], m["false_accepted"]]
    for stage in ("extract", "search", "match", "verify", "total"):
        row.append(f"{fmt(g(stage, 'median'))} / {fmt(g(stage, 'p99'))}")
    ratio = g("total", "median") / base_total if base_total else float("nan")
    row += [ratio, m["bytes_per_keyframe"]]
    return row


def write_markdown(res, args, docs):
    mc = res["machine"]
    mode = "--quick" if args.quick else "(full)"
    md = []
    md.append("# Benchmarks\n")
    md.append(f"Generated by `scripts/benchmark {mode if args.quick else ''}`".rstrip() +
              f" on {mc['date']}, commit `{mc['commit']}`. **Do not edit by hand**: every number "
              "below comes from this script's output (`results.json` in its output folder).\n")
    md.append(table(["machine", "value"], [["CPU", mc["cpu"]], ["cores", mc["cores"]],
                                            ["memory (GiB)", mc["mem_gib"]], ["OS", mc["os"]],
                                            ["mode", "quick" if args.quick else "full"],
                                            ["parallel experiments", args.jobs]]))
    tm = res["timings"]
    md.append(f"\nWall time: rendering {tm['render_s']:.0f} s, accuracy runs "
              f"{tm['accuracy_runs_s']:.0f} s, baselines {tm['baseline_runs_s']:.0f} s, "
              f"micro-benchmarks {tm['micro_s']:.0f} s; total {tm['total_s']:.0f} s "
              "(the Release build before it is not included).\n")
    md.append("Reproduce: `scripts/benchmark --quick` (this file; 10-18 minutes after the "
              "build on the 2-core hosts it ran on, this run's time above) or `scripts/benchmark` (full: KITTI 00/05/06/07 street worlds, the whole K "
              "range, longer robustness curves; about an hour). Real-data sections need "
              "`../shared/data` (or `SPARSELOOP_DATA`).\n")

    # ---- targets
    md.append(targets_section(res))
    md.append(scoring_section())
    md.append(table1_section(res))
    md.append(ablation_section(res))
    md.append(sparse_section(res))
    md.append(baseline_section(res))
    md.append(accuracy_section(res))
    md.append(drift_family_section(res))
    md.append(robustness_section(res))
    md.append(external_section(res))
    md.append(micro_section(res))
    text = "\n".join(md) + "\n"
    tmp = docs / "BENCHMARKS.md.tmp"
    tmp.write_text(text)
    tmp.replace(docs / "BENCHMARKS.md")


def default_runs(res):
    """Every run made with default options: (label, metrics)."""
    out = []
    for seq, variants in res["metrics"].items():
        for v, m in variants.items():
            if v in ("kdefault", "default", "family_new") or v.endswith("_paper"):
                out.append((f"{seq}/{v}", m))
    for v, m in res["baselines"].items():
        if v == "sparseloop_default":
            out.append((f"{res['baseline_sequence']}/baseline default", m))
    return out


def targets_section(res):
    rows = []
    runs = default_runs(res)
    false_acc = sum(m["false_accepted"] for _, m in runs)
    worst = [l for l, m in runs if m["false_accepted"] > 0]
    rows.append(["zero false loops accepted, default options, every experiment",
                 f"{false_acc} false accepted over {len(runs)} runs" +
                 (f" ({', '.join(worst[:4])})" if worst else ""),
                 "met" if false_acc == 0 else "**missed**", ""])
    b = res["baselines"]
    fg = b.get("full_global")
    small_k = [(k, res["metrics"][res["baseline_sequence"]].get(f"k{k}", {}).get(
        "recall_100p_accepted", float("nan"))) for k in res["k_sweep"] if k <= 32]
    best_k, best_r = max(small_k, key=lambda x: -1 if math.isnan(x[1]) else x[1])
    if fg:
        # Compare with the better of the two full-global thresholds.
        fg_r = max(b[v]["recall_100p_accepted"] for v in ("full_global", "full_global_24") if v in b)
        if fg_r > 0:
            st = status(best_r, best_r >= fg_r)
        else:
            st = "not meaningful (the baseline recalls nothing here)"
        why = ""
        if "missed" in st:
            fg24 = b.get("full_global_24", {})
            why = ("K <= 32 features give at most K descriptor matches, and on these street frames "
                   "few pairs reach the small-K floors (8 matches and 8 inliers at K = 15, 12 "
                   "from K = 30) in verification; the baseline's recall "
                   "comes from 1,000 features at a 24-inlier threshold, paid for with "
                   f"{fg24.get('false_detected', '?')} false detections that only the pose "
                   "graph's outlier rejection removed. At the default K sparseloop recalls "
                   f"{fmt(res['metrics'][res['baseline_sequence']].get('kdefault', {}).get('recall_100p_accepted', float('nan')))}"
                   " with no false detection.")
        rows.append([f"street recall@100%P at K <= 32 >= full-global's ({res['baseline_sequence']})",
                     f"best K <= 32: K={best_k}, {fmt(best_r)} vs best full-global {fmt(fg_r)}", st,
                     why])
        sl = b["sparseloop_default"]
        ratio = fg["ms_total_median"] / sl["ms_total_median"]
        rows.append([f"time per keyframe >= 5x lower than full-global (at {fg['keyframes']} "
                     "keyframes, end to end)", f"{fmt(ratio, 1)}x (median total "
                     f"{fmt(sl['ms_total_median'])} vs {fmt(fg['ms_total_median'])} ms)",
                     status(ratio, ratio >= 5),
                     "" if ratio >= 5 else "matching dominates at this map size"])
        for label in ("sparseloop_default", "sparseloop_k32", "sparseloop_k15"):
            if label in b:
                r = fg["bytes_per_keyframe"] / b[label]["bytes_per_keyframe"]
                budget = fg["bytes_per_keyframe"] / 50
                rows.append([f"bytes per keyframe <= 1/50 of full-global ({label})",
                             f"1/{fmt(r, 1)} ({fmt(b[label]['bytes_per_keyframe'], 0)} vs "
                             f"{fmt(fg['bytes_per_keyframe'], 0)} B)",
                             "met" if r >= 50 else "**missed**",
                             "" if r >= 50 else
                             f"1/50 is {fmt(budget, 0)} B; a packed record costs 38 B per feature "
                             "(32 B descriptor, 4 B keypoint, 2 B depth) plus 56 B fixed (48 B "
                             "header, 8 B owning pointer; include/sparseloop/core/packed_keyframe.h),"
                             f" so only K <= {max(0, int((budget - 56) // 38))} fits"])
    else:
        rows.append(["baselines", "bench/configs/full_global.json missing", "**not measured**",
                     ""])
    series = scaling_series(res)
    for name, pts in series.items():
        if any(w in name for w in ("PaperArea", "QueryStoredKeyframes", "BM_Query/paper")):
            growth = pts[-1][1] / pts[0][1]
            rows.append([f"query time flat from {pts[0][0]} to {pts[-1][0]} keyframes ({name})",
                         f"x{fmt(growth)} ({fmt(pts[0][1], 3)} -> {fmt(pts[-1][1], 3)} ms)",
                         "met" if growth < 2 else "**missed**", ""])
    for seq, variants in res["metrics"].items():
        if seq.startswith("street") and "kdefault" in variants:
            m = variants["kdefault"]
            rows.append([f"corrected KITTI t_err < 1.5 % ({seq})",
                         f"{fmt(m['corrected_t_err_pct'])} % (raw {fmt(m['raw_t_err_pct'])} %)",
                         status(m["corrected_t_err_pct"], m["corrected_t_err_pct"] < 1.5), ""])
    micro = {row["name"]: row for rows_ in res.get("micro", {}).values() for row in rows_}
    proc = micro.get("BM_ProcessKittiKeyframe/K:300/paper:1/iterations:160")
    if proc:
        t = proc.get("total_ms", float("nan"))
        # Same-run baseline: plain cv::ORB::detectAndCompute (1,000 features, no mask) on the same
        # frames, what a feature-based vSLAM already spends per frame; the ratio is comparable
        # across hosts, the milliseconds are not.
        orb = micro.get("BM_ExtractKitti/K:300/area:0/fast:0/iterations:320")
        ratio = (f"; {fmt(t / orb['total_ms'])}x plain cv::ORB (1,000 features, no mask, "
                 f"{fmt(orb['total_ms'])} ms) in the same run" if orb and orb.get("total_ms")
                 else "")
        rows.append(["#3: Process() median <= 5 ms per 1226x370 KITTI keyframe, one core (default "
                     "K = 300, paper search, kitti07_first160 GT poses)",
                     f"{fmt(t)} ms (extract {fmt(proc.get('extract_ms', float('nan')))} ms){ratio}",
                     status(t, t <= 5.0), "" if t <= 5.0 else
                     "ORB extraction in the high-gradient area is the whole cost; this shared VM "
                     "varies up to 2x between hosts and, on some days, 1.5x between consecutive "
                     "runs of the same binary (plain ORB 5.3-7.8 ms, Process()/ORB 1.03-1.22 "
                     "with the same detector code), so compare the ratio across runs "
                     "(docs/DETECTOR.md, Speed)"])
    eu = res.get("external", {}).get("detector_accuracy", {}).get("euroc", [])
    for depths in ("none", "stereo"):
        pairs = [e for e in eu if e.get("depths", "none") == depths]
        if pairs:
            ok = all(e.get("status") == "detected" and e.get("rotation_error_deg", 99) < 3.0
                     for e in pairs)
            got = ", ".join(f"{e['pair'][0]}-{e['pair'][1]} {e.get('status')} "
                            f"{fmt(e.get('rotation_error_deg', float('nan')))} deg" +
                            (" (planar alternative)" if e.get("planar_alternative") else "")
                            for e in pairs)
            rows.append([f"#3: euroc_loop_pairs both verified, rotation < 3 deg "
                         f"({'monocular' if depths == 'none' else 'stereo depths'})", got,
                         "met" if ok else "**missed**", "" if ok else "docs/DETECTOR.md"])
    for case, label in (("WarmNewLoop", "warm re-solve after one new loop"),
                        ("Cold", "cold solve")):
        row = next((v for k, v in micro.items()
                    if k.startswith(f"BM_PoseGraphSim3{case}/5000/100")), None)
        full = next((v for k, v in micro.items()
                     if k.startswith(f"BM_PoseGraphSim3{case}FullGraph/5000/100")), None)
        if row:
            ms = row["cpu_ms"]
            ok = ms <= 100.0  # two frames at 20 Hz, one at 10 Hz
            got = f"{fmt(ms, 1)} ms CPU"
            if full:
                got += (f" (every vertex in the solve: {fmt(full['cpu_ms'], 1)} ms, "
                        f"{fmt(full['cpu_ms'] / ms, 1)}x, same run)")
            rows.append([f"#4: 5,000-keyframe Sim(3) graph, 100 loops, {label}: about a frame or "
                         "two (<= 100 ms: 2 frames at 20 Hz)", got,
                         status(ms, ok), "" if ok else
                         "sparse Cholesky (CHOLMOD) is most of it, symbolic analysis redone at "
                         "every Solve (docs/POSEGRAPH.md, Speed)"])
    return ("\n## Targets (issues #3, #4, #6)\n\n" +
            table(["target", "measured", "status", "why, where missed"], rows) + "\n")


def scoring_section():
    rows = [[w, r["revisit_m"], r["gap_m"], r["angle_deg"], r["correct_m"]]
            for w, r in GT_RULES.items()]
    return ("\n## How loops are scored\n\nEach rendered frame is a keyframe. A query frame has a "
            "**GT revisit** when an earlier frame lies within `revisit` metres, at least `gap` "
            "metres of path back, with optical axes closer than `angle` (so the views can "
            "overlap). A detection is **correct** when its two frames are closer than `correct` "
            "metres; detections of the same place moments ago (closer than `correct`, less than "
            "`gap` of path apart) are neither loops nor errors and are ignored for every method. "
            "**Recall at 100% precision**: detections sorted by score, cut before the first false "
            "one; the fraction of GT revisit query frames with a correct detection above the cut. "
            "`accepted` = after the pose graph's outlier rejection. A **loop event** is a run of "
            "consecutive GT revisit frames; `+` means every event got a correct accepted loop.\n\n"
            + table(["world", "revisit (m)", "gap (m)", "angle (deg)", "correct (m)"], rows) + "\n")


def table1_section(res):
    ks = res["k_sweep"] + ["default"]
    rows = []
    for seq, variants in res["metrics"].items():
        if seq.startswith("robust_"):
            continue
        row = [seq]
        for k in ks:
            m = variants.get(f"k{k}")
            if not m:
                row.append("")
                continue
            sign = "+" if m["events"] and m["events_detected"] == m["events"] else "-"
            fa = f", {m['false_accepted']} FA" if m["false_accepted"] else ""
            row.append(f"{sign} {fmt(m['recall_100p_accepted'])}{fa}")
        rows.append(row)
    n_events = {seq: v.get("kdefault", {}).get("events", 0) for seq, v in res["metrics"].items()}
    text = ("\n## Paper Table 1, reproduced: loop detected (+/-) and recall at 100% precision "
            "against K\n\nCells: `+`/`-` (every loop event detected or not), recall at 100% "
            "precision after outlier rejection, and `FA` = false loops accepted (when any). "
            "`default` is the shipped K. Loop events per sequence: " +
            ", ".join(f"{s} {n}" for s, n in n_events.items() if not s.startswith("robust")) +
            ".\n\n" + table(["sequence"] + [f"K={k}" for k in ks], rows) + "\n\n"
            "![recall vs K](img/bench_table1.png)\n")
    smallest = None
    for k in res["k_sweep"]:
        ok = all(v.get(f"k{k}", {}).get("events_detected", -1) == v.get(f"k{k}", {}).get("events")
                 and v.get(f"k{k}", {}).get("false_accepted", 1) == 0
                 for s, v in res["metrics"].items() if not s.startswith("robust_"))
        if ok:
            smallest = k
            break
    text += ("\nSmallest K that detects every loop event on every rendered sequence with no false "
             f"loop accepted: **{smallest if smallest else 'none in the sweep'}** (the paper: "
             "K=15).\n")
    da = res["external"].get("detector_accuracy", {})
    if "missing" not in da:
        text += real_sets_md(da)
    else:
        text += f"\nReal sets: not measured ({da['missing']}).\n"
    return text


def ablation_section(res):
    rows = []
    for seq in ("street07", "aerial_circuit"):
        variants = res["metrics"].get(seq, {})
        for name, (group, _, _) in ablation_variants().items():
            m = variants.get("kdefault" if name == "default" else name)
            if not m:
                continue
            rows.append([seq, group or "-", ABLATION_LABELS[name], m["recall_100p_accepted"],
                         m["false_detected"], m["false_accepted"], m["ms_total_median"],
                         m["timing_ms"].get("search", {}).get("median", float("nan")),
                         m["bytes_per_keyframe"]])
    return ("\n## Ablations (default K)\n\n" +
            table(["sequence", "group", "variant", "recall@100%P", "false detected",
                   "false accepted", "ms/kf median", "search ms median", "bytes/kf"], rows) + "\n")


def sparse_section(res):
    rows = []
    for seq in ("street07", "aerial_circuit", "aerial_figure8"):
        variants = res["metrics"].get(seq, {})
        for name, label in [("kdefault", "default (K = 300, symmetric)")] + [
                (n, l) for n, (l, _) in sparse_variants().items()]:
            m = variants.get(name)
            if not m:
                continue
            rows.append([seq, label, m["recall_100p_accepted"], m["events_detected"],
                         m["false_detected"], m["false_accepted"], m["ms_total_median"],
                         m["ms_total_p99"], m["bytes_per_keyframe"]])
    return ("\n## Sparse K = 15 (issue #19)\n\nStored records of K = 15; asymmetric matching "
            "(the query's whole extraction against the stored 15), repeatability ranking (store "
            "first the features the previous keyframes re-find) and weak pairs (6-7 inliers, "
            "accepted only when the keyframe before verified the same place); "
            "docs/DETECTOR.md, \"Sparse K = 15\".\n\n" +
            table(["sequence", "variant", "recall@100%P", "events", "false detected",
                   "false accepted", "ms/kf median", "ms/kf p99", "bytes/kf"], rows) + "\n")


def baseline_section(res):
    b = res["baselines"]
    sl = b.get("sparseloop_default")
    rows = [stage_row(v, m, sl["ms_total_median"] if sl else None) for v, m in b.items()]
    text = (f"\n## Baselines on the same frames ({res['baseline_sequence']}, "
            f"{sl['keyframes'] if sl else '?'} keyframes, run one at a time)\n\n"
            "`full_global`: 1,000 ORB per keyframe from the whole image, every past keyframe "
            "but the 50 most recent a candidate (the temporal window classic detectors use, else "
            "the previous seconds of driving win every query), the same verification (at least "
            "max(12, 8 % of K) = 80 inliers), no pose prior. `full_global_24`: the same with the "
            "absolute inlier threshold of sparseloop's default (24), to show what a lower "
            "threshold costs without the pose prior. `full_ann`: the `full_global` features in an "
            "approximate nearest-neighbour index (FAISS), top-voted keyframes verified. Stage cells are "
            "median / p99 ms; `x total` = median total time relative to sparseloop's default.\n\n" +
            table(["method", "recall@100%P", "false detected", "false accepted", "extract",
                   "search", "match", "verify", "total", "x total", "bytes/kf"], rows) + "\n")
    series = scaling_series(res)
    if series:
        rows = [[name] + [f"{n}: {fmt(ms, 3)} ms" for n, ms in pts] for name, pts in series.items()]
        width = max(len(r) for r in rows)
        rows = [r + [""] * (width - len(r)) for r in rows]
        text += ("\nQuery time against the number of stored keyframes (micro-benchmarks, log-log "
                 "plot below):\n\n" + table(["benchmark"] + [f"size {i + 1}" for i in
                                                             range(width - 1)], rows) +
                 "\n\n![query scaling](img/bench_query_scaling.png)\n")
    return text


def accuracy_section(res):
    rows = []
    for seq, variants in res["metrics"].items():
        m = variants.get("kdefault")
        if not m:
            continue
        rows.append([seq, m["raw_t_err_pct"], m["corrected_t_err_pct"], m["raw_r_err"],
                     m["corrected_r_err"], m["raw_ate_m"], m["corrected_ate_m"],
                     m["optimizer_ms"]])
    text = ("\n## Trajectory accuracy, raw vs corrected (paper Fig. 6/7)\n\nKITTI devkit metric "
            "(segments of 100..800 m) and Sim(3)-aligned ATE; default options.\n\n" +
            table(["sequence", "raw t_err %", "corrected t_err %", "raw r_err deg/100m",
                   "corrected r_err deg/100m", "raw ATE m", "corrected ATE m", "solve ms"], rows)
            + "\n\n![error vs distance](img/bench_accuracy.png)\n")
    pa = res["external"].get("posegraph_accuracy", {})
    if "missing" not in pa:
        text += ("\nReal vSLAM drift (`posegraph_accuracy`: loops from GT as a monocular vSLAM "
                 "would measure them; see docs/POSEGRAPH.md):\n\n" + posegraph_md(pa) + "\n")
    else:
        text += f"\nReal vSLAM drift: not measured ({pa['missing']}).\n"
    return text


def drift_family_section(res):
    rows = []
    for seq, d, name in res.get("drift_family", []):
        for variant in ("old", "new"):
            m = res["metrics"].get(name, {}).get(f"family_{variant}")
            if not m:
                continue
            ratio = m["corrected_ate_m"] / m["raw_ate_m"] if m["raw_ate_m"] > 0 else float("nan")
            rows.append([seq, d, "old loop options" if variant == "old" else "today",
                         m["raw_ate_m"], m["corrected_ate_m"], f"{100 * ratio:.0f} %",
                         m["raw_t_err_pct"], m["corrected_t_err_pct"],
                         m["recall_100p_accepted"], m["false_detected"], m["false_accepted"]])
    return ("\n## Loop correction under drift (issue #18)\n\nEach sequence rendered at x1 and "
            "x4 the default drift rates (x1, x2, x4 in the full run), each render complete (its "
            "mapped depths in its own raw units). `today`: default options; `old loop options`: "
            "the loop and odometry weights and the gate rate before session 8 (fixed loop sigmas, "
            "odometry 2 % / 0.002 rad / 0.002 per step, gate 0.1 deg per keyframe: "
            "`OLD_LOOP_DEFAULTS` in scripts/benchmark.py), same run; the gate's prior along the "
            "loop graph (session 8) is in both. Targets: "
            "corrected ATE <= 30 % of raw and KITTI t_err <= 1 % where loops exist; zero false "
            "loops accepted.\n\n" +
            table(["sequence", "drift x", "options", "raw ATE m", "corrected ATE m", "ratio",
                   "raw t_err %", "corrected t_err %", "recall@100%P", "false detected",
                   "false accepted"], rows) + "\n")


def robustness_section(res):
    rows = []
    for name, (kind, v) in sorted(res["robust"].items(), key=lambda x: (x[1][0], x[1][1])):
        m = res["metrics"][name]["default"]
        rows.append([kind, v, m["recall_100p_accepted"], m["false_detected"], m["false_accepted"]])
    for d in res["drift_scales"]:
        for variant in ("paper", "paper_drift"):
            m = res["metrics"]["street07"].get(f"drift{d:g}_{variant}")
            if m:
                rows.append([f"drift ({variant})", d, m["recall_100p_accepted"],
                             m["false_detected"], m["false_accepted"]])
    return ("\n## Robustness curve\n\nImage degradation on a short aerial flight (one factor at a "
            "time; default noise 1.5, blur 0, exposure x1) and raw-trajectory drift on street07 "
            "(x the default drift rates; images unchanged) with the paper search area, without and "
            "with the 5 % drift tolerance.\n\n" +
            table(["factor", "value", "recall@100%P", "false detected", "false accepted"], rows) +
            "\n\n![robustness](img/bench_robustness.png)\n")


def real_sets_md(da):
    """detector_accuracy's JSON as the tables of docs/DETECTOR.md (default options unless noted)."""
    text = "\n### Real sets (`detector_accuracy`, real images)\n"
    castle = da.get("castle", {})
    if castle:
        rows = [[f"{l['query']} -> {l['match']}", l["inliers"], l["rotation_error_deg"],
                 l["translation_direction_error_deg"]] for l in castle.get("loops", [])]
        text += ("\ncastle_p30_768, views 1..29 in order, GT poses as raw poses, default options: "
                 f"ring closure found: **{castle.get('ring_closure_found')}**; every reported "
                 "loop (targets: rotation < 2 deg, translation direction < 5 deg):\n\n" +
                 table(["loop", "inliers", "rotation err deg", "direction err deg"], rows) + "\n")
    eu = da.get("euroc", [])
    if eu:
        rows = [[f"{e['pair'][0]}-{e['pair'][1]}", e.get("depths", "none"), e.get("status"),
                 e.get("method", ""), "yes" if e.get("planar_alternative") else "no",
                 e.get("matches"), e.get("inliers"),
                 e.get("rotation_error_deg"), e.get("translation_direction_error_deg"),
                 e.get("translation_error_m", "")] for e in eu]
        text += ("\neuroc_loop_pairs (two images each, global search; target: both verified, "
                 "rotation < 3 deg). `stereo`: the keyframes carry the left image's ORB corners "
                 "with StereoSGBM depths, what a stereo vSLAM hands over (tests/support/"
                 "euroc_pairs.h); `none`: monocular, where pair 2-3 is near-planar: its "
                 "lowest-cost essential model is ~21 deg off, the pose-prior check rejects it "
                 "and takes a homography decomposition instead (`planar`; docs/DETECTOR.md, "
                 "\"Planar alternatives\"):\n\n" +
                 table(["pair", "depths", "status", "method", "planar", "matches", "inliers",
                        "rotation err deg", "direction err deg", "translation err m"],
                       rows) + "\n")
    cp = da.get("castle_pairs", {})
    if cp:
        pairs = sorted({p for ks in cp.values() for prs in ks.values() for p in prs})
        rows = []
        for ranking, ks in cp.items():
            for k in sorted(ks, key=int):
                rows.append([ranking, k] + [f"{ks[k][p]['matches']}/{ks[k][p]['inliers']}"
                                            if p in ks[k] else "" for p in pairs])
        truth = {p: any(ks[k].get(p, {}).get("true_loop") for ks in cp.values() for k in ks)
                 for p in pairs}
        text += ("\ncastle pairs, descriptor matches / essential-matrix inliers by ranking and K "
                 "(" + ", ".join(f"{p} {'true loop' if truth[p] else 'false pair'}"
                                 for p in pairs) + "):\n\n" +
                 table(["ranking", "K"] + pairs, rows) + "\n")
    rt = da.get("rtabmap", {})
    if rt:
        rankings = [k for k, v in rt.items() if isinstance(v, dict)]
        ks = sorted({k for r in rankings for k in rt[r]}, key=int)
        rows = [[r] + [rt[r][k]["recall_at_full_precision"] if k in rt[r] else "" for k in ks]
                for r in rankings]
        prec = min(rt[r][k]["precision"] for r in rankings for k in rt[r])
        text += ("\nrtabmap_corridor_loop (no poses: global search; "
                 f"{rt.get('queries_with_gt', '?')} query images with a GT loop): recall at 100 % "
                 f"precision by ranking and K; lowest precision in the table: **{fmt(prec, 3)}**"
                 "\n\n" + table(["ranking"] + [f"K={k}" for k in ks], rows) + "\n")
    return text


def posegraph_md(pa):
    text = ""
    drift = pa.get("drift", {})
    if drift:
        rows = []
        for seq, d in drift.items():
            c, f, p = d.get("clean", {}), d.get("false_20pct", {}), d.get("false_20pct_plain_ls", {})
            pct = lambda x: f"{fmt(x.get('ate_m'), 3)} ({fmt(100 * x.get('ratio', float('nan')), 0)} %)"  # noqa: E731
            rows.append([seq, d.get("keyframes"), c.get("loops"), fmt(d.get("raw_ate_m"), 3),
                         pct(c), status(c.get("ratio", float("nan")),
                                        c.get("ratio", 9) <= 0.30),
                         pct(f) + f", {f.get('accepted_false', '?')} of "
                         f"{f.get('loops_false', '?')} false accepted",
                         status(f.get("ratio", float("nan")), f.get("ratio", 9) <= 0.40), pct(p),
                         f"{fmt(100 * d.get('clean_se3', {}).get('ratio', float('nan')), 0)} % / "
                         f"{fmt(100 * d.get('clean_four_dof', {}).get('ratio', float('nan')), 0)} %"])
        text += ("Sim(3)-aligned ATE in metres (and as % of raw). Targets (issue #4): <= 30 % of "
                 "raw with true loops, <= 40 % with 20 % false loops; plain least squares on the "
                 "same graph for comparison. Where a target is missed, why (docs/POSEGRAPH.md has "
                 "the diagnostics): KITTI 09 revisits only at its end, where the raw trajectory "
                 "already closes within a few metres, so its loops observe almost none of the "
                 "drift inside the loop; on EuRoC the raw VIO's error is mostly local (per-step "
                 "translation errors of 9-17 %, a per-window Sim(3) alignment already leaves "
                 "13-28 % of the ATE), which odometry edges reproduce and loops between revisits "
                 "cannot remove. Noise-free loops give the same ratios. Last column: the same "
                 "true loops on SE(3) / 4-DoF vertices (the EuRoC VIO is metric, but its scale "
                 "is a few per cent off, which only Sim(3) vertices correct).\n\n" +
                 table(["sequence", "keyframes", "loops", "raw ATE", "true loops", "<= 30 %",
                        "20 % false, PCM", "<= 40 %", "20 % false, plain LS",
                        "true loops, SE(3) / 4-DoF"], rows) + "\n")
    graphs = pa.get("graphs", {})
    if graphs:
        rows = [[g, v.get("initial_cost"), v.get("final_cost"), v.get("iterations"),
                 v.get("solve_seconds"), v.get("status"),
                 f"{fmt(v['ate_before_m'], 3)} -> {fmt(v['ate_after_m'], 3)}"
                 if "ate_after_m" in v else ""]
                for g, v in graphs.items()]
        text += ("\nStandard pose graphs (Ceres LM, sparse normal Cholesky):\n\n" +
                 table(["graph", "initial cost", "final cost", "iterations", "solve s",
                        "status", "ATE vs GT m (initial -> final)"], rows) + "\n")
    rest = {k: v for k, v in pa.items() if k not in ("drift", "graphs")}
    if rest:
        text += "\n" + json_md(rest) + "\n"
    return text


def soak_md(soak):
    slope = soak.get("rss_bytes_per_keyframe_second_half", float("nan"))
    rows = [["keyframes pushed", soak.get("keyframes")], ["K", soak.get("k")],
            ["check every", soak.get("check_every")], ["optimizer", soak.get("optimizer")],
            ["loops detected", soak.get("loops")], ["completed solves", soak.get("solves")],
            ["record bytes per keyframe (Bytes())", soak.get("record_bytes_per_keyframe")],
            ["RSS growth per keyframe, 2nd half (B)", slope],
            ["RSS at start / end / peak (MiB)",
             f"{fmt(soak.get('rss_start_kib', 0) / 1024, 0)} / "
             f"{fmt(soak.get('rss_end_kib', 0) / 1024, 0)} / "
             f"{fmt(soak.get('peak_rss_kib', 0) / 1024, 0)}"],
            ["mean ms per keyframe (wall)", soak.get("ms_per_keyframe")],
            ["wall time (s)", soak.get("total_seconds")]]
    full = soak.get("keyframes", 0) >= 100000
    verdict = ("met" if slope <= 2048 else "missed") if full else "not judged in quick mode"
    return ("Synthetic nadir flight (`bench_soak`, docs/ROBUSTNESS.md), detector + background "
            "optimiser. Target (issue #7): RSS growth <= 2 KiB per keyframe beyond the fixed "
            f"overhead, over 100,000 keyframes: **{verdict}**; measured "
            f"{fmt(slope, 0)} B/keyframe over the second half of {soak.get('keyframes')} "
            "keyframes" + ("" if full else " (the 100,000-keyframe runs: the full mode, and the "
                           "record of `scripts/soak` below)") + ".\n\n" +
            table(["quantity", "value"], rows))


def external_section(res):
    soak = res["external"].get("soak", {})
    text = "\n## Long run (soak)\n\n"
    if "missing" in soak:
        text += f"Not measured ({soak['missing']}).\n"
    else:
        text += soak_md(soak) + "\n\n![soak](img/bench_soak.png)\n"
    rec = res.get("soak_record")
    if rec:
        text += ("\n### Long run, 100,000 keyframes (recorded by `scripts/soak`)\n\n"
                 "The two 100,000-keyframe runs take ~12 minutes side by side, so this script "
                 "renders the "
                 "record `scripts/soak` wrote into bench/results/ (commit, date and conditions "
                 "below) instead of re-running it in quick mode. Two runs: the default "
                 "(`release_memory_after_solve`, the solver's freed heap returned to the system "
                 "after each solve) and `--keep-heap`.\n\n")
        for run in rec["runs"]:
            label = ("default (release_memory_after_solve)" if run.get("release_memory_after_solve",
                                                                       True)
                     else "--keep-heap")
            text += (f"**{label}**, commit {run.get('commit')}, {run.get('date')}, "
                     f"{run.get('conditions')}:\n\n" + soak_md(run) + "\n\n")
        text += "![soak, 100k keyframes](img/bench_soak_100k.png)\n"
    return text


def micro_section(res):
    text = "\n## Micro-benchmarks (Google Benchmark, Release)\n"
    for exe, rows in res["micro"].items():
        if not rows:
            text += f"\n`{exe}`: not built.\n"
            continue
        extra = sorted({k for r in rows for k in r if k not in ("name", "ms", "cpu_ms")})
        text += f"\n`{exe}`:\n\n" + table(["benchmark", "real ms", "cpu ms"] + extra,
                                          [[r["name"], r["ms"], r["cpu_ms"]] +
                                           [r.get(k, "") for k in extra] for r in rows]) + "\n"
    return text


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", required=True, help="build folder with bin/sparseloop")
    ap.add_argument("--quick", action="store_true", help="the <10 minute subset")
    ap.add_argument("--out", help="output folder (default out/bench-quick or out/bench-full)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--reuse", action="store_true", help="skip experiments whose output exists")
    ap.add_argument("--docs", default=str(ROOT / "docs"), help="where BENCHMARKS.md goes")
    ap.add_argument("--smoke", type=int, default=0,
                    help="test the script itself: every sequence cut to this many frames")
    args = ap.parse_args()
    if not DATA.exists():
        sys.exit(f"benchmark: data folder {DATA} not found (set SPARSELOOP_DATA)")
    out = Path(args.out or ROOT / "out" / ("bench-quick" if args.quick else "bench-full"))
    r = Runner(args.build, out, args.jobs, args.reuse)
    global SMOKE_FRAMES
    SMOKE_FRAMES = args.smoke
    res = run_all(r, args.quick)
    rec = RESULTS / "soak_100k.json"
    if rec.exists():
        res["soak_record"] = json.loads(rec.read_text())
    res["machine"] = machine()
    res["command"] = " ".join(sys.argv)
    (r.out / "results.json").write_text(json.dumps(res, indent=1, default=str))
    docs = Path(args.docs)
    img = docs / "img"
    img.mkdir(parents=True, exist_ok=True)
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
