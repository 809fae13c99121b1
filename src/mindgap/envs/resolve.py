"""From an ``--env`` string to a world every learner takes, and the checks that a user's world follows the interface.

``--env`` accepts:

* a named terrain world (``nav1``, ``d3``, …) or a world file (``my-world.toml``);
* ``path/to/file.py:factory`` or ``package.module:factory``: a user's own world — ``factory``
  (a function or a class) is called with the ``key=value`` arguments after a comma
  (``examples/point_mass.py:make_world,drift=0.1``) and returns either an
  :class:`~mindgap.envs.interface.World` or a ``gymnasium.Env``, which is registered with
  gymnasium and stepped on the host as ``gym:ID`` is (``max_episode_steps=N`` sets its
  horizon where the env carries none; :func:`~mindgap.envs.gym_world.user_gym_world`);
* ``gym:ID`` (``gym:Pendulum-v1,g=9.81``): a gymnasium environment, stepped on the host
  (:mod:`~mindgap.envs.gym_world`; ``max_episode_steps=N`` sets its horizon);
* ``mjx:hopper`` or ``mjx:cheetah`` (``mjx:hopper,share=0.1,solver=gym``): gymnasium's hopper
  or half-cheetah with hidden noise as a pure-JAX world on MuJoCo's JAX backend
  (:mod:`~mindgap.envs.mjx_locomotion`).

Every problem is one line (an :class:`~mindgap.envs.interface.EnvError`): nothing is trained
or written before the world has passed :func:`check_world`.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import sys
from pathlib import Path

import jax
import numpy as np

from .interface import Box, EnvError, World, check_env
from .terrain import TerrainWorld, load_world


def parse_kwargs(text: str) -> dict:
    """``a=1,b=x`` → ``{"a": 1, "b": "x"}`` (numbers, true/false, else strings)."""
    out = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        if "=" not in part:
            raise EnvError(f"expected key=value, got {part!r}")
        k, v = (s.strip() for s in part.split("=", 1))
        out[k] = _value(v)
    return out


def _value(v: str):
    if v.lower() in ("true", "false"):
        return v.lower() == "true"
    for cast in (int, float):
        try:
            return cast(v)
        except ValueError:
            pass
    return v


def import_module(target: str):
    """A module from a ``.py`` path or a dotted name (:class:`~mindgap.envs.interface.EnvError` if it cannot be imported)."""
    return _import(target)


def _import(target: str):
    """A module from a ``.py`` path or a dotted name."""
    if target.endswith(".py"):
        path = Path(target)
        if not path.is_file():
            raise EnvError(f"no such file: {target}")
        name = f"mindgap_user_env_{abs(hash(str(path.resolve())))}"
        if name in sys.modules:  # imported once per process, as any module
            return sys.modules[name]
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except Exception as e:
            del sys.modules[name]
            raise EnvError(f"cannot import {target}: {type(e).__name__}: {e}") from None
        return module
    try:
        return importlib.import_module(target)
    except Exception as e:
        raise EnvError(f"cannot import {target}: {type(e).__name__}: {e}") from None


def _entry(head: str) -> str:
    """``path.py:factory`` with the path made absolute (any process can import it again), or ``module:factory``."""
    target, _, factory = head.rpartition(":")
    if not target.endswith(".py"):
        return head
    if not Path(target).is_file():
        raise EnvError(f"no such file: {target}")
    return f"{Path(target).resolve()}:{factory}"


def import_factory(entry: str, who: str | None = None):
    """The callable (a function or a class) that ``path.py:factory`` or ``module:factory`` names."""
    target, _, factory = entry.rpartition(":")
    fn = getattr(_import(target), factory, None)
    if not callable(fn):
        raise EnvError(f"{(who or entry).rpartition(':')[0]} has no function or class {factory!r}")
    return fn


def _takes(fn, name: str) -> bool:
    """Whether ``fn`` accepts the keyword ``name`` (True where its signature cannot be read)."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return True
    return any(p.name == name or p.kind is inspect.Parameter.VAR_KEYWORD for p in params)


def _is_gym_env(obj) -> bool:
    try:
        import gymnasium
    except ImportError:
        return False
    return isinstance(obj, gymnasium.Env)


def resolve_env(spec: str):
    """The world ``spec`` names (see the module docstring), checked."""
    spec = spec.strip()
    if spec.startswith("gym:"):
        from .gym_world import gym_world_from_spec

        return gym_world_from_spec(spec)
    if spec.startswith("mjx:"):
        from .mjx_locomotion import mjx_world_from_spec

        world = mjx_world_from_spec(spec)
        check_world(world, spec)
        return world
    head, _, kwargs = spec.partition(",")
    if ":" in head:
        entry = _entry(head)
        fn = import_factory(entry, head)
        kw = parse_kwargs(kwargs)
        steps = (
            kw.pop("max_episode_steps") if "max_episode_steps" in kw and not _takes(fn, "max_episode_steps") else None
        )
        try:
            world = fn(**kw)
        except EnvError:
            raise
        except Exception as e:
            raise EnvError(f"{head}() failed: {type(e).__name__}: {e}") from None
        if _is_gym_env(world):
            from .gym_world import user_gym_world

            return user_gym_world(entry, head, fn, kw, world, steps)
        if steps is not None:
            raise EnvError(f"{head}: max_episode_steps is for a factory that returns a gymnasium env")
        check_world(world, head)
        return world
    if kwargs:
        raise EnvError(f"{spec}: key=value arguments belong to a module:factory world")
    return load_world(head)


def check_world(world, name: str = "the world") -> None:
    """Refuse a world that does not follow the interface: its type, spaces, and the shapes its functions return.

    The functions are traced abstractly (``jax.eval_shape``), so nothing is computed.
    """
    if isinstance(world, TerrainWorld):
        return
    if not isinstance(world, World):
        raise EnvError(
            f"{name} returned {type(world).__name__}, not a mindgap World (mindgap.envs.interface.World) or a gymnasium.Env"
        )
    env = world.env
    check_env(env, continuous_actions=False, who=name)
    obs_dim = env.observation_space.dim
    act = env.action_space
    action = np.zeros(act.shape if isinstance(act, Box) else (), np.float32 if isinstance(act, Box) else np.int32)
    key = jax.random.key(0)
    try:
        state = jax.eval_shape(env.reset, key, world.params)
        obs = jax.eval_shape(env.observe, state, world.params)
        out = jax.eval_shape(env.step, key, state, action, world.params)
    except Exception as e:
        raise EnvError(f"{name}: its reset/step/observe cannot be traced: {type(e).__name__}: {e}") from None
    if obs.shape != (obs_dim,):
        raise EnvError(f"{name}: observe returns shape {obs.shape}, its observation space says ({obs_dim},)")
    if not all(hasattr(out, f) for f in ("state", "reward", "terminated", "truncated")):
        raise EnvError(f"{name}: step must return a Step(state, reward, terminated, truncated)")
    for field in ("reward", "terminated", "truncated"):
        if getattr(out, field).shape != ():
            raise EnvError(f"{name}: step's {field} must be a scalar, got shape {getattr(out, field).shape}")
    if jax.tree.structure(out.state) != jax.tree.structure(state):
        raise EnvError(f"{name}: step's next state has another structure than reset's state")
    if world.horizon < 1:
        raise EnvError(f"{name}: horizon must be at least 1, got {world.horizon}")
