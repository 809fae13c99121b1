"""Parameterisations of a person's believed dynamics ``Θ`` (§2.2.1, §2.2.2).

A :class:`BeliefSpace` maps ``F`` categorical *factors* with up to ``M`` outcomes each
onto a full ``[S, A, S]`` transition tensor:
``T(s'|s, a) = Σ_m θ[factor(s, a), m] · [s' = target(s, a, m)]``.

- **per-(s,a)** (the dissertation's form): one factor per state-action pair over the
  states reachable in one step under the true dynamics (from that state, any action)
  plus staying; ``full=True`` puts every state in the support.
- **tied**: one factor per action over relative moves shared by all states ("Up moves
  the robot down"); needs the domain's move table.
- **factored**: a few named probabilities of a factored domain, each a Beta (or
  Dirichlet) shared by every pair it governs (the coffee robot's spill probability
  when holding coffee and umbrella); every other pair keeps its true, deterministic
  next state through one fixed single-outcome factor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from . import dirichlet


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class BeliefSpace:
    """How belief factors ``θ`` ``[F, M]`` expand to transitions (a pytree; ``kind`` is static).

    Attributes:
        factor: ``[S, A]`` int, which factor governs ``(s, a)``.
        targets: ``[S, A, M]`` int, next state of outcome ``m`` of that factor at ``(s, a)``.
        mask: ``[F, M]`` bool, which outcomes exist.
        kind: ``"tied"``, ``"per-sa"``, ``"full"`` or ``"factored"`` (static metadata).
    """

    factor: jnp.ndarray
    targets: jnp.ndarray
    mask: jnp.ndarray
    kind: str = field(metadata=dict(static=True))

    @property
    def n_factors(self) -> int:
        return self.mask.shape[0]

    def to_transitions(self, theta) -> jnp.ndarray:
        """Expand ``θ`` ``[..., F, M]`` to ``T`` ``[..., S, A, S]``."""
        theta = jnp.asarray(theta)
        n_s, n_a, _ = self.targets.shape
        per_sa = self.to_sparse(theta)
        onehot_idx = self.targets
        out = jnp.zeros(theta.shape[:-2] + (n_s, n_a, n_s), theta.dtype)
        s_idx = jnp.arange(n_s)[:, None, None]
        a_idx = jnp.arange(n_a)[None, :, None]
        return out.at[..., s_idx, a_idx, onehot_idx].add(per_sa)

    def to_sparse(self, theta) -> jnp.ndarray:
        """``θ`` ``[..., F, M]`` as successor probabilities ``[..., S, A, M]`` on :attr:`targets`."""
        return theta[..., self.factor, :] * self.mask[self.factor]

    def successor_form(self, theta) -> tuple[jnp.ndarray, jnp.ndarray]:
        """``θ`` ``[..., F, M]`` as ``(probs, successors)`` for :func:`mindgap.planning.sparse_q_values`.

        The same dynamics as :meth:`to_transitions` without the dense tensor:

        - ``tied``: ``probs [..., 1, A, M]`` (one distribution per action, shared by every
          state) on ``successors [S, M]``;
        - ``per-sa``: ``probs [..., S, A, M]`` on ``successors [S, M]`` (a pair's support is
          the states reachable from its state, whatever the action);
        - ``factored`` and ``full``: ``probs [..., S, A, M]`` on ``successors [S, A, M]``.
        """
        if self.kind == "tied":
            # tied() gives factor[s, a] = a at every state
            return (theta[..., self.factor[0], :] * self.mask[self.factor[0]])[..., None, :, :], self.targets[:, 0]
        if self.kind == "per-sa":
            return self.to_sparse(theta), self.targets[:, 0]
        return self.to_sparse(theta), self.targets

    def from_transitions(self, transitions) -> np.ndarray:
        """Project a tensor onto the factors: ``θ`` ``[F, M]`` (averaged over tied pairs).

        Mass outside a factor's support is dropped and the rest renormalised.
        """
        t = np.asarray(transitions, np.float64)
        factor = np.asarray(self.factor)
        targets = np.asarray(self.targets)
        mask = np.asarray(self.mask)
        theta = np.zeros(mask.shape)
        counts = np.zeros(mask.shape[0])
        n_s, n_a, n_m = targets.shape
        distinct = np.array(
            [
                [len(set(targets[s, a, mask[factor[s, a]]])) == mask[factor[s, a]].sum() for a in range(n_a)]
                for s in range(n_s)
            ]
        )
        has_distinct = np.zeros(mask.shape[0], bool)
        np.logical_or.at(has_distinct, factor[distinct], True)
        for s in range(n_s):
            for a in range(n_a):
                f = factor[s, a]
                if has_distinct[f] and not distinct[s, a]:
                    continue  # tied factors are read off cells away from walls
                row = t[s, a].copy()
                vals = np.zeros(n_m)
                for m in range(n_m):
                    if mask[f, m]:
                        vals[m] = row[targets[s, a, m]]
                        row[targets[s, a, m]] = 0.0  # an outcome shared by two slots counts once
                theta[f] += vals
                counts[f] += 1
        theta = theta / counts[:, None]
        theta = np.where(mask, theta, 0.0)
        return theta / np.maximum(theta.sum(-1, keepdims=True), 1e-12)

    def mean_transitions(self, alpha) -> jnp.ndarray:
        """Transitions under the posterior mean ``E[θ] = α / Σα``."""
        return self.to_transitions(dirichlet.mean(alpha, self.mask))


def per_state_action(true_transitions, *, full: bool = False) -> BeliefSpace:
    """One Dirichlet per ``(s, a)``: support = one-step reachable states plus staying."""
    t = np.asarray(true_transitions)
    n_s, n_a, _ = t.shape
    if full:
        targets = np.broadcast_to(np.arange(n_s), (n_s, n_a, n_s)).astype(np.int32)
        mask = np.ones((n_s * n_a, n_s), bool)
    else:
        reach = (t > 0).any(1) | np.eye(n_s, dtype=bool)  # [S, S']
        width = int(reach.sum(1).max())
        targets = np.zeros((n_s, n_a, width), np.int32)
        mask = np.zeros((n_s * n_a, width), bool)
        for s in range(n_s):
            nxt = np.flatnonzero(reach[s])
            targets[s, :, : len(nxt)] = nxt
            targets[s, :, len(nxt) :] = s
            mask[s * n_a : (s + 1) * n_a, : len(nxt)] = True
    factor = np.arange(n_s * n_a, dtype=np.int32).reshape(n_s, n_a)
    return BeliefSpace(jnp.asarray(factor), jnp.asarray(targets), jnp.asarray(mask), "full" if full else "per-sa")


def tied(move_targets, n_actions: int) -> BeliefSpace:
    """One Dirichlet per action over relative moves shared by all states.

    Args:
        move_targets: ``[S, M]`` next state of each relative move (e.g. up, down,
            left, right, stay; see :func:`mindgap.envs.grid.move_targets`).
        n_actions: number of actions.
    """
    mt = np.asarray(move_targets, np.int32)
    n_s, n_m = mt.shape
    targets = np.broadcast_to(mt[:, None, :], (n_s, n_actions, n_m))
    factor = np.broadcast_to(np.arange(n_actions, dtype=np.int32), (n_s, n_actions))
    return BeliefSpace(jnp.asarray(factor), jnp.asarray(targets), jnp.ones((n_actions, n_m), bool), "tied")


def factored(factor, targets, n_outcomes) -> BeliefSpace:
    """A few shared factor distributions; all other pairs fixed to one known next state.

    Factor ``f`` is a ``Dir(α_f)`` over ``n_outcomes[f]`` outcomes (a Beta for two) and
    governs every ``(s, a)`` with ``factor[s, a] == f``. Pairs with ``factor == -1`` go
    to ``targets[s, a, 0]`` with certainty: they share one extra factor with a single
    outcome (a point mass, so it adds nothing to the ELBO and is never moved by a
    gradient). It is the last row of ``θ``.

    :func:`mindgap.envs.coffee.factored_layout` gives these arguments for the coffee world.

    Args:
        factor: ``[S, A]`` int, the factor of each pair, or ``-1`` for a fixed pair.
        targets: ``[S, A, M]`` int, next state of each outcome (of the fixed next state
            in slot 0 for fixed pairs).
        n_outcomes: ``[F]`` outcomes of each factor (``2 <= n <= M``).

    Raises:
        ValueError: on inconsistent shapes, a factor id out of range, a factor that
            governs no pair, or a next state outside ``0..S-1``.
    """
    factor = np.asarray(factor, np.int32)
    targets = np.asarray(targets, np.int32)
    n_outcomes = np.asarray(n_outcomes, np.int32).reshape(-1)
    if factor.ndim != 2 or targets.shape[:2] != factor.shape or targets.ndim != 3:
        raise ValueError(f"factor [S, A] {factor.shape} and targets [S, A, M] {targets.shape} do not match")
    n_s, _, width = targets.shape
    n_f = len(n_outcomes)
    if np.any((factor < -1) | (factor >= n_f)):
        raise ValueError(f"factor ids must lie in -1..{n_f - 1}")
    if np.any((n_outcomes < 2) | (n_outcomes > width)):
        raise ValueError(f"each factor needs 2..{width} outcomes, got {n_outcomes.tolist()}")
    unused = sorted(set(range(n_f)) - set(np.unique(factor).tolist()))
    if unused:
        raise ValueError(f"factor(s) {unused} govern no state-action pair")
    if np.any((targets < 0) | (targets >= n_s)):
        raise ValueError(f"targets must be state ids 0..{n_s - 1}")
    mask = np.zeros((n_f + 1, width), bool)
    mask[np.arange(n_f + 1)[:, None], np.arange(width)] = np.arange(width) < np.append(n_outcomes, 1)[:, None]
    full_factor = np.where(factor < 0, n_f, factor).astype(np.int32)
    return BeliefSpace(jnp.asarray(full_factor), jnp.asarray(targets), jnp.asarray(mask), "factored")
