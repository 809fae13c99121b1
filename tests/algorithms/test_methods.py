"""The method registry: each method is one record, run through one ``train``."""

import jax.numpy as jnp
import pytest

from mindgap.algorithms import engine, eps, methods, pbrl, prefbias
from mindgap.feedback.queries import SAMPLERS, QueryModel, check_sampler, query_scores, sampler_names


@pytest.mark.parametrize("name", list(methods.METHODS))
def test_every_method_is_one_record_that_runs_its_own_configs(name):
    m = methods.get(name)
    cfg = m.preset("fast")
    assert isinstance(cfg, m.config) and cfg.method == m.tag
    assert methods.for_config(cfg) is m  # a config finds the record that runs it
    assert isinstance(m.learner(cfg), engine.Learner)
    assert (m.learned_reward is None) == (m.answers == "nothing")


def test_the_variants_of_one_config_are_separate_learners():
    # no cfg.method branch inside a learner: SAC, PEBBLE/DRLHP, EPS and expectation-DRLHP each have their own
    assert methods.SAC.learner(None) is pbrl.ORACLE_LEARNER
    assert methods.PEBBLE.learner(None) is methods.DRLHP.learner(None) is pbrl.REWARD_LEARNER
    assert methods.EPS.learner(None) is eps.EPS_LEARNER and methods.EXPECTATION_DRLHP.learner(None) is eps.DRLHP_LEARNER
    assert methods.PREFBIAS.learner(None) is prefbias.LEARNER
    cfg = methods.EPS.preset("fast", lam=2.5, nats_per_unit=1.0)
    assert eps.EPS_LEARNER.agent_sac(cfg).alpha == pytest.approx(2.5)  # Eq. 4.6's H_π: α = λ/s_H
    assert eps.DRLHP_LEARNER.agent_sac(cfg).alpha == pytest.approx(1.0)  # the baseline: u_H in nats, α = 1/s_H
    tuned = methods.EXPECTATION_DRLHP.preset("fast", drlhp_alpha="sac")
    assert eps.DRLHP_LEARNER.agent_sac(tuned).alpha is None  # or SAC's own, tuned


def test_train_refuses_what_a_method_cannot_run():
    with pytest.raises(ValueError, match="unknown method 'bpref'"):
        methods.get("bpref")
    with pytest.raises(ValueError, match="sac runs configs of method 'sac', got one of 'pebble'"):
        methods.train("sac", None, methods.PEBBLE.preset("fast"))
    with pytest.raises(ValueError, match="eps takes a EPSConfig, got a PbRLConfig"):
        methods.train("eps", None, methods.DRLHP.preset("fast"))
    with pytest.raises(ValueError, match="already registered"):
        methods.register(methods.Method("sac", "x", pbrl.PbRLConfig, None, None, None, None, "nothing"))
    with pytest.raises(ValueError, match="answers must be one of"):
        methods.Method("x", "x", pbrl.PbRLConfig, None, None, None, None, "ratings")


def test_one_sampler_registry_serves_every_learner():
    assert set(sampler_names(belief=True)) == set(SAMPLERS)
    assert "preference_disagreement" not in sampler_names(belief=False)
    check_sampler("preference_disagreement", belief=True)
    with pytest.raises(ValueError, match="unknown sampler 'preference_disagreement': choose from uniform"):
        methods.PEBBLE.preset("fast", sampler="preference_disagreement")
    probs = jnp.array([[0.5, 0.9, 0.1], [0.5, 0.9, 0.9]])
    model = QueryModel(lambda a, b: probs)
    for name in ("disagreement", "entropy"):  # the registry's scores are the ensemble scores
        assert jnp.array_equal(SAMPLERS[name].score(model, None, None), query_scores(probs, name))
    with pytest.raises(ValueError, match="needs a learner with a model of the person's belief"):
        SAMPLERS["preference_disagreement"].score(model, None, None)
