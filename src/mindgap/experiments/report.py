"""``mindgap report``: one page gathering experiments' run folders beside the dissertation.

For each run folder it reads ``config.json`` (which experiment, which preset),
``progress.json`` (the jobs finished and missing, the version and the command that
finishes the run), ``summary.json`` (the tables and the claims, decided by the experiment
from its results) and the figures and CSVs the experiment wrote, and renders them with the
dissertation's numbers (:mod:`~.report_catalog`) into ``report.html`` (self-contained:
figures embedded) and ``report.md`` (figures and CSVs linked). Templates are Jinja2
(``templates/report.*.j2``); Markdown tables become HTML with Python-Markdown.
"""

from __future__ import annotations

import base64
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .._io import atomic_write
from . import registry
from .claim_sources import DISSERTATION, PROJECT
from .report_catalog import CATALOG, GRID, claims

_MIME = {".png": "image/png", ".gif": "image/gif", ".svg": "image/svg+xml", ".webp": "image/webp"}


@dataclass
class Run:
    """One experiment's run folder, as the report shows it."""

    path: Path
    experiment: str
    preset: str
    config: dict
    summary: dict | None
    progress: dict | None
    claims: list[dict] = field(default_factory=list)
    jobs_done: int = 0
    jobs_total: int | None = None
    missing: list[str] = field(default_factory=list)
    stale: bool = False
    """The folder holds job records newer than its ``summary.json``."""

    @property
    def fast(self) -> bool:
        return self.preset == "fast"

    @property
    def dissertation_claims(self) -> list[dict]:
        """The claims the dissertation makes (:data:`~.claim_sources.DISSERTATION`): the tally's."""
        return [c for c in self.claims if c["kind"] == DISSERTATION]

    @property
    def project_checks(self) -> list[dict]:
        """The project's own checks (:data:`~.claim_sources.PROJECT`): shown apart, outside the tally."""
        return [c for c in self.claims if c["kind"] != DISSERTATION]

    @property
    def command(self) -> str:
        if self.progress and self.progress.get("command"):
            return self.progress["command"]
        if self.experiment not in registry.NAMES:
            return "mindgap sweep SPEC"
        return registry.command(self.experiment, self.config, self.path)

    @property
    def entry(self):
        """What the catalogue says of this run's experiment (a grid sweep's part: :data:`~.report_catalog.GRID`)."""
        return CATALOG.get(self.experiment, GRID)

    @property
    def how(self) -> str:
        """The command that makes runs of this kind."""
        return f"mindgap reproduce {self.experiment}" if self.experiment in registry.NAMES else "mindgap sweep"


def find_runs(paths) -> list[Run]:
    """The run folders under ``paths``: each path is a run folder or a folder of them (one level).

    Raises:
        ValueError: a path that does not exist or holds no run folder (one line, naming it).
    """
    runs: list[Run] = []
    for p in map(Path, paths):
        if not p.is_dir():
            raise ValueError(f"{p}: no such folder")
        if (p / "config.json").exists():
            runs.append(read_run(p))
            continue
        found = sorted(c for c in p.iterdir() if (c / "config.json").exists())
        if not found:
            raise ValueError(f"{p}: neither a run folder (no config.json) nor a folder of run folders")
        runs += [read_run(c) for c in found]
    order = {name: i for i, name in enumerate(registry.NAMES)}
    return sorted(runs, key=lambda r: (order.get(r.experiment, len(order)), str(r.path)))


def read_run(path: Path) -> Run:
    """Read one run folder (see the module docstring).

    Raises:
        ValueError: a folder no named experiment made.
    """
    path = Path(path)
    config = _json(path / "config.json")
    summary = _json(path / "summary.json") if (path / "summary.json").exists() else None
    progress = _json(path / "progress.json") if (path / "progress.json").exists() else None
    name = _experiment(path, config, summary, progress)
    preset = registry.preset_of(name, config) if name in registry.NAMES else str(config.get("preset", "custom"))
    run = Run(path, name, preset, config, summary, progress)
    records = list((path / "jobs").glob("*.json"))
    run.jobs_done = len(records)
    if progress:
        run.jobs_total = progress["jobs"]
        run.jobs_done = progress["done"]
        run.missing = list(progress["missing"])
    if summary is not None:
        run.claims = claims(name, summary)
        newest = max((p.stat().st_mtime for p in records), default=0.0)
        run.stale = newest > (path / "summary.json").stat().st_mtime
    return run


def _json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not readable JSON ({e})") from None


def _experiment(path: Path, config: dict, summary: dict | None, progress: dict | None) -> str:
    for source in (progress, summary):
        if source and source.get("experiment") in (*registry.NAMES, "grid"):
            return source["experiment"]
    if summary and "table2" in summary:
        return "coffee"
    if summary and "checks" in summary and "basins" in summary:
        return "table1"
    for name in registry.NAMES:
        if registry.preset_of(name, config) != "custom":
            return name
    raise ValueError(f"{path}: not a run folder of a named experiment ({', '.join(registry.NAMES)})")


def tally(runs: list[Run], kind: str = DISSERTATION) -> dict:
    """The dissertation's claims (or, with ``kind`` :data:`~.claim_sources.PROJECT`, the project's
    own checks) held / not held / undecided over the full-preset runs (fast runs' numbers mean nothing)."""
    counted = [
        c for r in runs if not r.fast for c in (r.dissertation_claims if kind == DISSERTATION else r.project_checks)
    ]
    return {
        "held": sum(c["held"] is True for c in counted),
        "failed": sum(c["held"] is False for c in counted),
        "undecided": sum(c["held"] is None for c in counted),
    }


def _context(runs: list[Run], out: Path, embed: bool) -> dict:
    import markdown as md

    def files(run, patterns):
        seen = []
        for pat in patterns:
            seen += [p for p in sorted(run.path.glob(pat)) if p not in seen]
        return seen

    def link(p: Path) -> str:
        return Path(os.path.relpath(p.resolve(), out.resolve())).as_posix()

    def picture(p: Path) -> str:
        if not embed:
            return link(p)
        return f"data:{_MIME[p.suffix.lower()]};base64," + base64.b64encode(p.read_bytes()).decode()

    sections = []
    for run in runs:
        entry = run.entry
        items = []
        table_md = (run.summary or {}).get("table_md", "")
        for item in entry.items:
            figs = [f for f in files(run, item.figures) if f.suffix.lower() in _MIME]
            ours = "\n\n".join(b for b in table_blocks(table_md) if any(w in b for w in item.tables))
            items.append(
                {
                    "name": item.name,
                    "ours_md": ours,
                    "ours_html": md.markdown(ours, extensions=["tables"]) if ours else "",
                    "paper_md": item.paper,
                    "paper_html": md.markdown(item.paper, extensions=["tables"]),
                    "figures": [{"src": picture(f), "name": f.name} for f in figs],
                    "files": [{"href": link(f), "name": f.name} for f in files(run, item.files)],
                }
            )
        sections.append(
            {
                "run": run,
                "title": entry.title,
                "section": entry.section,
                "anchor": f"{run.experiment}-{run.path.name}",
                "how": run.how,
                "items": items,
                "table_md": table_md.strip(),
                "table_html": md.markdown(table_md, extensions=["tables"]),
                "config_json": json.dumps(run.config, indent=2, sort_keys=True),
                "config_href": link(run.path / "config.json"),
                "path": link(run.path),
            }
        )
    from .. import __version__

    return {
        "sections": sections,
        "tally": tally(runs),
        "checks_tally": tally(runs, PROJECT),
        "version": __version__,
        "written": time.strftime("%Y-%m-%d %H:%M %Z"),
    }


def table_blocks(table_md: str) -> list[str]:
    """``table.md`` cut into its captioned tables: each block is the text before a table and the table."""
    blocks, lines, in_table = [], [], False
    for line in table_md.strip().splitlines():
        is_row = line.lstrip().startswith("|")
        if in_table and not is_row:
            blocks.append("\n".join(lines).strip())
            lines = []
        in_table = is_row
        lines.append(line)
    if lines:
        blocks.append("\n".join(lines).strip())
    return [b for b in blocks if b]


def _env():
    import jinja2

    return jinja2.Environment(
        loader=jinja2.PackageLoader("mindgap.experiments", "templates"),
        autoescape=jinja2.select_autoescape(["html.j2"]),
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def write_report(paths, out: str | Path = "report") -> tuple[Path, Path, list[Run]]:
    """Write ``report.html`` and ``report.md`` for the run folders under ``paths`` into ``out``.

    Returns:
        The two files' paths and the runs they show.
    """
    runs = find_runs(paths)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = _env()
    html = env.get_template("report.html.j2").render(**_context(runs, out, embed=True))
    text = env.get_template("report.md.j2").render(**_context(runs, out, embed=False))
    atomic_write(out / "report.html", html)
    atomic_write(out / "report.md", text)
    return out / "report.html", out / "report.md", runs


def claims_markdown(runs: list[Run], relative_to: str | Path | None = None) -> str:
    """The claims of the full-preset runs as Markdown (✓ held, ✗ not, – undecided): a table of the
    dissertation's claims, each with where the dissertation says it, then, apart, a table of the
    project's own checks with why the project checks them (none: no second table).

    With ``relative_to`` (the folder of the file the table goes into), each experiment links
    to its documentation page and its run's tables (``table.md``, else the run folder).
    """
    ours = ["| experiment | claim, as checked here | the dissertation | measured | |", "|---|---|---|---|---|"]
    checks = ["| experiment | check | why the project checks it | measured | |", "|---|---|---|---|---|"]
    for run in runs:
        if run.fast:
            continue
        entry = run.entry
        where = run.experiment
        if relative_to is not None:
            base = Path(relative_to).resolve()
            docs = Path(__file__).resolve().parents[3] / entry.docs
            tables = run.path / "table.md"
            target = _rel(tables, base) if tables.exists() else _rel(run.path, base) + "/"
            where = f"[{run.experiment}]({target})"
            if docs.exists():  # a source checkout: the docs are beside the package
                where = f"[{run.experiment}]({_rel(docs, base)}) ([run]({target}))"
        for c in run.claims:
            mark = {True: "✓", False: "✗", None: "–"}[c["held"]]
            source = f"{c['where']}: {c['says']}" if c["where"] else c["says"]
            rows = ours if c["kind"] == DISSERTATION else checks
            rows.append(f"| {where} ({entry.section}) | {c['text']} | {source} | {c['measured']} | {mark} |")
    text = "\n".join(ours) + "\n"
    if len(checks) > 2:
        text += (
            "\nThe project's own checks (controls, thresholds it chose, belief parameterisations the "
            "dissertation does not use), outside the tally:\n\n" + "\n".join(checks) + "\n"
        )
    return text


def _rel(path: Path, base: Path) -> str:
    return Path(os.path.relpath(Path(path).resolve(), base)).as_posix()


CLAIMS_START, CLAIMS_END = "<!-- claims:start -->", "<!-- claims:end -->"
TALLY_START, TALLY_END = "<!-- tally:start -->", "<!-- tally:end -->"


def update_claims_block(path: str | Path, runs: list[Run]) -> None:
    """Replace the lines between ``path``'s claims markers with :func:`claims_markdown` of ``runs``,
    and the text between its tally markers (if it has them) with :func:`tally_sentence`.

    Raises:
        ValueError: the file lacks the claims markers (nothing is written).
    """
    path = Path(path)
    text = path.read_text()
    if CLAIMS_START not in text or CLAIMS_END not in text:
        raise ValueError(f"{path}: no {CLAIMS_START} … {CLAIMS_END} lines to put the claims between")
    atomic_write(path, with_claims(text, runs, path.parent))


def with_claims(text: str, runs: list[Run], relative_to: str | Path) -> str:
    """``text`` with its claims table and tally sentence made from ``runs`` (links relative to ``relative_to``)."""
    text = _between(text, CLAIMS_START, CLAIMS_END, "\n" + claims_markdown(runs, relative_to=relative_to))
    if TALLY_START in text and TALLY_END in text:
        text = _between(text, TALLY_START, TALLY_END, tally_sentence(runs))
    return text


def _between(text: str, start: str, end: str, block: str) -> str:
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}{block}{end}{tail}"


def tally_sentence(runs: list[Run]) -> str:
    """``N of M of the dissertation's claims hold in the full runs of …; not run in full yet: …``
    (fast runs and the project's own checks left out).

    An experiment counts as run in full when a finished (assembled, no job missing) full-preset
    run of it is among ``runs``, whether or not it decides claims by a rule (``sampling`` only
    describes its figure); a full-preset run still under way is named as partial.
    """
    t = tally(runs)
    total = t["held"] + t["failed"] + t["undecided"]
    full = [
        n
        for n in registry.NAMES
        if any(r.experiment == n and r.preset == "full" and r.summary and not r.missing for r in runs)
    ]
    partial = [
        n for n in registry.NAMES if n not in full and any(r.experiment == n and r.preset == "full" for r in runs)
    ]
    rest = [n for n in registry.NAMES if n not in full and n not in partial]
    text = f"{t['held']} of {total} of the dissertation's claims hold in the full runs of {', '.join(full) or 'no experiment'}"
    text += f" (partial: {', '.join(partial)})" if partial else ""
    return text + (f"; not run in full yet: {', '.join(rest)}" if rest else "")
