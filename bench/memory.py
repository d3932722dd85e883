"""Section ``memory``: bytes of state per sub-env of the native 2D vector env (20 debris).

Each instance is built in a fresh process (``python bench/run.py --memory-child N``, which runs
:func:`memory_child`), so that what one measurement allocates does not hide in the other's
heap. Reported: (a) the numpy arrays held by the env, its ``MissionBatch`` and its ``FieldBatch``
(bytes, the observation buffer apart), Python objects held per sub-env (deep
``sys.getsizeof``, bytes), and (b) the process RSS growth (bytes, ``/proc/self/statm``) of a
large instance minus that of a small one, per sub-env. Rows have section "memory".
"""

from __future__ import annotations

import dataclasses
import gc
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from bench.config import DEFAULT_OBSTACLES, ID_2D, THRUST

RUN_SCRIPT = Path(__file__).resolve().with_name("run.py")
"""The script a memory child runs (``--memory-child N``)."""
CHILD_TIMEOUT = 1800
"""Seconds a memory child may take before the row reports a timeout."""


def rss_bytes() -> int:
    """Resident set size of this process (``/proc/self/statm``, second field × page size)."""
    with open("/proc/self/statm", encoding="ascii") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def deep_size(root: Any) -> int:
    """Bytes of ``root`` and everything it references (containers, instance dicts, arrays).

    Objects shared between references are counted once; classes, modules and functions are not
    followed. Numpy arrays count their data (``sys.getsizeof`` includes it for owners).
    """
    skip = (type, type(sys), type(deep_size), type(len))
    seen: set[int] = set()
    stack = [root]
    total = 0
    while stack:
        obj = stack.pop()
        if id(obj) in seen or isinstance(obj, skip):
            continue
        seen.add(id(obj))
        total += sys.getsizeof(obj)
        if isinstance(obj, np.ndarray):
            if obj.base is not None:
                stack.append(obj.base)
        elif isinstance(obj, dict):
            stack.extend(obj.keys())
            stack.extend(obj.values())
        elif isinstance(obj, (list, tuple, set, frozenset)):
            stack.extend(obj)
        elif isinstance(obj, np.random.Generator):
            stack.append(obj.bit_generator)
        else:
            if hasattr(obj, "__dict__"):
                stack.append(vars(obj))
            for slot in getattr(type(obj), "__slots__", ()):
                if hasattr(obj, slot):
                    stack.append(getattr(obj, slot))
    return total


def memory_child(num_envs: int, env_id: str = ID_2D) -> dict[str, Any]:
    """Build and reset an ``num_envs`` native vector env here; report its memory.

    Meant to run in a fresh process (``python bench/run.py --memory-child N``): a 1-env instance
    is built, reset, stepped and dropped first, so that imports and one-off caches are not
    counted; then RSS is read before building, after ``reset(seed=0)`` and after 10 steps.
    """
    warm = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
    warm.reset(seed=0)
    warm.step(np.zeros((1, *warm.single_action_space.shape), dtype=np.float32))
    warm.close()
    del warm
    gc.collect()
    rss_before = rss_bytes()
    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    gc.collect()
    rss_reset = rss_bytes()
    rng = np.random.default_rng(0)
    shape = (num_envs, *env.single_action_space.shape)
    for _ in range(10):
        env.step(rng.uniform(-THRUST, THRUST, size=shape).astype(np.float32))
    gc.collect()
    rss_steps = rss_bytes()
    un = env.unwrapped
    # An inventory of what the env holds looks at every attribute of the env, its shell, the
    # shell's field supply (the fields drawn ahead), its batch and field, arrays inside named
    # structures included.
    arrays = []
    seen: set[int] = set()  # an array held by two attributes counts once
    shell = un.shell
    owners = [("env", un), ("shell", shell), ("supply", shell.supply)]
    owners += [("field", un.batch.field), ("batch", un.batch)]
    for owner, obj in owners:
        for name, value in _named_values(obj):
            if isinstance(value, np.ndarray) and id(value) not in seen:
                seen.add(id(value))
                arrays.append(_array_entry(owner, name, value, observation=False))
    # the env holds no observation buffer: each step returns a new (N, size) array
    observation = np.zeros(env.observation_space.shape, dtype=env.observation_space.dtype)
    arrays.append(_array_entry("env", "observation", observation, observation=True))
    arrays.sort(key=lambda a: a["nbytes"], reverse=True)
    return {
        "num_envs": num_envs,
        "env_id": env_id,
        "n_bodies": int(un.batch.field.n_bodies),
        "rss_before": rss_before,
        "rss_after_reset": rss_reset,
        "rss_after_steps": rss_steps,
        "arrays": arrays,
        "python_bytes": {
            "scenarios": deep_size(list(un.scenarios)),
            "rngs": deep_size(list(shell.supply.generators)),
        },
    }


def _array_entry(owner: str, name: str, value: np.ndarray, *, observation: bool) -> dict:
    return {
        "owner": owner,
        "name": name,
        "shape": list(value.shape),
        "dtype": str(value.dtype),
        "nbytes": int(value.nbytes),
        "observation_buffer": observation,
    }


def _named_values(obj: Any) -> list[tuple[str, Any]]:
    """``obj``'s attributes as (name, value), then the fields of its named-tuple and dataclass
    attributes spelled ``attribute.field`` (the compiled core keeps some arrays only in such
    structures; the field supply keeps the fields drawn ahead in a dataclass)."""
    plain = [(name, value) for name, value in vars(obj).items() if not _is_record(value)]
    nested = [
        (f"{name}.{field}", v)
        for name, value in vars(obj).items()
        if _is_record(value)
        for field, v in _record_items(value)
    ]
    return plain + nested


def _is_record(value: Any) -> bool:
    named_tuple = isinstance(value, tuple) and hasattr(value, "_fields")
    return named_tuple or (dataclasses.is_dataclass(value) and not isinstance(value, type))


def _record_items(value: Any) -> list[tuple[str, Any]]:
    if isinstance(value, tuple):
        return list(zip(value._fields, value))
    return [(f.name, getattr(value, f.name)) for f in dataclasses.fields(value)]


def _memory_child_run(num_envs: int) -> dict[str, Any]:
    """Run :func:`memory_child` in a fresh process; its report is the last line of stdout."""
    cmd = [sys.executable, str(RUN_SCRIPT), "--memory-child", str(num_envs)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=CHILD_TIMEOUT, check=False)
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        raise RuntimeError(f"memory child N={num_envs} exited {done.returncode}: {tail[0]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def run_memory(cfg: dict[str, Any]) -> dict[str, Any]:
    """Run the section: bytes of state per sub-env of the native 2D vector env (20 debris).

    Args:
        cfg: sizes (:data:`bench.config.QUICK` or alike): ``memory_envs``, the (small, large) N.

    Fields: ``small_envs`` / ``large_envs`` (the two instance sizes, each built in a fresh
    process), ``rss_growth`` (N → bytes of RSS growth on build + reset), ``rss_per_env``
    ((growth at large N − growth at small N) / (large − small)), ``rss_steps_per_env`` (the same
    after 10 more steps), ``array_bytes_per_env`` (numpy arrays of the env, its MissionBatch and
    FieldBatch at the large N, observation buffers excluded, / N), ``obs_buffer_bytes_per_env``,
    ``arrays`` (the large instance's arrays, biggest first), ``python_bytes_per_env`` (deep size
    of the ``scenarios`` and per-sub-env generators, / N) and ``error``.
    """
    small, large = (int(n) for n in cfg["memory_envs"])
    row: dict[str, Any] = {
        "section": "memory",
        "env_id": ID_2D,
        "variant": "",
        "level": "native",
        "n_obstacles": DEFAULT_OBSTACLES,
        "small_envs": small,
        "large_envs": large,
        "rss_growth": {},
        "rss_per_env": math.nan,
        "rss_steps_per_env": math.nan,
        "array_bytes_per_env": math.nan,
        "obs_buffer_bytes_per_env": math.nan,
        "arrays": [],
        "python_bytes_per_env": {},
        "n_bodies": None,
        "error": None,
    }
    try:
        children = {n: _memory_child_run(n) for n in (small, large)}
    except (OSError, RuntimeError, ValueError, subprocess.TimeoutExpired) as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    grow = {n: c["rss_after_reset"] - c["rss_before"] for n, c in children.items()}
    grow_steps = {n: c["rss_after_steps"] - c["rss_before"] for n, c in children.items()}
    big = children[large]
    arrays = sorted(big["arrays"], key=lambda a: -a["nbytes"])
    state = sum(a["nbytes"] for a in arrays if not a["observation_buffer"])
    obs = sum(a["nbytes"] for a in arrays if a["observation_buffer"])
    row.update(
        rss_growth=grow,
        rss_steps_growth=grow_steps,
        rss_per_env=(grow[large] - grow[small]) / (large - small),
        rss_steps_per_env=(grow_steps[large] - grow_steps[small]) / (large - small),
        array_bytes_per_env=state / large,
        obs_buffer_bytes_per_env=obs / large,
        arrays=arrays,
        python_bytes_per_env={k: v / large for k, v in big["python_bytes"].items()},
        n_bodies=big["n_bodies"],
    )
    return row
