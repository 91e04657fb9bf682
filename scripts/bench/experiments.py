"""Every experiment of docs/BENCHMARKS.md run (or reused) and its numbers collected."""
import concurrent.futures as cf
import json
import time

from .common import *  # noqa: F401,F403
from .plan import *  # noqa: F401,F403
from .runner import *  # noqa: F401,F403
from .scoring import *  # noqa: F401,F403

# --------------------------------------------------------------------------------------------
# The experiments


def family_renders(r, seqs, family_plan, threads):
    """Render tasks of the drift family (the x1 heading render is the sequence's own) and its
    (label, drift, render name) list; the label of a pitch / roll row is "SEQ pitch" / "SEQ roll"."""
    tasks, family = [], []
    for seq, scales, axis in family_plan:
        for d in scales:
            label, name = (seq, seq) if axis is None else (f"{seq} {axis}", f"{seq}_{axis}")
            extra = [] if axis is None else ["--rotation-bias", ROTATION_BIAS_AXES[axis]]
            if d != 1.0:
                name += f"_df{d:g}"
            family.append((label, d, name))
            if name != seq:  # the base render has drift 1 and the heading bias
                tasks += render_tasks(r, {name: (seqs[seq][0], seqs[seq][1] + extra +
                                                 ["--drift", str(d)])}, threads)
    return tasks, family


def family_runs(r, family, runs, sparse=False):
    """Run tasks of the drift family: today's options, the old loop options (OLD_LOOP_DEFAULTS)
    and the paper's search area alone (OLD_AREA_DEFAULTS), side by side (and with `sparse` the
    K = 15 preset, bench/configs/sparse_k15.json); their run folders go into `runs`. The pitch /
    roll rows run today's options (and the preset) only."""
    tasks = []
    variants = [("new", {}), ("old", OLD_LOOP_DEFAULTS), ("oldarea", OLD_AREA_DEFAULTS)]
    if sparse:
        variants.append(("sparse", {"detector": sparse_variants()["sparse_preset"][1]}))
    for label, _, name in family:
        for variant, cfg in variants:
            if " " in label and variant in ("old", "oldarea"):
                continue
            task, rd = run_task(r, name, f"family_{variant}", cfg)
            tasks.append(task)
            runs[(name, f"family_{variant}")] = rd
    return tasks


def collect_metrics(r, runs):
    metrics = {}
    for (seq, variant), d in runs.items():
        world = "street" if seq.startswith("street") else "aerial"
        metrics.setdefault(seq, {})[variant] = run_metrics(r.bin, d, r.out / "seq" / seq, world)
    return metrics


def run_family(r):
    """The drift family alone at its full size: the street worlds along KITTI 00 / 05 / 06 at
    x1 / x2 / x4 and the aerial circuit at x1 / x4, four option sets each; each of them with the
    bias about pitch and about roll at x1 / x4, two option sets each."""
    full = plan(quick=False)
    family_plan = drift_family(quick=False)
    seqs = {seq: full[seq] for seq, _, _ in family_plan}
    threads = "1" if r.jobs > 1 else "2"
    t0 = time.time()
    renders, family = family_renders(r, seqs, family_plan, threads)
    r.parallel(render_tasks(r, seqs, threads) + renders)
    render_s = time.time() - t0
    runs = {}
    t1 = time.time()
    r.parallel(family_runs(r, family, runs, sparse=True))
    runs_s = time.time() - t1
    t2 = time.time()
    castle = castle_family(r)
    return {"sequences": {n: {"world": w, "render_args": a} for n, (w, a) in seqs.items()},
            "metrics": collect_metrics(r, runs), "drift_family": family,
            "castle_family": castle,
            "timings": {"render_s": render_s, "accuracy_runs_s": runs_s,
                        "castle_s": time.time() - t2, "total_s": time.time() - t0}}


def castle_family(r):
    """The castle ring under pitch / yaw / roll bias (bench/castle_drift), each option
    set of CASTLE_DRIFT_VARIANTS; variant -> castle_drift's JSON (or {"missing": why})."""
    args = ["--data", DATA] + (["--seeds", "11", "--biases", "1"] if r.smoke_frames else [])
    with cf.ThreadPoolExecutor(max_workers=r.jobs) as pool:
        futures = {v: pool.submit(json_exe, r, "castle_drift", args + extra, f"castle_drift_{v}")
                   for v, _, extra in CASTLE_DRIFT_VARIANTS}
        return {v: f.result() for v, f in futures.items()}


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
        base = (with_frames(seqs["street07"][1], r.smoke_frames) if r.smoke_frames
                else seqs["street07"][1])
        drift_tasks.append(render_task(r, f"drift_{d:g}",
                                       [*base, "--poses-only", "--drift", str(d)], out))
    r.parallel(drift_tasks)
    family_tasks, family = family_renders(r, seqs, drift_family(quick), threads)
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
        for variant, det in (("default", {}), ("paper", OLD_AREA_DEFAULTS["detector"])):
            task, rd = run_task(r, "street07", f"drift{d:g}_{variant}",
                                detector_config(**det), poses=poses)
            tasks.append(task)
            runs[("street07", f"drift{d:g}_{variant}")] = rd
    tasks += family_runs(r, family, runs)
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
        # K = 15 (the paper's K): the soak's memory budget is per keyframe record + graph.
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

    metrics = collect_metrics(r, runs)
    baselines = {v: run_metrics(r.bin, d, r.out / "seq" / base_seq, "street")
                 for v, d in base_runs.items()}
    return {"sequences": {n: {"world": w, "render_args": a} for n, (w, a) in seqs.items()},
            "k_sweep": k_sweep(quick), "metrics": metrics, "baselines": baselines,
            "baseline_sequence": base_seq, "robust": robust, "drift_scales": drift_scales,
            "drift_family": family,
            "external": ext, "micro": {k: gb_rows(v) for k, v in micro.items()},
            "timings": timings}
