"""Planners: pure functions of a field (a :class:`debris_gym.Scenario`) that return explicit
result dataclasses. They know no env, never print and never plot.

Layer order inside ``agents``: planners → control → policies → experiments; a module imports only
from its own layer or the layers before it.
"""
