"""Trajectory plots of an evaluation: every agent's path of one episode over its field."""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np

from agents.experiments.evaluation.records import EvaluationResults

__all__ = ["AGENT_COLOURS", "plot_episode"]

AGENT_COLOURS = (
    "#1f5fd0",
    "#d62728",
    "#9467bd",
    "#17becf",
    "#8c564b",
    "#e377c2",
    "#bcbd22",
    "#000000",
    "#7f7f7f",
)
"""One colour per agent (targets keep the renderer's orange, debris its grey)."""


def _body_tracks(scenario: Any, recs: list) -> list[tuple[np.ndarray, bool]]:
    """Every body's path (m), from t = 0 to the end of the longest of these missions, as
    (samples, dim) arrays, each with whether it is a target."""
    end = max((r.time for r in recs), default=0.0)
    times = np.linspace(0.0, max(end, 0.0), 200)
    positions = np.stack([scenario.body_positions(float(t)) for t in times])  # (S, B, dim)
    n_targets = len(scenario.targets)
    return [(positions[:, b], b < n_targets) for b in range(positions.shape[1])]


def plot_episode(results: EvaluationResults, episode: int) -> bytes:
    """PNG bytes: every agent's trajectory of ``episode`` over its field.

    Drawn like the env's renderer (:mod:`debris_gym.envs.rendering`): top view, along-track (y)
    right, radial (x) up; a 3D field gets a second panel (y right, z up). Debris grey, targets
    orange, dock a square, the start a triangle, each agent its own colour, a collision an ×
    (at the end of the step that collided). Uses matplotlib's Agg canvas (no pyplot state).
    """
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
    fig = Figure(figsize=(6.4 * n + 0.4, 7.4), dpi=100, facecolor="white")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    handles: list[Any] = []
    for k, ((h, v), ax) in enumerate(zip(views, axes, strict=True)):
        style_field_axes(ax, scenario, h, v, title=n > 1)
        patches = []
        for body in scenario.obstacles:
            if body.vertices is not None:
                pts = np.asarray(body.position) + np.asarray(body.vertices)
                patches.append(Polygon(pts[:, [h, v]], closed=True))
            else:
                patches.append(Circle((body.position[h], body.position[v]), body.radius))
        ax.add_collection(
            PatchCollection(
                patches, facecolor=DEBRIS_FACE, edgecolor=DEBRIS_EDGE, linewidth=0.7, zorder=1
            ),
            autolim=False,
        )
        for i, t in enumerate(scenario.targets):
            ax.add_patch(
                Circle(
                    (t.position[h], t.position[v]),
                    t.radius,
                    facecolor=TARGET_OPEN,
                    edgecolor=TARGET_EDGE,
                    linewidth=0.6,
                    zorder=3,
                )
            )
            ax.scatter(
                [t.position[h]], [t.position[v]], s=110, facecolors="none",
                edgecolors=TARGET_OPEN, linewidths=1.8, zorder=3,
            )  # fmt: skip
            ax.annotate(
                str(i), (t.position[h], t.position[v]), xytext=(7, 6),
                textcoords="offset points", fontsize=8, color=TARGET_EDGE, fontweight="bold",
                zorder=4,
            )  # fmt: skip
        if scenario.moving:  # the bodies are drawn at t = 0; their paths over the missions
            for track, is_target in _body_tracks(scenario, recs):
                ax.plot(
                    track[:, h], track[:, v], color=TARGET_EDGE if is_target else DEBRIS_EDGE,
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
            colour = AGENT_COLOURS[j % len(AGENT_COLOURS)]
            p = traj.positions
            ax.plot(p[:, h], p[:, v], color=colour, linewidth=1.4, alpha=0.9, zorder=5)
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
                handles.append(
                    Line2D(
                        [], [], color=colour, linewidth=2.0,
                        label=f"{rec.agent}: {rec.outcome.replace('_', ' ')}, "
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

    handles += [
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
    if scenario.moving:
        handles.append(
            Line2D([], [], color=DEBRIS_EDGE, linewidth=0.8, linestyle=":",
                   label="bodies drawn at t = 0; dotted: their paths")
        )  # fmt: skip
    name = scenario.name or "debris field"
    fig.suptitle(
        f"{results.env_id} — episode {episode} (reset seed {results.seed + episode}, {name})",
        fontsize=10,
        fontweight="bold",
    )
    fig.legend(
        handles=handles, loc="lower center", ncol=2 if n == 1 else 3, fontsize=8, frameon=False
    )
    rows = math.ceil(len(handles) / (2 if n == 1 else 3))
    fig.subplots_adjust(left=0.1 / n, right=1 - 0.03 / n, top=0.92, bottom=0.1 + 0.032 * rows)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
