"""A bank of mission start states: where recorded missions stood right after each capture.

Each entry is a :class:`~debris_gym.mission_starts.MissionStart` that puts a mission back in the
state a recorded episode reached at that step: the same moving field (its 64-bit word), every
body flown on to the step, the targets captured so far (in their order), the Δv spent, the
chaser's exact state. Resetting an env of the bank's ID and options with
``options={"start": bank.start(k)}`` reproduces the episode's observation at that step
(tested). Stored as one ``.npz`` file; the command that builds a bank from planner rollouts is
``python starts.py`` (docs/training.md, "Starting part-way").
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.files import save_atomic
from debris_gym.mission_starts import MissionStart

__all__ = ["FORMAT", "LEARNER_OPTIONS", "StartBank", "world_options"]

FORMAT = "debris-gym start bank 1"
"""The ``format`` stored in every bank file (a file of another format is refused)."""


LEARNER_OPTIONS = ("observation", "action", "fine_thrust", "shield", "shield_penalty")
"""Options that change only what a learner sees, does or is paid (with every option named
``reward_*``, ``shaping_*``, ``obs_*`` and ``lidar_*``): a bank fits envs that differ in them.
The shield filters the learner's commands in the same world (a recorded state stays valid)."""


def world_options(config: EnvConfig) -> dict[str, Any]:
    """The options of ``config`` that decide where a recorded start is valid: the fields, the
    physics and the rules (every option but the learner's, :data:`LEARNER_OPTIONS`)."""
    learner = ("reward_", "shaping_", "obs_", "lidar_")
    return {
        key: value
        for key, value in config.to_dict().items()
        if key not in LEARNER_OPTIONS and not key.startswith(learner)
    }


@dataclass(frozen=True)
class StartBank:
    """S start states recorded from missions of one env.

    Attributes:
        env_id: the env's registered ID.
        env_kwargs: the options it was made with (JSON-able).
        world: the recording env's :func:`world_options` (what an env must share with it).
        source: what flew the missions (e.g. ``"apf-mpc"``).
        words: (S,) uint64 each entry's field word.
        steps: (S,) int64 the step the entry was recorded at (after that step).
        states: (S, 2·dim) the chaser's LVLH state (m, m/s).
        captured: (S, T) int64 the targets captured by then, in capture order, −1 padded.
        delta_v: (S,) Δv spent by then (m/s).
        episodes: (S,) int64 the index of the recorded mission each entry comes from.
    """

    env_id: str
    env_kwargs: Mapping[str, Any]
    world: Mapping[str, Any]
    source: str
    words: np.ndarray
    steps: np.ndarray
    states: np.ndarray
    captured: np.ndarray
    delta_v: np.ndarray
    episodes: np.ndarray
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        s = len(self.words)
        for name in ("steps", "states", "captured", "delta_v", "episodes"):
            if len(getattr(self, name)) != s:
                raise ValueError(f"start bank: {name} has {len(getattr(self, name))} rows, not {s}")

    def __len__(self) -> int:
        return len(self.words)

    @property
    def legs(self) -> np.ndarray:
        """(S,) int64 the leg each entry starts: the number of targets captured."""
        return (self.captured >= 0).sum(axis=1)

    def start(self, k: int) -> MissionStart:
        """Entry ``k`` as a reset's start."""
        order = tuple(int(j) for j in self.captured[k] if j >= 0)
        return MissionStart(
            captured=order, step=int(self.steps[k]), delta_v=float(self.delta_v[k]),
            chaser_state=self.states[k].copy(), field_word=int(self.words[k]),
        )  # fmt: skip

    def check_config(self, config: EnvConfig) -> None:
        """Refuse an env whose fields, physics or rules differ from the recording env's (its
        starts put the chaser where that env's missions went, in that env's fields); the
        learner's options may differ.

        Raises:
            ValueError: naming the options that differ.
        """
        world = world_options(config)
        differ = sorted(
            k for k in set(world) | set(self.world) if world.get(k) != self.world.get(k)
        )
        if differ:
            shown = ", ".join(f"{k}={world.get(k)!r} (bank: {self.world.get(k)!r})" for k in differ)
            raise ValueError(
                f"the start bank was recorded in {self.env_id} with {dict(self.env_kwargs)}; this "
                f"env differs in {shown}: build a bank for it (python starts.py --env ...)"
            )

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the bank to ``path`` (``.npz``) atomically."""
        header = {
            "format": FORMAT, "env_id": self.env_id, "env_kwargs": dict(self.env_kwargs),
            "world": dict(self.world), "source": self.source, "meta": dict(self.meta),
        }  # fmt: skip

        def write(tmp: str) -> None:
            np.savez_compressed(
                tmp, header=np.array(json.dumps(header)), words=self.words, steps=self.steps,
                states=self.states, captured=self.captured, delta_v=self.delta_v,
                episodes=self.episodes,
            )  # fmt: skip

        save_atomic(path, write)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> StartBank:
        """Read a bank that :meth:`save` wrote.

        Raises:
            ValueError: not a start bank file (naming the path).
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                header = json.loads(str(data["header"]))
                arrays = {k: data[k] for k in ("words", "steps", "states", "captured")}
                arrays.update(delta_v=data["delta_v"], episodes=data["episodes"])
        except (OSError, KeyError, ValueError) as err:
            raise ValueError(f"{os.fspath(path)} is not a start bank ({err})") from err
        if header.get("format") != FORMAT:
            raise ValueError(f"{os.fspath(path)} is not a start bank of format {FORMAT!r}")
        return cls(
            env_id=header["env_id"], env_kwargs=header["env_kwargs"], world=header["world"],
            source=header["source"],
            meta=header.get("meta", {}), **arrays,
        )  # fmt: skip
