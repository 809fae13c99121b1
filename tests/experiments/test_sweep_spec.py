"""Sweep files (:mod:`mindgap.experiments.sweep_spec`): a bad one is refused before anything runs,
in one line naming the file, the key and the problem; a good one lists its parts and jobs."""

from __future__ import annotations

import pytest

from mindgap.cli import main
from mindgap.experiments import sweep_grid, sweep_spec

GOOD = """
[sweep]
out = "{out}"
workers = 2

[[experiment]]
name = "table1"
preset = "fast"

[grid]
methods = ["pebble", "prefbias"]
worlds = ["nav1", "nav2"]
seeds = [0, 1]
[grid.params]
queries = [30, 60]
"sac.lr" = [0.0003]
"""

BAD = [
    # (what is wrong, the file, the key the message names, words of the problem)
    (
        "unknown method",
        '[grid]\nmethods = ["pebble", "ppo"]\nworlds = ["nav1"]\n',
        "grid.methods[1]",
        "unknown method 'ppo'",
    ),
    ("missing field", '[grid]\nmethods = ["pebble"]\n', "grid.worlds", "missing"),
    (
        "a world that cannot be imported",
        '[grid]\nmethods = ["sac"]\nworlds = ["nav1", "no/such/file.py:make_world"]\n',
        "grid.worlds[1]",
        "no/such/file.py:make_world",
    ),
    ("unknown experiment", '[[experiment]]\nname = "table9"\n', "experiment[0].name", "unknown experiment"),
    ("experiment without a name", '[[experiment]]\npreset = "fast"\n', "experiment[0].name", "missing"),
    ("unknown key", '[[experiment]]\nname = "table1"\nseed = 3\n', "experiment[0].seed", "unknown key"),
    (
        "option it does not take",
        '[[experiment]]\nname = "table1"\nworlds = ["nav1"]\n',
        "experiment[0].worlds",
        "does not take",
    ),
    (
        "hyperparameter of no method",
        '[grid]\nmethods = ["sac"]\nworlds = ["nav1"]\n[grid.params]\nqueries = [30]\n',
        "grid.params.queries",
        "not a setting of sac",
    ),
    (
        "hyperparameter of the wrong kind",
        '[grid]\nmethods = ["pebble"]\nworlds = ["nav1"]\n[grid.params]\nqueries = ["many"]\n',
        "grid.params.queries",
        "expected int",
    ),
    ("unknown backend", '[sweep]\nbackend = "slurm"\n[[experiment]]\nname = "table1"\n', "sweep.backend", "slurm"),
    ("nothing to run", "[sweep]\nworkers = 2\n", "experiment", "nothing to run"),
    ("not TOML", "[grid\nmethods = 1\n", None, "not valid TOML"),
]


@pytest.mark.parametrize("what,text,key,problem", BAD, ids=[b[0] for b in BAD])
def test_a_bad_sweep_file_is_refused_in_one_line_before_anything_runs(tmp_path, capsys, what, text, key, problem):
    spec = tmp_path / "bad.toml"
    spec.write_text(f'[sweep]\nout = "{tmp_path / "store"}"\n' + text if not text.startswith("[sweep]") else text)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "store")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert err.startswith(f"mindgap: error: {spec}: ")
    if key is not None:
        assert f": {key}: " in err
    assert problem in err
    assert not (tmp_path / "store").exists()


def test_a_good_sweep_file_lists_its_parts_and_jobs(tmp_path, capsys):
    spec = tmp_path / "good.toml"
    spec.write_text(GOOD.format(out=tmp_path / "store"))
    sweep = sweep_spec.load(spec)
    assert [p.label for p in sweep.parts] == ["table1-fast", "grid"] and sweep.workers == 2
    grid = sweep.parts[1].config
    assert grid.seed_values == (0, 1) and dict(grid.params)["queries"] == (30, 60)
    keys = [j.key for j in sweep_grid.jobs(grid)]
    # per world: the reference, PEBBLE and PrefBias at two budgets × two seeds; sac.lr reaches both learners
    assert len(keys) == 2 * (1 + 2 * 2 * 2) and "nav1/prefbias-queries=60-sac.lr=0.0003-seed=1" in keys
    prefbias = {j.key: j for j in sweep_grid.jobs(grid)}["nav2/prefbias-queries=30-sac.lr=0.0003-seed=1"]
    assert prefbias.cfg.queries == 30 and prefbias.cfg.seed == 1 and prefbias.cfg.sac.lr == 0.0003
    assert main(["sweep", str(spec), "--check"]) == 0
    out = capsys.readouterr().out
    assert "table1-fast" in out and "20 jobs" in out and "18 jobs" in out and "2 parts, 38 jobs" in out
    assert not (tmp_path / "store").exists()
