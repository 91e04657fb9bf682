#!/usr/bin/env python3
"""Writes the timing report of a scripts/test run: LOGS/times.md, and prints it.

Reads LOGS/stages.tsv (stage, seconds, status: one line per stage, written by scripts/test) and
LOGS/<stage>.junit.xml (ctest --output-junit) for the test count and the 20 slowest tests of each
ctest stage, and LOGS/<stage>.ccache.before / .after (ccache --print-stats) for the compiles the
cache served in each stage. Usage: ci_times.py LOGS_DIR
"""
import sys
import xml.etree.ElementTree as ET
from pathlib import Path


def minutes(seconds: float) -> str:
    return f"{int(seconds) // 60}:{int(seconds) % 60:02d}"


def ccache_counts(logs: Path, name: str) -> str:
    """'hits / compiles' of the stage from ccache's counters before and after it, '' if none."""
    def read(suffix):
        path = logs / f"{name}.ccache.{suffix}"
        if not path.exists():
            return None
        counters = {}
        for line in path.read_text().splitlines():
            key, _, value = line.partition("\t")
            if value.strip().isdigit():
                counters[key] = int(value)
        return counters
    before, after = read("before"), read("after")
    if before is None or after is None:
        return ""
    diff = {k: after.get(k, 0) - before.get(k, 0) for k in after}
    hits = diff.get("direct_cache_hit", 0) + diff.get("preprocessed_cache_hit", 0)
    compiles = hits + diff.get("cache_miss", 0)
    return f"{hits} / {compiles}" if compiles else ""


def main() -> int:
    logs = Path(sys.argv[1])
    stages_file = logs / "stages.tsv"
    if not stages_file.exists():
        return 0
    stages = []
    for line in stages_file.read_text().splitlines():
        name, seconds, status = line.split("\t")
        stages.append((name, int(seconds), status))
    out = ["# scripts/test: time per stage", "",
           "| stage | time (m:ss) | status | tests | failed | ccache hits / compiles |",
           "|---|---|---|---|---|---|"]
    slowest = []
    for name, seconds, status in stages:
        junit = logs / f"{name}.junit.xml"
        tests = failed = ""
        if junit.exists():
            cases = []
            for case in ET.parse(junit).getroot().iter("testcase"):
                failed_case = case.find("failure") is not None or case.get("status") == "fail"
                cases.append((float(case.get("time", 0)), case.get("name"), failed_case))
            tests = str(len(cases))
            failed = str(sum(1 for c in cases if c[2]))
            cases.sort(reverse=True)
            slowest.append((name, cases[:20]))
        out.append(f"| {name} | {minutes(seconds)} | {status} | {tests} | {failed} | "
                   f"{ccache_counts(logs, name)} |")
    total = sum(s[1] for s in stages)
    out.append(f"| **total** | **{minutes(total)}** | | | | |")
    for name, cases in slowest:
        out += ["", f"## {name}: the 20 slowest tests", "", "| s | test |", "|---|---|"]
        out += [f"| {t:.1f} | {n}{' (FAILED)' if f else ''} |" for t, n, f in cases]
    text = "\n".join(out) + "\n"
    (logs / "times.md").write_text(text)
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
