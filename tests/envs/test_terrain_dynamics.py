"""The terrain transition model: ``sample_next``, ``log_prob_pos`` and ``subcell_probs`` agree exactly."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from mindgap.envs.terrain import Dynamics, Rewards, parse_layout
from mindgap.envs.terrain.dynamics import landing_allowed, log_prob_pos, sample_next, subcell_probs
from mindgap.envs.terrain.params import make_params

# Every terrain, walls on several sides, a diagonal gap closed by two walls, a pit.
LAYOUT = """
#########
#S.~~:::#
#..~~:#.#
#.P.#.#.#
#....#.G#
#########
"""
TABLE = {
    "floor": {"speed": 1.0, "noise": 0.12, "stuck": 0.0},
    "ice": {"speed": 0.8, "noise": 0.3, "stuck": 0.0},
    "sand": {"speed": 0.5, "noise": 0.08, "stuck": 0.4},
    "pit_noise": 0.3,
    "pit_scale": 0.7,
}
# (name, position (x, y), action): one per terrain and wall configuration
CASES = [
    ("floor, open", (1.5, 2.5), (1.0, 0.3)),
    ("floor, near pit", (2.5, 2.2), (-0.4, 1.0)),
    ("floor, corner into walls", (1.15, 1.2), (-1.0, -1.0)),
    ("ice, wide noise", (3.5, 1.5), (1.0, 1.0)),
    ("ice, against wall", (4.8, 2.5), (1.0, 0.5)),
    ("sand, stuck mass", (5.5, 1.5), (1.0, 0.0)),
    ("sand, diagonal gap closed by two walls", (5.9, 2.9), (1.0, 1.0)),
    ("floor beside the goal", (6.5, 3.5), (1.0, 1.0)),
]


def _params(walls: str):
    table = dict(TABLE, walls=walls)
    return make_params(parse_layout(LAYOUT), Dynamics.from_dict(table), Rewards(10.0, -10.0, -1.0, 0.0), horizon=50)


@pytest.fixture(scope="module", params=["bump", "slide"])
def params(request):
    """The test world under each wall rule: every consistency test runs for both."""
    return _params(request.param)


@pytest.fixture(scope="module")
def bump_params():
    return _params("bump")


# One program each for every case and wall rule: the world, the position and the action are arguments,
# not constants of a program compiled per test.
_density = jax.jit(jax.vmap(log_prob_pos, in_axes=(None, None, None, 0)))
_draws = jax.jit(jax.vmap(sample_next, in_axes=(0, None, None, None)))


def _grid(pos, k):
    """Midpoints of a k×k grid per cell over the 3×3 block around pos, and the cell area."""
    cx, cy = np.floor(pos)
    xs = cx - 1 + (np.arange(3 * k) + 0.5) / k
    ys = cy - 1 + (np.arange(3 * k) + 0.5) / k
    gx, gy = np.meshgrid(xs, ys)
    return jnp.asarray(np.stack([gx.ravel(), gy.ravel()], -1), jnp.float32), 1.0 / k**2


@pytest.mark.parametrize("name,pos,action", CASES, ids=[c[0] for c in CASES])
def test_density_integrates_to_one(params, name, pos, action):
    pos, action = jnp.asarray(pos, jnp.float32), jnp.asarray(action, jnp.float32)
    pts, area = _grid(np.asarray(pos), 240)
    dens = jnp.exp(_density(params, pos, action, pts))
    stay = jnp.exp(log_prob_pos(params, pos, action, pos))
    total = float(stay + dens.sum() * area)
    assert total == pytest.approx(1.0, abs=2e-3), name


@pytest.mark.parametrize("name,pos,action", CASES, ids=[c[0] for c in CASES])
def test_density_matches_subcell_masses(params, name, pos, action):
    """Integrating exp(log_prob) over each sub-cell gives the exact rectangle mass."""
    pos, action = jnp.asarray(pos, jnp.float32), jnp.asarray(action, jnp.float32)
    # 4×4 sub-cells per cell, 40×40 quadrature points per sub-cell (the slide rule's density is
    # steep at a wall's face when the mean lies inside the wall)
    n, k = 4, 160
    stay, probs = subcell_probs(params, pos, action, n)
    pts, area = _grid(np.asarray(pos), k)
    dens = np.exp(np.asarray(_density(params, pos, action, pts)))
    per_sub = dens.reshape(3 * n, k // n, 3 * n, k // n).sum((1, 3)) * area
    np.testing.assert_allclose(per_sub, np.asarray(probs), atol=2e-3)
    assert float(jnp.exp(log_prob_pos(params, pos, action, pos))) == pytest.approx(float(stay), abs=1e-4)


@pytest.mark.parametrize("name,pos,action", CASES, ids=[c[0] for c in CASES])
def test_samples_follow_the_masses(params, name, pos, action, key):
    """Chi-square test of 20 000 draws of ``sample_next`` against the exact sub-cell masses."""
    pos, action = jnp.asarray(pos, jnp.float32), jnp.asarray(action, jnp.float32)
    n, draws = 4, 20_000
    nxt = np.asarray(_draws(jax.random.split(key, draws), params, pos, action))
    stayed = np.all(nxt == np.asarray(pos), axis=1)
    corner = np.floor(np.asarray(pos)) - 1
    sub = np.floor((nxt[~stayed] - corner) * n).astype(int)
    assert np.all((sub >= 0) & (sub < 3 * n)), "a sample left the 3×3 block"
    counts = np.zeros((3 * n, 3 * n))
    np.add.at(counts, (sub[:, 1], sub[:, 0]), 1)
    stay_p, probs = (np.asarray(x, np.float64) for x in subcell_probs(params, pos, action, n))
    assert counts[probs == 0].sum() == 0, "a sample landed where the model puts no mass"
    observed = np.append(counts[probs > 0], stayed.sum())
    expected = np.append(probs[probs > 0], stay_p) * draws
    big = expected >= 5  # pool the sparse bins into one, as the test requires
    observed = np.append(observed[big], observed[~big].sum())
    expected = np.append(expected[big], expected[~big].sum())
    keep = expected > 0
    expected = expected[keep] * observed[keep].sum() / expected[keep].sum()
    p = stats.chisquare(observed[keep], expected).pvalue
    assert p > 1e-3, f"{name}: samples disagree with the masses (p = {p:.2g})"


def test_walls_refuse_and_diagonal_gaps_are_closed(params):
    pos = jnp.asarray([5.9, 2.9])  # sand at row 2 col 5; cells (2,6) and (3,5) are walls
    assert not landing_allowed(params, pos, jnp.asarray([6.2, 3.2]))  # through the closed corner
    assert not landing_allowed(params, pos, jnp.asarray([6.2, 2.5]))  # into the wall
    assert landing_allowed(params, pos, jnp.asarray([5.5, 2.2]))
    assert not landing_allowed(params, pos, jnp.asarray([7.5, 2.5]))  # beyond the 3×3 block


def test_log_prob_is_finite_far_in_the_tails(bump_params):
    """A precise step far from walls: the bump mass underflows float32 but its log does not."""
    precise = bump_params.with_dynamics(Dynamics.from_dict({"floor": {"noise": 0.01}, "pit_noise": 0.0}))
    pos, a = jnp.asarray([1.5, 2.5]), jnp.asarray([0.0, 0.0])
    lp_stay = log_prob_pos(precise, pos, a, pos)
    assert np.isfinite(float(lp_stay)) and float(lp_stay) < -1000
    far = float(log_prob_pos(precise, pos, a, pos + 0.3))  # 30σ away on both axes: −900 − log(2πσ²)
    assert np.isfinite(far) and far < -800
    assert float(log_prob_pos(precise, pos, a, jnp.asarray([0.5, 2.5]))) == -np.inf  # inside the border wall
    assert float(log_prob_pos(precise, pos, a, pos + 0.01)) > float(log_prob_pos(precise, pos, a, pos + 0.02))


def test_a_stay_read_back_from_observations_is_a_stay(bump_params):
    """A position read back from an observation may differ from the state's in the last bit; the
    point mass still scores it (a person scoring observed steps), not the density."""
    pos, a = jnp.asarray([1.5, 2.5]), jnp.asarray([0.4, 0.0])
    last_bit = jnp.nextafter(pos, jnp.inf)
    assert float(log_prob_pos(bump_params, pos, a, last_bit)) == float(log_prob_pos(bump_params, pos, a, pos))


def test_slide_keeps_the_motion_along_a_wall():
    """The freeze the bump rule has and the slide rule removes: a precise diagonal push into a
    wall (mean 0.3 cells inside it, 6σ) stays put under ``bump`` and, under ``slide``, moves the
    full step along the wall and ends within a few σ²/d of its face."""
    table = {"floor": {"noise": 0.05}, "pit_noise": 0.0}
    pos = jnp.asarray([3.5, 4.8], jnp.float32)  # floor, row 4, just above the border wall
    a = jnp.asarray([-1.0, 1.0], jnp.float32)  # down-left, into the wall
    keys = jax.random.split(jax.random.key(3), 2000)
    for walls in ("bump", "slide"):
        world = _params("bump").with_dynamics(Dynamics.from_dict(dict(table, walls=walls)))
        nxt = np.asarray(_draws(keys, world, pos, a))
        moved = ~np.all(nxt == np.asarray(pos), axis=1)
        lp_stay = float(log_prob_pos(world, pos, a, pos))
        if walls == "bump":
            assert moved.mean() < 0.01 and lp_stay > -0.01  # frozen: almost surely a bump
        else:
            assert moved.all() and lp_stay == -np.inf
            assert np.abs(nxt[:, 0] - (3.5 - 0.5)).max() < 0.25  # the x motion is kept
            gap = 5.0 - nxt[:, 1]  # distance from the wall's face: about Exp(mean σ²/d = 0.008)
            assert np.all(gap > 0) and gap.max() < 0.1 and gap.mean() < 0.02
            dens = np.asarray(_density(world, pos, a, jnp.asarray(nxt)))
            assert np.all(np.isfinite(dens))  # every draw is a point the density gives mass to


def test_wall_rule_is_read_checked_and_recorded():
    assert float(Dynamics.from_dict({}).slide) == 0.0
    slide = Dynamics.from_dict({"walls": "slide"})
    assert float(slide.slide) == 1.0 and slide.as_dict()["walls"] == "slide"
    assert "walls" not in Dynamics.from_dict({"walls": "bump"}).as_dict()  # old records unchanged
    assert float(Dynamics.from_dict({"ice": {"noise": 0.3}}, base=slide).slide) == 1.0  # a belief inherits it
    with pytest.raises(ValueError, match="walls must be one of bump, slide"):
        Dynamics.from_dict({"walls": "stick"})


def test_bump_worlds_keep_the_fingerprint_they_had_before_the_slide_rule():
    """Run folders and the expected-policy cache are keyed by a hash of the world's arrays: the
    ``slide`` flag is left out of it when 0, so bump worlds hash as before the rule existed
    (the hash nav2's run folders recorded then), and a slide world hashes differently."""
    from mindgap.algorithms.expected_policy import ExpectedPolicyConfig, cache_key
    from mindgap.data.fingerprint import fingerprint, identity_leaves
    from mindgap.envs.terrain import load_world

    world = load_world("nav2-v1")  # the dissertation's nav2, as run folders recorded it
    tree = (world.params, world.beliefs)
    leaves = jax.tree.leaves(tree)
    kept = identity_leaves(tree)
    assert len(leaves) - len(kept) == 5  # both tables' slide flags, the reward form and distance, the fixed horizon
    assert all(any(k is leaf for leaf in leaves) for k in kept)
    assert fingerprint(tree) == "e48df9479d0359a1"  # recorded by nav2 run folders before `walls` existed

    slide = world.params.with_dynamics(world.params.dynamics._replace(slide=np.float64(1.0)))
    assert len(identity_leaves(slide)) == len(jax.tree.leaves(slide)) - 3  # the three other late fields hold 0
    assert fingerprint(slide) != fingerprint(world.params)
    fixed = world.params._replace(fixed_horizon=np.float32(1.0))
    state_form = world.params._replace(rewards=world.params.rewards._replace(state_form=np.float32(1.0)))
    assert len({fingerprint(world.params), fingerprint(fixed), fingerprint(state_form)}) == 3
    cfg = ExpectedPolicyConfig.fast()
    assert cache_key(slide, cfg) != cache_key(world.params, cfg)


@pytest.mark.parametrize("a,b", [(-28.0, -8.0), (8.0, 28.0), (5.0, 5.5), (-1.0, 0.5), (0.0, 1.0)])
def test_truncated_normal_is_exact_in_the_tails(a, b):
    """The slide rule's redraw: a Kolmogorov–Smirnov test against SciPy's truncated normal,
    including intervals far beyond 5σ where float32 inversion of the CDF fails."""
    from mindgap.envs.terrain.dynamics import _truncated_normal

    keys = jax.random.split(jax.random.key(5), 5000)
    x = np.asarray(jax.vmap(lambda k: _truncated_normal(k, jnp.float32(a), jnp.float32(b)))(keys))
    assert np.all((x >= a) & (x <= b))
    assert stats.kstest(x, stats.truncnorm(a, b).cdf).pvalue > 1e-3
