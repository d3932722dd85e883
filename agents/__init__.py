"""Guidance baselines and learned policies for the debris_gym environments, all behind one
``predict()`` interface.

``make_agent(name, env, **params)`` builds a baseline by name:

=============  ==================================================================
``zero``       never thrusts (floor)
``random``     uniform random thrust (floor)
``apf``        artificial potential field, gradient → thrust with damping
``apf-rrt``    APF with local-minimum detection and RRT escape ([An23])
``apf-mpc``    APF reference path tracked by an OSQP MPC on the CWH model ([APF-MPC])
``astar``      A* grid path tracked by the same MPC (the [APF-MPC] A* baseline)
``st-rrt``     Tube-ST-RRT*: space-time RRT* among the moving bodies, a tube of
               free balls, minimum-snap smoothing, tracked by the MPC ([Zhou24])
``se-scp``     spherical expansion and sequential convex programming of a
               fuel-optimal trajectory, tracked by the MPC ([Bandyopadhyay17])
``base-law``   the compiled CW guidance law of ``action="residual"`` flown alone:
               line of sight to the goal's hold point, bent around near bodies
=============  ==================================================================

Every name of :data:`BASELINES` is listed here (``tests/test_docs.py`` checks it);
docs/baselines.md describes each method, its parameters and its measured results.

``load_agent("ppo:runs/ppo/model.zip", env)`` loads a policy trained by ``train.py`` (``sac``,
``td3``, ``dqn`` likewise; ``load_agent("pretrained", env)`` the shipped one) behind the same
interface; see :mod:`agents.policies.learned`.

The package is layered, imports pointing one way: :mod:`agents.planners` (pure functions of a
field) → :mod:`agents.control` (the MPC tracker, reference profiles) → :mod:`agents.policies`
(every ``predict()`` agent and the registry) → :mod:`agents.experiments` (training, imitation,
evaluation). ``import agents`` imports neither torch nor the experiment machinery.

Keys in square brackets refer to docs/references.md.
"""

from __future__ import annotations

from agents.policies.learned import observation_options
from agents.policies.registry import BASELINES, load_agent, make_agent

__all__ = ["BASELINES", "load_agent", "make_agent", "observation_options"]
