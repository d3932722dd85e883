"""One compiled call for a step and the observation after it.

The single env steps one mission and observes it at once; as two compiled calls, each unboxes
the same records (the rules, the missions, the field: dozens of arrays) on its way in, which
costs a third of the two calls for one row (docs/benchmarks.md, "Measured design choices").
:func:`step_observe` runs :func:`~debris_gym.mission_step.step_all` and
:func:`~debris_gym.observation.observe_all` in one call with the same arguments, so the
records are unboxed once, and without numba's reference counting (it only borrows the arrays
its caller holds; the step's own scratch arrays are counted inside
:func:`~debris_gym.mission_step.step_all`). The results are those of the two calls in turn.
"""

from __future__ import annotations

from debris_gym.jit import borrowing
from debris_gym.mission_step import step_all
from debris_gym.observation import observe_all

__all__ = ["step_observe"]


@borrowing  # no reference counting of its arguments: they are unboxed at a third of the cost
def step_observe(live, actions, rules, shaping, missions, field, outputs, layout, horizon, out):
    """:func:`step_all` (``live``, ``actions`` (N, dim) float64, the step's records, its
    ``outputs``), then :func:`observe_all` of every mission into ``out`` (N, size) float32
    (``horizon``: steps the ``time_remaining`` element counts down from)."""
    step_all(live, actions, rules, shaping, missions, field, outputs)
    observe_all(rules, layout, missions, field, horizon, out)
