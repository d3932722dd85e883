"""Where the other chasers of a swarm will be: spheres on predicted tracks, and their keep-out.

A chaser's teammates are free bodies like the debris, but they thrust, so their future is not
the field's known CW motion. A team that shares its members' plans knows it better (the
prioritised-planning assumption, and [Bandyopadhyay17]'s swarm, whose agents exchange
information every step; keys refer to docs/references.md): :func:`predict_tracks` takes each
teammate's last shared plan, its states over the plan's horizon, and flies it on from the
teammate's true state now. The dynamics are linear, so a teammate that keeps flying the rest of
its planned thrust is where its plan says plus the unforced motion of its deviation from the
plan (x(now + j·dt) = plan(now + j·dt) + Φʲ (x_now − plan(now)), Φ the exact one-step CW
transition matrix): exact when it flies the plan, and a teammate whose plan ended, or that has
none, coasts on unforced CW motion. A chaser held at its formation slot (a reconfiguration's
arrived chasers: not simulated, they do not move) stays where it is.

A teammate is a sphere of radius ``r_col − chaser_radius`` (``r_col``: the centre distance at
or below which two chasers collide), so growing it by the chaser's radius, like every body of the
field, gives the collision distance. :func:`sphere_halfspaces` gives the MPC's keep-out
half-spaces of the nearest of them around each predicted position (the same supporting
half-spaces as for a round body: :class:`agents.control.mpc.MPCTracker`).

Between two predicted positions a teammate is taken on the chord; :func:`chord_error` bounds its
distance from the true path (a·dt²/8 for an acceleration bounded by a: its thrust limit plus
the natural CWH term along the track, 5 % spare), which the safety shield and the space-time
planner add to its reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from debris_gym.dynamics import cwh_acceleration

__all__ = [
    "MovingSpheres",
    "chord_error",
    "keepout_halfspaces",
    "predict_tracks",
    "sphere_halfspaces",
]


@dataclass(frozen=True)
class MovingSpheres:
    """Spheres (circles in 2D) on predicted tracks over a horizon.

    Attributes:
        tracks: (J, S + 1, dim) centres (m) at now, now + dt, …, now + S·dt.
        radii: (J,) radii (m).
    """

    tracks: np.ndarray
    radii: np.ndarray

    def __post_init__(self) -> None:
        tracks, radii = np.asarray(self.tracks), np.asarray(self.radii)
        if tracks.ndim != 3 or tracks.shape[1] < 1:
            raise ValueError(f"tracks must be (J, S + 1, dim) centres, got shape {tracks.shape}")
        if radii.shape != (tracks.shape[0],) or not np.all(np.isfinite(radii) & (radii >= 0)):
            raise ValueError(f"radii must be {tracks.shape[0]} finite values >= 0 m, got {radii}")

    @property
    def count(self) -> int:
        """J, the spheres."""
        return int(self.tracks.shape[0])

    @classmethod
    def none(cls, steps: int, dim: int) -> MovingSpheres:
        """No spheres, over ``steps`` steps in ``dim`` dimensions."""
        return cls(np.zeros((0, steps + 1, dim)), np.zeros(0))


def predict_tracks(
    states: np.ndarray,
    plans: list[np.ndarray | None],
    offsets: np.ndarray,
    held: np.ndarray,
    step_matrix: np.ndarray,
    steps: int,
) -> np.ndarray:
    """Each teammate's predicted positions at now, now + dt, …, now + ``steps``·dt (m).

    Args:
        states: (J, 2·dim) the teammates' states now (m, m/s).
        plans: per teammate, its last shared plan — (P + 1, 2·dim) states at t_p, t_p + dt,
            …, t_p + P·dt — or None (it coasts).
        offsets: (J,) whole steps from each plan's first state to now (now − t_p = offset·dt;
            ignored without a plan), >= 0.
        held: (J,) bool: held where it is (it does not move).
        step_matrix: (2·dim, 2·dim) the exact one-step transition matrix Φ of unforced CW
            motion (:func:`debris_gym.dynamics.discretize`'s ``ad``).
        steps: S, the horizon (steps).

    Returns:
        (J, S + 1, dim) positions (m); row j = 0 is each teammate's position now.
    """
    states = np.asarray(states, dtype=float)
    count, width = states.shape
    d = width // 2
    out = np.empty((count, steps + 1, d))
    for j in range(count):
        x_now = states[j]
        if held[j]:
            out[j] = x_now[:d]
            continue
        plan = plans[j]
        m = int(offsets[j])
        # the plan's states at now + i·dt (i = 0 … S), coasting on past its end; without a
        # plan, zeros (the teammate coasts from where it is)
        planned = np.zeros((steps + 1, width))
        if plan is not None:
            last = len(plan) - 1
            x = plan[last]
            for i in range(steps + 1):
                k = m + i
                if k <= last:
                    planned[i] = plan[k]
                else:
                    x = step_matrix @ x
                    planned[i] = x
        deviation = x_now - planned[0]
        for i in range(steps + 1):
            out[j, i] = planned[i, :d] + deviation[:d]
            deviation = step_matrix @ deviation
    return out


def chord_error(
    tracks: np.ndarray, dt: float, mean_motion: float, thrust: float | np.ndarray
) -> np.ndarray:
    """How far (m) each track's true path may stray from the chords between its positions.

    Between two positions dt apart a path whose acceleration is bounded by a lies within
    a·dt²/8 of its chord. The bound a is ``thrust`` plus the largest natural CWH acceleration
    along the track (its velocity taken from the chords), with 5 % to spare; a track that does
    not move strays not at all.

    Args:
        tracks: (J, S + 1, dim) positions (m) at t, t + dt, …, t + S·dt, S >= 1.
        dt: the spacing (s), > 0.
        mean_motion: n (rad/s) of the frame the tracks are in, >= 0.
        thrust: largest thrust acceleration (m/s²), one or (J,).

    Returns:
        (J,) distances (m).
    """
    tracks = np.asarray(tracks, dtype=float)
    if tracks.shape[0] == 0:
        return np.zeros(0)
    step = tracks[:, 1:] - tracks[:, :-1]
    moving = np.any(step != 0.0, axis=(1, 2))
    chords = np.concatenate([tracks[:, :-1], step / dt], axis=2)
    natural = np.linalg.norm(cwh_acceleration(chords, mean_motion), axis=2).max(axis=1)
    return np.where(moving, 1.05 * (np.asarray(thrust, dtype=float) + natural) * dt**2 / 8.0, 0.0)


def sphere_halfspaces(
    points: np.ndarray, spheres: MovingSpheres, keep: np.ndarray, count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Supporting half-spaces n·p ≥ b of the ``count`` nearest spheres around each point, each
    also carried one step on with its sphere.

    Around the point p̂_k (the linearisation point at now + k·dt) the sphere j centred at
    c = tracks[j, k] gives n = (p̂_k − c)/‖p̂_k − c‖ and b = n·c + radius_j + keep_j: every
    point of the half-space is at least keep_j from the sphere's surface. Carried to the next
    step with the sphere, b grows by n·(tracks[j, k + 1] − c).

    Args:
        points: (S + 1, dim) linearisation points p̂_0 … p̂_S (m), at the tracks' instants.
        spheres: the spheres (tracks of S + 1 positions or more).
        keep: (J,) distance (m) to keep from each sphere's surface.
        count: half-spaces per point; missing ones (fewer spheres) have b = −inf.

    Returns:
        ``(normals (S + 1, count, dim), offsets (S + 1, count), carried offsets (S, count))``.
    """
    pts = np.asarray(points, dtype=float)
    n_pts, d = pts.shape
    normals = np.zeros((n_pts, count, d))
    normals[..., 0] = 1.0
    offsets = np.full((n_pts, count), -np.inf)
    carried = np.full((n_pts - 1, count), -np.inf)
    j_count = spheres.count
    if j_count == 0 or count == 0:
        return normals, offsets, carried
    centres = np.asarray(spheres.tracks, dtype=float)[:, :n_pts].transpose(1, 0, 2)  # (P, J, d)
    diff = pts[:, None, :] - centres
    dist = np.linalg.norm(diff, axis=2)  # (P, J)
    reach = np.asarray(spheres.radii, dtype=float) + np.asarray(keep, dtype=float)  # (J,)
    score = dist - reach[None]
    take = min(count, j_count)
    if take < j_count:
        nearest = np.argpartition(score, take - 1, axis=1)[:, :take]
    else:
        nearest = np.tile(np.arange(j_count), (n_pts, 1))
    rows = np.arange(n_pts)[:, None]
    n = diff[rows, nearest] / np.maximum(dist[rows, nearest], 1e-12)[..., None]
    c = centres[rows, nearest]
    normals[:, :take] = n
    offsets[:, :take] = np.einsum("pmd,pmd->pm", n, c) + reach[nearest]
    shift = centres[1:][rows[:-1], nearest[:-1]] - c[:-1]  # each sphere's move to the next step
    carried[:, :take] = offsets[:-1, :take] + np.einsum("pmd,pmd->pm", n[:-1], shift)
    return normals, offsets, carried


def keepout_halfspaces(
    points: np.ndarray, spheres: MovingSpheres, radius: float, margin: float, count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`sphere_halfspaces` keeping a chaser of radius ``radius`` (m) ``margin`` (m) clear
    of every sphere, except one already nearer than that to ``points[0]`` (the chaser now): that
    one must only not come nearer than it is (so the first steps stay feasible)."""
    gap_now = np.linalg.norm(points[0] - spheres.tracks[:, 0], axis=1) - spheres.radii - radius
    keep = radius + np.clip(gap_now, 0.0, margin)
    return sphere_halfspaces(points, spheres, keep, count)
