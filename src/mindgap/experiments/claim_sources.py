"""Where the dissertation says each claim the experiments check, and which checks are the project's own.

Every claim an experiment decides is ``{id, text, held, measured}`` (:func:`claim`): ``text``
says what was checked on which world and by which rule, ``measured`` the numbers that decided
it. The ``id`` names its entry in :data:`SOURCES`, which holds what does not change from run to
run: whether the claim is the dissertation's (:data:`DISSERTATION`: a short quote, “…” marking
the dissertation's own words, or a close paraphrase, with its section and the line numbers of
the dissertation's text) or a check of the project's own (:data:`PROJECT`: a coin-flip control,
a threshold the project chose, a parameterisation the dissertation does not use, a sanity level),
and why the project checks it. The report counts the dissertation's claims in its tally and
shows the project's checks apart.

Because the source is looked up by id when the report is made, a run folder keeps its
``summary.json`` when a quote is corrected; a ``summary.json`` written before claims carried
ids has its ids recognised from the claims' texts (:func:`legacy_id`).
"""

from __future__ import annotations

import re
from typing import NamedTuple

DISSERTATION = "dissertation"
"""A claim the dissertation makes: it counts in the tally."""
PROJECT = "project"
"""A check of the project's own: shown apart, outside the tally."""

DISSERTATION_BELIEF = "per-sa"
"""The belief parameterisation of GeReL as §2.2.2 defines it: one Dirichlet per state-action
pair (l. 237: each θ_i follows a Dirichlet, 𝒜 = [α_1, …, α_{|S|×|A|}]). Table 1's and the coffee study's checks on this
belief are the dissertation's claims; the same checks on a parameterisation the project adds
(``tied``, ``factored``) are its own."""


class Source(NamedTuple):
    """Where a claim comes from."""

    kind: str
    """:data:`DISSERTATION` or :data:`PROJECT`."""
    where: str
    """The dissertation's section and lines (``§2.3.1, l. 355, 378–381``): where it says so, or,
    for a check of the project's own, the statement the check stands beside."""
    says: str
    """The dissertation's statement (its words in “…”), or why the project checks it."""


_D, _P = DISSERTATION, PROJECT

_OTHER_BELIEF = (
    "The same check with a belief parameterisation the project adds (tied: one believed move "
    "distribution per action, shared by all states; factored: one Beta over the spill "
    "probability, the rest of the world known), which recovers a belief from few ratings; the "
    "dissertation's Θ is one Dirichlet per (s, a)."
)

SOURCES: dict[str, Source] = {
    # §2.3.1, Table 1 ------------------------------------------------------------------
    "table1/gerel-lowest": Source(
        _D,
        "§2.3.1, l. 355, 378–381",
        "Table 1: GeReL has the lowest d(R), d(Θ) and d(π) of the four methods in both settings; "
        "SERD “converges in the right direction, but the learned values are farther from the "
        "ground truth than GeReL in all cases”.",
    ),
    "table1/beats-unaware": Source(
        _D,
        "§2.3.1, l. 378–381; §2.4, l. 459",
        "Table 1: GeReL below GeReL⁻ and MaxEnt-IRL on all three metrics; “GeReL outperformed "
        "prior approaches that could have misinterpreted the human preferences when such biases "
        "are not considered”.",
    ),
    "table1/unaware-opposite": Source(
        _D,
        "§2.3.1, l. 355",
        "GeReL⁻ and MaxEnt-IRL “converge in the completely opposite direction since they do not "
        "consider that the human’s belief could be biased”.",
    ),
    "table1/other-belief": Source(_P, "§2.2.2, l. 237", _OTHER_BELIEF),
    "table1/tied-target": Source(
        _P,
        "§2.3.1, l. 378",
        "A target the project set for the tied belief near Table 1's GeReL values (d(Θ) 0.06 and "
        "0.08, d(π) 0.11 and 0.23); the dissertation states no bound.",
    ),
    # §2.3.2, the coffee robot -----------------------------------------------------------
    "coffee/gerel-spill": Source(
        _D,
        "§2.3.2, l. 448",
        "“the learned probability of spilling coffee while holding an umbrella by GeReL for the "
        "humanoid robot setting is generally larger than the mobile robot setting”.",
    ),
    "coffee/gerel-wet": Source(
        _D,
        "§2.3.2, l. 448, 455",
        "GeReL “learned that the participants cared more about the robot getting wet in the "
        "humanoid setting than the mobile robot setting”.",
    ),
    "coffee/minus-opposite": Source(
        _D,
        "§2.3.2, l. 455",
        "Of the same wetness: “In contrast, GeReL⁻ discovered just the opposite!”",
    ),
    "coffee/other-belief": Source(_P, "§2.2.2, l. 237", _OTHER_BELIEF),
    "coffee/wet-per-coffee": Source(
        _P,
        "§2.3.2, l. 448, 455",
        "A variant the project adds: the wet penalty relative to the coffee weight, which does "
        "not depend on the scale each participant's normalised ratings give the weights.",
    ),
    "coffee/as-truth": Source(
        _P,
        "§2.3.2, l. 448, 455",
        "A check the project adds: the simulated participants' own beliefs and rewards are known, "
        "and the learned ordering is compared with theirs. The dissertation compares with its "
        "participants' answers (Table 2).",
    ),
    # §3.4.2.1, §3.4.3: PrefBias on the navigation tasks -----------------------------------
    "nav/prefbias-reaches-sac": Source(
        _D,
        "§3.4.3, l. 739",
        "“PrefBias (green) with 800 queries reaches the performance as SAC (pink)”. The 90% of the "
        "oracle's normalised score is the project's reading of “reaches”.",
    ),
    "nav/prefbias-route": Source(
        _D,
        "§3.4.3, l. 741",
        "“PrefBias agent could successfully neutralize the biased belief and recover the optimal "
        "behavior as SAC”; on navigation 2 “PrefBias could find the shortcut to the goal”.",
    ),
    "nav/pebble-below-sac": Source(
        _D,
        "§3.4.3, l. 739",
        "“PEBBLE obtains less return”. The ceiling of 80% of the oracle's normalised score is the "
        "project's reading of “less”.",
    ),
    "nav/pebble-route": Source(
        _D,
        "§3.4.3, l. 741",
        "“the PEBBLE agent navigates through the sandy corridor which gives us a suboptimal "
        "behavior”; on navigation 2 “PEBBLE learns to keep distance from the pit area and take a detour”.",
    ),
    "nav/reward-error": Source(
        _D,
        "§3.4.3, l. 739",
        "“the surrogate reward function learned by PEBBLE is misguided by the biased belief and "
        "hardly capture the human’s objectives”.",
    ),
    "nav/coin-control": Source(
        _P,
        "§3.4.3, l. 739",
        "A control the project adds: PrefBias on coin-flip answers with the same budget; what "
        "PrefBias reaches must come from the answers, not from its prior or the task.",
    ),
    "nav/unbiased-control": Source(
        _P,
        "§3.4.3, l. 739",
        "A control the project adds: with an unbiased person (belief = truth) learning the "
        "belief should cost PrefBias nothing against PEBBLE; Chapter 3 runs no unbiased person.",
    ),
    # §3.4.3.1: the belief prior ----------------------------------------------------------------
    "priors/belief-error": Source(
        _D,
        "§3.4.3.1, l. 764",
        "Fig. 22: “PrefBias can learn a belief that matches the ground truth while taking the "
        "parameters of an estimated domain dynamics model as the prior”.",
    ),
    "priors/reward-error": Source(
        _D,
        "§3.4.3.1, l. 764",
        "“the True Domain Dynamics-based initialization outperforms the random initialization in "
        "terms of reward and policy learning (see Figure 23 and 24)”: reward (Fig. 23).",
    ),
    "priors/return": Source(
        _D,
        "§3.4.3.1, l. 764",
        "“the True Domain Dynamics-based initialization outperforms the random initialization in "
        "terms of reward and policy learning (see Figure 23 and 24)”: policy (Fig. 24).",
    ),
    # §3.4.3: the control domains ---------------------------------------------------------------
    "gym/lunar-below-sac": Source(
        _D,
        "§3.4.3, l. 743",
        "“For Lunar Lander (see Figure 18), both PrefBias and PEBBLE fail to match the SAC performance.”",
    ),
    "gym/hopper-above-pebble": Source(
        _D,
        "§3.4.3, l. 743",
        "“For Hopper (see Figure 19), PEBBLE presents very poor performance … while PrefBias "
        "achieves much better performance.”",
    ),
    "gym/cheetah-above-pebble": Source(
        _D,
        "§3.4.3, l. 743",
        "“for Cheetah (see Figure 20), PrefBias can better match the performance of SAC, compared to PEBBLE baseline.”",
    ),
    "gym/coin-control": Source(
        _P,
        "§3.4.3, l. 743",
        "A control the project adds: PrefBias (800 queries) on coin-flip answers with the same budget "
        "and schedule; what PrefBias reaches must come from the answers, not from its prior or the task.",
    ),
    "gym/sac-level": Source(
        _P,
        "§3.4.1.2, l. 655",
        "A check the project adds: SAC, the oracle, reaches a published level on the belief's env, "
        "so that the env and SAC are sound; the dissertation gives no number.",
    ),
    # §4.4.1: EPS on D1–D4 --------------------------------------------------------------------------
    "eps/highest-explicability": Source(
        _D,
        "§4.4.1.2, l. 954",
        "“For all domains, EPS achieved the highest policy explicability score”.",
    ),
    "eps/route": Source(
        _D,
        "§4.4.1.2, l. 986, 993",
        "In D1 and D2 the “EPS agent takes a detour that bypasses the pit”; EPS can “generate "
        "novel reconciled behaviors (D1 and D2), stick to the task priorities (D3), or follow the "
        "human’s expectation (D4)”.",
    ),
    "eps/return-near-sac": Source(
        _D,
        "§4.4.1.2, l. 954",
        "EPS “followed the best performer for average return” (Table 3: within 2% of SAC). The "
        "10% margin is the project's reading of “followed”.",
    ),
    "eps/unbiased-near-sac": Source(
        _D,
        "§4.4.1.3, l. 1002, 1004",
        "“our method reduces to SAC when there is no human bias”; EPS and SAC “are comparable (as "
        "expected)”. The 5% margin is the project's reading of “comparable”.",
    ),
    "eps/coin-control": Source(
        _P,
        "§4.4.1.2, l. 954",
        "A control the project adds: EPS on coin-flip answers; its explicability must come from the answers.",
    ),
    "eps/shaping-d3": Source(
        _D,
        "§4.4.1.2, l. 954",
        "“PS performed well on most tasks while being considerably worse than others in D3”. A "
        "return at least 50 below EPS's is the project's reading of “considerably worse”.",
    ),
    # §4.4.1.4: λ ----------------------------------------------------------------------------------------
    "lambda/explicability-rises": Source(
        _D,
        "§4.4.1.4, l. 1008",
        "“the higher the λ, the closer the behavior is to the human’s expectation”: read as the "
        "explicability score rising with λ.",
    ),
    "lambda/return-falls": Source(
        _D,
        "§4.4.1.4, l. 1008",
        "“the lower the λ, the closer the behavior is to the SAC agent”: read as the return, "
        "which SAC maximises, falling as λ rises.",
    ),
    # §4.4.2: the driving study ----------------------------------------------------------------------
    "driving/eps-rated-highest": Source(
        _D,
        "§4.4.2.1, l. 1085",
        "“the participants rated EPS agent the most preferable, followed by DRLHP and SAC agents” (Table 5).",
    ),
    "driving/sac-highest-return": Source(
        _D,
        "§4.4.2.1, l. 1087",
        "“In terms of the reward function we obtained in the training phase, the SAC agent performs the best.”",
    ),
    "driving/drlhp-lowest-return": Source(
        _D,
        "§4.4.2.1, l. 1087",
        "“DRLHP agent obtained a significantly lower return compared to the other two” (checked as the lowest).",
    ),
    "driving/sac-steers-first": Source(
        _D,
        "§4.4.2.1, l. 1081, 1083",
        "“SAC agent (see Figure 35) steers immediately when the front car slows down.”",
    ),
    "driving/drlhp-brakes-in-lane": Source(
        _D,
        "§4.4.2.1, l. 1083",
        "“DRLHP agent … chooses to brake while staying in the same lane”; “the agent is getting "
        "dangerously close to the vehicle in the front”.",
    ),
    "driving/eps-brakes-then-steers": Source(
        _D,
        "§4.4.2.1, l. 1083",
        "“EPS agent (see Figure 34) first chooses to brake (to be explicable), and then steers to the other lane”.",
    ),
    "driving/control": Source(
        _P,
        "§4.4.2.1, l. 1083",
        "A control the project adds: DRLHP trained on coin-flip answers must not brake first as "
        "DRLHP on the participants' answers does, so that its braking comes from the answers.",
    ),
}


def claim(claim_id: str, text: str, held, measured: str) -> dict:
    """One claim as decided on a run: ``{id, text, held, measured}`` (``held`` False where a number is missing).

    Raises:
        KeyError: ``claim_id`` is not in :data:`SOURCES` (every claim says where it comes from).
    """
    if claim_id not in SOURCES:
        raise KeyError(f"claim {claim_id!r} has no entry in claim_sources.SOURCES")
    return {"id": claim_id, "text": text, "held": bool(held), "measured": measured}


def sourced(experiment: str, c: dict) -> dict:
    """``c`` with its source's ``kind``, ``where`` and ``says``; a claim whose id is unknown is
    shown as a check of the project's own that no dissertation statement backs."""
    cid = c.get("id") or legacy_id(experiment, c["text"])
    src = SOURCES.get(cid) or Source(_P, "", "Not tied to a statement of the dissertation (no known claim id).")
    return {**c, "id": cid, "kind": src.kind, "where": src.where, "says": src.says}


_LEGACY: dict[str, tuple[tuple[str, str], ...]] = {
    "nav": (
        (r"reaches ≥ \d+% of the oracle$", "nav/prefbias-reaches-sac"),
        (r"stays at or below \d+% of the oracle$", "nav/pebble-below-sac"),
        (r"takes the person's route \(not .+\) in most seeds$", "nav/pebble-route"),
        (r"^\S+: PrefBias.* takes .+ in most seeds$", "nav/prefbias-route"),
        (r"'s reward error is below .+'s$", "nav/reward-error"),
        (r"learns from the answers: above coin-flip answers", "nav/coin-control"),
        (r"with an unbiased person PrefBias is no worse than PEBBLE", "nav/unbiased-control"),
    ),
    "priors": (
        (r"gives the lower reward error$", "priors/reward-error"),
        (r"gives the lower .*belief error", "priors/belief-error"),
        (r"return is at least the random prior's$", "priors/return"),
    ),
    "gym": (
        (r"neither PbRL method matches SAC", "gym/lunar-below-sac"),
        (r"^hopper\S*: .+ above .+ \(by more than", "gym/hopper-above-pebble"),
        (r"^cheetah\S*: .+ above .+ \(by more than", "gym/cheetah-above-pebble"),
        (r": SAC on .+ reaches ", "gym/sac-level"),
    ),
    "eps": (
        (r"EPS has the highest explicability score", "eps/highest-explicability"),
        (r"EPS takes the required route", "eps/route"),
        (r"EPS's return is within \d+% of SAC's$", "eps/return-near-sac"),
        (r"EPS \(unbiased person\)'s return is within", "eps/unbiased-near-sac"),
        (r"more explicable than on coin-flip answers", "eps/coin-control"),
        (r"Policy Shaping does much worse than EPS", "eps/shaping-d3"),
    ),
    "lambda": (
        (r"the explicability rises with λ", "lambda/explicability-rises"),
        (r"the return falls with λ", "lambda/return-falls"),
    ),
    "driving": (
        (r"DRLHP follows the answers", "driving/control"),
        (r"EPS is rated highest", "driving/eps-rated-highest"),
        (r"SAC has the highest return", "driving/sac-highest-return"),
        (r"DRLHP has the lowest return", "driving/drlhp-lowest-return"),
        (r"SAC changes lane first", "driving/sac-steers-first"),
        (r"DRLHP brakes in lane", "driving/drlhp-brakes-in-lane"),
        (r"EPS brakes first, then changes lane", "driving/eps-brakes-then-steers"),
    ),
}
"""The wordings claims had before they carried ids: (pattern, id) per experiment, first match wins."""


def legacy_id(experiment: str, text: str) -> str | None:
    """The id of a claim from a ``summary.json`` written before claims carried ids, recognised
    from its text (None when no wording of ``experiment`` matches)."""
    for pattern, cid in _LEGACY.get(experiment, ()):
        if re.search(pattern, text):
            return cid
    return None
