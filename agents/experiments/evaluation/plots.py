"""Trajectory plots of an evaluation: every agent's path of one episode over its field."""

from __future__ import annotations

import io
import math
from typing import Any, Literal

import numpy as np

from agents.experiments.evaluation.records import EvaluationResults

__all__ = [
    "AGENT_COLOURS",
    "agent_style",
    "body_track",
    "episode_figure",
    "meeting_steps",
    "plot_episode",
]

AGENT_COLOURS = (
    "#1f5fd0",
    "#d62728",
    "#9467bd",
    "#17becf",
    "#8c564b",
    "#e377c2",
    "#bcbd22",
    "#000000",
    "#2ca02c",
    "#008080",
)
"""One colour per agent, none of them a grey or an orange: targets keep the renderer's orange,
debris and the bodies' paths its greys. Agents beyond these reuse them with dashed lines."""

LEGEND_LABEL_CHARS = 40
"""Longest agent label shown in a legend (longer ones are cut, with an ellipsis)."""

PANEL_IN = 6.4
"""Edge of one square field panel (inches); the figure grows below it for the legend."""

LEGEND_ROW_IN = 0.2
"""Height of one legend row (inches, font size 8)."""


def agent_style(index: int) -> tuple[str, Literal["-", "--"]]:
    """(colour, line style) of the agent at position ``index`` of a plot."""
    colour = AGENT_COLOURS[index % len(AGENT_COLOURS)]
    return colour, "-" if index < len(AGENT_COLOURS) else "--"


def body_track(scenario: Any, steps: int) -> np.ndarray:
    """(steps, n_bodies, dim) every body's centre (m) at the step ends k·dt, k = 0 … steps − 1,
    propagated with the field's exact one-step transition (the env's own motion)."""
    from debris_gym.dynamics import discretize

    states = np.array(scenario.initial_body_states(), dtype=float)
    out = np.empty((max(steps, 1), len(states), scenario.dim))
    out[0] = states[:, : scenario.dim]
    if scenario.moving and steps > 1:
        step = discretize(scenario.mean_motion, scenario.dt, scenario.dim).ad.T
        for k in range(1, steps):
            states = states @ step
            out[k] = states[:, : scenario.dim]
    elif steps > 1:
        out[1:] = out[0]
    return out


def meeting_steps(scenario: Any, recs: list, track: np.ndarray | None = None) -> np.ndarray:
    """(n_bodies,) the step end k at which some agent of ``recs`` came closest to each body (the
    body is drawn there: where the agents met it); 0 for a body in a frozen field."""
    n_bodies = len(scenario.bodies)
    trajs = [r.trajectory for r in recs if r.trajectory is not None]
    if not scenario.moving or not trajs:
        return np.zeros(n_bodies, dtype=int)
    if track is None:
        track = body_track(scenario, max(len(t.positions) for t in trajs))
    best = np.full(n_bodies, np.inf)
    when = np.zeros(n_bodies, dtype=int)
    for traj in trajs:
        k = min(len(traj.positions), len(track))
        gaps = np.linalg.norm(track[:k] - traj.positions[:k, None, :], axis=2)  # (k, bodies)
        closest = np.argmin(gaps, axis=0)
        distance = gaps[closest, np.arange(n_bodies)]
        nearer = distance < best
        best[nearer] = distance[nearer]
        when[nearer] = closest[nearer]
    return when


OUTCOME_WORDS = {
    "success": "success",
    "collision": "collision",
    "out_of_bounds": "out of bounds",
    "delta_v_budget": "Δv budget spent (failed)",
    "time_limit": "time limit",
}
"""How each episode outcome reads in a legend."""


def _legend_label(text: str) -> str:
    if len(text) <= LEGEND_LABEL_CHARS:
        return text
    return text[: LEGEND_LABEL_CHARS - 1] + "…"


def episode_figure(results: EvaluationResults, episode: int) -> Any:
    """The matplotlib ``Figure`` of :func:`plot_episode` (Agg canvas, no pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PatchCollection
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Patch, Polygon

    from debris_gym.envs.rendering import (
        DEBRIS_EDGE,
        DEBRIS_FACE,
        DOCK,
        TARGET_EDGE,
        TARGET_OPEN,
        VIEWS,
        style_field_axes,
    )

    scenario = results.scenarios[episode]
    recs = results.for_episode(episode)
    views = VIEWS[scenario.dim]
    n = len(views)
    steps = max((len(r.trajectory.positions) for r in recs if r.trajectory is not None), default=1)
    track = body_track(scenario, steps)
    met = meeting_steps(scenario, recs, track)
    centres = track[met, np.arange(len(met))]  # each body where the agents met it
    n_targets = len(scenario.targets)
    agent_cols = n  # agent entries are long: one column per panel's width
    note_rows = 1 if scenario.moving else 0
    legend_rows = math.ceil(len(recs) / agent_cols) + 1 + note_rows
    top_in, axes_in, legend_in = 0.5, 0.6, legend_rows * LEGEND_ROW_IN + 0.1
    height = top_in + PANEL_IN + axes_in + legend_in
    fig = Figure(figsize=(PANEL_IN * n + 0.4 * n, height), dpi=100, facecolor="white")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    handles: list[Any] = []
    for k, ((h, v), ax) in enumerate(zip(views, axes, strict=True)):
        style_field_axes(ax, scenario, h, v, title=n > 1)
        patches: list[Patch] = []
        for j, body in enumerate(scenario.obstacles):
            b = n_targets + j
            pts = scenario.body_vertices(b, float(met[b]) * scenario.dt)  # None: a circle
            if pts is not None:
                patches.append(Polygon(pts[:, [h, v]], closed=True))
            else:
                patches.append(Circle((centres[b, h], centres[b, v]), body.radius))
        ax.add_collection(
            PatchCollection(
                patches, facecolor=DEBRIS_FACE, edgecolor=DEBRIS_EDGE, linewidth=0.7, zorder=1
            ),
            autolim=False,
        )
        for i, t in enumerate(scenario.targets):
            c = centres[i]
            ax.add_patch(
                Circle(
                    (c[h], c[v]), t.radius, facecolor=TARGET_OPEN, edgecolor=TARGET_EDGE,
                    linewidth=0.6, zorder=3,
                )
            )  # fmt: skip
            ax.scatter(
                [c[h]], [c[v]], s=110, facecolors="none", edgecolors=TARGET_OPEN,
                linewidths=1.8, zorder=3,
            )  # fmt: skip
            when = f" · {met[i] * scenario.dt:.0f} s" if scenario.moving else ""
            lo, hi = scenario.bounds[h]
            right = c[h] > lo + 0.8 * (hi - lo)  # near the right edge: label on the left
            ax.annotate(
                f"{i}{when}", (c[h], c[v]), xytext=(-7 if right else 7, 6),
                textcoords="offset points", ha="right" if right else "left", fontsize=8,
                color=TARGET_EDGE, fontweight="bold", zorder=4,
            )  # fmt: skip
        if scenario.moving:  # each body's path over the missions, dotted
            for b in range(track.shape[1]):
                ax.plot(
                    track[:, b, h], track[:, b, v],
                    color=TARGET_EDGE if b < n_targets else DEBRIS_EDGE,
                    linewidth=0.6, alpha=0.6, linestyle=":", zorder=1.5,
                )  # fmt: skip
        ax.plot(
            [scenario.dock[h]], [scenario.dock[v]], marker="s", markersize=11,
            markerfacecolor="white", markeredgecolor=DOCK, markeredgewidth=1.8,
            linestyle="none", zorder=2,
        )  # fmt: skip
        for j, rec in enumerate(recs):
            traj = rec.trajectory
            if traj is None:
                continue
            colour, style = agent_style(j)
            p = traj.positions
            ax.plot(
                p[:, h], p[:, v], color=colour, linestyle=style, linewidth=1.4, alpha=0.9,
                zorder=5,
            )  # fmt: skip
            ax.plot(
                [p[-1, h]], [p[-1, v]], marker="o", markersize=5, color=colour,
                markeredgecolor="white", markeredgewidth=0.6, linestyle="none", zorder=6,
            )  # fmt: skip
            if traj.collision_point is not None:
                c = traj.collision_point
                ax.plot(
                    [c[h]], [c[v]], marker="x", markersize=11, markeredgewidth=2.5,
                    color=colour, linestyle="none", zorder=7,
                )  # fmt: skip
            if k == 0:
                outcome = OUTCOME_WORDS.get(rec.outcome, rec.outcome)
                handles.append(
                    Line2D(
                        [], [], color=colour, linestyle=style, linewidth=2.0,
                        label=f"{_legend_label(rec.agent)}: {outcome}, "
                        f"{rec.targets_captured}/{rec.n_targets} captured, "
                        f"Δv {rec.delta_v:.3g} m/s",
                    )
                )  # fmt: skip
        start = recs[0].trajectory.positions[0] if recs and recs[0].trajectory else scenario.dock
        ax.plot(
            [start[h]], [start[v]], marker="^", markersize=8, markerfacecolor=DOCK,
            markeredgecolor="white", linestyle="none", zorder=5.5,
        )  # fmt: skip

    def marker(label: str, **kw: Any) -> Any:
        return Line2D([], [], linestyle="none", label=label, **kw)

    keys = [
        marker("dock", marker="s", markersize=8, markerfacecolor="white", markeredgecolor=DOCK,
               markeredgewidth=1.5),
        marker("start", marker="^", markersize=8, markerfacecolor=DOCK, markeredgecolor="white"),
        marker("end", marker="o", markersize=6, markerfacecolor="#333333",
               markeredgecolor="white"),
        marker("target", marker="o", markersize=8, markerfacecolor=TARGET_OPEN,
               markeredgecolor=TARGET_OPEN),
        Patch(facecolor=DEBRIS_FACE, edgecolor=DEBRIS_EDGE, label="debris"),
        marker("collision", marker="x", markersize=8, markeredgewidth=2.0, color="#333333"),
    ]  # fmt: skip
    name = scenario.name or "debris field"
    seed = results.reset_seeds[episode]
    fig.suptitle(
        f"{results.env_id} — episode {episode} (reset seed {seed}, {name})",
        fontsize=10,
        fontweight="bold",
        y=1 - 0.15 / height,
    )
    fig.legend(
        handles=handles, loc="lower center", ncol=agent_cols, fontsize=8, frameon=False,
        bbox_to_anchor=(0.5, ((1 + note_rows) * LEGEND_ROW_IN + 0.05) / height),
    )  # fmt: skip
    fig.legend(
        handles=keys, loc="lower center", ncol=len(keys), fontsize=8, frameon=False,
        bbox_to_anchor=(0.5, (note_rows * LEGEND_ROW_IN + 0.02) / height),
        columnspacing=1.2, handletextpad=0.4,
    )  # fmt: skip
    if note_rows:
        fig.text(
            0.5, 0.06 / height, "Bodies are drawn where an agent came closest to them "
            "(targets: at the time shown); dotted: their paths.", ha="center", va="bottom",
            fontsize=8, color="#444444",
        )  # fmt: skip
    fig.subplots_adjust(
        left=0.1 / n, right=1 - 0.03 / n, top=1 - top_in / height,
        bottom=(legend_in + axes_in) / height,
    )  # fmt: skip
    return fig


def plot_episode(results: EvaluationResults, episode: int) -> bytes:
    """PNG bytes: every agent's trajectory of ``episode`` over its field.

    Drawn like the env's renderer (:mod:`debris_gym.envs.rendering`): top view, along-track (y)
    right, radial (x) up; a 3D field gets a second panel (y right, z up). Debris grey, targets
    orange, dock a square, the start a triangle, each agent its own colour (never a body's grey
    or orange), a collision an × (at the end of the step that collided). In a moving field each
    body is drawn where an agent came closest to it (a target with that time), so a path that
    met a body ends at it, and every body's path is dotted. The legends sit below the field,
    which they never shrink: the figure grows with them.
    """
    buf = io.BytesIO()
    episode_figure(results, episode).savefig(buf, format="png")
    return buf.getvalue()
