"""Native vectorised DebrisField env: N envs as numpy arrays, one compiled step.

Reached through ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
Every sub-env behaves exactly like ``gym.make(id)`` reset with seed ``seed + i`` (same fields,
same dynamics, same rewards, observations and infos; ``tests/test_vector_env.py`` checks it
against N single envs): both envs are views of one
:class:`~debris_gym.envs.shell.MissionShell`, the single env of its one row, this env of all N.

Autoreset follows Gymnasium 1.x's default *next-step* mode: the step after a sub-env terminates or
truncates resets it (its action is ignored) and returns the first observation of the new episode
with reward 0; *same-step* mode is an option. Each sub-env keeps its own seeded generator, and a
sub-env's fields depend on that generator alone, so the fields of a moving world are drawn ahead
on a worker thread while the missions fly
(:class:`~debris_gym.envs.field_supply.FieldSupply`) — the same fields as a draw at reset time.
:attr:`DebrisFieldVectorEnv.scenarios` builds a sub-env's :class:`Scenario` only when read.
``step`` has no Python loop over envs or debris.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from debris_gym.config import EnvConfig
from debris_gym.envs.common import (
    checked_continuous_actions,
    checked_seed,
    discrete_action_table,
    observation_names,
    real_array,
    registered_horizon,
    single_spaces,
)
from debris_gym.envs.shell import Autoreset, MissionShell, ShellView
from debris_gym.envs.shell_info import INFO_KEYS
from debris_gym.rewards import REWARD_TERMS
from debris_gym.scenario import Scenario

_AUTORESET = {
    AutoresetMode.NEXT_STEP: Autoreset.NEXT_STEP,
    AutoresetMode.SAME_STEP: Autoreset.SAME_STEP,
}


class DebrisFieldVectorEnv(ShellView, VectorEnv):
    """N DebrisField envs stepped together.

    Args:
        num_envs: number of sub-envs N (>= 1).
        max_episode_steps: truncation limit per episode (the registration's value when made
            through ``gym.make_vec``); None means no limit.
        render_mode: only None (render a single env to look at episodes).
        autoreset_mode: ``NEXT_STEP`` (Gymnasium's default) or ``SAME_STEP`` (the ending step
            already returns the new episode's first observation; the last one is in
            ``info["final_obs"]``, its info in ``info["final_info"]``), as for SyncVectorEnv.
        num_threads: threads that step the sub-envs (1, the default: the calling thread only;
            up to the number of cores). The sub-envs are split into row ranges stepped in
            parallel by numba; results are identical for any count. On a shared machine, or
            with other processes training beside it, keep 1.
        draw_ahead: draw each sub-env's next moving field on a worker thread while the
            missions fly (default True; results are the same either way).
        **kwargs: any :class:`~debris_gym.config.EnvConfig` key, as for the single env.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        num_threads: int = 1,
        draw_ahead: bool = True,
        **kwargs: Any,
    ) -> None:
        if not (_is_int(num_envs) and num_envs >= 1):
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if max_episode_steps is not None and not (
            _is_int(max_episode_steps) and max_episode_steps >= 1
        ):
            raise ValueError(
                f"max_episode_steps must be an integer >= 1 or None, got {max_episode_steps!r}"
            )
        if render_mode is not None:
            raise ValueError(
                "the vector env does not render; make a single env with render_mode='rgb_array'"
            )
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            mode = None
        if mode not in _AUTORESET:
            raise ValueError(
                f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {autoreset_mode!r}"
            )
        if not isinstance(draw_ahead, (bool, np.bool_)):
            raise ValueError(f"draw_ahead must be True or False, got {draw_ahead!r}")
        cfg = EnvConfig.from_kwargs(**kwargs)
        self.num_envs = n = int(num_envs)
        self._shell = MissionShell(
            cfg, n, autoreset=_AUTORESET[mode], max_episode_steps=max_episode_steps,
            threads=num_threads, draw_ahead=bool(draw_ahead),
        )  # fmt: skip
        self.num_threads = self._shell.threads
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.max_episode_steps = max_episode_steps
        self.render_mode = None
        self.dim = d = cfg.dim
        self.single_observation_space, self.single_action_space = single_spaces(cfg)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self._obs_names = observation_names(cfg)
        self._discrete_actions = discrete_action_table(d, cfg.fine_thrust)

    # --- state accessors ----------------------------------------------------------------------

    @property
    def scenarios(self) -> Sequence[Scenario | None]:
        """The current field of every sub-env (None before the first reset).

        A read-only sequence; a random field is stored as arrays and turned into its
        :class:`Scenario` when accessed (the same ``Scenario`` the single env builds).
        """
        return _ScenarioList(self._shell)

    # --- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every sub-env.

        Transactional, as the single env: seeds, options, the fields (drawn or pinned) and the
        initial states are all checked before anything of the env changes, so a reset that
        raises leaves every sub-env as it was (fields, states, clocks, generators, pending
        autoresets).

        Args:
            seed: an int seeds sub-env i with ``seed + i``; a list gives one seed per sub-env.
            options: ``{"scenario": ...}`` pins the same field in every sub-env (it must have
                the physics and sizes of the fields the autoresets draw);
                ``{"chaser_state": array (N, 2·dim) or (2·dim,)}`` sets the initial states
                (:func:`~debris_gym.envs.common.checked_chaser_states`);
                ``{"mission": {...}}`` changes what every sub-env's missions ask
                (:data:`~debris_gym.envs.common.MISSION_KEYS`) from this reset on, autoresets
                included, until a reset names another mission (``{}``: the env's own again).

        Raises:
            ValueError: naming the bad seed or option; the env is unchanged.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            first = int(seed)
            checked_seed(first)
            seeds = [first + i for i in range(n)]
        else:
            if isinstance(seed, (str, bytes, bool)) or not isinstance(seed, (Sequence, np.ndarray)):
                raise ValueError(f"seed must be an int, a list of num_envs={n} ints or None")
            seeds = [checked_seed(s, f"seed[{i}]") for i, s in enumerate(seed)]
            if len(seeds) != n:
                raise ValueError(f"seed list must have num_envs={n} entries, got {len(seeds)}")
        generators = [None if s is None else seeding.np_random(s)[0] for s in seeds]
        shell = self._shell
        shell.horizon = registered_horizon(self.spec)
        shell.reset(generators, options)
        return shell.observe(), self._info(np.zeros((n, len(REWARD_TERMS))))

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-env (sub-envs that ended last step reset instead)."""
        shell = self._shell
        if shell.batch is None:
            raise RuntimeError("call reset() before step()")
        result = shell.step(self._actions(actions))
        info = self._info(result.terms)
        ended, final_obs, final_info = result.ended, result.final_observation, result.final_info
        if ended is not None and final_obs is not None and final_info is not None:  # same step
            info["final_obs"] = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(ended):
                info["final_obs"][i] = final_obs[i]
            info["_final_obs"] = ended.copy()
            info["final_info"] = _masked(final_info, ended)
            info["_final_info"] = ended.copy()
        return shell.observe(), result.reward, result.terminated, result.truncated, info

    def close_extras(self, **kwargs: Any) -> None:
        shell = getattr(self, "_shell", None)  # None when the constructor refused its options
        if shell is not None:
            shell.close()

    # --- step hooks ---------------------------------------------------------------------------

    def _actions(self, actions: Any) -> np.ndarray:
        """Validated actions as normalised thrust commands (N, dim)."""
        cfg, n, d = self.config, self.num_envs, self.dim
        if cfg.action == "discrete":
            idx = real_array(actions, "action")
            if idx.shape != (n,) or idx.dtype.kind not in "iu":
                raise ValueError(f"discrete actions must be {n} integers, got {actions!r}")
            last = len(self._discrete_actions) - 1
            if np.any((idx < 0) | (idx > last)):
                raise ValueError(f"discrete actions must lie in [0, {last}], got {idx}")
            return self._discrete_actions[idx]
        return checked_continuous_actions(actions, (n, d))

    def _info(self, terms: np.ndarray) -> dict[str, Any]:
        return _masked(self._shell.info(terms), np.ones(self.num_envs, dtype=bool))


def _masked(values: dict[str, Any], mask: np.ndarray) -> dict[str, Any]:
    """A vector env's info: every key of :data:`INFO_KEYS` with its ``_key`` mask (gymnasium's
    convention: which sub-envs the value is for)."""
    info: dict[str, Any] = {}
    for key in INFO_KEYS:
        info[key] = values[key]
        info["_" + key] = mask
    return info


def _is_int(value: Any) -> bool:
    """A Python or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


class _ScenarioList(Sequence):
    """Read-only view of a vector env's fields: item i is sub-env i's :class:`Scenario`."""

    def __init__(self, shell: MissionShell) -> None:
        self._shell = shell

    def __len__(self) -> int:
        return self._shell.num

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._shell.scenario(i) for i in range(len(self))[index]]
        i = operator.index(index)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"sub-env index {index} out of range for {len(self)} sub-envs")
        return self._shell.scenario(i)
