"""Sweep files (:mod:`mindgap.sweeps.spec`): a bad one is refused before anything runs,
in one line naming the file, the key and the problem; a good one lists its parts and jobs."""

from __future__ import annotations

from pathlib import Path

import pytest

from mindgap.cli import main
from mindgap.experiments import registry
from mindgap.sweeps import grid as sweep_grid
from mindgap.sweeps import spec as sweep_spec

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


@pytest.mark.parametrize(
    "argv,problem",
    [
        (["--backend", "local", "--shard", "0/2"], "does not combine with --shard"),
        (["--backend", "local", "--job", "main/reversed/s0/n300/gerel/tied"], "does not combine with --job"),
        (["--workers", "2"], "--workers goes with --backend local|ray"),
        (["--backend", "local", "--address", "head:6379"], "--address names a Ray cluster"),
        (["--backend", "local", "--seeds", "0"], "seeds must be at least 1"),
    ],
)
def test_reproduce_refuses_backend_flags_that_do_not_fit(tmp_path, capsys, argv, problem):
    out = tmp_path / "run"
    assert main(["reproduce", "table1", "--fast", "--quiet", "--out", str(out), *argv]) == 2
    assert problem in capsys.readouterr().err
    assert not out.exists()


def test_the_example_sweep_file_checks(monkeypatch, capsys):
    monkeypatch.chdir(Path(__file__).resolve().parents[2])  # its user world is named from the repository root
    assert main(["sweep", "examples/sweep.toml", "--check"]) == 0
    out = capsys.readouterr().out
    # per world: the reference, PEBBLE and PrefBias at two budgets and two seeds
    assert "table1-fast" in out and "2 parts, 38 jobs; backend local" in out


@pytest.mark.parametrize("name", [n for n in registry.NAMES if n != "coffee"])
def test_every_named_experiment_gives_the_backends_unique_jobs_after_the_jobs_they_read(name):
    jobs = registry.jobs(name, registry.configure(name, "fast"))
    keys = [k for k, _ in jobs]
    assert keys and len(set(keys)) == len(keys)
    for i, (key, needs) in enumerate(jobs):
        assert all(n in keys[:i] for n in needs), f"{key} reads {needs}, which do not all come before it"
    if name == "eps":
        assert any(needs for _, needs in jobs)  # Policy Shaping reads the policies it shapes
