"""The ladder table of docs/training.md: every agent's success and typical return on each rung.

Reads the ``episodes.csv`` that ``evaluate.py`` wrote for each rung and prints one Markdown
table: per agent and rung, the success rate, the median and mean episode return (the shaped
reward a learner maximises), the mean task score (the unshaped one) and the success of each leg
(the flight to the k-th target over the missions that reached its start, then the return).

    python evaluate.py --env DebrisGym/Rendezvous2D-Easy-v1 --agents zero,random,apf,... \
        --episodes 20 --out runs/ladder/easy
    ...
    python docs/ladder_table.py runs/ladder/easy runs/ladder/medium runs/ladder/default
"""

from __future__ import annotations

import argparse
import csv
import json
from collections import defaultdict
from pathlib import Path

import numpy as np


def rung_rows(folder: Path) -> tuple[str, dict[str, dict[str, float]]]:
    """(env ID, agent → its figures) of one evaluation directory."""
    summary = json.loads((folder / "summary.json").read_text())
    episodes: dict[str, list[dict[str, str]]] = defaultdict(list)
    with open(folder / "episodes.csv", newline="") as fh:
        for row in csv.DictReader(fh):
            episodes[row["agent"]].append(row)
    figures = {}
    for agent, rows in episodes.items():
        returns = np.array([float(r["return"]) for r in rows])
        captured = np.array([int(r["targets_captured"]) for r in rows])
        success = np.array([r["success"] in ("1", "True", "true") for r in rows])
        n = max(int(r["n_targets"]) for r in rows)
        figures[agent] = {
            "legs": leg_counts(captured, success, n),
            "n": len(rows),
            "success": float(np.mean([r["success"] in ("1", "True", "true") for r in rows])),
            "return_median": float(np.median(returns)),
            "return_mean": float(np.mean(returns)),
            "task_score": float(np.mean([float(r["task_score"]) for r in rows])),
        }
    return summary["env_id"], figures


def table(folders: list[Path]) -> str:
    """The Markdown table over the rungs in ``folders`` (in that order)."""
    rungs = [rung_rows(folder) for folder in folders]
    agents: list[str] = []
    for _, figures in rungs:
        agents += [a for a in figures if a not in agents]
    header = "| agent | " + " | ".join(f"`{env.split('/')[-1]}`" for env, _ in rungs) + " |"
    lines = [header, "|---|" + "---|" * len(rungs)]
    for agent in agents:
        cells = []
        for _, figures in rungs:
            f = figures.get(agent)
            cells.append(
                "–"
                if f is None
                else (
                    f"{f['success']:.0%} · {f['return_median']:.1f} "
                    f"({f['return_mean']:.1f}) · {f['task_score']:.1f} · legs "
                    + "/".join("–" if s == 0 else f"{d / s:.0%}" for d, s in f["legs"])
                )
            )
        lines.append(f"| {agent} | " + " | ".join(cells) + " |")
    counts = sorted({f["n"] for _, figures in rungs for f in figures.values()})
    lines.append("")
    lines.append(
        "Each cell: success · median (mean) return · mean task score · the success of each leg "
        "(to target 1, 2, …, then home; over the missions that reached its start), over "
        f"{'/'.join(map(str, counts))} missions per agent and rung (reset seeds 0…)."
    )
    return "\n".join(lines)


def leg_counts(captured: np.ndarray, success: np.ndarray, n: int) -> list[tuple[int, int]]:
    """(missions that completed, missions that reached the start) of each leg: to target
    k = 1 … n, then the return after the n-th capture."""
    counts = [(int(np.sum(captured >= k)), int(np.sum(captured >= k - 1))) for k in range(1, n + 1)]
    counts.append((int(np.sum(success)), int(np.sum(captured == n))))
    return counts


def leg_table(folder: Path) -> str:
    """Per-leg success of every agent in one evaluation: leg k (k = 1…n) is the flight to the
    k-th target, counted over the missions that reached its start (k − 1 captures), and the
    return leg the flight home after the n-th capture; a mission that stops on a leg (collision,
    bounds, budget, time) fails that leg."""
    rows_by_agent: dict[str, list[dict[str, str]]] = defaultdict(list)
    with open(folder / "episodes.csv", newline="") as fh:
        for row in csv.DictReader(fh):
            rows_by_agent[row["agent"]].append(row)
    n = max(int(r["n_targets"]) for rows in rows_by_agent.values() for r in rows)
    header = "| agent | " + " | ".join(f"leg {k}" for k in range(1, n + 1)) + " | return |"
    lines = [header, "|---|" + "---|" * (n + 1)]
    for agent, rows in rows_by_agent.items():
        captured = np.array([int(r["targets_captured"]) for r in rows])
        success = np.array([r["success"] in ("1", "True", "true") for r in rows])
        cells = [f"{d}/{s}" if s else "–" for d, s in leg_counts(captured, success, n)]
        lines.append(f"| {agent} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="evaluate.py output directories")
    parser.add_argument(
        "--legs", action="store_true", help="per-leg success of each folder's agents instead"
    )
    args = parser.parse_args(argv)
    if args.legs:
        for folder in args.folders:
            print(f"{folder}:\n{leg_table(folder)}\n")
    else:
        print(table(args.folders))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
