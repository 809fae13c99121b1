"""Tables and figures of experiment ``table1`` from its result rows."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from ..plotting.curves import save_metric_curves
from ..plotting.heatmaps import save_reward_panels

METRICS = ("d_R", "d_Theta", "d_pi")
LABELS = {"gerel": "GeReL", "serd": "SERD", "gerel-minus": "GeReL⁻", "maxent-irl": "MaxEnt-IRL"}
ORDER = ("gerel", "serd", "gerel-minus", "maxent-irl")


def _ms(values):
    v = np.asarray(values, float)
    return float(v.mean()), float(v.std())


def summarise(cfg, rows, restart_rows, demo_rows) -> dict:
    """Mean ± std per (parameterisation, setting, method), target checks, basin rates."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r["belief_param"], r["setting"], r["method"])].append(r)
    stats = {}
    for (p, s, m), rs in groups.items():
        entry = {k: _ms([r[k] for r in rs]) for k in METRICS + ("corr_R", "seconds")}
        entry["n"] = len(rs)
        entry["negative_corr"] = float(np.mean([r["corr_R"] < 0 for r in rs]))
        stats[f"{p}|{s}|{m}"] = entry

    lines = []
    for p in cfg.belief_params:
        n_seeds = sorted({e["n"] for k, e in stats.items() if k.startswith(p + "|")})
        seeds = "/".join(str(n) for n in n_seeds)
        lines.append(f"\nBelief parameterisation: {p}  (mean ± std over {seeds} seeds, {cfg.demos} demonstrations)\n")
        head = "| method | " + " | ".join(f"{s} d(R) | d(Θ) | d(π)" for s in cfg.settings) + " |"
        lines += [head, "|" + "---|" * (1 + 3 * len(cfg.settings))]
        for m in ORDER:
            cells = []
            for s in cfg.settings:
                e = stats.get(f"{p}|{s}|{m}")
                for k in METRICS:
                    fmt = ".2f" if k == "d_R" else ".3f"
                    cells.append(f"{e[k][0]:{fmt}} ± {e[k][1]:{fmt}}" if e else "–")
            lines.append(f"| {LABELS[m]} | " + " | ".join(cells) + " |")

    checks = {}
    for p in cfg.belief_params:
        for s in cfg.settings:

            def mean(m, k, p=p, s=s):
                e = stats.get(f"{p}|{s}|{m}")
                return e[k][0] if e else float("nan")

            key = f"{p}|{s}"
            checks[key] = {
                "gerel_lowest_" + k: all(mean("gerel", k) < mean(m, k) for m in ORDER if m != "gerel") for k in METRICS
            }
            checks[key]["gerel_beats_minus_and_maxent"] = all(
                mean("gerel", k) < min(mean("gerel-minus", k), mean("maxent-irl", k)) for k in METRICS
            )
            checks[key]["unaware_corr_negative"] = bool(
                mean("gerel-minus", "corr_R") < 0 and mean("maxent-irl", "corr_R") < 0
            )
            if p == "tied":
                checks[key]["tied_d_Theta<=0.10"] = mean("gerel", "d_Theta") <= 0.10
                checks[key]["tied_d_pi<=0.25"] = mean("gerel", "d_pi") <= 0.25

    basins = {}
    by = defaultdict(list)
    for r in restart_rows:
        by[(r["belief_param"], r["setting"])].append(r)
    for (p, s), rs in by.items():
        chosen = [r for r in rs if r["chosen"]]
        basins[f"{p}|{s}"] = {
            "restarts_right_basin": float(np.mean([r["corr_R"] > 0 for r in rs])),
            "chosen_right_basin": float(np.mean([r["corr_R"] > 0 for r in chosen])) if chosen else float("nan"),
            "restarts": len(rs),
        }
    lines.append("\nRight basin (learned reward positively correlated with the truth), GeReL:\n")
    lines += ["| param | setting | share of restarts | share of chosen fits |", "|---|---|---|---|"]
    for k, b in sorted(basins.items()):
        p, s = k.split("|")
        lines.append(f"| {p} | {s} | {b['restarts_right_basin']:.2f} | {b['chosen_right_basin']:.2f} |")

    demo = defaultdict(list)
    for r in demo_rows:
        demo[(r["setting"], r["method"], r["n_demos"])].append(r)
    demo_stats = {f"{s}|{m}|{n}": {k: _ms([r[k] for r in rs]) for k in METRICS} for (s, m, n), rs in demo.items()}
    if demo_stats:
        lines.append("\nData efficiency (tied belief; d(R) / d(Θ) / d(π), mean over seeds):\n")
        counts = sorted({r["n_demos"] for r in demo_rows})
        lines += [
            "| setting | method | " + " | ".join(str(n) for n in counts) + " |",
            "|---|---|" + "---|" * len(counts),
        ]
        for s in cfg.settings:
            for m in ORDER:
                cells = []
                for n in counts:
                    e = demo_stats.get(f"{s}|{m}|{n}")
                    cells.append(" / ".join(f"{e[k][0]:.2f}" for k in METRICS) if e else "–")
                lines.append(f"| {s} | {LABELS[m]} | " + " | ".join(cells) + " |")
    return {
        "stats": stats,
        "checks": checks,
        "basins": basins,
        "demo_counts": demo_stats,
        "table_md": "\n".join(lines) + "\n",
    }


def _step_interp(x_grid, xs, ys):
    """Value of a step function (last value at or before x) on ``x_grid``."""
    idx = np.searchsorted(xs, x_grid, side="right") - 1
    return np.asarray(ys)[np.clip(idx, 0, len(ys) - 1)]


def render_figures(cfg, out: Path, rows, curve_rows, demo_rows, tasks: dict, priors: dict) -> None:
    """Reward heatmaps, metric curves over iterations and over demonstration counts, per setting.

    Args:
        cfg: the experiment's configuration (settings, belief parameterisations).
        out: the run folder.
        rows: ``results.csv`` rows (``w`` the learned weights as text).
        curve_rows: ``curves.csv`` rows, metrics per iteration.
        demo_rows: ``demo_counts.csv`` rows.
        tasks: ``{setting: GridTask}``, seed 0's grid of each setting (the reward heatmaps).
        priors: ``{(setting, param): metrics}`` of the untrained fit (a line in the curves).
    """
    out = Path(out)
    for s in cfg.settings:
        task = tasks[s]
        feats = np.asarray(task.mdp.features)
        panels = [("true R_H", feats @ np.asarray(task.true_weights))]
        for m in ORDER:
            r = next(
                (
                    r
                    for r in rows
                    if r["setting"] == s
                    and r["seed"] == 0
                    and r["method"] == m
                    and r["belief_param"] == cfg.belief_params[0]
                ),
                None,
            )
            if r is not None:
                panels.append((LABELS[m], feats @ np.array([float(x) for x in r["w"].split()])))
        save_reward_panels(out / f"rewards_{s}.png", panels, cfg.size)

        for p in cfg.belief_params:
            curves = {}
            for m in ORDER:
                rs = [c for c in curve_rows if c["setting"] == s and c["belief_param"] == p and c["method"] == m]
                if not rs:
                    continue
                seeds = sorted({c["seed"] for c in rs})
                grid = np.unique([c["iteration"] for c in rs])
                per = {k: [] for k in METRICS}
                for sd in seeds:
                    cs = sorted((c for c in rs if c["seed"] == sd), key=lambda c: c["iteration"])
                    xs = np.array([c["iteration"] for c in cs])
                    for k in METRICS:
                        per[k].append(_step_interp(grid, xs, [c[k] for c in cs]))
                curves[LABELS[m]] = {k: (grid, np.mean(per[k], 0), np.std(per[k], 0)) for k in METRICS}
            if curves:
                save_metric_curves(
                    out / f"curves_{s}_{p}.png",
                    curves,
                    METRICS,
                    "iteration",
                    prior=priors[(s, p)],
                    title=f"{s} belief, {p} parameterisation",
                )

        curves = {}
        for m in ORDER:
            rs = [r for r in demo_rows if r["setting"] == s and r["method"] == m]
            if not rs:
                continue
            ns = sorted({r["n_demos"] for r in rs})
            curves[LABELS[m]] = {
                k: (
                    np.array(ns),
                    np.array([np.mean([r[k] for r in rs if r["n_demos"] == n]) for n in ns]),
                    np.array([np.std([r[k] for r in rs if r["n_demos"] == n]) for n in ns]),
                )
                for k in METRICS
            }
        if curves:
            save_metric_curves(
                out / f"demo_counts_{s}.png",
                curves,
                METRICS,
                "demonstrations",
                logx=True,
                title=f"{s} belief, tied parameterisation",
            )
