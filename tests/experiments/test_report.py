"""``mindgap report``: the run folders it reads, the page it writes, what it refuses.

The folders here are written by hand in the experiments' formats (the run's own tests check
the report on real ``--fast`` runs through :mod:`report_check`), so every experiment, a
partial run and a fast run fit in one quick test.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from mindgap.cli import main
from mindgap.experiments import registry
from mindgap.experiments._runfolder import RunFolder, same_config, to_jsonable
from mindgap.experiments.claim_sources import PROJECT, SOURCES
from mindgap.experiments.report import claims_markdown, find_runs, table_blocks, tally, tally_sentence
from mindgap.experiments.report_catalog import CATALOG

OURS, CONTROL = "eps/highest-explicability", "eps/coin-control"
"""A claim of the dissertation's and a check of the project's own, for the hand-written summaries."""


def _claim(cid, text, held, measured):
    return {"id": cid, "text": text, "held": held, "measured": measured}


def _summary(name: str) -> dict:
    if name == "table1":
        stats = {
            f"{param}|reversed|{m}": {
                "d_R": [d, 0.1],
                "d_Theta": [d / 10, 0.0],
                "d_pi": [d / 100, 0.0],
                "corr_R": [c, 0.0],
            }
            for param in ("tied", "per-sa")
            for m, d, c in (
                ("gerel", 2.0, 0.9),
                ("serd", 3.0, 0.5),
                ("gerel-minus", 9.0, -0.8),
                ("maxent-irl", 8.0, -0.7),
            )
        }
        # the dissertation's per-(s, a) belief makes claims (1 held, 1 not); the tied one is the project's (1, 1)
        checks = {
            "tied|reversed": {"gerel_lowest_d_R": True, "tied_d_Theta<=0.10": False},
            "per-sa|reversed": {"gerel_lowest_d_R": True, "gerel_lowest_d_pi": False},
        }
        return {
            "stats": stats,
            "checks": checks,
            "basins": {},
            "table_md": "\nBelief parameterisation: tied\n\n| a |\n|---|\n| 1 |\n",
        }
    if name == "coffee":
        spill = {"humanoid": {"spill": [0.6, 0.1]}, "mobile": {"spill": [0.2, 0.1]}}
        learned = {
            "GeReL (per-sa)": spill,
            "GeReL (factored)": spill,
            "GeReL⁻": {"humanoid": {"wet_penalty": [5.0, 1.0]}, "mobile": {"wet_penalty": [3.0, 1.0]}},
        }
        # the dissertation's: per-sa's spill (held) and GeReL⁻'s "opposite" wetness (not: its humanoid
        # penalty is the higher); the project's: the factored belief's spill (held); GeReL⁻'s spill is
        # not learned and makes no claim, an undecided ordering none either
        orderings = {
            "GeReL (per-sa)": {"spill_humanoid_gt_mobile": True, "spill_order_matches_truth": None},
            "GeReL (factored)": {"spill_humanoid_gt_mobile": True},
            "GeReL⁻": {"spill_humanoid_gt_mobile": False, "wet_penalty_humanoid_gt_mobile": True},
        }
        return {
            "table2": {},
            "learned": learned,
            "orderings": orderings,
            "table_md": "Table 2 (simulated)\n\n| q |\n|---|\n| 1 |",
        }
    return {
        "experiment": name,
        "claims": [
            _claim(OURS, f"{name}: first claim", True, "1.0"),
            _claim(OURS, f"{name}: second claim", False, "0.5"),
            _claim(CONTROL, f"{name}: a control", True, "0.9"),
        ],
        "table_md": f"{name} (Table 3): ours\n\n| world | x |\n|---|---|\n| w | 1 |\n",
    }


def _folder(root: Path, name: str, preset: str, *, missing=(), summary=True, label=None) -> Path:
    out = root / (label or f"{name}-{preset}")
    folder = RunFolder(out, registry.module(name).preset(preset))
    keys = [f"w/job{i}" for i in range(3)]
    for k in keys:
        if k not in missing:
            folder.save(k, {"key": k})
    folder.write_progress(name, keys, registry.command(name, registry.module(name).preset(preset), out))
    if summary:
        (out / "summary.json").write_text(json.dumps(_summary(name)))
    return out


def test_report_shows_every_experiment_with_its_claims_and_marks_fast_and_partial_runs(tmp_path, capsys):
    runs = tmp_path / "runs"
    for name in registry.NAMES:
        _folder(runs, name, "full")
    _folder(runs, "nav", "fast")
    _folder(runs, "lambda", "full", missing=("w/job2",), label="lambda-partial")
    out = tmp_path / "report"
    assert main(["report", str(runs), "--out", str(out)]) == 0
    md, html = (out / "report.md").read_text(), (out / "report.html").read_text()
    for name, entry in CATALOG.items():
        assert f"## {entry.title} ({entry.section}, `mindgap reproduce {name}`)" in md
    assert md.count("`--fast`: numbers mean nothing") == 1
    assert "partial: 1 jobs missing" in md and "`w/job2`" in md
    assert "2 of 3 jobs finished" in md
    # the tally counts the full runs' claims of the dissertation only: every experiment but table1 and
    # coffee with 1 held + 1 not (lambda twice), table1 1 + 1, coffee 1 + 1; the project's checks apart:
    # 1 held per generic run, table1 1 + 1, coffee 1 held
    generic = len(registry.NAMES) - 2 + 1
    assert f"the dissertation's claims: {generic + 2} ✓, {generic + 2} ✗;" in md
    assert f"the project's own checks: {generic + 2} ✓, 1 ✗." in md
    lowest = SOURCES["table1/gerel-lowest"]
    assert (
        "| ✓ | reversed, per-sa belief: GeReL has the lowest d(R) of the four methods | "
        f"{lowest.where}: {lowest.says} | GeReL 2, best other SERD 3 |" in md
    )
    assert "| ✓ | reversed, tied belief: GeReL has the lowest d(R) of the four methods | §2.2.2, l. 237: " in md
    tied = md.index("| ✗ | reversed, tied belief: GeReL's d(Θ) ≤ 0.10 | §2.3.1, l. 378: A target the project set")
    table1 = md[md.index("## GeReL on the grid world") : md.index("## The coffee-robot user study")]
    assert table1.index("The dissertation's claims:") < table1.index("The project's own checks (outside the tally):")
    assert md.index("The project's own checks (outside the tally):") < tied
    assert "| ✓ | GeReL (per-sa) learns a higher spill probability (with the umbrella) for the humanoid" in md
    assert "| ✗ | GeReL⁻ discovers the opposite: a higher wet penalty for the mobile robot" in md
    assert "GeReL⁻ learns a higher spill" not in md and "GeReL⁻ discovers the opposite per unit" not in md
    assert "mindgap reproduce nav --fast --out" in md
    # our table beside the dissertation's, picked out of table.md by its caption
    assert md.index("eps (Table 3): ours") > md.index("### Table 3")
    assert "<table>" in html and "12.17" in html and "95.53 (1.88)" in html
    assert "report in" in capsys.readouterr().out


def test_the_tally_names_finished_full_runs_with_or_without_claims(tmp_path):
    runs = tmp_path / "runs"
    _folder(runs, "nav", "full")
    sampling = _folder(runs, "sampling", "full")
    summary = json.loads((sampling / "summary.json").read_text())
    summary["claims"] = []  # sampling describes its figure and decides no claim by a rule
    (sampling / "summary.json").write_text(json.dumps(summary))
    _folder(runs, "priors", "fast")
    _folder(runs, "lambda", "full", missing=("w/job2",))
    _folder(runs, "coffee", "full", summary=False)  # under way: nothing assembled yet
    found = find_runs([runs])
    sentence = tally_sentence(found)
    # the partial run's claims count, and the sentence says whose they are; the project's checks do not
    assert sentence.startswith(
        "2 of 4 of the dissertation's claims hold in the full runs of nav, sampling (partial: coffee, lambda);"
    )
    assert tally(found, PROJECT) == {"held": 2, "failed": 0, "undecided": 0}
    rest = sentence.split("not run in full yet: ")[1].split(", ")
    assert "priors" in rest and "lambda" not in rest and "nav" not in rest and "sampling" not in rest


def test_report_embeds_figures_in_the_html_and_links_them_in_the_markdown(tmp_path):
    run = _folder(tmp_path / "runs", "eps", "full")
    png = Path(__file__).parents[2] / "docs" / "eps" / "d1-eps-routes.png"
    (run / "trajectories.png").write_bytes(png.read_bytes())
    (run / "results.csv").write_text("a\n1\n")
    out = tmp_path / "report"
    assert main(["report", str(run), "--out", str(out)]) == 0
    md, html = (out / "report.md").read_text(), (out / "report.html").read_text()
    assert "![trajectories.png](../runs/eps-full/trajectories.png)" in md
    assert "[results.csv](../runs/eps-full/results.csv)" in md
    assert "data:image/png;base64," in html and "../runs/eps-full/trajectories.png" not in html


def test_a_run_without_summary_is_shown_as_not_assembled(tmp_path):
    run = _folder(tmp_path / "runs", "priors", "full", summary=False)
    (run / "summary.json").unlink(missing_ok=True)
    out = tmp_path / "report"
    assert main(["report", str(run), "--out", str(out)]) == 0
    assert "No `summary.json` yet" in (out / "report.md").read_text()


@pytest.mark.parametrize(
    "setup, message",
    [
        (lambda root: root / "nowhere", "no such folder"),
        (lambda root: root, "neither a run folder"),
    ],
)
def test_report_refuses_what_is_not_a_run_folder_with_one_line(tmp_path, capsys, setup, message):
    out = tmp_path / "report"
    assert main(["report", str(setup(tmp_path)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_readme_claims_block_is_rewritten_between_its_markers_and_refused_without_them(tmp_path, capsys):
    runs = tmp_path / "runs"
    _folder(runs, "nav", "full")
    _folder(runs, "eps", "fast")
    readme = tmp_path / "README.md"
    readme.write_text("# x\n\nbefore\n<!-- claims:start -->\nthe stale table\n<!-- claims:end -->\nafter\n")
    assert main(["report", str(runs), "--out", str(tmp_path / "r"), "--readme", str(readme)]) == 0
    text = readme.read_text()
    assert (
        "the stale table" not in text
        and text.startswith("# x\n\nbefore\n")
        and text.endswith("<!-- claims:end -->\nafter\n")
    )
    ours = SOURCES[OURS]
    assert (
        f"([run](runs/nav-full/)) (§3.4.2.1, §3.4.3) | nav: first claim | {ours.where}: {ours.says} | 1.0 | ✓ |" in text
    )
    control = SOURCES[CONTROL]
    checks = text.split("outside the tally:")[1]
    assert f"| nav: a control | {control.where}: {control.says} | 0.9 | ✓ |" in checks
    assert "nav: first claim" not in checks
    assert "docs/experiments/prefbias.md)" in text
    assert "eps:" not in text  # a fast run's claims mean nothing
    plain = tmp_path / "PLAIN.md"
    plain.write_text("no markers\n")
    out = tmp_path / "r2"
    assert main(["report", str(runs), "--out", str(out), "--readme", str(plain)]) == 2
    assert "claims:start" in capsys.readouterr().err
    assert plain.read_text() == "no markers\n" and not out.exists()
    ours, _, checks = claims_markdown(find_runs([runs])).partition("outside the tally:")
    assert ours.count("\n| nav (") == 2 and checks.count("\n| nav (") == 1  # nav's two claims, its control


def test_table_blocks_cut_table_md_at_its_captions():
    text = "A caption\n\n| a |\n|---|\n| 1 |\n\nB caption\n| b |\n|---|\n\ntrailing words"
    assert table_blocks(text) == ["A caption\n\n| a |\n|---|\n| 1 |", "B caption\n| b |\n|---|", "trailing words"]


def test_presets_and_rerun_commands_are_read_from_config():
    nav = registry.module("nav")
    full = nav.preset("full")
    assert registry.preset_of("nav", full) == "full"
    assert registry.preset_of("nav", dataclasses.replace(full, seeds=2, worlds=("nav1",))) == "full"
    cmd = registry.command("nav", dataclasses.replace(full, seeds=2, worlds=("nav1",)), "runs/n")
    assert cmd == "mindgap reproduce nav --seeds 2 --worlds nav1 --out runs/n"
    assert registry.command("eps", registry.module("eps").preset("fast"), "o") == "mindgap reproduce eps --fast --out o"
    custom = dataclasses.replace(full, learners=registry.module("nav").preset("fast").learners)
    assert registry.preset_of("nav", custom) == "custom"
    assert registry.command("table1", dataclasses.replace(registry.module("table1").preset("full"), seeds=3), "t") == (
        "mindgap reproduce table1 --seeds 3 --out t"
    )


@dataclasses.dataclass(frozen=True)
class _Old:
    a: int = 1


@dataclasses.dataclass(frozen=True)
class _New:
    a: int = 1
    added: str = "default"
    inner: _Old = _Old()


def test_a_config_written_before_a_field_was_added_matches_only_at_that_fields_default():
    stored = {"a": 1, "inner": {"a": 1}}
    assert same_config(stored, _New())
    assert not same_config(stored, _New(added="other"))
    assert not same_config(stored, _New(a=2))
    assert not same_config({**stored, "gone": 0}, _New())
    assert same_config(json.loads(json.dumps(to_jsonable(_New(added="x")))), _New(added="x"))


def test_run_folder_resumes_a_folder_written_before_a_field_was_added(tmp_path):
    (tmp_path / "config.json").write_text(json.dumps({"a": 1, "inner": {"a": 1}}, indent=2, sort_keys=True))
    before = (tmp_path / "config.json").read_text()
    RunFolder(tmp_path, _New())
    assert (tmp_path / "config.json").read_text() == before  # kept as it was written
    with pytest.raises(RuntimeError, match="another configuration"):
        RunFolder(tmp_path, _New(added="other"))
