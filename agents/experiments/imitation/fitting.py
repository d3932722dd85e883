"""The policy network and its fit: an SB3 PPO model whose actor regresses the expert's actions
(mean-squared error), and its numpy copy :class:`MLPActor` for rollouts without torch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.experiments.imitation.config import ImitationConfig

__all__ = [
    "CLIP_OBS",
    "OBS_EPSILON",
    "MLPActor",
    "export_actor",
    "fit",
    "make_model",
    "set_observation_stats",
]

ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "tanh": np.tanh,
    "relu": lambda x: np.maximum(x, 0.0),
}


@dataclass
class MLPActor:
    """A numpy copy of the policy (for rollouts in worker processes without torch).

    Attributes:
        mean, std: observation normalisation (the VecNormalize statistics, clip ``clip``).
        weights, biases: layer parameters, the last layer linear.
        activation: hidden activation name.
    """

    mean: np.ndarray
    std: np.ndarray
    weights: list[np.ndarray]
    biases: list[np.ndarray]
    activation: str = "tanh"
    clip: float = 10.0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Action in [-1, 1] (clipped like SB3's ``predict``) for one observation or a batch."""
        x = np.clip(
            (np.asarray(obs, dtype=np.float64) - self.mean) / self.std, -self.clip, self.clip
        )
        act = ACTIVATIONS[self.activation]
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = x @ w.T + b
            if k < len(self.weights) - 1:
                x = act(x)
        return np.clip(x, -1.0, 1.0).astype(np.float32)


OBS_EPSILON = 0.01
"""Added to the observation variance before dividing (a floor of 0.1 on the std), as the PPO
recipe's ``normalize.epsilon``: elements constant in the data set stay finite."""

CLIP_OBS = 10.0


def make_model(config: ImitationConfig) -> tuple[Any, Any]:
    """An SB3 PPO model of the policy's shape and its VecNormalize (observations only).

    The env is a one-sub-env native vector env with ``config.env_kwargs``: the model's spaces
    are the env's, so :func:`agents.load_agent` accepts it.
    """
    import torch.nn as nn
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from debris_gym.integrations.sb3 import NativeVecEnv

    venv = VecNormalize(
        NativeVecEnv(config.env_id, 1, **config.env_kwargs),
        training=False,
        norm_obs=True,
        norm_reward=False,
        clip_obs=CLIP_OBS,
        epsilon=OBS_EPSILON,
    )
    activation = {"tanh": nn.Tanh, "relu": nn.ReLU}[config.activation_fn]
    model = PPO(
        "MlpPolicy",
        venv,
        policy_kwargs={
            "net_arch": {"pi": list(config.net_arch), "vf": [64, 64]},
            "activation_fn": activation,
            "log_std_init": -2.0,
        },
        seed=config.seed,
        device="cpu",
        verbose=0,
    )
    return model, venv


def set_observation_stats(venv: Any, observations: np.ndarray) -> None:
    """Freeze ``venv``'s observation statistics at the data set's mean and variance."""
    venv.obs_rms.mean = observations.mean(axis=0).astype(np.float64)
    venv.obs_rms.var = observations.var(axis=0).astype(np.float64)
    venv.obs_rms.count = float(len(observations))


def export_actor(model: Any, venv: Any, activation: str) -> MLPActor:
    """The deterministic policy of ``model`` (behind ``venv``'s normalisation) as numpy."""
    layers = [m for m in model.policy.mlp_extractor.policy_net if hasattr(m, "weight")]
    layers.append(model.policy.action_net)
    return MLPActor(
        mean=np.array(venv.obs_rms.mean, dtype=np.float64),
        std=np.sqrt(np.array(venv.obs_rms.var, dtype=np.float64) + OBS_EPSILON),
        weights=[m.weight.detach().cpu().numpy().astype(np.float64) for m in layers],
        biases=[m.bias.detach().cpu().numpy().astype(np.float64) for m in layers],
        activation=activation,
        clip=CLIP_OBS,
    )


def fit(
    model: Any,
    venv: Any,
    observations: np.ndarray,
    actions: np.ndarray,
    epochs: int,
    config: ImitationConfig,
    rng: np.random.Generator,
) -> list[float]:
    """Regress the policy's mean action on the expert's (MSE), ``epochs`` passes; returns the
    mean loss of each pass."""
    import torch

    x = torch.as_tensor(venv.normalize_obs(observations), dtype=torch.float32)
    y = torch.as_tensor(actions, dtype=torch.float32)
    policy = model.policy
    params = list(policy.mlp_extractor.policy_net.parameters()) + list(
        policy.action_net.parameters()
    )
    optimiser = torch.optim.Adam(params, lr=config.learning_rate, weight_decay=config.weight_decay)
    losses = []
    policy.set_training_mode(True)
    for _ in range(epochs):
        order = torch.as_tensor(rng.permutation(len(x)))
        total = 0.0
        for start in range(0, len(x), config.batch_size):
            idx = order[start : start + config.batch_size]
            mean = policy.action_net(policy.mlp_extractor.forward_actor(x[idx]))
            loss = torch.mean((mean - y[idx]) ** 2)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(idx)
        losses.append(total / len(x))
    policy.set_training_mode(False)
    return losses
