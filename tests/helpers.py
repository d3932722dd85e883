"""Builders that several test modules share."""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from numpy.typing import ArrayLike
from scipy.integrate import solve_ivp

from debris_gym.scenario import Body, Scenario

flies_old_ids = pytest.mark.filterwarnings(
    r"ignore:.*DebrisGym/[\w-]+-v[01] is out of date:DeprecationWarning"
)
"""Mark of a test (or ``pytestmark`` of a module) that flies an old version's ID on purpose (the
frozen world, v0, or the v1 rules, to reproduce their figures): it silences, there only,
gymnasium's notice that a newer version of the ID exists (which
``tests/test_env.py::test_an_old_id_warns_that_it_is_out_of_date`` checks is given)."""


def simple_scenario(**overrides) -> Scenario:
    """Free-space field: one target 100 m along-track, one circle obstacle, dock at origin.

    Its physics (``mean_motion=0``, ``dt=10``, ``max_accel=0.05``) are free space: an env with
    the default LEO orbit flies it in free space, with a warning that the physics differ.
    """
    data = dict(
        dim=2,
        bounds=((-500.0, 500.0), (-500.0, 500.0)),
        dock=(0.0, 0.0),
        targets=(Body(position=(0.0, 100.0), radius=5.0, velocity=(0.0, 0.0)),),
        obstacles=(Body(position=(200.0, 0.0), radius=20.0, velocity=(0.0, 0.0)),),
        mean_motion=0.0,
        dt=10.0,
        max_accel=0.05,
    )
    data.update(overrides)
    return Scenario(**data)


ROOT = Path(__file__).resolve().parents[1]
"""The repository root, where the scripts live."""


def load_script(file_name: str, module_name: str | None = None) -> ModuleType:
    """Import one of the repository's scripts (``"evaluate.py"``, ``"train.py"``, …) as a module
    without running its ``main``; each call gives a fresh module."""
    name = module_name or f"debris_script_{Path(file_name).stem}"
    spec = importlib.util.spec_from_file_location(name, ROOT / file_name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


LEO_MEAN_MOTION = 1.1314e-3
"""n (rad/s) of about 400 km LEO, the tests' moving-world orbit."""

MOVING_DT = 10.0
"""Step length (s) of the tests' moving-world envs."""

MOVING_WORLD = {
    "debris_motion": "bounded",
    "solid_targets": True,
    "capture_hold": 30.0,
    "capture_speed": 0.2,
    "mean_motion": LEO_MEAN_MOTION,
    "dt": MOVING_DT,
    "max_accel": 0.05,
}
"""Env options of the moving world (the v1 rules) with the tests' orbit, for pinned
``motion="cwh"`` scenarios."""


def moving_scenario(
    targets: Sequence[Body], obstacles: Sequence[Body], dim: int = 2, size: float = 1000.0
) -> Scenario:
    """A hand-built moving world (``motion="cwh"`` on the tests' orbit) in a cube of edge
    ``size`` centred on the dock. Its bodies may cross the dock, drift or leave the bounds within
    an episode, so it opts in to be flown anyway (``motion_faults="warn"``)."""
    half = size / 2
    return Scenario(
        dim=dim, bounds=((-half, half),) * dim, dock=(0.0,) * dim, targets=tuple(targets),
        obstacles=tuple(obstacles), mean_motion=LEO_MEAN_MOTION, dt=MOVING_DT, max_accel=0.05,
        motion="cwh", motion_faults="warn",
    )  # fmt: skip


def cw_closed_form(state0: np.ndarray, t: float, n: float = LEO_MEAN_MOTION) -> np.ndarray:
    """The textbook closed-form CW solution ([Curtis14] eq. 7.53), typed in here for the tests
    (unforced, 2D or 3D): independent of the library's matrix exponential."""
    dim = len(state0) // 2
    x0, y0, vx0, vy0 = state0[0], state0[1], state0[dim], state0[dim + 1]
    s, c = math.sin(n * t), math.cos(n * t)
    x = (4 - 3 * c) * x0 + s / n * vx0 + 2 / n * (1 - c) * vy0
    y = 6 * (s - n * t) * x0 + y0 - 2 / n * (1 - c) * vx0 + (4 * s - 3 * n * t) / n * vy0
    vx = 3 * n * s * x0 + c * vx0 + 2 * s * vy0
    vy = -6 * n * (1 - c) * x0 - 2 * s * vx0 + (4 * c - 3) * vy0
    if dim == 2:
        return np.array([x, y, vx, vy])
    z0, vz0 = state0[2], state0[5]
    return np.array([x, y, c * z0 + s / n * vz0, vx, vy, -n * s * z0 + c * vz0])


def cw_positions(states: np.ndarray, n: float, t: np.ndarray) -> np.ndarray:
    """The same textbook closed form, vectorised: positions (S, B, dim) at times ``t`` (S,) from
    states (B, 2·dim) at t = 0; straight lines for n = 0."""
    dim = states.shape[1] // 2
    if n == 0.0:
        return states[:, :dim][None] + states[:, dim:][None] * t[:, None, None]
    x0, y0, vx0, vy0 = (states[:, i][None] for i in (0, 1, dim, dim + 1))
    nt = (n * t)[:, None]
    s, c = np.sin(nt), np.cos(nt)
    x = (4.0 - 3.0 * c) * x0 + s / n * vx0 + 2.0 / n * (1.0 - c) * vy0
    y = 6.0 * (s - nt) * x0 + y0 - 2.0 / n * (1.0 - c) * vx0 + (4.0 * s - 3.0 * nt) / n * vy0
    out = [x, y]
    if dim == 3:
        z0, vz0 = states[:, 2][None], states[:, 5][None]
        out.append(c * z0 + s / n * vz0)
    return np.stack(out, axis=-1)


def cwh_rhs(n: float, dim: int, accel: ArrayLike) -> Callable[[float, np.ndarray], np.ndarray]:
    """Right-hand side of the CWH ODE with a constant commanded acceleration, typed from the
    equations (ẍ = 3n²x + 2nẏ + u_x, ÿ = −2nẋ + u_y, z̈ = −n²z + u_z), not from the library's
    ``cwh_matrices``."""
    accel = np.asarray(accel, dtype=float)

    def rhs(_t: float, s: np.ndarray) -> np.ndarray:
        if dim == 2:
            x, _y, vx, vy = s
            return np.array([vx, vy, 3 * n * n * x + 2 * n * vy + accel[0], -2 * n * vx + accel[1]])
        x, _y, z, vx, vy, vz = s
        return np.array(
            [
                vx,
                vy,
                vz,
                3 * n * n * x + 2 * n * vy + accel[0],
                -2 * n * vx + accel[1],
                -n * n * z + accel[2],
            ]
        )

    return rhs


def integrate_cwh(n: float, dim: int, state0: ArrayLike, accel: ArrayLike, t: float) -> np.ndarray:
    """The state after ``t`` s of ``accel`` held constant from ``state0``: :func:`cwh_rhs`
    integrated by DOP853 (rtol 1e-12, atol 1e-14)."""
    sol = solve_ivp(
        cwh_rhs(n, dim, accel),
        (0.0, t),
        np.asarray(state0, dtype=float),
        method="DOP853",
        rtol=1e-12,
        atol=1e-14,
    )
    assert sol.success
    return sol.y[:, -1]


def discounted(rewards: list[float], gamma: float) -> float:
    """The discounted return Σ γᵏ r_k of a list of rewards."""
    return float(sum(r * gamma**k for k, r in enumerate(rewards)))


def fly_policy(env, seed: int, policy) -> tuple[list[float], dict]:
    """One episode from ``env.reset(seed=seed)`` under ``policy(env, obs, info, first)``:
    its rewards and its last info."""
    obs, info = env.reset(seed=seed)
    rewards, done, first = [], False, True
    while not done:
        action = policy(env, obs, info, first)
        first = False
        obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(float(reward))
        done = terminated or truncated
    return rewards, info


def assert_same(a, b, what: str) -> None:
    """``a`` equals ``b``: exactly for booleans and integers, else to 1e-9 (relative and
    absolute); ``what`` names the quantity in the failure."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype == bool or b.dtype == bool or np.issubdtype(a.dtype, np.integer):
        np.testing.assert_array_equal(a, b, err_msg=what)
    else:
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=what)


def assert_same_step(out: tuple, expected: tuple, info_keys: Sequence[str], where: str) -> None:
    """Two ``step`` results agree (:func:`assert_same`): observation, reward, terminated,
    truncated, the infos' ``info_keys`` and every reward term; ``where`` names the step."""
    for name, a, b in zip(("obs", "reward", "terminated", "truncated"), out, expected):
        assert_same(a, b, f"{name} at {where}")
    for key in info_keys:
        assert_same(out[4][key], expected[4][key], f"info[{key!r}] at {where}")
    for term, value in out[4]["reward_terms"].items():
        assert_same(value, expected[4]["reward_terms"][term], f"reward term {term} at {where}")
