"""Loops scored against the GT poses of a rendered sequence (recall@100%P, events, false loops)."""
import csv
import json
import math

import numpy as np

from .common import *  # noqa: F401,F403
from .plan import GT_RULES

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
