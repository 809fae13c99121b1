"""The gym experiment's claims (dissertation §3.4.3, Figs. 18–20) and SAC's published levels.

:func:`domain_claims` checks the dissertation's words on each control domain against a run's rows;
:data:`LEVELS` holds, per host domain, the published level of SAC that the ``sac-level`` job of
:mod:`~.prefbias_gym` is compared with (the project's check, not the dissertation's).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import prefbias_common as pc

NO_X = "exclude_current_positions_from_observation=False"
"""The walkers' belief envs and levels keep the x position in the observation (the noisy envs do)."""


class Level(NamedTuple):
    """A published level of SAC that our SAC on the belief env is compared with (docs/experiments/gym.md)."""

    env: str
    """The env the level was measured on."""
    level: float
    """The return SAC must reach (mean over seeds of the final greedy return)."""
    steps: int
    """The source's training budget (our level job trains as long)."""
    source: str


LEVELS = {
    "lunar": Level(
        "gym:LunarLander-v3,continuous=True",
        200.0,
        500_000,
        "the 'solved' score of the Gym documentation (dissertation §3.4.2.2); the SB3 RL Zoo's SAC "
        "reaches 260.4 ± 65.5 on LunarLanderContinuous-v2 at 500k steps",
    ),
    "hopper": Level(
        f"gym:Hopper-v5,{NO_X}",
        2325.5 - 1129.7,
        1_000_000,
        "the SB3 RL Zoo's SAC on Hopper-v3 at 1M steps: 2325.5 ± 1129.7 (mean ± std over evaluation "
        "episodes); the level is the mean minus one std",
    ),
    "cheetah": Level(
        f"gym:HalfCheetah-v5,{NO_X}",
        9535.5 - 100.5,
        1_000_000,
        "the SB3 RL Zoo's SAC on HalfCheetah-v3 at 1M steps: 9535.5 ± 100.5; the level is the mean minus one std",
    ),
}
"""Per host domain, the published SAC level (docs/experiments/gym.md cites the tables)."""


def figure_domain(name: str) -> str:
    """The preset domain a domain or its variant (``hopper-fixed``, ``cheetah-mjx``) stands for: its name before ``-``."""
    return name.split("-")[0]


def _se(a: dict, b: dict) -> float:
    """Standard error of the difference of two rows' mean final returns (seeds independent); NaN with one seed."""
    if min(a["seeds"], b["seeds"]) < 2:
        return float("nan")
    return float(np.sqrt(a["return_std"] ** 2 / max(a["seeds"], 1) + b["return_std"] ** 2 / max(b["seeds"], 1)))


_ABOVE_PEBBLE = {
    "hopper": "PrefBias achieves much better performance than PEBBLE",
    "cheetah": "PrefBias better matches SAC's performance than PEBBLE",
}
"""§3.4.3's words (l. 743) on the hopper and the cheetah, both checked as PrefBias above PEBBLE."""


def domain_claims(name: str, rows: list[dict], level_row: dict | None = None) -> list[dict]:
    """The dissertation's claims on this domain (§3.4.3, l. 743, on Figs. 18–20) and the project's
    check of SAC's level, as measured (sources by id: :data:`~.claim_sources.SOURCES`).

    * lunar: "both PrefBias and PEBBLE fail to match the SAC performance" — every PbRL learner's
      mean final return lies below SAC's by more than two standard errors of the difference;
    * hopper ("PrefBias achieves much better performance"), cheetah ("PrefBias can better match
      the performance of SAC, compared to PEBBLE"): PrefBias (the largest budget) above PEBBLE by
      more than two standard errors of the difference — on the cheetah, where both stay below
      SAC, above PEBBLE is closer to SAC;
    * the coin-flip control (the project's check): PrefBias above the same PrefBias on coin-flip
      answers (a row tagged ``person="coin"``, left out of the claims above) by more than two
      standard errors of the difference;
    * SAC's level (:data:`LEVELS`, the project's check): SAC on the belief env reaches the published level.

    A variant of a domain (``hopper-fixed``, ``cheetah-mjx``) is checked as its figure's domain.
    With one seed there is no standard error, and the comparisons are not met.
    """
    base = figure_domain(name)
    sac = next((r for r in rows if r["method"] == "sac"), None)
    coin = [r for r in rows if r.get("person") == "coin" and r["method"] == "prefbias"]
    rows = [r for r in rows if r.get("person") != "coin"]
    pbrl_rows = [r for r in rows if r["method"] in ("prefbias", "pebble")]
    pb = [r for r in pbrl_rows if r["method"] == "prefbias"]
    peb = [r for r in pbrl_rows if r["method"] == "pebble"]
    out = []
    if base == "lunar" and sac is not None and pbrl_rows:
        gaps = {r["label"]: (sac["return_mean"] - r["return_mean"], 2 * _se(sac, r)) for r in pbrl_rows}
        out.append(
            pc.claim(
                "gym/lunar-below-sac",
                f"{name}: both PrefBias and PEBBLE fail to match SAC (each below it by more than 2 standard errors)",
                all(g > z for g, z in gaps.values()),
                "; ".join(f"SAC − {k} = {g:.1f} (2 SE {z:.1f})" for k, (g, z) in gaps.items()),
            )
        )
    if base in ("hopper", "cheetah") and pb and peb:
        top, p = max(pb, key=lambda r: r["queries"]), peb[0]
        gap, z = top["return_mean"] - p["return_mean"], 2 * _se(top, p)
        out.append(
            pc.claim(
                f"gym/{base}-above-pebble",
                f"{name}: {_ABOVE_PEBBLE[base]}: {top['label']} above {p['label']} (by more than 2 standard errors)",
                gap > z,
                f"{top['return_mean']:.1f} vs {p['return_mean']:.1f} (difference {gap:+.1f}, 2 SE {z:.1f})",
            )
        )
    twin = [r for r in pb if coin and r["queries"] == coin[0]["queries"]]
    if twin:
        a, c = twin[0], coin[0]
        gap, z = a["return_mean"] - c["return_mean"], 2 * _se(a, c)
        out.append(
            pc.claim(
                "gym/coin-control",
                f"{name}: {a['label']} learns from the answers: above coin-flip answers (by more than 2 standard errors)",
                gap > z,
                f"{a['return_mean']:.1f} vs {c['return_mean']:.1f} (difference {gap:+.1f}, 2 SE {z:.1f})",
            )
        )
    if level_row is not None and base in LEVELS:
        lv = LEVELS[base]
        out.append(
            pc.claim(
                "gym/sac-level",
                f"{name}: SAC on {lv.env} reaches {lv.level:.0f} ({lv.source.split(';')[0]})",
                level_row["return_mean"] >= lv.level,
                f"{pc.fmt(level_row['return_mean'], level_row['return_std'])} after "
                f"{level_row.get('steps', 0)} steps (the source's budget: {lv.steps})",
            )
        )
    return out
