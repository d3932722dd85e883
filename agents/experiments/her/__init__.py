"""Hindsight experience replay (HER) with goal-conditioned SAC on the one-target rungs.

============  ======================================================================
goal_env      :class:`GoalConditionedEnv`: the goal ``Dict`` observation and the sparse,
              relabellable reward (the design is in its docstring)
train         :func:`train_sac`: SAC+HER, or plain SAC as the control; held-out curve
policy        :class:`GoalPolicy`, :func:`load_policy`, :func:`policy`: fly a trained
              model through ``evaluate.py`` / ``evaluate_agents``
============  ======================================================================

``python -m agents.experiments.her --help`` trains; docs/training.md ("HER with
goal-conditioned SAC") has the commands and what was measured.
"""

from agents.experiments.her.goal_env import DEFAULT_CRASH_PENALTY, GoalConditionedEnv, GoalLayout
from agents.experiments.her.policy import MODEL_ENV_VAR, GoalPolicy, load_policy, policy

__all__ = [
    "DEFAULT_CRASH_PENALTY",
    "MODEL_ENV_VAR",
    "GoalConditionedEnv",
    "GoalLayout",
    "GoalPolicy",
    "load_policy",
    "policy",
]
