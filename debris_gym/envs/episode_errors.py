"""The uncertain world's draws of a mission shell: each new episode's error key, and the field
as the chaser's navigation saw it at the episode's start."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.scenario import Scenario
from debris_gym.uncertainty import estimated_field

__all__ = ["EpisodeErrors"]


class EpisodeErrors:
    """Per field, the generator of its episodes' error keys: a child of the field's generator,
    spawned when first needed, so that drawing keys never moves the field draws on.

    Args:
        fields: number of fields.
        chasers: chasers per field (each gets its field's key).
    """

    def __init__(self, fields: int, chasers: int) -> None:
        self._chasers = chasers
        self._generators: list[np.random.Generator | None] = [None] * fields
        self._estimates: dict[int, tuple[int, Scenario, Scenario]] = {}

    def forget(self, field: int) -> None:
        """Field ``field`` got a new generator (a seeded reset): its errors follow the new
        seed."""
        self._generators[field] = None

    def keys(
        self,
        fields: np.ndarray,
        field_generators: Sequence[np.random.Generator],
        config: EnvConfig,
    ) -> np.ndarray | None:
        """The error keys of new episodes in ``fields``, one per row (``chasers`` per field),
        uint64; None in a world without errors (``config``; nothing is drawn then)."""
        if not config.uncertain:
            return None
        keys = np.empty(len(fields), dtype=np.uint64)
        for r, f in enumerate(np.asarray(fields).tolist()):
            generator = self._generators[f]
            if generator is None:
                generator = self._generators[f] = _child(field_generators[f])
            keys[r] = generator.integers(0, np.iinfo(np.uint64).max, dtype=np.uint64, endpoint=True)
        return np.repeat(keys, self._chasers)

    def estimated(self, field: int, truth: Scenario, key: int, config: EnvConfig) -> Scenario:
        """``truth`` (field ``field`` at its episode's start) plus the navigation errors of the
        episode of error key ``key`` (the same object again while neither changes)."""
        cached = self._estimates.get(field)
        if cached is not None and cached[0] == key and cached[1] is truth:
            return cached[2]
        estimate = estimated_field(truth, key, config)
        self._estimates[field] = (key, truth, estimate)
        return estimate


def _child(generator: np.random.Generator) -> np.random.Generator:
    """A generator independent of ``generator`` that leaves its stream where it is: spawned
    from its seed sequence, or (a generator built without one) seeded from its state."""
    try:
        return generator.spawn(1)[0]
    except (TypeError, ValueError):
        words = np.frombuffer(repr(generator.bit_generator.state).encode(), dtype=np.uint8)
        return np.random.default_rng(np.random.SeedSequence(words.tolist()))
