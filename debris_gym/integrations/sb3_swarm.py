"""Stable-Baselines3 ``VecEnv`` over swarm fields: one SB3 env per chaser, for parameter-shared
learners (IPPO) without SuperSuit.

Rows are fields × chasers (:class:`~debris_gym.swarm.core.SwarmCore`). A chaser that ends stays
in its row with a zero observation and zero reward until every chaser of its field has ended
("black death"); then the field restarts and each of its rows reports ``done`` with the field's
outcome (``is_success``: the team's success, ``targets_captured``: the team's captures), so an
SB3 episode is one chaser's flight and its monitor return that chaser's return. Requires
``stable-baselines3``.

    from debris_gym.integrations.sb3_swarm import SwarmVecEnv
    venv = SwarmVecEnv("DebrisGym/Swarm2D-Easy-v0", num_envs=64)   # 32 fields of 2 chasers
    model = PPO("MlpPolicy", venv)
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.utils import seeding

from debris_gym.integrations.batch_vec_env import BatchVecEnv
from debris_gym.swarm import SWARM_SPECS
from debris_gym.swarm.core import SwarmCore

__all__ = ["SwarmVecEnv"]


class SwarmVecEnv(BatchVecEnv):
    """SB3 view of ``num_envs / K`` swarm fields of the swarm ID ``env_id``, one env per chaser.

    Args:
        env_id: a swarm ID.
        num_envs: SB3 envs, a multiple of the swarm's ``n_chasers`` K.
        **kwargs: swarm options (``n_chasers`` and every single-agent and swarm option) and
            ``max_episode_steps``.

    Raises:
        ValueError: an unknown ID, a ``num_envs`` that is not a multiple of K, a bad option.
    """

    _what = "the swarm vector env"

    def __init__(self, env_id: str, num_envs: int, **kwargs: Any) -> None:
        spec = SWARM_SPECS.get(env_id)
        if spec is None:
            raise ValueError(f"unknown swarm ID {env_id!r}; known: {', '.join(SWARM_SPECS)}")
        options = {**spec["kwargs"], **kwargs}
        steps = options.pop("max_episode_steps", spec["max_episode_steps"])
        k = options.get("n_chasers")
        if not isinstance(k, int) or isinstance(k, bool) or k < 1 or num_envs % k:
            raise ValueError(
                f"num_envs={num_envs} must be a multiple of n_chasers={k!r} (one env per chaser)"
            )
        self.env_id = env_id
        self.core = SwarmCore(num_envs // k, steps, **options)
        super().__init__(num_envs, self.core.observation_space, self.core.action_space)
        self._actions: np.ndarray | None = None
        self._started = False

    def reset(self) -> np.ndarray:
        """Every field anew; field e's generator seeded with ``seed()``'s seed of its first
        chaser's env (e·K), if any."""
        k = self.core.chasers
        seeds = self._seeds[::k]
        generators = None
        if any(s is not None for s in seeds):
            generators = [None if s is None else seeding.np_random(s)[0] for s in seeds]
        options = self._options[0] if self._options else None
        obs = self.core.reset(generators, options or None).copy()
        self._reset_seeds()
        self._reset_options()
        self._started = True
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        core = self.core
        actions = np.asarray(self._actions)
        if core.config.action == "discrete":
            commands = np.stack([core.command(a) for a in actions.reshape(-1)])
        else:
            commands = np.zeros((self.num_envs, core.config.dim))
            for row in np.flatnonzero(core.flying):  # the chasers flying: every action checked
                commands[row] = core.command(actions[row])
        result = core.step(commands)
        last = core.observe().copy()
        obs = last.copy()
        obs[~core.flying] = 0.0  # ended chasers: black death
        # SB3 reads infos at episode ends only: rows go on with an empty one
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        over = result.field_over
        dones = np.repeat(over, core.chasers)
        if over.any():
            team = core.team_success()
            captures = core.team_captures()
            k = core.chasers
            for e in np.flatnonzero(over).tolist():
                for i in range(e * k, e * k + k):
                    info = self._info(i)
                    info["is_success"] = bool(team[e])
                    info["targets_captured"] = int(captures[e])
                    cut = bool(result.truncated[i] and not result.terminated[i])
                    # a chaser cut by the time limit is bootstrapped from where it was
                    info["terminal_observation"] = (last if cut else obs)[i].copy()
                    info["TimeLimit.truncated"] = cut
                    infos[i] = info
            core.restart(over)
            fresh = core.observe()
            obs[dones] = fresh[dones]
        return obs, result.reward.astype(np.float32), dones, infos

    def _info(self, i: int) -> dict[str, Any]:
        """Chaser ``i``'s outcome so far."""
        m = self.core.shell.batch_in_use.missions
        return {
            "collision": bool(m.collision[i]),
            "teammate_collision": bool(m.teammate_collision[i]),
            "out_of_bounds": bool(m.out_of_bounds[i]),
            "chaser_success": bool(m.success[i]),
            "delta_v": float(m.delta_v[i]),
        }

    def close(self) -> None:
        self.core.close()

    def _batch(self) -> Any:
        return self.core
