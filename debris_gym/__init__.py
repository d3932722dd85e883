"""debris-gym: Gymnasium environments for multi-target spacecraft rendezvous in debris fields.

Importing the package registers the ``DebrisGym/…`` IDs; ``gym.make("debris_gym:DebrisGym/…")``
imports it for you.
"""

from debris_gym.registration import ENV_SPECS, register_envs
from debris_gym.scenario import Body, Scenario

__version__ = "0.1.0"
__all__ = ["ENV_SPECS", "Body", "Scenario", "__version__", "register_envs"]

register_envs()
