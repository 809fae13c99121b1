"""What every experiment's test checks of ``mindgap report`` on the run folder it made."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from mindgap.cli import main
from mindgap.experiments.claim_sources import SOURCES
from mindgap.experiments.report_catalog import CATALOG, claims


def check_report(run_dir: Path, out: Path, name: str, *, fast: bool = True) -> str:
    """Run ``mindgap report run_dir``; check the section, its marks and its items; return the Markdown.

    What the command prints is kept out of the calling test's captured output.
    """
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["report", str(run_dir), "--out", str(out)]) == 0
    md = (out / "report.md").read_text()
    html = (out / "report.html").read_text()
    entry = CATALOG[name]
    assert f"## {entry.title} ({entry.section}, `mindgap reproduce {name}`)" in md
    assert ("`--fast`: numbers mean nothing" in md) == fast
    for item in entry.items:
        assert f"### {item.name}" in md
        assert f"<h3>{item.name}</h3>" in html
    summary = json.loads((run_dir / "summary.json").read_text())
    for c in claims(name, summary):  # each mark is the experiment's own verdict on its results
        mark = {True: "✓", False: "✗", None: "–"}[c["held"]]
        assert c["id"] in SOURCES, c  # every claim an experiment makes says where it comes from
        assert f"| {mark} | {c['text']} | {c['where']}: {c['says']} | {c['measured']} |" in md
    for img in (out / "report.md").read_text().split("](")[1:]:
        target = img.split(")")[0]
        if not target.startswith(("http", "#")):
            assert (out / target).resolve().exists(), target
    return md
