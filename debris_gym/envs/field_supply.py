"""Where a mission shell's fields come from: random draws from per-row generators, the paper
world, drawn ahead on a worker thread while the missions fly.

A row's random fields are a function of its generator alone: a moving (v1) field of one 64-bit
word of it (:class:`~debris_gym.orbit_fields.OrbitDrawer`), a frozen (v0) field of a fixed
block of its uniform numbers (:func:`~debris_gym.generators.random_fields`). So the field of a
row's k-th episode does not depend on when it is drawn, nor on which other rows draw with it.

That is what lets :class:`FieldSupply` draw moving fields ahead: the rows that took a field are
gathered over a few steps (:data:`GATHER_CALLS`) and handed to a worker thread in one job, which
takes each row's next word (the *pending* word, then out of the generator) and draws its field
while the missions fly, straight into the row's slot of a store of drawn fields (one call of
compiled code that releases the GIL: the worker holds Python's lock only to enter and leave it,
and each wake-up of the worker makes the missions' thread wait for that lock once, hence the
gathering). The row's next reset finds the field ready and pays only for copying it into the
batch; a row that restarts before its field was handed over draws it then, from the same word.
The pending word is part of the row's random state: a reset that fails puts it back
with the generator's state, and a reset that changes the mission draws the new mission's field
from the same word — so the fields are those a draw at reset time gives, the same for the same
seed with or without drawing ahead (tested).
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import field_spec
from debris_gym.generators import FieldArrays, FieldSpec, paper_field, random_fields
from debris_gym.orbit_fields import DrawnOrbits, OrbitDrawer, orbit_drawer
from debris_gym.scenario import Scenario

__all__ = ["FieldSupply", "SupplyState"]

GATHER_CALLS = 4
"""Calls of :meth:`FieldSupply.draw_ahead` whose rows are gathered into one job before the
worker is woken: each wake-up makes the missions' thread wait once for Python's lock."""

GATHER_ROWS = 128
"""Rows that wake the worker at once, however few calls gathered them."""


@dataclass(frozen=True)
class SupplyState:
    """What a failed reset puts back: the rows' generators and their states, and the pending
    words (see :class:`FieldSupply`)."""

    generators: tuple[np.random.Generator, ...]
    states: tuple[Mapping[str, Any], ...]
    pending: np.ndarray
    words: np.ndarray
    taken: np.ndarray
    config: EnvConfig
    spec: FieldSpec
    drawer: OrbitDrawer | None


class FieldSupply:
    """The fields of ``num`` rows: random ones drawn from each row's generator, or the paper
    world (``scenario="paper"``).

    Args:
        config: the env configuration in force (what the random fields look like).
        num: number of rows.
        ahead: draw each row's next moving field on a worker thread as soon as the row has
            taken one (see the module docstring). Off, every field is drawn when taken.

    Raises:
        ValueError: a random-field config whose fields can never be placed
            (:func:`~debris_gym.envs.common.field_spec`).
    """

    def __init__(self, config: EnvConfig, num: int, *, ahead: bool = False) -> None:
        self.num = num
        self.generators: list[np.random.Generator] = [np.random.default_rng() for _ in range(num)]
        self._pending = np.zeros(num, dtype=bool)  # the row's next word is out of its generator
        self._words = np.zeros(num, dtype=np.uint64)
        self.taken_words = np.zeros(num, dtype=np.uint64)
        """(num,) uint64: the word of each row's last moving random field (see
        :meth:`take`)."""
        self._ahead = ahead
        # fields drawn ahead: row i's was handed to the worker while _ready[i], drawn from the
        # word _ready_words[i] that the row takes next, with the drawer now in force
        # (_ready_drawer), into row i of _store (valid once the worker is done, if
        # _store.placed[i])
        self._ready = np.zeros(num, dtype=bool)
        self._ready_words = np.zeros(num, dtype=np.uint64)
        self._ready_drawer: OrbitDrawer | None = None
        self._store: DrawnOrbits | None = None
        self._worker: _Worker | None = None
        self._gathered: list[np.ndarray] = []  # rows to draw ahead, not yet handed over
        self._in_flight = np.zeros(num, dtype=bool)  # rows of jobs not yet waited for
        self._gathered_calls = 0
        self._paper: Scenario | None = None
        self.configure(config)

    # --- configuration ------------------------------------------------------------------------

    def configure(self, config: EnvConfig) -> None:
        """Draw the fields of ``config`` from now on (a mission option: the pending words stay,
        their fields are drawn anew).

        Raises:
            ValueError: the fields of ``config`` can never be placed; nothing changed.
        """
        spec = field_spec(config)
        self.wait()
        self.config, self.spec = config, spec
        self._drawer: OrbitDrawer | None = None

    @property
    def moving(self) -> bool:
        """The random fields move (v1): their draws can go ahead."""
        return self.spec.motion != "frozen"

    @property
    def paper(self) -> bool:
        """Every field is the paper world."""
        return self.config.scenario == "paper"

    def paper_field(self) -> Scenario:
        """The [APF-MPC] world of the config's ``dt`` and ``max_accel`` (built once)."""
        if self._paper is None or (self._paper.dt, self._paper.max_accel) != (
            self.config.dt,
            self.config.max_accel,
        ):
            self._paper = paper_field(dt=self.config.dt, max_accel=self.config.max_accel)
        return self._paper

    def drawer(self) -> OrbitDrawer:
        """The moving-field drawer of the config in force (its spec checked on first use).

        Raises:
            ValueError: the spec breaks the moving fields' conditions (naming them).
        """
        drawer = self._drawer
        if drawer is None:
            drawer = self._drawer = orbit_drawer(self.spec, self.config.capture_radius)
        return drawer

    # --- random state -------------------------------------------------------------------------

    def save(self) -> SupplyState:
        """Everything a draw may change, for :meth:`restore` (waits for the worker)."""
        self.wait()
        return SupplyState(
            generators=tuple(self.generators),
            states=tuple(g.bit_generator.state for g in self.generators),
            pending=self._pending.copy(),
            words=self._words.copy(),
            taken=self.taken_words.copy(),
            config=self.config,
            spec=self.spec,
            drawer=self._drawer,
        )

    def restore(self, saved: SupplyState) -> None:
        """Put back what :meth:`save` saved (the same generator objects, in their states)."""
        self.wait()
        self.generators = list(saved.generators)
        for generator, state in zip(saved.generators, saved.states):
            generator.bit_generator.state = dict(state)
        self._pending[:] = saved.pending
        self._words[:] = saved.words
        self.taken_words[:] = saved.taken
        self.config, self.spec, self._drawer = saved.config, saved.spec, saved.drawer

    def set_generators(self, rows: np.ndarray, generators: Sequence[np.random.Generator]) -> None:
        """Give the rows ``rows`` new generators (a seeded reset): their pending words go."""
        self.wait()
        for i, generator in zip(rows.tolist(), generators):
            if generator is not self.generators[i]:
                self.generators[i] = generator
                self._pending[i] = False

    # --- drawing ------------------------------------------------------------------------------

    def take(self, rows: np.ndarray) -> FieldArrays | None:
        """The next field of each row in ``rows`` (None: the paper world, see
        :meth:`paper_field`). Changes nothing but the generators and the pending words.

        Raises:
            ValueError: some field could not be placed (the generators have moved on).
        """
        if self.paper:
            return None
        if not self.moving:
            chosen = [self.generators[i] for i in rows.tolist()]
            return random_fields(chosen, self.spec, capture_radius=self.config.capture_radius)
        drawer = self.drawer()
        self.wait()  # the worker takes words too
        words = self._next_words(rows)
        self.taken_words[rows] = words
        if self._taken_ready(rows, words):
            assert self._store is not None
            return _drawn_fields(self._store, drawer, rows)
        return drawer.from_words(words)

    def take_drawn(self, rows: np.ndarray) -> FieldArrays | None:
        """The next fields of the rows ``rows`` as :meth:`take` gives them, but as the whole
        store of fields drawn ahead (row i of it is row i's field: load the rows ``rows`` of
        it), or None when that cannot be (then nothing changed but the store: call
        :meth:`take`). A row whose field is not drawn yet (its draw still gathered, see
        :data:`GATHER_CALLS`) is drawn into the store here. Spares the copy of the rows out of
        the store."""
        if not self._ahead or self.paper or not self.moving or self._store is None:
            return None
        drawer = self.drawer()
        if self._ready_drawer is not drawer:
            return None
        # wait for the worker only when it holds some of these rows, or a row must be drawn
        # here (the worker and this thread share the drawer's working arrays)
        if self._in_flight[rows].any():
            self.wait()
        store = self._store
        ready = self._ready[rows] & self._pending[rows]
        ready &= self._ready_words[rows] == self._words[rows]
        if not ready.all():  # draw them now, from the words a draw at take time uses
            self.wait()
            missing = rows[~ready]
            words = self._next_words(missing)  # now in _words, no longer pending
            self._pending[missing] = True
            self._ready_words[missing] = words
            self._ready[missing] = True
            drawer.draw_rows(words, missing, store)
        if not store.placed[rows].all():
            return None
        self.taken_words[rows] = self._words[rows]
        self._pending[rows] = False
        self._ready[rows] = False
        return _drawn_fields(store, drawer, None)

    def _taken_ready(self, rows: np.ndarray, words: np.ndarray) -> bool:
        """Were the fields of ``words`` drawn ahead for ``rows`` (waits for the worker)? Their
        rows of the store are given away either way."""
        if not (self._ahead and self._ready_drawer is self.drawer()):
            return False
        self.wait()
        ready = self._ready[rows] & (self._ready_words[rows] == words)
        self._ready[rows] = False
        store = self._store
        return bool(ready.all()) and store is not None and bool(store.placed[rows].all())

    def with_words(
        self, fields: FieldArrays, positions: np.ndarray, words: np.ndarray
    ) -> FieldArrays:
        """``fields`` (what :meth:`take` gave for some rows) with the fields at ``positions``
        replaced by those of the moving-field ``words`` (a copy; ``fields`` is unchanged).

        Raises:
            ValueError: the fields are not moving random ones (only those have words), or a
                word's field cannot be placed in this mission.
        """
        if self.paper or not self.moving:
            raise ValueError(
                "a field_word names a moving random field; this env's fields are "
                f"{'the paper world' if self.paper else 'frozen (v0)'}"
            )
        drawn = self.drawer().from_words(np.asarray(words, dtype=np.uint64))
        copy = FieldArrays(
            fields.dim, fields.half_size, fields.n_targets, fields.centers.copy(),
            fields.radii.copy(), fields.vertices.copy(), fields.n_vertices.copy(),
            velocities=_moving(fields.velocities).copy(), spins=_moving(fields.spins).copy(),
        )  # fmt: skip
        at = np.asarray(positions, dtype=np.int64)
        copy.centers[at], copy.radii[at] = drawn.centers, drawn.radii
        copy.vertices[at], copy.n_vertices[at] = drawn.vertices, drawn.n_vertices
        _moving(copy.velocities)[at] = _moving(drawn.velocities)
        _moving(copy.spins)[at] = _moving(drawn.spins)
        return copy

    def draw_ahead(self, rows: np.ndarray) -> None:
        """Start drawing the next field of each row in ``rows`` on the worker thread (moving
        random fields with ``ahead`` only; otherwise nothing)."""
        if not (self._ahead and self.moving) or self.paper or len(rows) == 0:
            return
        drawer = self.drawer()
        if self._ready_drawer is not drawer:  # a new mission: what was drawn ahead is stale
            self.wait()
            self._ready[:] = False
            self._gathered, self._gathered_calls = [], 0
            self._ready_drawer = drawer
            self._store = drawer.empty(self.num)
        self._gathered.append(np.array(rows, dtype=np.int64))
        self._gathered_calls += 1
        if (
            self._gathered_calls < GATHER_CALLS
            and sum(len(r) for r in self._gathered) < GATHER_ROWS
        ):
            return
        rows = np.unique(np.concatenate(self._gathered))
        self._gathered, self._gathered_calls = [], 0
        self._ready[rows] = True
        self._in_flight[rows] = True
        if self._worker is None:
            self._worker = _Worker()
        self._worker.submit(self._draw_next, drawer, rows)

    def _draw_next(self, drawer: OrbitDrawer, rows: np.ndarray) -> None:
        """The worker's job: take the rows' next words (they become pending) and draw their
        fields into the store. Until :meth:`wait` returns, only the worker touches the rows'
        generators, words and store rows."""
        words = self._next_words(rows)
        self._pending[rows] = True
        self._ready_words[rows] = words
        assert self._store is not None
        drawer.draw_rows(words, rows, self._store)

    def _next_words(self, rows: np.ndarray) -> np.ndarray:
        """The rows' pending words, taken from their generators where there is none; after
        this the rows have none pending (the words are being used)."""
        pending = self._pending[rows]
        if not pending.all():
            for i in rows[~pending].tolist():
                self._words[i] = self.generators[i].bit_generator.random_raw()
        words = self._words[rows]
        self._pending[rows] = False
        return words

    def wait(self) -> None:
        """Wait for the worker (fields drawn ahead that found no valid try are not ``placed``:
        their rows draw again when taken, and raise then)."""
        if self._worker is not None:
            self._in_flight[:] = False  # done or failed: either way not in the worker's hands
            self._worker.wait()

    def close(self) -> None:
        """Stop the worker thread."""
        if self._worker is not None:
            self._worker.close()
            self._worker = None

    def __getstate__(self) -> dict:
        # threads do not pickle: a copy draws its fields when taken, the same fields
        self.wait()
        state = self.__dict__.copy()
        state.update(_worker=None, _store=None, _ready_drawer=None, _gathered=[], _gathered_calls=0)
        state["_ready"] = np.zeros(self.num, dtype=bool)
        state["_in_flight"] = np.zeros(self.num, dtype=bool)
        return state


def _moving(array: np.ndarray | None) -> np.ndarray:
    """A moving field's velocities or spins (only moving fields have field words)."""
    if array is None:
        raise RuntimeError("a moving field has no velocities or spins")
    return array


def _drawn_fields(store: DrawnOrbits, drawer: OrbitDrawer, rows: np.ndarray | None) -> FieldArrays:
    """The rows ``rows`` of a store of fields drawn ahead as fields of their own (copies), or
    with ``rows`` None the whole store (its own arrays)."""

    def pick(array: np.ndarray) -> np.ndarray:
        return array if rows is None else array[rows]

    rules = drawer.rules
    return FieldArrays(
        rules.dim, rules.half_size, rules.n_targets, pick(store.centers), pick(store.radii),
        pick(store.vertices), pick(store.n_vertices), velocities=pick(store.velocities),
        spins=pick(store.spins),
    )  # fmt: skip


class _Worker:
    """One thread that runs the jobs handed to it in order (the supply's drawing ahead): a
    job is a queue entry, not a future, so that handing one over costs a few microseconds."""

    def __init__(self) -> None:
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._done: queue.SimpleQueue = queue.SimpleQueue()
        self._running = 0  # jobs handed over and not yet waited for
        self._thread = threading.Thread(target=self._run, name="debris-gym-fields", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None:
                return
            function, args = job
            try:
                function(*args)
            except BaseException as error:  # handed to the waiting thread
                self._done.put(error)
            else:
                self._done.put(None)

    def submit(self, function: Any, *args: Any) -> None:
        """Run ``function(*args)`` on the thread after the jobs before it."""
        self._jobs.put((function, args))
        self._running += 1

    def wait(self) -> None:
        """Wait for every job handed over; raise the first error one of them raised."""
        first = None
        while self._running:
            error = self._done.get()
            self._running -= 1
            if first is None:
                first = error
        if first is not None:
            raise first

    def close(self) -> None:
        """Wait for the jobs, then stop the thread."""
        try:
            self.wait()
        finally:
            self._jobs.put(None)
            self._thread.join()
