"""The journal of an unfinished swarm evaluation, so that ``evaluate.py --resume DIR`` finishes a
run that Ctrl-C, a failing team or the end of a working day stopped: a 48-chaser episode takes
half an hour, and a run of ten should not have to be flown in one sitting.

It lives in ``DIR/unfinished/`` like the single-agent journal
(:mod:`agents.experiments.evaluation.journal`, whose mechanics it shares):

* ``options.json`` — the run's resolved options, marked ``"kind": "swarm"``;
* ``episodes.jsonl`` — one line per finished episode of a team: its :class:`TeamEpisode`, every
  rule's assignment on its field (``assignments.csv``) and, for a drawn episode, the name of its
  trajectory plot;
* ``plots/`` — the trajectory plots (PNG) of the finished episodes, written before their line.

Floats are written with ``repr`` precision, so a record read back equals the one written.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from agents.experiments.evaluation.journal import JOURNAL_DIR, EvaluationJournal, JournalError
from agents.experiments.swarm_evaluation.episode import TeamEpisode
from agents.planners.team_assignment import TeamAssignment
from agents.policies.shielded import ShieldStats
from debris_gym.files import write_atomic

__all__ = ["FinishedEpisode", "SwarmJournal", "is_swarm_journal"]

KIND = "swarm"
"""``options.json``'s ``kind`` in a swarm evaluation's journal."""


class FinishedEpisode(NamedTuple):
    """One team's finished episode as the journal keeps it.

    Attributes:
        record: the episode's measurements.
        rules: every assignment rule's choice on its field.
        plot: the file name of its trajectory plot (in the journal's ``plots/``), or None.
    """

    record: TeamEpisode
    rules: dict[str, TeamAssignment]
    plot: str | None = None


def is_swarm_journal(out: str | os.PathLike[str]) -> bool:
    """Whether ``out`` holds the journal of an unfinished swarm evaluation."""
    path = Path(out) / JOURNAL_DIR / "options.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(data, dict) and data.get("kind") == KIND


def _assignment_to_json(a: TeamAssignment) -> dict[str, Any]:
    return {
        "rule": a.rule,
        "table": a.table.astype(int).tolist(),
        "cost": a.cost,
        "tours": a.tours.tolist(),
    }


def _assignment_from_json(data: dict[str, Any]) -> TeamAssignment:
    table = np.asarray(data["table"], dtype=bool)
    return TeamAssignment(
        rule=str(data["rule"]),
        table=table.reshape(len(data["table"]), -1),
        cost=float(data["cost"]),
        tours=np.asarray(data["tours"], dtype=float),
    )


def _tuples(value: Any) -> Any:
    """JSON lists back to the tuples the record held."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def episode_to_json(finished: FinishedEpisode) -> dict[str, Any]:
    """A plain-JSON form of ``finished``."""
    record = finished.record
    data = {f.name: getattr(record, f.name) for f in dataclasses.fields(record)}
    data["shield"] = [dataclasses.asdict(s) for s in record.shield]
    return {
        "record": data,
        "rules": {rule: _assignment_to_json(a) for rule, a in finished.rules.items()},
        "plot": finished.plot,
    }


def episode_from_json(data: dict[str, Any]) -> FinishedEpisode:
    """The :class:`FinishedEpisode` that :func:`episode_to_json` wrote.

    Raises:
        KeyError, TypeError, ValueError: ``data`` is not such an episode.
    """
    values = dict(data["record"])
    names = {f.name for f in dataclasses.fields(TeamEpisode)}
    if set(values) != names:
        raise ValueError(f"fields {sorted(set(values) ^ names)} differ from a TeamEpisode's")
    shield = tuple(ShieldStats(**s) for s in values.pop("shield"))
    exploration = values.pop("exploration")
    if exploration is not None:
        exploration = {k: _tuples(v) for k, v in exploration.items()}
    values = {k: _tuples(v) for k, v in values.items()}
    record = TeamEpisode(**values, exploration=exploration, shield=shield)
    rules = {rule: _assignment_from_json(a) for rule, a in data["rules"].items()}
    plot = data.get("plot")
    return FinishedEpisode(record, rules, None if plot is None else str(plot))


class SwarmJournal(EvaluationJournal):
    """The journal of the swarm evaluation writing into ``out`` (see the module docstring).

    Callers hold the directory's :class:`~agents.experiments.run_directory.RunDirectoryLock`
    while they write.
    """

    def __init__(self, out: str | os.PathLike[str]) -> None:
        super().__init__(out)
        self.plots_dir = self.dir / "plots"

    def start(self, options: dict[str, Any]) -> None:
        """Begin a new journal with the run's resolved ``options`` (a JSON mapping)."""
        super().start({"kind": KIND, **options})
        self.plots_dir.mkdir()

    def read_options(self) -> dict[str, Any]:
        """The resolved options the run started with (``format`` and ``kind`` removed).

        Raises:
            JournalError: no journal, or not a swarm evaluation's.
        """
        data = super().read_options()
        if data.pop("kind", None) != KIND:
            raise JournalError(f"{self.options_path}: not the journal of a swarm evaluation")
        return data

    def append_episode(self, finished: FinishedEpisode, picture: bytes | None) -> None:
        """Add a finished episode (its plot ``picture``, PNG bytes, first): one line, written
        whole and flushed to disk."""
        if picture is not None:
            if finished.plot is None:
                raise ValueError("a plot needs its file name (FinishedEpisode.plot)")
            write_atomic(self.plots_dir / finished.plot, picture)
        self._append_line(episode_to_json(finished))

    def read_episodes(self) -> list[FinishedEpisode]:
        """The finished episodes in the order they finished (a last line cut short by a kill
        is dropped: that episode flies again).

        Raises:
            JournalError: a damaged line, or a plot it names is missing.
        """
        episodes = []
        for number, data in self._read_lines():
            try:
                finished = episode_from_json(data)
            except (KeyError, TypeError, ValueError, IndexError) as exc:
                raise JournalError(
                    f"{self.episodes_path}, line {number}: not a swarm episode "
                    f"({type(exc).__name__}: {exc}); delete the line to fly it again"
                ) from None
            if finished.plot is not None and not (self.plots_dir / finished.plot).is_file():
                raise JournalError(
                    f"{self.episodes_path}, line {number}: its plot {finished.plot} is missing "
                    f"from {self.plots_dir}; delete the line to fly the episode again"
                )
            episodes.append(finished)
        return episodes

    def plot(self, name: str) -> bytes:
        """The PNG bytes of a journaled plot."""
        return (self.plots_dir / name).read_bytes()
