"""The EPS loop (Algorithm 3): one feedback round relabels exactly with Eq. 4.6; the CLI runs, writes, resumes."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.algorithms import engine, eps, methods
from mindgap.algorithms.eps_config import EPSConfig, eps_config
from mindgap.algorithms.eps_maps import surrogate_maps
from mindgap.algorithms.eps_reward import environment_entropy, eps_reward
from mindgap.algorithms.sac import SACConfig, sac_init
from mindgap.cli import main
from mindgap.envs.terrain import load_world
from mindgap.teachers.expectation import ExpectationTeacher, step_log_likelihood


def test_config_sets_the_entropy_weight_and_rejects_bad_settings():
    cfg = eps_config("fast", lam=2.5, sac=SACConfig(hidden=(16, 16), batch_size=32, learning_starts=250))
    assert cfg.agent_sac().alpha == pytest.approx(2.5 / cfg.nats_per_unit)  # λ H_π / s_H: SAC's own α (reward scale 1)
    assert eps_config("fast", lam=2.5, nats_per_unit=1.0).agent_sac().alpha == pytest.approx(2.5)
    # DRLHP's α: 1/s_H in the presets (u_H read in nats), SAC's own (tuned) with drlhp_alpha="sac"
    assert eps_config("fast", method="drlhp").agent_sac().alpha == pytest.approx(1.0 / cfg.nats_per_unit)
    assert eps_config("fast", method="drlhp", nats_per_unit=2.0).agent_sac().alpha == pytest.approx(0.5)
    assert eps_config("fast", method="drlhp", drlhp_alpha="sac").agent_sac() == eps_config("fast").sac
    assert "drlhp_alpha" not in EPSConfig().as_dict()  # the field's default: earlier run folders keep their meaning
    assert eps_config("fast").as_dict()["drlhp_alpha"] == "nats"
    with pytest.raises(ValueError, match="drlhp_alpha must be one of sac, nats"):
        eps_config("fast", drlhp_alpha="tuned")
    with pytest.raises(ValueError, match="set drlhp_alpha to sac"):  # a fixed α would be overridden silently
        eps_config("fast", method="drlhp", sac=SACConfig(alpha=0.5))
    assert eps_config("fast", method="drlhp", drlhp_alpha="sac", sac=SACConfig(alpha=0.5)).agent_sac().alpha == 0.5
    # policy_entropy "sac": SAC's own tuned α plus λ/s_H, so that at λ = 0 the agent is SAC on r_A
    sac = eps_config("fast", lam=2.5, policy_entropy="sac").agent_sac()
    assert sac.alpha is None and sac.alpha_extra == pytest.approx(2.5 / cfg.nats_per_unit)
    assert eps_config("fast", lam=0.0, policy_entropy="sac").agent_sac() == eps_config("fast").sac
    assert "policy_entropy" not in eps_config("fast").as_dict()  # run folders from before it still resume
    with pytest.raises(ValueError, match="policy_entropy must be one of lambda, sac"):
        eps_config("fast", policy_entropy="tuned")
    with pytest.raises(ValueError, match="unknown method"):
        eps_config("fast", method="ppo")
    with pytest.raises(ValueError, match="non-negative"):
        eps_config("fast", lam=-1.0)
    with pytest.raises(ValueError, match="positive"):
        eps_config("fast", nats_per_unit=0.0)
    with pytest.raises(ValueError, match="preset"):
        eps_config("huge")
    with pytest.raises(ValueError, match="unknown surrogate"):
        eps_config("fast", surrogate="oracle")
    assert "surrogate" not in eps_config("fast").as_dict()  # recorded only when set: old run folders resume
    assert eps_config("fast", surrogate="exact").as_dict()["surrogate"] == "exact"


@pytest.mark.parametrize(
    "method, offset, surrogate",
    [
        ("eps", "cost", "learned"),
        ("eps", "centred", "learned"),
        ("eps", "none", "learned"),
        ("drlhp", "cost", "learned"),
        ("eps", "cost", "exact"),
        ("drlhp", "cost", "exact"),
    ],
)
def test_a_feedback_round_relabels_the_buffer_with_the_reshaped_reward(method, offset, surrogate, key):
    world = load_world("d1")
    # ("eps", "cost", "learned") is the CLI test's round
    cfg = eps_config("fast", method=method, offset=offset, surrogate=surrogate)
    # an untrained actor stands in for π_H: the round's bookkeeping does not depend on its quality
    person = ExpectationTeacher(world.belief(), sac_init(key, 2, 2, SACConfig(hidden=(8,))).params.actor, world.env)
    person = dataclasses.replace(person, cfg=cfg.teacher)
    env, w = world.env, engine.WorldArgs(world.params, world.obs_units(), person)
    learner = methods.for_config(cfg).learner(cfg)  # EPS's or expectation-DRLHP's
    carry = engine.init_carry(jax.random.split(key, 2), learner, env, world.params, cfg)
    carry = engine.run_chunk_all(carry, w, learner, env, cfg, "random")
    before = np.asarray(carry.loop.replay.reward)
    carry, _ = engine.feedback_round(carry, w, person, learner, env, cfg)
    assert np.asarray(carry.queries).tolist() == [cfg.per_round] * 2  # the round's budget, asked or not
    asked = np.asarray(carry.prefs.count).tolist()
    assert asked == ([0, 0] if surrogate == "exact" else [cfg.per_round] * 2)
    for s in range(2):
        c = jax.tree.map(lambda a: a[s], carry)
        buf = c.loop.replay
        n = int(buf.size)
        params = eps._reward_params(c.model, w, env, cfg)
        fn = eps_reward if method == "eps" else eps.expectation_reward
        want = fn(params, buf.obs[:n], buf.act[:n], buf.next_obs[:n])
        np.testing.assert_allclose(np.asarray(buf.reward[:n]), np.asarray(want), rtol=1e-4, atol=1e-4)
        assert not np.allclose(np.asarray(buf.reward[:n]), before[s, :n])  # the rewards did change
        u = eps.normalised_u(params, buf.obs[:n], buf.act[:n], buf.next_obs[:n])
        h = environment_entropy(params, buf.obs[:n], buf.act[:n])
        if method == "eps" and offset == "centred":  # u_H and H_T centred over the buffer
            assert float(jnp.mean(h)) == pytest.approx(0.0, abs=1e-3) and float(c.model.h_shift) != 0.0
        elif method == "eps" and offset == "cost":  # the λ-term ≤ 0 on every step, 0 on the buffer's best
            term = u + params.h_weight * h  # h = H_T − H_π,max; SAC adds H_π ≤ H_π,max
            assert float(c.model.h_shift) == pytest.approx(eps.policy_entropy_max(env))
            assert float(term.max()) == pytest.approx(-float(params.h_weight) * float(c.model.h_shift), abs=1e-3)
        else:
            assert float(c.model.h_shift) == 0.0  # Eq. 4.6 as written
        if method == "drlhp" or offset != "cost":  # standardised to mean 0 over the buffer
            assert float(jnp.mean(u)) == pytest.approx(0.0, abs=2e-3)
        if surrogate == "exact":  # u_H is the person's own score, standardised over the buffer
            score = step_log_likelihood(person, buf.obs[:n], buf.act[:n], buf.next_obs[:n], cfg.teacher.log_t_floor)
            z = (score - score.mean()) / score.std()
            np.testing.assert_allclose(np.asarray(u - u.mean()), np.asarray(z), atol=2e-3)
            assert not np.allclose(np.asarray(params.u_mean), 0.0)
        if method == "drlhp":  # u_H standardised over the buffer (§4.3.3)
            assert float(jnp.mean(buf.reward[:n])) == pytest.approx(0.0, abs=1e-3)
            assert float(jnp.std(buf.reward[:n])) == pytest.approx(1.0, abs=1e-2)

    if surrogate == "exact" and method == "eps":  # Fig. 28's map draws the person's score, not the idle ensemble
        maps = np.asarray(surrogate_maps(carry, world.params, person, cfg, k=2))
        h, w = world.params.grid.shape
        assert maps.shape == (2, 2 * h, 2 * w)
        (m0, s0), (m1, s1) = np.asarray(carry.model.u_norm)
        open_cells = np.isfinite(maps[0])
        np.testing.assert_allclose(
            (maps[0] * s0 + m0)[open_cells], (maps[1] * s1 + m1)[open_cells], rtol=1e-4, atol=1e-3
        )


def test_cli_runs_writes_its_outputs_and_resumes(tmp_path, monkeypatch):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "run"
    argv = ["eps", "--world", "d1", "--fast", "--seeds", "2", "--rollouts", "4", "--nats-per-unit", "3"]
    argv += ["--out", str(out), "--quiet"]
    assert main(argv) == 0
    assert json.loads((out / "config.json").read_text())["config"]["nats_per_unit"] == 3.0
    for name in ("curve.csv", "curve.png", "trajectories.png", "surrogate.png", "explicability.json", "summary.json"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    scores = json.loads((out / "explicability.json").read_text())
    assert summary["queries"] == 30 and summary["method"] == "eps" and len(scores) == 2
    for s in scores:  # −KL: the two parts are expectations of log-ratios, finite for a stochastic agent
        assert np.isfinite([s["score"], s["dynamics_part"], s["policy_part"]]).all()
        assert s["score"] == pytest.approx(-(s["dynamics_part"] + s["policy_part"]), rel=1e-4, abs=1e-3)
    curve = (out / "curve.csv").read_text()
    assert len(list((tmp_path / "cache").rglob("*.npz"))) == 1  # π_H trained once and cached
    assert main(argv) == 0  # a rerun resumes from the finished checkpoint: the same curve
    assert (out / "curve.csv").read_text() == curve
    assert main([*argv[:-1], "--method", "ppo", "--fresh"]) == 2


@pytest.mark.slow  # a second EPS program to compile (cold ~20 s); the default tier checks the same at the round
# level: the exact surrogate's rounds ask no query (test_a_feedback_round_relabels_the_buffer_with_the_reshaped_reward)
def test_cli_with_the_exact_surrogate_asks_no_query(tmp_path, monkeypatch):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    argv = ["eps", "--world", "d1", "--fast", "--seeds", "2", "--rollouts", "4", "--nats-per-unit", "3"]
    # the oracle ablation asks no query, and says so (its rounds still count their budget)
    assert main([*argv, "--out", str(tmp_path / "exact"), "--quiet", "--surrogate", "exact"]) == 0
    assert json.loads((tmp_path / "exact" / "summary.json").read_text())["queries"] == 0


def test_eps_config_defaults_are_consistent():
    cfg = EPSConfig()
    cfg.check()
    assert cfg.learning_steps() == cfg.sac.learning_starts  # no pre-training phase
