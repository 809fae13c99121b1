"""The default suite's CPU time per test file against its budget in docs/development.md.

    python scripts/test_budget.py LOG            # files over their budget, files without one, the total
    python scripts/test_budget.py LOG --write    # rewrite the budget table from this run (a cold one)

LOG is the file ``MINDGAP_TEST_CPU_LOG`` names during a run (``scripts/test.sh`` sets it): one JSON
line per test file, its CPU seconds (the test process and its finished subprocesses) and wall seconds.
A file's budget is what it took on a cold run on the quiet 2-core machine, plus a quarter, rounded up
to 5 s; a change that makes a file cost more shows here, and a rewritten table shows in its diff.

Machines of one kind differ (a later one took 1.31 times the table's times, file for file), so the
report also gives this machine's pace — the median, over the files of 10 CPU-s or more in the table,
of their time here against the table's measured column — and says which files are over their
budget even at that pace: those grew, where the others only ran on a slower machine.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
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


def _rows(doc: str) -> list[re.Match]:
    """The rows of the budget table in docs/development.md."""
    if BEGIN not in doc:
        return []
    table = doc[doc.index(BEGIN) : doc.index(END)]
    return [m for line in table.splitlines() if (m := ROW.match(line))]


def budgets(doc: str) -> dict[str, int]:
    """The budget table of docs/development.md: test file → CPU seconds."""
    return {m["file"]: int(m["budget"]) for m in _rows(doc)}


def measured_column(doc: str) -> dict[str, float]:
    """The budget table's measured column: test file → CPU seconds on the machine that wrote it."""
    return {m["file"]: float(m["measured"]) for m in _rows(doc)}


def pace(times: dict[str, tuple[float, float]], column: dict[str, float], least: float = 10.0) -> float | None:
    """This run's CPU time against the table's, the median over files the table measured at ``least`` s or
    more (None with fewer than 5 such files)."""
    ratios = [times[f][0] / t for f, t in column.items() if t >= least and f in times]
    return statistics.median(ratios) if len(ratios) >= 5 else None


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
    speed = pace(times, measured_column(doc))
    scale = max(speed or 1.0, 1.0)
    grew = [f for f, cpu, b in over if cpu > b * scale]
    for f, cpu, b in sorted(over, key=lambda x: x[1] - x[2], reverse=True):
        at_pace = (
            f" and of {b * scale:.0f} at this machine's pace"
            if f in grew
            else f" ({b * scale:.0f} at this machine's pace)"
        )
        print(f"test_budget: {f} took {cpu:.0f} CPU-s, over its budget of {b}" + (at_pace if scale > 1 else ""))
    for f, cpu in sorted(new, key=lambda x: -x[1]):
        print(f"test_budget: {f} took {cpu:.0f} CPU-s and has no budget in docs/development.md")
    if speed is not None:
        print(f"test_budget: this machine's pace: {speed:.2f} times the table's measured column (median of its files)")
    print(
        f"test_budget: {len(times)} test files, {total / 60:.1f} CPU-minutes in the test processes; "
        f"{len(over)} over budget ({len(grew)} also at this machine's pace), {len(new)} without one"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
