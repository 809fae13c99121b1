"""The EPS experiments (``mindgap reproduce eps|lambda``): files, values, resume.

As for the PrefBias experiments, the default tests run the ``--fast`` presets through the CLI
with the learners' training and the person's π_H replaced by stand-ins of the real shape
(random SAC actors, routes drawn by hand); everything after training runs for real: the
explicability scores and returns of the stored policies, Policy Shaping's product of the
SAC and DRLHP policies read back from the run folder, route judging, tables and figures.
The ``slow`` tests run the real fast presets end to end.
"""

import csv
import dataclasses
import json

import jax
import numpy as np
import pytest

from mindgap import rng
from mindgap.algorithms.expected_policy import ExpectedPolicyConfig
from mindgap.algorithms.explicability import explicability_scores
from mindgap.algorithms.policy_shaping import ShapedPolicy, shaped_dist
from mindgap.algorithms.sac import SACConfig, sac_init
from mindgap.cli import main
from mindgap.envs.terrain import load_world
from mindgap.experiments import eps_common as ec
from mindgap.experiments import world_measures
from mindgap.teachers.expectation import ExpectationTeacher
from report_check import check_report

GREEDY = {"eps": 90.0, "sac": 100.0, "drlhp": -100.0}


def rows(path):
    with path.open() as f:
        return list(csv.DictReader(f))


def _route(*points, step=0.3):
    out = []
    for a, b in zip(points, points[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * np.linspace(0, 1, n + 1)[:-1, None])
    return np.concatenate(out + [np.asarray([points[-1]], float)])


ROUTES = {  # (x, y) in cells; the start is cell (1, 1)
    "d1": {
        "hug": _route((1.5, 1.5), (1.5, 2.5), (5.5, 2.5), (5.5, 1.5)),
        "detour": _route((1.5, 1.5), (1.5, 4.5), (5.5, 4.5), (5.5, 1.5)),
    },
    "d3": {
        "ice": _route((1.5, 1.5), (4.5, 1.5), (4.5, 5.5), (5.5, 5.5)),
        "sand": _route((1.5, 1.5), (1.5, 5.5), (5.5, 5.5)),
    },
}
ROUTES["d4"] = ROUTES["d3"]
TAKES = {  # the route each stand-in learner takes
    "d1": {"eps": "detour", "sac": "hug", "drlhp": "detour"},
    "d3": {"eps": "ice", "sac": "ice", "drlhp": "sand"},
    "d4": {"eps": "sand", "sac": "ice", "drlhp": "sand"},
}


def _actors(name: str, seeds: int, hidden):
    """Random SAC actors, a different set per name (deterministic)."""
    base = jax.random.fold_in(rng.key(7), sum(map(ord, name)))
    cfg = SACConfig(hidden=hidden)
    return jax.vmap(lambda k: sac_init(k, 2, 2, cfg).params.actor)(jax.random.split(base, seeds))


@pytest.fixture
def stand_ins(monkeypatch):
    """Replace training and π_H; record the calls and the actors each job was given."""
    calls, actors = [], {}

    def fake_train(world, job, seeds, out, person, *, fresh, progress):
        assert out.parent.name == "train"
        calls.append(job.key)
        method = job.method
        cfg = job.cfg
        lam = job.tags.get("lam", 0.0)
        steps = range(cfg.eval_every, cfg.total_steps + 1, cfg.eval_every)
        greedy = GREEDY[method] - 10 * lam
        curve = [(s, t, greedy * t / cfg.total_steps, 0) for t in steps for s in range(seeds)]
        mapped = world_measures.has_map(world)
        path = ROUTES[world.name][TAKES[world.name][method]] if mapped else np.linspace([-0.7, 0.0], [0.6, 0.0], 9)
        actors[job.key] = _actors(job.key, seeds, cfg.sac.hidden)
        h, w = np.asarray(world.params.grid).shape if mapped else (1, 1)
        return {
            "curve": curve,
            "final_returns": np.full((seeds, 4), greedy),
            "paths": [[path, path] for _ in range(seeds)],
            "actor": actors[job.key],
            "u_map": None if method == "sac" or not mapped else np.linspace(-1, 1, h * w * 16).reshape(h * 4, w * 4),
        }

    def fake_person(world, belief=None, *, unbiased=False, policy_cfg=None, cache_dir=None):
        params = world.params if unbiased else world.belief(belief)
        actor = jax.tree.map(lambda a: a[0], _actors(f"person-{unbiased}", 1, policy_cfg.sac.hidden))
        return ExpectationTeacher(params, actor, world.env)

    monkeypatch.setattr(ec, "train", fake_train)
    monkeypatch.setattr(ec, "expectation_teacher", fake_person)
    return calls, actors


def test_eps_fast_tables_figures_shaping_and_resume(stand_ins, tmp_path, capsys):
    calls, actors = stand_ins
    out = tmp_path / "eps"
    argv = ["reproduce", "eps", "--fast", "--quiet", "--worlds", "d1,d3", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    learners = ("sac", "drlhp", "eps-lam2", "eps-lam2-unbiased")
    assert sorted(calls) == sorted(f"{w}/{m}" for w in ("d1", "d3") for m in learners)
    assert len(list((out / "jobs").glob("*.json"))) == 2 * 7  # + 2 persons and Policy Shaping per world
    assert "| world | EPS | SAC | DRLHP | Policy Shaping |" in printed
    check_report(out, tmp_path / "report", "eps")

    results = rows(out / "results.csv")
    by = {(r["world"], r["method"], r["person"]): r for r in results}
    assert len(by) == len(results) == 2 * 5
    for (_, m, _), r in by.items():
        if m != "shaping":
            assert float(r["greedy_return_mean"]) == pytest.approx(GREEDY[m] - (20 if m == "eps" else 0))
        assert np.isfinite(float(r["return_mean"])) and float(r["explicability_mean"]) <= 0.5
    # the required routes: d1 a detour (EPS's and DRLHP's, not SAC's hug), d3 the ice (EPS, SAC)
    assert [float(by["d1", m, "biased"]["required_route"]) for m in ("eps", "sac", "drlhp")] == [1.0, 0.0, 1.0]
    assert [float(by["d3", m, "biased"]["required_route"]) for m in ("eps", "sac", "drlhp")] == [1.0, 1.0, 0.0]

    # the explicability scores are those of the policies the learners returned (and, for
    # Policy Shaping, of the product of the SAC and DRLHP policies read back from disk)
    world = load_world("d3")
    person = ec.expectation_teacher(world, policy_cfg=ExpectedPolicyConfig.fast())
    rec = json.loads((out / "jobs" / "d3__eps-lam2.json").read_text())
    want = explicability_scores(rng.key(20_000), world, person, actors["d3/eps-lam2"], 10)
    assert rec["explicability"] == pytest.approx([s["score"] for s in want], rel=1e-5)
    ones = np.ones(1, np.float32)
    shaped = ShapedPolicy(actors["d3/sac"], actors["d3/drlhp"], ones, ones)
    want = explicability_scores(rng.key(20_000), world, person, shaped, 10, agent_dist=shaped_dist)
    rec = json.loads((out / "jobs" / "d3__shaping.json").read_text())
    assert rec["explicability"] == pytest.approx([s["score"] for s in want], rel=1e-5)
    assert rec["return"] == pytest.approx([s["stochastic_return"] for s in want], rel=1e-5)

    summary = json.loads((out / "summary.json").read_text())
    claims = {(c["text"].split(":")[0], c["id"]): c for c in summary["claims"]}
    assert claims["d1", "eps/route"]["held"] and "(detour)" in claims["d1", "eps/route"]["text"]
    assert ("d3", "eps/shaping-d3") in claims and ("d1", "eps/shaping-d3") not in claims  # d3's ice only
    assert claims["d1", "eps/unbiased-near-sac"]["text"].endswith("(within 5% of SAC's return)")
    assert [p["world"] for p in summary["person"]] == ["d1", "d3"]
    for name in ("trajectories.png", "unbiased.png", "surrogate_d1.png", "curves_d3.png", "table.md", "person.csv"):
        assert (out / name).stat().st_size > 0, name

    # a rerun reads everything back
    stamps = {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")}
    assert main(argv) == 0
    assert len(calls) == 8 and capsys.readouterr().out == printed
    assert {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")} == stamps


def test_eps_fast_on_a_users_world(stand_ins, tmp_path, capsys):
    """``--env`` with a user's factory: π_H's record, Policy Shaping and the scores through the interface."""
    calls, actors = stand_ins
    spec = "examples/point_mass.py:make_world"
    out = tmp_path / "eps"
    assert main(["reproduce", "eps", "--fast", "--quiet", "--env", spec, "--out", str(out)]) == 0
    assert sorted(calls) == sorted(f"{spec}/{m}" for m in ("sac", "drlhp", "eps-lam2", "eps-lam2-unbiased"))
    results = rows(out / "results.csv")
    assert {r["method"] for r in results} == {"eps", "sac", "drlhp", "shaping"}
    for r in results:
        assert np.isfinite(float(r["return_mean"])) and np.isfinite(float(r["explicability_mean"]))
        assert r["required_route"] == "nan" and r["goal_rate"] == "nan"  # no map, no route to judge
    world = world_measures.experiment_world(spec, "eps")
    person = ec.expectation_teacher(world, policy_cfg=ExpectedPolicyConfig.fast())
    ones = np.ones(1, np.float32)
    shaped = ShapedPolicy(actors[f"{spec}/sac"], actors[f"{spec}/drlhp"], ones, ones)
    want = explicability_scores(rng.key(20_000), world, person, shaped, 10, agent_dist=shaped_dist)
    rec = json.loads(next((out / "jobs").glob("*__shaping.json")).read_text())
    assert rec["explicability"] == pytest.approx([s["score"] for s in want], rel=1e-5)
    assert len(rec["paths"][0]) == 3 and np.asarray(rec["paths"][0][0]).shape[1] == 2  # greedy rollouts, traced
    person_rec = json.loads(next((out / "jobs").glob("*__person-biased.json")).read_text())
    assert person_rec["plan_return"] is None and np.isfinite(person_rec["obey_return"])
    assert [p["world"] for p in rows(out / "person.csv")] == [spec]
    assert "| point-mass |" in capsys.readouterr().out
    assert not any(c["id"] == "eps/route" for c in json.loads((out / "summary.json").read_text())["claims"])
    for name in ("trajectories.png", "unbiased.png", "curves_point-mass.png", "table.md"):
        assert (out / name).stat().st_size > 0, name


def test_lambda_fast_routes_and_trend(stand_ins, tmp_path, capsys):
    calls, _ = stand_ins
    out = tmp_path / "lambda"
    assert main(["reproduce", "lambda", "--fast", "--quiet", "--worlds", "d4", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert calls == ["d4/eps-lam0", "d4/eps-lam1.5", "d4/eps-lam3"]
    results = rows(out / "results.csv")
    assert [float(r["lam"]) for r in results] == [0.0, 1.5, 3.0]
    check_report(out, tmp_path / "report", "lambda")
    assert [float(r["greedy_return_mean"]) for r in results] == pytest.approx([90.0, 75.0, 60.0])
    assert all(float(r["required_route"]) == 1.0 for r in results)  # the sandy road
    claims = json.loads((out / "summary.json").read_text())["claims"]
    assert [c["id"] for c in claims] == ["lambda/explicability-rises", "lambda/return-falls"]
    assert all(c["text"].startswith("d4: ") for c in claims)
    assert "| d4 | 1.5 |" in printed and "held still" in printed
    for name in ("routes.png", "lambda.png", "table.md", "curves.csv"):
        assert (out / name).stat().st_size > 0, name


def test_worlds_flag_is_checked(capsys):
    assert main(["reproduce", "table1", "--fast", "--worlds", "d1"]) == 2
    assert "--worlds belongs to the terrain experiments" in capsys.readouterr().err
    assert main(["reproduce", "eps", "--fast", "--worlds", " , "]) == 2
    assert "at least one world" in capsys.readouterr().err


def test_required_route_on_hand_made_routes():
    person = {"optimal": {"pit_mean": 1.0}, "expected": {"pit_mean": 2.4}}  # halfway: 1.7
    d1, d3, d4 = (load_world(w) for w in ("d1", "d3", "d4"))

    def judge(world, path, goal=1.0):
        route = world_measures.route_of(world, [path])
        route["goal"] = goal if goal != 1.0 else route["goal"]
        return ec.required_route(world, route, person)

    assert judge(d3, ROUTES["d3"]["ice"]) and not judge(d3, ROUTES["d3"]["sand"])
    assert judge(d4, ROUTES["d4"]["sand"]) and not judge(d4, ROUTES["d4"]["ice"])
    assert not judge(d3, ROUTES["d3"]["ice"], goal=0.0)  # a route that never arrives is no route
    assert judge(d1, ROUTES["d1"]["detour"]) and not judge(d1, ROUTES["d1"]["hug"])
    route = world_measures.route_of(d1, [ROUTES["d1"]["detour"]])
    near = {"optimal": {"pit_mean": route["pit_mean"] - 0.2}, "expected": {"pit_mean": route["pit_mean"] + 0.4}}
    assert not ec.required_route(d1, route, near)  # nearer the optimal berth than the person's
    assert ec.required_route(d1, route, {**near, "expected": None}) is None
    assert ec.required_route(load_world("nav1"), route, person) is None  # no eps_route there


def test_eps_runs_a_coin_flip_control_and_states_its_claim():
    from mindgap.experiments import eps_table

    jobs = {j.key: j for j in eps_table.jobs(eps_table.preset("full"))}
    coin, eps = jobs["d3/eps-lam2-coin"], jobs["d3/eps-lam2"]
    assert coin.cfg.teacher.beta == 0.0 and dataclasses.replace(coin.cfg, teacher=eps.cfg.teacher) == eps.cfg
    assert coin.tags["person"] == "coin" and not any(
        "coin" in k for k in map(str, eps_table.jobs(eps_table.preset("fast")))
    )

    def row(expl, std=2.0):
        return {"explicability_mean": expl, "explicability_std": std, "seeds": 5, "label": "x", "required_route": 1.0}

    def coin_claims(eps, coin):
        claims = eps_table._claims(load_world("d3"), {"eps": row(eps), "eps-coin": row(coin)})
        return {c["id"]: c["held"] for c in claims if "coin" in c["id"]}

    assert coin_claims(-10.0, -30.0) == {"eps/coin-control": True}
    assert coin_claims(-10.0, -12.0) == {"eps/coin-control": False}  # within two standard errors (2.5)


def test_a_seed_held_still_short_of_the_goal_is_counted():
    d1 = load_world("d1")  # goal: the cell x ∈ [5, 6], y ∈ [1, 2]
    walk = np.stack([np.linspace(1.5, 4.5, 30), np.full(30, 3.5)], -1)  # along row 3
    stopped = np.concatenate([walk, np.repeat(walk[-1:], 20, 0) + 0.01])  # then 20 steps in place
    arrived = np.concatenate([walk, [[5.5, 1.5]] * 20])  # then into the goal and staying there
    assert world_measures.held_still(d1, stopped)
    assert not world_measures.held_still(d1, walk)  # still moving when the horizon came
    assert not world_measures.held_still(d1, arrived)
    seeds = [[stopped, stopped, walk], [arrived, stopped, arrived], [walk]]  # per seed, its rollouts
    assert world_measures.held_still_seeds(d1, seeds) == 1  # most rollouts of seed 0 only


def test_monotone_within_noise():
    held, worst = ec.monotone_within_noise([1.0, 2.0, 3.0], [0.0, 0.0, 0.0], 5, rising=True)
    assert held and worst == 0.0
    # 3 → 2.5 is a reversal of 0.5; the standard errors are 1/√4 = 0.5 each, so 0.5/0.707 ≈ 0.71 of them
    held, worst = ec.monotone_within_noise([1.0, 3.0, 2.5], [1.0, 1.0, 1.0], 4, rising=True)
    assert held and worst == pytest.approx(0.5 / np.hypot(0.5, 0.5))
    held, worst = ec.monotone_within_noise([1.0, 3.0, 0.0], [0.1, 0.1, 0.1], 4, rising=True)
    assert not held and worst > 2
    assert ec.monotone_within_noise([3.0, 2.0, 1.0], [0.0] * 3, 3, rising=False)[0]


@pytest.mark.slow
def test_eps_and_lambda_fast_for_real(tmp_path, capsys):
    """The real fast presets on one world each (tiny networks; π_H from the fast cache)."""
    assert main(["reproduce", "eps", "--fast", "--quiet", "--worlds", "d3", "--out", str(tmp_path / "e")]) == 0
    results = rows(tmp_path / "e" / "results.csv")
    assert sorted(r["method"] for r in results) == ["drlhp", "eps", "eps", "sac", "shaping"]
    assert all(np.isfinite(float(r["explicability_mean"])) for r in results)
    assert main(["reproduce", "lambda", "--fast", "--quiet", "--worlds", "d1", "--out", str(tmp_path / "l")]) == 0
    assert len(rows(tmp_path / "l" / "results.csv")) == 3
    capsys.readouterr()


def test_policy_shaping_as_one_job_brings_the_jobs_whose_policies_it_shapes():
    from mindgap.experiments import eps_table
    from mindgap.experiments.prefbias_common import select_job

    jobs = eps_table.jobs(eps_table.preset("fast"))
    assert [j.key for j in select_job(jobs, "d3/shaping")] == ["d3/sac", "d3/drlhp", "d3/shaping"]
    assert [j.key for j in select_job(jobs, "d3/sac")] == ["d3/sac"]
    with pytest.raises(ValueError, match="has no job 'd9/sac'"):
        select_job(jobs, "d9/sac")
