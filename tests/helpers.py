"""Builders that several test modules share."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

from debris_gym.scenario import Body, Scenario


def simple_scenario(**overrides) -> Scenario:
    """Free-space field: one target 100 m along-track, one circle obstacle, dock at origin.

    Its physics (``mean_motion=0``, ``dt=10``, ``max_accel=0.05``) are free space: an env with
    the default LEO orbit flies it in free space, with a warning that the physics differ.
    """
    data = dict(
        dim=2,
        bounds=((-500.0, 500.0), (-500.0, 500.0)),
        dock=(0.0, 0.0),
        targets=(Body(position=(0.0, 100.0), radius=5.0, velocity=(0.0, 0.0)),),
        obstacles=(Body(position=(200.0, 0.0), radius=20.0, velocity=(0.0, 0.0)),),
        mean_motion=0.0,
        dt=10.0,
        max_accel=0.05,
    )
    data.update(overrides)
    return Scenario(**data)


ROOT = Path(__file__).resolve().parents[1]
"""The repository root, where the scripts live."""


def load_script(file_name: str, module_name: str | None = None) -> ModuleType:
    """Import one of the repository's scripts (``"evaluate.py"``, ``"train.py"``, …) as a module
    without running its ``main``; each call gives a fresh module."""
    name = module_name or f"debris_script_{Path(file_name).stem}"
    spec = importlib.util.spec_from_file_location(name, ROOT / file_name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
