"""The control-domain experiment ``mindgap reproduce gym`` (Figs. 18–20).

The default tests run the ``--fast`` preset through the CLI on the lander with the learners'
``train``, the belief fit, the reward error and the rollout animation replaced by stand-ins
(the reference job — random episodes on gymnasium, the identifiability conditions — is
real); they check the run folder, the outputs, the claims' logic on hand-made rows, the
measured conditions and the refusals. The ``slow`` test runs the real ``--fast`` preset on
all three domains (several minutes on a 2-core CPU with a cold compilation cache).
"""

import csv
import json
from dataclasses import replace
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.algorithms import methods, pbrl, prefbias
from mindgap.cli import main
from mindgap.envs.gym_world import gym_world_from_spec
from mindgap.experiments import gym_claims as gc
from mindgap.experiments import gym_measures as gm
from mindgap.experiments import prefbias_common as pc
from mindgap.experiments import prefbias_gym as pg
from mindgap.experiments import registry
from report_check import check_report

FINAL = {"prefbias": -150.0, "pebble": -200.0, "sac": 100.0}
LEVEL = 250.0


def rows(path):
    with path.open() as f:
        return list(csv.DictReader(f))


def _fake_result(cfg, seeds, method, level=False):
    steps = range(cfg.eval_every, cfg.total_steps + 1, cfg.eval_every)
    final = LEVEL if level else FINAL[method]
    curve = [(s, t, final * t / cfg.total_steps + s, cfg.queries) for t in steps for s in range(seeds)]
    path = np.linspace(0, 1, 40)[:, None] * np.ones((1, 8))
    carry = SimpleNamespace(
        loop=SimpleNamespace(sac=SimpleNamespace(params=SimpleNamespace(actor={"w": jnp.zeros((seeds, 3))}))),
        model=SimpleNamespace(
            params="ensemble", posterior=SimpleNamespace(reward=SimpleNamespace(mean="posterior mean"))
        ),
    )
    return {
        "curve": curve,
        "final_returns": np.full((seeds, 5), final) + np.arange(seeds)[:, None],
        "paths": [[path, path[:10], path[:5]] for _ in range(seeds)],
        "carry": carry,
    }


@pytest.fixture
def stand_ins(monkeypatch):
    """Replace training, the belief fit, the reward error and the animation; record the calls."""
    calls = []

    def fake_prefbias(world, cfg, seeds=1, teacher="biased", **kw):
        calls.append(("prefbias", world.name, cfg.queries, tuple(world.beliefs)))
        assert teacher == "biased" and kw["out"].parent.name == "train"
        return _fake_result(cfg, seeds, "prefbias")

    def fake_pbrl(world, cfg, seeds=1, teacher="true", **kw):
        level = "LunarLander-v3" in world.name
        calls.append(("sac-level" if level else cfg.method, world.name, cfg.queries, tuple(world.beliefs)))
        assert teacher == ("true" if cfg.method == "sac" else "biased")
        return _fake_result(cfg, seeds, cfg.method, level)

    def fake_fit(belief_world, cfg, *, true_world=None, **kw):
        calls.append(("fit", belief_world.name, cfg.transitions, (kw.get("cache_dir"),)))
        # the fields of learned_belief.fit_learned_belief's record
        record = dict(
            belief_env=belief_world.name, config={"dynamics": {"hidden": [8, 8]}}, transitions=cfg.transitions
        )
        record.update(held_out_log_lik=1.25, held_out_below_floor=0.0, true_env=true_world.name)
        record.update(true_log_lik=-40.0, true_below_floor=0.125)
        return "the fitted model", record

    def fake_error(world, cfg, fn, params):
        return np.full(1, {"posterior mean": 0.5, "ensemble": 1.2}[params])

    def fake_draw(path, world, actor):
        assert actor["w"].shape == (3,)  # seed 0's actor
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"GIF89a")

    def fake_train(method, world, cfg, seeds=1, **kw):  # methods.train, as the experiments call it
        return (fake_prefbias if method == "prefbias" else fake_pbrl)(world, cfg, seeds, **kw)

    monkeypatch.setattr(prefbias, "train", fake_prefbias)
    monkeypatch.setattr(pbrl, "train", fake_pbrl)
    monkeypatch.setattr(methods, "train", fake_train)
    monkeypatch.setattr(pg, "fit_learned_belief", fake_fit)
    monkeypatch.setattr(pg, "reward_error", fake_error)
    monkeypatch.setattr(pg, "draw_rollout", fake_draw)
    return calls


def test_gym_fast_on_the_lander_writes_curves_results_claims_and_resumes(stand_ins, tmp_path, capsys):
    out = tmp_path / "gym"
    argv = ["reproduce", "gym", "--fast", "--quiet", "--worlds", "lunar", "--levels", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    learners = [c for c in stand_ins if c[0] != "fit"]
    # SAC, PEBBLE, PrefBias (30 queries) on the windy lander, each with the vacuum belief; SAC in the vacuum
    vacuum = "gym:LunarLander-v3,continuous=True,max_episode_steps=200"
    windy = "gym:mindgap/SolarWindLander-v0,max_episode_steps=200"
    assert learners == [
        ("sac", windy, 0, (vacuum,)),
        ("pebble", windy, 30, (vacuum,)),
        ("prefbias", windy, 30, (vacuum,)),
        ("sac-level", vacuum, 0, ()),
    ]
    # every job's person is fitted in (or read from) the run's own folder: one person on any machine
    assert {(c[1], c[3]) for c in stand_ins if c[0] == "fit"} == {(vacuum, (out,))}
    assert len(list((out / "jobs").glob("*.json"))) == 5  # and the reference
    results = {r["method"]: r for r in rows(out / "results.csv")}
    assert set(results) == {"prefbias", "pebble", "sac", "sac-level"}
    reference = json.loads((out / "jobs" / "lunar__reference.json").read_text())
    rand = reference["random_return"]
    assert rand < 0 and 0 < reference["random_length"] <= 200
    for m in ("prefbias", "pebble", "sac"):
        assert float(results[m]["return_mean"]) == FINAL[m]
        norm = (FINAL[m] - rand) / (FINAL["sac"] - rand)
        assert float(results[m]["normalised_mean"]) == pytest.approx(norm, abs=1e-4)
    gifs = {m: results[m]["rollout"] for m in results}
    assert gifs == {
        f"{m}": f"rollouts/lunar__{k}.gif"
        for m, k in (("prefbias", "prefbias-q30"), ("pebble", "pebble-q30"), ("sac", "sac"), ("sac-level", "sac-level"))
    }
    assert (
        float(results["prefbias"]["reward_error_mean"]) == 0.5 and float(results["pebble"]["reward_error_mean"]) == 1.2
    )
    assert float(results["sac-level"]["return_mean"]) == LEVEL and results["sac-level"]["env"] == vacuum
    assert "better_route" not in results["sac"]  # no map, no routes
    assert len(rows(out / "curves.csv")) == 4 * 3  # learners × evaluations (1 seed)
    summary = json.loads((out / "summary.json").read_text())
    claims = {c["id"]: c["held"] for c in summary["claims"]}
    assert claims == {"gym/lunar-below-sac": False, "gym/sac-level": True}  # one seed: no standard error
    level = next(c for c in summary["claims"] if c["id"] == "gym/sac-level")
    assert level["text"] == (
        "lunar: SAC on gym:LunarLander-v3,continuous=True reaches 200 (the 'solved' score of the Gym "
        "documentation (dissertation §3.4.2.2))"
    )
    # the conditions are measured; the lander's reward shapes by the next state and its episodes end early
    conds = summary["conditions"]["lunar"]
    assert [c["met"] for c in conds] == [True, False, False, None, True]
    assert "| lunar | 1 ✓, 2 ✗, 3 ✗, 4 –, 5 ✓ (learned belief; no design check) |" in printed
    assert "no design check" in printed and "| lunar | PrefBias (30 queries) | −150.0 ± 0.0 |" in printed
    # what each finished job cost, from its record, and the total so far
    jobs = {p.stem.replace("__", "/"): json.loads(p.read_text()) for p in (out / "jobs").glob("*.json")}
    assert [c["job"] for c in summary["costs"]] == sorted(jobs)
    assert all(c["seconds"] == pytest.approx(jobs[c["job"]]["seconds"]) for c in summary["costs"])
    assert f"{len(jobs)} jobs finished: " in printed
    # the person's learned belief beside the figure: its held-out fit, and how the true env's steps score under it
    assert (
        f"- lunar: the person's believed dynamics (a Gaussian model fitted to 600 transitions of {vacuum}): "
        "held-out log-likelihood 1.2 a transition (0.0% below the floor on log T_H); on the true env's "
        "transitions -40.0 (12.5% below)"
    ) in printed
    for name in ("curves_lunar.png", "trajectories_lunar.png", "rollouts/lunar__sac.gif", "table.md"):
        assert (out / name).stat().st_size > 0, name
    record = json.loads((out / "jobs" / "lunar__prefbias-q30.json").read_text())
    assert record["belief_model"]["belief_env"] == vacuum and len(record["paths"][0]) == pg.PATH_EPISODES
    assert (
        record["command"]
        == f"mindgap reproduce gym --fast --worlds lunar --levels --out {out} --job lunar/prefbias-q30"
    )
    # a rerun computes nothing and prints the same
    stamps = {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")}
    n = len(stand_ins)
    assert main(argv) == 0
    assert capsys.readouterr().out == printed and len(stand_ins) == n
    assert {p: p.stat().st_mtime_ns for p in (out / "jobs").glob("*.json")} == stamps
    check_report(out, tmp_path / "report", "gym")


def test_the_coin_flip_control_trains_on_fair_coins_and_is_checked_apart(stand_ins, tmp_path, monkeypatch):
    """The full preset's control on the fast schedule: PrefBias on a person at β = 0, its own row and
    curve, the project's check against the biased person's PrefBias, and no part in the figure's claim."""
    cfg = replace(pg.preset("fast"), worlds=("lunar",), coin=True)
    out = tmp_path / "gym"
    seen = []
    train = methods.train

    def watch(method, world, c, seeds=1, **kw):
        seen.append((method, c.queries, getattr(c, "teacher", None) and c.teacher.beta))
        return train(method, world, c, seeds, **kw)

    monkeypatch.setattr(methods, "train", watch)
    pg.run(cfg, out, fresh=False, progress=False, assemble_only=False)
    assert sorted(x for x in seen if x[0] == "prefbias") == [("prefbias", 30, 0.0), ("prefbias", 30, 1.0)]
    results = [r for r in rows(out / "results.csv") if r["method"] == "prefbias"]
    assert [(r["label"], r.get("person", "")) for r in results] == [
        ("PrefBias (30 queries)", ""),
        ("PrefBias (30 queries, coin-flip answers)", "coin"),
    ]
    claims = {c["id"]: c for c in json.loads((out / "summary.json").read_text())["claims"]}
    assert set(claims) == {"gym/lunar-below-sac", "gym/coin-control"}
    assert "PrefBias (30 queries, coin" not in claims["gym/lunar-below-sac"]["measured"]
    assert claims["gym/coin-control"]["held"] is False  # one seed: no standard error
    assert (out / "jobs" / "lunar__prefbias-q30-coin.json").exists()
    assert any(r.get("person") == "coin" for r in rows(out / "curves.csv"))  # its curve beside the learners'


def test_assemble_reads_a_run_whose_other_domains_have_no_job_yet(stand_ins, tmp_path):
    out = tmp_path / "gym"
    base = ["reproduce", "gym", "--fast", "--quiet", "--worlds", "lunar,hopper", "--out", str(out)]
    assert main([*base, "--job", "lunar/sac"]) == 0
    assert main([*base, "--assemble"]) == 0
    assert [(r["world"], r["method"]) for r in rows(out / "results.csv")] == [("lunar", "sac")]
    assert (out / "curves_lunar.png").exists() and not (out / "curves_hopper.png").exists()


def test_the_conditions_are_measured_per_domain():
    """The lander's reward shapes by the next state and its random episodes end early, as the hopper's do;
    the cheetah's and ``hopper-fixed``'s run to the horizon (condition 3 met)."""
    cfg = pg.preset("fast")
    for spec, early in (
        ("gym:mindgap/SolarWindLander-v0,max_episode_steps=200", True),
        ("gym:mindgap/NoisyHalfCheetah-v0,max_episode_steps=50", False),
        (pg._spec(pg.DOMAINS["hopper"].env, 50), True),
        (pg._spec(pg.DOMAINS["hopper-fixed"].env, 50), False),
    ):
        world = gym_world_from_spec(spec)
        rets, lens = gm.random_host(world, 3, 0)
        assert np.all(np.isfinite(rets)) and np.all((1 <= lens) & (lens <= world.horizon))
        ended = float(np.mean(lens < world.horizon))
        assert (ended > 0) == early
        conds = gm.conditions(world, cfg, ended, {"config": {"dynamics": {"hidden": [8, 8]}}})
        assert [c["met"] for c in conds] == [True, False, not early, None, True]
        assert "of random-action transitions" in conds[1]["why"]


def test_each_belief_env_ends_its_episodes_as_its_true_env_does():
    """The person's belief is fitted to random episodes of the belief env: where those ended at a fall and the
    task's did not, the belief never saw a fallen robot and put its moves at the teacher's floor."""
    for name in ("lunar", "hopper", "cheetah", "hopper-fixed"):
        d = pg.DOMAINS[name]
        ended = [
            float(np.mean(gm.random_host(w, 3, 0)[1] < w.horizon))
            for w in (gym_world_from_spec(pg._spec(spec, 200)) for spec in (d.env, d.belief_env))
        ]
        assert (ended[0] > 0) == (ended[1] > 0), (name, ended)


def test_the_reward_error_is_zero_for_the_person_s_reward_and_two_for_its_reverse():
    world = gym_world_from_spec("gym:mindgap/SolarWindLander-v0,max_episode_steps=100")
    cfg = pg.preset("fast")

    def scaled(p, obs, act, nxt):
        import jax

        return p * jax.vmap(lambda o, a, n: world.env.reward(o, a, n, world.params))(obs, act, nxt) + 3.0

    err = gm.reward_error(world, cfg, scaled, jnp.array([2.0, -1.0]))
    np.testing.assert_allclose(err, [0.0, 2.0], atol=1e-4)


def test_bad_input_is_refused_with_one_line(tmp_path, capsys):
    for extra, says in (
        (["--worlds", "mars"], f"gym has no domain 'mars': choose from {', '.join(pg.DOMAINS)}"),
        (["--env", "gym:Pendulum-v1"], "gym has no domain 'gym:Pendulum-v1'"),
        (["--seeds", "0"], "--seeds must be at least 1"),
        (["--participants", "3"], "--participants belongs to the coffee study"),
    ):
        out = tmp_path / "gym"
        assert main(["reproduce", "gym", "--fast", *extra, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert says in err and err.count("\n") == 1 and "Traceback" not in err, err
        assert not out.exists()
    assert main(["reproduce", "nav", "--fast", "--levels", "--out", str(tmp_path / "nav")]) == 2
    assert "--levels adds SAC's level runs to gym" in capsys.readouterr().err and not (tmp_path / "nav").exists()


def test_the_presets_and_the_jobs():
    full = pg.preset("full")
    learners = (
        "reference",
        "sac",
        "pebble-q800",
        "prefbias-q200",
        "prefbias-q400",
        "prefbias-q800",
        "prefbias-q800-coin",
    )
    keys = [j.key for j in pg.jobs(full)]
    for w in ("lunar", "hopper", "cheetah"):
        assert [k for k in keys if k.startswith(w + "/")] == [f"{w}/{n}" for n in learners]  # levels: opt-in
    keys = [j.key for j in pg.jobs(replace(full, levels=True))]
    for w in ("lunar", "hopper", "cheetah"):
        assert [k for k in keys if k.startswith(w + "/")] == [f"{w}/{n}" for n in (*learners, "sac-level")]
    by = {j.key: j for j in pg.jobs(replace(full, levels=True))}
    assert full.seeds == 5 and by["hopper/prefbias-q400"].cfg.total_steps == pg.FULL_STEPS["hopper"]
    assert by["cheetah/sac-level"].cfg.total_steps == gc.LEVELS["cheetah"].steps == 1_000_000
    # a variant of a domain runs as long as the domain, and has no published level
    fixed = {j.key: j for j in pg.jobs(replace(full, worlds=("hopper-fixed",), levels=True))}
    assert [k.split("/")[1] for k in fixed] == list(learners)
    assert fixed["hopper-fixed/sac"].cfg.total_steps == pg.FULL_STEPS["hopper"]
    # the learners' SAC is the cheaper one measured against the published levels' (gym.md, "A cheaper SAC");
    # the level runs keep the levels' own 256 × 256 with an update every step
    level, learner = by["cheetah/sac-level"].cfg.sac, by["cheetah/sac"].cfg.sac
    assert (learner.hidden, learner.train_every) == ((128, 128), 2) and (level.hidden, level.train_every) == (
        (256, 256),
        1,
    )
    assert replace(level, hidden=(128, 128), train_every=2) == learner
    assert by["lunar/pebble-q800"].cfg.absorbing_state == "single" and by["lunar/prefbias-q800"].cfg.prefbias.absorbing
    assert pc.teacher_of(by["lunar/prefbias-q800"]) == "biased" and pc.teacher_of(by["lunar/sac"]) == "true"
    # the coin-flip control: PrefBias at the largest budget whose person answers by a fair coin (β = 0),
    # everything else as the biased person's job; the fast preset (a dry run) has none
    coin, biased = by["hopper/prefbias-q800-coin"], by["hopper/prefbias-q800"]
    assert coin.tags["person"] == "coin" and coin.cfg.teacher.beta == 0.0 and biased.cfg.teacher.beta == 1.0
    assert replace(coin.cfg, teacher=biased.cfg.teacher) == biased.cfg
    assert not any(j.key.endswith("-coin") for j in pg.jobs(pg.preset("fast")))
    # the learners share one schedule
    pb, peb, sac = (by[f"lunar/{n}"].cfg for n in ("prefbias-q800", "pebble-q800", "sac"))
    for name in ("total_steps", "chunk", "eval_every", "eval_episodes", "sac", "feedback_every", "segment"):
        assert getattr(pb, name) == getattr(peb, name), name
    assert pb.sac == sac.sac and pb.total_steps == sac.total_steps
    assert registry.preset_of("gym", full) == "full" and registry.preset_of("gym", pg.preset("fast")) == "fast"
    assert registry.command("gym", pg.preset("fast"), "runs/x") == "mindgap reproduce gym --fast --out runs/x"
    with_levels = registry.configure("gym", "full", levels=True)
    assert registry.command("gym", with_levels, "r") == "mindgap reproduce gym --levels --out r"
    assert registry.preset_of("gym", with_levels) == "full"  # an option, as --seeds is


def test_the_seen_domains_floor_the_person_s_belief_and_narrow_prefbias_s_posterior(monkeypatch):
    """``hopper-fixed-seen`` and ``cheetah-seen`` are their domains with the person's belief floored at one typical
    step's change (the same fitted model) and PrefBias's belief posterior at 0.001 a weight; nothing else moves."""
    for seen, base in (("hopper-fixed-seen", "hopper-fixed"), ("cheetah-seen", "cheetah")):
        d, b = pg.DOMAINS[seen], pg.DOMAINS[base]
        assert (d.env, d.belief_env, d.draw) == (b.env, b.belief_env, b.draw) and b.person_min_std is None
        full = pg.preset("full")
        ours = {j.key.split("/")[1]: j.cfg for j in pg.jobs(replace(full, worlds=(seen,)))}
        theirs = {j.key.split("/")[1]: j.cfg for j in pg.jobs(replace(full, worlds=(base,)))}
        assert list(ours) == list(theirs)
        for key, cfg in ours.items():
            if key.startswith("prefbias"):
                pb, preset = cfg.prefbias, theirs[key].prefbias
                assert pb.init_std == pb.belief_prior_std == 0.001
                assert preset.init_std == preset.belief_prior_std == 0.01
                cfg = replace(cfg, prefbias=replace(pb, init_std=0.01, belief_prior_std=0.01))
            assert cfg == theirs[key], key
    # load_world hands the domain's floor to the fit (whose own test, tests/teachers/test_learned_belief.py, checks
    # that it keeps the fitted model and cache entry and measures the held-out figures at it)
    asked = []

    def fit(belief_world, cfg, *, true_world, progress, min_std, cache_dir):
        asked.append(min_std)
        return SimpleNamespace(min_std=min_std), {"belief_env": belief_world.name}

    monkeypatch.setattr(pg, "fit_learned_belief", fit)
    monkeypatch.setattr(pg, "with_learned_belief", lambda world, name, belief: (world, belief))
    fast = pg.preset("fast")
    (_, belief), _ = pg.load_world("hopper-fixed-seen", fast)
    pg.load_world("hopper-fixed", fast)
    assert asked == [1.0, None] and belief.min_std == 1.0


@pytest.mark.slow
def test_gym_fast_for_real(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("MUJOCO_GL", "egl")
    out = tmp_path / "gym"
    assert main(["reproduce", "gym", "--fast", "--quiet", "--levels", "--out", str(out)]) == 0
    results = rows(out / "results.csv")
    assert sorted((r["world"], r["method"]) for r in results) == sorted(
        (w, m) for w in ("lunar", "hopper", "cheetah") for m in ("prefbias", "pebble", "sac", "sac-level")
    )
    for r in results:
        assert np.isfinite(float(r["return_mean"]))
        if r["method"] in ("prefbias", "pebble"):
            assert 0 <= float(r["reward_error_mean"]) <= 2
    for w in ("lunar", "hopper", "cheetah"):
        assert (out / f"rollouts/{w}__prefbias-q30.gif").stat().st_size > 0
        assert (out / f"curves_{w}.png").stat().st_size > 0


def test_a_job_whose_person_is_not_the_reference_s_is_refused():
    """The person's belief fitted on another number of cores is another model (docs/experiments/gym.md, "The person's
    fit and the machine"): a job is refused before it trains unless its belief's figures are the reference's."""
    ran = {"held_out_log_lik": 33.94292449951172, "true_log_lik": 15.3, "path": "/there/e320.npz"}
    here = {**ran, "path": "/here/e320.npz", "config": {"seed": 0}}
    gm.check_person("hopper-fixed", here, {"belief_model": ran})  # the same model, another machine's file
    gm.check_person("hopper-fixed", here, None)  # no reference yet
    gm.check_person("hopper-mjx", None, {"belief_model": None})  # an exact belief
    with pytest.raises(ValueError) as e:
        gm.check_person("hopper-fixed", {**here, "held_out_log_lik": 34.048423767089844}, {"belief_model": ran})
    assert str(e.value).count("\n") == 0 and "34.048423767089844 against 33.94292449951172" in str(e.value)
    assert "/here/e320.npz" in str(e.value)
