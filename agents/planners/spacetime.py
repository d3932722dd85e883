"""The moving bodies as a space-time field: clearance at (position, time) and straight-edge checks.

The Tube-ST-RRT* planner ([Zhou24], after [Grothe22]; keys refer to docs/references.md) works in
position × time. :class:`SpaceTimeField` gives it what it asks, in a *planning frame*: the LVLH
frame, or the frame of one body (the goal target), whose origin moves with that body. The
chaser's motion relative to any body obeys the same CWH law, so a body's frame is as good a place
to plan in as LVLH; in the goal target's frame the goal is a fixed point and the goal target
stands still.

How the bodies are represented:

* their centres on a time grid t₀ + k·h (h = the env's step), propagated from their states at t₀
  with the env's own exact model (:func:`debris_gym.dynamics.discretize`; a frozen field's bodies
  stay where they are), minus the frame
  body's centre; between grid points the centres are interpolated linearly, and the
  interpolation error — at most a·h²/8 for a relative acceleration bounded by a — is added to
  every body's inflation (a is the largest natural CWH acceleration of the relative motion on
  the grid, with 5 % to spare for the grid's sampling of the sinusoid);
* every body as its circumscribed circle / sphere (``Body.radius``): for a polygon this is
  conservative, and it makes the polygon's attitude irrelevant.

Moving spheres besides the field's bodies (``movers``: the teammates of a swarm's chaser on their
predicted tracks, :mod:`agents.planners.teammates`) join the bodies as extra columns: their
positions on the same grid minus the frame body's, each grown by its own inflation plus the
distance its true path may stray from the chords between grid points (its thrust limit plus the
natural CWH term of its motion relative to the frame: :func:`~agents.planners.teammates.
chord_error`).

A straight space-time edge (p₀, t₀) → (p₁, t₁) is checked exactly against that representation:
on each grid interval the chaser's position and every body's interpolated centre are both linear
in time, so their difference is a segment and its distance to the origin has a closed form
(:meth:`SpaceTimeField.edge_clear`). No sampling, nothing tunnels.
"""

from __future__ import annotations

import math

import numpy as np

from agents.planners.motion import FieldMotion
from agents.planners.teammates import MovingSpheres, chord_error
from debris_gym.dynamics import cwh_acceleration, discretize

__all__ = ["SpaceTimeField"]


class SpaceTimeField:
    """The bodies of a moving field over a time window, seen from a planning frame.

    Args:
        motion: the bodies' predicted motion.
        start_time: t₀ (s since the episode began): the window's start.
        horizon: window length (s); queries are clamped to the window's end.
        frame: index of the body whose frame to plan in; None: LVLH (the dock's frame).
        inflation: (n_bodies,) distance (m) every body is grown by (the chaser's radius plus a
            margin); a body with ``inf`` is left out. None: zeros.
        step: grid step h (s); None: the scenario's ``dt``.
        movers: moving spheres to keep out of besides the bodies (a swarm's teammates), their
            tracks (LVLH, m) at t₀, t₀ + h, … covering the window (K+1 positions or more);
            None: none.
        mover_inflation: distance (m) every mover is grown by (one, or one per mover).
        mover_thrust: largest thrust acceleration (m/s²) of a mover that moves: its path
            between grid points may stray from the chord by what this and its natural CWH
            motion allow, which is added to its reach.

    Attributes:
        t0, t_end: the window (s).
        frame_track: (K+1, 2·dim) the frame body's LVLH state on the grid (zeros for LVLH).
        body_speed: (n_bodies,) largest speed (m/s) of each body in the planning frame on the grid.
        n_movers: J, the movers; columns ``n_bodies … n_bodies + J − 1`` of :meth:`gaps`.
    """

    def __init__(
        self,
        motion: FieldMotion,
        start_time: float,
        horizon: float,
        frame: int | None = None,
        inflation: np.ndarray | None = None,
        step: float | None = None,
        movers: MovingSpheres | None = None,
        mover_inflation: float | np.ndarray = 0.0,
        mover_thrust: float = 0.0,
    ) -> None:
        scen = motion.scenario
        if not (math.isfinite(start_time) and start_time >= 0):
            raise ValueError(f"start_time must be finite and >= 0 s, got {start_time!r}")
        if not (math.isfinite(horizon) and horizon > 0):
            raise ValueError(f"horizon must be finite and > 0 s, got {horizon!r}")
        h = float(step) if step is not None else float(scen.dt)
        if not (math.isfinite(h) and h > 0):
            raise ValueError(f"step must be finite and > 0 s, got {step!r}")
        n_bodies = len(scen.bodies)
        if frame is not None and not 0 <= frame < n_bodies:
            raise ValueError(f"frame must be a body index in [0, {n_bodies}) or None: {frame!r}")
        self.dim = d = scen.dim
        self.scenario = scen
        self.frame = frame
        self.h = h
        self.t0 = float(start_time)
        count = max(2, math.ceil(horizon / h) + 1)
        self.t_end = self.t0 + (count - 1) * h
        ad = discretize(scen.mean_motion, h, d).ad
        states = np.empty((count, n_bodies, 2 * d))
        states[0] = motion.states(self.t0)
        for k in range(1, count):  # a frozen field stands still
            states[k] = states[k - 1] @ ad.T if scen.moving else states[0]
        if frame is None:
            self.frame_track = np.zeros((count, 2 * d))
        else:
            self.frame_track = states[:, frame].copy()
        rel = states - self.frame_track[:, None, :]
        self.centres = np.ascontiguousarray(rel[..., :d])  # (K+1, B, d)
        self.radii = np.array([b.radius for b in scen.bodies], dtype=float)
        self.body_speed = np.linalg.norm(rel[..., d:], axis=2).max(axis=0)
        accel = np.linalg.norm(cwh_acceleration(rel, scen.mean_motion), axis=2).max(axis=0)
        accel = accel if scen.moving else np.zeros(n_bodies)
        self.interp_error = 1.05 * accel * h * h / 8.0
        inflation = np.zeros(n_bodies) if inflation is None else np.asarray(inflation, float)
        if inflation.shape != (n_bodies,) or np.any(np.isnan(inflation)):
            raise ValueError(f"inflation must be a ({n_bodies},) array of distances (m)")
        self.inflation = inflation
        self.active = np.isfinite(inflation)
        self.n_movers = 0
        if movers is not None and movers.count:
            self._add_movers(movers, mover_inflation, mover_thrust, scen.mean_motion)
        # distance a centre must keep: radius + inflation + interpolation error
        self.reach = np.where(self.active, self.radii + self.inflation + self.interp_error, -np.inf)
        self.low = scen.low
        self.high = scen.high

    def _add_movers(
        self, movers: MovingSpheres, inflation: float | np.ndarray, thrust: float, n: float
    ) -> None:
        """Append the movers' columns to the bodies' (centres, radii, inflation, chord error)."""
        count, j = len(self.centres), movers.count
        tracks = np.asarray(movers.tracks, dtype=float)
        if tracks.shape[1] < count or tracks.shape[2] != self.dim:
            raise ValueError(
                f"movers' tracks must cover the window: ({j}, >= {count}, {self.dim}) "
                f"positions, got shape {tracks.shape}"
            )
        grow = np.broadcast_to(np.asarray(inflation, dtype=float), (j,))
        if np.any(np.isnan(grow)):
            raise ValueError(f"mover_inflation must be distances (m), got {inflation!r}")
        if not (math.isfinite(thrust) and thrust >= 0):
            raise ValueError(f"mover_thrust must be finite and >= 0 m/s², got {thrust!r}")
        rel = tracks[:, :count] - self.frame_track[None, :, : self.dim]  # (J, K+1, d)
        # a mover that stands still in LVLH does not thrust; in a body's frame it still moves
        still = ~np.any(tracks[:, 1:count] != tracks[:, : count - 1], axis=(1, 2))
        error = chord_error(rel, self.h, n, np.where(still, 0.0, thrust))
        self.centres = np.ascontiguousarray(
            np.concatenate([self.centres, rel.transpose(1, 0, 2)], axis=1)
        )
        self.radii = np.concatenate([self.radii, np.asarray(movers.radii, dtype=float)])
        self.inflation = np.concatenate([self.inflation, grow])
        self.active = np.concatenate([self.active, np.isfinite(grow)])
        self.interp_error = np.concatenate([self.interp_error, error])
        self.n_movers = j

    # --- time grid ----------------------------------------------------------------------------

    def _locate(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grid interval index and fraction of each time (clamped to the window)."""
        x = np.clip((np.asarray(times, float) - self.t0) / self.h, 0.0, len(self.centres) - 1)
        k = np.minimum(np.floor(x).astype(np.int64), len(self.centres) - 2)
        return k, x - k

    def body_centres(self, times: np.ndarray) -> np.ndarray:
        """(M, B, dim) body centres (m, planning frame) at each time (s)."""
        k, f = self._locate(times)
        c = self.centres
        return c[k] + (c[k + 1] - c[k]) * f[:, None, None]

    def frame_position(self, times: np.ndarray) -> np.ndarray:
        """(M, dim) the frame's origin in LVLH (m) at each time (s)."""
        k, f = self._locate(times)
        track = self.frame_track[:, : self.dim]
        return track[k] + (track[k + 1] - track[k]) * f[:, None]

    # --- clearance ----------------------------------------------------------------------------

    def gaps(self, points: np.ndarray, times: np.ndarray) -> np.ndarray:
        """(M, B) distance (m) from each point to each body grown by its inflation, at the point's
        own time (circumscribed circles; +inf for a body left out)."""
        pts = np.asarray(points, float).reshape(-1, self.dim)
        centres = self.body_centres(np.broadcast_to(times, (len(pts),)))
        dist = np.linalg.norm(pts[:, None, :] - centres, axis=2)
        return np.where(self.active, dist - self.reach, np.inf)

    def clearance(self, points: np.ndarray, times: np.ndarray) -> np.ndarray:
        """(M,) the largest radius (m) of a ball around each point, at its time, that no grown
        body enters (negative: the point is inside one); +inf with no body."""
        gaps = self.gaps(points, times)
        return gaps.min(axis=1, initial=np.inf)

    def in_bounds(self, points: np.ndarray, times: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(M,) whether each point (planning frame) lies inside the world bounds in LVLH, shrunk
        by ``margin`` (m), at its time."""
        pts = np.asarray(points, float).reshape(-1, self.dim)
        lvlh = pts + self.frame_position(np.broadcast_to(times, (len(pts),)))
        return np.all((lvlh >= self.low + margin) & (lvlh <= self.high - margin), axis=1)

    def node(self, point: np.ndarray, time: float, margin: float = 0.0) -> tuple[float, bool]:
        """One state's clearance (m, as :meth:`clearance`) and whether it lies in the bounds
        shrunk by ``margin`` (m, as :meth:`in_bounds`): the two in one look-up."""
        x = min(max((time - self.t0) / self.h, 0.0), len(self.centres) - 1.0)
        k = min(int(x), len(self.centres) - 2)
        f = x - k
        c0, c1 = self.centres[k], self.centres[k + 1]
        diff = point - (c0 + (c1 - c0) * f)
        dist = np.sqrt(np.einsum("bd,bd->b", diff, diff))
        gap = float(np.min(np.where(self.active, dist - self.reach, np.inf), initial=np.inf))
        o0, o1 = self.frame_track[k, : self.dim], self.frame_track[k + 1, : self.dim]
        lvlh = point + o0 + (o1 - o0) * f
        inside = bool(np.all(lvlh >= self.low + margin) and np.all(lvlh <= self.high - margin))
        return gap, inside

    # --- edges --------------------------------------------------------------------------------

    def edge_gap(self, p0: np.ndarray, t0: float, p1: np.ndarray, t1: float) -> float:
        """Smallest distance (m) over the straight space-time edge to any grown body.

        The edge is cut at every grid time between ``t0`` and ``t1`` (s, ``t0 <= t1``); on each
        piece the chaser-minus-centre vector is linear in time, so its least norm is the
        distance from the origin to a segment.
        """
        lo, hi = (t0, t1) if t0 <= t1 else (t1, t0)
        k_lo = math.floor((lo - self.t0) / self.h) + 1
        k_hi = math.ceil((hi - self.t0) / self.h) - 1
        inner = self.t0 + self.h * np.arange(max(k_lo, 0), min(k_hi, len(self.centres) - 1) + 1)
        times = np.concatenate([[lo], inner[(inner > lo) & (inner < hi)], [hi]])
        span = t1 - t0
        frac = (times - t0) / span if span != 0.0 else np.zeros_like(times)
        chaser = np.asarray(p0, float) + frac[:, None] * (np.asarray(p1, float) - p0)
        rel = chaser[:, None, :] - self.body_centres(times)  # (T, B, d)
        a, b = rel[:-1], rel[1:]
        seg = b - a
        den = np.einsum("tbd,tbd->tb", seg, seg)
        s = np.clip(-np.einsum("tbd,tbd->tb", a, seg) / np.maximum(den, 1e-300), 0.0, 1.0)
        near = a + s[..., None] * seg
        closest = np.sqrt(np.einsum("tbd,tbd->tb", near, near).min(axis=0))  # (B,)
        gaps = np.where(self.active, closest - self.reach, np.inf)
        return float(gaps.min(initial=np.inf))

    def edge_clear(self, p0: np.ndarray, t0: float, p1: np.ndarray, t1: float) -> bool:
        """True when the straight space-time edge keeps out of every grown body."""
        return self.edge_gap(p0, t0, p1, t1) >= 0.0
