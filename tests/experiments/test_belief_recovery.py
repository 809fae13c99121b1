"""The belief-recovery check: PrefBias's inference alone recovers nav1's belief from the person's answers."""

import pytest

from mindgap.algorithms.prefbias_inference import PrefBiasConfig
from mindgap.envs.terrain import load_world
from mindgap.experiments.belief_recovery import RecoveryConfig, belief_recovery


@pytest.mark.slow
def test_prefbias_recovers_nav1_s_stuck_robot_on_the_ice_from_800_answers():
    """The issue's target: held-out ice P(not moving) ≥ 0.8 (person 0.91, truth 0.19) and the posterior's
    draws of the predicted move within half the world's noise; elsewhere the belief stays near the person's."""
    rec = belief_recovery(load_world("nav1"), PrefBiasConfig(), RecoveryConfig(tabular=False))
    ice, floor, sand = rec.row("ice"), rec.row("floor"), rec.row("sand")
    assert ice.stay_person > 0.85 and ice.stay_truth < 0.25
    assert ice.stay_phi >= 0.8, rec
    assert max(r.spread_sigma for r in rec.terrains) < 0.5, rec
    assert abs(floor.stay_phi - floor.stay_person) < 0.2 and abs(sand.stay_phi - sand.stay_person) < 0.15, rec
    assert rec.stay_error < rec.prior_stay_error - 0.15  # closer to the person than the prior's centre is
    assert rec.held_nll < 0.35  # the previous learner: 0.29 without early stopping, 0.40 on this learner without
