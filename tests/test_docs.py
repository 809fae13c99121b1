"""The documentation site builds with warnings as errors, and the README's links resolve."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytest.importorskip("mkdocs", reason="the docs extra is not installed")


def _build(tmp_path: Path, config: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # Material's notice about MkDocs 2, not a warning of the build
    args = ["build", "--strict", "--config-file", str(config), "--site-dir", str(tmp_path)]
    return subprocess.run(
        [sys.executable, "-m", "mkdocs", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_the_site_builds_strictly(tmp_path):
    """A broken link or anchor, a page missing from the nav or an API reference to no object fails the build."""
    run = _build(tmp_path / "site", ROOT / "mkdocs.yml")
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "site" / "api" / "methods" / "index.html").read_text().count("mindgap.prefbias.train") > 0


@pytest.mark.parametrize(
    "page, named",
    [
        ("[gone](no-such-page.md)", "no-such-page.md"),
        ("[gone](#no-such-anchor)", "no-such-anchor"),
        ("::: mindgap.no_such_module", "mindgap.no_such_module"),
    ],
)
def test_a_broken_reference_fails_the_build(tmp_path, page, named):
    """The strict build is what guards the pages: a dead link or anchor and a missing API object each fail it."""
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text(f"# t\n\n{page}\n")
    config = tmp_path / "mkdocs.yml"
    text = (ROOT / "mkdocs.yml").read_text()
    text = re.sub(r"(?ms)^nav:.*", "nav:\n  - index.md\n", text)
    text = text.replace("docs_dir: docs", f"docs_dir: {docs}").replace("paths: [src]", f"paths: [{ROOT / 'src'}]")
    config.write_text(text)
    run = _build(tmp_path / "site", config)
    assert run.returncode != 0 and named in run.stdout + run.stderr


def _relative_links(markdown: str) -> list[str]:
    """Targets of Markdown links and images that point into the repository (no scheme, no bare anchor)."""
    text = re.sub(r"(?s)```.*?```", "", markdown)
    targets = re.findall(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", text)
    targets += re.findall(r"<img[^>]+src=\"([^\"]+)\"", text)
    return [t for t in targets if not urlparse(t).scheme and not t.startswith("#")]


def test_every_relative_link_in_the_readme_resolves():
    links = _relative_links((ROOT / "README.md").read_text())
    assert any(link.endswith(".png") for link in links) and any(link.startswith("docs/") for link in links)
    missing = [link for link in links if not (ROOT / unquote(link.split("#")[0])).is_file()]
    assert not missing, f"README links to files that do not exist: {missing}"


def test_the_terrain_snippet_runs():
    """The terrain worlds page's example: the person does not expect precise moves on ice."""
    page = (ROOT / "docs" / "domains" / "terrain.md").read_text()
    snippet = next(s for s in re.findall(r"```python\n(.*?)```", page, re.S) if "surprise" in s)
    namespace: dict = {}
    exec(compile(snippet, "docs/domains/terrain.md", "exec"), namespace)
    surprise, check = namespace["surprise"], namespace["check"]
    assert surprise["robot"] > surprise["person"] + 2
    assert check.true.ice > check.true.sand and check.expected.sand > check.expected.ice


def test_the_readme_claims_table_is_what_the_committed_runs_decide():
    """The README's ✓/✗ table and its tally are generated from results/ (``mindgap report results --readme``)."""
    from mindgap.experiments.report import find_runs, with_claims

    text = (ROOT / "README.md").read_text()
    table = text.split("<!-- claims:start -->")[1].split("<!-- claims:end -->")[0]
    assert table.count("\n| ") > 2  # a header and at least one claim
    assert with_claims(text, find_runs([ROOT / "results"]), ROOT) == text, (
        "README.md's claims differ from what results/ decides: run `mindgap report results --readme README.md`"
    )
