"""Reward terms and the shaping potential (no gymnasium import).

The reward is a sum of named terms; each term's weight is the config key ``reward_<term>``.
Penalty weights are given as positive magnitudes and enter with a minus sign.

=================  ===============================================================
term               value per step
=================  ===============================================================
``capture``        ``+reward_capture`` × targets captured this step
``success``        ``+reward_success`` on completing the mission
``progress``       ``reward_progress`` × (γ Φ(s′) − Φ(s)), Φ(terminal) = 0
``delta_v``        ``−reward_delta_v`` × Δv spent this step (m/s)
``collision``      ``−reward_collision`` on a collision
``out_of_bounds``  ``−reward_out_of_bounds`` on leaving the world bounds
``time``           ``−reward_time`` every step
=================  ===============================================================

The progress term is potential-based (Ng, Harada & Russell 1999), so it changes how fast an agent
learns but not which policy is optimal (for the same γ as the learner's).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from debris_gym.config import EnvConfig

REWARD_TERMS = ("capture", "success", "progress", "delta_v", "collision", "out_of_bounds", "time")


def potential(goal_gap: float, goals_after: int, length_scale: float) -> float:
    """Shaping potential Φ(s) = −(gap to the current goal / length_scale + goals after it).

    Args:
        goal_gap: distance (m) from the chaser to the current goal (a target's surface, or the
            dock); 0 when no goal is left.
        goals_after: number of goals still to visit after the current one (targets, plus the dock
            if a return is required), so that completing a goal raises Φ by about 1.
        length_scale: normalising length (m), e.g. half the field size.
    """
    return -(goal_gap / length_scale + goals_after)


def reward_terms(
    cfg: EnvConfig,
    *,
    new_captures: Any,
    success: Any,
    progress: Any,
    delta_v: Any,
    collision: Any,
    out_of_bounds: Any,
) -> dict[str, Any]:
    """The weighted reward terms of one step, for one env (scalars) or a batch (arrays).

    Args:
        cfg: weights ``reward_<term>``.
        new_captures: targets captured this step.
        success, collision, out_of_bounds: this step's flags.
        progress: γΦ(s′) − Φ(s) (before the terminal correction).
        delta_v: Δv spent this step (m/s).
    """
    time = np.full(np.shape(delta_v), -cfg.reward_time) if np.ndim(delta_v) else -cfg.reward_time
    return {
        "capture": cfg.reward_capture * new_captures,
        "success": cfg.reward_success * success,
        "progress": cfg.reward_progress * progress,
        "delta_v": -cfg.reward_delta_v * delta_v,
        "collision": -cfg.reward_collision * collision,
        "out_of_bounds": -cfg.reward_out_of_bounds * out_of_bounds,
        "time": time,
    }
