"""Matplotlib rendering of :class:`debris_gym.envs.DebrisFieldEnv`.

The field is drawn in the LVLH frame with the usual top-view convention: along-track (y) to the
right, radial (x) up. A 3D field gets a second panel beside it, along-track (y) right and
cross-track (z) up; spheres are drawn as circles in both projections.

Speed: a frame is three layers. The *frame* layer (axes, ticks, labels, legend, titles) depends
only on the world's bounds, dimension, name and motion model and is drawn once; the *field* layer
is drawn on top of it once per scenario; each frame restores that cached picture and draws only
the dynamic artists on top ("blitting"). In a frozen field (``Scenario.motion == "frozen"``) the
field layer holds the debris, the dock and the target labels, and the dynamic artists are the
targets, trail, chaser, thrust arrow and status numbers. In a moving field (``"cwh"``) every body
is drawn where it is at the frame's ``time`` (polygons turned), so the bodies and target labels
are dynamic too, and the field layer holds the dock and each body's path, drawn faintly: its
positions over one orbit period (a drift-free body's closed relative-orbit ellipse), for the
period that holds ``time`` (:func:`debris_gym.envs.render_bodies.path_window`).

Frames are rendered off screen with Agg in both modes; ``"human"`` also shows them in a pyplot
window. Without a display (or with a non-interactive matplotlib backend) ``"human"`` keeps
drawing off screen, like a pygame env under SDL's dummy video driver, and says so once with a
:class:`NoDisplayWarning`; headless checks such as gymnasium's ``check_env`` then still run.

Matplotlib is imported only when a :class:`Renderer` is built, so importing the env stays light.
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from typing import Any

import numpy as np

from debris_gym.envs.render_bodies import (
    CLIP_SPAN,
    MovingBodies,
    label_glyphs,
    off_view,
    orbit_paths,
    outline,
    path_window,
)
from debris_gym.scenario import Scenario

__all__ = ["CLIP_SPAN", "RENDER_MODES", "NoDisplayWarning", "Renderer", "outline"]

RENDER_MODES = ("human", "rgb_array")

DPI = 100
PANEL_PX = 480
"""Edge of one square field panel (pixels)."""

ARROW_FRACTION = 0.05
"""Length of the thrust arrow at full thrust (|accel| = max_accel), as a fraction of the world."""

DEBRIS_FACE, DEBRIS_EDGE = "#a6a6a6", "#5f5f5f"
TARGET_OPEN, TARGET_DONE, TARGET_EDGE = "#ff8c00", "#2ca02c", "#6b3d00"
CHASER, TRAIL, THRUST, DOCK = "#1f5fd0", "#5b8fe8", "#d62728", "#222222"
DEBRIS_ORBIT, TARGET_ORBIT = "#c4c8dc", "#f3c48f"
"""Faint colours of the bodies' paths in a moving field (light enough to read bodies over)."""
LABEL = {"xytext": (7, 6), "textcoords": "offset points", "fontsize": 8, "color": TARGET_EDGE,
         "fontweight": "bold", "zorder": 4, "animated": True}  # fmt: skip
"""Style of the target numbers, set beside each target."""

AXIS_LABELS = {0: "x radial [m]", 1: "y along-track [m]", 2: "z cross-track [m]"}
PANEL_TITLES = {
    (1, 0): "in-plane (y–x): along-track →, radial ↑",
    (1, 2): "out-of-plane (y–z): along-track →, cross-track ↑",
}
VIEWS = {2: ((1, 0),), 3: ((1, 0), (1, 2))}
"""(horizontal, vertical) state components of each panel, per dimension."""

STATUS_FIELDS = (
    # static label, value format, typical widest value (reserves its width)
    ("t = ", "{:.1f} s", "0000.0 s"),
    ("Δv = ", "{:.2f} m/s", "00.00 m/s"),
    ("|v| = ", "{:.3g} m/s", "0.000 m/s"),
    ("captured ", "{:d}/{n}", "0/0"),
)
STATUS_FONTSIZE = 9.5


def style_field_axes(ax: Any, scenario: Any, h: int, v: int, title: bool) -> None:
    """Limits, equal aspect, axis labels and grid of one field panel (axis h right, v up)."""
    ax.set_xlim(*scenario.bounds[h])
    ax.set_ylim(*scenario.bounds[v])
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(AXIS_LABELS[h], fontsize=9)
    ax.set_ylabel(AXIS_LABELS[v], fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, color="#e4e4e4", linewidth=0.6)
    ax.set_axisbelow(True)
    ax.set_facecolor("#fbfbfd")
    if title:
        ax.set_title(PANEL_TITLES[(h, v)], fontsize=9, pad=4)


def _import_matplotlib() -> Any:
    try:
        import matplotlib
    except ImportError as exc:  # pragma: no cover - matplotlib is a declared dependency
        raise ImportError(
            "rendering debris_gym environments needs matplotlib; install it with "
            "`pip install matplotlib`"
        ) from exc
    return matplotlib


class NoDisplayWarning(UserWarning):
    """``render_mode="human"`` found no window to show frames in and draws them off screen."""


def _window_pyplot() -> tuple[Any, str]:
    """pyplot on an interactive backend and ``""``, or ``None`` and the reason there is none."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        return None, "neither DISPLAY nor WAYLAND_DISPLAY is set"
    import matplotlib.pyplot as plt

    backend = str(plt.get_backend()).lower()
    try:
        from matplotlib.backends import BackendFilter, backend_registry

        interactive = set(backend_registry.list_builtin(BackendFilter.INTERACTIVE))
    except ImportError:  # matplotlib < 3.9
        from matplotlib import rcsetup

        # (gone from matplotlib 3.9 on, whose stubs are the ones checked)
        interactive = {b.lower() for b in rcsetup.interactive_bk}  # type: ignore[attr-defined]
    if backend not in interactive and not backend.startswith("module://"):
        return None, f"the matplotlib backend {backend!r} is not interactive"
    return plt, ""


def _warn_no_window(reason: str) -> None:
    warnings.warn(
        f"render_mode='human' cannot open a window ({reason}); frames are drawn off screen and "
        "not shown. To see them, run with a display: set DISPLAY (a desktop session, `ssh -X`, "
        "or `xvfb-run python ...`) and use an interactive matplotlib backend (e.g. "
        "MPLBACKEND=TkAgg). To get the frames as arrays, use render_mode='rgb_array'.",
        NoDisplayWarning,
        stacklevel=2,
    )


class _Panel:
    """One 2D projection: horizontal axis = state component ``h``, vertical = component ``v``."""

    def __init__(self, ax: Any, h: int, v: int) -> None:
        self.ax, self.h, self.v = ax, h, v
        self.field: list[Any] = []  # artists of the cached field layer
        self.debris: Any = None  # a moving field's obstacles (in a frozen one, in self.field)
        self.numbers: Any = None  # moving field: the target labels as one collection of glyphs
        self.paths: list[Any] = []  # a moving field's body paths (in the field layer)
        self.targets: Any = None  # true-size target discs
        self.rings: Any = None  # fixed-size rings around targets, so small ones stay visible
        self.trail: Any = None
        self.arrow: Any = None
        self.chaser: Any = None
        self.goals: Any = None  # several chasers: each one's goal slot

    def xy(self, points: Any) -> tuple[Any, Any]:
        points = np.asarray(points, dtype=float)
        return points[..., self.h], points[..., self.v]

    def view(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower-left and upper-right corner of the panel's view (m): the world's bounds."""
        limits = np.array([self.ax.get_xlim(), self.ax.get_ylim()], dtype=float)
        return limits[:, 0], limits[:, 1]

    def patch(self, body: Any, lo: np.ndarray, hi: np.ndarray, circle: Any, polygon: Any) -> Any:
        """The matplotlib patch of one body in this projection (``circle`` / ``polygon`` are
        matplotlib's classes, imported by the caller); a huge body is cut to the view
        (:func:`outline`), and one that is nowhere near it becomes an empty polygon."""
        centre = np.array(self.xy(body.position))
        vertices = None
        if body.vertices is not None:
            world = np.asarray(body.position) + np.asarray(body.vertices)
            vertices = np.column_stack(self.xy(world))
        shape = outline(centre, float(body.radius), vertices, lo, hi)
        if shape is None:
            return circle(centre, body.radius) if vertices is None else polygon(vertices)
        if len(shape) == 0:  # keep one patch per body: the targets' colours are per patch
            shape = off_view(lo, hi)
        return polygon(shape, closed=True)

    def dynamic(self) -> tuple[Any, ...]:
        """The artists drawn on every frame, bottom first."""
        if self.debris is None:
            return (self.targets, self.rings, self.goals, self.trail, self.arrow, self.chaser)
        return (self.debris, self.targets, self.rings, self.numbers, self.goals, self.trail,
                self.arrow, self.chaser)  # fmt: skip

    def remove_field(self) -> None:
        """Take the previous scenario's artists off the axes."""
        for artist in (*self.field, *self.paths, self.debris, self.numbers, self.targets,
                       self.rings):  # fmt: skip
            if artist is not None:
                artist.remove()
        self.field, self.paths = [], []
        self.debris = self.numbers = self.targets = self.rings = None


class Renderer:
    """Draws frames of a debris field with the chaser, its trail and its thrust.

    Args:
        mode: ``"rgb_array"`` (return frames) or ``"human"`` (also show them in a window).
        fps: frame rate of the ``"human"`` window (it pauses ``1 / fps`` s per frame).

    Warns:
        NoDisplayWarning: ``mode="human"`` without a display or an interactive matplotlib
            backend; frames are then drawn (and returned by :meth:`draw`) but not shown.
    """

    def __init__(self, mode: str, fps: int = 15) -> None:
        if mode not in RENDER_MODES:
            raise ValueError(f"mode must be one of {RENDER_MODES}, got {mode!r}")
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        self.mode = mode
        self.fps = fps
        _import_matplotlib()
        self._plt: Any = None
        if mode == "human":
            self._plt, reason = _window_pyplot()
            if self._plt is None:
                _warn_no_window(reason)
        self._scenario: Scenario | None = None
        self._bodies: MovingBodies | None = None  # set while a moving field is drawn
        self._path_window = math.inf  # length (s) of the stretch of motion drawn as paths
        self._path_start: float | None = None  # start (s) of the paths in the field layer
        self._layout_key: tuple[Any, ...] | None = None
        self._fig: Any = None
        self._canvas: Any = None
        self._frame_background: Any = None
        self._background: Any = None
        self._panels: list[_Panel] = []
        self._status: list[Any] = []
        self._rgba_open = self._rgba_done = np.zeros(4)
        self._window: Any = None
        self._window_image: Any = None

    # --- public API ---------------------------------------------------------------------------

    @property
    def on_screen(self) -> bool:
        """Whether frames are shown in a window (``"human"`` with a display)."""
        return self._plt is not None

    def draw(
        self,
        *,
        scenario: Scenario,
        chaser_state: np.ndarray,
        captured: np.ndarray,
        trail: np.ndarray | list[np.ndarray],
        accel: np.ndarray,
        time: float,
        delta_v: float,
        goals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Render one frame: an (H, W, 3) uint8 RGB array (also shown on screen if human).

        Args:
            scenario: the field; its static part is drawn once and reused while it is the same.
            chaser_state: LVLH state, position then velocity, length 2·dim (m, m/s); several
                chasers: (K, 2·dim), one row each (the status then gives the fastest speed).
            captured: one flag per target.
            trail: past chaser positions, shape (n, dim) (m); several chasers: one such array
                per chaser.
            accel: commanded acceleration of the last step, length dim (m/s²); several
                chasers: (K, dim), not drawn.
            time: elapsed time (s), >= 0; a moving field's bodies are drawn where they are then.
            delta_v: Δv spent so far (m/s; several chasers: by all of them).
            goals: several chasers: (K, dim) each one's own slot (m), marked; None: none.

        Raises:
            ValueError: ``time`` is negative or not finite.
        """
        time = float(time)
        if not (math.isfinite(time) and time >= 0.0):
            raise ValueError(f"time must be a finite number of s >= 0, got {time!r}")
        self._ensure_scene(scenario, time)
        d = scenario.dim
        states = np.asarray(chaser_state, dtype=float).reshape(-1, 2 * d)
        pos, speeds = states[:, :d], np.linalg.norm(states[:, d:], axis=1)
        captured = np.asarray(captured, dtype=bool).reshape(len(scenario.targets))
        if isinstance(trail, (list, tuple)):  # one path per chaser, apart: NaN rows between
            gap = np.full((1, d), np.nan)
            parts = [np.asarray(t, dtype=float).reshape(-1, d) for t in trail]
            trail = np.concatenate([x for t in parts for x in (t, gap)][:-1] or [gap])
        path = np.asarray(trail, dtype=float).reshape(-1, d)
        thrust_of = np.asarray(accel, dtype=float).reshape(-1, d)[0] if len(states) == 1 else None
        marks = np.empty((0, d)) if goals is None else np.asarray(goals, float).reshape(-1, d)

        if self._bodies is not None:
            self._place_bodies(self._bodies, scenario, time)
        colours = np.where(captured[:, None], self._rgba_done, self._rgba_open)
        for panel in self._panels:
            panel.targets.set_facecolor(colours)
            panel.rings.set_edgecolor(colours)
            panel.trail.set_data(*panel.xy(path))
            panel.goals.set_data(*panel.xy(marks))
            x, y = panel.xy(pos)
            panel.chaser.set_data(x, y)
            panel.arrow.set_visible(False)
            if thrust_of is None:
                continue
            thrust = float(np.linalg.norm(thrust_of)) / scenario.max_accel
            dx, dy = panel.xy(thrust_of / scenario.max_accel * (ARROW_FRACTION * scenario.size))
            if thrust > 1e-9 and (dx != 0.0 or dy != 0.0):
                panel.arrow.set_positions((x[0], y[0]), (x[0] + dx, y[0] + dy))
                panel.arrow.set_mutation_scale(5.0 + 7.0 * min(thrust, 1.0))  # head size (pt)
                panel.arrow.set_visible(True)
        fastest = float(speeds.max()) if len(speeds) else 0.0
        values = (time, delta_v, fastest, int(captured.sum()))
        for text, field, value in zip(self._status, STATUS_FIELDS, values, strict=True):
            text.set_text(field[1].format(value, n=captured.size))

        fig, canvas = self._fig, self._canvas
        canvas.restore_region(self._background)
        for panel in self._panels:
            for artist in panel.dynamic():
                fig.draw_artist(artist)
        for text in self._status:
            fig.draw_artist(text)
        rgba = np.asarray(canvas.buffer_rgba())
        # Channel by channel: several times faster than copying the strided rgba[..., :3].
        frame = np.stack([rgba[..., 0], rgba[..., 1], rgba[..., 2]], axis=-1)
        if self._plt is not None:
            self._show(frame)
        return frame

    def close(self) -> None:
        """Release the figure and close the window, if any. The renderer can be used again."""
        if self._window is not None and self._plt is not None:
            self._plt.close(self._window)
        self._window = self._window_image = None
        self._fig = self._canvas = self._frame_background = self._background = None
        self._panels, self._status = [], []
        self._scenario = self._layout_key = self._bodies = self._path_start = None

    # --- cached layers ------------------------------------------------------------------------

    def _ensure_scene(self, scenario: Scenario, time: float) -> None:
        if scenario is not self._scenario:
            key = (scenario.dim, scenario.bounds, scenario.name, scenario.moving)
            if key != self._layout_key:
                self._build_frame(scenario)
                self._layout_key = key
                self._build_field(scenario)
            elif scenario != self._scenario:
                self._build_field(scenario)
            self._scenario = scenario  # an equal copy keeps the drawn field
        if self._bodies is not None:
            window = self._path_window
            start = math.floor(time / window) * window if math.isfinite(window) else 0.0
            if start != self._path_start:
                self._draw_paths(scenario, self._bodies, start)

    def _build_frame(self, scenario: Scenario) -> None:
        """Figure, axes, titles, status labels and legend: everything but the field itself."""
        from matplotlib import colors
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.lines import Line2D
        from matplotlib.patches import FancyArrowPatch

        self._rgba_open = np.array(colors.to_rgba(TARGET_OPEN))
        self._rgba_done = np.array(colors.to_rgba(TARGET_DONE))
        views = VIEWS[scenario.dim]
        n = len(views)
        left, gap, right, bottom = 78, 84, 24, 86
        top = 60 if n == 1 else 82  # room for the panel titles
        width = left + n * PANEL_PX + (n - 1) * gap + right
        height = bottom + PANEL_PX + top
        fig = Figure(figsize=(width / DPI, height / DPI), dpi=DPI, facecolor="white")
        canvas = FigureCanvasAgg(fig)
        self._panels = []
        for k, (h, v) in enumerate(views):
            x0 = left + k * (PANEL_PX + gap)
            ax = fig.add_axes((x0 / width, bottom / height, PANEL_PX / width, PANEL_PX / height))
            style_field_axes(ax, scenario, h, v, title=n > 1)
            panel = _Panel(ax, h, v)
            panel.trail = ax.add_line(
                Line2D([], [], color=TRAIL, linewidth=1.3, alpha=0.9, zorder=5, animated=True)
            )
            panel.arrow = ax.add_patch(
                FancyArrowPatch(
                    (0.0, 0.0), (0.0, 0.0), arrowstyle="-|>", mutation_scale=12, color=THRUST,
                    linewidth=2.0, shrinkA=0.0, shrinkB=0.0, zorder=8, animated=True,
                    visible=False,
                )
            )  # fmt: skip
            panel.chaser = ax.add_line(
                Line2D(
                    [], [], marker="o", markersize=6.5, markerfacecolor=CHASER,
                    markeredgecolor="white", markeredgewidth=1.0, linestyle="none", zorder=7,
                    animated=True,
                )
            )  # fmt: skip
            panel.goals = ax.add_line(
                Line2D(
                    [], [], marker="x", markersize=5, markeredgecolor=DOCK,
                    markeredgewidth=1.0, linestyle="none", zorder=2, animated=True,
                )
            )  # fmt: skip
            self._panels.append(panel)
        name = scenario.name or "debris field"
        fig.text(
            0.5, 1.0 - 14 / height, f"{name} — LVLH frame" if n > 1 else f"{name} — LVLH top view",
            ha="center", va="center", fontsize=11, fontweight="bold",
        )  # fmt: skip
        self._status = self._status_line(fig, canvas, 1.0 - 36 / height)
        handles = self._legend_handles(scenario.moving)
        fig.legend(
            handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.0),
            ncol=len(handles) if n > 1 else 4, fontsize=8, frameon=False, handlelength=1.6,
            columnspacing=1.2, borderaxespad=0.3,
        )  # fmt: skip
        canvas.draw()
        self._fig, self._canvas = fig, canvas
        self._frame_background = canvas.copy_from_bbox(fig.bbox)
        self._scenario = None

    def _build_field(self, scenario: Scenario) -> None:
        """Make the scenario's artists. A frozen field's debris, dock and target labels are drawn
        over the frame layer here and the result cached; a moving field's bodies and labels are
        dynamic, and its field layer (paths and dock) is drawn by :meth:`_draw_paths`."""
        from matplotlib.collections import Collection, PatchCollection, PathCollection
        from matplotlib.lines import Line2D
        from matplotlib.patches import Circle, Polygon
        from matplotlib.transforms import IdentityTransform

        moving = scenario.moving
        self._bodies, self._path_start = None, None
        if moving:
            span = min(float(np.max(hi - lo)) for lo, hi in (p.view() for p in self._panels))
            self._bodies = MovingBodies(scenario, span)
            self._path_window = path_window(scenario)
        canvas, fig = self._canvas, self._fig
        if not moving:
            canvas.restore_region(self._frame_background)
        centres = np.array([t.position for t in scenario.targets], dtype=float)
        alpha = 0.85 if scenario.dim == 3 else 1.0
        for panel in self._panels:
            panel.remove_field()
            ax = panel.ax
            lo, hi = panel.view()
            dx, dy = panel.xy(scenario.dock)
            dock = Line2D(
                [dx], [dy], marker="s", markersize=11, markerfacecolor="white",
                markeredgecolor=DOCK, markeredgewidth=1.8, linestyle="none", zorder=2,
                animated=True,
            )  # fmt: skip
            tx, ty = panel.xy(centres)
            style: dict[str, Any] = {"zorder": 1, "alpha": alpha, "animated": True}
            debris: dict[str, Any] = {
                "facecolor": DEBRIS_FACE,
                "edgecolor": DEBRIS_EDGE,
                "linewidth": 0.7,
            }
            target: dict[str, Any] = {
                "edgecolor": TARGET_EDGE,
                "linewidth": 0.6,
                "zorder": 3,
                "animated": True,
            }
            if moving:  # shapes set per frame (_place_bodies)
                panel.debris = ax.add_collection(PathCollection([], **debris, **style), False)
                panel.field = [ax.add_line(dock)]
                panel.numbers = ax.add_collection(
                    PathCollection(
                        label_glyphs(len(centres), LABEL), sizes=[1.0],
                        offsets=np.column_stack([tx, ty]), offset_transform=ax.transData,
                        transform=IdentityTransform(), facecolor=TARGET_EDGE, edgecolor="none",
                        zorder=4, animated=True, clip_on=False,
                    ),
                    autolim=False,
                )  # fmt: skip
                targets: Collection = PathCollection([], **target)
            else:
                patches = [panel.patch(b, lo, hi, Circle, Polygon) for b in scenario.obstacles]
                collection = PatchCollection(patches, **debris, **style)
                panel.field = [ax.add_collection(collection, autolim=False), ax.add_line(dock)]
                panel.field += [
                    ax.annotate(str(i), xy, **LABEL) for i, xy in enumerate(zip(tx, ty))
                ]
                for artist in panel.field:
                    fig.draw_artist(artist)
                targets = PatchCollection(
                    [panel.patch(t, lo, hi, Circle, Polygon) for t in scenario.targets], **target
                )
            panel.targets = ax.add_collection(targets, autolim=False)
            panel.rings = ax.scatter(
                tx, ty, s=110, facecolors="none", edgecolors=TARGET_OPEN, linewidths=1.8,
                zorder=3, animated=True,
            )  # fmt: skip
        if not moving:
            self._background = canvas.copy_from_bbox(fig.bbox)

    def _draw_paths(self, scenario: Scenario, bodies: MovingBodies, start: float) -> None:
        """Field layer of a moving field: each body's path from ``start`` (s) over the path window
        (bodies cut by ``outline`` have none: their centres are far off the view), then the dock;
        cached as the background of the frames in that window."""
        from matplotlib.collections import LineCollection

        canvas, fig = self._canvas, self._fig
        canvas.restore_region(self._frame_background)
        window = self._path_window
        paths = orbit_paths(scenario, start, window) if math.isfinite(window) else None
        is_target = np.arange(len(scenario.bodies)) < len(scenario.targets)
        for panel in self._panels:
            for artist in panel.paths:
                artist.remove()
            panel.paths = []
            if paths is not None:
                for chosen, colour in ((~is_target, DEBRIS_ORBIT), (is_target, TARGET_ORBIT)):
                    lines = paths[chosen & ~bodies.huge][:, :, [panel.h, panel.v]]
                    collection = LineCollection(
                        list(lines), colors=colour, linewidths=1.0, zorder=0.5, animated=True
                    )
                    panel.paths.append(panel.ax.add_collection(collection, autolim=False))
            for artist in (*panel.paths, *panel.field):
                fig.draw_artist(artist)
        self._background = canvas.copy_from_bbox(fig.bbox)
        self._path_start = start

    def _place_bodies(self, bodies: MovingBodies, scenario: Scenario, time: float) -> None:
        """Put a moving field's bodies, target rings and labels where they are at ``time``."""
        centres, vertices = bodies.at(time)
        n_targets = len(scenario.targets)
        for panel in self._panels:
            lo, hi = panel.view()
            shapes = (centres, vertices, panel.h, panel.v, lo, hi)
            panel.debris.set_paths(bodies.paths(range(n_targets, len(centres)), *shapes))
            panel.targets.set_paths(bodies.paths(range(n_targets), *shapes))
            rings = centres[:n_targets][:, [panel.h, panel.v]]
            panel.rings.set_offsets(rings)
            # Like an annotation: drawn unclipped (beside a body at the edge), but only for a
            # body whose centre is in view (a non-finite offset is skipped).
            inside = np.all((rings >= lo) & (rings <= hi), axis=1)
            panel.numbers.set_offsets(np.where(inside[:, None], rings, np.nan))

    @staticmethod
    def _status_line(fig: Any, canvas: Any, y: float) -> list[Any]:
        """Lay out the status line; return its value texts.

        Labels are static (drawn into the cached frame layer); each value is its own animated
        text starting at a fixed place, so only the numbers are redrawn per frame (text is the
        slowest thing matplotlib draws) and the fields do not jump around as numbers change.
        """
        from matplotlib.font_manager import FontProperties

        renderer = canvas.get_renderer()
        prop = FontProperties(size=STATUS_FONTSIZE)

        def width(text: str) -> float:
            return renderer.get_text_width_height_descent(text, prop, ismath=False)[0]

        gap = width("    ")
        pieces = []  # (x offset (px), text, is a value)
        x = 0.0
        for label, _, widest in STATUS_FIELDS:
            pieces.append((x, label, False))
            x += width(label)
            pieces.append((x, "", True))
            x += width(widest) + gap
        fig_width = fig.bbox.width
        x0 = (fig_width - (x - gap)) / 2.0
        values = []
        for dx, text, is_value in pieces:
            artist = fig.text(
                (x0 + dx) / fig_width, y, text, ha="left", va="center",
                fontsize=STATUS_FONTSIZE, animated=is_value,
            )  # fmt: skip
            if is_value:
                values.append(artist)
        return values

    @staticmethod
    def _legend_handles(moving: bool) -> list[Any]:
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch

        def marker(label: str, **kw: Any) -> Any:
            return Line2D([], [], linestyle="none", label=label, **kw)

        return [
            marker("dock", marker="s", markersize=8, markerfacecolor="white",
                   markeredgecolor=DOCK, markeredgewidth=1.5),
            marker("chaser", marker="o", markersize=7, markerfacecolor=CHASER,
                   markeredgecolor="white"),
            Line2D([], [], color=TRAIL, linewidth=1.3, label="trail"),
            Line2D([], [], color=THRUST, linewidth=2.0, marker=">", markersize=5,
                   markevery=[1], label="thrust"),
            marker("target", marker="o", markersize=8, markerfacecolor=TARGET_OPEN,
                   markeredgecolor=TARGET_OPEN),
            marker("captured", marker="o", markersize=8, markerfacecolor=TARGET_DONE,
                   markeredgecolor=TARGET_DONE),
            Patch(facecolor=DEBRIS_FACE, edgecolor=DEBRIS_EDGE, label="debris"),
        ] + ([Line2D([], [], color=DEBRIS_ORBIT, linewidth=1.5, label="paths")] if moving
             else [])  # fmt: skip

    # --- human window -------------------------------------------------------------------------

    def _show(self, frame: np.ndarray) -> None:
        plt = self._plt
        window = self._window
        if (
            window is None
            or not plt.fignum_exists(window.number)
            or self._window_image.get_array().shape != frame.shape
        ):
            if window is not None:
                plt.close(window)
            height, width = frame.shape[:2]
            window = plt.figure(figsize=(width / DPI, height / DPI), dpi=DPI)
            if window.canvas.manager is not None:
                window.canvas.manager.set_window_title("debris-gym")
            ax = window.add_axes((0.0, 0.0, 1.0, 1.0))
            ax.set_axis_off()
            self._window_image = ax.imshow(frame, interpolation="nearest")
            self._window = window
            plt.show(block=False)
        else:
            self._window_image.set_data(frame)
        plt.pause(1.0 / self.fps)
