"""How a run was made: library versions and UTC timestamps, recorded in its ``config.yaml``."""

from __future__ import annotations

import platform
from datetime import datetime, timezone

import numpy as np

__all__ = ["iso_time", "library_versions", "utc_now"]


def library_versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import debris_gym

    versions = {
        "debris_gym": debris_gym.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gymnasium.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }
    return {k: str(v) for k, v in versions.items()}  # torch's version is a str subclass


def utc_now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def iso_time(t: float) -> str:
    """A Unix time (s) as an ISO 8601 UTC timestamp, to the second."""
    return datetime.fromtimestamp(t, tz=timezone.utc).isoformat(timespec="seconds")
