"""``mindgap report``: gather experiments' run folders into one page beside the dissertation.

mindgap report RUN_DIR [RUN_DIR …] [--out DIR] [--readme FILE]

Each RUN_DIR is a run folder of ``mindgap reproduce`` or a folder holding several (e.g.
``results/``). Writes ``DIR/report.html`` (self-contained) and ``DIR/report.md``
(:mod:`mindgap.experiments.report`). ``--readme FILE`` also rewrites the claims table
between FILE's ``<!-- claims:start -->`` and ``<!-- claims:end -->`` lines.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub) -> None:
    r = sub.add_parser("report", help="one HTML/Markdown page of experiments' results beside the dissertation's")
    r.add_argument("runs", nargs="+", type=Path, help="run folders, or folders holding run folders")
    r.add_argument("--out", type=Path, default=Path("report"), help="folder for report.html and report.md")
    r.add_argument("--readme", type=Path, help="also rewrite this file's claims table (between its claims markers)")


def run(args: argparse.Namespace) -> int:
    from ..experiments.report import find_runs, update_claims_block, write_report

    if args.readme is not None:
        update_claims_block(args.readme, find_runs(args.runs))  # refused before anything is written
    html, md, runs = write_report(args.runs, args.out)
    for r in runs:
        held = sum(c["held"] is True for c in r.claims)
        failed = sum(c["held"] is False for c in r.claims)
        jobs = f"{r.jobs_done}/{r.jobs_total}" if r.jobs_total is not None else f"{r.jobs_done}"
        print(f"{r.experiment:9s} {r.preset:6s} jobs {jobs:>7s}  claims {held} held, {failed} not  ({r.path})")
    print(f"report in {html} and {md}")
    return 0
