"""The PrefBias experiments (``mindgap reproduce nav|priors|sampling``): files, values, resume.

Two tiers. The default tests run each experiment's ``--fast`` preset through the CLI with the
learners' ``train`` and the reference job (random policy, planning check) replaced by
stand-ins that return results of the real shape: seconds, no RL program to compile. They
check the run folder, the CSV/JSON/PNG outputs, the metrics computed from the results and
that a rerun computes nothing. The metrics themselves are checked on hand-made inputs. The
``slow`` tests run the real ``--fast`` presets end to end: each compiles PrefBias's feedback
round for every setting it compares, several minutes on a 2-core CPU with a cold compilation
cache, one to a few with a warm one.
"""

import csv
import dataclasses
import json
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap import rng
from mindgap.algorithms import methods, pbrl, prefbias
from mindgap.cli import main
from mindgap.data.segments import Segments
from mindgap.envs.terrain import load_world
from mindgap.experiments import prefbias_common as pc
from mindgap.experiments import world_measures as wm
from mindgap.models.mlp import init_mlp, init_stack
from mindgap.models.prefbias_nets import reward_sizes
from mindgap.planning.terrain_maps import table_noise_map, table_stay_map
from report_check import check_report

FINAL = {"prefbias": -5.0, "pebble": -90.0, "sac": -1.0}
RANDOM = -100.0


def rows(path):
    with path.open() as f:
        return list(csv.DictReader(f))


def _line(a, b, step=0.3):
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
    return a + (b - a) * np.linspace(0, 1, n + 1)[:, None]


def _route(*points):
    return np.concatenate([_line(p, q)[:-1] for p, q in zip(points, points[1:])] + [np.asarray([points[-1]])])


ICE_ROUTE = _route((12.5, 3.5), (12.5, 1.5), (1.5, 1.5), (1.5, 3.5))  # nav1: up, along the icy corridor, down
SAND_ROUTE = _route((12.5, 3.5), (12.5, 4.5), (1.5, 4.5), (1.5, 3.5))
NEAR_ROUTE = _route((9.5, 1.5), (1.5, 1.5))  # nav2: along the pit's edge
FAR_ROUTE = _route((9.5, 1.5), (9.5, 5.5), (1.5, 5.5), (1.5, 1.5))  # round it, well away


def _stack(trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


def _fake_result(world, cfg, seeds, method):
    """What ``train`` returns, of the right shapes, with a final return per method."""
    steps = range(cfg.eval_every, cfg.total_steps + 1, cfg.eval_every)
    curve = [(s, t, FINAL[method] * t / cfg.total_steps + s, cfg.queries) for t in steps for s in range(seeds)]
    keys = jax.random.split(rng.key(1), seeds)
    good, bad = (ICE_ROUTE, SAND_ROUTE) if world.name == "nav1-v1" else (NEAR_ROUTE, FAR_ROUTE)
    path = bad if method == "pebble" else good
    res = {
        "curve": curve,
        "final_returns": np.full((seeds, 20), FINAL[method]) + np.arange(seeds)[:, None],
        "paths": [[path, path[:10]] for _ in range(seeds)],
    }
    if method == "prefbias":
        sizes = reward_sizes(2, 2, cfg.prefbias.reward_hidden)
        res["carry"] = SimpleNamespace(
            model=SimpleNamespace(
                posterior=SimpleNamespace(reward=SimpleNamespace(mean=_stack([init_mlp(k, sizes) for k in keys])))
            )
        )
        if wm.has_map(world):
            wall = np.isnan(np.asarray(table_noise_map(world.params)))
            noise = np.where(wall, np.nan, 0.1 + 0.01 * np.arange(seeds)[:, None, None])
            res["belief_noise"], res["dynamics_noise"] = noise, noise * 0.5
            res["belief_stay"], res["dynamics_stay"] = noise * 3, noise
    else:
        params = _stack([init_stack(k, cfg.reward.members, (4, *cfg.reward.hidden, 1)) for k in keys])
        res["carry"] = SimpleNamespace(model=SimpleNamespace(params=params))
    return res


@pytest.fixture
def stand_ins(monkeypatch):
    """Replace the learners' ``train`` and the reference job; count the calls."""
    calls = []

    def fake_prefbias(world, cfg, seeds=1, teacher="biased", **kw):
        calls.append(("prefbias", world.name, cfg.queries))
        assert teacher == "biased" and kw["out"].parent.name == "train"
        return _fake_result(world, cfg, seeds, "prefbias")

    def fake_pbrl(world, cfg, seeds=1, teacher="true", **kw):
        calls.append((cfg.method, world.name, cfg.queries))
        assert teacher == ("true" if cfg.method == "sac" else "biased")
        return _fake_result(world, cfg, seeds, cfg.method)

    def fake_reference(world, cfg):
        calls.append(("reference", world.name, 0))
        stats = {"goal": 1.0, "pit_mean": 1.0}
        return {
            "random_return": RANDOM,
            "random_return_std": 1.0,
            "plan_return": 0.5,
            "optimal": stats,
            "expected": {**stats, "pit_mean": 1.7},
            "belief": "human",
        }

    def fake_train(method, world, cfg, seeds=1, **kw):  # methods.train, as the experiments call it
        return (fake_prefbias if method == "prefbias" else fake_pbrl)(world, cfg, seeds, **kw)

    monkeypatch.setattr(prefbias, "train", fake_prefbias)
    monkeypatch.setattr(pbrl, "train", fake_pbrl)
    monkeypatch.setattr(methods, "train", fake_train)
    monkeypatch.setattr(pc, "_reference", fake_reference)
    monkeypatch.setattr(pc, "learned_noise", lambda res, world, cfg: (res["belief_noise"], res["dynamics_noise"]))
    monkeypatch.setattr(pc, "learned_stay", lambda res, world: (res["belief_stay"], res["dynamics_stay"]))
    return calls


def _run_twice(name, out, calls, capsys, n_jobs, extra=()):
    """Run the fast preset, then again: the rerun computes nothing and prints the same table."""
    assert main(["reproduce", name, "--fast", "--quiet", *extra, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert len(calls) == n_jobs and len(list((out / "jobs").glob("*.json"))) == n_jobs
    stamps = {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")}
    assert main(["reproduce", name, "--fast", "--quiet", *extra, "--out", str(out)]) == 0
    assert len(calls) == n_jobs  # nothing recomputed
    assert {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")} == stamps
    assert capsys.readouterr().out == printed
    check_report(out, out.parent / f"{name}-report", name)
    return printed


V1 = ("--worlds", "nav1-v1,nav2-v1")  # the stand-in routes are drawn on the dissertation's maps


def test_nav_fast_writes_curves_results_figures_and_resumes(stand_ins, tmp_path, capsys):
    out = tmp_path / "nav"
    # 2 worlds × reference, SAC, PEBBLE, PrefBias
    printed = _run_twice("nav", out, stand_ins, capsys, n_jobs=8, extra=V1)
    assert "| nav1-v1 | PrefBias (30 queries) |" in printed and "| nav2-v1 | PEBBLE (30 queries) |" in printed
    results = rows(out / "results.csv")
    assert list(results[0])[:6] == ["method", "world", "queries", "seeds", "return_mean", "return_std"]
    assert sorted((r["world"], r["method"]) for r in results) == [
        (w, m) for w in ("nav1-v1", "nav2-v1") for m in ("pebble", "prefbias", "sac")
    ]
    for r in results:
        assert float(r["return_mean"]) == FINAL[r["method"]]
        norm = (FINAL[r["method"]] - RANDOM) / (FINAL["sac"] - RANDOM)
        assert float(r["normalised_mean"]) == pytest.approx(norm, abs=1e-4)
        if r["method"] != "sac":
            assert 0 <= float(r["reward_error_mean"]) <= 2
    by = {(r["world"], r["method"]): r for r in results}
    assert float(by["nav1-v1", "prefbias"]["better_route"]) == 1.0  # the icy corridor
    assert float(by["nav1-v1", "pebble"]["better_route"]) == 0.0  # the sandy one
    curves = rows(out / "curves.csv")
    assert list(curves[0])[:6] == ["method", "world", "queries", "seed", "step", "return"]
    assert len(curves) == 2 * 3 * 3  # worlds × learners × evaluations (1 seed)
    assert all(np.isfinite(float(c["return"])) for c in curves)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["experiment"] == "nav" and summary["config"]["seeds"] == 1
    claims = {(c["text"].split(":")[0], c["id"]): c for c in summary["claims"]}
    for cid in ("nav/prefbias-route", "nav/pebble-below-sac", "nav/pebble-route"):
        assert claims["nav1-v1", cid]["held"], cid
    assert "the ice corridor" in claims["nav1-v1", "nav/prefbias-route"]["text"]
    for name in (
        "curves_nav1-v1.png",
        "curves_nav2-v1.png",
        "trajectories_nav1-v1.png",
        "trajectories_nav2-v1.png",
        "table.md",
    ):
        assert (out / name).stat().st_size > 0, name
    # a run in slices: the outputs of a folder where one world has no finished job yet but its reference
    for p in (out / "jobs").glob("nav2-v1__*.json"):
        if "reference" not in p.name:
            p.unlink()
    assert main(["reproduce", "nav", "--fast", "--quiet", *V1, "--out", str(out), "--assemble"]) == 0
    assert {r["world"] for r in rows(out / "results.csv")} == {"nav1-v1"}
    # another configuration in the same folder is refused; --fresh recomputes everything
    assert main(["reproduce", "nav", "--fast", "--quiet", *V1, "--seeds", "2", "--out", str(out)]) == 2
    assert "another configuration" in capsys.readouterr().err
    assert main(["reproduce", "nav", "--fast", "--quiet", *V1, "--seeds", "2", "--fresh", "--out", str(out)]) == 0
    assert len(stand_ins) == 16
    assert len(rows(out / "curves.csv")) == 2 * 3 * 3 * 2
    assert main(["reproduce", "nav", "--fast", "--shard", "0/2", "--out", str(out)]) == 2
    assert "--shard is not supported" in capsys.readouterr().err


REAL_REFERENCE = pc._reference
POINT_MASS = "examples/point_mass.py:make_world"


def test_nav_fast_on_a_users_world(stand_ins, tmp_path, capsys, monkeypatch):
    """``--env`` with a user's factory: the learners' jobs, a real random reference, no routes."""
    monkeypatch.setattr(pc, "_reference", REAL_REFERENCE)
    out = tmp_path / "nav"
    argv = ["reproduce", "nav", "--fast", "--quiet", "--env", POINT_MASS, "--env", POINT_MASS + ",drift=0.1"]
    assert main([*argv, "--out", str(out)]) == 0
    assert sorted({w for _, w, _ in stand_ins}) == ["point-mass", "point-mass(drift=0.1)"]
    results = rows(out / "results.csv")
    assert sorted(r["world"] for r in results) == sorted([POINT_MASS] * 3 + [POINT_MASS + ",drift=0.1"] * 3)
    reference = json.loads(next((out / "jobs").glob("*make_world__reference.json")).read_text())
    assert reference["plan_return"] is None and reference["random_return"] < 0
    for r in results:
        norm = (FINAL[r["method"]] - reference["random_return"]) / (FINAL["sac"] - reference["random_return"])
        if r["world"] == POINT_MASS:
            assert float(r["normalised_mean"]) == pytest.approx(norm, abs=1e-4)
        assert r["better_route"] == "nan" and r["goal_rate"] == "nan"
        if r["method"] != "sac":
            assert 0 <= float(r["reward_error_mean"]) <= 2
    claims = [c["id"] for c in json.loads((out / "summary.json").read_text())["claims"]]
    assert claims and not {"nav/prefbias-route", "nav/pebble-route"} & set(claims)  # no route to judge
    for name in ("curves_point-mass.png", "trajectories_point-mass(drift=0.1).png"):
        assert (out / name).stat().st_size > 0, name


def test_an_experiment_refuses_a_world_it_cannot_use_and_writes_nothing(tmp_path, capsys):
    for spec, says in (
        ("gym:Pendulum-v1", "nav needs a pure-JAX world with a belief and an exact density"),
        ("no/such/file.py:make", "no such file: no/such/file.py"),
        (POINT_MASS + ",drift", "expected key=value, got 'drift'"),
    ):
        out = tmp_path / "nav"
        assert main(["reproduce", "nav", "--fast", "--env", spec, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert says in err and err.count("\n") == 1 and "Traceback" not in err
        assert not out.exists()
    assert main(["reproduce", "table1", "--fast", "--env", "nav1"]) == 2
    assert "--env belongs to the terrain experiments" in capsys.readouterr().err


def test_priors_fast_reports_belief_and_reward_errors(stand_ins, tmp_path, capsys):
    out = tmp_path / "priors"
    printed = _run_twice("priors", out, stand_ins, capsys, n_jobs=4)  # reference, SAC, two priors
    assert "| nav1 | dynamics |" in printed and "| nav1 | random |" in printed
    results = {r["prior"]: r for r in rows(out / "results.csv")}
    assert set(results) == {"dynamics", "random", ""}  # "" is the SAC oracle
    for prior in ("dynamics", "random"):
        r = results[prior]
        assert float(r["belief_error_mean"]) >= 0 and float(r["dynamics_error_mean"]) >= 0
        assert 0 <= float(r["reward_error_mean"]) <= 2 and np.isfinite(float(r["return_mean"]))
    # the stand-in's belief noise is 0.1 everywhere: its error is the RMS of (0.1 − the person's table)
    person = np.asarray(table_noise_map(load_world("nav1").belief()))
    expect = np.sqrt(np.nanmean((0.1 - person) ** 2))
    assert float(results["dynamics"]["belief_error_mean"]) == pytest.approx(expect, rel=1e-4)
    assert {c["prior"] for c in rows(out / "curves.csv")} == {"dynamics", "random", ""}
    # nav1's person misjudges the probability of not moving (the ice holds the robot), not the noise
    assert pc.biased_parts(load_world("nav1")) == ["stay"] and pc.biased_parts(load_world("nav1-v1")) == [
        "noise",
        "stay",
    ]
    person_stay = np.asarray(table_stay_map(load_world("nav1").belief()))
    expect = np.sqrt(np.nanmean((0.3 - person_stay) ** 2))
    assert float(results["dynamics"]["belief_stay_error_mean"]) == pytest.approx(expect, rel=1e-4)
    summary = json.loads((out / "summary.json").read_text())
    assert [c["id"] for c in summary["claims"]] == ["priors/belief-error", "priors/reward-error", "priors/return"]
    assert "the lower belief error (stay)" in summary["claims"][0]["text"]  # what nav1's person gets wrong
    for name in ("errors_nav1.png", "curves_nav1.png", "beliefs_nav1.png", "stays_nav1.png"):
        assert (out / name).stat().st_size > 0, name


def test_sampling_fast_compares_the_four_samplers(stand_ins, tmp_path, capsys):
    out = tmp_path / "sampling"
    printed = _run_twice("sampling", out, stand_ins, capsys, n_jobs=6)  # reference, SAC, four samplers
    results = rows(out / "results.csv")
    samplers = [r["sampler"] for r in results if r["method"] == "prefbias"]
    assert samplers == ["uniform", "disagreement", "entropy", "preference_disagreement"]
    assert all(f"| nav1 | {s} |" in printed for s in samplers)
    assert all(float(r["belief_error_mean"]) >= 0 for r in results if r["method"] == "prefbias")
    assert len(rows(out / "curves.csv")) == 5 * 3
    for name in ("curves_nav1.png", "final_nav1.png", "summary.json"):
        assert (out / name).stat().st_size > 0, name


def test_metrics_on_hand_made_inputs():
    nav1, nav2 = load_world("nav1-v1"), load_world("nav2-v1")
    # routes: the icy corridor is nav1's better route, the sandy one is not; half-way is not arriving
    assert wm.route_of(nav1, [ICE_ROUTE] * 3)["better"] is True
    sand = wm.route_of(nav1, [SAND_ROUTE] * 3)
    assert sand["better"] is False and sand["goal"] == 1.0 and sand["sand"] > 0.5
    assert wm.route_of(nav1, [ICE_ROUTE[:20]] * 3)["better"] is False
    # nav2 is judged by the distance to the pit against the two planned routes
    ref = {"optimal": {"pit_mean": 1.0}, "expected": {"pit_mean": 1.8}}
    assert wm.better_route(wm.route_of(nav2, [NEAR_ROUTE]), ref) is True
    assert wm.better_route(wm.route_of(nav2, [FAR_ROUTE]), ref) is False
    # the normalised score
    np.testing.assert_allclose(pc.normalised([-100.0, -50.0, 0.0], -100.0, 0.0), [0.0, 0.5, 1.0])
    assert np.isnan(pc.normalised([1.0], 0.0, -1.0)).all()
    # the reward error is 0 for the truth up to offset and scale, 2 for its reverse, ~1.41 for noise
    *_, truth = wm.reward_grid(nav1)
    noise = np.random.default_rng(0).standard_normal(truth.shape)

    def scaled(p, obs, act, next_obs):
        return p[0] * jnp.asarray(truth) + p[1] + p[2] * jnp.asarray(noise)

    err = wm.reward_error(nav1, scaled, jnp.array([[3.0, 5.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(err[:2], [0.0, 2.0], atol=1e-5)
    assert abs(err[2] - np.sqrt(2)) < 0.1


def test_nav_asks_an_unbiased_person_too_and_states_its_claims():
    from mindgap.experiments import prefbias_nav

    cfg = prefbias_nav.preset("full")
    jobs = {j.key: j for j in prefbias_nav.jobs(cfg)}
    # the unbiased person scores by r_H + log T (the engine's "unbiased" teacher), not by r_H alone
    assert {pc.teacher_of(jobs[k]) for k in ("nav1/prefbias-q800-unbiased", "nav1/pebble-q800-unbiased")} == {
        "unbiased"
    }
    assert pc.teacher_of(jobs["nav1/pebble-q800"]._replace(tags={"person": "reward-only"})) == "true"
    assert {pc.teacher_of(jobs[k]) for k in ("nav1/prefbias-q800", "nav1/pebble-q800")} == {"biased"}
    assert pc.teacher_of(jobs["nav1/sac"]) == "true"
    assert not any("unbiased" in j.key for j in prefbias_nav.jobs(prefbias_nav.preset("fast")))
    # the coin-flip control: PrefBias-800 with the same schedule, its person answering at β = 0
    coin, twin = jobs["nav1/prefbias-q800-coin"].cfg, jobs["nav1/prefbias-q800"].cfg
    assert coin.teacher.beta == 0.0 and dataclasses.replace(coin, teacher=twin.teacher) == twin

    def row(method, norm, better, err, person="biased", std=0.05):
        return dict(
            method=method,
            queries=800,
            person=person,
            label=f"{method} {person}",
            seeds=5,
            normalised_mean=norm,
            normalised_std=std,
            better_route=better,
            reward_error_mean=err,
        )

    world = load_world("nav1")
    held = {
        c["id"]: c["held"]
        for c in prefbias_nav._claims(
            world,
            [
                row("prefbias", 0.95, 0.8, 0.3),
                row("pebble", 0.6, 0.2, 0.7),
                row("prefbias", 0.97, 1.0, 0.2, "unbiased"),
                row("pebble", 0.99, 1.0, 0.2, "unbiased"),
                row("prefbias", 0.3, 0.2, 1.2, "coin"),
            ],
        )
    }
    assert len(held) == 7 and all(held.values()), held
    held = {
        c["id"]: c["held"]
        for c in prefbias_nav._claims(
            world,
            [
                row("prefbias", 0.85, 0.4, 0.8),
                row("pebble", 0.85, 0.6, 0.7),
                row("prefbias", 0.80, 1.0, 0.2, "unbiased"),
                row("pebble", 0.99, 1.0, 0.2, "unbiased"),
                row("prefbias", 0.83, 0.4, 0.9, "coin"),  # within 2 standard errors of the person's answers
            ],
        )
    }
    assert len(held) == 7 and not any(held.values()), held


def test_measures_on_a_world_without_a_map():
    """A user's world: random return and reward error from the interface, no routes."""
    world = wm.experiment_world("examples/point_mass.py:make_world,drift=0.1", "nav")
    assert world.name == "point-mass(drift=0.1)" and not wm.has_map(world)
    assert wm.route_of(world, [np.zeros((3, 2))]) == wm.NO_ROUTE
    ref = wm.reference_record(world, episodes=20, seed=0, plan_resolution=2, plan_rollouts=10)
    assert ref["plan_return"] is None and ref["optimal"] is None
    assert -2.0 * world.horizon < ref["random_return"] < 0  # minus a distance of at most ~2 a step
    obs, act, nxt, truth = wm.reward_grid(world)
    assert obs.shape == nxt.shape and obs.shape[1] == 2 and act.shape == obs.shape and truth.shape == (len(obs),)
    assert 20 <= len(obs) <= 50 * world.horizon

    def env_reward(sign, obs, act, next_obs):
        return sign * jax.vmap(lambda o, a, n: world.env.reward(o, a, n, world.params))(obs, act, next_obs)

    err = wm.reward_error(world, env_reward, jnp.array([1.0, -1.0]))
    assert err[0] < 0.2 and err[1] > 1.8  # the realised reward against its mean over 32 draws


def _real(name, tmp_path, capsys):
    out = tmp_path / name
    assert main(["reproduce", name, "--fast", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    stamps = {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")}
    assert main(["reproduce", name, "--fast", "--quiet", "--out", str(out)]) == 0
    assert capsys.readouterr().out == printed
    assert {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")} == stamps
    results = rows(out / "results.csv")
    for r in results:
        assert -250 < float(r["return_mean"]) < 50
        for col in ("reward_error_mean", "belief_error_mean"):
            if r.get(col):
                assert float(r[col]) >= 0
    assert all(np.isfinite(float(c["return"])) for c in rows(out / "curves.csv"))
    return results


@pytest.mark.slow
def test_nav_fast_for_real(tmp_path, capsys):
    results = _real("nav", tmp_path, capsys)
    assert sorted((r["world"], r["method"]) for r in results) == [
        (w, m) for w in ("nav1", "nav2") for m in ("pebble", "prefbias", "sac")
    ]


@pytest.mark.slow
def test_priors_fast_for_real(tmp_path, capsys):
    results = _real("priors", tmp_path, capsys)
    assert {r["prior"] for r in results} == {"dynamics", "random", ""}


@pytest.mark.slow
def test_sampling_fast_for_real(tmp_path, capsys):
    results = _real("sampling", tmp_path, capsys)
    assert len([r for r in results if r["method"] == "prefbias"]) == 4


def test_one_job_runs_again_from_the_command_its_record_keeps(stand_ins, tmp_path, capsys):
    out = tmp_path / "nav"
    _run_twice("nav", out, stand_ins, capsys, n_jobs=8, extra=V1)
    key = "nav1-v1/prefbias-q30"
    record = json.loads((out / "jobs" / key.replace("/", "__")).with_suffix(".json").read_text())
    assert record["command"] == f"mindgap reproduce nav --fast --worlds nav1-v1,nav2-v1 --out {out} --job {key}"
    stand_ins.clear()
    again = tmp_path / "again"
    assert main(["reproduce", "nav", "--fast", "--quiet", *V1, "--job", key, "--out", str(again)]) == 0
    assert stand_ins == [("prefbias", "nav1-v1", 30)]  # that job only
    assert f"record in {again}/jobs/nav1-v1__prefbias-q30.json" in capsys.readouterr().out
    rerun = json.loads((again / "jobs" / "nav1-v1__prefbias-q30.json").read_text())
    same = ("final", "curve", "routes", "belief_stay", "reward_error")
    assert {k: rerun.get(k) for k in same} == {k: record.get(k) for k in same}
    assert not (again / "summary.json").exists()  # one job writes no tables
    assert main(["reproduce", "nav", "--fast", *V1, "--job", "nav1-v1/nope", "--out", str(again)]) == 2
    assert "has no job 'nav1-v1/nope'" in capsys.readouterr().err
    assert main(["reproduce", "nav", "--fast", *V1, "--job", key, "--assemble", "--out", str(again)]) == 2


def test_the_oracle_is_its_median_seed_and_goal_reaching_is_counted_apart():
    oracle = {"final": [-40.0, -38.0, -209.0]}  # each seed's mean greedy return; one seed failed
    assert pc.oracle_return(oracle) == -40.0
    rec = {"method": "prefbias", "world": "nav2", "tags": {"queries": 800}, "label": "x",
           "final": [-40.0, -100.0], "routes": [{"goal": 1.0, "better": True}, {"goal": 0.2, "better": False}]}  # fmt: skip
    ref = {"random_return": -140.0}
    row = pc.result_row(rec, ref, oracle)
    np.testing.assert_allclose([row["normalised_mean"]], [np.mean([1.0, 0.4])])
    assert row["goal_seeds"] == 0.5 and row["oracle_seeds_above_random"] == 2


def test_the_engine_s_unbiased_person_believes_the_truth():
    from mindgap.algorithms.engine import preference_teacher
    from mindgap.algorithms.prefbias import prefbias_config
    from mindgap.envs.terrain import load_world

    nav1, cfg = load_world("nav1"), prefbias_config("fast")
    unbiased, meta = preference_teacher(nav1, cfg, 1, "unbiased", None, who="test")
    assert unbiased.belief is nav1.params and unbiased.cfg.use_belief and meta["teacher"] == "unbiased"
    reward_only, _ = preference_teacher(nav1, cfg, 1, "true", None, who="test")
    assert reward_only.belief is None and not reward_only.cfg.use_belief
    biased, _ = preference_teacher(nav1, cfg, 1, "biased", None, who="test")
    np.testing.assert_array_equal(biased.belief.dynamics.stuck, nav1.belief().dynamics.stuck)
    with pytest.raises(ValueError, match="biased, unbiased, true"):
        preference_teacher(nav1, cfg, 1, "sceptical", None, who="test")
    # the coin: the biased person at β = 0, whose answers are fair coins whatever the segments
    coin, _ = preference_teacher(nav1, pc.coin_flips(cfg), 1, "biased", None, who="test")

    def still(x, y):  # 4000 segments of three steps held still at one point (obs units)
        at = jnp.broadcast_to(jnp.array([x, y]), (4000, 3, 2))
        return Segments(at, jnp.zeros_like(at), at, jnp.ones((4000, 3), bool))

    better, seg = still(-0.786, -0.5), still(0.643, 0.5)  # in the goal; on the sand, far from it
    labels, _ = coin.answer(jax.random.key(0), better, seg)
    assert abs(float(labels.mean()) - 0.5) < 0.03  # 4000 fair coins: 4 standard deviations
    labels, _ = biased.answer(jax.random.key(0), better, seg)
    assert float(labels.mean()) > 0.9
