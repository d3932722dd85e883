"""Run the chosen sections and gather their rows: the entry point of the benchmark as a library.

Everything is measured in one process, in one run (the memory section in child processes, and
SubprocVecEnv steps its envs in its workers), and reported as *ratios* measured within that run:
absolute speeds on shared machines are noisy and only comparable inside a run.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

from bench.config import FULL, QUICK
from bench.decisions import run_decisions
from bench.harness import pin_torch
from bench.memory import run_memory
from bench.scaling import run_scaling
from bench.shield import run_shield
from bench.single import run_single
from bench.swarm import run_swarm
from bench.train import run_train
from bench.vector import run_vector

SECTIONS = ("single", "vector", "scaling", "shield", "swarm", "memory", "train", "decisions")
"""Section names for ``--only`` / ``run(sections=…)``, in the order they run."""


def choose_sections(sections: Iterable[str] | None) -> tuple[str, ...]:
    """The named sections in run order (all of them for None).

    Raises:
        ValueError: a name that is not in :data:`SECTIONS`, or no name at all.
    """
    if sections is None:
        return SECTIONS
    names = [str(s) for s in sections]
    chosen = tuple(s.strip() for s in names if s.strip())
    unknown = sorted(set(chosen) - set(SECTIONS))
    if not chosen:
        raise ValueError(
            f"names no section (got {','.join(names)!r}); choose from {', '.join(SECTIONS)}"
        )
    if unknown:
        raise ValueError(f"unknown section(s) {unknown}; choose from {', '.join(SECTIONS)}")
    return tuple(s for s in SECTIONS if s in chosen)


def run(
    quick: bool = False,
    steps: int | None = None,
    *,
    resets: int | None = None,
    repeats: int | None = None,
    progress: bool = True,
    sections: Iterable[str] | None = None,
    sizes: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Run every measurement of the chosen sections and return one row (dict) per measurement.

    Args:
        quick: fewer and shorter repeats, smaller N.
        steps: fixed steps per repeat for every step measurement, single-env and vector (default:
            calibrated so a repeat lasts about the same time for every env).
        resets: fixed resets per repeat for the reset measurements (default: calibrated).
        repeats: number of interleaved repeats (default 3 quick, 5 full; the training section
            uses ``train_repeats`` unless this is given).
        progress: show a tqdm bar on stderr.
        sections: names from :data:`SECTIONS` (default: all).
        sizes: overrides of the :data:`bench.config.QUICK` / :data:`bench.config.FULL`
            settings, e.g. :data:`bench.config.TINY`.

    Returns:
        The rows, section by section. Every row carries ``section``, ``env_id``, ``variant``,
        ``level``, ``n_obstacles`` and ``error`` (None, or the message of what failed: a failure
        is reported in its row, not raised). Their other fields are described by
        :func:`bench.single.single_rows` (sections "step", "scaling", "reset"),
        :func:`bench.vector.vector_rows` ("vector", "vector_scaling"),
        :func:`bench.shield.run_shield` ("shield"),
        :func:`bench.swarm.swarm_rows` ("swarm"), :func:`bench.memory.run_memory` ("memory"),
        :func:`bench.train.train_rows` ("train") and :func:`bench.decisions.decision_rows`
        ("decisions").

    Raises:
        ValueError: an unknown section name.
    """
    chosen = choose_sections(sections)
    if "torch" in sys.modules:  # pin only if something imported it: importing it is slow
        pin_torch()
    cfg = dict(QUICK if quick else FULL)
    cfg.update(sizes or {})
    n_repeats = repeats if repeats is not None else cfg["repeats"]
    rows: list[dict[str, Any]] = []
    if "single" in chosen:
        rows += run_single(cfg, n_repeats, steps, resets, progress)
    if "vector" in chosen:
        rows += run_vector(cfg, n_repeats, steps, progress)
    if "scaling" in chosen:
        rows += run_scaling(cfg, n_repeats, steps, progress)
    if "shield" in chosen:
        rows += run_shield(cfg, n_repeats, steps, progress)
    if "swarm" in chosen:
        rows += run_swarm(cfg, n_repeats, steps, progress)
    if "memory" in chosen:
        rows.append(run_memory(cfg))
    if "train" in chosen:
        train_repeats = repeats if repeats is not None else cfg["train_repeats"]
        rows += run_train(cfg, train_repeats, progress)
    if "decisions" in chosen:
        rows += run_decisions(cfg, steps, progress)
    return rows
