"""Experiment ``eps``: EPS vs SAC vs DRLHP vs Policy Shaping on d1–d4 (dissertation §4.4, Tables 3–4, Figs. 27–30).

On each world the simulated person (the world's belief: slippery ice, falls likelier near
the pit, easy sand; π_H trained in it) answers "which segment is more expected?". EPS
learns from those answers with λ (default 2 in every world); DRLHP optimises the learned
u_H alone; SAC optimises the task reward; Policy Shaping multiplies the SAC and DRLHP
policies of each seed. EPS also learns from an *unbiased* person (belief = truth, Fig. 29).
Every learner runs the same schedule (:func:`~.eps_common.learners`), one job per (world,
learner) with its seeds vmapped.

Outputs in the run folder:

* ``results.csv``: per world and method, over seeds: the return of ``rollouts`` stochastic
  episodes per seed (Table 3) and their explicability score (Table 4; its dynamics and
  policy parts), the greedy policy's return, goal rate, terrain shares, mean pit distance
  and ``required_route`` (the share of seeds on the route the world file's ``[expect] eps_route`` asks of EPS, §4.4.1:
  :func:`~.eps_common.required_route`);
* ``person.csv``: per world, the person's expected policy π_H run in the real world (what
  obeying the person earns, and its explicability — the most a policy can have there);
* ``curves.csv``: method, world, seed, step, return (greedy, true reward), queries shown;
* ``table.md`` (Tables 3 and 4), ``summary.json`` (rows, the claims as measured);
* ``trajectories.png`` (Fig. 27: per world, the person's expected routes and each method's
  greedy routes), ``surrogate_WORLD.png`` (Fig. 28: EPS's learned u_H), ``unbiased.png``
  (Fig. 29: EPS with an unbiased person, routes and return beside SAC's),
  ``curves_WORLD.png`` (Fig. 30: EPS vs SAC learning curves).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..plotting.learning import save_learning_curves
from ..plotting.terrain import METHOD_COLOURS, save_fields, save_panels
from . import eps_common as ec
from . import prefbias_common as pc
from . import world_measures as wm
from ._runfolder import to_jsonable, write_csv

METHODS = ("eps", "sac", "drlhp", "shaping")
"""Table columns, in the dissertation's order."""
COLOURS = {"EPS": "#2ca02c", "SAC": "#d62728", "DRLHP": "#9467bd", "Policy Shaping": "#ff7f0e"}
PERSON_COLOUR = "#1f77b4"

RETURN_SHARE = 0.9
"""EPS's return must be within 10% of SAC's (Table 3, §4.4.1: EPS trades little return for explicability)."""
UNBIASED_SHARE = 0.95
"""EPS with an unbiased person: at least 95% of SAC's return (Fig. 29)."""
MUCH_WORSE = 50.0
"""Policy Shaping is "much worse" than EPS in d3 when its return is lower by at least this
(half the goal's reward; the dissertation's gap is 275: −178.76 vs 96.80)."""


@dataclass(frozen=True)
class EPSTableConfig:
    """What ``mindgap reproduce eps`` runs."""

    worlds: tuple[str, ...] = ("d1", "d2", "d3", "d4")
    """Named worlds or world files (each needs a belief)."""
    lam: float = 2.0
    """EPS's λ in every world (the dissertation tunes it per domain in [2.0, 2.8])."""
    unbiased: bool = True
    """Also run EPS with an unbiased person (Fig. 29)."""
    coin: bool = True
    """Also run EPS on coin-flip answers: a learner that learns from the answers must be more
    explicable on the person's than on a fair coin's."""
    seeds: int = 5
    learners: ec.EPSLearners = field(default_factory=lambda: ec.learners("full"))


def preset(name: str) -> EPSTableConfig:
    """``full`` (5 seeds, 60 000 steps, 800 queries, 100 rollouts) or ``fast`` (1 seed, 1500 steps, 30 queries)."""
    if name == "full":
        return EPSTableConfig()
    if name == "fast":
        return EPSTableConfig(seeds=1, coin=False, learners=ec.learners("fast"))
    raise ValueError(f"unknown preset {name!r}: use 'fast' or 'full'")


def jobs(cfg: EPSTableConfig) -> list[pc.Job]:
    out = []
    learn = cfg.learners
    for w in cfg.worlds:
        out += [ec.person_job(w, learn), ec.sac_job(w, learn), ec.drlhp_job(w, learn), ec.shaping_job(w, learn)]
        out.append(ec.eps_job(w, learn, cfg.lam))
        if cfg.unbiased:
            out += [ec.person_job(w, learn, "unbiased"), ec.eps_job(w, learn, cfg.lam, "unbiased")]
        if cfg.coin:
            out.append(ec.eps_job(w, learn, cfg.lam, "coin"))
    return out


def run(cfg: EPSTableConfig, out: Path, **kw) -> dict:
    """Run (or resume) the experiment in ``out``; write CSV/JSON/PNG; return the summary.

    Keywords (``fresh``, ``progress``, ``assemble_only``, ``only``) as
    :func:`~.prefbias_common.run_experiment`.
    """
    return ec.run_experiment(cfg, out, jobs(cfg), write_outputs, name="eps", **kw)


def _learned(records: dict, spec: str) -> dict[str, dict]:
    """A world's learner records by column name (eps, sac, drlhp, shaping, eps-unbiased, eps-coin)."""
    out = {}
    for r in records.values():
        if r["world"] != spec or r["method"] == "person":
            continue
        person = r["tags"].get("person", "biased")
        name = r["method"] if person == "biased" else f"{r['method']}-{person}"
        out[name] = r
    return out


def write_outputs(cfg: EPSTableConfig, out: Path, records: dict) -> dict:
    people = ec.persons(records)
    rows, curves, person_rows, claims, t3, t4 = [], [], [], [], [], []
    traj_panels, names = [], {}
    for spec in cfg.worlds:
        world = wm.experiment_world(spec, "eps")
        person = people.get((spec, "biased"))
        learned = _learned(records, spec)
        mine = {n: ec.result_row(world, r, person) for n, r in learned.items()}
        rows += list(mine.values())
        curves += [c for r in learned.values() for c in pc.curve_rows(r)]
        if person is not None:
            person_rows.append(_person_row(spec, person, people.get((spec, "unbiased"))))
        names[spec] = world.name
        t3.append([world.name] + [_cell(mine.get(m), "return") + _still(mine.get(m)) for m in METHODS])
        t4.append([world.name] + [_cell(mine.get(m), "explicability") for m in METHODS])
        claims += _claims(world, mine)
        traj_panels += _trajectory_panels(world, person, learned)
        _world_figures(out, world, learned)
    if traj_panels:
        save_panels(out / "trajectories.png", traj_panels, {**COLOURS, "person expects": PERSON_COLOUR}, ncols=5)
    _unbiased_figure(out, cfg, records)
    cols = ["method", "world", "person", "lam", "seeds", "return_mean", "return_std"]
    write_csv(out / "results.csv", rows, cols + ["explicability_mean", "explicability_std"])
    write_csv(out / "curves.csv", curves, ["method", "world", "person", "seed", "step", "return"])
    write_csv(out / "person.csv", person_rows, ["world", "obey_return", "obey_explicability"])
    labels = ["EPS", "SAC", "DRLHP", "Policy Shaping"]
    n_roll = cfg.learners.rollouts
    table_md = (
        f"eps (Table 3): return under the true reward of {n_roll} stochastic rollouts per seed, "
        f"mean ± std over {cfg.seeds} seed(s); EPS λ = {cfg.lam:g}; (k still): k seeds whose greedy rollouts "
        "mostly stop short of the goal.\n\n"
        + pc.markdown(["world"] + labels, t3)
        + "\neps (Table 4): explicability score −KL(p_A ‖ p_A^H) (Eq. 4.4) over the same rollouts "
        "(higher is more explicable; 0 is exactly what the person expects).\n\n" + pc.markdown(["world"] + labels, t4)
    )
    if person_rows:
        table_md += (
            "\nThe person's expected policy π_H run in the real world (what obeying them earns):\n\n"
            + pc.markdown(
                ["world", "return", "explicability", "EPS (unbiased person) return", "SAC return"],
                [
                    [
                        names[p["world"]],
                        pc.fmt(p["obey_return"]),
                        pc.fmt(p["obey_explicability"]),
                        *_unbiased_cells(p, rows),
                    ]
                    for p in person_rows
                ],
            )
        )
    summary = {
        "experiment": "eps",
        "config": to_jsonable(cfg),
        "results": rows,
        "person": person_rows,
        "claims": claims,
        "table_md": table_md,
    }
    pc.write_summary(out, summary)
    return summary


def _still(row: dict | None) -> str:
    """`` (k still)`` where k > 0 seeds are held still short of the goal (:func:`~.world_measures.held_still_seeds`)."""
    n = None if row is None else row.get("held_still")
    return f" ({n} still)" if n else ""


def _cell(row: dict | None, name: str) -> str:
    return "–" if row is None else pc.fmt(row[f"{name}_mean"], row[f"{name}_std"])


def _person_row(spec: str, person: dict, unbiased: dict | None) -> dict:
    """person.csv's row of a world (``spec``, as results.csv names it)."""
    row = {
        "world": spec,
        "obey_return": person["obey_return"],
        "obey_stochastic_return": person["obey_stochastic_return"],
        "obey_explicability": person["obey_explicability"],
        "plan_return": person["plan_return"],
        "optimal_pit_mean": (person.get("optimal") or {}).get("pit_mean"),
        "expected_pit_mean": (person.get("expected") or {}).get("pit_mean"),
    }
    if unbiased is not None:
        row["unbiased_obey_return"] = unbiased["obey_return"]
    return row


def _unbiased_cells(person_row: dict, rows: list[dict]) -> list[str]:
    def find(method, who):
        hit = [
            r for r in rows if r["world"] == person_row["world"] and r["method"] == method and r.get("person") == who
        ]
        return pc.fmt(hit[0]["return_mean"], hit[0]["return_std"]) if hit else "–"

    return [find("eps", "unbiased"), find("sac", "biased")]


def _claims(world, mine: dict[str, dict]) -> list[dict]:
    """The claims of §4.4.1 (Tables 3–4, Figs. 27–30; l. 954, 986, 993, 1002–1004) and the project's
    coin-flip control, as measured on this world (sources by id: :data:`~.claim_sources.SOURCES`)."""
    eps, sac = mine.get("eps"), mine.get("sac")
    out = []
    if eps is not None:
        others = {m: r for m, r in mine.items() if m in METHODS and m != "eps"}
        best = max(others.values(), key=lambda r: r["explicability_mean"], default=None)
        if best is not None:
            out.append(
                pc.claim(
                    "eps/highest-explicability",
                    f"{world.name}: EPS achieves the highest explicability score of the {len(others) + 1} methods",
                    eps["explicability_mean"] > best["explicability_mean"],
                    f"EPS {eps['explicability_mean']:.1f}, best other {best['label']} {best['explicability_mean']:.1f}",
                )
            )
        want = wm.expect(world).get("eps_route")
        if want:
            out.append(
                pc.claim(
                    "eps/route",
                    f"{world.name}: EPS takes the route §4.4.1 describes for it ({want}) in most seeds",
                    eps["required_route"] > 0.5,
                    f"{pc.share(eps['required_route'])} of seeds",
                )
            )
    if eps is not None and sac is not None:
        out.append(
            _share_claim(
                "eps/return-near-sac",
                f"{world.name}: EPS follows the best performer for return",
                eps,
                sac,
                RETURN_SHARE,
            )
        )
    unb = mine.get("eps-unbiased")
    if unb is not None and sac is not None:
        out.append(
            _share_claim(
                "eps/unbiased-near-sac",
                f"{world.name}: with an unbiased person EPS's return is comparable to SAC's",
                unb,
                sac,
                UNBIASED_SHARE,
            )
        )
    coin = mine.get("eps-coin")
    if eps is not None and coin is not None:
        se = np.sqrt(eps["explicability_std"] ** 2 / eps["seeds"] + coin["explicability_std"] ** 2 / coin["seeds"])
        out.append(
            pc.claim(
                "eps/coin-control",
                f"{world.name}: EPS learns from the answers: more explicable than on coin-flip answers by ≥ 2 standard errors",
                eps["explicability_mean"] - coin["explicability_mean"] >= 2 * se,
                f"{eps['explicability_mean']:.1f} vs {coin['explicability_mean']:.1f}",
            )
        )
    shaping = mine.get("shaping")
    if wm.expect(world).get("eps_route") == "ice" and eps is not None and shaping is not None:
        gap = eps["return_mean"] - shaping["return_mean"]
        out.append(
            pc.claim(
                "eps/shaping-d3",
                f"{world.name}: Policy Shaping is considerably worse than EPS (≥ {MUCH_WORSE:g} lower return)",
                gap >= MUCH_WORSE,
                f"{shaping['return_mean']:.1f} vs {eps['return_mean']:.1f}",
            )
        )
    return out


def _share_claim(claim_id: str, statement: str, row: dict, sac: dict, share: float) -> dict:
    """``statement``, decided as: ``row``'s return is at least ``share`` of SAC's (SAC's must be
    positive for a share to mean anything)."""
    a, b = row["return_mean"], sac["return_mean"]
    held = b > 0 and a >= share * b
    ratio = f"{a / b:.0%} of SAC's" if b > 0 else "SAC's return is not positive"
    return pc.claim(
        claim_id,
        f"{statement} (within {1 - share:.0%} of SAC's return)",
        held,
        f"{a:.1f} vs {b:.1f} ({ratio})",
    )


def _trajectory_panels(world, person: dict | None, learned: dict[str, dict]) -> list:
    """Fig. 27's row for one world: the person's expected routes, then each method's greedy routes."""
    exp = [] if person is None else [np.asarray(p) for p in person["expected_paths"]]
    panels = [(f"{world.name}: person expects", world.params, {"person expects": exp} if exp else {})]
    for m in METHODS:  # one panel per method, empty where it has not run, so rows line up
        r = learned.get(m)
        trajs = {r["label"]: _flat(r["paths"])} if r is not None and r["paths"] else {}
        panels.append((f"{world.name}: {r['label'] if r else m + ' (not run)'}", world.params, trajs))
    return panels


def _world_figures(out: Path, world, learned: dict[str, dict]) -> None:
    eps = learned.get("eps")
    if eps is not None and eps.get("u_map") is not None:
        save_fields(
            out / f"surrogate_{world.name}.png",
            world.params,
            [(f"{world.name}: EPS's learned u_H (standardised, mean over seeds)", pc.map_array(eps["u_map"]))],
            label="u_H",
            vmin=None,
            cmap="viridis",
        )
    runs = {r["label"]: r["curve"] for m, r in learned.items() if m in ("eps", "sac") and r["curve"]}
    if runs:
        save_learning_curves(
            out / f"curves_{world.name}.png",
            runs,
            title=f"{world.name}: EPS vs SAC, greedy return (mean ± std over seeds)",
        )


def _unbiased_figure(out: Path, cfg: EPSTableConfig, records: dict) -> None:
    """Fig. 29: EPS's routes with an unbiased person in each world."""
    panels = []
    for spec in cfg.worlds:
        world = wm.experiment_world(spec, "eps")
        r = _learned(records, spec).get("eps-unbiased")
        if r is not None:
            panels.append((f"{world.name}: EPS, unbiased person", world.params, {"EPS (unbiased)": _flat(r["paths"])}))
    if panels:
        save_panels(out / "unbiased.png", panels, {"EPS (unbiased)": METHOD_COLOURS[2]})


def _flat(paths) -> list[np.ndarray]:
    return [np.asarray(p) for seed in paths for p in seed]
