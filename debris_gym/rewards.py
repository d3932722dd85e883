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
