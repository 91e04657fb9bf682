"""docs/BENCHMARKS.md from the collected results: the targets table and one section per experiment.

The page's prose (headings, paragraphs, captions) is in the Markdown template BENCHMARKS.md.in next
to this file; the functions here compute the numbers and tables that fill its ${names}."""
import math
import re
import string
from pathlib import Path

from .common import *  # noqa: F401,F403
from .plan import *  # noqa: F401,F403
from .plots import scaling_series

# --------------------------------------------------------------------------------------------
# BENCHMARKS.md

TEMPLATE = Path(__file__).with_name("BENCHMARKS.md.in")


def template_sections():
    """The template's sections by name: the text from the line after each `<!-- section NAME -->`
    marker to the next marker, its trailing blank lines dropped (one newline kept)."""
    parts = re.split(r"^<!-- section (\w+) -->\n", TEMPLATE.read_text(), flags=re.M)
    return {parts[i]: parts[i + 1].rstrip("\n") + "\n" for i in range(1, len(parts), 2)}


def prose(name, **values):
    """Section `name` of the template with its ${names} filled."""
    return string.Template(template_sections()[name]).substitute(values)


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
    tm = res["timings"]
    table_rows = [["CPU", mc["cpu"]], ["cores", mc["cores"]], ["memory (GiB)", mc["mem_gib"]],
                  ["OS", mc["os"]], ["mode", "quick" if args.quick else "full"],
                  ["parallel experiments", args.jobs]]
    md = [prose("header", mode=" --quick" if args.quick else "", date=mc["date"],
                commit=mc["commit"], machine_table=table(["machine", "value"], table_rows),
                render_s=f"{tm['render_s']:.0f}", accuracy_s=f"{tm['accuracy_runs_s']:.0f}",
                baseline_s=f"{tm['baseline_runs_s']:.0f}", micro_s=f"{tm['micro_s']:.0f}",
                total_s=f"{tm['total_s']:.0f}")]
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


def write_family_markdown(res, args, docs):
    """docs/BENCHMARKS_DRIFT.md: the drift family alone at its full size (`--family`)."""
    mc = res["machine"]
    tm = res["timings"]
    runs = [(f"{seq}/{v}", m) for seq, vs in res["metrics"].items() for v, m in vs.items()]
    rows = []
    for variant, label in (("family_new", "today's defaults"),
                           ("family_old", "old loop options"),
                           ("family_oldarea", "paper area only"),
                           ("family_sparse", "K = 15 preset")):
        chosen = [(l, m) for l, m in runs if l.endswith("/" + variant)]
        acc = sum(m["false_accepted"] for _, m in chosen)
        det = sum(m["false_detected"] for _, m in chosen)
        rows.append([f"zero false loops accepted ({label}, every family run)",
                     f"{acc} accepted, {det} detected over {len(chosen)} runs",
                     status(acc, acc == 0) if variant in ("family_new", "family_sparse") else
                     ("met" if acc == 0 else "(old options: no target)"), ""])
    rows += drift_family_targets(res)
    rows += castle_family_targets(res)
    text = "\n".join([
        prose("family_header", date=mc["date"], commit=mc["commit"], cpu=mc["cpu"],
              cores=mc["cores"], jobs=args.jobs, render_s=f"{tm['render_s']:.0f}",
              runs_s=f"{tm['accuracy_runs_s']:.0f}", castle_s=f"{tm.get('castle_s', 0):.0f}",
              total_s=f"{tm['total_s']:.0f}"),
        prose("family_targets", table=table(["target", "measured", "status", "why, where missed"],
                                            rows)),
        drift_family_section(res),
        castle_family_section(res)]) + "\n"
    tmp = docs / "BENCHMARKS_DRIFT.md.tmp"
    tmp.write_text(text)
    tmp.replace(docs / "BENCHMARKS_DRIFT.md")


def default_runs(res):
    """Every run made with default options: (label, metrics)."""
    out = []
    for seq, variants in res["metrics"].items():
        for v, m in variants.items():
            if v in ("kdefault", "default", "family_new") or v.endswith("_default"):
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
        m = variants.get("sparse_preset")
        if m:
            tail = m["ms_total_p90"] / m["ms_total_median"]
            rows.append([f"sparse K = 15 preset: Process() p90 <= 2x its median ({seq})",
                         f"{fmt(tail, 1)}x (p90 {fmt(m['ms_total_p90'])} / median "
                         f"{fmt(m['ms_total_median'])} ms)", status(tail, tail <= 2.0),
                         "" if tail <= 2.0 else
                         "verification of the failing pairs of tail frames (weak 6-inlier "
                         "hypotheses; docs/DETECTOR.md, Sparse K = 15)"])
    for seq, variants in res["metrics"].items():
        if seq.startswith("street") and "kdefault" in variants:
            m = variants["kdefault"]
            rows.append([f"corrected KITTI t_err < 1.5 % ({seq})",
                         f"{fmt(m['corrected_t_err_pct'])} % (raw {fmt(m['raw_t_err_pct'])} %)",
                         status(m["corrected_t_err_pct"], m["corrected_t_err_pct"] < 1.5), ""])
    rows += drift_family_targets(res)
    micro = {row["name"]: row for rows_ in res.get("micro", {}).values() for row in rows_}
    for k, how in ((15, "matched with 1,000 query features"), (300, "matched in full, 300 x 300")):
        fallback = micro.get(f"BM_AppearanceFallback/stored:10000/variant:0/k:{k}")
        if not fallback:
            continue
        full = micro.get(f"BM_AppearanceFallback/stored:10000/variant:1/k:{k}")
        one = micro.get(f"BM_AppearanceFallback/stored:10000/variant:2/k:{k}")
        t = fallback["cpu_ms"]
        versus = (f"; {fmt(t / full['cpu_ms'], 3)}x matching all of them in full "
                  f"({fmt(full['cpu_ms'])} ms)" if full else "")
        versus += (f"; one-stage pre-ranking {fmt(one['cpu_ms'])} ms" if one else "")
        rows.append([f"appearance fallback <= 2 ms at 10,000 stored K = {k} keyframes "
                     f"(two-stage pre-ranking + {fmt(fallback.get('matched_in_full'), 0)} {how}, "
                     "bench_detector)",
                     f"{fmt(t)} ms{versus}", status(t, t <= 2.0),
                     "" if fallback.get("found_revisit") == 1 else
                     "**the pre-ranking lost the planted revisit**"])
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
        rows.append(["Process() median <= 5 ms per 1226x370 KITTI keyframe, one core (default "
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
            rows.append([f"euroc_loop_pairs both verified, rotation < 3 deg "
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
            rows.append([f"5,000-keyframe Sim(3) graph, 100 loops, {label}: about a frame or "
                         "two (<= 100 ms: 2 frames at 20 Hz)", got,
                         status(ms, ok), "" if ok else
                         "sparse Cholesky (CHOLMOD) is most of it, symbolic analysis redone at "
                         "every Solve (docs/POSEGRAPH.md, Speed)"])
    return prose("targets", table=table(["target", "measured", "status", "why, where missed"], rows))


def scoring_section():
    rows = [[w, r["revisit_m"], r["gap_m"], r["angle_deg"], r["correct_m"]]
            for w, r in GT_RULES.items()]
    return prose("scoring", table=table(["world", "revisit (m)", "gap (m)", "angle (deg)",
                                         "correct (m)"], rows))


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
    smallest = None
    for k in res["k_sweep"]:
        ok = all(v.get(f"k{k}", {}).get("events_detected", -1) == v.get(f"k{k}", {}).get("events")
                 and v.get(f"k{k}", {}).get("false_accepted", 1) == 0
                 for s, v in res["metrics"].items() if not s.startswith("robust_"))
        if ok:
            smallest = k
            break
    text = prose("table1", table=table(["sequence"] + [f"K={k}" for k in ks], rows),
                 events=", ".join(f"{s} {n}" for s, n in n_events.items()
                                  if not s.startswith("robust")),
                 smallest=smallest if smallest else "none in the sweep")
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
            rows.append([seq, group or "-", ABLATION_LABELS[name],
                         m.get("area_coverage", float("nan")),
                         m.get("area_mean_candidates", float("nan")), m["recall_100p_accepted"],
                         m["false_detected"], m["false_accepted"], m["ms_total_median"],
                         m["timing_ms"].get("search", {}).get("median", float("nan")),
                         m["bytes_per_keyframe"]])
    return prose("ablation", table=table(["sequence", "group", "variant", "in area",
                                          "candidates", "recall@100%P", "false detected",
                                          "false accepted", "ms/kf median", "search ms median",
                                          "bytes/kf"], rows))


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
                         m["ms_total_p90"], m["ms_total_p99"],
                         m["ms_total_p90"] / m["ms_total_median"], m["bytes_per_keyframe"]])
    return prose("sparse", table=table(
        ["sequence", "variant", "recall@100%P", "events", "false detected", "false accepted",
         "ms/kf median", "ms/kf p90", "ms/kf p99", "p90 / median", "bytes/kf"], rows))


def baseline_section(res):
    b = res["baselines"]
    sl = b.get("sparseloop_default")
    rows = [stage_row(v, m, sl["ms_total_median"] if sl else None) for v, m in b.items()]
    text = prose("baselines", sequence=res["baseline_sequence"],
                 keyframes=sl["keyframes"] if sl else "?",
                 table=table(["method", "recall@100%P", "false detected", "false accepted",
                              "extract", "search", "match", "verify", "total", "x total",
                              "bytes/kf"], rows))
    series = scaling_series(res)
    if series:
        rows = [[name] + [f"{n}: {fmt(ms, 3)} ms" for n, ms in pts] for name, pts in series.items()]
        width = max(len(r) for r in rows)
        rows = [r + [""] * (width - len(r)) for r in rows]
        text += prose("scaling", table=table(["benchmark"] + [f"size {i + 1}"
                                                             for i in range(width - 1)], rows))
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
    text = prose("accuracy", table=table(
        ["sequence", "raw t_err %", "corrected t_err %", "raw r_err deg/100m",
         "corrected r_err deg/100m", "raw ATE m", "corrected ATE m", "solve ms"], rows))
    pa = res["external"].get("posegraph_accuracy", {})
    if "missing" not in pa:
        text += prose("real_drift", tables=posegraph_md(pa))
    else:
        text += f"\nReal vSLAM drift: not measured ({pa['missing']}).\n"
    return text


def drift_family_targets(res):
    """The drift family's targets (search area, loop correction, pitch/roll correction) read off
    its runs with default options (`family_new`)."""
    rows = []
    by_seq = {}
    for seq, d, name in res.get("drift_family", []):
        m = res["metrics"].get(name, {}).get("family_new")
        if m:
            by_seq.setdefault(seq, {})[d] = m
    for seq, per_drift in by_seq.items():
        top = max(per_drift)
        if top >= 4:
            cov = per_drift[top].get("area_coverage", float("nan"))
            rows.append([f"search area: holds the GT match for >= 90 % of GT revisit frames "
                         f"({seq}, drift x{top:g}, raw poses)", f"{fmt(cov)}",
                         status(cov, cov >= 0.9), ""])
        if 1 in per_drift and top > 1:
            r1 = per_drift[1]["recall_100p_accepted"]
            rt = per_drift[top]["recall_100p_accepted"]
            rows.append([f"search area: recall@100%P at drift x{top:g} >= 0.8 x at x1 ({seq})",
                         f"{fmt(rt)} vs {fmt(r1)} (x{fmt(rt / r1) if r1 > 0 else 'n/a'})",
                         status(rt, rt >= 0.8 * r1), ""])
    for seq, d, name in res.get("drift_family", []):
        m = res["metrics"].get(name, {}).get("family_new")
        if not m or m["raw_ate_m"] <= 0 or m["events"] == 0 or m["recall_100p_accepted"] <= 0:
            continue  # the targets hold where loops exist
        ratio = m["corrected_ate_m"] / m["raw_ate_m"]
        # "SEQ pitch" / "SEQ roll": the bias about another camera axis than the heading
        topic = "pitch/roll correction" if " " in seq else "correction"
        rows.append([f"{topic}: corrected ATE <= 30 % of raw ({seq}, drift x{d:g})",
                     f"{100 * ratio:.0f} % ({fmt(m['corrected_ate_m'])} / {fmt(m['raw_ate_m'])} m)",
                     status(ratio, ratio <= 0.30), ""])
        if seq.startswith("street"):
            t = m["corrected_t_err_pct"]
            rows.append([f"{topic}: KITTI t_err <= 1 % where loops exist ({seq}, drift x{d:g})",
                         f"{fmt(t)} % (raw {fmt(m['raw_t_err_pct'])} %)", status(t, t <= 1.0),
                         "" if t <= 1.0 else "docs/POSEGRAPH.md, street renders"])
    circuit = res["metrics"].get("aerial_circuit", {}).get("kdefault")
    if circuit:
        r = circuit["recall_100p_accepted"]
        rows.append(["search area: aerial circuit recall@100%P >= 0.95, raw poses, default search",
                     fmt(r), status(r, r >= 0.95), ""])
    return rows


def drift_family_section(res):
    rows = []
    for seq, d, name in res.get("drift_family", []):
        labels = {"old": "old loop options",
                  "oldarea": "paper area only (no uncertainty area, fallback or gate)",
                  "new": "today", "sparse": "K = 15 preset (sparse_k15.json)"}
        for variant in ("old", "oldarea", "new", "sparse"):
            m = res["metrics"].get(name, {}).get(f"family_{variant}")
            if not m:
                continue
            ratio = m["corrected_ate_m"] / m["raw_ate_m"] if m["raw_ate_m"] > 0 else float("nan")
            rows.append([seq, d, labels[variant], m.get("area_coverage", float("nan")),
                         m["raw_ate_m"], m["corrected_ate_m"], f"{100 * ratio:.0f} %",
                         m["raw_t_err_pct"], m["corrected_t_err_pct"],
                         m["recall_100p_accepted"], m["false_detected"], m["false_accepted"]])
    return prose("drift_family", table=table(
        ["sequence", "drift x", "options", "in area", "raw ATE m", "corrected ATE m", "ratio",
         "raw t_err %", "corrected t_err %", "recall@100%P", "false detected", "false accepted"],
        rows))


def castle_cases(res):
    """(variant, label, cases) of the castle family that ran; cases grouped by (axis, bias,
    scale) in the order axis pitch / yaw / roll, bias, scale."""
    out = []
    axes = {"pitch": 0, "yaw": 1, "roll": 2}
    for variant, label, _ in CASTLE_DRIFT_VARIANTS:
        cf = res.get("castle_family", {}).get(variant)
        if not cf or "missing" in cf:
            continue
        groups = {}
        for c in cf["cases"]:
            key = (axes[c["axis"]], c["bias_deg_per_keyframe"], c["scale_step"])
            groups.setdefault(key, []).append(c)
        out.append((variant, label, [groups[k] for k in sorted(groups)]))
    return out


def castle_family_targets(res):
    """The castle ring's target per axis and option set: corrected <= 40 % of raw ATE in every
    case (rotation bias 0.2-1 deg per keyframe, alone and with scale drift, 3 seeds)."""
    rows = []
    for _, label, groups in castle_cases(res):
        for axis in ("pitch", "yaw", "roll"):
            ratios = [c["ratio"] for g in groups for c in g if c["axis"] == axis]
            if not ratios:
                continue
            met = sum(1 for x in ratios if x <= 0.4)
            rows.append([f"castle ring: corrected ATE <= 40 % of raw, every case ({axis} "
                         f"bias, {label})", f"{met} of {len(ratios)} cases; worst "
                         f"{100 * max(ratios):.0f} %, median "
                         f"{100 * sorted(ratios)[len(ratios) // 2]:.0f} %",
                         status(max(ratios), met == len(ratios)),
                         "" if met == len(ratios) else
                         "one loop at the ring closure (an exact loop does no better; "
                         "docs/POSEGRAPH.md)"])
    return rows


def castle_family_section(res):
    rows = []
    for _, label, groups in castle_cases(res):
        for g in groups:
            ratios = [c["ratio"] for c in g]
            accepted = [l for c in g for l in c["loops"] if l["accepted"]]
            kinds = sorted({l["pose_kind"] for l in accepted})
            rot = [l["rotation_error_deg"] for l in accepted]
            rows.append([label, g[0]["axis"], f"{g[0]['bias_deg_per_keyframe']:g}",
                         f"{g[0]['scale_step']:g}",
                         " / ".join(f"{c['raw_ate_m']:.2f}" for c in g),
                         " / ".join(f"{100 * x:.0f} %" for x in ratios),
                         f"{sum(1 for x in ratios if x <= 0.4)}/{len(g)}",
                         f"{len(accepted)} ({', '.join(kinds) or 'none'})",
                         "-" if not rot else f"{min(rot):.1f}" if len(set(rot)) == 1 else
                         f"{min(rot):.1f}-{max(rot):.1f}"])
    if not rows:
        miss = "; ".join(f"{v}: {cf['missing']}" for v, cf in
                         res.get("castle_family", {}).items() if "missing" in cf)
        return f"\nCastle ring family: not measured ({miss or 'not run'}).\n"
    return prose("castle_family", table=table(
        ["options", "axis", "bias deg / keyframe", "scale / keyframe", "raw ATE m (per seed)",
         "corrected / raw (per seed)", "<= 40 %", "accepted loops (pose kinds)",
         "loop rotation error deg"], rows))


def robustness_section(res):
    rows = []
    for name, (kind, v) in sorted(res["robust"].items(), key=lambda x: (x[1][0], x[1][1])):
        m = res["metrics"][name]["default"]
        rows.append([kind, v, m["recall_100p_accepted"], m["false_detected"], m["false_accepted"]])
    labels = {"default": "drift (default area)", "paper": "drift (paper area only)"}
    for d in res["drift_scales"]:
        for variant in ("paper", "default"):
            m = res["metrics"]["street07"].get(f"drift{d:g}_{variant}")
            if m:
                rows.append([labels[variant], d, m["recall_100p_accepted"],
                             m["false_detected"], m["false_accepted"]])
    return prose("robustness", table=table(["factor", "value", "recall@100%P", "false detected",
                                            "false accepted"], rows))


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
        text += prose("euroc_pairs", table=table(
            ["pair", "depths", "status", "method", "planar", "matches", "inliers",
             "rotation err deg", "direction err deg", "translation err m"], rows))
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
        rankings = [k for k, v in rt.items() if isinstance(v, dict) and k != "oracle"]
        ks = sorted({k for r in rankings for k in rt[r]}, key=int)
        rows = [[r] + [rt[r][k]["recall_at_full_precision"] if k in rt[r] else "" for k in ks]
                for r in rankings]
        prec = min(rt[r][k]["precision"] for r in rankings for k in rt[r])
        text += ("\nrtabmap_corridor_loop (no poses: global search; "
                 f"{rt.get('queries_with_gt', '?')} query images with a GT loop): recall at 100 % "
                 f"precision by ranking and K; lowest precision in the table: **{fmt(prec, 3)}**"
                 "\n\n" + table(["ranking"] + [f"K={k}" for k in ks], rows) + "\n")
    oracle = rt.get("oracle", {})
    if oracle:
        def agreement(a):
            if not a:
                return "-"
            return f"{fmt(a['recall'], 3)} ({a['strong']} / {a['weak']})"

        rows = []
        for name, o in oracle.items():
            at = {b["t"]: b for b in o.get("by_threshold", [])}
            at8 = at.get(8, {})
            rows.append([name.replace("_", " K = "), f"{fmt(o['ceiling'], 3)} (t = {o['ceiling_threshold']})",
                         fmt(o.get("ceiling_one_false", float("nan")), 3),
                         agreement(o.get("ceiling_with_agreement")),
                         f"{fmt(at8.get('recall', float('nan')), 3)}, {at8.get('false', '?')} false",
                         fmt(o["verifiable_at_8"], 3)])
        text += ("\nrtabmap oracle (every pair >= 30 keyframes apart verified, default ranking; "
                 "docs/DETECTOR.md): the best recall at 100 % precision of any inlier threshold t "
                 "for a detector that accepts each query's top pair, the best with at most one "
                 "false loop, the best at 100 % precision with the weak-pair agreement rule "
                 "(strong / weak inlier floors), the same at the small-K floor t = 8, and the GT "
                 "queries whose best true pair reaches 8 inliers\n\n"
                 + table(["matching, K", "ceiling", "<= 1 false", "with agreement", "at t = 8",
                          "verifiable at 8"], rows)
                 + "\n")
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
        text += prose("real_drift_table", table=table(
            ["sequence", "keyframes", "loops", "raw ATE", "true loops", "<= 30 %",
             "20 % false, PCM", "<= 40 %", "20 % false, plain LS", "true loops, SE(3) / 4-DoF"],
            rows))
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
            "optimiser. Target: RSS growth <= 2 KiB per keyframe beyond the fixed "
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
        text += prose("soak_record") + "\n"
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
