"""MuJoCo models of gymnasium's locomotion envs on MuJoCo's JAX backend (MJX), with solver options chosen for it.

The model files are gymnasium's own (``gymnasium/envs/mujoco/assets/hopper.xml``,
``half_cheetah.xml``), read from the installed package, so the MJX worlds
(:mod:`~mindgap.envs.mjx_locomotion`) simulate what ``Hopper-v5`` / ``HalfCheetah-v5`` simulate.
Written here: which file each body is, and the solver options (:data:`SOLVERS`) applied to
the compiled model before MJX takes it. MJX gives the physics.

Why the options matter: MJX runs a fixed computation for every world. Its constraint
solver stops when *every* world of a vmapped batch has converged, so with many worlds it
runs to the cap, and gymnasium's models keep MuJoCo's default cap (100 Newton iterations,
50 line-search steps). MuJoCo's Newton solver, warm-started from the previous step,
converges within 4 iterations on almost every step of these bodies, so capping there
changes next to nothing (measured below) and makes a batch several times faster. The
hopper's RK4 integrator evaluates the dynamics four times a substep; semi-implicit Euler
(as Brax's hopper does) once, but that is another simulation.

One-step differences to gymnasium's options, both in MuJoCo's C engine (float64, so they are
the options' own), from the states of random-action episodes (5 cheetah, 60 hopper episodes;
max |Δ qvel| over the joints):

========  =======================  ========================  ======  ========  =========
body      solver                   options                   median  95th pct  max
========  =======================  ========================  ======  ========  =========
cheetah   ``fast``                 4 iterations, 4 ls steps  0       0         4.0e-3
hopper    ``fast``                 4 iterations, 4 ls steps  0       0         4.4e-16
hopper    ``euler``                ``fast`` + Euler          4.2e-3  9.3e-2    6.2e-1
cheetah   (2 iterations)           not offered               0       0.92      9.7
cheetah   (Euler damping off)      not offered               1.0     2.9       17
========  =======================  ========================  ======  ========  =========

against the hidden noise's N(0, 0.5²) on every joint velocity (``python
benchmarks/mjx_locomotion.py --accuracy`` measures it again). These are the states of random
actions; a policy that runs fast may meet contacts that need more iterations.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
from importlib import resources

from .interface import EnvError

ASSETS = "envs/mujoco/assets"
"""Where gymnasium keeps its MuJoCo model files, inside the installed package."""
XML = {"hopper": "hopper.xml", "cheetah": "half_cheetah.xml"}
"""Body → its model file among gymnasium's assets."""
INSTALL = "MuJoCo's JAX backend is missing: pip install 'mindgap[gym]' (it brings mujoco-mjx)"


@dataclasses.dataclass(frozen=True)
class Solver:
    """MuJoCo options set on the model before MJX takes it; None keeps the model file's.

    Attributes:
        iterations: the constraint solver's iteration cap (``opt.iterations``; MuJoCo's default 100).
        ls_iterations: the line search's step cap (``opt.ls_iterations``; default 50).
        integrator: ``"euler"`` (semi-implicit), ``"rk4"`` or ``"implicitfast"`` (``opt.integrator``).
    """

    iterations: int | None = None
    ls_iterations: int | None = None
    integrator: str | None = None

    def as_numbers(self) -> tuple[int, int, int]:
        """(iterations, ls_iterations, integrator) with −1 for the model's own: what a world's fingerprint hashes."""
        integrators = {None: -1, "euler": 0, "rk4": 1, "implicitfast": 3}
        return (self.iterations or -1, self.ls_iterations or -1, integrators[self.integrator])


SOLVERS = {
    "gym": Solver(),
    "fast": Solver(iterations=4, ls_iterations=4),
    "euler": Solver(iterations=4, ls_iterations=4, integrator="euler"),
}
"""Named solver options: ``gym`` keeps gymnasium's (the model file's and MuJoCo's defaults);
``fast`` caps the solver (the same simulation within the table above); ``euler`` also
integrates with semi-implicit Euler (the cheetah already does; the hopper's RK4 becomes
Euler: another simulation, four to ten times faster on two CPU cores)."""


def mjx():
    """The ``mujoco.mjx`` module, or one line saying which extra installs it.

    MJX prints a line on import when its optional Warp backend is absent (it is not needed
    here: these worlds use MJX's JAX implementation), so its import runs with stdout muted.
    """
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            from mujoco import mjx as module
    except ImportError:
        raise EnvError(INSTALL) from None
    return module


def xml_path(body: str) -> str:
    """The path of ``body``'s model file in the installed gymnasium."""
    if body not in XML:
        raise EnvError(f"no MJX body {body!r}; there are: {', '.join(XML)}")
    path = resources.files("gymnasium") / ASSETS / XML[body]
    if not path.is_file():
        raise EnvError(f"gymnasium's MuJoCo model {XML[body]} is not installed: pip install 'mindgap[gym]'")
    return str(path)


@functools.cache
def load_model(body: str, solver: str = "fast"):
    """``body``'s MuJoCo model from gymnasium's file with the options of ``SOLVERS[solver]``
    (a ``mujoco.MjModel``, float64, for MuJoCo's C engine and to hand to MJX)."""
    if solver not in SOLVERS:
        raise EnvError(f"no solver options {solver!r}; there are: {', '.join(SOLVERS)}")
    try:
        import mujoco
    except ImportError:
        raise EnvError(INSTALL) from None
    model = mujoco.MjModel.from_xml_path(xml_path(body))
    opt = SOLVERS[solver]
    if opt.iterations is not None:
        model.opt.iterations = opt.iterations
    if opt.ls_iterations is not None:
        model.opt.ls_iterations = opt.ls_iterations
    if opt.integrator is not None:
        model.opt.integrator = {
            "euler": mujoco.mjtIntegrator.mjINT_EULER,
            "rk4": mujoco.mjtIntegrator.mjINT_RK4,
            "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        }[opt.integrator]
    return model


def put_model(body: str, solver: str = "fast"):
    """(the MJX model, a blank MJX data) of :func:`load_model`, on JAX's default device, MJX's JAX implementation,
    in float64 while JAX runs in 64 bits (``jax.enable_x64``), else float32."""
    import jax

    return _put_model(body, solver, bool(jax.config.read("jax_enable_x64")))


@functools.cache
def _put_model(body: str, solver: str, x64: bool):
    module = mjx()
    model = module.put_model(load_model(body, solver), impl="jax")
    return model, module.make_data(model, impl="jax")
