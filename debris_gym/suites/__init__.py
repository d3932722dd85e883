"""Frozen evaluation suites shipped with the package: named, fixed lists of missions.

A suite is a file ``debris_gym/suites/NAME.json.gz``: gzip of the JSON object ::

    {"name": str, "env_id": str, "description": str, "env_kwargs": {...},
     "provenance": {"command": str, "git": str},
     "missions": [{"seed": int, "scenario": Scenario.to_dict()}, ...]}

Episode ``i`` of a suite is ``env.reset(seed=missions[i].seed, options={"scenario":
missions[i].scenario})`` in ``gym.make(env_id, **env_kwargs)``: the field is pinned and the
chaser starts at rest at the dock, so the start state is fully determined by the file. The seed
is the one the field was drawn with (its provenance); it also seeds the env's generator.

Suites are for evaluation only: ``evaluate.py --suite NAME`` flies them, and ``train.py`` /
``imitate.py`` refuse any option that would train or select models on their missions
(:func:`seeds_in_suites`). Their seeds are drawn from :data:`RESERVED_SEEDS`, which no default
training, periodic-evaluation or imitation seed reaches. ``python -m debris_gym.suites.build``
writes the standard suites (docs/baselines.md, "Evaluation suites").

This module needs nothing beyond :class:`~debris_gym.scenario.Scenario` (no gymnasium).
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

from debris_gym.scenario import Scenario

__all__ = [
    "EVALUATION_ONLY",
    "RESERVED_SEEDS",
    "SUITE_KEYS",
    "Mission",
    "Suite",
    "list_suites",
    "load_suite",
    "read_suite",
    "refuse_suite_seeds",
    "seeds_in_suites",
    "suite_seeds",
    "write_suite",
]

RESERVED_SEEDS = range(900_000_000, 1_000_000_000)
"""Reset seeds kept for evaluation suites. Training (seeds below 1 000 000), train.py's periodic
evaluation (1 000 000 + i), imitation's default fields (5 000 000 + k) and the docs' held-out
evaluations (10 000 000, 20 000 000) stay below it."""

SUITE_KEYS = ("name", "env_id", "description", "env_kwargs", "provenance", "missions")
"""Top-level keys of a suite file, all required."""

_SUFFIX = ".json.gz"


class Mission(NamedTuple):
    """One mission of a suite: the reset seed and the pinned field."""

    seed: int
    scenario: Scenario


@dataclass(frozen=True)
class Suite:
    """A frozen evaluation suite.

    Attributes:
        name: the suite's name (its file is ``NAME.json.gz``).
        env_id: the registered env every mission is flown in.
        description: what the suite is for (free text).
        env_kwargs: ``gym.make`` keyword arguments besides ``env_id``.
        missions: ``(seed, scenario)`` of every mission, episode order.
        provenance: how the file was made: ``{"command": ..., "git": commit}``.
    """

    name: str
    env_id: str
    description: str
    env_kwargs: Mapping[str, Any]
    missions: tuple[Mission, ...]
    provenance: Mapping[str, str] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.missions)

    @property
    def seeds(self) -> tuple[int, ...]:
        """Reset seeds of the missions, episode order."""
        return tuple(m.seed for m in self.missions)

    @property
    def content_hash(self) -> str:
        """SHA-256 (16 hex digits) of what is flown: name, env_id, env_kwargs and missions in
        canonical JSON (sorted keys). Description and provenance are left out."""
        return _content_hash(self._flown_json())

    def _flown_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "env_id": self.env_id,
            "env_kwargs": dict(self.env_kwargs),
            "missions": [{"seed": m.seed, "scenario": m.scenario.to_dict()} for m in self.missions],
        }

    def to_dict(self) -> dict[str, Any]:
        """The file's JSON object."""
        data = self._flown_json()
        return {
            "name": data["name"],
            "env_id": data["env_id"],
            "description": self.description,
            "env_kwargs": data["env_kwargs"],
            "provenance": dict(self.provenance),
            "missions": data["missions"],
        }


def _content_hash(flown: Mapping[str, Any]) -> str:
    text = json.dumps(flown, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _suite_dir() -> Path:
    return Path(str(resources.files(__name__)))


def list_suites() -> list[str]:
    """Names of the suites shipped with the package, sorted."""
    return sorted(p.name[: -len(_SUFFIX)] for p in _suite_dir().glob(f"*{_SUFFIX}"))


def _suite_path(name: str) -> Path:
    names = list_suites()
    if not isinstance(name, str) or name not in names:
        raise ValueError(
            f"suite must be one of {', '.join(names) or '(none shipped)'}; got {name!r}"
        )
    return _suite_dir() / f"{name}{_SUFFIX}"


def _read_json(path: str | os.PathLike[str]) -> dict[str, Any]:
    try:
        with gzip.open(path, "rt", encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, EOFError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a gzip-compressed JSON suite file ({exc})") from exc
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a suite file holds a JSON object, got {type(data).__name__}")
    missing = [k for k in SUITE_KEYS if k not in data]
    unknown = sorted(set(data) - set(SUITE_KEYS))
    if missing or unknown:
        raise ValueError(
            f"{path}: suite keys must be exactly {list(SUITE_KEYS)}; missing {missing}, "
            f"unknown {unknown}"
        )
    return data


def _seed(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{where}.seed must be an integer >= 0, got {value!r}")
    return value


def read_suite(path: str | os.PathLike[str]) -> Suite:
    """Read and check a suite file (any path); every scenario passes ``Scenario.from_dict``.

    Raises:
        ValueError: not gzip JSON, keys other than :data:`SUITE_KEYS`, a bad value (naming it),
            no missions, or a seed listed twice.
    """
    data = _read_json(path)
    for key in ("name", "env_id", "description"):
        if not isinstance(data[key], str) or (key != "description" and not data[key]):
            raise ValueError(f"{path}: {key} must be a non-empty string, got {data[key]!r}")
    for key in ("env_kwargs", "provenance"):
        if not isinstance(data[key], dict):
            raise ValueError(f"{path}: {key} must be a JSON object, got {data[key]!r}")
    raw = data["missions"]
    if not isinstance(raw, list) or not raw:
        raise ValueError(f"{path}: missions must be a non-empty list of {{seed, scenario}}")
    missions = []
    for i, item in enumerate(raw):
        where = f"{path}: missions[{i}]"
        if not isinstance(item, dict) or set(item) != {"seed", "scenario"}:
            raise ValueError(f"{where} must be an object with exactly the keys seed, scenario")
        try:
            scenario = Scenario.from_dict(item["scenario"])
        except ValueError as exc:
            raise ValueError(f"{where}.scenario: {exc}") from exc
        missions.append(Mission(_seed(item["seed"], where), scenario))
    seeds = [m.seed for m in missions]
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"{path}: a mission seed is listed twice")
    return Suite(
        name=data["name"],
        env_id=data["env_id"],
        description=data["description"],
        env_kwargs=dict(data["env_kwargs"]),
        missions=tuple(missions),
        provenance={str(k): str(v) for k, v in data["provenance"].items()},
    )


@functools.cache
def load_suite(name: str) -> Suite:
    """The shipped suite ``name`` (one of :func:`list_suites`), read once per process.

    Raises:
        ValueError: an unknown name (listing the known ones), or a damaged file.
    """
    suite = read_suite(_suite_path(name))
    if suite.name != name:
        raise ValueError(f"suite file {name}{_SUFFIX} names itself {suite.name!r}")
    return suite


@functools.cache
def suite_seeds(name: str) -> frozenset[int]:
    """The reset seeds of shipped suite ``name``, read without building its scenarios."""
    data = _read_json(_suite_path(name))
    return frozenset(int(m["seed"]) for m in data["missions"])


def seeds_in_suites(seeds: Iterable[int]) -> dict[str, list[int]]:
    """Which of ``seeds`` are reset seeds of a shipped suite: ``{suite name: [seeds]}`` (empty
    when none is). Training and imitation refuse such seeds: suites are evaluation-only."""
    wanted = set(seeds) if not isinstance(seeds, range) else None
    found: dict[str, list[int]] = {}
    for name in list_suites():
        own = suite_seeds(name)
        if wanted is None:  # a range: test membership without listing it
            hits = sorted(s for s in own if s in seeds)
        else:
            hits = sorted(own & wanted)
        if hits:
            found[name] = hits
    return found


EVALUATION_ONLY = "suites are evaluation-only (never for training or model selection)"
"""What a refusal to train on a suite says."""


def refuse_suite_seeds(seeds: range, what: str) -> None:
    """Refuse reset seeds ``seeds`` for ``what`` (a training or model-selection use) when any
    is a shipped suite's: training on a suite's fields would leak them into its evaluation.

    Raises:
        ValueError: naming ``what``, the seed range, the suite(s) and the seeds they share.
    """
    hits = seeds_in_suites(seeds)
    if hits:
        shared = "; ".join(
            f"{name}: {', '.join(map(str, found[:3]))}{'…' if len(found) > 3 else ''}"
            for name, found in hits.items()
        )
        raise ValueError(
            f"{what} would use reset seeds {seeds.start}…{seeds.stop - 1}, which include the "
            f"missions of evaluation suite(s) ({shared}); {EVALUATION_ONLY}. Choose seeds "
            f"outside {RESERVED_SEEDS.start}…{RESERVED_SEEDS.stop - 1}"
        )


def write_suite(suite: Suite, path: str | os.PathLike[str]) -> None:
    """Write ``suite`` in the file format above (gzip with no timestamp: the same suite gives
    the same bytes), atomically."""
    from debris_gym.files import write_atomic

    text = json.dumps(suite.to_dict(), separators=(",", ":"))
    write_atomic(path, gzip.compress(text.encode(), compresslevel=9, mtime=0))
