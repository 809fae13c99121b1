"""Tables and figures of experiment ``coffee`` (Table 2, Fig. 12 and the rating pattern of §2.3.2)."""

from __future__ import annotations

import json
import math
import warnings
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy import stats

from .._io import atomic_write
from ..envs.coffee import ROBOTS
from ..plotting.coffee import save_demo_strip, save_learned_values, save_ratings_by_demo

LABELS = {"gerel": "GeReL", "gerel-minus": "GeReL⁻"}
QUESTION_TEXT = {"q1": "(Q1) Domain dynamics: spill with an umbrella", "q2": "(Q2) Weight preference: robot wet"}


def _finite(values) -> np.ndarray:
    v = np.asarray([x for x in values if x is not None], float)
    return v[np.isfinite(v)]


def _ms(values) -> tuple[float, float]:
    v = _finite(values)
    return (float(v.mean()), float(v.std())) if len(v) else (math.nan, math.nan)


def _nan_to_none(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _nan_to_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_nan_to_none(v) for v in obj]
    return obj


def two_sample(a, b) -> dict:
    """Welch's t-test and the Mann–Whitney U test of two groups of answers (two-sided)."""
    a, b = _finite(a), _finite(b)
    if len(a) < 2 or len(b) < 2:
        return {"p_welch": math.nan, "p_mannwhitney": math.nan}
    if np.ptp(np.concatenate([a, b])) == 0:
        return {"p_welch": 1.0, "p_mannwhitney": 1.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # near-identical tiny groups (the fast preset)
        return {
            "p_welch": float(stats.ttest_ind(a, b, equal_var=False).pvalue),
            "p_mannwhitney": float(stats.mannwhitneyu(a, b, alternative="two-sided").pvalue),
        }


def correlation(x, y) -> dict:
    """Pearson and Spearman correlation over pairs where both are finite (NaN when undefined)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if len(x) < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return {"pearson": math.nan, "spearman": math.nan, "n": int(len(x))}
    return {
        "pearson": float(stats.pearsonr(x, y).statistic),
        "spearman": float(stats.spearmanr(x, y).statistic),
        "n": int(len(x)),
    }


def _fit_label(method: str, param: str) -> str:
    return LABELS[method] if method == "gerel-minus" else f"{LABELS[method]} ({param})"


def summarise(cfg, study, responses, rows) -> dict:
    """Table 2, learned values per method and robot, orderings and correlations."""
    valid = {robot: [r for r in rs if r.valid] for robot, rs in responses.items()}
    table2 = {}
    for q in ("q1", "q2"):
        answers = {robot: [getattr(r.participant, q) for r in valid[robot]] for robot in ROBOTS}
        table2[q] = {robot: float(np.mean(answers[robot])) for robot in ROBOTS} | two_sample(
            answers["mobile"], answers["humanoid"]
        )

    fits = defaultdict(list)
    for r in rows:
        fits[(r["method"], r["belief_param"])].append(r)
    truth = {
        robot: {
            "spill": _ms([r.participant.spill for r in valid[robot]]),
            "wet_penalty": _ms([-r.participant.wet_weight for r in valid[robot]]),
            "coffee_weight": _ms([r.participant.coffee_weight for r in valid[robot]]),
            "wet_per_coffee": _ms([-r.participant.wet_weight / r.participant.coffee_weight for r in valid[robot]]),
        }
        for robot in ROBOTS
    }
    learned, orderings, correlations = {}, {}, {}
    true_spill_order = truth["humanoid"]["spill"][0] > truth["mobile"]["spill"][0]
    true_wet_order = truth["humanoid"]["wet_penalty"][0] > truth["mobile"]["wet_penalty"][0]
    true_ratio_order = truth["humanoid"]["wet_per_coffee"][0] > truth["mobile"]["wet_per_coffee"][0]
    for (method, param), rs in sorted(fits.items()):
        name = _fit_label(method, param)
        per = {}
        for robot in ROBOTS:
            mine = [r for r in rs if r["robot"] == robot]
            per[robot] = {
                "spill": _ms([r["spill_learned"] for r in mine]),
                "wet_penalty": _ms([-r["wet_weight_learned"] for r in mine]),
                "coffee_weight": _ms([r["coffee_weight_learned"] for r in mine]),
                "wet_per_coffee": _ms([-r["wet_weight_learned"] / r["coffee_weight_learned"] for r in mine]),
                "n": len(mine),
            }
        learned[name] = per
        spill_higher = per["humanoid"]["spill"][0] > per["mobile"]["spill"][0]
        wet_higher = per["humanoid"]["wet_penalty"][0] > per["mobile"]["wet_penalty"][0]
        ratio_higher = per["humanoid"]["wet_per_coffee"][0] > per["mobile"]["wet_per_coffee"][0]
        orderings[name] = {
            "spill_humanoid_gt_mobile": bool(spill_higher),
            "wet_penalty_humanoid_gt_mobile": bool(wet_higher),
            "wet_per_coffee_humanoid_gt_mobile": bool(ratio_higher),
            "spill_order_matches_truth": bool(spill_higher == true_spill_order) if method == "gerel" else None,
            "wet_order_matches_truth": bool(wet_higher == true_wet_order),
            "wet_per_coffee_order_matches_truth": bool(ratio_higher == true_ratio_order),
        }
        correlations[name] = {
            "wet_weight": correlation([r["wet_weight_learned"] for r in rs], [r["wet_weight_true"] for r in rs]),
        }
        if method == "gerel":
            correlations[name]["spill"] = correlation([r["spill_learned"] for r in rs], [r["spill_true"] for r in rs])
    recruitment = {
        robot: {
            "recruited": len(rs),
            "valid": len(valid[robot]),
            "valid_answering_at_random": sum(not r.participant.attentive for r in valid[robot]),
            "dropped": dict(sorted(_count(r.dropped.split(" (")[0] for r in rs if r.dropped).items())),
        }
        for robot, rs in responses.items()
    }
    by_demo = {
        robot: {
            "mean": np.mean([r.ratings for r in valid[robot]], 0).tolist(),
            "std": np.std([r.ratings for r in valid[robot]], 0).tolist(),
        }
        for robot in ROBOTS
    }
    summary = {
        "participants_per_robot": cfg.participants,
        "table2": table2,
        "truth": truth,
        "learned": learned,
        "orderings": orderings,
        "correlations": correlations,
        "recruitment": recruitment,
        "ratings_by_demo": {"demos": list(study.names), **by_demo},
    }
    summary["table_md"] = render_tables(summary)
    return summary


def _count(items) -> dict:
    out: dict = defaultdict(int)
    for x in items:
        out[x] += 1
    return out


def _f(x, fmt=".2f") -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:{fmt}}"


def render_tables(s: dict) -> str:
    """Markdown: Table 2 analogue, learned values (Fig. 12 in numbers), correlations, recruitment."""
    lines = [
        f"\nTable 2 (simulated): mean Likert answers of the valid participants ({s['participants_per_robot']} per robot)\n"
    ]
    lines += ["| question | p (Welch t) | p (Mann–Whitney) | mobile | humanoid |", "|---|---|---|---|---|"]
    for q, e in s["table2"].items():
        lines.append(
            f"| {QUESTION_TEXT[q]} | {_f(e['p_welch'], '.3f')} | {_f(e['p_mannwhitney'], '.3f')} "
            f"| {e['mobile']:.2f} | {e['humanoid']:.2f} |"
        )
    lines.append("\nLearned per robot type (mean ± std over participants; truth = the participants' own values)\n")
    lines += [
        "| fit | spill mobile | spill humanoid | wet penalty mobile | wet penalty humanoid "
        "| coffee w mobile | coffee w humanoid | wet/coffee mobile | wet/coffee humanoid |",
        "|---|---|---|---|---|---|---|---|---|",
    ]

    def cells(per, keys=("spill", "wet_penalty", "coffee_weight", "wet_per_coffee")):
        out = []
        for k in keys:
            for robot in ROBOTS:
                m, sd = per[robot][k]
                out.append(f"{_f(m)} ± {_f(sd)}")
        return " | ".join(out)

    lines.append(f"| truth | {cells(s['truth'])} |")
    for name, per in s["learned"].items():
        lines.append(f"| {name} | {cells(per)} |")
    lines.append("\nOrderings (humanoid > mobile?) and correlation with the participants' true values\n")
    lines += [
        "| fit | spill h > m | wet penalty h > m | as truth | wet/coffee h > m | as truth | r(spill) | r(wet weight) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    t = s["truth"]
    truth = [t["humanoid"][k][0] > t["mobile"][k][0] for k in ("spill", "wet_penalty", "wet_per_coffee")]
    lines.append(f"| truth | {truth[0]} | {truth[1]} | – | {truth[2]} | – | – | – |")
    for name, o in s["orderings"].items():
        c = s["correlations"][name]
        r_spill = _f(c["spill"]["pearson"]) if "spill" in c else "–"
        lines.append(
            f"| {name} | {o['spill_humanoid_gt_mobile'] if 'GeReL⁻' not in name else '(truth)'} "
            f"| {o['wet_penalty_humanoid_gt_mobile']} | {o['wet_order_matches_truth']} "
            f"| {o['wet_per_coffee_humanoid_gt_mobile']} | {o['wet_per_coffee_order_matches_truth']} "
            f"| {r_spill} | {_f(c['wet_weight']['pearson'])} |"
        )
    lines.append("\nRecruitment\n")
    lines += ["| robot | recruited | valid | valid but answering at random | dropped |", "|---|---|---|---|---|"]
    for robot, r in s["recruitment"].items():
        dropped = "; ".join(f"{k}: {v}" for k, v in r["dropped"].items()) or "–"
        lines.append(f"| {robot} | {r['recruited']} | {r['valid']} | {r['valid_answering_at_random']} | {dropped} |")
    demos = s["ratings_by_demo"]
    lines.append("\nMean raw rating per demonstration (valid participants)\n")
    lines += ["| demonstration | mobile | humanoid |", "|---|---|---|"]
    for i, name in enumerate(demos["demos"]):
        lines.append(f"| {name} | {demos['mobile']['mean'][i]:.2f} | {demos['humanoid']['mean'][i]:.2f} |")
    return "\n".join(lines) + "\n"


def write_outputs(cfg, out: Path, study, responses, rows: list[dict]) -> dict:
    """Write ``summary.json``, ``table.md`` and the figures from the ``results.csv`` rows.

    Args:
        cfg: the study's configuration.
        out: the run folder.
        study: the demonstrations every participant saw (:class:`~mindgap.experiments.coffee.Study`).
        responses: ``{robot: [response, …]}`` of every recruit.
        rows: one row per fit, the participant's truth and answers joined in.

    Returns:
        The summary that ``summary.json`` holds (NaN there as null).
    """
    out = Path(out)
    summary = summarise(cfg, study, responses, rows)
    atomic_write(out / "summary.json", json.dumps(_nan_to_none(summary), indent=2))
    atomic_write(out / "table.md", summary["table_md"])

    groups: dict = defaultdict(lambda: defaultdict(list))
    for r in rows:
        groups[_fit_label(r["method"], r["belief_param"])][r["robot"]].append(r)
    valid = {robot: [r.participant for r in rs if r.valid] for robot, rs in responses.items()}
    truth = {
        robot: {
            "coffee": [p.coffee_weight for p in ps],
            "wet": [p.wet_weight for p in ps],
            "ratio": [-p.wet_weight / p.coffee_weight for p in ps],
            "spill": [p.spill for p in ps],
        }
        for robot, ps in valid.items()
    }
    save_learned_values(out / "fig12.png", {k: dict(v) for k, v in groups.items()}, truth)
    d = summary["ratings_by_demo"]
    save_ratings_by_demo(
        out / "ratings_by_demo.png",
        d["demos"],
        {robot: np.asarray(d[robot]["mean"]) for robot in ROBOTS},
        {robot: np.asarray(d[robot]["std"]) for robot in ROBOTS},
    )
    for robot in ROBOTS:  # the demonstrations depend on the configuration only: drawn once per run folder
        folder = out / "demos" / robot
        folder.mkdir(parents=True, exist_ok=True)
        for k, t in enumerate(study.traces):
            path = folder / f"{k + 1}-{t.name}.png"
            if not path.exists():
                save_demo_strip(path, t.states, t.actions, robot, f"Demonstration {k + 1}")
    return summary
