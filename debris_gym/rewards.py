"""Reward terms and the shaping potential (no gymnasium import).

The reward is a sum of named terms; each term's weight is the config key ``reward_<term>``.
Penalty weights are given as positive magnitudes and enter with a minus sign.

=================  ===============================================================
term               value per step
=================  ===============================================================
``capture``        ``+reward_capture`` × targets captured this step
``success``        ``+reward_success`` on completing the mission
``progress``       ``reward_progress`` × (γ Φ(s′) − Φ(s)), Φ after termination per
                   ``shaping_terminal`` ("zero": 0; "hold": its own value)
``delta_v``        ``−reward_delta_v`` × Δv spent this step (m/s)
``collision``      ``−reward_collision`` on a collision
``out_of_bounds``  ``−reward_out_of_bounds`` on leaving the world bounds
``time``           ``−reward_time`` every step
``budget``         ``−reward_budget`` when the Δv budget runs out (the mission failed:
                   it ends with no success, collision or exit in that step)
=================  ===============================================================

Φ(s) = −(gap to the current goal / L + goals after it), minus, when ``shaping_speed`` > 0,
``shaping_speed`` · max(0, speed − (capture_speed + ``shaping_speed_slope`` · gap)) / V, and
minus, when ``shaping_clearance`` > 0, ``shaping_clearance`` · max(0, 1 − c / d)², c the gap
from the chaser's surface to the nearest obstacle (debris that is not a target) and d
``shaping_clearance_distance`` (m), and minus, when ``shaping_closing`` > 0, ``shaping_closing``
· max over the bodies b other than the current goal whose clearance c_b is below
``shaping_closing_distance`` d of max(0, v_b − capture_speed) / V · (1 − c_b / d), v_b the
chaser's speed toward b's centre. The progress term is potential-based ([Ng99] in
docs/references.md), so it changes how fast an agent learns but not which policy is optimal (for
the same γ as the learner's, and Φ = 0 after termination).

The terms are computed in the envs' compiled step (:mod:`debris_gym.mission_step`); this
module names them (in the order of ``info["reward_terms"]`` and of the step's term columns).
"""

from __future__ import annotations

REWARD_TERMS = (
    "capture", "success", "progress", "delta_v", "collision", "out_of_bounds", "time", "budget"
)  # fmt: skip
