"""Where a mission shell's fields come from: random draws from per-row generators, the paper
world, drawn ahead on a worker thread while the missions fly.

A row's random fields are a function of its generator alone: a moving (v1) field of one 64-bit
word of it (:class:`~debris_gym.orbit_fields.OrbitDrawer`), a frozen (v0) field of a fixed
block of its uniform numbers (:func:`~debris_gym.generators.random_fields`). So the field of a
row's k-th episode does not depend on when it is drawn, nor on which other rows draw with it.

That is what lets :class:`FieldSupply` draw moving fields ahead: when a row takes a field, the
supply takes the row's next word at once (the *pending* word, already out of the generator) and
hands its field to a worker thread, which draws it while the missions fly (the compiled draw
releases the GIL). The row's next reset finds the field ready and pays only for copying it into
the batch. The pending word is part of the row's random state: a reset that fails puts it back
with the generator's state, and a reset that changes the mission draws the new mission's field
from the same word — so the fields are those a draw at reset time gives, the same for the same
seed with or without drawing ahead (tested).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import field_spec
from debris_gym.generators import FieldArrays, FieldSpec, paper_field, random_fields
from debris_gym.orbit_fields import OrbitDrawer, orbit_drawer
from debris_gym.scenario import Scenario

__all__ = ["FieldSupply", "SupplyState"]


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
        # fields drawn ahead: row i's is valid while _ready[i], it was drawn from the word
        # _ready_words[i] that the row takes next, with the drawer now in force
        # (_ready_drawer); the worker writes them
        self._ready = np.zeros(num, dtype=bool)
        self._ready_words = np.zeros(num, dtype=np.uint64)
        self._ready_drawer: OrbitDrawer | None = None
        self._store: FieldArrays | None = None
        self._executor: ThreadPoolExecutor | None = None
        self._jobs: list[Future] = []
        self._lock = threading.Lock()
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
        words = self._next_words(rows)
        self.taken_words[rows] = words
        if self._ahead and self._ready_drawer is drawer:
            self.wait()
            ready = self._ready[rows] & (self._ready_words[rows] == words)
            self._ready[rows] = False
            if ready.all() and self._store is not None:
                return _select(self._store, rows)
        return drawer.from_words(words)

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
        _assign(copy, np.asarray(positions, dtype=np.int64), drawn)
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
            self._ready_drawer = drawer
        words = self._next_words(rows).copy()
        self._pending[rows] = True
        if self._executor is None:
            self._executor = ThreadPoolExecutor(1, thread_name_prefix="debris-gym-fields")
        rows = rows.copy()
        self._jobs.append(self._executor.submit(self._draw_into_store, drawer, rows, words))

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

    def _draw_into_store(self, drawer: OrbitDrawer, rows: np.ndarray, words: np.ndarray) -> None:
        """The worker's job: draw the fields of ``words`` and keep them for ``rows``."""
        fields = drawer.from_words(words)  # the compiled draw releases the GIL
        with self._lock:
            store = self._store
            if store is None or not _fits(store, fields, self.num):
                store = self._store = _empty_store(fields, self.num)
            _assign(store, rows, fields)
            self._ready_words[rows] = words
            self._ready[rows] = True

    def wait(self) -> None:
        """Wait for the worker; fields drawn ahead that failed are dropped (their rows draw
        again when taken, and raise then)."""
        jobs, self._jobs = self._jobs, []
        for job in jobs:
            try:
                job.result()
            except ValueError:
                pass

    def close(self) -> None:
        """Stop the worker thread."""
        self.wait()
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None

    def __getstate__(self) -> dict:
        # threads do not pickle: a copy draws its fields when taken, the same fields
        self.wait()
        state = self.__dict__.copy()
        state.update(_executor=None, _jobs=[], _lock=None, _store=None, _ready_drawer=None)
        state["_ready"] = np.zeros(self.num, dtype=bool)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()


def _moving(array: np.ndarray | None) -> np.ndarray:
    """A moving field's velocities or spins (the supply draws ahead only moving fields)."""
    if array is None:
        raise RuntimeError("a field drawn ahead has no velocities or spins")
    return array


def _select(store: FieldArrays, rows: np.ndarray) -> FieldArrays:
    """The rows ``rows`` of a store of fields, as fields of their own."""
    return FieldArrays(
        store.dim, store.half_size, store.n_targets, store.centers[rows], store.radii[rows],
        store.vertices[rows], store.n_vertices[rows], velocities=_moving(store.velocities)[rows],
        spins=_moving(store.spins)[rows],
    )  # fmt: skip


def _fits(store: FieldArrays, fields: FieldArrays, num: int) -> bool:
    return (
        store.centers.shape[1:] == fields.centers.shape[1:]
        and store.vertices.shape[1:] == fields.vertices.shape[1:]
        and store.n_targets == fields.n_targets
        and math.isclose(store.half_size, fields.half_size)
        and len(store) == num
    )


def _empty_store(fields: FieldArrays, num: int) -> FieldArrays:
    def rows_of(array: np.ndarray) -> np.ndarray:
        return np.zeros((num, *array.shape[1:]), dtype=array.dtype)

    return FieldArrays(
        fields.dim, fields.half_size, fields.n_targets, rows_of(fields.centers),
        rows_of(fields.radii), rows_of(fields.vertices), rows_of(fields.n_vertices),
        velocities=rows_of(_moving(fields.velocities)), spins=rows_of(_moving(fields.spins)),
    )  # fmt: skip


def _assign(store: FieldArrays, rows: np.ndarray, fields: FieldArrays) -> None:
    store.centers[rows] = fields.centers
    store.radii[rows] = fields.radii
    store.vertices[rows] = fields.vertices
    store.n_vertices[rows] = fields.n_vertices
    _moving(store.velocities)[rows] = _moving(fields.velocities)
    _moving(store.spins)[rows] = _moving(fields.spins)
