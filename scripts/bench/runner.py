"""Running the sparseloop binary and the benchmark programs, one log per task, --jobs at a time."""
import concurrent.futures as cf
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

from .common import *  # noqa: F401,F403

# --------------------------------------------------------------------------------------------
# Running things


class Runner:
    def __init__(self, build, out, jobs, reuse):
        self.build = Path(build).resolve()
        self.bin = self.build / "bin" / "sparseloop"
        self.out = Path(out).resolve()
        self.jobs = jobs
        self.reuse = reuse
        self.smoke_frames = 0  # --smoke: cut every sequence (tests the script, not the numbers)
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


def with_frames(args, frames):
    """Render arguments with --frames set to `frames` (replacing an existing value)."""
    args = list(args)
    if "--frames" in args:
        args[args.index("--frames") + 1] = str(frames)
    else:
        args += ["--frames", str(frames)]
    return args


def render_task(r, name, args, out):
    """A `sparseloop render ARGS --out OUT` task, done when OUT/render.json exists (written last).
    render refuses an --out that is not one of its finished renders: a render cut off earlier
    left a folder without render.json, removed here to be rendered again whole."""
    if out.is_dir() and not (out / "render.json").exists():
        shutil.rmtree(out)
    return (name, [r.bin, "render", *args, "--out", out], out / "render.json")


def render_tasks(r, seqs, threads):
    tasks = []
    for name, (_, args) in seqs.items():
        if r.smoke_frames:
            args = with_frames(args, r.smoke_frames)
        tasks.append(render_task(r, f"render_{name}", [*args, "--threads", threads],
                                 r.out / "seq" / name))
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
