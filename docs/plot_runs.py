"""Compare training runs: targets captured and success rate vs env steps.

    python docs/plot_runs.py runs/a runs/b --labels "A" "B" --out docs/images/runs.png

``--source eval`` (default) plots each run's held-out evaluations (``evaluations.npz``: the
final task, the same held-out fields every time, deterministic policy) — the fair comparison,
also for runs with a curriculum, whose training episodes fly easier stages. ``--source train``
plots the training episodes (``train_episodes.csv``), averaged over windows of ``--window`` env
steps. The figure is written atomically.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
from pathlib import Path

import numpy as np


def load_episodes(run: Path) -> np.ndarray:
    """(timestep, targets captured, success) of every finished training episode of a run."""
    path = run / "train_episodes.csv"
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: is {run} a train.py run directory?")
    with open(path, newline="") as fh:
        rows = [
            (float(r["timesteps"]), float(r["targets_captured"]), float(r["is_success"]))
            for r in csv.DictReader(fh)
        ]
    return np.array(rows).reshape(-1, 3)


def load_evaluations(run: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps, mean targets captured and success rate of each held-out evaluation of a run."""
    path = run / "evaluations.npz"
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: did the run evaluate (eval.freq > 0)?")
    with np.load(path, allow_pickle=True) as data:
        n = min(len(data["timesteps"]), len(data["successes"]), len(data["targets_captured"]))
        steps = np.asarray(data["timesteps"][:n], dtype=float)
        captured = np.array([np.mean(x) for x in data["targets_captured"][:n]])
        success = np.array([np.nanmean(np.asarray(x, dtype=float)) for x in data["successes"][:n]])
    return steps, captured, success


def binned(episodes: np.ndarray, window: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Window centres (steps) and the mean captures and success of the episodes in each."""
    bins = (episodes[:, 0] // window).astype(int)
    keys = np.unique(bins)
    centres = (keys + 0.5) * window
    captured = np.array([episodes[bins == k, 1].mean() for k in keys])
    success = np.array([episodes[bins == k, 2].mean() for k in keys])
    return centres, captured, success


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="train.py run directories")
    parser.add_argument("--labels", nargs="+", help="one label per run (default: directory)")
    parser.add_argument("--window", type=float, default=500_000, help="env steps per point")
    parser.add_argument("--out", type=Path, required=True, help="PNG to write")
    parser.add_argument("--title", default=None)
    parser.add_argument(
        "--source", choices=("eval", "train"), default="eval",
        help="held-out evaluations (default) or training episodes",
    )  # fmt: skip
    args = parser.parse_args(argv)
    labels = args.labels or [run.name for run in args.runs]
    if len(labels) != len(args.runs):
        parser.error(f"--labels needs one label per run ({len(args.runs)}), got {len(labels)}")
    if args.window <= 0:
        parser.error(f"--window must be > 0 env steps, got {args.window}")
    try:
        if args.source == "eval":
            curves = [load_evaluations(run) for run in args.runs]
        else:
            curves = [binned(load_episodes(run), args.window) for run in args.runs]
    except (FileNotFoundError, KeyError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_c, ax_s) = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for label, (steps, captured, success) in zip(labels, curves):
        ax_c.plot(steps / 1e6, captured, label=label)
        ax_s.plot(steps / 1e6, 100 * success, label=label)
    ax_c.set(xlabel="env steps (millions)", ylabel="targets captured per episode")
    ax_s.set(xlabel="env steps (millions)", ylabel="episodes that succeed (%)", ylim=(-2, 102))
    for ax in (ax_c, ax_s):
        ax.grid(alpha=0.3)
    ax_c.legend(fontsize=8)
    title = args.title or (
        "Held-out evaluations (final task, deterministic)"
        if args.source == "eval"
        else f"Training episodes (mean per {args.window / 1e6:g} M steps)"
    )
    fig.suptitle(title)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_name(f".{args.out.stem}.tmp{os.getpid()}.png")
    try:
        fig.savefig(tmp, dpi=110)
        os.replace(tmp, args.out)
    finally:
        tmp.unlink(missing_ok=True)
        plt.close(fig)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
