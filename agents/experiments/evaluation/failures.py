"""What stops an evaluation before its end other than Ctrl-C: an agent that fails mid-run
(:class:`AgentFailure`) and an output that cannot be written (:class:`OutputWriteError`).

Both name what happened and where (agent, episode, step; file), so the command line can say so
in one message and print the command that resumes the run once the cause is fixed.
"""

from __future__ import annotations

import os
import traceback

__all__ = ["AgentFailure", "OutputWriteError", "code_location", "describe"]


_HERE = os.path.dirname(os.path.abspath(__file__))


def code_location(exc: BaseException) -> str:
    """Where ``exc`` was raised: ``"file.py, line 12, in predict"`` (the innermost frame), or
    ``""`` without a traceback or when that frame is the evaluation's own call (a builtin that
    raised has no frame of its own)."""
    frames = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ else []
    frames = [f for f in frames if not f.filename.startswith("<frozen")]  # importlib's own
    if not frames or os.path.dirname(os.path.abspath(frames[-1].filename)) == _HERE:
        return ""
    frame = frames[-1]
    return f"{os.path.basename(frame.filename)}, line {frame.lineno}, in {frame.name}"


def describe(exc: BaseException) -> str:
    """``"ZeroDivisionError: division by zero (policy.py, line 3, in predict)"``."""
    text = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    where = code_location(exc)
    return f"{text} ({where})" if where else text


class AgentFailure(Exception):
    """An agent failed: its ``predict`` raised (``SystemExit`` included), returned something
    other than ``(action, state)``, or gave an action the env refused; or it could not be built
    in a worker.

    Attributes:
        agent: the agent's label.
        episode: the episode it was flying (None: while it was built).
        seed: that episode's reset seed (None: while it was built).
        step: steps of the episode already flown when it failed (None: unknown, or while it
            was built).
        reason: what went wrong, with the exception and where it was raised.
    """

    def __init__(
        self,
        agent: str,
        episode: int | None,
        seed: int | None,
        step: int | None,
        reason: str,
    ) -> None:
        self.agent = agent
        self.episode = episode
        self.seed = seed
        self.step = step
        self.reason = reason
        super().__init__(self.message())

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:  # pickled from worker processes
        return (type(self), (self.agent, self.episode, self.seed, self.step, self.reason))

    def message(self) -> str:
        """One line: the agent, the episode and step, and what went wrong."""
        if self.episode is None:
            return f"agent {self.agent!r} could not be built: {self.reason}"
        at = "" if self.step is None else f" at step {self.step}"
        return (
            f"agent {self.agent!r} failed in episode {self.episode} (reset seed {self.seed})"
            f"{at}: {self.reason}"
        )


class OutputWriteError(Exception):
    """A file of the run (the journal, an output) could not be written: a full disk, a directory
    made read-only, ... The files already there stay consistent.

    Attributes:
        path: the file (or directory) being written.
        error: the operating system's error.
    """

    def __init__(self, path: os.PathLike[str] | str, error: OSError) -> None:
        self.path = os.fspath(path)
        self.error = error
        super().__init__(self.message())

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return (type(self), (self.path, self.error))

    def message(self) -> str:
        """One line: the file and the operating system's reason."""
        reason = self.error.strerror or str(self.error)
        return f"cannot write {self.path} ({reason})"
