"""The functional API (reset, step, reward, log_prob) and world files."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.envs.terrain import (
    NAMED_WORLDS,
    Dynamics,
    LayoutError,
    TerrainState,
    load_world,
    log_prob,
    observe,
    position,
    reset,
    reward,
    world_from_dict,
)
from mindgap.envs.terrain import step as _step
from mindgap.envs.terrain.layout import GOAL, PIT
from mindgap.envs.terrain.world import potential

step = jax.jit(_step)  # an eager call would compile its control flow again at every call

SPEC = {
    "name": "tiny",
    "horizon": 5,
    "layout": "#######\n#S..PG#\n#.....#\n#######",
    "rewards": {"goal": 10.0, "pit": -7.0, "step": -1.0, "progress": 1.0},
    "dynamics": {"floor": {"noise": 0.02}},
    "beliefs": {"careful": {"floor": {"noise": 0.3}, "pit_noise": 0.5}},
}


@pytest.fixture(scope="module")
def world():
    return world_from_dict(SPEC)


def _state(x, y, t=0, done=False):
    return TerrainState(jnp.asarray([x, y], jnp.float32), jnp.asarray(t, jnp.int32), jnp.asarray(done))


def test_reset_starts_in_a_start_cell(world, key):
    states = jax.vmap(reset, (0, None))(jax.random.split(key, 256), world.params)
    pos = np.asarray(states.pos)
    assert np.all(np.abs(pos - 1.5) <= 0.2 + 1e-6) and not np.asarray(states.done).any()
    assert pos.std(0).min() > 0.05  # jittered


def test_goal_and_pit_end_the_episode_with_their_reward(world, key):
    out = step(key, _state(4.7, 1.5), jnp.asarray([1.0, 0.0]), world.params)  # 0.5 right: into the goal
    assert bool(out.terminated) and bool(out.state.done) and not bool(out.truncated)
    progress = float(potential(world.params, jnp.asarray([4.7, 1.5])) - potential(world.params, out.state.pos))
    assert float(out.reward) == pytest.approx(-1.0 + progress + 10.0, abs=1e-5)
    out = step(key, _state(3.7, 1.5), jnp.asarray([1.0, 0.0]), world.params)  # into the pit
    assert bool(out.terminated) and int(jnp.floor(out.state.pos[0])) == 4
    phi = float(potential(world.params, jnp.asarray([3.7, 1.5])))
    assert float(out.reward) == pytest.approx(-1.0 + phi - 7.0, abs=1e-5)  # Φ is 0 in a pit


def test_finished_state_does_not_move(world, key):
    s = _state(2.5, 2.5, t=3, done=True)
    out = step(key, s, jnp.asarray([1.0, 1.0]), world.params)
    assert np.array_equal(np.asarray(out.state.pos), np.asarray(s.pos)) and float(out.reward) == 0.0
    assert not bool(out.terminated) and not bool(out.truncated) and int(out.state.t) == 3
    assert float(log_prob(s, jnp.zeros(2), out.state, world.params)) == 0.0


def test_horizon_truncates(world, key):
    out = step(key, _state(1.5, 2.5, t=4), jnp.asarray([0.0, 0.0]), world.params)
    assert bool(out.truncated) and bool(out.state.done) and not bool(out.terminated)


FIXED = {**SPEC, "episode_ends": False, "rewards": {"form": "state", "goal": 1.0, "pit": -2.0, "step": -1.0}}


def test_a_state_form_reward_depends_on_where_the_step_starts_only(key):
    params = world_from_dict(FIXED).params
    assert float(reward(_state(1.5, 1.5), jnp.zeros(2), _state(5.5, 1.5), params)) == -1.0  # into the goal: no bonus
    assert float(reward(_state(5.5, 1.5), jnp.zeros(2), _state(4.5, 1.5), params)) == 0.0  # in the goal: −1 + 1
    assert float(reward(_state(4.5, 1.5), jnp.zeros(2), _state(4.5, 1.5), params)) == -3.0  # in the pit: −1 − 2


def test_a_state_form_distance_term_charges_the_distance_to_the_goal(key):
    """r(s) = step − distance·Φ(s) outside the goal and the pits; a transition-form world refuses the term."""
    spec = {**FIXED, "rewards": {**FIXED["rewards"], "distance": 0.25}}
    params = world_from_dict(spec).params
    far, near = _state(1.5, 1.5), _state(3.5, 2.5)
    for s in (far, near):
        phi = float(potential(params, s.pos))
        assert phi > 0
        assert float(reward(s, jnp.zeros(2), s, params)) == pytest.approx(-1.0 - 0.25 * phi, abs=1e-6)
    assert float(reward(far, jnp.zeros(2), far, params)) < float(reward(near, jnp.zeros(2), near, params))
    assert float(reward(_state(5.5, 1.5), jnp.zeros(2), _state(5.5, 1.5), params)) == 0.0  # in the goal
    assert float(reward(_state(4.5, 1.5), jnp.zeros(2), _state(4.5, 1.5), params)) == -3.0  # in the pit: no Φ
    with pytest.raises(ValueError, match="distance is a term of the state form"):
        world_from_dict({**SPEC, "rewards": {"step": -1.0, "distance": 0.1}})


def test_a_fixed_horizon_ends_nowhere_but_the_horizon_and_a_pit_traps(key):
    params = world_from_dict(FIXED).params
    out = step(key, _state(5.5, 2.2), jnp.asarray([0.0, -1.0]), params)  # up into the goal: the episode goes on
    assert not bool(out.terminated) and not bool(out.state.done) and int(out.state.pos[1]) == 1
    inside = step(key, out.state, jnp.asarray([-0.2, 0.0]), params)
    assert float(inside.reward) == 0.0 and not bool(inside.state.done)  # the goal is a region to stay in
    pit = _state(4.5, 1.5)
    for k in jax.random.split(key, 5):
        out = step(k, pit, jnp.asarray([1.0, 1.0]), params)
        assert np.array_equal(np.asarray(out.state.pos), np.asarray(pit.pos)) and not bool(out.terminated)
    assert float(log_prob(pit, jnp.ones(2), pit, params)) == 0.0  # trapped: staying is certain
    assert float(log_prob(pit, jnp.ones(2), _state(4.9, 1.5), params)) == -np.inf
    assert bool(step(key, _state(1.5, 2.5, t=4), jnp.zeros(2), params).truncated)


def test_progress_rewards_telescope_along_a_rollout(world, key):
    """Σ progress terms = Φ(start) − Φ(end), with Φ = 0 at a pit or the goal (potential-based shaping)."""
    params = world.params
    s = _state(1.5, 2.5)
    start_phi = float(potential(params, s.pos))
    total, steps = 0.0, 0
    for k in jax.random.split(key, 5):
        out = step(k, s, jnp.asarray([1.0, -0.2]), params)
        total += float(out.reward) - float(params.rewards.step)
        steps += 1
        s = out.state
        if bool(s.done):
            break
    terr = int(world.params.grid[int(s.pos[1]), int(s.pos[0])])
    bonus = 10.0 if terr == GOAL else -7.0 if terr == PIT else 0.0
    end_phi = 0.0 if bonus else float(potential(params, s.pos))
    assert total - bonus == pytest.approx(start_phi - end_phi, abs=1e-4)


def test_reward_ignores_the_action(world):
    s, s2 = _state(1.5, 2.5), _state(2.0, 2.4)
    r1 = reward(s, jnp.asarray([1.0, 0.0]), s2, world.params)
    r2 = reward(s, jnp.asarray([-1.0, 1.0]), s2, world.params)
    assert float(r1) == float(r2)


def test_observation_round_trip(world):
    s = _state(3.25, 2.75)
    obs = observe(s, world.params)
    assert np.all(np.abs(np.asarray(obs)) <= 1)
    np.testing.assert_allclose(np.asarray(position(obs, world.params)), [3.25, 2.75], atol=1e-6)


def test_jit_and_vmap_over_4096_worlds_with_their_own_dynamics(world, key):
    """4096 copies of the world, each with its own noise level, step together in one program."""
    n = 4096
    noise = jnp.linspace(0.02, 0.4, n)
    batched = jax.vmap(lambda s: world.params._replace(dynamics=world.params.dynamics._replace(noise=s * jnp.ones(5))))(
        noise
    )
    k_reset, k_step = jax.random.split(key)
    states = jax.jit(jax.vmap(reset))(jax.random.split(k_reset, n), batched)
    actions = jnp.tile(jnp.asarray([[0.0, 0.0]]), (n, 1))
    out = jax.jit(jax.vmap(step))(jax.random.split(k_step, n), states, actions, batched)
    moved = np.linalg.norm(np.asarray(out.state.pos - states.pos), axis=1)
    assert out.state.pos.shape == (n, 2) and np.isfinite(moved).all()
    lo, hi = moved[: n // 10].mean(), moved[-n // 10 :].mean()
    assert hi > 4 * lo  # each world used its own noise level
    lp = jax.jit(jax.vmap(log_prob))(states, actions, out.state, batched)
    assert np.isfinite(np.asarray(lp)).all()


def test_belief_is_another_table(world):
    b = world.belief("careful")
    assert float(b.dynamics.noise[0]) == pytest.approx(0.3) and float(b.dynamics.pit_noise) == pytest.approx(0.5)
    assert float(b.dynamics.speed[1]) == float(world.params.dynamics.speed[1])  # unspecified: the true value
    assert np.array_equal(np.asarray(b.grid), np.asarray(world.params.grid))
    with pytest.raises(ValueError, match="no belief 'reckless'"):
        world.belief("reckless")


@pytest.mark.parametrize("name", NAMED_WORLDS)
def test_named_worlds_load(name):
    w = load_world(name)
    assert w.name == name and w.beliefs and w.description and w.expect
    assert w.layout.shape[0] >= 5


@pytest.mark.parametrize(
    "patch,pattern",
    [
        ({"layout": "#####\n#S.G#\n###"}, r"tiny.toml: layout: row 3 has 3 columns"),
        ({"colour": "red"}, r"unknown key\(s\) colour"),
        ({"dynamics": {"lava": {"speed": 1.0}}}, r"unknown dynamics entry 'lava'"),
        ({"dynamics": {"ice": {"speed": 2.0}}}, r"ice: speed must be in \[0, 1\]"),
        ({"dynamics": {"sand": {"stuck": 1.0}}}, r"sand: stuck must be in \[0, 1\)"),
        ({"dynamics": {"floor": {"noise": 0.0}}}, r"floor: noise must be positive"),
        ({"rewards": {"gold": 1.0}}, r"\[rewards\]: unknown key\(s\) gold"),
        ({"expect": {"true_prefers": "lava"}}, r"must be 'ice' or 'sand'"),
        ({"expect": {"obeying": "maybe"}}, r"obeying must be 'arrives' or 'fails'"),
        ({"horizon": 0}, r"horizon must be at least 1"),
        ({"rewards": {"form": "episode"}}, r"\[rewards\] form must be one of transition, state"),
        ({"rewards": {"form": "state", "progress": 1.0}}, r"a state-form reward cannot have it"),
        ({"episode_ends": "no"}, r"episode_ends must be true or false"),
    ],
)
def test_malformed_world_files_get_clear_errors(patch, pattern):
    spec = {**SPEC, **patch}
    with pytest.raises(ValueError, match=pattern):
        world_from_dict(spec, source="tiny.toml")


def test_layout_error_is_a_value_error():
    with pytest.raises(LayoutError):
        world_from_dict({**SPEC, "layout": "#?#"})


def test_world_file_round_trip(tmp_path):
    path = tmp_path / "corridor.toml"
    path.write_text(
        'horizon = 20\nlayout = """\n######\n#S~~G#\n######\n"""\n[dynamics]\nice = { speed = 0.5 }\n'
        "[beliefs.person]\nice = { noise = 0.4 }\n"
    )
    w = load_world(path)
    assert w.name == "corridor" and list(w.beliefs) == ["person"]
    assert float(w.params.dynamics.speed[1]) == 0.5 and float(w.belief().dynamics.speed[1]) == 0.5
    assert float(w.belief().dynamics.noise[1]) == pytest.approx(0.4)
    with pytest.raises(ValueError, match="unknown world 'nowhere'"):
        load_world("nowhere")
    bad = tmp_path / "bad.toml"
    bad.write_text("horizon = = 3")
    with pytest.raises(ValueError, match="not valid TOML"):
        load_world(bad)


def test_dynamics_table_round_trips_through_a_dict():
    d = Dynamics.from_dict({"sand": {"speed": 0.4, "stuck": 0.3}, "pit_noise": 0.2})
    again = Dynamics.from_dict(d.as_dict())
    for a, b in zip(d, again):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b))
