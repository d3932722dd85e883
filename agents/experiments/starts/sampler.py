"""Which leg a training mission starts on: prioritised level replay [Jiang21] over the legs of a
mission, with starts from a bank of recorded states [Salimans18].

A *leg* is the flight that starts with k targets captured (k = 0: from the dock; k = T: the
return home). :class:`LegSampler` is a :class:`~debris_gym.envs.starts.StartSampler`: each
restarting mission starts as usual (at the dock) with probability ``usual``, otherwise from a
bank entry of a leg drawn by PLR's rank prioritisation of each leg's recent failure rate, mixed
with a staleness term that keeps every leg visited:

    P(l) = (1 − ρ) · h(rank_l)^(1/β) / Σ h^(1/β)  +  ρ · (c − C_l) / Σ (c − C),

h(rank) = 1 / rank (rank 1 the highest failure rate), β the temperature, ρ the staleness
weight, c the number of starts so far and C_l the start at which leg l was last drawn. The
failure rates are exponential moving averages, updated from every ended mission: a mission
that started on leg L and ended with c targets captured flew legs L … c − 1 and, unless it
succeeded, failed leg c.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from debris_gym.envs.starts import EpisodeEnds
from debris_gym.mission_starts import MissionStart
from debris_gym.start_bank import StartBank

__all__ = ["LegSampler", "SamplerParams"]


@dataclass(frozen=True)
class SamplerParams:
    """How a :class:`LegSampler` mixes its starts.

    Attributes:
        usual: share of missions that start as usual, at the dock (in [0, 1]).
        temperature: β of the rank prioritisation (> 0; small: the worst leg nearly always).
        staleness: ρ, weight of the staleness term (in [0, 1]).
        smoothing: rate of each leg's moving-average failure rate (in (0, 1]).
        seed: the sampler's own generator (the fields keep theirs).
    """

    usual: float = 0.5
    temperature: float = 0.3
    staleness: float = 0.1
    smoothing: float = 0.05
    seed: int = 0

    def __post_init__(self) -> None:
        for name, low, high, open_low in (
            ("usual", 0.0, 1.0, False), ("staleness", 0.0, 1.0, False),
            ("smoothing", 0.0, 1.0, True),
        ):  # fmt: skip
            value = getattr(self, name)
            if not (low < value <= high if open_low else low <= value <= high):
                bracket = "(" if open_low else "["
                raise ValueError(
                    f"{name}={value} is out of range; allowed: {bracket}{low}, {high}]"
                )
        if not self.temperature > 0.0:
            raise ValueError(f"temperature={self.temperature} must be > 0")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")


class LegSampler:
    """Starts for the missions of ``num`` rows, from ``bank`` (see the module docstring).

    Args:
        bank: the recorded starts (legs 1 … T).
        num: rows of the env it serves.
        n_targets: targets per mission T (legs 0 … T, T the return home).
        params: the mix (:class:`SamplerParams`).

    Raises:
        ValueError: an empty bank.
    """

    def __init__(
        self, bank: StartBank, num: int, n_targets: int, params: SamplerParams | None = None
    ) -> None:
        if len(bank) == 0:
            raise ValueError("the start bank is empty: its missions captured nothing")
        self.bank, self.params = bank, params or SamplerParams()
        self.n_legs = n_targets + 1
        legs = bank.legs
        self._entries = [np.flatnonzero(legs == leg) for leg in range(self.n_legs)]
        self.banked = np.array([len(e) > 0 for e in self._entries])
        """(T + 1,) bool: the legs the bank can start (leg 0 never: it is the usual start)."""
        self.banked[0] = False
        self.failure = np.full(self.n_legs, 0.5)
        """(T + 1,) moving-average failure rate of each leg."""
        self.flown = np.zeros(self.n_legs, dtype=np.int64)
        """(T + 1,) ended missions that flew (or failed) each leg."""
        self.started = np.zeros(self.n_legs, dtype=np.int64)
        """(T + 1,) missions started on each leg."""
        self._last_drawn = np.zeros(self.n_legs, dtype=np.int64)
        self._draws = 0
        self._row_leg = np.zeros(num, dtype=np.int64)
        self._rng = np.random.default_rng(self.params.seed)

    # --- the StartSampler protocol ------------------------------------------------------------

    def __call__(self, rows: np.ndarray, ended: EpisodeEnds | None) -> list[MissionStart | None]:
        if ended is not None:
            self.record(rows, ended)
        starts: list[MissionStart | None] = []
        for row in np.asarray(rows).tolist():
            start, leg = None, 0
            if self.banked.any() and self._rng.random() >= self.params.usual:
                leg = self._draw_leg()
                entries = self._entries[leg]
                start = self.bank.start(int(entries[self._rng.integers(len(entries))]))
            self._row_leg[row] = leg
            self.started[leg] += 1
            starts.append(start)
        return starts

    # --- bookkeeping --------------------------------------------------------------------------

    def record(self, rows: np.ndarray, ended: EpisodeEnds) -> None:
        """Update the legs' failure rates from the missions of ``rows`` that just ended."""
        rate = self.params.smoothing
        for row, captured, success in zip(
            np.asarray(rows).tolist(), ended.captured.tolist(), ended.success.tolist()
        ):
            first = int(self._row_leg[row])
            last = self.n_legs - 1 if success else min(int(captured), self.n_legs - 1)
            for leg in range(first, last + 1):
                failed = leg == last and not success
                self.failure[leg] += rate * (float(failed) - self.failure[leg])
                self.flown[leg] += 1

    def probabilities(self) -> np.ndarray:
        """(T + 1,) the chance that a bank start is on each leg (0 for legs the bank lacks)."""
        legs = np.flatnonzero(self.banked)
        out = np.zeros(self.n_legs)
        if len(legs) == 0:
            return out
        order = np.argsort(-self.failure[legs], kind="stable")
        ranks = np.empty(len(legs))
        ranks[order] = np.arange(1, len(legs) + 1)
        score = (1.0 / ranks) ** (1.0 / self.params.temperature)
        score /= score.sum()
        stale = (self._draws - self._last_drawn[legs]).astype(float)
        stale = stale / stale.sum() if stale.sum() > 0 else np.full(len(legs), 1.0 / len(legs))
        rho = self.params.staleness
        out[legs] = (1.0 - rho) * score + rho * stale
        return out

    def _draw_leg(self) -> int:
        p = self.probabilities()
        leg = int(self._rng.choice(self.n_legs, p=p / p.sum()))
        self._draws += 1
        self._last_drawn[leg] = self._draws
        return leg

    def stats(self) -> dict[str, Any]:
        """The sampler's state for a log: per leg the failure rate, missions flown and started,
        and the chance of a bank start on it."""
        return {
            "params": asdict(self.params),
            "failure": self.failure.tolist(),
            "flown": self.flown.tolist(),
            "started": self.started.tolist(),
            "probability": self.probabilities().tolist(),
        }
