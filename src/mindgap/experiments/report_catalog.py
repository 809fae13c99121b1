"""What the dissertation reports for each experiment, and how each run folder's claims are read.

:data:`CATALOG` holds, per named experiment, the dissertation's tables (its numbers) or a
description of its figures, and which files of a run folder show ours beside them.
:func:`claims` turns a run folder's ``summary.json`` into claims ``{id, text, held, measured}``
with their sources (:mod:`~.claim_sources`: the dissertation's claim or the project's own
check, where the dissertation says it): the PrefBias, EPS and driving experiments write their
claims themselves; Table 1's ``checks`` and the coffee study's ``orderings`` are put in the
same form here, with the numbers that decide them.
"""

from __future__ import annotations

from typing import NamedTuple

from .claim_sources import DISSERTATION_BELIEF, sourced


class Item(NamedTuple):
    """One table or figure of the dissertation and where a run folder shows ours."""

    name: str
    """``Table 1``, ``Figs. 5–7``, …"""
    paper: str
    """The dissertation's numbers (a Markdown table) or what its figure shows."""
    figures: tuple[str, ...] = ()
    """Glob patterns of the run folder's figures that show ours."""
    files: tuple[str, ...] = ()
    """Glob patterns of the run folder's data files (CSV, JSON) behind ours."""
    tables: tuple[str, ...] = ()
    """Words that pick ours out of the run's ``table.md`` (the tables whose caption holds one)."""


class Entry(NamedTuple):
    title: str
    section: str
    items: tuple[Item, ...]
    docs: str
    """The documentation page on the experiment, from the repository root."""


_TABLE1 = """| | d(R) | d(Θ) | d(π) | d(R) | d(Θ) | d(π) |
|---|---|---|---|---|---|---|
| | *reversed* | | | *rotated* | | |
| GeReL | 12.17 | 0.06 | 0.11 | 12.61 | 0.08 | 0.23 |
| SERD | 16.43 | 0.38 | 0.47 | 17.62 | 0.57 | 0.63 |
| GeReL⁻ | 26.72 | 0.56 | 1.46 | 23.96 | 0.91 | 1.43 |
| MaxEnt-IRL | 23.32 | 0.56 | 1.68 | 28.02 | 0.91 | 1.55 |"""

_TABLE2 = """| question | p | mobile | humanoid |
|---|---|---|---|
| (Q1) domain dynamics | 0.047 | 2.92 | 3.58 |
| (Q2) weight preference | 0.027 | 2.83 | 3.67 |"""

_TABLE3 = """| domain | EPS | SAC | DRLHP | PS |
|---|---|---|---|---|
| D1 | 95.53 (1.88) | 97.46 (1.53) | 74.51 (29.92) | 93.91 (3.55) |
| D2 | 94.07 (2.43) | 95.65 (1.98) | 23.28 (43.71) | 95.55 (3.17) |
| D3 | 96.80 (1.16) | 94.47 (2.77) | −50.76 (56.49) | −178.76 (63.88) |
| D4 | 92.37 (1.80) | 93.27 (2.03) | 26.52 (49.02) | 90.11 (14.79) |"""

_TABLE5 = """| | EPS | SAC | DRLHP |
|---|---|---|---|
| Avg. Rating | 7.6 | 5.0 | 5.9 |
| Avg. Return | 11.0 | 11.9 | 9.6 |"""


GRID = Entry(
    "Grid sweep",
    "a sweep file's grid",
    (
        Item(
            "Grid",
            "Learners × worlds × settings of a sweep file: the dissertation has no number to set beside these.",
            (),
            ("results.csv", "curves.csv", "summary.json"),
            ("Grid sweep",),
        ),
    ),
    "docs/sweeps.md",
)
"""The entry of a grid sweep's run folder (``mindgap sweep``), which no named experiment made."""

CATALOG: dict[str, Entry] = {
    "table1": Entry(
        "GeReL on the grid world",
        "§2.3.1",
        (
            Item(
                "Table 1",
                "L2 distance of the learned reward d(R) and belief d(Θ) to the truth, and the KL "
                "divergence d(π) of the person's expected policy, 7×7 grid:\n\n" + _TABLE1,
                ("rewards_*.png",),
                ("results.csv", "summary.json"),
                ("Belief parameterisation",),
            ),
            Item(
                "Figs. 5–7",
                "d(R), d(Θ) and d(π) of the four methods (and the prior) as the number of rated "
                "demonstrations grows: GeReL lowest throughout.",
                ("demo_counts_*.png", "curves_*.png"),
                ("demo_counts.csv", "curves.csv", "restarts.csv"),
                ("Data efficiency",),
            ),
        ),
        "docs/experiments/table1.md",
    ),
    "coffee": Entry(
        "The coffee-robot user study",
        "§2.3.2",
        (
            Item(
                "Table 2",
                "Mean Likert answers before the demonstrations (real participants):\n\n" + _TABLE2,
                ("ratings_by_demo.png",),
                ("participants.csv", "ratings.csv"),
                ("Table 2",),
            ),
            Item(
                "Fig. 12",
                "Feature weights and spill probability learned per participant: GeReL's spill "
                "probability (umbrella while holding coffee) is larger for the humanoid than for the "
                "mobile robot, as the participants answered, and so is the weight they put on the robot "
                "staying dry; GeReL⁻ finds “just the opposite” about wetness (l. 448, 455).",
                ("fig12.png",),
                ("results.csv",),
                ("Learned per robot",),
            ),
        ),
        "docs/experiments/coffee.md",
    ),
    "nav": Entry(
        "PrefBias on the navigation tasks",
        "§3.4.2.1, §3.4.3",
        (
            Item(
                "Figs. 16–17",
                "Learning curves on Navigation 1 and 2 under the true reward: PrefBias reaches SAC's "
                "return, PEBBLE stays below it.",
                ("curves_*.png",),
                ("curves.csv", "results.csv"),
            ),
            Item(
                "Fig. 21",
                "Trajectories: on Navigation 1 PEBBLE takes the sandy corridor, PrefBias the ice as SAC "
                "does; on Navigation 2 PEBBLE keeps away from the pit, PrefBias takes the shortcut.",
                ("trajectories_*.png",),
                ("results.csv",),
            ),
        ),
        "docs/experiments/prefbias.md",
    ),
    "priors": Entry(
        "PrefBias: the belief prior",
        "§3.4.3.1",
        (
            Item(
                "Figs. 22–24",
                "A prior centred on a learned model of the true dynamics gives a lower belief error "
                "(Fig. 22), a lower reward error (Fig. 23) and a higher return (Fig. 24) than a random prior.",
                ("*.png",),
                ("results.csv", "curves.csv"),
            ),
        ),
        "docs/experiments/prefbias.md",
    ),
    "sampling": Entry(
        "PrefBias: query sampling",
        "§3.4.3.2",
        (
            Item(
                "§3.4.3.2 (text)",
                "Uniform, disagreement, entropy and preference-disagreement sampling: the "
                "preference-disagreement sampler is slightly better, but not much.",
                ("*.png",),
                ("results.csv", "curves.csv"),
            ),
        ),
        "docs/experiments/prefbias.md",
    ),
    "eps": Entry(
        "Explicable policy search on D1–D4",
        "§4.4.1",
        (
            Item(
                "Table 3",
                "Average return over 100 rollouts, mean (std):\n\n" + _TABLE3,
                (),
                ("results.csv",),
                ("(Table 3)",),
            ),
            Item(
                "Table 4",
                "Explicability score (Eq. 4.4). The dissertation's Table 4 repeats Table 3's numbers; "
                "its text says EPS has the highest explicability score in every domain.",
                (),
                ("results.csv",),
                ("(Table 4)",),
            ),
            Item(
                "Figs. 27–28",
                "Trajectories of EPS, SAC, DRLHP and Policy Shaping beside the person's expectation: "
                "EPS detours round the pit in D1–D2 and takes the expected road in D3–D4; the learned "
                "surrogate rewards.",
                ("trajectories.png", "surrogate_*.png"),
                ("person.csv",),
            ),
            Item(
                "Figs. 29–30",
                "Without a biased person EPS recovers SAC's behaviour and learns as fast.",
                ("unbiased.png", "curves_*.png"),
                ("curves.csv",),
            ),
        ),
        "docs/experiments/eps.md",
    ),
    "driving": Entry(
        "The driving study: sleety braking",
        "§4.4.2",
        (
            Item(
                "Table 5",
                "Average rating (1–10) of each method's rollouts by new participants, and average return "
                "under r_A: EPS rated highest, SAC the highest return, DRLHP the lowest:\n\n" + _TABLE5,
                (),
                ("results.csv", "ratings.csv", "participants.csv"),
                ("(Table 5)",),
            ),
            Item(
                "Figs. 34–36",
                "Three characteristic steps per policy on a sleety day: SAC steers at once; DRLHP brakes in "
                "its lane and gets dangerously close to the front car; EPS first brakes, then changes lane.",
                ("frames_*.png", "episode_*.gif"),
                ("results.csv",),
                ("behaviours",),
            ),
        ),
        "docs/experiments/driving.md",
    ),
    "lambda": Entry(
        "EPS: the reconciliation weight λ",
        "§4.4.1.4",
        (
            Item(
                "Fig. 31",
                "The lower λ, the closer EPS's behaviour to SAC's; the higher, the closer to the person's expectation.",
                ("*.png",),
                ("results.csv", "curves.csv"),
            ),
        ),
        "docs/experiments/eps.md",
    ),
    "gym": Entry(
        "PrefBias on the control domains",
        "§3.4.2.2–3, §3.4.3",
        (
            Item(
                "Fig. 18",
                "Learning curves on the lunar lander with an invisible solar wind, under the true reward: "
                "both PrefBias and PEBBLE fail to match SAC's return.",
                ("curves_lunar*.png", "trajectories_lunar*.png", "rollouts/lunar*.gif"),
                ("curves.csv", "results.csv"),
                ("Figs. 18–20",),
            ),
            Item(
                "Figs. 19–20",
                "Learning curves on the hopper and the cheetah with hidden noise: PEBBLE stays near a return of "
                "0 on the hopper while PrefBias does much better (with a larger variance); on the cheetah "
                "PrefBias comes closer to SAC than PEBBLE.",
                (
                    "curves_hopper*.png",
                    "curves_cheetah*.png",
                    "trajectories_hopper*.png",
                    "trajectories_cheetah*.png",
                    "rollouts/hopper*.gif",
                    "rollouts/cheetah*.gif",
                ),
                ("curves.csv", "results.csv"),
                ("Design check",),
            ),
        ),
        "docs/experiments/gym.md",
    ),
}

_LABELS = {"gerel": "GeReL", "serd": "SERD", "gerel-minus": "GeReL⁻", "maxent-irl": "MaxEnt-IRL"}
_METRIC = {"d_R": "d(R)", "d_Theta": "d(Θ)", "d_pi": "d(π)"}


def claims(name: str, summary: dict) -> list[dict]:
    """The claims of a run folder's ``summary.json``: ``{id, text, held, measured}`` each, with
    their source's ``kind``, ``where`` and ``says`` (:func:`~.claim_sources.sourced`).

    ``held`` is ``True``, ``False`` or ``None`` (not decidable from this run).
    """
    if name == "table1":
        made = _table1_claims(summary)
    elif name == "coffee":
        made = _coffee_claims(summary)
    else:
        made = [dict(c) for c in summary.get("claims", [])]
    return [sourced(name, c) for c in made]


def _table1_claims(summary: dict) -> list[dict]:
    """Table 1's ``checks`` as claims. On the dissertation's belief (:data:`~.claim_sources.DISSERTATION_BELIEF`)
    they are §2.3.1's claims; on a parameterisation the project adds, its own checks; the tied
    belief's bounds on d(Θ) and d(π) are targets the project set."""
    stats, out = summary.get("stats", {}), []

    def mean(key, method, metric):
        e = stats.get(f"{key}|{method}")
        return e[metric][0] if e else float("nan")

    for key, checks in summary.get("checks", {}).items():
        param, setting = key.split("|")
        where = f"{setting}, {param} belief"
        ours = param == DISSERTATION_BELIEF

        def source(cid):
            return cid if ours else "table1/other-belief"

        for check, held in checks.items():
            if check.startswith("gerel_lowest_"):
                m = check[len("gerel_lowest_") :]
                others = {_LABELS[o]: mean(key, o, m) for o in _LABELS if o != "gerel"}
                best = min(others, key=others.get)
                cid = source("table1/gerel-lowest")
                text = f"{where}: GeReL has the lowest {_METRIC[m]} of the four methods"
                measured = f"GeReL {mean(key, 'gerel', m):.3g}, best other {best} {others[best]:.3g}"
            elif check == "gerel_beats_minus_and_maxent":
                cid = source("table1/beats-unaware")
                text = f"{where}: GeReL outperforms GeReL⁻ and MaxEnt-IRL on d(R), d(Θ) and d(π)"
                measured = ", ".join(
                    f"{_METRIC[m]} {mean(key, 'gerel', m):.3g} vs "
                    f"{min(mean(key, 'gerel-minus', m), mean(key, 'maxent-irl', m)):.3g}"
                    for m in _METRIC
                )
            elif check == "unaware_corr_negative":
                cid = source("table1/unaware-opposite")
                text = (
                    f"{where}: GeReL⁻ and MaxEnt-IRL converge in the opposite direction "
                    "(a reward anti-correlated with the truth)"
                )
                measured = f"corr {mean(key, 'gerel-minus', 'corr_R'):.2f} and {mean(key, 'maxent-irl', 'corr_R'):.2f}"
            elif check.startswith("tied_"):
                metric, bound = check[len("tied_") :].split("<=")
                cid = "table1/tied-target"
                text = f"{where}: GeReL's {_METRIC[metric]} ≤ {bound}"
                measured = f"{mean(key, 'gerel', metric):.3g}"
            else:  # a check this reader does not know: no dissertation statement to tie it to
                cid, text, measured = None, f"{where}: {check}", ""
            out.append({"id": cid, "text": text, "held": bool(held), "measured": measured})
    return out


_COFFEE = {
    "spill_humanoid_gt_mobile": (
        "coffee/gerel-spill",
        "learns a higher spill probability (with the umbrella) for the humanoid than for the mobile robot",
    ),
    "wet_penalty_humanoid_gt_mobile": (
        "coffee/gerel-wet",
        "learns that the participants care more about the robot getting wet with the humanoid (a higher wet penalty)",
    ),
    "wet_per_coffee_humanoid_gt_mobile": (
        "coffee/wet-per-coffee",
        "learns a higher wet penalty per unit of coffee weight for the humanoid",
    ),
    "spill_order_matches_truth": (
        "coffee/as-truth",
        "orders the robots' spill probabilities as the participants' own beliefs do",
    ),
    "wet_order_matches_truth": ("coffee/as-truth", "orders the wet penalties as the participants' own rewards do"),
    "wet_per_coffee_order_matches_truth": (
        "coffee/as-truth",
        "orders wet penalty per coffee as the participants' own rewards do",
    ),
}
"""The coffee study's ``orderings``: the claim's id (on the dissertation's belief) and what it says."""

_MINUS = "GeReL⁻"
_OPPOSITE = {
    "wet_penalty_humanoid_gt_mobile": (
        "coffee/minus-opposite",
        "discovers the opposite: a higher wet penalty for the mobile robot than for the humanoid",
    ),
    "wet_per_coffee_humanoid_gt_mobile": (
        "coffee/wet-per-coffee",
        "discovers the opposite per unit of coffee weight: a higher wet penalty per coffee for the mobile robot",
    ),
}
"""GeReL⁻'s orderings read as §2.3.2 states them (l. 455: it "discovered just the opposite")."""


def _coffee_claims(summary: dict) -> list[dict]:
    """The coffee study's ``orderings`` as claims (§2.3.2, l. 448, 455).

    GeReL on the dissertation's belief (:data:`~.claim_sources.DISSERTATION_BELIEF`) makes the
    dissertation's two claims (spill probability and wet penalty higher for the humanoid); on a
    parameterisation the project adds, the same orderings are the project's checks. Of GeReL⁻ the
    dissertation says it "discovered just the opposite" about wetness: its wet-penalty orderings (the
    penalty, the dissertation's claim, and per unit of coffee weight, the project's variant) are
    checked for the mobile robot's penalty being the higher. GeReL⁻'s spill probability is the
    robot's true one (§2.3.1, l. 353: the true dynamics), not learned, so it makes no claim.
    """
    out = []
    learned = summary.get("learned", {})
    for fit, orderings in summary.get("orderings", {}).items():
        minus = fit == _MINUS
        ours = minus or fit.endswith(f"({DISSERTATION_BELIEF})")
        per = learned.get(fit, {})
        for check, held in orderings.items():
            if held is None or (minus and check.startswith("spill")):
                continue
            cid, says = _COFFEE.get(check, (None, check))
            what = check.split("_humanoid")[0].split("_order")[0]
            key = {"spill": "spill", "wet_penalty": "wet_penalty", "wet": "wet_penalty"}.get(what, what)
            numbers = per and key in per.get("humanoid", {})
            measured = f"humanoid {per['humanoid'][key][0]:.3g}, mobile {per['mobile'][key][0]:.3g}" if numbers else ""
            if minus and check in _OPPOSITE:
                cid, says = _OPPOSITE[check]
                # the same comparison, read the other way round: the mobile robot's penalty strictly higher
                held = per["mobile"][key][0] > per["humanoid"][key][0] if numbers else not held
            elif not ours and cid in ("coffee/gerel-spill", "coffee/gerel-wet"):
                cid = "coffee/other-belief"
            out.append({"id": cid, "text": f"{fit} {says}", "held": bool(held), "measured": measured})
    return out
