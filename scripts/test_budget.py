"""The default suite's CPU time per test file against its budget in docs/development.md.

    python scripts/test_budget.py LOG            # files over their budget, files without one, the total
    python scripts/test_budget.py LOG --write    # rewrite the budget table from this run (a cold one)

LOG is the file ``MINDGAP_TEST_CPU_LOG`` names during a run (``scripts/test.sh`` sets it): one JSON
line per test file, its CPU seconds (the test process and its finished subprocesses) and wall seconds.
A file's budget is what it took on a cold run on the quiet 2-core machine, plus a quarter, rounded up
to 5 s; a change that makes a file cost more shows here, and a rewritten table shows in its diff.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "development.md"
BEGIN, END = "<!-- budget per test file: begin -->", "<!-- budget per test file: end -->"
ROW = re.compile(r"^\| `(?P<file>[^`]+)` \| (?P<budget>\d+) \| (?P<measured>[\d.]+) \|$")


def measured(log: Path) -> dict[str, tuple[float, float]]:
    """CPU and wall seconds per test file (summed if a file's lines repeat)."""
    out: dict[str, tuple[float, float]] = {}
    for line in log.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            cpu, wall = out.get(r["file"], (0.0, 0.0))
            out[r["file"]] = (cpu + r["cpu_s"], wall + r["wall_s"])
    return out


def budgets(doc: str) -> dict[str, int]:
    """The budget table of docs/development.md: test file → CPU seconds."""
    if BEGIN not in doc:
        return {}
    table = doc[doc.index(BEGIN) : doc.index(END)]
    return {m["file"]: int(m["budget"]) for line in table.splitlines() if (m := ROW.match(line))}


def table(times: dict[str, tuple[float, float]]) -> str:
    rows = ["| test file | budget, CPU-s | measured cold, CPU-s |", "|---|---|---|"]
    for f, (cpu, _) in sorted(times.items(), key=lambda kv: -kv[1][0]):
        rows.append(f"| `{f}` | {5 * math.ceil(1.25 * cpu / 5)} | {cpu:.1f} |")
    return "\n".join(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", type=Path)
    ap.add_argument("--write", action="store_true", help="rewrite the budget table from this run")
    args = ap.parse_args()
    if not args.log.is_file():
        print(f"test_budget: no such file: {args.log}", file=sys.stderr)
        return 2
    times = measured(args.log)
    doc = DOC.read_text()
    if args.write:
        if BEGIN not in doc:
            print(f"test_budget: {DOC} has no {BEGIN} … {END} block", file=sys.stderr)
            return 2
        DOC.write_text(doc[: doc.index(BEGIN) + len(BEGIN)] + "\n" + table(times) + "\n" + doc[doc.index(END) :])
        print(f"test_budget: wrote the budgets of {len(times)} test files into {DOC}")
        return 0
    limit = budgets(doc)
    over = [(f, cpu, limit[f]) for f, (cpu, _) in times.items() if f in limit and cpu > limit[f]]
    new = [(f, cpu) for f, (cpu, _) in times.items() if f not in limit and cpu >= 5]
    total = sum(cpu for cpu, _ in times.values())
    for f, cpu, b in sorted(over, key=lambda x: x[1] - x[2], reverse=True):
        print(f"test_budget: {f} took {cpu:.0f} CPU-s, over its budget of {b}")
    for f, cpu in sorted(new, key=lambda x: -x[1]):
        print(f"test_budget: {f} took {cpu:.0f} CPU-s and has no budget in docs/development.md")
    print(
        f"test_budget: {len(times)} test files, {total / 60:.1f} CPU-minutes in the test processes; "
        f"{len(over)} over budget, {len(new)} without one"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
