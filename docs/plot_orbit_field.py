"""Draw one default 2D moving (v1) field: its bodies at t = 0 and their relative orbits.

    python docs/plot_orbit_field.py --seed 0 --out docs/images/relative_orbit_field.png

The field is the env's default random spec with ``motion="bounded"`` (3 targets, 20 obstacles,
1 km, n = 1.1314e-3 rad/s). Each body is drawn where it is at t = 0 (targets orange, obstacles
grey, polygons with their vertices), with the ellipse its centre runs round once per orbit
(propagated with the scenario's own exact motion), an arrow for its velocity, the dock and the
bounds. Along-track (y) to the right, radial (x) up, as the env's renderer. Written atomically.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

N = 1.1314e-3  # rad/s


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "relative_orbit_field.png"))
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    from debris_gym.generators import FieldSpec, random_field

    spec = FieldSpec(motion="bounded", mean_motion=N, target_clearance=17.0, dock_clearance=50.0)
    scenario = random_field(
        np.random.default_rng(args.seed), spec, mean_motion=N, dt=10.0, max_accel=0.05,
        capture_radius=5.0,
    )  # fmt: skip
    times = np.linspace(0.0, 2.0 * np.pi / N, 361)
    track = np.stack([scenario.body_positions(t) for t in times])  # (S, B, 2)
    n_t = len(scenario.targets)
    half = spec.field_size / 2.0

    fig, ax = plt.subplots(figsize=(8.0, 8.4), dpi=110)
    ax.add_patch(plt.Rectangle((-half, -half), 2 * half, 2 * half, fill=False, lw=1.0, ec="k"))
    ax.add_patch(Circle((0.0, 0.0), spec.dock_clearance, fc="none", ec="tab:blue", ls=":"))
    ax.plot(0.0, 0.0, marker="s", color="tab:blue", ms=6, label="dock (origin)")
    states = scenario.initial_body_states()
    for b, body in enumerate(scenario.bodies):
        target = b < n_t
        color = "tab:orange" if target else "0.45"
        ax.plot(track[:, b, 1], track[:, b, 0], color=color, lw=0.8, alpha=0.6)
        x, y = body.position
        if body.vertices is not None:
            verts = np.asarray(body.vertices) + body.position
            ax.add_patch(Polygon(verts[:, ::-1], closed=True, fc=color, ec="k", lw=0.5))
        else:
            ax.add_patch(Circle((y, x), body.radius, fc=color, ec="k", lw=0.5))
        vx, vy = states[b, 2:]
        ax.annotate(
            "", xy=(y + 150.0 * vy, x + 150.0 * vx), xytext=(y, x),
            arrowprops={"arrowstyle": "->", "color": "k", "lw": 0.7},
        )  # fmt: skip
    ax.plot([], [], color="tab:orange", label="target and its relative orbit")
    ax.plot([], [], color="0.45", label="obstacle and its relative orbit")
    ax.plot([], [], color="k", lw=0.7, label="velocity at t = 0 (× 150 s)")
    ax.set_aspect("equal")
    ax.set_xlim(-half - 20, half + 20)
    ax.set_ylim(-half - 20, half + 20)
    ax.set_xlabel("along-track y (m)")
    ax.set_ylabel("radial x (m)")
    ax.set_title(
        f"Rendezvous2D-v1 field (seed {args.seed}): bodies at t = 0 on drift-free relative "
        "orbits\n(each ellipse is run once per orbit, 2π/n = 92.6 min, and repeats)",
        fontsize=10,
    )
    ax.legend(loc="lower left", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp.png")
    fig.savefig(tmp)
    os.replace(tmp, out)
    plt.close(fig)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
