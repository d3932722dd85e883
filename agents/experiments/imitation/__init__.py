"""Imitation learning: a policy network taught by a classical baseline (behaviour cloning + DAgger).

The classical APF-MPC agent completes every held-out mission but decides in about a millisecond
with a QP per step; PPO from scratch plateaus far below it (docs/training.md). This module trains
the same kind of small MLP policy as PPO does, by supervised regression on the expert's actions:

1. **Behaviour cloning**: the expert flies ``bc_episodes`` training fields; every (observation,
   expert action) pair is kept.
2. **DAgger** [Ross11]: for each of ``dagger_rounds`` rounds the current
   policy flies ``dagger_episodes`` fields while the expert, attached to the same env, names the
   action it would take in every state the *policy* visits; those pairs join the data set and the
   policy is refit. The policy thereby learns to recover from its own mistakes, which plain
   cloning never shows it.

The expert follows the env's own current goal (``ordering="nearest"``, see
:class:`agents.planners.mission.MissionPlan`), the goal the policy sees in its observation
(``obs_goal``), so the labels are a function of what the policy can observe. Rollouts run in
``workers`` processes; the fit is plain mean-squared error on the normalised action, with the
observation normalised by the data set's mean and standard deviation.

One job per module (import from them):

==========  ==========================================================================
config      :class:`~.config.ImitationConfig`, the checked-in configs, the expert's settings
collection  expert-labelled rollouts in worker processes
fitting     the policy network, its fit, and its numpy copy for the workers
run         :func:`~.run.imitate` — what ``imitate.py`` calls
==========  ==========================================================================

The result is an SB3 PPO model (its actor trained here, its value head untouched) with a
VecNormalize file holding the observation statistics, in the same run-directory layout as
``train.py`` writes, so :func:`agents.load_agent` and ``evaluate.py --agents ppo=DIR/model.zip``
use it as they use any trained policy.
"""
