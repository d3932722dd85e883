"""A safety shield (run-time assurance) for any agent: each command checked against the bodies'
predicted motion, and replaced by the closest safe one when it would lead to a collision.

The check is a reachability test with backup (fallback) manoeuvres, the simplex / run-time
assurance pattern of [Hobbs23] (keys refer to docs/references.md): a command is *safe* when,
after flying it for one step, at least one backup manoeuvre keeps the chaser clear of every body
for the rest of a short horizon. Everything is predicted with the env's own exact model:

* the chaser by exact zero-order-hold CWH propagation (:func:`debris_gym.dynamics.discretize`),
  sampled ``substeps`` times per step;
* the bodies by their known CWH motion, exactly as the moving-field planners see them
  (:class:`agents.planners.motion.FieldMotion`, :class:`agents.planners.spacetime.SpaceTimeField`
  on the same sample grid), each body as its circumscribed circle / sphere grown by the chaser's
  radius;
* clearance along the path, not only at samples: between two samples both the chaser and a body
  centre are replaced by straight segments, the distance of the relative segment to the origin
  has a closed form, and the interpolation error of both (a·h²/8 for an acceleration bounded by
  a over a sample interval h) is added to the body's radius.

Backup manoeuvres: brake to rest in LVLH, or to the velocity of one of the nearest bodies
(deadbeat each step: the acceleration that would cancel the relative velocity at the step's end,
cut to the thrust limit by the env's thrust model, or the nearest discrete action), then hold it.

Required clearance: ``margin`` (m) from debris, ``target_margin`` (m, default 0: touching is
still refused) from targets, whose capture zone lies just outside their surface. A body already
closer than its margin (after a capture, say) must not come closer than it is now, so a shield
never blocks the way out.

The command passes unchanged (the very object) when it is safe. Otherwise the candidates —
scaled copies of the command, blends of it with each backup's first action, and a grid of the
action space (every discrete action in ``action="discrete"``) — are tried in order of distance
to the command (of the accelerations they command), and the first safe one is flown; if none
is safe, the one with the largest predicted clearance.

Teammates: filtering one chaser of a swarm (its :class:`~agents.policies.chaser_view.
ChaserView`), the other chasers still in the field are bodies too, each a sphere of the
collision distance on its predicted track (the view's ``teammates``: its shared plan flown on
from where it is, coasting without one, standing when held; :mod:`agents.planners.teammates`),
sampled between whole steps on the chord, whose distance from the true path (a·dt²/8, a its
thrust limit plus the natural CWH term along the track, 5 % spare) is added to its reach;
``margin`` applies to them as to debris. This is a check against a prediction, not a
guarantee for the pair: a teammate that re-plans, or whose own shield changes its command,
leaves its predicted track (each re-check starts from its true state).

The shield reads only the env's public state: ``scenario``, ``chaser_state``, ``elapsed``,
``config`` (and a view's ``teammates``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from agents.planners.motion import FieldMotion
from agents.planners.spacetime import SpaceTimeField
from agents.planners.teammates import chord_error
from agents.policies.base import field_view, teammates_of
from debris_gym.dynamics import cwh_acceleration, discretize
from debris_gym.envs.common import (
    checked_continuous_actions,
    checked_discrete_action,
    discrete_action_table,
)
from debris_gym.scenario import Scenario
from debris_gym.thrust import action_for_accel, commanded_accel

__all__ = ["SafetyShield", "ShieldDecision", "ShieldParams"]

_LIMITS: dict[str, tuple[float, float]] = {
    "horizon_steps": (1, 200),
    "substeps": (1, 64),
    "margin": (0.0, 1e6),
    "target_margin": (0.0, 1e6),
    "directions": (4, 512),
    "levels": (1, 16),
    "fallback_bodies": (0, 32),
}
"""Allowed range (inclusive) of every :class:`ShieldParams` field."""


@dataclass(frozen=True)
class ShieldParams:
    """Tunables of :class:`SafetyShield`.

    Attributes:
        horizon_steps: look-ahead in env steps (the candidate step plus the backup manoeuvre),
            in [1, 200]. It must cover the braking time (speed / thrust limit) to be of use.
        substeps: samples of the path per step, in [1, 64]; clearance between samples is
            bounded analytically, so more samples only make the bound tighter.
        margin: clearance (m) kept from debris beyond contact (chaser radius included by the
            env), in [0, 1e6]; None: the env's ``chaser_radius`` (1 m in the Rendezvous IDs,
            0.1 in the 20-unit PaperField2D-v0 world), so the margin scales with the world,
            plus 3·√2·``nav_sigma_position`` when the env's observations carry navigation
            errors (the shield then acts on the observed state and field).
        target_margin: clearance (m) kept from targets, in [0, 1e6]; keep it below the
            env's ``capture_radius`` or captures become impossible.
        directions: thrust directions of the candidate grid (on a circle in 2D, a Fibonacci
            sphere in 3D; box thrust uses a per-axis grid instead), in [4, 512].
        levels: thrust magnitudes of the candidate grid (k / levels of the limit), in [1, 16].
        fallback_bodies: how many of the nearest bodies the backups may brake to the velocity
            of (besides rest in LVLH), in [0, 32].
    """

    horizon_steps: int = 10
    substeps: int = 4
    margin: float | None = None
    target_margin: float = 0.0
    directions: int = 16
    levels: int = 2
    fallback_bodies: int = 3

    def __post_init__(self) -> None:
        for name, (low, high) in _LIMITS.items():
            value = getattr(self, name)
            if name == "margin" and value is None:
                continue
            integer = isinstance(low, int)
            kind = "an integer" if integer else "a finite number"
            ok = (
                isinstance(value, (int, np.integer))
                if integer
                else isinstance(value, (int, float, np.integer, np.floating))
            )
            if isinstance(value, bool) or not ok or not (low <= value <= high):
                none = " or None" if name == "margin" else ""
                raise ValueError(f"{name} must be {kind} in [{low}, {high}]{none}, got {value!r}")
            if not integer and not math.isfinite(value):
                raise ValueError(f"{name} must be {kind} in [{low}, {high}], got {value!r}")

    def to_dict(self) -> dict[str, Any]:
        """The parameters as a plain dict (for summaries and manifests)."""
        return asdict(self)


@dataclass(frozen=True)
class ShieldDecision:
    """What :meth:`SafetyShield.decide` concluded for one command.

    Attributes:
        action: the action to fly (the command itself when it was safe).
        intervened: whether it differs from the command.
        size: ‖u_safe − u_cmd‖ / max_accel, the change of commanded acceleration as a fraction
            of the thrust limit (0 when passed through).
        clearance: predicted least clearance (m) beyond the required margins of the action
            flown and its best backup (negative: no safe action was found).
    """

    action: Any
    intervened: bool
    size: float
    clearance: float


@dataclass(frozen=True)
class _Setting:
    """What one decision needs, computed once per call (units: m, m/s, m/s², s).

    Attributes:
        x0: the chaser's state now (2·dim,).
        n, h: mean motion (rad/s) and the sample interval (s).
        max_accel: thrust limit (m/s²).
        sub: the exact ZOH model over one sample interval.
        brake_gain: (dim, 2·dim) the deadbeat gain: u = gain · (state relative to a reference)
            cancels the relative velocity at the end of one step.
        centres: (T + 1, B, dim) the bodies' centres on the sample grid.
        reach: (B,) centre distance of contact (body radius + chaser radius + interpolation
            error of the body's path).
        centre_gap: (B,) the chaser's distance to each body centre now.
        margins: (B,) required clearance beyond contact (debris: margin, targets:
            target_margin).
        ref_states: (K, F, 2·dim) the state each backup brakes to at every step (zeros: rest in
            LVLH).
    """

    x0: np.ndarray
    n: float
    h: float
    max_accel: float
    sub: Any
    brake_gain: np.ndarray
    centres: np.ndarray
    reach: np.ndarray
    centre_gap: np.ndarray
    margins: np.ndarray
    ref_states: np.ndarray


class SafetyShield:
    """Run-time assurance filter for one DebrisGym env (see the module docstring).

    Args:
        env: the env (wrapped or not), or a :class:`~agents.policies.base.FieldView` (one
            chaser of a swarm), whose commands are filtered; its public state is read at every
            call, so build the shield once and keep it across episodes.
        params: tunables; None: :class:`ShieldParams` defaults.
    """

    def __init__(self, env: Any, params: ShieldParams | None = None) -> None:
        self.env = field_view(env)
        self._teammates = teammates_of(self.env)
        if params is not None and not isinstance(params, ShieldParams):
            raise TypeError(f"params must be a ShieldParams, got {type(params).__name__}")
        self.params = params if params is not None else ShieldParams()
        cfg = self.env.config
        self.dim = cfg.dim
        self.discrete = cfg.action == "discrete"
        self.thrust_model = cfg.thrust_model
        self.table = discrete_action_table(cfg.dim, cfg.fine_thrust) if self.discrete else None
        self.chaser_radius = float(cfg.chaser_radius)
        self._scenario: Scenario | None = None
        self._motion: FieldMotion | None = None
        self._unit_grid = self._grid_directions()

    # --- the public interface -----------------------------------------------------------------

    def filter(self, action: Any) -> tuple[Any, bool]:
        """The action to fly instead of ``action`` and whether the shield changed it.

        A safe ``action`` is returned as it is (the same object).

        Raises:
            ValueError: naming ``action`` (NaN, inf, wrong shape or type; a discrete index out
                of range).
            RuntimeError: the env has not been reset.
        """
        decision = self.decide(action)
        return decision.action, decision.intervened

    def decide(self, action: Any) -> ShieldDecision:
        """Like :meth:`filter`, with the intervention's size and the predicted clearance."""
        u_cmd = self._command_accel(action)
        setting = self._setting()
        clearance = float(self._scores(setting, u_cmd[None])[0])
        if clearance >= 0.0:
            return ShieldDecision(action, False, 0.0, clearance)
        actions, accels = self._candidates(setting, u_cmd)
        scores = self._scores(setting, accels)
        order = np.argsort(np.linalg.norm(accels - u_cmd, axis=1), kind="stable")
        safe = order[scores[order] >= 0.0]
        best = int(safe[0]) if len(safe) else int(np.argmax(scores))
        size = float(np.linalg.norm(accels[best] - u_cmd)) / setting.max_accel
        chosen = int(actions[best]) if self.discrete else actions[best].copy()
        if size == 0.0:  # the command's own twin won: fly the command itself
            return ShieldDecision(action, False, 0.0, float(scores[best]))
        return ShieldDecision(chosen, True, size, float(scores[best]))

    # --- commands and candidates --------------------------------------------------------------

    def _command_accel(self, action: Any) -> np.ndarray:
        """The acceleration (m/s²) ``action`` commands, after the env's own input checks."""
        scen = self._current_scenario()
        if self.table is not None:  # a discrete action space
            index = checked_discrete_action(action, len(self.table))
            return self.table[index] * scen.max_accel
        a = checked_continuous_actions(action, (self.dim,))
        return commanded_accel(a, scen.max_accel, self.thrust_model)

    def _grid_directions(self) -> np.ndarray:
        """Unit thrust directions of the candidate grid (ball thrust)."""
        k = self.params.directions
        if self.dim == 2:
            angle = 2.0 * math.pi * np.arange(k) / k
            return np.stack([np.cos(angle), np.sin(angle)], axis=1)
        i = np.arange(k) + 0.5  # Fibonacci sphere: near-uniform directions
        polar = np.arccos(1.0 - 2.0 * i / k)
        azimuth = math.pi * (1.0 + 5**0.5) * i
        return np.stack(
            [np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)],
            axis=1,
        )

    def _candidates(self, setting: _Setting, u_cmd: np.ndarray) -> tuple[Any, np.ndarray]:
        """Candidate actions and the accelerations (m/s²) they command, the command's first."""
        amax = setting.max_accel
        if self.table is not None:  # a discrete action space
            return np.arange(len(self.table)), self.table * amax
        p = self.params
        levels = np.arange(1, p.levels + 1) / p.levels
        if self.thrust_model == "box":  # per-axis thrusters: a grid of the box
            ticks = np.linspace(-1.0, 1.0, 2 * p.levels + 1)
            grid = np.stack(np.meshgrid(*[ticks] * self.dim, indexing="ij"), -1)
            grid = grid.reshape(-1, self.dim) * amax
        else:
            grid = (levels[:, None, None] * self._unit_grid[None]).reshape(-1, self.dim) * amax
        brakes = self._first_backup_accels(setting)
        blend = np.array([0.25, 0.5, 0.75, 1.0])[:, None, None]
        blends = ((1.0 - blend) * u_cmd + blend * brakes[None]).reshape(-1, self.dim)
        scaled = np.array([1.0, 0.75, 0.5, 0.25, 0.0])[:, None] * u_cmd
        accels = np.concatenate([scaled, blends, grid])
        # the actions the env will be given (float32, as its action space), and what they
        # command after its thrust model: the candidates are judged on what is really flown
        actions = action_for_accel(accels, amax, self.thrust_model).astype(np.float32)
        return actions, commanded_accel(actions.astype(float), amax, self.thrust_model)

    # --- the prediction -----------------------------------------------------------------------

    def _current_scenario(self) -> Scenario:
        scen = self.env.scenario
        if scen is None:
            raise RuntimeError("the shield's env has not been reset: call env.reset() first")
        return scen

    def _own_margin(self) -> float:
        """The clearance kept from debris and teammates (m): ``margin``, or by default the
        chaser's radius plus, with navigation errors, three standard deviations of the error of
        a relative position along one axis (3·√2·``nav_sigma_position``: the chaser's and the
        body's errors are independent)."""
        if self.params.margin is not None:
            return float(self.params.margin)
        return self.chaser_radius + 3.0 * math.sqrt(2.0) * self.env.config.nav_sigma_position

    def _setting(self) -> _Setting:
        """Everything one decision needs: models, the bodies on the sample grid, backups."""
        scen = self._current_scenario()
        if scen is not self._scenario or self._motion is None:  # a new field: its motion, once
            self._scenario, self._motion = scen, FieldMotion(scen)
        p, d = self.params, self.dim
        dt, n = float(scen.dt), float(scen.mean_motion)
        h = dt / p.substeps
        t0 = self.env.elapsed
        n_bodies = len(scen.bodies)
        field = SpaceTimeField(
            self._motion, t0, p.horizon_steps * dt,
            inflation=np.full(n_bodies, self.chaser_radius), step=h,
        )  # fmt: skip
        samples = p.horizon_steps * p.substeps + 1
        x0 = np.asarray(self.env.chaser_state, dtype=float)
        bodies_now = self._motion.states(t0)
        reach = field.reach.copy()
        centre_gap = np.linalg.norm(x0[:d] - bodies_now[:, :d], axis=1)
        margins = np.full(n_bodies, self._own_margin())
        margins[: len(scen.targets)] = p.target_margin
        # backups: rest in LVLH (-1), then the velocity of each of the nearest bodies
        refs = [-1]
        if scen.moving and p.fallback_bodies > 0:
            nearest = np.argsort(centre_gap - reach, kind="stable")[: p.fallback_bodies]
            refs += [int(b) for b in nearest]
        ref_states = np.zeros((p.horizon_steps, len(refs), 2 * d))
        for k in range(p.horizon_steps):
            states = self._motion.states(t0 + k * dt)
            for j, b in enumerate(refs):
                if b >= 0:
                    ref_states[k, j] = states[b]
        model = discretize(n, dt, d)
        centres = field.centres[:samples]
        if self._teammates is not None:
            centres, reach, centre_gap, margins = self._with_teammates(
                centres, reach, centre_gap, margins, x0, float(scen.max_accel), dt, n
            )
        return _Setting(
            x0=x0, n=n, h=h, max_accel=float(scen.max_accel), sub=discretize(n, h, d),
            brake_gain=-np.linalg.solve(model.bd[d:], model.ad[d:]),
            centres=centres, reach=reach, centre_gap=centre_gap,
            margins=margins, ref_states=ref_states,
        )  # fmt: skip

    def _with_teammates(
        self,
        centres: np.ndarray,
        reach: np.ndarray,
        centre_gap: np.ndarray,
        margins: np.ndarray,
        x0: np.ndarray,
        max_accel: float,
        dt: float,
        n: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The bodies' sample-grid centres (T + 1, B, dim), reach, present centre distance and
        margins (B,), followed by the teammates' (see the module docstring)."""
        p, d = self.params, self.dim
        assert self._teammates is not None
        mates = self._teammates(p.horizon_steps)
        if mates.count == 0:
            return centres, reach, centre_gap, margins
        tracks = mates.tracks.transpose(1, 0, 2)  # (H + 1, J, d) at whole steps
        frac = (np.arange(p.horizon_steps * p.substeps + 1) / p.substeps)[:, None, None]
        k = np.minimum(frac[:, 0, 0].astype(np.int64), p.horizon_steps - 1)
        sampled = tracks[k] + (frac - k[:, None, None]) * (tracks[k + 1] - tracks[k])
        thrust = max_accel * (math.sqrt(d) if self.thrust_model == "box" else 1.0)
        chord = chord_error(mates.tracks, dt, n, thrust)
        mate_reach = mates.radii + self.chaser_radius + chord
        own = self._own_margin()
        return (
            np.concatenate([centres, sampled], axis=1),
            np.concatenate([reach, mate_reach]),
            np.concatenate([centre_gap, np.linalg.norm(x0[:d] - tracks[0], axis=1)]),
            np.concatenate([margins, np.full(mates.count, own)]),
        )

    def _saturate(self, u: np.ndarray, amax: float) -> np.ndarray:
        """Accelerations (N, d) cut to what the env can fly: its thrust model, or the nearest
        discrete action."""
        if self.table is not None:  # a discrete action space
            table = self.table * amax
            best = np.argmin(np.linalg.norm(u[:, None, :] - table[None], axis=2), axis=1)
            return table[best]
        return commanded_accel(u / amax, amax, self.thrust_model)

    def _backup_accels(self, setting: _Setting, x: np.ndarray, k: int) -> np.ndarray:
        """(C, F, d) deadbeat braking accelerations of every backup at step ``k``."""
        rel = x - setting.ref_states[k][None]  # (C, F, 2d)
        u = rel @ setting.brake_gain.T
        shape = u.shape
        return self._saturate(u.reshape(-1, self.dim), setting.max_accel).reshape(shape)

    def _first_backup_accels(self, setting: _Setting) -> np.ndarray:
        """(F, d) each backup's braking acceleration from the present state (m/s²)."""
        return self._backup_accels(setting, setting.x0[None, None], 0)[0]

    def _scores(self, setting: _Setting, accels: np.ndarray) -> np.ndarray:
        """(C,) predicted least clearance (m) beyond the required margins of each candidate
        acceleration flown for one step, with its best backup after it (>= 0: safe)."""
        p, d = self.params, self.dim
        sub, amax = setting.sub, setting.max_accel
        n_refs = setting.ref_states.shape[1]
        x = np.broadcast_to(setting.x0, (len(accels), n_refs, 2 * d)).copy()
        u = np.broadcast_to(accels[:, None, :], (*x.shape[:2], d))
        states = [x]
        for k in range(p.horizon_steps):
            if k > 0:
                u = self._backup_accels(setting, x, k)
            for _ in range(p.substeps):
                x = x @ sub.ad.T + u @ sub.bd.T
                states.append(x)
        path = np.stack(states)  # (T + 1, C, F, 2d)
        # the chaser's deviation from a straight line between samples: a·h²/8 with a its largest
        # acceleration (thrust plus the natural CWH term), 5 % spare as the bodies' bound has
        thrust = amax * (math.sqrt(d) if self.thrust_model == "box" else 1.0)
        natural = np.linalg.norm(cwh_acceleration(path, setting.n), axis=-1).max()
        slack = 1.05 * (thrust + natural) * setting.h**2 / 8.0
        reach = setting.reach + slack  # (B,)
        # a body already closer than its margin must only not come closer than it is now
        # (1 µm below its present gap, so rounding cannot make the present state unsafe)
        now = setting.centre_gap - reach
        margins = setting.margins
        need = reach + np.where(now < margins, now - 1e-6, margins)
        rel = path[:, :, :, None, :d] - setting.centres[:, None, None, :, :]  # (T+1,C,F,B,d)
        a, seg = rel[:-1], rel[1:] - rel[:-1]
        den = np.einsum("...d,...d->...", seg, seg)
        s = np.clip(-np.einsum("...d,...d->...", a, seg) / np.maximum(den, 1e-300), 0.0, 1.0)
        near = a + s[..., None] * seg
        closest = np.sqrt(np.einsum("...d,...d->...", near, near).min(axis=0))  # (C, F, B)
        gap = (closest - need).min(axis=-1, initial=np.inf)  # (C, F)
        return gap.max(axis=1)
