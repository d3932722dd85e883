"""The compiled safety shield in an env's step: the ``shield`` option.

:class:`LoopShield` filters every live row's normalised command through
:func:`debris_gym.shield_kernel.shield_rows` before the compiled step flies it, counts the
interventions of each row's episode and gives the penalty they cost
(``shield_penalty`` per intervention). The shell (:class:`~debris_gym.envs.shell.MissionShell`)
owns one when its config says ``shield=True``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import discrete_action_table
from debris_gym.jit import specialise
from debris_gym.mission_batch import MissionBatch
from debris_gym.shield_kernel import shield_rows
from debris_gym.shield_model import ShieldModel, make_shield_model

__all__ = ["LoopShield", "check_shield_support", "row_shield_info", "shield_info", "shield_term"]


def check_shield_support(config: EnvConfig, chasers: int) -> None:
    """Refuse the ``shield`` option where it has no meaning yet.

    Raises:
        ValueError: ``shield=True`` with several chasers per field (the compiled shield does
            not predict teammates).
    """
    if config.shield and chasers != 1:
        raise ValueError(
            "shield=True is for one chaser per field: the compiled shield does not predict "
            "teammates; filter a swarm's actions with the agents package's TeamShield instead"
        )


class LoopShield:
    """The compiled shield of N missions, with per-episode intervention counts.

    Args:
        config: the env config (``shield_penalty`` is read from it).
        num: missions N.
    """

    def __init__(self, config: EnvConfig, num: int) -> None:
        self.penalty = float(config.shield_penalty)
        self._table = discrete_action_table(config.dim, config.fine_thrust)
        self.interventions = np.zeros(num, dtype=np.int64)
        """(N,) commands replaced in each row's current episode."""
        self.intervened = np.zeros(num, dtype=bool)
        """(N,) whether the last step replaced each row's command."""
        self._out = np.zeros((num, config.dim))
        self._model: ShieldModel | None = None
        self._key: tuple[Any, ...] | None = None
        self._code: Callable[..., Any] | None = None

    def __getstate__(self) -> dict:
        # the resolved machine code does not pickle: it is resolved again on first use
        state = self.__dict__.copy()
        state.update(_code=None, _model=None, _key=None)
        return state

    def _model_of(self, batch: MissionBatch) -> ShieldModel:
        """The shield's model for ``batch`` (rebuilt when the batch's physics changed)."""
        key = (id(batch), batch.config, batch.physics, batch.n_targets)
        if self._model is None or key != self._key:
            n, dt, accel = batch.physics
            self._model = make_shield_model(
                batch.config, mean_motion=n, dt=dt, max_accel=accel,
                n_targets=batch.n_targets, table=self._table,
            )  # fmt: skip
            self._key = key
        return self._model

    def begin(self, rows: np.ndarray) -> None:
        """New episodes in ``rows``: their counts start from zero."""
        self.interventions[rows] = 0
        self.intervened[rows] = False

    def filter(self, batch: MissionBatch, actions: np.ndarray, live: np.ndarray) -> np.ndarray:
        """The commands to fly instead of ``actions`` (N, dim) in the rows ``live`` (N,) bool;
        updates :attr:`intervened` and :attr:`interventions`. Returns a buffer the next call
        overwrites."""
        missions, field = batch.missions, batch.field
        actions = np.ascontiguousarray(actions, dtype=np.float64)
        live = np.ascontiguousarray(live, dtype=np.bool_)
        args = (
            self._model_of(batch), live, actions, missions.state, field.centers,
            field.velocities, field.radii, self._out, self.intervened,
        )  # fmt: skip
        if self._code is None:
            self._code = specialise(shield_rows, *args)
        self._code(*args)
        self.interventions += self.intervened
        return self._out

    def penalties(self) -> np.ndarray:
        """(N,) this step's penalty (>= 0) of each row: ``shield_penalty`` if the shield
        replaced its command."""
        return self.penalty * self.intervened


def shield_info(shield: LoopShield | None, num: int) -> dict[str, np.ndarray]:
    """The shield's ``info`` keys of the ``num`` rows, new arrays: ``shield_intervened`` (bool)
    and ``shield_interventions`` (int64), False / 0 without the shield."""
    if shield is None:
        return {
            "shield_intervened": np.zeros(num, dtype=bool),
            "shield_interventions": np.zeros(num, dtype=np.int64),
        }
    return {
        "shield_intervened": shield.intervened.copy(),
        "shield_interventions": shield.interventions.copy(),
    }


def row_shield_info(shield: LoopShield | None, row: int) -> dict[str, Any]:
    """The shield's ``info`` keys of mission ``row`` as Python scalars (:func:`shield_info`'s
    values in that row)."""
    if shield is None:
        return {"shield_intervened": False, "shield_interventions": 0}
    return {
        "shield_intervened": shield.intervened.item(row),
        "shield_interventions": shield.interventions.item(row),
    }


def shield_term(
    shield: LoopShield | None, terms: dict[str, Any], row: int | None = None
) -> dict[str, Any]:
    """``terms`` (the reward terms by name) with the shield's penalty term ``"shield"``
    (<= 0; of ``row``, or an array of every row) when the shield is on; as they are without it."""
    if shield is None:
        return terms
    penalty = 0.0 - shield.penalties()
    terms["shield"] = penalty if row is None else float(penalty[row])
    return terms
