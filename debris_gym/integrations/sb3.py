"""Stable-Baselines3 ``VecEnv`` over the native vector env, so SB3 trains on it directly.

SB3 expects *same-step* autoreset (the step that ends an episode returns the next episode's first
observation, the last one in ``info["terminal_observation"]``) and per-env info dicts; this adapter
builds the native env in ``SAME_STEP`` mode and translates. Requires ``stable-baselines3``.

    from debris_gym.integrations.sb3 import NativeVecEnv
    venv = NativeVecEnv("DebrisGym/Rendezvous2D-v2", num_envs=64)
    model = PPO("MlpPolicy", venv)
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.integrations.batch_vec_env import BatchVecEnv  # names SB3 if it is missing

INFO_KEYS = ("time", "delta_v", "targets_captured", "n_targets", "min_clearance", "collision",
             "out_of_bounds", "is_success")  # fmt: skip


def make_vec_env(env_id: str, num_envs: int, **kwargs: Any) -> BatchVecEnv:
    """The SB3 training env of ``env_id``: :class:`NativeVecEnv` for the single-agent IDs,
    :class:`~debris_gym.integrations.sb3_swarm.SwarmVecEnv` (one env per chaser) for the swarm
    IDs."""
    from debris_gym.swarm import SWARM_SPECS

    if env_id in SWARM_SPECS:
        from debris_gym.integrations.sb3_swarm import SwarmVecEnv

        return SwarmVecEnv(env_id, num_envs, **kwargs)
    return NativeVecEnv(env_id, num_envs, **kwargs)


def envs_per_mission(env_id: str, **kwargs: Any) -> int:
    """SB3 envs one mission takes: the chasers of a swarm ID's field, else 1."""
    from debris_gym.swarm import SWARM_SPECS

    if env_id not in SWARM_SPECS:
        return 1
    return int(kwargs.get("n_chasers", SWARM_SPECS[env_id]["kwargs"]["n_chasers"]))


class NativeVecEnv(BatchVecEnv):
    """SB3 view of ``gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point")``.

    Args:
        env_id: a DebrisGym ID.
        num_envs: number of sub-envs.
        **kwargs: env options (any config key) and ``max_episode_steps``.
    """

    _what = "the native vector env"

    def __init__(self, env_id: str, num_envs: int, **kwargs: Any) -> None:
        self.env_id = env_id
        venv = gym.make_vec(
            env_id,
            num_envs=num_envs,
            vectorization_mode="vector_entry_point",
            autoreset_mode=AutoresetMode.SAME_STEP,
            **kwargs,
        )
        if not isinstance(venv, DebrisFieldVectorEnv):
            raise ValueError(
                f"env_id {env_id!r} builds a {type(venv).__name__}, not debris-gym's native "
                "vector env: use a DebrisGym ID"
            )
        self.venv = venv
        super().__init__(
            num_envs, self.venv.single_observation_space, self.venv.single_action_space
        )
        self._actions: np.ndarray | None = None
        self._new_mission: dict[str, Any] | None = None

    def reset(self) -> np.ndarray:
        """Reset every sub-env, with the seeds of ``seed()`` and the options of
        ``set_options()`` (one dict for all: the sub-envs share one batch)."""
        seeds = self._seeds
        seed: list[int | None] | None = None if all(s is None for s in seeds) else list(seeds)
        options = self._options[0] if self._options else {}
        if any(o != options for o in self._options):
            raise ValueError("the native vector env takes one options dict for every sub-env")
        obs, _ = self.venv.reset(seed=seed, options=options or None)
        self._reset_seeds()
        self._reset_options()
        self._new_mission = None
        return obs

    def set_mission(self, mission: dict[str, Any]) -> None:
        """Move every sub-env to another mission (a difficulty rung) at the next step.

        That step ends every running episode — those that do not end by themselves are
        truncated (``TimeLimit.truncated``: learners bootstrap them, as at a time limit) — and
        restarts every sub-env with ``reset(options={"mission": mission})``; the generators go
        on, so nothing else about the run changes. This is how a curriculum changes rungs while
        SB3 is collecting rollouts, with no reset from outside.

        Raises:
            ValueError: now, naming the bad key or value (checked against the env's options).
        """
        self.venv.shell.checked_mission(mission)
        self._new_mission = dict(mission)

    def set_start_sampler(self, sampler: Any) -> None:
        """Start the missions the env restarts from now on where ``sampler`` says (a
        :class:`~debris_gym.envs.starts.StartSampler`; None: at the dock)."""
        self.venv.shell.start_sampler = sampler

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in range(self.num_envs):
            if dones[i]:
                final = info["final_info"]
                infos[i] = {key: final[key][i] for key in INFO_KEYS}
                infos[i]["terminal_observation"] = info["final_obs"][i]
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            else:
                infos[i] = {key: info[key][i] for key in INFO_KEYS}
        if self._new_mission is not None:
            obs = self._change_mission(obs, dones, infos)
            dones = np.ones(self.num_envs, dtype=bool)
        return obs, reward.astype(np.float32), dones, infos

    def _change_mission(
        self, obs: np.ndarray, dones: np.ndarray, infos: list[dict[str, Any]]
    ) -> np.ndarray:
        """Truncate the running episodes and restart every sub-env on the new mission."""
        for i in np.flatnonzero(~dones):
            infos[i]["terminal_observation"] = obs[i].copy()
            infos[i]["TimeLimit.truncated"] = True
        mission, self._new_mission = self._new_mission, None
        new_obs, _ = self.venv.reset(options={"mission": mission})
        return new_obs

    def close(self) -> None:
        self.venv.close()

    def _batch(self) -> Any:
        return self.venv.unwrapped
