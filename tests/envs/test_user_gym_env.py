"""A user's own gymnasium env from a file (``--env path.py:factory``): resolved, re-registered, answered, learned on."""

import json
import textwrap

import gymnasium
import jax.numpy as jnp
import numpy as np
import pytest

from mindgap.cli import main
from mindgap.data.segments import Segments
from mindgap.envs.gym_world import GymWorld, user_env_id
from mindgap.envs.interface import EnvError
from mindgap.envs.resolve import resolve_env
from mindgap.teachers.preference import PreferenceTeacher, TeacherConfig

SOURCE = textwrap.dedent(
    '''
    import gymnasium
    import numpy as np
    from gymnasium.wrappers import TimeLimit


    class Drift(gymnasium.Env):
        """A point on a line pushed by the agent and carried by a current; reward −|x|."""

        def __init__(self, drift=0.1):
            self.drift = drift
            self.observation_space = gymnasium.spaces.Box(-5.0, 5.0, (2,), np.float32)
            self.action_space = gymnasium.spaces.Box(-0.5, 0.5, (1,), np.float32)

        def _obs(self):
            return np.array([self.x, self.drift], np.float32)

        def reset(self, seed=None, options=None):
            super().reset(seed=seed)
            self.x = float(self.np_random.uniform(-2, 2))
            return self._obs(), {}

        def step(self, action):
            self.x = float(np.clip(self.x + float(action[0]) + self.drift, -5, 5))
            return self._obs(), -abs(self.x), False, False, {}


    def make_env(drift=0.1):
        return TimeLimit(Drift(drift), 30)


    def not_an_env():
        return 3
    '''
)


@pytest.fixture
def env_file(tmp_path):
    path = tmp_path / "drift.py"
    path.write_text(SOURCE)
    return path


def test_a_factory_or_a_class_returning_a_gymnasium_env_is_a_gym_world(env_file):
    world = resolve_env(f"{env_file}:make_env,drift=0.2")
    assert isinstance(world, GymWorld) and world.horizon == 30  # the TimeLimit the factory put on
    assert world.name == f"{env_file}:make_env,drift=0.2" and world.env.reward is None
    assert world.act_low == (-0.5,) and world.env.action_space.shape == (1,)
    env, obs = world.make(seed=0)
    assert obs.shape == (2,) and obs[1] == pytest.approx(0.2)
    env.close()
    cls = resolve_env(f"{env_file}:Drift,max_episode_steps=12")
    assert cls.horizon == 12 and cls.name.endswith("max_episode_steps=12")
    # a process that has not registered it (a sweep's worker) registers it again from the file
    del gymnasium.registry[cls.env_id]
    env, _ = cls.make(seed=1)
    assert cls.env_id in gymnasium.registry
    env.close()
    other = env_file.parent / "sub"
    other.mkdir()
    (other / "drift.py").write_text(SOURCE)
    assert user_env_id(f"{other / 'drift.py'}:Drift") != cls.env_id  # one name, two files


@pytest.mark.parametrize(
    ("tail", "message"),
    [
        (":Drift", "declares no max_episode_steps; pass one"),
        (":Drift,max_episode_steps=0", "max_episode_steps must be a positive integer"),
        (":not_an_env", "returned int, not a mindgap World (mindgap.envs.interface.World) or a gymnasium.Env"),
        (":nothing", "has no function or class 'nothing'"),
        (":make_env,colour=red", "make_env() failed: TypeError"),
    ],
)
def test_bad_user_envs_are_one_line(env_file, tail, message):
    with pytest.raises(EnvError) as e:
        resolve_env(f"{env_file}{tail}")
    assert message in str(e.value) and "\n" not in str(e.value)


def test_the_ordinary_person_compares_the_rewards_the_env_returned(env_file):
    world = resolve_env(f"{env_file}:make_env")
    k, length = 4, 3
    rewards = jnp.array([[-1.0, -1.0, -1.0], [-0.1, -0.1, -9.0], [0.0, -0.5, 0.0], [-2.0, 0.0, 0.0]])
    zeros = jnp.zeros((k, length, 2))
    mask = jnp.array([[1, 1, 1], [1, 1, 0], [1, 1, 1], [1, 1, 1]], bool)  # the second's third step ended
    seg_a = Segments(zeros, jnp.zeros((k, length, 1)), zeros, mask, rewards)
    seg_b = Segments(zeros, jnp.zeros((k, length, 1)), zeros, jnp.ones((k, length), bool), jnp.full((k, length), -0.6))
    person = PreferenceTeacher(world.params, None, world.env, TeacherConfig(beta=None))
    labels, answered = person.answer(jnp.zeros(2, jnp.uint32), seg_a, seg_b)
    # sums: a = -3, -0.2, -0.5, -2 against b = -1.8 each
    np.testing.assert_array_equal(np.asarray(labels), [0.0, 1.0, 1.0, 0.0])
    assert np.asarray(answered).all()
    biased = PreferenceTeacher(world.params, world.params, world.env, TeacherConfig())
    with pytest.raises(ValueError, match="by r alone"):
        biased.answer(jnp.zeros(2, jnp.uint32), seg_a, seg_b)
    with pytest.raises(ValueError, match="cut from a buffer"):
        person.answer(jnp.zeros(2, jnp.uint32), seg_a._replace(env_reward=None), seg_b)


@pytest.mark.parametrize(
    "method",
    # the default tier runs DRLHP (the host loop with answers from the env's returned rewards); SAC is the
    # same loop without feedback, PEBBLE's pre-training and critic reset run on Pendulum in test_host_loop
    [pytest.param("sac", marks=pytest.mark.slow), pytest.param("pebble", marks=pytest.mark.slow), "drlhp"],
)
def test_sac_pebble_and_drlhp_run_on_a_users_env_class(env_file, method, tmp_path, capsys):
    spec = f"{env_file}:Drift,max_episode_steps=30"
    out = tmp_path / method
    teacher = [] if method == "sac" else ["--teacher", "true"]
    assert main([method, "--env", spec, "--fast", "--steps", "750", *teacher, "--quiet", "--out", str(out)]) == 0
    assert "final return" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["world"] == spec and summary["queries"] == {"sac": 0, "pebble": 10, "drlhp": 20}[method]
    assert (out / "curve.csv").is_file() and (out / "checkpoint.npz").is_file()
