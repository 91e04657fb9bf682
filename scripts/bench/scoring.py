"""Loops scored against the GT poses of a rendered sequence (recall@100%P, events, false loops).

The scoring is `sparseloop eval --correct-distance` (eval's ScoreLoopsByGtDistance, the one
definition, docs/METRICS.md); this module only passes each world's rule and reads the JSON."""
import json
import subprocess
import tempfile
from pathlib import Path

from .common import num
from .plan import GT_RULES


def eval_args(world):
    """`sparseloop eval` flags of a world's rule: GT revisits closer than revisit_m with more than
    gap_m of GT path between them (and at most angle_deg between viewing directions); a loop is
    correct closer than correct_m, trivial (left out) when correct with less than gap_m of path."""
    rule = GT_RULES[world]
    return ["--derive-loops", f"{rule['revisit_m']},1", "--min-path", str(rule["gap_m"]),
            "--view-angle", str(rule["angle_deg"]), "--correct-distance", str(rule["correct_m"])]


def has_area_column(frames_csv):
    """frames.csv written by a sparseloop that reports the search area (its `area` column)."""
    if not frames_csv.exists():
        return False
    with frames_csv.open() as f:
        return "area" in f.readline().strip().split(",")


def score_loops(sparseloop, run_dir, seq_dir, world):
    frames = run_dir / "frames.csv"
    area_args = ["--frames", str(frames)] if has_area_column(frames) else []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "eval.json"
        subprocess.run([str(sparseloop), "eval", "--gt", str(seq_dir / "poses_gt.txt"),
                        "--loops", str(run_dir / "loops.csv"), *eval_args(world), *area_args,
                        "--json", str(out)], check=True, stdout=subprocess.DEVNULL)
        e = json.loads(out.read_text())
    area = e.get("search_area", {})
    return {
        # GT loop queries whose GT match was among the search area's candidates
        "area_coverage": num(area.get("coverage")),
        "area_mean_candidates": num(area.get("mean_candidates")),
        "gt_queries": e["loops"]["num_gt_queries"],
        "events": e["loop_events"],
        "events_detected": e["loop_events_detected"],
        "loops": e["loops"]["num_detections"],
        "trivial": e["loop_trivial"],
        "false_detected": e["loop_false_positives"],
        "false_accepted": e["loop_false_accepted"],
        "recall_100p": num(e["loop_recall_at_100p"]),
        "recall_100p_accepted": num(e["loop_recall_at_100p_accepted"]),
    }


def run_metrics(sparseloop, run_dir, seq_dir, world):
    s = json.loads((run_dir / "summary.json").read_text())
    m = score_loops(sparseloop, run_dir, seq_dir, world)
    t = s.get("timing_ms", {})
    m["timing_ms"] = t
    m["ms_total_median"] = t.get("total", {}).get("median", float("nan"))
    m["ms_total_p90"] = t.get("total", {}).get("p90", float("nan"))
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
