"""Learning a reward from recorded preferences: ``mindgap pebble|drlhp --world W --preferences FILE``.

The answers of a preference study (a :mod:`preferences file <.prefs_file>`) train the same
reward ensemble PEBBLE and DRLHP train online (:mod:`mindgap.models.reward_ensemble`,
Bradley–Terry cross-entropy, Eq. 3.1): all recorded pairs are added at once with
``prefs_add`` and ``train_reward`` takes ``max(updates, 1000)`` Adam steps. Nothing is
asked of a simulated person; the world is needed only to draw the result and to score
the recorded pairs under its own reward, which says how far the people's answers and
the learned reward agree with what the world rewards.

Writes to ``--out``: ``reward.png`` (the learned reward over the map, the mean over
eight push directions at each point), ``reward.npz`` (the ensemble's parameters,
:func:`mindgap.checkpoint.save_pytree`) and ``summary.json``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

OFFLINE_UPDATES = 1000


def fit_preferences(prefs, reward_cfg, *, seed: int = 0):
    """Train a reward ensemble on every record of ``prefs``.

    Returns:
        (RewardState, final loss, accuracy of the ensemble mean on the records).
    """
    import jax
    import jax.numpy as jnp

    from .. import rng
    from ..data.prefs import prefs_add, prefs_init
    from ..data.segments import Segments
    from ..models.reward_ensemble import reward_init, train_reward

    seg_a, seg_b, labels = prefs.arrays()
    n = len(labels)
    data = prefs_init(n, prefs.segment, prefs.obs_dim, prefs.act_dim)

    def segs(s):
        return Segments(*(jnp.asarray(s[k]) for k in ("obs", "act", "next_obs", "mask")))

    data = prefs_add(data, segs(seg_a), segs(seg_b), jnp.asarray(labels), jnp.ones(n, bool))
    k_init, k_train = jax.random.split(rng.key(seed))
    state = reward_init(k_init, prefs.obs_dim, prefs.act_dim, reward_cfg)
    state, loss, acc = jax.jit(train_reward, static_argnames="cfg")(state, data, k_train, reward_cfg)
    return state, float(loss), float(acc)


def reward_field(params, reward_params, per_cell: int = 6) -> np.ndarray:
    """The learned reward at ``per_cell²`` points per cell, mean over 8 pushes: [h·k, w·k]."""
    import jax.numpy as jnp

    from ..models.reward_ensemble import ensemble_reward

    h, w = np.asarray(params.grid).shape
    k = per_cell
    ys, xs = np.meshgrid((np.arange(h * k) + 0.5) / k, (np.arange(w * k) + 0.5) / k, indexing="ij")
    pos = np.stack([xs.ravel(), ys.ravel()], -1)
    obs = 2.0 * pos / np.array([w, h]) - 1.0
    angles = np.arange(8) * np.pi / 4
    total = np.zeros(len(obs))
    for a in angles:
        act = np.tile(0.8 * np.array([np.cos(a), np.sin(a)]), (len(obs), 1))
        total += np.asarray(
            ensemble_reward(reward_params, jnp.asarray(obs, jnp.float32), jnp.asarray(act, jnp.float32), None)
        )
    return (total / len(angles)).reshape(h * k, w * k)


def save_reward_map(path: Path, params, field: np.ndarray, title: str) -> None:
    import matplotlib.pyplot as plt

    from ..envs.terrain.layout import WALL
    from ..plotting.terrain import draw_world

    grid = np.asarray(params.grid)
    h, w = grid.shape
    k = field.shape[0] // h
    wall = np.repeat(np.repeat(grid == WALL, k, 0), k, 1)
    vmax = float(np.abs(field).max()) or 1.0
    fig, ax = plt.subplots(figsize=(0.45 * w + 1.4, 0.45 * h + 0.8))
    draw_world(ax, params)
    im = ax.imshow(np.ma.masked_where(wall, field), extent=(0, w, h, 0), cmap="RdBu", vmin=-vmax, vmax=vmax, alpha=0.8)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label="learned reward")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)


def run_offline(args) -> int:
    """``mindgap pebble|drlhp --world W --preferences FILE --out DIR [--seed S]``."""
    import jax.numpy as jnp

    from .._io import atomic_write
    from ..algorithms.pbrl import method_config
    from ..checkpoint import save_pytree
    from ..data.segments import Segments
    from ..envs.terrain import load_world
    from ..models.reward_ensemble import segment_returns
    from .items import true_returns
    from .prefs_file import read_preferences

    prefs = read_preferences(args.preferences)
    world = load_world(args.env)
    recorded = prefs.domain.get("world")
    if recorded and recorded != world.name and Path(recorded).stem != world.name:
        raise ValueError(f"{args.preferences} was recorded on world {recorded!r}; pass --env {recorded}")
    if (prefs.obs_dim, prefs.act_dim) != (2, 2):
        raise ValueError(
            f"{args.preferences}: terrain worlds have 2-D observations and actions, the file has {prefs.obs_dim}, {prefs.act_dim}"
        )
    cfg = method_config(args.command).reward
    cfg = dataclasses.replace(cfg, updates=max(cfg.updates, OFFLINE_UPDATES))
    state, loss, acc = fit_preferences(prefs, cfg, seed=args.seed)

    seg_a, seg_b, labels = prefs.arrays()
    decided = labels != 0.5

    def segs(s):
        return Segments(*(jnp.asarray(s[k]) for k in ("obs", "act", "next_obs", "mask")))

    learned = np.asarray(segment_returns(state.params, segs(seg_a)) - segment_returns(state.params, segs(seg_b))).mean(
        0
    )
    true_diff = true_returns(world.params, seg_a) - true_returns(world.params, seg_b)
    clear = decided & (true_diff != 0)
    summary = {
        "method": f"{args.command} (offline reward from preferences)",
        "world": world.name,
        "preferences": str(args.preferences),
        "protocol": prefs.protocol,
        "records": int(len(labels)),
        "participants": len({r.get("participant") for r in prefs.records}),
        "answers": {k: int(np.sum(labels == v)) for k, v in (("a", 1.0), ("b", 0.0), ("equal", 0.5))},
        "train_accuracy": acc,
        "final_loss": loss,
        "updates": cfg.updates,
        "answers_agree_with_world_reward": float(np.mean((labels[clear] > 0.5) == (true_diff[clear] > 0)))
        if clear.any()
        else None,
        "learned_agrees_with_world_reward": float(np.mean((learned[clear] > 0) == (true_diff[clear] > 0)))
        if clear.any()
        else None,
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_pytree(out / "reward.npz", state.params)
    field = reward_field(world.params, state.params)
    save_reward_map(
        out / "reward.png", world.params, field, f"{world.name}: reward learned from {len(labels)} recorded answers"
    )
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    print(
        f"reward learned from {summary['records']} answers of {summary['participants']} participant(s): "
        f"training accuracy {acc:.2f}; reward.png, reward.npz, summary.json in {out}/"
    )
    return 0
