"""Imitation learning: a policy network taught by a classical baseline (behaviour cloning + DAgger).

The classical APF-MPC agent completes every held-out mission but decides in about a millisecond
with a QP per step; PPO from scratch plateaus far below it (docs/training.md). This module trains
the same kind of small MLP policy as PPO does, by supervised regression on the expert's actions:

1. **Behaviour cloning**: the expert flies ``bc_episodes`` training fields; every (observation,
   expert action) pair is kept.
2. **DAgger** (Ross, Gordon & Bagnell 2011): for each of ``dagger_rounds`` rounds the current
   policy flies ``dagger_episodes`` fields while the expert, attached to the same env, names the
   action it would take in every state the *policy* visits; those pairs join the data set and the
   policy is refit. The policy thereby learns to recover from its own mistakes, which plain
   cloning never shows it.

The expert follows the env's own current goal (``ordering="nearest"``, see
:class:`agents.mission.MissionPlan`), the goal the policy sees in its observation
(``obs_goal``), so the labels are a function of what the policy can observe. Rollouts run in
``workers`` processes; the fit is plain mean-squared error on the normalised action, with the
observation normalised by the data set's mean and standard deviation.

The result is an SB3 PPO model (its actor trained here, its value head untouched) with a
VecNormalize file holding the observation statistics, in the same run-directory layout as
``train.py`` writes, so :func:`agents.load_agent` and ``evaluate.py --agents ppo=DIR/model.zip``
use it as they use any trained policy.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import pickle
import signal
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["ImitationConfig", "MLPActor", "RolloutStats", "collect", "imitate"]

TRAIN_SEED = 5_000_000
"""Fields of imitation runs are reset with seeds ``seed + TRAIN_SEED + k``: apart from the
held-out evaluation seeds of train.py (1 000 000 + i) and of the docs (10 000 000, 20 000 000)."""


@dataclass(frozen=True)
class ImitationConfig:
    """Everything an imitation run depends on (validated on construction).

    Attributes:
        env_id: the DebrisGym ID.
        env_kwargs: env options (the observation options the policy will need, e.g.
            ``obs_goal``); the task itself should be the default one.
        expert: baseline name (:func:`agents.make_agent`).
        expert_kwargs: its constructor arguments (``ordering`` defaults to "nearest").
        bc_episodes: expert-flown episodes first.
        dagger_rounds: DAgger rounds after cloning.
        dagger_episodes: policy-flown, expert-labelled episodes per round.
        dagger_beta: probability per step that the expert's action is executed instead of the
            policy's in the DAgger rollouts (0 = pure DAgger).
        net_arch: hidden layer widths of the MLP.
        activation_fn: hidden activation ("tanh" or "relu").
        epochs: passes over the data set per fit (the first fit; later fits warm-start).
        refit_epochs: passes per fit after a DAgger round.
        batch_size: minibatch size.
        learning_rate: Adam step size.
        weight_decay: Adam weight decay.
        workers: rollout processes.
        max_episode_steps: time limit of the rollouts (None: the ID's).
        seed: base seed (fields, network initialisation, minibatch order).
    """

    env_id: str = "DebrisGym/Rendezvous2D-v0"
    env_kwargs: dict[str, Any] = field(
        default_factory=lambda: {"obs_goal": True, "obs_targets": 1, "obs_other_targets": True}
    )
    expert: str = "apf-mpc"
    expert_kwargs: dict[str, Any] = field(default_factory=lambda: {"ordering": "nearest"})
    bc_episodes: int = 400
    dagger_rounds: int = 4
    dagger_episodes: int = 200
    dagger_beta: float = 0.0
    net_arch: tuple[int, ...] = (256, 256)
    activation_fn: str = "tanh"
    epochs: int = 30
    refit_epochs: int = 10
    batch_size: int = 512
    learning_rate: float = 1e-3
    weight_decay: float = 0.0
    workers: int = 2
    max_episode_steps: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        ints = {
            "bc_episodes": (1, None),
            "dagger_rounds": (0, None),
            "dagger_episodes": (1, None),
            "epochs": (1, None),
            "refit_epochs": (1, None),
            "batch_size": (1, None),
            "workers": (1, 64),
            "seed": (0, None),
        }
        for key, (low, high) in ints.items():
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"{key} must be an integer, got {value!r}")
            if value < low or (high is not None and value > high):
                allowed = f"[{low}, {high}]" if high is not None else f">= {low}"
                raise ValueError(f"{key}={value} is out of range; allowed: {allowed}")
        if not 0.0 <= self.dagger_beta <= 1.0:
            raise ValueError(f"dagger_beta={self.dagger_beta} is out of range; allowed: [0, 1]")
        for key in ("learning_rate",):
            value = getattr(self, key)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{key}={value} must be a positive finite number")
        if not (np.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise ValueError(f"weight_decay={self.weight_decay} must be >= 0")
        if not self.net_arch or any(int(w) < 1 for w in self.net_arch):
            raise ValueError(f"net_arch={self.net_arch!r} must be a non-empty list of widths >= 1")
        if self.activation_fn not in ACTIVATIONS:
            raise ValueError(
                f"activation_fn={self.activation_fn!r}; allowed: {', '.join(ACTIVATIONS)}"
            )
        if self.max_episode_steps is not None and self.max_episode_steps < 1:
            raise ValueError(f"max_episode_steps={self.max_episode_steps} must be >= 1")

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["net_arch"] = list(self.net_arch)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "config") -> ImitationConfig:
        """Build from a mapping (a YAML file's), rejecting unknown keys by name.

        Raises:
            ValueError: an unknown key (the closest known one suggested), a bad value.
        """
        import difflib

        known = [f.name for f in dataclasses.fields(cls)]
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key == "version":
                continue
            if key not in known:
                close = difflib.get_close_matches(str(key), known, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ValueError(f"{source}: unknown key {key!r}{hint}; known: {', '.join(known)}")
            kwargs[key] = value
        if "net_arch" in kwargs:
            kwargs["net_arch"] = tuple(kwargs["net_arch"])
        for key in ("env_kwargs", "expert_kwargs"):
            if key in kwargs and not isinstance(kwargs[key], dict):
                raise ValueError(f"{source}: {key} must be a mapping, got {kwargs[key]!r}")
        try:
            config = cls(**kwargs)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{source}: {exc}") from None
        config.check_env()
        return config

    def check_env(self) -> None:
        """Validate ``env_id`` and ``env_kwargs`` with the env's own checks.

        Raises:
            ValueError: an unknown ID or a bad env option.
        """
        import gymnasium as gym

        import debris_gym  # noqa: F401

        if self.env_id not in gym.registry:
            raise ValueError(f"unknown env_id {self.env_id!r}")
        kwargs = dict(self.env_kwargs)
        if kwargs.get("action", "continuous") != "continuous":
            raise ValueError("imitation needs env_kwargs.action = 'continuous' (the expert's)")
        from debris_gym.config import EnvConfig

        EnvConfig.from_kwargs(**{**gym.registry[self.env_id].kwargs, **kwargs})
        import agents

        env = gym.make(self.env_id, **kwargs)
        try:  # the expert's own checks (unknown name, bad parameters)
            agents.make_agent(self.expert, env, **expert_params(self.expert_kwargs))
        except TypeError as exc:
            raise ValueError(f"expert_kwargs: {exc}") from None
        finally:
            env.close()


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


@dataclass
class RolloutStats:
    """Outcomes of a batch of rollouts (per episode)."""

    seeds: list[int] = field(default_factory=list)
    success: list[bool] = field(default_factory=list)
    collision: list[bool] = field(default_factory=list)
    captured: list[int] = field(default_factory=list)
    delta_v: list[float] = field(default_factory=list)
    steps: list[int] = field(default_factory=list)

    def extend(self, other: RolloutStats) -> None:
        for f in dataclasses.fields(self):
            getattr(self, f.name).extend(getattr(other, f.name))

    def summary(self) -> dict[str, float]:
        n = max(len(self.seeds), 1)
        ok = [dv for dv, s in zip(self.delta_v, self.success, strict=True) if s]
        return {
            "episodes": len(self.seeds),
            "success": sum(self.success) / n,
            "collision": sum(self.collision) / n,
            "captured": float(np.mean(self.captured)) if self.captured else 0.0,
            "delta_v_success": float(np.mean(ok)) if ok else float("nan"),
            "steps": int(sum(self.steps)),
        }


def expert_params(kwargs: dict[str, Any]) -> dict[str, Any]:
    """The expert's constructor arguments, with the parameter mappings of a YAML file
    (``apf``, ``mpc``, ``reference``) turned into their dataclasses."""
    from agents.apf import APFParams
    from agents.mpc import MPCParams, ReferenceParams

    classes = {"apf": APFParams, "mpc": MPCParams, "reference": ReferenceParams}
    out = dict(kwargs)
    for key, cls in classes.items():
        if isinstance(out.get(key), dict):
            out[key] = cls(**out[key])
    return out


def _rollouts(
    task: tuple[ImitationConfig, Sequence[int], MLPActor | None, float, int],
) -> tuple[np.ndarray, np.ndarray, RolloutStats]:
    """Fly the episodes of ``seeds`` (worker process): observations, expert actions, outcomes."""
    import gymnasium as gym

    import agents
    import debris_gym  # noqa: F401  (registers the IDs)

    config, seeds, actor, beta, rng_seed = task
    kwargs = dict(config.env_kwargs)
    if config.max_episode_steps is not None:
        kwargs["max_episode_steps"] = config.max_episode_steps
    env = gym.make(config.env_id, **kwargs)
    expert = agents.make_agent(config.expert, env, **expert_params(config.expert_kwargs))
    rng = np.random.default_rng(rng_seed)
    observations: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    stats = RolloutStats()
    for seed in seeds:
        obs, info = env.reset(seed=int(seed))
        done, steps = False, 0
        while not done:
            label, _ = expert.predict(obs)
            observations.append(obs)
            labels.append(label)
            if actor is None or rng.random() < beta:
                action = label
            else:
                action = actor(obs)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            steps += 1
        stats.seeds.append(int(seed))
        stats.success.append(bool(info.get("is_success", False)))
        stats.collision.append(bool(info.get("collision", False)))
        stats.captured.append(int(info.get("targets_captured", 0)))
        stats.delta_v.append(float(info.get("delta_v", 0.0)))
        stats.steps.append(steps)
    env.close()
    return np.asarray(observations, np.float32), np.asarray(labels, np.float32), stats


def _ignore_interrupts() -> None:
    """Worker initialiser: Ctrl-C is the parent's to handle; the parent's SIGTERM (how
    ``Pool.terminate`` stops a worker) ends a worker quietly, whatever handler imitate.py set."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def collect(
    config: ImitationConfig,
    seeds: Sequence[int],
    actor: MLPActor | None = None,
    beta: float = 0.0,
    progress: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, RolloutStats]:
    """Expert-labelled rollouts on the fields of ``seeds``, in ``config.workers`` processes.

    Args:
        config: the run's configuration.
        seeds: reset seeds, one episode each.
        actor: the policy that flies (None: the expert flies).
        beta: probability per step of executing the expert's action instead of the actor's.
        progress: called with the number of episodes finished, after each chunk.

    Returns:
        (observations (M, obs_dim), expert actions (M, act_dim), per-episode outcomes).
    """
    seeds = [int(s) for s in seeds]
    chunk = 5
    tasks = [
        (config, seeds[i : i + chunk], actor, beta, config.seed * 7919 + i)
        for i in range(0, len(seeds), chunk)
    ]
    obs_parts, act_parts, stats = [], [], RolloutStats()
    if config.workers == 1:
        results = map(_rollouts, tasks)
        pool = None
    else:
        pool = multiprocessing.get_context("fork").Pool(config.workers, _ignore_interrupts)
        results = pool.imap(_rollouts, tasks)
    try:
        for obs, act, part in results:
            obs_parts.append(obs)
            act_parts.append(act)
            stats.extend(part)
            if progress is not None:
                progress(len(part.seeds))
    except BaseException:  # Ctrl-C or a worker's error: stop the workers now
        if pool is not None:
            pool.terminate()
            pool.join()
            pool = None
        raise
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    return np.concatenate(obs_parts), np.concatenate(act_parts), stats


# --------------------------------------------------------------------------------------------------
# the policy network and its fit
# --------------------------------------------------------------------------------------------------

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


# --------------------------------------------------------------------------------------------------
# a run
# --------------------------------------------------------------------------------------------------


def _atomic_pickle(path: Path, obj: Any) -> None:
    from debris_gym.files import save_atomic

    def save(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            pickle.dump(obj, fh)

    save_atomic(path, save)


def imitate(
    config: ImitationConfig,
    out: str | Path,
    log: Callable[[str], None] = print,
    progress: bool = True,
    command: str | None = None,
) -> dict[str, Any]:
    """Behaviour cloning then DAgger; writes a run directory ``out`` (see the module doc).

    Args:
        config: the run's settings.
        out: run directory (created; refused if it already holds a model).
        log: where the per-round lines go.
        progress: tqdm bars over the rollouts.
        command: the command line, recorded in ``config.yaml``.

    Returns:
        the run log (also written to ``out/imitation_log.json``): per round the rollout outcomes
        of the policy that flew it, the data set size, the fit losses and wall times.
    """
    import torch

    from debris_gym.files import save_atomic, write_atomic

    torch.set_num_threads(1)
    out = Path(out)
    if (out / "model.zip").exists():
        raise FileExistsError(f"{out} already holds a run (model.zip); choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(config.seed)
    torch.manual_seed(config.seed)
    next_seed = TRAIN_SEED + config.seed * 100_000
    started = time.time()
    history: list[dict[str, Any]] = []

    def seeds(n: int) -> list[int]:
        nonlocal next_seed
        out_seeds = list(range(next_seed, next_seed + n))
        next_seed += n
        return out_seeds

    def rollouts(n: int, actor: MLPActor | None, what: str) -> tuple:
        bar = _progress_bar(n, what) if progress else None
        try:
            return collect(
                config,
                seeds(n),
                actor,
                config.dagger_beta if actor is not None else 0.0,
                progress=bar.update if bar is not None else None,
            )
        finally:
            if bar is not None:
                bar.close()

    model, venv = make_model(config)
    t0 = time.time()
    observations, actions, stats = rollouts(config.bc_episodes, None, "expert rollouts")
    set_observation_stats(venv, observations)
    collect_time = time.time() - t0
    t0 = time.time()
    losses = fit(model, venv, observations, actions, config.epochs, config, rng)
    history.append(
        {
            "round": 0,
            "flown_by": config.expert,
            **stats.summary(),
            "dataset": len(observations),
            "loss_first": losses[0],
            "loss_last": losses[-1],
            "collect_s": collect_time,
            "fit_s": time.time() - t0,
        }
    )
    log(_round_line(history[-1]))
    for r in range(1, config.dagger_rounds + 1):
        actor = export_actor(model, venv, config.activation_fn)
        t0 = time.time()
        obs_r, act_r, stats = rollouts(config.dagger_episodes, actor, f"DAgger round {r}")
        collect_time = time.time() - t0
        observations = np.concatenate([observations, obs_r])
        actions = np.concatenate([actions, act_r])
        t0 = time.time()
        losses = fit(model, venv, observations, actions, config.refit_epochs, config, rng)
        history.append(
            {
                "round": r,
                "flown_by": "policy",
                **stats.summary(),
                "dataset": len(observations),
                "loss_first": losses[0],
                "loss_last": losses[-1],
                "collect_s": collect_time,
                "fit_s": time.time() - t0,
            }
        )
        log(_round_line(history[-1]))

    model_path = save_atomic(out / "model.zip", model.save)
    save_atomic(out / "vecnormalize.pkl", venv.save)
    run_log = {
        "config": config.to_dict(),
        "rounds": history,
        "wall_s": time.time() - started,
        "model": str(model_path),
    }
    write_atomic(out / "imitation_log.json", json.dumps(run_log, indent=2) + "\n")
    run = {
        "command": command,
        "started_at": _iso(started),
        "finished_at": _iso(time.time()),
        "wall_s": round(run_log["wall_s"], 1),
        "versions": _versions(),
    }
    write_atomic(out / "config.yaml", _run_config_yaml(config, run))
    plot_rounds(run_log, out / "imitation_curve.png")
    return run_log


def _round_line(h: dict[str, Any]) -> str:
    return (
        f"round {h['round']} ({h['flown_by']} flew {h['episodes']} episodes): success "
        f"{h['success']:.0%}, collisions {h['collision']:.0%}, captured {h['captured']:.2f}, "
        f"dv on successes {h['delta_v_success']:.1f} m/s; data {h['dataset']} pairs, loss "
        f"{h['loss_first']:.4f} -> {h['loss_last']:.4f}; "
        f"{h['collect_s']:.0f} s + {h['fit_s']:.0f} s"
    )


def _iso(t: float) -> str:
    from datetime import datetime, timezone

    return datetime.fromtimestamp(t, tz=timezone.utc).isoformat(timespec="seconds")


def _versions() -> dict[str, str]:
    from agents.training import _versions as training_versions

    return training_versions()


def _run_config_yaml(config: ImitationConfig, run: dict[str, Any] | None = None) -> str:
    """``config.yaml`` of an imitation run: what :mod:`agents.learned` reads (``env_kwargs`` for
    the observation options, ``normalize`` for the statistics) plus the imitation settings."""
    import yaml

    data = {
        "env_id": config.env_id,
        "algo": "ppo",
        "env_kwargs": dict(config.env_kwargs),
        "normalize": {
            "enabled": True,
            "norm_obs": True,
            "norm_reward": False,
            "clip_obs": CLIP_OBS,
            "epsilon": OBS_EPSILON,
        },
        "imitation": config.to_dict(),
    }
    if run is not None:
        data["run"] = run
    header = (
        "# Imitation run (imitate.py): an SB3 PPO model whose actor was fit to the expert's\n"
        "# actions (behaviour cloning + DAgger); see agents/imitation.py.\n"
    )
    return header + yaml.safe_dump(data, sort_keys=False)


def _progress_bar(total: int, what: str) -> Any:
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=what, unit="ep", leave=False)


def default_config_path(env_id: str) -> Path:
    """The checked-in imitation config of ``env_id`` (``agents/configs/<env>_imitation.yaml``)."""
    from agents.training import CONFIG_DIR, env_stub

    return CONFIG_DIR / f"{env_stub(env_id)}_imitation.yaml"


def load_imitation_config(
    env_id: str,
    path: str | Path | None = None,
    overrides: Sequence[str] = (),
    seed: int | None = None,
) -> ImitationConfig:
    """The run's configuration: a YAML file (default: :func:`default_config_path`), ``--set``
    overrides, then ``seed``.

    Raises:
        FileNotFoundError: no such file (or no checked-in config for ``env_id``).
        ValueError: bad YAML, keys or values; an ``env_id`` in the file other than ``env_id``.
    """
    from agents.training import apply_overrides, load_config_file

    source = Path(path) if path is not None else default_config_path(env_id)
    if path is None and not source.is_file():
        raise FileNotFoundError(
            f"no imitation config for {env_id} ({source.name}); give --config FILE"
        )
    data, _ = load_config_file(source)
    data = apply_overrides(data, overrides)
    file_env = data.setdefault("env_id", env_id)
    if file_env != env_id:
        raise ValueError(f"{source}: env_id {file_env!r} differs from --env {env_id!r}")
    if seed is not None:
        data["seed"] = seed
    return ImitationConfig.from_dict(data, str(source))


def plot_rounds(run_log: dict[str, Any], path: str | Path) -> Path:
    """Success and collision rate of each round's rollouts, and the data set size (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from debris_gym.files import save_atomic

    rounds = run_log["rounds"]
    r = [h["round"] for h in rounds]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
    ax1.plot(r, [h["success"] for h in rounds], "o-", label="success")
    ax1.plot(r, [h["collision"] for h in rounds], "s--", label="collision")
    ax1.set_xlabel("round (0: the expert flies; k: the policy of fit k flies)")
    ax1.set_ylabel("rate on the round's training fields")
    ax1.set_ylim(-0.02, 1.02)
    ax1.grid(alpha=0.3)
    ax1.legend()
    ax2.plot(r, [h["dataset"] / 1000 for h in rounds], "o-")
    ax2.set_xlabel("round")
    ax2.set_ylabel("data set [thousand pairs]")
    ax2.grid(alpha=0.3)
    fig.suptitle(f"imitation of {run_log['config']['expert']} on {run_log['config']['env_id']}")
    fig.tight_layout()
    out = Path(path)
    save_atomic(out, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return out
