#!/usr/bin/env python3
"""One-page HTML report of a sparseloop run directory (headless, matplotlib Agg).

Usage: report.py DIR [--false-loop-distance METRES] [--sparseloop BIN]
  --false-loop-distance  re-score the loops at this GT distance (default: the run's own verdicts,
                         loops.csv "correct", at summary.json's gt_loop_distance)
  --sparseloop           the binary whose `eval` aligns the trajectories with GT and scores loops
                         (default: $SPARSELOOP_BIN, then sparseloop on PATH); needed to align, to
                         re-score or for a P/R curve from gt_loops.txt. Nothing is aligned,
                         associated or scored here: `sparseloop eval` is the one definition
                         (docs/METRICS.md).

Reads (every file optional except summary.json and at least one trajectory), each as `sparseloop eval` reads text
files (a UTF-8 byte order mark, LF, CRLF or lone CR line ends; bytes that are not UTF-8 read as
U+FFFD):
  poses_gt.txt | poses.txt     ground truth (KITTI 12 numbers, or index + 12, or TUM)
  poses_raw.txt                raw (drifting) input trajectory
  trajectory.txt               corrected trajectory written by `sparseloop run`
  loops.csv                    loops, header with at least "query,match" (+ "score", "accepted",
                               "correct" as `sparseloop run` writes them); a malformed or
                               truncated file is an error naming the line
  gt_loops.txt                 ground-truth loop pairs "i j" (for the P/R curve)
  pr_curve.csv                 precomputed "threshold,precision,recall" (used when present)
  summary.json                 thresholds and counts of the run (gt_loop_distance, loops,
                               accepted_loops, accepted_loops_false, timing_ms {stage: {median}});
                               a truncated or invalid file is an error naming the line
  timings.csv                  per-keyframe timings, one column per stage (ms)
Writes DIR/report.html, one self-contained file (the plots embedded as base64 PNG data URIs), and
DIR/report_*.png (the same plots).
Raw and corrected are drawn as `sparseloop eval --align sim3` aligned them to GT (monocular scale
is arbitrary), with the position error of each pose it associated (its "aligned_positions" and
"associated" JSON keys).
"""
import argparse
import base64
import csv
import html
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_text(path):
    """The text of a file as `sparseloop eval` reads it: a UTF-8 byte order mark is not part of
    it, and bytes that are not UTF-8 (an image name in another encoding) become U+FFFD."""
    with open(path, "rb") as f:
        text = f.read().decode("utf-8", errors="replace")
    return text[1:] if text.startswith("\ufeff") else text


def split_lines(text):
    r"""The lines of `text` without their ends ("\n", "\r\n" or a lone "\r", as SplitLines in
    sparseloop/core/text_lines.h); an end at the very end opens no further line."""
    lines = re.split(r"\r\n|\r|\n", text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


def read_csv_rows(path):
    """[(line number, {column: value})] of a CSV file with a header line, read as `eval` reads
    loops.csv: blank lines skipped, a quoted field may span lines (RFC 4180)."""
    lines = split_lines(read_text(path))
    rows, header, k = [], None, 0
    while k < len(lines):
        number, record = k + 1, lines[k]
        k += 1
        if not record.strip():
            continue
        while record.count('"') % 2 == 1 and k < len(lines):
            record += "\n" + lines[k]
            k += 1
        fields = next(csv.reader([record]))
        if header is None:
            header = fields
            continue
        if record.startswith("#"):
            continue
        if len(fields) != len(header):
            raise ReportError(f"{path}:{number}: expected {len(header)} columns, got "
                              f"{len(fields)} (a truncated or foreign file)")
        rows.append((number, dict(zip(header, fields))))
    return header or [], rows


def read_summary(path):
    """summary.json as a dict; a truncated or invalid file is a ReportError naming its line."""
    try:
        summary = json.loads(read_text(path))
    except json.JSONDecodeError as e:
        raise ReportError(f"{path}:{e.lineno}: expected valid JSON (summary.json as `sparseloop "
                          f"run` / `detect` write it), got '{e.msg}' at column {e.colno}: a "
                          "truncated or foreign file")
    if not isinstance(summary, dict):
        raise ReportError(f"{path}: expected a JSON object (summary.json as `sparseloop run` / "
                          f"`detect` write it), got {type(summary).__name__}")
    return summary


def summary_number(summary, key, default):
    """summary.json's number `key` (default when absent); a ReportError when it is not one."""
    value = summary.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ReportError(f"summary.json: expected a number for \"{key}\", got {value!r}")
    return value


def read_trajectory(path):
    """Returns (keys, positions Nx3, kind) where keys are frame indices or timestamps."""
    rows = []
    for line in split_lines(read_text(path)):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        rows.append([float(x) for x in line.replace(",", " ").split()])
    if not rows:
        raise ValueError(f"{path}: no data lines")
    n = len(rows[0])
    a = np.array(rows)
    if n == 12:
        return np.arange(len(a)), a[:, [3, 7, 11]], "index"
    if n == 13:
        return a[:, 0].astype(int), a[:, [4, 8, 12]], "index"
    if n == 8:
        return a[:, 0], a[:, 1:4], "time"
    if n == 4:
        return a[:, 0].astype(int), a[:, 1:4], "index"
    raise ValueError(f"{path}: cannot tell the format from {n} columns")


def top_view_axes(p):
    """The two axes of largest spread (KITTI: x-z, aerial: x-y)."""
    spread = p.max(0) - p.min(0)
    ax = sorted(np.argsort(spread)[-2:])
    return ax


class ReportError(Exception):
    pass


def read_loops(path):
    """[(query, match, score, accepted, correct)]; accepted / correct are None when unknown.
    Every row must have the header's column count: a truncated file is an error with the line."""
    text = read_text(path)
    if text and not text.endswith(("\n", "\r")):
        raise ReportError(f"{path}:{len(split_lines(text))}: expected a complete line (ending "
                          "with a line end), got a truncated file")
    header, rows = read_csv_rows(path)
    if not header:
        return []
    if "query" not in header or "match" not in header:
        raise ReportError(f"{path}:1: expected a header with query and match columns")
    loops = []
    for number, row in rows:
        try:
            q, m = int(row["query"]), int(row["match"])
            score = float(row["score"]) if row.get("score") not in (None, "") else float("nan")
        except ValueError:
            raise ReportError(f"{path}:{number}: expected integer query and match ids and a "
                              "numeric score")
        flag = lambda k: None if row.get(k) in (None, "") else row[k] == "1"  # noqa: E731
        loops.append((q, m, score, flag("accepted"), flag("correct")))
    return loops


def find_sparseloop(args):
    return args.sparseloop or os.environ.get("SPARSELOOP_BIN") or shutil.which("sparseloop")


def run_eval(args, flags, what):
    """`sparseloop eval FLAGS --json`: its JSON (the keys of docs/METRICS.md)."""
    exe = find_sparseloop(args)
    if not exe:
        raise ReportError(f"{what} needs the sparseloop binary (its `eval`): pass "
                          "--sparseloop BIN or set SPARSELOOP_BIN")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "eval.json")
        done = subprocess.run([exe, "eval", *flags, "--json", out],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            raise ReportError(f"sparseloop eval {' '.join(flags)} failed: {done.stderr.strip()}")
        with open(out) as f:
            return json.load(f)


def eval_loops(args, loops_csv, flags):
    """`sparseloop eval --loops LOOPS FLAGS --json`: its loop keys."""
    return run_eval(args, ["--loops", loops_csv, *flags], "scoring loops")


def align_to_gt(args, gt_path, est_path):
    """`sparseloop eval --gt GT --est EST --align sim3 --json`: the estimate as eval aligned it
    ("aligned_positions", every pose) and its associated pairs with their errors ("associated")."""
    return run_eval(args, ["--gt", gt_path, "--est", est_path, "--align", "sim3"],
                    "aligning trajectories with GT")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--false-loop-distance", type=float, default=None,
                    help="GT distance beyond which a loop is false (default: summary.json's "
                         "gt_loop_distance, else 10)")
    ap.add_argument("--sparseloop", default=None,
                    help="sparseloop binary whose eval scores loops (default: $SPARSELOOP_BIN, "
                         "then PATH)")
    args = ap.parse_args()
    try:
        return make_report(args)
    except ReportError as e:
        print(f"report.py: {e}", file=sys.stderr)
        return 2


def make_report(args):
    d = args.dir
    fp = lambda name: os.path.join(d, name)  # noqa: E731
    sections, notes = [], []
    # A run output holds summary.json; a dataset folder does not, and the report's files must not
    # be written into it.
    if not os.path.isfile(fp("summary.json")):
        raise ReportError(f"{d}: expected a run output folder (holding summary.json, as `sparseloop "
                          "run` / `detect` write it), got a folder without summary.json (a "
                          "dataset? report the --out folder of its run)")
    summary = read_summary(fp("summary.json"))
    # The run's own threshold, so the report agrees with summary.json.
    false_distance = args.false_loop_distance
    if false_distance is None:
        false_distance = float(summary_number(summary, "gt_loop_distance", 10.0))

    traj = {}
    for label, names in (("GT", ["poses_gt.txt", "poses.txt"]), ("raw", ["poses_raw.txt"]),
                         ("corrected", ["trajectory.txt"])):
        for name in names:
            if os.path.isfile(fp(name)):
                try:
                    traj[label] = read_trajectory(fp(name)) + (name,)
                except ValueError as e:
                    notes.append(str(e))
                break
    if not traj:
        print(f"report.py: no trajectory in {d} (poses_gt.txt, poses_raw.txt, trajectory.txt)",
              file=sys.stderr)
        return 2

    # Raw / corrected as `sparseloop eval --align sim3` associated and aligned them with GT.
    aligned, errors = {}, {}
    gt = traj.get("GT")
    for label in ("raw", "corrected"):
        if label not in traj:
            continue
        keys, pos, _, name = traj[label]
        aligned[label] = (keys, pos)  # as it is, unless eval aligns it
        if gt is None:
            continue
        try:
            e = align_to_gt(args, fp(gt[3]), fp(name))
        except ReportError as err:
            notes.append(f"{label}: not aligned to GT ({err})")
            continue
        if e["alignment"]["status"] == "too_few_points":
            notes.append(f"{label}: fewer than 3 poses associate with GT; not aligned")
            continue
        pa = np.asarray(e["aligned_positions"], dtype=float).reshape(-1, 3)
        if len(pa) != len(pos):
            raise ReportError(f"{fp(name)}: sparseloop eval read {len(pa)} poses, the report "
                              f"{len(pos)}")
        aligned[label] = (keys, pa)
        pairs = e["associated"]
        errors[label] = (np.asarray(pairs["gt_frame"]), np.asarray(pairs["ate_m"], dtype=float))

    ref = gt[1] if gt is not None else next(iter(aligned.values()))[1]
    ax_idx = top_view_axes(ref)
    names = "xyz"

    # 1. Top view with loops.
    loops = read_loops(fp("loops.csv")) if os.path.isfile(fp("loops.csv")) else []
    in_session = summary.get("loops")
    if in_session is not None and os.path.isfile(fp("loops.csv")):
        expected = (int(summary_number(summary, "loops", 0))
                    + int(summary_number(summary, "cross_session_loops", 0)))
        if len(loops) != expected:
            raise ReportError(f"{fp('loops.csv')}: expected {expected} loops (summary.json), got "
                              f"{len(loops)}: the file is truncated or from another run")
    fig, ax = plt.subplots(figsize=(8, 7))
    colours = {"GT": "k", "raw": "tab:red", "corrected": "tab:blue"}
    if gt is not None:
        ax.plot(gt[1][:, ax_idx[0]], gt[1][:, ax_idx[1]], "-", color="k", lw=1.2, label="GT")
    for label, (keys, p) in aligned.items():
        ax.plot(p[:, ax_idx[0]], p[:, ax_idx[1]], "-", color=colours[label], lw=1.0,
                label=f"{label} (Sim3-aligned)" if label in errors else label)
    n_true = n_false = n_rejected = 0
    if loops:
        base_label = "corrected" if "corrected" in aligned else ("GT" if gt is not None else None)
        if base_label == "GT":
            base_keys, base_pos = gt[0], gt[1]
        elif base_label is not None:
            base_keys, base_pos = aligned[base_label]
        # Loop ids are frame indices. Index-keyed files map directly; time-keyed (TUM) files
        # written by `sparseloop run` hold one row per frame in frame order, so row = frame.
        base_kind = gt[2] if base_label == "GT" else traj[base_label][2] if base_label else None
        if base_kind == "time":
            lut = {i: i for i in range(len(base_keys))}
        else:
            lut = {int(k): i for i, k in enumerate(base_keys)} if base_label else {}
        # Re-scored at --false-loop-distance by `sparseloop eval` (GT by frame id: row of a TUM
        # file, index of a KITTI one), else the run's own verdicts (loops.csv "correct").
        verdicts = None
        own = all(l[4] is not None for l in loops)
        if gt is not None and (args.false_loop_distance is not None or not own):
            if args.false_loop_distance is None and not find_sparseloop(args):
                notes.append("loops.csv has no verdicts and no sparseloop binary was found to "
                             "score them (--sparseloop): no loop is drawn as false")
            else:
                verdicts = eval_loops(args, fp("loops.csv"), [
                    "--gt", fp(gt[3]), "--correct-distance", str(false_distance)])["loop_verdicts"]
        for k, (q, m, _, accepted, correct) in enumerate(loops):
            if accepted is False:  # rejected by the pose graph: drawn as rejected
                n_rejected += 1
                if q in lut and m in lut:
                    a, b = base_pos[lut[q]], base_pos[lut[m]]
                    ax.plot([a[ax_idx[0]], b[ax_idx[0]]], [a[ax_idx[1]], b[ax_idx[1]]], ":",
                            color="tab:grey", lw=1.0, alpha=0.9)
                continue
            if verdicts is not None:
                false = verdicts[k] == "false"
            else:
                false = correct is False  # the run's own verdict, at its threshold
            n_false += false
            n_true += not false
            if q not in lut or m not in lut:
                continue
            a, b = base_pos[lut[q]], base_pos[lut[m]]
            ax.plot([a[ax_idx[0]], b[ax_idx[0]]], [a[ax_idx[1]], b[ax_idx[1]]], "-",
                    color="tab:orange" if false else "tab:green", lw=1.5 if false else 0.8,
                    alpha=0.9)
        ax.plot([], [], "-", color="tab:green", label=f"accepted loops, correct ({n_true})")
        if gt is not None:
            ax.plot([], [], "-", color="tab:orange",
                    label=f"accepted loops, false ({n_false}, GT dist > {false_distance:g})")
        if n_rejected:
            ax.plot([], [], ":", color="tab:grey", label=f"rejected loops ({n_rejected})")
    ax.set_xlabel(f"{names[ax_idx[0]]} [m]")
    ax.set_ylabel(f"{names[ax_idx[1]]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Top view")
    fig.tight_layout()
    fig.savefig(fp("report_topview.png"), dpi=90)
    plt.close(fig)
    caption = f"{len(loops)} loops, {n_true + n_false} accepted"
    if n_rejected:
        caption += f", {n_rejected} rejected by the pose graph"
    if gt is not None:
        caption += f"; {n_false} accepted loops false (GT distance > {false_distance:g})"
    sections.append(("Top view", "report_topview.png", caption))

    # 2. Error along the trajectory.
    if errors:
        fig, ax = plt.subplots(figsize=(8, 3.5))
        stats = []
        for label, (x, e) in errors.items():
            ax.plot(x, e, "-", color=colours[label], lw=1.0, label=label)
            stats.append(f"{label}: RMSE {math.sqrt(float(np.mean(e ** 2))):.2f} m, "
                         f"max {float(np.max(e)):.2f} m")
        ax.set_xlabel("frame")
        ax.set_ylabel("position error [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title("Position error after Sim(3) alignment")
        fig.tight_layout()
        fig.savefig(fp("report_error.png"), dpi=90)
        plt.close(fig)
        sections.append(("Error along the trajectory", "report_error.png", "; ".join(stats)))

    # 3. Timing per stage.
    timing = {}
    if os.path.isfile(fp("timings.csv")):
        for _, row in read_csv_rows(fp("timings.csv"))[1]:
            for k, v in row.items():
                if k in ("keyframe", "frame", "query") or v in (None, ""):
                    continue
                try:
                    value = float(v)
                except ValueError:  # a non-numeric column (e.g. status) is not a stage
                    continue
                timing.setdefault(k, []).append(value)
    # summary.json timing_ms {stage: {median, p90, max, ...}} (ms per keyframe), as detect and
    # run write it.
    if not timing and isinstance(summary.get("timing_ms"), dict):
        for k, v in summary["timing_ms"].items():
            if isinstance(v, (int, float)):
                timing[k] = [float(v)]
            elif isinstance(v, dict):
                val = v.get("median", v.get("mean"))
                if isinstance(val, (int, float)):
                    timing[k] = [float(val)]
    if timing:
        stages = list(timing)
        fig, axes = plt.subplots(1, len(stages), figsize=(min(3 * len(stages), 14), 3),
                                 squeeze=False)
        for a, stage in zip(axes[0], stages):
            vals = np.array(timing[stage])
            if len(vals) > 1:
                a.hist(vals, bins=30, color="tab:purple")
                a.set_title(f"{stage}\nmedian {np.median(vals):.2f} ms", fontsize=9)
            else:
                a.bar([0], vals, color="tab:purple")
                a.set_xticks([])
                a.set_title(f"{stage}\n{vals[0]:.2f} ms", fontsize=9)
            a.set_xlabel("ms")
        fig.tight_layout()
        fig.savefig(fp("report_timing.png"), dpi=90)
        plt.close(fig)
        sections.append(("Timing per stage", "report_timing.png",
                         "per keyframe (timings.csv)" if os.path.isfile(fp("timings.csv"))
                         else "median per keyframe, from summary.json timing_ms"))

    # 4. Precision / recall.
    curve = None
    if os.path.isfile(fp("pr_curve.csv")):
        rows = [row for _, row in read_csv_rows(fp("pr_curve.csv"))[1]]
        try:
            curve = [(float(r["recall"]), float(r["precision"])) for r in rows]
        except (KeyError, ValueError):
            raise ReportError(f"{fp('pr_curve.csv')}: expected numeric recall and precision "
                              "columns (pr_curve.csv as `sparseloop run` writes it)")
    elif os.path.isfile(fp("gt_loops.txt")) and loops:
        e = eval_loops(args, fp("loops.csv"), ["--gt-loops", fp("gt_loops.txt")])
        curve = [(p["recall"], p["precision"]) for p in e["loops"]["curve"]]
    if curve:
        r, p = zip(*curve)
        fig, ax = plt.subplots(figsize=(4.5, 4))
        ax.plot(r, p, "-o", ms=2)
        ax.set_xlabel("recall")
        ax.set_ylabel("precision")
        ax.set_xlim(0, 1.02)
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.set_title("Loop detection P/R")
        fig.tight_layout()
        fig.savefig(fp("report_pr.png"), dpi=90)
        plt.close(fig)
        sections.append(("Precision / recall", "report_pr.png", ""))

    # HTML (written to a temporary file, then renamed: atomic).
    body = [f"<h1>sparseloop report</h1><p>{html.escape(os.path.abspath(d))}</p>",
            "<ul>" + "".join(f"<li>{html.escape(k)}: {html.escape(v[3])}</li>"
                             for k, v in traj.items()) + "</ul>"]
    if summary:
        flat = {k: v for k, v in summary.items() if not isinstance(v, (dict, list))}
        if flat:
            body.append("<table>" + "".join(
                f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v))}</td></tr>"
                for k, v in flat.items()) + "</table>")
    for title, png, caption in sections:
        # Embedded: report.html is one self-contained file.
        with open(fp(png), "rb") as f:
            data = base64.b64encode(f.read()).decode("ascii")
        body.append(f"<h2>{html.escape(title)}</h2><p>{html.escape(caption)}</p>"
                    f"<img src=\"data:image/png;base64,{data}\" alt=\"{html.escape(title)} "
                    f"({png})\">")
    for n in notes:
        body.append(f"<p><em>{html.escape(n)}</em></p>")
    page = ("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>sparseloop report</title>"
            "<style>body{font-family:sans-serif;max-width:1000px;margin:auto}"
            "img{max-width:100%}td{padding:2px 8px}</style></head><body>"
            + "\n".join(body) + "</body></html>\n")
    tmp = fp(f"report.html.tmp.{os.getpid()}")
    # A folder name that is not UTF-8 reaches here as surrogates: written as U+FFFD.
    with open(tmp, "w", encoding="utf-8", errors="replace") as f:
        f.write(page)
    os.replace(tmp, fp("report.html"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
