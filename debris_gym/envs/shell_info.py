"""The ``info`` of a mission shell's steps and resets: one table of keys, read for every row
(the vector env) or for one row as Python scalars (the single env)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from debris_gym.envs.loop_shield import LoopShield, row_shield_info, shield_info, shield_term
from debris_gym.mission_batch import MissionBatch
from debris_gym.rewards import REWARD_TERMS

__all__ = ["INFO_KEYS", "all_rows_info", "one_row_info"]

INFO_KEYS = (
    "chaser_state",
    "time",
    "delta_v",
    "targets_captured",
    "n_targets",
    "captured",
    "hold",
    "min_clearance",
    "collision",
    "out_of_bounds",
    "budget_spent",
    "is_success",
    "applied_accel",
    "task_score",
    "reward_terms",
    "shield_intervened",
    "shield_interventions",
)
"""The keys of every step's and reset's ``info`` (docs/environments.md, "Info")."""


def all_rows_info(
    batch: MissionBatch, chaser_radius: float, shield: LoopShield | None, terms: np.ndarray
) -> dict[str, Any]:
    """The :data:`INFO_KEYS` of every mission of ``batch`` as new arrays (row i = mission i).

    Args:
        batch: the missions.
        chaser_radius: the chaser's radius (m): ``min_clearance`` is surface to surface.
        shield: the compiled safety shield, or None.
        terms: (N, 8) the step's reward terms (by term name under ``"reward_terms"``).
    """
    m, num = batch.missions, batch.num
    return {
        "chaser_state": m.state.copy(),
        "time": m.time.copy(),
        "delta_v": m.delta_v.copy(),
        "targets_captured": batch.captured_counts(),
        "n_targets": np.full(num, batch.n_targets),
        "captured": m.captured.copy(),
        "hold": m.hold.copy(),
        "min_clearance": m.min_clearance - chaser_radius,
        "collision": m.collision.copy(),
        "out_of_bounds": m.out_of_bounds.copy(),
        "budget_spent": m.budget_spent.copy(),
        "is_success": m.success.copy(),
        "applied_accel": m.accel.copy(),
        "task_score": m.score.copy(),
        "reward_terms": shield_term(shield, dict(zip(REWARD_TERMS, terms.T.copy()))),
        **shield_info(shield, num),
    }


def one_row_info(
    batch: MissionBatch,
    i: int,
    chaser_radius: float,
    shield: LoopShield | None,
    terms: Sequence[float],
) -> dict[str, Any]:
    """The :data:`INFO_KEYS` of mission ``i`` as Python scalars and arrays of its own;
    ``terms`` its 8 reward terms (the other arguments as for :func:`all_rows_info`)."""
    m = batch.missions
    captured = m.captured[i].copy()
    # item(i) gives the Python scalar without a numpy scalar in between: this runs every
    # step of the single env
    return {
        "chaser_state": m.state[i].copy(),
        "time": m.time.item(i),
        "delta_v": m.delta_v.item(i),
        "targets_captured": captured.tolist().count(True),
        "n_targets": batch.n_targets,
        "captured": captured,
        "hold": m.hold[i].copy(),
        "min_clearance": m.min_clearance.item(i) - chaser_radius,
        "collision": m.collision.item(i),
        "out_of_bounds": m.out_of_bounds.item(i),
        "budget_spent": m.budget_spent.item(i),
        "is_success": m.success.item(i),
        "applied_accel": m.accel[i].copy(),
        "task_score": m.score.item(i),
        "reward_terms": shield_term(shield, dict(zip(REWARD_TERMS, terms)), i),
        **row_shield_info(shield, i),
    }
