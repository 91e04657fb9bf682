"""The figures of docs/BENCHMARKS.md (docs/img/bench_*.png)."""
import csv
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .common import *  # noqa: F401,F403

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
    finish_row(fig, axes, "KITTI translation error (%)", path, legend_size=8)


def finish_row(fig, axes, ylabel, path, legend_size):
    """A row of panels: the y label and legend on the first, saved to `path`."""
    axes[0][0].set_ylabel(ylabel)
    axes[0][0].legend(fontsize=legend_size)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_family(res, path):
    """Per drift-family sequence: raw ATE and corrected ATE of each option set against drift
    (the heading rows; the pitch / roll rows are in the table only)."""
    by_seq = {}
    for seq, d, name in res.get("drift_family", []):
        if " " not in seq:
            by_seq.setdefault(seq, []).append((d, res["metrics"].get(name, {})))
    if not by_seq:
        return
    fig, axes = plt.subplots(1, len(by_seq), figsize=(3.4 * len(by_seq), 3.3), squeeze=False)
    styles = (("family_new", "corrected (today)", "o-"),
              ("family_oldarea", "corrected (paper area only)", "s--"),
              ("family_old", "corrected (old loop options)", "^:"),
              ("family_sparse", "corrected (K = 15 preset)", "d-."))
    for ax, (seq, pts) in zip(axes[0], by_seq.items()):
        pts.sort(key=lambda p: p[0])
        xs = [p[0] for p in pts]
        raw = [p[1].get("family_new", {}).get("raw_ate_m", float("nan")) for p in pts]
        ax.plot(xs, raw, "k.-", label="raw")
        for variant, label, style in styles:
            ax.plot(xs, [p[1].get(variant, {}).get("corrected_ate_m", float("nan"))
                         for p in pts], style, label=label)
        ax.set_title(seq, fontsize=9)
        ax.set_xlabel("drift (x default rates)")
        ax.set_xticks(xs)
        ax.grid(alpha=0.3)
    finish_row(fig, axes, "ATE RMSE (m, Sim(3)-aligned)", path, legend_size=7)


def plot_robustness(res, path):
    kinds = {}
    for name, (kind, v) in res["robust"].items():
        m = res["metrics"][name]["default"]
        kinds.setdefault(kind, []).append((v, m["recall_100p_accepted"], m["false_accepted"]))
    drift = []
    for d in res["drift_scales"]:
        for variant in ("paper", "default"):
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
    for variant, style in (("paper", "o-"), ("default", "^-")):
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
