"""The journal of an unfinished evaluation: its resolved options and every episode finished so
far, kept in ``DIR/unfinished/`` so that Ctrl-C loses at most the episode in flight and
``evaluate.py --resume DIR`` can finish the run.

* ``options.json`` — the run's resolved options (env, agents, episodes, seed, …), written
  atomically when the run starts;
* ``episodes.jsonl`` — one JSON line per finished episode (its :class:`EpisodeRecord` with the
  trajectory and the field), appended and flushed to disk as the episode ends. A line is one
  ``write`` of a whole record, so a killed process leaves at most a last line cut short, which
  :meth:`EvaluationJournal.read` drops.

The journal is removed once the run's output set is committed. Floats are written with
``repr`` precision, so a record read back is the record that was written, bit for bit.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.evaluation.records import (
    RECORD_FIELDS,
    SHIELD_COLUMNS,
    EpisodeRecord,
    Trajectory,
)
from agents.experiments.run_directory import deferred_interrupts
from debris_gym.files import write_atomic
from debris_gym.scenario import Scenario

__all__ = [
    "JOURNAL_DIR",
    "EvaluationJournal",
    "JournalError",
    "record_from_json",
    "record_to_json",
]

JOURNAL_DIR = "unfinished"
"""Folder of an output directory that holds an unfinished evaluation's journal."""

FORMAT = 1
"""Version of the journal's layout, stored in ``options.json``."""


class JournalError(ValueError):
    """A journal file is missing or damaged; the message names the file (and line)."""


def record_to_json(record: EpisodeRecord) -> dict[str, Any]:
    """A plain-JSON form of ``record``: its CSV fields, trajectory and field."""
    data: dict[str, Any] = {name: getattr(record, name) for name in RECORD_FIELDS}
    traj = record.trajectory
    if traj is not None:
        data["trajectory"] = {
            "positions": traj.positions.tolist(),
            "velocities": traj.velocities.tolist(),
            "accelerations": traj.accelerations.tolist(),
            "decision_ms": traj.decision_ms.tolist(),
            "dt": traj.dt,
            "collision_point": (
                None if traj.collision_point is None else traj.collision_point.tolist()
            ),
            "thrust_model": traj.thrust_model,
        }
    if record.scenario is not None:
        data["scenario"] = record.scenario.to_dict()
    return data


def record_from_json(data: dict[str, Any]) -> EpisodeRecord:
    """The :class:`EpisodeRecord` that :func:`record_to_json` wrote.

    Raises:
        KeyError, TypeError, ValueError: ``data`` is not such a record.
    """
    defaults: dict[str, Any] = {name: 0 for name in SHIELD_COLUMNS}  # before the shield
    # before its own column, a spent budget was the outcome alone
    defaults["budget_spent"] = data.get("outcome") == "delta_v_budget"
    values: dict[str, Any] = {
        name: data[name] if name in data else defaults[name] for name in RECORD_FIELDS
    }
    trajectory = None
    if data.get("trajectory") is not None:
        t = data["trajectory"]
        positions = np.asarray(t["positions"], dtype=float)
        d = positions.shape[1]
        trajectory = Trajectory(
            positions=positions,
            velocities=np.asarray(t["velocities"], dtype=float).reshape(-1, d),
            accelerations=np.asarray(t["accelerations"], dtype=float).reshape(-1, d),
            decision_ms=np.asarray(t["decision_ms"], dtype=float),
            dt=float(t["dt"]),
            collision_point=(
                None if t["collision_point"] is None else np.asarray(t["collision_point"], float)
            ),
            thrust_model=str(t["thrust_model"]),
        )
    scenario = Scenario.from_dict(data["scenario"]) if data.get("scenario") else None
    return EpisodeRecord(**values, trajectory=trajectory, scenario=scenario)


class EvaluationJournal:
    """The journal of the evaluation writing into ``out`` (see the module docstring).

    Callers hold the directory's :class:`~agents.experiments.run_directory.RunDirectoryLock`
    while they write.
    """

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.dir = Path(out) / JOURNAL_DIR
        self.options_path = self.dir / "options.json"
        self.episodes_path = self.dir / "episodes.jsonl"
        self.count = 0
        """Records in the journal: set by :meth:`start` and :meth:`read_records`, counted by
        :meth:`append` together with the write (a Ctrl-C never falls between the two)."""

    def exists(self) -> bool:
        """Whether ``out`` holds an unfinished evaluation."""
        return self.options_path.is_file()

    def start(self, options: dict[str, Any]) -> None:
        """Begin a new journal with the run's resolved ``options`` (a JSON mapping), replacing
        any earlier one."""
        self.remove()
        self.dir.mkdir(parents=True)
        self.episodes_path.touch()
        self.count = 0
        write_atomic(self.options_path, json.dumps({"format": FORMAT, **options}, indent=1) + "\n")

    def append(self, record: EpisodeRecord) -> None:
        """Add a finished episode: one line, written whole and flushed to disk."""
        self._append_line(record_to_json(record))

    def _append_line(self, data: dict[str, Any]) -> None:
        """Append ``data`` as one JSON line, written whole and flushed to disk."""
        line = (json.dumps(data, separators=(",", ":")) + "\n").encode()
        with deferred_interrupts():
            with open(self.episodes_path, "ab") as fh:
                fh.write(line)
                fh.flush()
                os.fsync(fh.fileno())
            self.count += 1

    def drop_partial_line(self) -> None:
        """Cut a last line left unfinished by a killed process, so appends start on a line of
        their own."""
        path = self.episodes_path
        if not path.is_file():
            return
        data = path.read_bytes()
        end = data.rfind(b"\n") + 1
        if end != len(data):
            with open(path, "rb+") as fh:
                fh.truncate(end)

    def read_options(self) -> dict[str, Any]:
        """The resolved options the run started with (``format`` removed).

        Raises:
            JournalError: no journal, or ``options.json`` is not a journal's options.
        """
        path = self.options_path
        if not path.is_file():
            raise JournalError(
                f"{self.dir.parent} holds no unfinished evaluation ({path} not found): "
                "nothing to resume"
            )
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise JournalError(f"{path}: not readable JSON ({exc})") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise JournalError(f"{path}: not the options of an evaluate.py run (format {FORMAT})")
        data.pop("format")
        return data

    def read_records(self) -> list[EpisodeRecord]:
        """The finished episodes, in the order they finished. A last line cut short (the
        process was killed while writing it) is dropped: that episode runs again.

        Raises:
            JournalError: a damaged line before the last one, or a line that is not a record.
        """
        records = []
        for number, data in self._read_lines():
            try:
                records.append(record_from_json(data))
            except (KeyError, TypeError, ValueError, IndexError) as exc:
                raise JournalError(
                    f"{self.episodes_path}, line {number}: not an episode record "
                    f"({type(exc).__name__}: {exc}); delete the line to run that episode again"
                ) from None
        return records

    def _read_lines(self) -> list[tuple[int, Any]]:
        """Every whole line of ``episodes.jsonl`` as ``(line number, parsed JSON)``; sets
        :attr:`count`. A last line cut short by a kill is dropped.

        Raises:
            JournalError: the file is unreadable, or a whole line is not JSON.
        """
        path = self.episodes_path
        if not path.is_file():
            self.count = 0
            return []
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise JournalError(f"{path}: not readable ({exc})") from None
        complete = text.split("\n")[:-1]  # a whole line ends with a newline
        lines = []
        for number, line in enumerate(complete, start=1):
            try:
                lines.append((number, json.loads(line)))
            except json.JSONDecodeError as exc:
                raise JournalError(
                    f"{path}, line {number}: not JSON ({exc}); delete the line to run that "
                    "episode again"
                ) from None
        self.count = len(lines)
        return lines

    def remove(self) -> None:
        """Delete the journal (after the run's outputs are committed)."""
        shutil.rmtree(self.dir, ignore_errors=True)
