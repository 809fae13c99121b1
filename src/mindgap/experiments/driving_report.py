"""The driving experiment's outputs (§4.4.2): Table 5 beside the dissertation's, the behaviours, Figs. 34–36.

Written from the job records of :mod:`~.driving` (``mindgap reproduce driving --assemble``
rewrites them without running anything). The frames and animations replay each method's
first seed in the highway-env version of the scenario (:mod:`~mindgap.envs.driving.highway`,
``pip install "mindgap[driving]"``): the greedy policy acts on that env's observations (the
JAX world's layout), the front car starts braking at the first decision it may. Without
highway-env the figures are skipped and the run says so.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

from . import prefbias_common as pc
from ._runfolder import to_jsonable, write_csv

METHODS = ("eps", "sac", "drlhp")
LABELS = {"eps": "EPS", "sac": "SAC", "drlhp": "DRLHP", "drlhp-coin": "DRLHP, coin flips"}
PAPER = {"eps": (7.6, 11.0), "sac": (5.0, 11.9), "drlhp": (5.9, 9.6)}
"""Table 5: (average rating, average return) of each method in the study."""
WORLD = "driving"
CONTROL = "drlhp-coin"
"""The control: DRLHP on answers that are fair coins (Bradley–Terry at β = 0), everything else as DRLHP's."""
COIN = f"{WORLD}/{CONTROL}"
"""The control's job key."""

BEHAVIOURS = ("collided", "changed", "first_change", "braked_first", "min_gap")


def _ms(values) -> tuple[float, float]:
    v = np.asarray([np.nan if x is None else x for x in values], np.float64)
    if not np.isfinite(v).any():
        return float("nan"), float("nan")
    return float(np.nanmean(v)), float(np.nanstd(v))


def write_outputs(cfg, out: Path, records: dict, *, world_of, load_actors) -> dict:
    """Table 5, the behaviours, claims and figures of the experiment ``cfg`` (a
    :class:`~.driving.DrivingConfig`) from its job records. ``world_of(cfg, weights)`` and
    ``load_actors(folder, key, world, cfg, seeds)`` are :mod:`~.driving`'s, passed in so that this
    module does not import it back."""
    out = Path(out)
    people = records.get(f"{WORLD}/people")
    testing = records.get(f"{WORLD}/testing")
    rows, curves = [], []
    valid_ratings = [r for r in (testing or {}).get("ratings", []) if r["valid"]]
    for m in (*METHODS, CONTROL):
        rec = records.get(f"{WORLD}/{m}")
        if rec is None:
            continue
        row = {"method": m, "label": LABELS[m], "seeds": rec["seeds"]}
        row["return_mean"], row["return_std"] = _ms(rec["return"])
        for b in BEHAVIOURS:
            row[f"{b}_mean"], row[f"{b}_std"] = _ms(rec[b])
        row["seeds_braking_first"] = int(np.sum(np.asarray([x or 0.0 for x in rec["braked_first"]]) > 0.5))
        mine = [r["rating"] for r in valid_ratings if r["method"] == m]
        row["rating_mean"], row["rating_std"] = (
            (float(np.mean(mine)), float(np.std(mine))) if mine else (np.nan, np.nan)
        )
        row["paper_rating"], row["paper_return"] = PAPER.get(m, (np.nan, np.nan))
        rows.append(row)
        curves += pc.curve_rows(rec)
    by = {r["method"]: r for r in rows}
    write_csv(out / "results.csv", rows, ["method", "seeds", "rating_mean", "rating_std", "return_mean", "return_std"])
    write_csv(out / "curves.csv", curves, ["method", "world", "seed", "step", "return"])
    if people is not None:
        write_csv(out / "participants.csv", people["participants"], ["pid", "attentive", "believed_sleet", "dropped"])
    if testing is not None:
        write_csv(out / "ratings.csv", testing["ratings"], ["rater", "valid", "method", "seed", "episode", "rating"])
    claims = _claims(by)
    table_md = _table(cfg, by, people, testing)
    figures = _figures(cfg, out, records, people, world_of, load_actors)
    summary = {
        "experiment": "driving",
        "config": to_jsonable(cfg),
        "results": rows,
        "people": None
        if people is None
        else {k: people[k] for k in ("valid", "recruits", "bias_effective", "engineered_weights")},
        "claims": claims,
        "figures": figures,
        "table_md": table_md,
    }
    pc.write_summary(out, summary)
    return summary


def _table(cfg, by: dict, people: dict | None, testing: dict | None) -> str:
    cols = [m for m in METHODS if m in by]
    head = ["", *(LABELS[m] for m in cols)]
    t5 = [
        ["avg. rating (ours)", *(pc.fmt(by[m]["rating_mean"], by[m]["rating_std"]) for m in cols)],
        ["avg. rating (dissertation)", *(f"{PAPER[m][0]:.1f}" for m in cols)],
        ["avg. return (ours)", *(pc.fmt(by[m]["return_mean"], by[m]["return_std"]) for m in cols)],
        ["avg. return (dissertation)", *(f"{PAPER[m][1]:.1f}" for m in cols)],
    ]
    raters = "–" if testing is None else sum(1 for r in testing["raters"] if not r["dropped"])
    md = (
        f"driving (Table 5): rating 1–10 by {raters} new simulated participants (mean ± std over ratings) and "
        f"return under r_A of {cfg.rollouts} greedy episodes per seed (mean ± std over {cfg.seeds} seed(s)), "
        f"sleet {cfg.sleet:g}; EPS λ = {cfg.eps.lam:g}.\n\n" + pc.markdown(head, t5)
    )
    shown = [*cols, *([CONTROL] if CONTROL in by else [])]  # the control beside the methods
    beh = [[name, *(cell(by[m]) for m in shown)] for name, cell in BEHAVIOUR_ROWS]
    md += "\ndriving behaviours (Figs. 34–36), mean over seeds of each seed's greedy episodes:\n\n" + pc.markdown(
        ["", *(LABELS[m] for m in shown)], beh
    )
    if people is not None:
        md += (
            f"\nTraining phase: {people['valid']} valid participants of {people['recruits']} recruits; "
            f"{people['bias_effective']} of {people['valid']} expect braking on sleet to work as on a dry road "
            "(the study: 12 of 14); r_A's weights from their average answers: "
            + ", ".join(f"{w:.3f}" for w in people["engineered_weights"])
            + ".\n"
        )
    return md


BEHAVIOUR_ROWS = (
    ("collision rate", lambda row: pc.share(row["collided_mean"])),
    ("episodes with a lane change", lambda row: pc.share(row["changed_mean"])),
    ("first lane change (decisions after the front car brakes)", lambda row: pc.fmt(row["first_change_mean"])),
    ("braked before changing lane", lambda row: pc.share(row["braked_first_mean"])),
    ("smallest gap to the front car, in line with it [m]", lambda row: pc.fmt(row["min_gap_mean"])),
    ("seeds braking first (in most of their episodes)", lambda row: f"{row['seeds_braking_first']} of {row['seeds']}"),
)
"""The behaviours table's rows: (label, the cell of one method's results row)."""


def _claims(by: dict) -> list[dict]:
    """§4.4.2.1's claims (Table 5 and Figs. 34–36; l. 1081–1087) and the project's coin-flip control,
    as measured (sources by id: :data:`~.claim_sources.SOURCES`). "Significantly lower" (DRLHP's
    return, l. 1087) is checked as the lowest: the rule is weaker than the words."""
    out = []
    if "drlhp" in by and CONTROL in by:
        a, c = by["drlhp"], by[CONTROL]
        out.append(
            pc.claim(
                "driving/control",
                "driving: DRLHP follows the answers: it brakes first in most seeds on the participants' answers "
                "(≥ 4 of 5) and in few on coin flips (≤ 1 of 5)",
                a["seeds_braking_first"] >= 0.8 * a["seeds"] and c["seeds_braking_first"] <= 0.2 * c["seeds"],
                f"answers {a['seeds_braking_first']} of {a['seeds']} seeds, coin flips "
                f"{c['seeds_braking_first']} of {c['seeds']}",
            )
        )
    if all(m in by for m in METHODS):
        r = {m: by[m]["rating_mean"] for m in METHODS}
        g = {m: by[m]["return_mean"] for m in METHODS}
        out.append(
            pc.claim(
                "driving/eps-rated-highest",
                "driving: the new participants rate EPS the most preferable (the highest average rating)",
                r["eps"] > max(r["sac"], r["drlhp"]),
                ", ".join(f"{LABELS[m]} {r[m]:.1f}" for m in METHODS),
            )
        )
        out.append(
            pc.claim(
                "driving/sac-highest-return",
                "driving: under the reward from the training phase SAC performs best (the highest return)",
                g["sac"] > max(g["eps"], g["drlhp"]),
                ", ".join(f"{LABELS[m]} {g[m]:.1f}" for m in METHODS),
            )
        )
        out.append(
            pc.claim(
                "driving/drlhp-lowest-return",
                "driving: DRLHP obtains a lower return than the other two (the lowest)",
                g["drlhp"] < min(g["eps"], g["sac"]),
                ", ".join(f"{LABELS[m]} {g[m]:.1f}" for m in METHODS),
            )
        )
        fc = {m: by[m]["first_change_mean"] for m in METHODS}
        out.append(
            pc.claim(
                "driving/sac-steers-first",
                "driving: SAC steers at once when the front car slows down (the earliest first lane change, "
                "changing lane in most episodes)",
                np.isfinite(fc["sac"])
                and by["sac"]["changed_mean"] > 0.5
                # strictly: a tie is not "first"; never changing lane (NaN) is later
                and all(not fc[m] <= fc["sac"] for m in ("eps", "drlhp")),
                ", ".join(f"{LABELS[m]} {fc[m]:.1f} ({pc.share(by[m]['changed_mean'])} change)" for m in METHODS),
            )
        )
        gap, col = {m: by[m]["min_gap_mean"] for m in METHODS}, {m: by[m]["collided_mean"] for m in METHODS}
        out.append(
            pc.claim(
                "driving/drlhp-brakes-in-lane",
                "driving: DRLHP brakes while staying in its lane and gets dangerously close to the front car "
                "(closest to it, or colliding most)",
                # braking in lane: braking before any lane change, or staying in lane, in most episodes
                (by["drlhp"]["braked_first_mean"] > 0.5 or by["drlhp"]["changed_mean"] < 0.5)
                and all(gap["drlhp"] < gap[m] or col["drlhp"] > col[m] for m in ("eps", "sac")),
                f"DRLHP braked first {pc.share(by['drlhp']['braked_first_mean'])}, "
                f"stayed in lane {pc.share(1 - by['drlhp']['changed_mean'])}; "
                + ", ".join(f"{LABELS[m]} gap {gap[m]:.1f} m, collisions {pc.share(col[m])}" for m in METHODS),
            )
        )
        out.append(
            pc.claim(
                "driving/eps-brakes-then-steers",
                "driving: EPS first brakes, then steers to the other lane (in most episodes)",
                by["eps"]["braked_first_mean"] > 0.5 and by["eps"]["changed_mean"] > 0.5,
                f"braked first {pc.share(by['eps']['braked_first_mean'])}, changed lane {pc.share(by['eps']['changed_mean'])}",
            )
        )
    return out


# ---------------------------------------------------------------------------------------
# Figs. 34–36 through highway-env


def highway_version(cfg, weights):
    """The highway-env version of the run's road (its sleet and other cars, r_A's ``weights``) that draws
    the figures; it needs ``highway-env`` (the ``driving`` extra)."""
    from ..envs.driving.highway import SleetHighwayEnv

    return SleetHighwayEnv(
        render_mode="rgb_array", sleet=cfg.sleet, traffic=cfg.traffic, weights=np.asarray(weights, np.float32)
    )


def _figures(cfg, out: Path, records: dict, people: dict | None, world_of, load_actors) -> list[str]:
    if people is None:
        return []
    try:
        import highway_env  # noqa: F401

        from ..envs.driving.highway import save_animation
    except ImportError:
        print("highway-env is not installed: no frames or animations (pip install 'mindgap[driving]')")
        return []
    from ..algorithms.sac_loop import greedy_policy

    world = world_of(cfg, people["engineered_weights"])
    folder = _Folder(out)
    made = []
    for m in METHODS:
        rec = records.get(f"{WORLD}/{m}")
        if rec is None:
            continue
        actor = jax.tree.map(lambda a: a[0], load_actors(folder, f"{WORLD}/{m}", world, cfg, rec["seeds"]))
        env = highway_version(cfg, people["engineered_weights"])
        env.record()
        policy = jax.jit(lambda o, actor=actor: greedy_policy(world.env)(actor, o))
        obs, _ = env.reset(seed=cfg.eps.seed, options={"onset": int(world.params.brake_first)})
        done, t = False, 0
        decisions = []
        while not done:
            a = int(np.asarray(policy(np.asarray(obs, np.float32)))[0])
            decisions.append(a)
            obs, _, term, trunc, info = env.step(a)
            t += 1
            done = term or trunc
        frames = env.frames
        per = (len(frames) - 1) // max(t, 1)
        onset = int(world.params.brake_first)
        picks = _characteristic(decisions, onset, t)
        idx = [min(len(frames) - 1, k * per) for _, k in picks]
        save_animation(frames, out / f"episode_{m}.gif")
        _save_frames(
            out / f"frames_{m}.png",
            [frames[i] for i in idx],
            [w for w, _ in picks],
            f"{LABELS[m]} ({_rating(records, m)})",
        )
        env.close()
        made += [f"frames_{m}.png", f"episode_{m}.gif"]
    return made


class _Folder:
    """What :func:`~.driving._load_actors` reads of a run folder: its root."""

    def __init__(self, root: Path):
        self.root = Path(root)


def _rating(records: dict, m: str) -> str:
    testing = records.get(f"{WORLD}/testing")
    if testing is None:
        return "not rated yet"
    r = [x["rating"] for x in testing["ratings"] if x["valid"] and x["method"] == m]
    return f"rating μ = {np.mean(r):.1f}, σ = {np.std(r):.1f}" if r else "not rated"


def _characteristic(decisions: list[int], onset: int, steps: int) -> list[tuple[str, int]]:
    """Three moments (label, decision step): the front car brakes; the car's first response after it
    (its first action other than IDLE); the end of the episode."""
    after = [k for k in range(onset, len(decisions)) if decisions[k] != 1]
    first = after[0] + 1 if after else min(onset + 2, steps)
    names = {0: "changes lane", 2: "changes lane", 3: "speeds up", 4: "brakes"}
    what = names.get(decisions[after[0]], "acts") if after else "keeps going"
    return [("front car brakes", onset), (f"car {what}", first), ("end", steps)]


def _save_frames(path: Path, frames: list, titles: list[str], suptitle: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(frames), 1, figsize=(7, 1.6 * len(frames)))
    for ax, f, t in zip(np.atleast_1d(axes), frames, titles):
        ax.imshow(np.asarray(f))
        ax.set_title(t, fontsize=9)
        ax.axis("off")
    fig.suptitle(suptitle, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
