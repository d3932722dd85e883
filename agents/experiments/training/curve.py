"""The learning curve of a run: ``DIR/learning_curve.png`` from its evaluation and episode logs."""

from __future__ import annotations

import contextlib
import csv
from pathlib import Path

import numpy as np

from agents.experiments.config_files import load_config_file
from agents.experiments.training.run_files import is_complete_row
from debris_gym.files import save_atomic

__all__ = ["plot_learning_curve"]


def _rolling(values: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over ``window`` values (over all values so far for the first ones)."""
    if values.size == 0:
        return values
    csum = np.concatenate([[0.0], np.cumsum(values, dtype=float)])
    idx = np.arange(1, values.size + 1)
    start = np.maximum(idx - window, 0)
    return (csum[idx] - csum[start]) / (idx - start)


def plot_learning_curve(run_dir: str | Path) -> Path:
    """Draw ``DIR/learning_curve.png`` vs timesteps: held-out evaluation mean return (± std),
    targets captured and success rate (``evaluations.npz``), with the training episodes'
    (``train_episodes.csv``, trailing mean over 100 episodes). Returns the PNG path.

    The return includes the potential-based progress term, whose undiscounted sum grows with
    episode length (each step pays (1 − γ)·|Φ|): survival alone raises it. Targets captured and
    success rate are the task's own measures.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    fig, axes = plt.subplots(3, 1, figsize=(8, 8.5), sharex=True)
    ax_r, ax_t, ax_s = axes
    title = run_dir.name
    config_path = run_dir / "config.yaml"
    if config_path.is_file():
        with contextlib.suppress(Exception):
            data, _ = load_config_file(config_path)
            title = f"{data.get('algo', '?')} on {data.get('env_id', '?')} ({run_dir.name})"
    train_label = "training episodes (mean of last 100)"
    path = run_dir / "train_episodes.csv"
    if path.is_file():
        with open(path, newline="") as fh:
            reader = csv.reader(fh)
            header = next(reader, [])
            rows = [dict(zip(header, r)) for r in reader if is_complete_row(r, len(header))]
        if rows:
            t = np.array([float(r["timesteps"]) for r in rows])
            columns = {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if k != "wall_s"}
            ax_r.scatter(t, columns["return"], s=3, color="tab:gray", alpha=0.2)
            for ax, key in ((ax_r, "return"), (ax_t, "targets_captured"), (ax_s, "is_success")):
                ax.plot(t, _rolling(columns[key], 100), color="tab:gray", label=train_label)
    path = run_dir / "evaluations.npz"
    if path.is_file():
        with np.load(path, allow_pickle=True) as data:
            t = np.asarray(data["timesteps"], dtype=float)
            series = {
                key: [np.asarray(v, dtype=float) for v in data[key]]
                for key in ("results", "targets_captured", "successes")
                if key in data and len(data[key]) == t.size
            }
        if t.size:
            label = "held-out evaluation (mean)"
            mean = np.array([r.mean() for r in series["results"]])
            std = np.array([r.std() for r in series["results"]])
            ax_r.plot(t, mean, "o-", color="tab:blue", label=label + " ± std")
            ax_r.fill_between(t, mean - std, mean + std, color="tab:blue", alpha=0.2)
            for ax, key in ((ax_t, "targets_captured"), (ax_s, "successes")):
                if key in series:
                    ax.plot(t, [v.mean() for v in series[key]], "o-", color="tab:blue", label=label)
    ax_r.set_ylabel("episode return")
    ax_t.set_ylabel("targets captured")
    ax_s.set_ylabel("success rate")
    ax_s.set_ylim(-0.05, 1.05)
    ax_s.set_xlabel("timesteps (env steps)")
    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
        else:
            ax.text(0.5, 0.5, "no finished episodes yet", ha="center", transform=ax.transAxes)
    ax_r.set_title(title, fontsize=10)
    fig.tight_layout()
    out = run_dir / "learning_curve.png"
    save_atomic(out, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return out
