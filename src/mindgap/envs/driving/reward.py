"""r_A, the driving task's reward (§4.4.2, Fig. 32): four features the participants rated, linearly combined.

The study asked how important four factors are to the driving behaviour (1 "NOT care" … 5
"Strongly care"; averages 3.42, 4.57, 3.28, 3.78) and "linearly combined" the answers into
the engineered reward. Each feature here is a number in [0, 1], 1 the best, of the state a
step reaches:

* ``speed`` — progress on the road: the forward speed ``v cos ψ`` over ``top_speed`` (30 m/s),
  clipped to [0, 1];
* ``front_distance`` — distance to the front car: the bumper-to-bumper gap to the nearest car
  ahead in the ego's lane over the desired gap ``standstill + headway · v`` (IDM's 5 m + 1.5 s,
  as highway-env's ``IDMVehicle``), clipped to [0, 1]; 1 with no car ahead;
* ``relative_speed`` — relative speed to neighbours: 1 − the mean |v − v_j| over the cars within
  ``neighbourhood`` (50 m) ahead or behind in the ego's lane or the next ones, over
  ``speed_scale`` (10 m/s), clipped to [0, 1]; 1 with no neighbour;
* ``lane_following`` — staying on a lane: 1 − the distance from the nearest lane's centre line
  over half a lane width (0 halfway through a lane change).

r_A(s, a, s') = Σ_i w_i φ_i(s') on a step that ends without a collision, and − ``collision``
(5 by default) on one that ends in a collision, which ends the episode.

**Weights from importance ratings** (:func:`importance_weights`): w_i = r_i / Σ_j r_j, the
ratings themselves, as the study combined them ("the distance to the front car is ... given a
larger weight"), normalised to sum to 1. The scale then means the same for every participant:
a step that is perfect on every feature earns 1, whatever the ratings' level (a participant who
answers 5 everywhere weighs the features as one who answers 1 everywhere), so the collision
penalty and the returns of two participants' rewards compare. The study's averages give
w = (0.227, 0.304, 0.218, 0.251).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .params import FEATURES, LANE_WIDTH, LENGTH, RewardParams


def importance_weights(importance) -> np.ndarray:
    """[..., 4] reward weights from importance ratings [..., 4] on the study's 1–5 scale, in
    :data:`~mindgap.envs.driving.params.FEATURES` order: each rating over the ratings' sum.

    Raises a one-line ValueError for a wrong shape or a rating outside [1, 5].
    """
    r = np.asarray(importance, np.float64)
    if r.ndim < 1 or r.shape[-1] != len(FEATURES):
        raise ValueError(
            f"importance must hold {len(FEATURES)} ratings ({', '.join(FEATURES)}), got shape {np.shape(importance)}"
        )
    bad = ~np.isfinite(r) | (r < 1) | (r > 5)
    if bad.any():
        raise ValueError(f"importance ratings must be in [1, 5] (1 NOT care … 5 Strongly care), got {r[bad][0]:g}")
    return (r / r.sum(-1, keepdims=True)).astype(np.float32)


def features(ego_y, heading, speed, others_dx, others_y, others_speed, rw: RewardParams) -> jax.Array:
    """[4] the features (module docstring) of one state: the ego's lateral position, heading and
    speed, and the other cars' [M] distance ahead (centre to centre), lateral position and speed."""
    lane = jnp.round(ego_y / LANE_WIDTH)
    others_lane = jnp.round(others_y / LANE_WIDTH)
    f_speed = jnp.clip(speed * jnp.cos(heading) / rw.top_speed, 0.0, 1.0)

    ahead = (others_lane == lane) & (others_dx > 0)
    gap = jnp.min(jnp.where(ahead, others_dx - LENGTH, jnp.inf), initial=jnp.inf)
    desired = rw.standstill + rw.headway * jnp.maximum(speed, 0.0)
    f_front = jnp.where(jnp.isfinite(gap), jnp.clip(gap / desired, 0.0, 1.0), 1.0)

    near = (jnp.abs(others_dx) <= rw.neighbourhood) & (jnp.abs(others_lane - lane) <= 1)
    count = jnp.sum(near)
    mean_diff = jnp.sum(jnp.where(near, jnp.abs(speed - others_speed), 0.0)) / jnp.maximum(count, 1)
    f_rel = jnp.where(count > 0, 1.0 - jnp.clip(mean_diff / rw.speed_scale, 0.0, 1.0), 1.0)

    f_lane = 1.0 - jnp.clip(jnp.abs(ego_y - LANE_WIDTH * lane) / (LANE_WIDTH / 2), 0.0, 1.0)
    return jnp.stack([f_speed, f_front, f_rel, f_lane])


def combine(phi: jax.Array, crashed: jax.Array, rw: RewardParams) -> jax.Array:
    """r_A of a step from the features of the state it reaches and whether it ended in a collision."""
    return jnp.where(crashed, -rw.collision, jnp.dot(rw.weights, phi))
