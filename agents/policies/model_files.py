"""Where a trained model's files live, and how to read them, without importing the trainer.

A run directory written by ``train.py`` (or ``imitate.py``) holds ``model.zip``, its
VecNormalize statistics beside it (:func:`sidecar_path`) and the resolved ``config.yaml``
(:func:`read_config_mapping`). Both the loader of learned policies and the trainer use these names,
so they live here, below both: :func:`find_model_file` (a model file, or a run directory's
newest model) and :func:`load_vecnormalize_pickle` (statistics unpickled with only their own
types allowed).
"""

from __future__ import annotations

import json
import os
import pickle
import re
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

LEARNED_ALGOS = ("ppo", "sac", "td3", "dqn", "recurrent_ppo")
"""Algorithms whose saved models :func:`agents.load_agent` loads: the SB3 classes of the same
name, and sb3-contrib's ``RecurrentPPO`` (an LSTM policy)."""

FINAL_MODEL = "model.zip"
"""File name of a run's final model inside its directory."""

CHECKPOINT_RE = re.compile(r"^(?P<prefix>.+)_(?P<steps>\d+)_steps$")
"""The stem of an SB3 checkpoint, ``rl_model_N_steps``."""


def algo_class(algo: str) -> type[BaseAlgorithm]:
    """The Stable-Baselines3 class of ``algo`` (one of :data:`LEARNED_ALGOS`).

    Raises:
        ValueError: ``recurrent_ppo`` without the sb3-contrib package installed.
    """
    import stable_baselines3 as sb3

    if algo == "recurrent_ppo":
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError:
            raise ValueError(
                "algo 'recurrent_ppo' needs the sb3-contrib package: pip install sb3-contrib "
                '(or pip install -e ".[rl]")'
            ) from None
        return RecurrentPPO
    classes: dict[str, type[BaseAlgorithm]] = {
        "ppo": sb3.PPO,
        "sac": sb3.SAC,
        "td3": sb3.TD3,
        "dqn": sb3.DQN,
    }
    return classes[algo]


def sidecar_path(model_path: str | Path, kind: str) -> Path:
    """Where the ``kind`` ("vecnormalize" or "replay_buffer") file of a model lives.

    ``DIR/model.zip`` → ``DIR/vecnormalize.pkl``; SB3 checkpoints ``rl_model_N_steps.zip`` →
    ``rl_model_vecnormalize_N_steps.pkl``; any other ``NAME.zip`` → ``NAME_vecnormalize.pkl``.
    """
    path = Path(model_path)
    stem = path.name[: -len(".zip")] if path.name.endswith(".zip") else path.name
    if path.name == FINAL_MODEL:
        return path.with_name(f"{kind}.pkl")
    match = CHECKPOINT_RE.match(stem)
    if match:
        return path.with_name(f"{match['prefix']}_{kind}_{match['steps']}_steps.pkl")
    return path.with_name(f"{stem}_{kind}.pkl")


MAX_CONFIG_BYTES = 1_000_000
"""Largest config file read (the checked-in ones are a few kB; a larger one is not a config)."""


def read_config_mapping(path: str | Path) -> dict[str, Any]:
    """The mapping a YAML config file holds (a run's ``config.yaml``, a recipe).

    Any readable file that is not a directory is read (a pipe such as ``<(...)`` too), at most
    :data:`MAX_CONFIG_BYTES` of it.

    Raises:
        FileNotFoundError: no such file.
        ValueError: a directory, unreadable, larger than :data:`MAX_CONFIG_BYTES`, not UTF-8
            text, not YAML, or not a mapping; the message names the file.
    """
    import yaml

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"config file {str(path)!r} not found")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, not a config file")
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"{path}: cannot be read ({exc.strerror})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ValueError(f"{path}: larger than {MAX_CONFIG_BYTES:,} bytes; not a config file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{path}: not a YAML text file (byte {exc.start} is not UTF-8 text)"
        ) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(data, dict):
        what = "is empty" if data is None else f"holds a {type(data).__name__}"
        raise ValueError(f"{path}: {what}; a config file holds a mapping of config keys")
    return data


BEST_MODEL = "best_model.zip"
"""File name of a run's best model on its held-out evaluations."""

CHECKPOINT_DIR = "checkpoints"
"""Folder of a run's periodic checkpoints (and the one a Ctrl-C writes)."""


def model_timesteps(model_path: str | Path) -> int | None:
    """``num_timesteps`` stored in an SB3 model zip (read without loading the model), or None
    if the file is not a readable model."""
    try:
        with zipfile.ZipFile(model_path) as archive:
            return int(json.loads(archive.read("data"))["num_timesteps"])
    except (OSError, KeyError, TypeError, ValueError, zipfile.BadZipFile):
        return None


def _run_contents(run_dir: Path) -> str:
    """What a directory holds, for an error message (``model.zip, checkpoints/ (2 files)``)."""
    try:
        entries = sorted(run_dir.iterdir())
    except OSError:
        return "nothing readable"
    if not entries:
        return "nothing (an empty directory)"
    shown = []
    for entry in entries[:12]:
        if entry.is_dir():
            count = sum(1 for _ in entry.iterdir()) if os.access(entry, os.R_OK) else 0
            shown.append(f"{entry.name}/ ({count} files)")
        else:
            shown.append(entry.name)
    more = f", … ({len(entries) - 12} more)" if len(entries) > 12 else ""
    return ", ".join(shown) + more


def run_models(run_dir: str | Path) -> list[tuple[Path, int | None]]:
    """The models of run directory ``run_dir`` with their step counts, in the order a loader
    prefers them: ``model.zip``, then the checkpoints (``checkpoints/*.zip``) newest first (most
    timesteps, then latest modified; unreadable ones last), then ``best_model.zip``."""
    run_dir = Path(run_dir)
    found: list[tuple[Path, int | None]] = []
    if (run_dir / FINAL_MODEL).is_file():
        found.append((run_dir / FINAL_MODEL, model_timesteps(run_dir / FINAL_MODEL)))
    checkpoints = [p for p in (run_dir / CHECKPOINT_DIR).glob("*.zip") if p.is_file()]
    ranked = sorted(
        ((p, model_timesteps(p)) for p in checkpoints),
        key=lambda item: (item[1] is not None, item[1] or 0, item[0].stat().st_mtime),
        reverse=True,
    )
    found += ranked
    if (run_dir / BEST_MODEL).is_file():
        found.append((run_dir / BEST_MODEL, model_timesteps(run_dir / BEST_MODEL)))
    return found


def find_model_file(path: str | Path) -> tuple[Path, str | None]:
    """The model file ``path`` names, and a note when it was chosen from a run directory.

    ``path`` may be a model file, or a run directory written by ``train.py``: its ``model.zip``,
    else (a run stopped by Ctrl-C or killed) its newest checkpoint, else its ``best_model.zip``
    (the note says which, and why).

    Raises:
        FileNotFoundError: no such file, or a directory without a model; the message lists what
            is there (the run's checkpoints when a named file is missing).
    """
    path = Path(path)
    if path.is_file():
        return path, None
    if path.is_dir():
        models = run_models(path)
        if not models:
            raise FileNotFoundError(
                f"{str(path)!r} holds no model (no {FINAL_MODEL}, {CHECKPOINT_DIR}/*.zip or "
                f"{BEST_MODEL}); it has: {_run_contents(path)}"
            )
        chosen, steps = models[0]
        if chosen.name == FINAL_MODEL and chosen.parent == path:
            return chosen, None
        when = f" ({steps} timesteps)" if steps is not None else ""
        return chosen, (
            f"{path} has no {FINAL_MODEL} (the run did not finish); using its newest model, "
            f"{chosen.relative_to(path)}{when}"
        )
    hint = ""
    run_dir = path.parent if path.suffix == ".zip" else None
    if run_dir is not None and run_dir.is_dir():
        models = run_models(run_dir)
        if models:
            listed = ", ".join(
                str(p.relative_to(run_dir)) + ("" if s is None else f" ({s} timesteps)")
                for p, s in models[:6]
            )
            hint = (
                f"; {run_dir} holds {listed}: name one of them, or the directory itself for its "
                "newest"
            )
        else:
            hint = f"; {run_dir} has: {_run_contents(run_dir)}"
    raise FileNotFoundError(f"model file {str(path)!r} not found{hint}")


_VECNORMALIZE_GLOBALS: dict[str, frozenset[str]] = {
    "stable_baselines3.common.vec_env.vec_normalize": frozenset({"VecNormalize"}),
    "stable_baselines3.common.running_mean_std": frozenset({"RunningMeanStd"}),
    "numpy": frozenset({"dtype", "ndarray"}),
    "numpy._core.multiarray": frozenset({"_reconstruct", "scalar"}),
    "numpy.core.multiarray": frozenset({"_reconstruct", "scalar"}),
    "numpy.random._pickle": frozenset(
        {"__generator_ctor", "__bit_generator_ctor", "__randomstate_ctor"}
    ),
    "numpy.random.bit_generator": frozenset({"__pyx_unpickle_SeedSequence", "SeedSequence"}),
    "numpy.random._pcg64": frozenset({"PCG64", "PCG64DXSM"}),
    "numpy.random._mt19937": frozenset({"MT19937"}),
    "numpy.random._philox": frozenset({"Philox"}),
    "numpy.random._sfc64": frozenset({"SFC64"}),
    "numpy.random._generator": frozenset({"Generator"}),
    "copyreg": frozenset({"_reconstructor"}),
    "collections": frozenset({"OrderedDict"}),
    "builtins": frozenset(
        "object set frozenset slice range complex bytearray tuple list dict int float bool str "
        "bytes".split()
    ),
}
"""What a pickled VecNormalize may reference: its class, its statistics, numpy arrays and
generators, and gymnasium spaces (every class in :mod:`gymnasium.spaces`)."""


class _VecNormalizeUnpickler(pickle.Unpickler):
    """An unpickler that builds only the types VecNormalize statistics are made of: anything
    else (a function to call, a foreign class) is refused before it is looked up."""

    def find_class(self, module: str, name: str) -> Any:
        allowed = _VECNORMALIZE_GLOBALS.get(module)
        if (allowed is not None and name in allowed) or (
            module.startswith("gymnasium.spaces.") and name[:1].isupper()
        ):
            found = super().find_class(module, name)
            if module.startswith("gymnasium.spaces."):
                from gymnasium import spaces

                if not (isinstance(found, type) and issubclass(found, spaces.Space)):
                    raise pickle.UnpicklingError(f"{module}.{name} is not a gymnasium space")
            return found
        raise pickle.UnpicklingError(
            f"it references {module}.{name}, which VecNormalize statistics never hold "
            "(refused before anything in it ran)"
        )


def load_vecnormalize_pickle(path: str | Path) -> Any:
    """Unpickle the VecNormalize statistics file ``path`` with :class:`_VecNormalizeUnpickler`:
    a file that references anything but VecNormalize's own types is refused before any of its
    code could run (a pickle can call any function it names).

    Raises:
        OSError: the file cannot be read.
        pickle.UnpicklingError, EOFError, ...: not a pickle of VecNormalize statistics.
    """
    with open(path, "rb") as fh:
        return _VecNormalizeUnpickler(fh).load()
