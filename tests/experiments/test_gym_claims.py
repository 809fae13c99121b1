"""The gym experiment's claims (Figs. 18–20, §3.4.3) on hand-made rows, and SAC's published levels."""

from mindgap.experiments import gym_claims as gc
from mindgap.experiments import prefbias_gym as pg


def test_the_claims_on_hand_made_rows():
    def row(method, ret, std=10.0, queries=800, seeds=5):
        return dict(
            method=method, label=f"{method} {queries}", return_mean=ret, return_std=std, seeds=seeds, queries=queries
        )

    held = {
        c["text"]: c["held"]
        for c in gc.domain_claims("lunar", [row("prefbias", 50), row("pebble", 80), row("sac", 200)])
    }
    assert list(held.values()) == [True]
    # PEBBLE within two standard errors of SAC: it matches
    held = {
        c["text"]: c["held"]
        for c in gc.domain_claims("lunar", [row("prefbias", 50), row("pebble", 190), row("sac", 200)])
    }
    assert list(held.values()) == [False]
    for name in ("hopper", "cheetah", "cheetah-mjx", "hopper-fixed"):
        rows_ = [row("prefbias", 900, queries=200), row("prefbias", 1500), row("pebble", 300), row("sac", 3000)]
        (c,) = gc.domain_claims(name, rows_)
        assert c["held"] and c["id"] == f"gym/{name.split('-')[0]}-above-pebble"
        assert c["text"].startswith(f"{name}: PrefBias ") and c["text"].endswith(
            ": prefbias 800 above pebble 800 (by more than 2 standard errors)"
        )
        (c,) = gc.domain_claims(name, [row("prefbias", 310, std=50), row("pebble", 300, std=50), row("sac", 3000)])
        assert not c["held"]  # above, but within two standard errors
    # the coin-flip control: PrefBias against itself on coin-flip answers, left out of the figure's claim
    coin = {**row("prefbias", 2000), "person": "coin"}
    claims = gc.domain_claims("hopper", [row("prefbias", 1500), row("pebble", 300), coin])
    assert [(c["id"], c["held"]) for c in claims] == [("gym/hopper-above-pebble", True), ("gym/coin-control", False)]
    assert claims[0]["measured"].startswith("1500.0 vs 300.0") and "learns from the answers" in claims[1]["text"]
    claims = gc.domain_claims(
        "lunar", [row("prefbias", 50), row("pebble", 80), row("sac", 200), {**coin, "return_mean": -500}]
    )
    assert [(c["id"], c["held"]) for c in claims] == [("gym/lunar-below-sac", True), ("gym/coin-control", True)]
    level = {**row("sac-level", 2000.0), "steps": 1_000_000}
    claims = gc.domain_claims("hopper", [row("prefbias", 1500), row("pebble", 300)], level_row=level)
    assert [c["held"] for c in claims] == [True, True] and "after 1000000 steps" in claims[1]["measured"]
    claims = gc.domain_claims("cheetah", [], level_row={**level, "return_mean": 9000.0})
    assert [c["held"] for c in claims] == [False]  # below the RL Zoo's 9535 − 100
    assert gc.domain_claims("lunar", [row("sac", 200)]) == []  # nothing to compare
    (c,) = gc.domain_claims("hopper", [row("prefbias", 1500, std=0.0, seeds=1), row("pebble", 300, std=0.0, seeds=1)])
    assert not c["held"] and "2 SE nan" in c["measured"]  # one seed: no standard error


def test_each_host_domain_has_a_level_on_its_belief_env():
    """The level job trains on the env the person believes in: the lander in a vacuum, the reliable walkers."""
    assert set(gc.LEVELS) == set(pg.preset("full").worlds)
    for name, level in gc.LEVELS.items():
        assert level.env == pg.DOMAINS[name].belief_env
    assert gc.LEVELS["lunar"].steps == 500_000 and gc.LEVELS["hopper"].steps == gc.LEVELS["cheetah"].steps == 1_000_000
