"""PPO anchored to an initial policy: critic warm-up, then PPO plus a decaying imitation term.

Fine-tuning a behaviour-cloned policy with plain PPO tends to collapse: its value head is
untrained, so the first advantages are noise and the first updates push the policy away from
what it imitated before the critic knows anything. :class:`AnchoredPPO` therefore

1. **warms up the critic**: while ``num_timesteps <= critic_warmup`` an update trains only the
   value function (its own optimiser over the value parameters; the policy, ``log_std``
   included, is left bit-identical);
2. **anchors the policy**: afterwards each minibatch's loss is the PPO loss plus
   ``coef(t) · mean ‖μθ(s) − μ₀(s)‖²`` — μθ the policy's deterministic (mean) action, μ₀ that of
   a frozen copy of the initial policy, both on the minibatch's (normalised) observations —
   with ``coef`` falling linearly from ``anchor_coef`` to 0 over ``anchor_decay`` env steps
   after the warm-up (:func:`anchor_coef_at`).

The update is SB3's PPO update (clipped surrogate, optionally clipped value loss, entropy
bonus, gradient-norm clipping, ``target_kl`` early stop, the same ``train/…`` logger keys) with
the anchor added; it logs ``train/anchor_coef``, ``train/anchor_loss`` and
``train/critic_warmup`` (1 during the warm-up) as well.

The frozen reference is not part of the saved model (a plain ``PPO.load`` reads the files this
class writes): :meth:`AnchoredPPO.set_reference` gives it, on a fresh run and on a resume
(:mod:`agents.experiments.training.finetune`). The critic's warm-up optimiser is not saved
either: a run resumed during the warm-up restarts its Adam moments.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.utils import explained_variance
from torch.nn import functional as F

__all__ = ["VALUE_PREFIXES", "AnchoredPPO", "anchor_coef_at", "value_parameter_names"]

VALUE_PREFIXES = ("mlp_extractor.value_net.", "value_net.", "vf_features_extractor.")
"""Names (in ``policy.named_parameters()``) of the value function's parameters; every other
parameter belongs to the policy (actor layers, ``action_net``, ``log_std``)."""


def anchor_coef_at(
    timesteps: int, critic_warmup: int, anchor_coef: float, anchor_decay: int
) -> float:
    """The anchor's weight after ``timesteps`` env steps (over all sub-envs).

    ``anchor_coef`` until the warm-up ends (the policy does not learn then), then a linear
    fall to 0 over ``anchor_decay`` env steps, then 0. ``anchor_decay`` 0 means no anchor.
    """
    if timesteps <= critic_warmup:
        return float(anchor_coef)
    if anchor_decay <= 0:
        return 0.0
    return float(anchor_coef) * max(0.0, 1.0 - (timesteps - critic_warmup) / anchor_decay)


def value_parameter_names(policy: th.nn.Module) -> list[str]:
    """The value function's parameter names in ``policy`` (see :data:`VALUE_PREFIXES`)."""
    return [n for n, _ in policy.named_parameters() if n.startswith(VALUE_PREFIXES)]


class AnchoredPPO(PPO):
    """SB3 PPO with a critic warm-up and a decaying imitation anchor (module docstring).

    Args:
        policy, env: as for :class:`~stable_baselines3.PPO`.
        critic_warmup: env steps (over all sub-envs) at the start during which only the value
            function learns.
        anchor_coef: anchor weight at the end of the warm-up (per squared action unit; actions
            are the env's normalised thrust commands in [-1, 1]).
        anchor_decay: env steps after the warm-up over which the weight falls linearly to 0.
        **kwargs: :class:`~stable_baselines3.PPO` keyword arguments.
    """

    def __init__(
        self,
        policy: Any,
        env: Any,
        critic_warmup: int = 0,
        anchor_coef: float = 0.0,
        anchor_decay: int = 0,
        **kwargs: Any,
    ) -> None:
        self.critic_warmup = int(critic_warmup)
        self.anchor_coef = float(anchor_coef)
        self.anchor_decay = int(anchor_decay)
        self.reference_policy: ActorCriticPolicy | None = None
        self.critic_optimizer: th.optim.Optimizer | None = None
        super().__init__(policy, env, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()
        names = set(value_parameter_names(self.policy))
        if not names:
            raise ValueError("the policy has no separate value parameters to warm up")
        params = [p for n, p in self.policy.named_parameters() if n in names]
        # its own optimiser: the warm-up leaves the policy's Adam moments untouched
        # SB3 types optimizer_class as torch's Optimizer base, whose __init__ takes no lr
        self.critic_optimizer = self.policy.optimizer_class(  # type: ignore[call-arg]
            params, lr=self.lr_schedule(1), **self.policy.optimizer_kwargs
        )

    def _excluded_save_params(self) -> list[str]:
        # neither goes into the zip, so a plain PPO.load reads it (evaluate.py, load_agent)
        return [*super()._excluded_save_params(), "reference_policy", "critic_optimizer"]

    def set_reference(self, policy: ActorCriticPolicy) -> None:
        """Anchor to ``policy`` (a frozen copy is kept; its deterministic action is μ₀)."""
        reference = copy.deepcopy(policy).to(self.device)
        reference.set_training_mode(False)
        for p in reference.parameters():
            p.requires_grad_(False)
        self.reference_policy = reference

    def current_anchor_coef(self) -> float:
        """The anchor's weight at the model's ``num_timesteps``."""
        return anchor_coef_at(
            self.num_timesteps, self.critic_warmup, self.anchor_coef, self.anchor_decay
        )

    def in_warmup(self) -> bool:
        """Whether the next update trains only the value function."""
        return self.num_timesteps <= self.critic_warmup

    def train(self) -> None:
        """One update on the collected rollout: value-only during the warm-up, else anchored
        PPO."""
        self.policy.set_training_mode(True)
        if self.in_warmup():
            self._train_critic()
            return
        coef = self.current_anchor_coef()
        if coef > 0 and self.reference_policy is None:
            raise RuntimeError("AnchoredPPO: set_reference() must be called before training")
        self._update_learning_rate(self.policy.optimizer)
        progress = self._current_progress_remaining
        # SB3 types clip_range(_vf) as a float or a schedule; _setup_model made them schedules
        # (SB3's PPO.train carries the same ignores)
        clip_range = self.clip_range(progress)  # type: ignore[operator]
        clip_range_vf = self.clip_range_vf(progress) if self.clip_range_vf is not None else None  # type: ignore[operator]
        logs: dict[str, list[float]] = {
            k: [] for k in ("pg", "value", "entropy", "clip", "kl", "anchor")
        }
        loss = th.zeros(())
        keep_going = True
        for _ in range(self.n_epochs):
            for batch in self.rollout_buffer.get(self.batch_size):
                dist = self.policy.get_distribution(batch.observations)
                log_prob = dist.log_prob(batch.actions)
                entropy = dist.entropy()
                values = self.policy.predict_values(batch.observations).flatten()

                advantages = batch.advantages
                if self.normalize_advantage and len(advantages) > 1:
                    advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
                ratio = th.exp(log_prob - batch.old_log_prob)
                surrogate = th.min(
                    advantages * ratio,
                    advantages * th.clamp(ratio, 1 - clip_range, 1 + clip_range),
                )
                policy_loss = -surrogate.mean()
                value_loss = self._value_loss(values, batch, clip_range_vf)
                entropy_loss = -th.mean(entropy) if entropy is not None else th.mean(log_prob)
                anchor_loss = self._anchor_loss(dist.mode(), batch.observations, coef)
                loss = (
                    policy_loss
                    + self.ent_coef * entropy_loss
                    + self.vf_coef * value_loss
                    + coef * anchor_loss
                )

                logs["pg"].append(policy_loss.item())
                logs["value"].append(value_loss.item())
                logs["entropy"].append(entropy_loss.item())
                logs["anchor"].append(anchor_loss.item())
                logs["clip"].append(th.mean((th.abs(ratio - 1) > clip_range).float()).item())
                with th.no_grad():  # Schulman's k3 estimate of KL(old || new)
                    log_ratio = log_prob - batch.old_log_prob
                    kl = th.mean((th.exp(log_ratio) - 1) - log_ratio).item()
                logs["kl"].append(kl)
                if self.target_kl is not None and kl > 1.5 * self.target_kl:
                    keep_going = False
                    break

                self.policy.optimizer.zero_grad()
                loss.backward()
                th.nn.utils.clip_grad_norm_(self.policy.parameters(), self.max_grad_norm)
                self.policy.optimizer.step()
            self._n_updates += 1
            if not keep_going:
                break

        self._record_common(logs["value"], coef, logs["anchor"], warmup=False)
        self.logger.record("train/entropy_loss", _mean(logs["entropy"]))
        self.logger.record("train/policy_gradient_loss", _mean(logs["pg"]))
        self.logger.record("train/approx_kl", _mean(logs["kl"]))
        self.logger.record("train/clip_fraction", _mean(logs["clip"]))
        self.logger.record("train/loss", loss.item())
        self.logger.record("train/clip_range", clip_range)
        if clip_range_vf is not None:
            self.logger.record("train/clip_range_vf", clip_range_vf)

    def _value_loss(self, values: th.Tensor, batch: Any, clip_range_vf: float | None) -> th.Tensor:
        if clip_range_vf is not None:  # the new value stays near the one the rollout used
            values = batch.old_values + th.clamp(
                values - batch.old_values, -clip_range_vf, clip_range_vf
            )
        return F.mse_loss(batch.returns, values)

    def _anchor_loss(
        self, mean_actions: th.Tensor, observations: th.Tensor, coef: float
    ) -> th.Tensor:
        """mean over the minibatch of ‖μθ(s) − μ₀(s)‖² (0 without a reference or a weight)."""
        if coef <= 0 or self.reference_policy is None:
            return th.zeros((), device=self.device)
        with th.no_grad():
            reference = self.reference_policy.get_distribution(observations).mode()
        return th.sum((mean_actions - reference) ** 2, dim=-1).mean()

    def _train_critic(self) -> None:
        """A warm-up update: the value loss only, through the critic's own optimiser."""
        assert self.critic_optimizer is not None
        self._update_learning_rate(self.critic_optimizer)
        progress = self._current_progress_remaining
        # (a schedule: see train())
        clip_range_vf = self.clip_range_vf(progress) if self.clip_range_vf is not None else None  # type: ignore[operator]
        params = [p for group in self.critic_optimizer.param_groups for p in group["params"]]
        losses: list[float] = []
        for _ in range(self.n_epochs):
            for batch in self.rollout_buffer.get(self.batch_size):
                values = self.policy.predict_values(batch.observations).flatten()
                value_loss = self._value_loss(values, batch, clip_range_vf)
                losses.append(value_loss.item())
                self.critic_optimizer.zero_grad()
                (self.vf_coef * value_loss).backward()
                th.nn.utils.clip_grad_norm_(params, self.max_grad_norm)
                self.critic_optimizer.step()
            self._n_updates += 1
        self._record_common(losses, self.current_anchor_coef(), [], warmup=True)

    def _record_common(
        self, value_losses: list[float], coef: float, anchor_losses: list[float], warmup: bool
    ) -> None:
        buffer = self.rollout_buffer
        explained = explained_variance(buffer.values.flatten(), buffer.returns.flatten())
        self.logger.record("train/value_loss", _mean(value_losses))
        self.logger.record("train/explained_variance", explained)
        self.logger.record("train/anchor_coef", coef)
        self.logger.record("train/anchor_loss", _mean(anchor_losses) if anchor_losses else 0.0)
        self.logger.record("train/critic_warmup", int(warmup))
        if hasattr(self.policy, "log_std"):
            self.logger.record("train/std", th.exp(self.policy.log_std).mean().item())
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")


def _mean(values: list[float]) -> float:
    return float(np.mean(values)) if values else float("nan")
