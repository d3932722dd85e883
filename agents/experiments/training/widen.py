"""Widening an initial policy to an observation with more elements (fine-tuning, ``--init``).

A fine-tune run may observe elements its initial policy never saw (a new observation block, e.g.
``obs_hold``'s ``target{k}_hold``), as long as every element the initial policy reads is still
there, under the same name and in the same order. The elements are matched by name
(:func:`debris_gym.observation.observation_names`): :func:`observation_columns` gives the
position of each of the initial policy's elements in the wider observation. Then

* :func:`widen_state_dict` gives every input layer of the network (a weight matrix whose input
  size is the observation's) zero weights for the new columns, so the widened policy and value
  function compute exactly what the initial ones did, whatever the new elements hold;
* :func:`widen_running_stats` gives the new columns mean 0 and variance 1 in the frozen
  observation statistics (the new elements enter the network about as they are, which is the
  scale the observation is normalised to).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["observation_columns", "widen_running_stats", "widen_state_dict"]


def observation_columns(init_names: Sequence[str], names: Sequence[str]) -> np.ndarray:
    """Position in ``names`` of each element of ``init_names`` (an int array, increasing).

    Args:
        init_names: the observation element names the initial policy was trained on.
        names: the element names of the observation it is to read now.

    Raises:
        ValueError: an element of ``init_names`` is missing from ``names``, or their order
            differs (the message names the elements).
    """
    position = {name: i for i, name in enumerate(names)}
    missing = [name for name in init_names if name not in position]
    if missing:
        raise ValueError(
            f"the initial policy reads observation elements this env does not give: "
            f"{', '.join(missing)} (a fine-tune may only add elements, not remove them)"
        )
    columns = np.array([position[name] for name in init_names], dtype=np.int64)
    moved = [
        f"{init_names[i + 1]} after {init_names[i]}"
        for i in range(len(columns) - 1)
        if columns[i + 1] <= columns[i]
    ]
    if moved:
        raise ValueError(
            "this env orders the initial policy's observation elements differently: "
            f"{'; '.join(moved)} no longer holds (a fine-tune may only add elements, not "
            "reorder them)"
        )
    return columns


def widen_state_dict(
    init_state: Mapping[str, Any], target_state: Mapping[str, Any], columns: np.ndarray
) -> dict[str, Any]:
    """``init_state`` (a torch ``state_dict`` of a network reading ``len(columns)`` inputs) in the
    shape of ``target_state`` (the same network reading the wider observation).

    Every tensor of the same shape in both is taken as it is. A weight matrix whose input size
    is the initial observation's where the target's is the wider one's (the first layer of the
    actor and of the critic) gets the initial weights in ``columns`` and zeros elsewhere, so for
    any values of the new elements the widened layer's output equals the initial one's.

    Raises:
        ValueError: the two networks differ in anything else (the message names the tensor).
    """
    import torch as th

    if set(init_state) != set(target_state):
        raise ValueError(
            "the initial policy's network has other parameters than the fine-tune's: "
            f"{sorted(set(init_state) ^ set(target_state))}"
        )
    width = len(columns)
    widened: dict[str, Any] = {}
    for name, target in target_state.items():
        source = init_state[name]
        if tuple(source.shape) == tuple(target.shape):
            widened[name] = source.clone()
            continue
        if (
            source.dim() == 2
            and target.dim() == 2
            and source.shape[0] == target.shape[0]
            and source.shape[1] == width
            and target.shape[1] > width
        ):
            weight = th.zeros_like(target)
            weight[:, th.as_tensor(columns)] = source.to(weight.dtype)
            widened[name] = weight
            continue
        raise ValueError(
            f"the initial policy's {name} has shape {tuple(source.shape)}, the fine-tune's "
            f"{tuple(target.shape)}: only the input columns of an observation layer may differ"
        )
    return widened


def widen_running_stats(stats: Any, columns: np.ndarray, size: int) -> Any:
    """A copy of SB3 ``RunningMeanStd`` ``stats`` (of ``len(columns)`` elements) for an
    observation of ``size`` elements: the initial means and variances in ``columns``, mean 0
    and variance 1 elsewhere; the count is kept.

    Raises:
        ValueError: ``stats`` is not of ``len(columns)`` elements, or ``columns`` do not fit
            ``size``.
    """
    mean = np.asarray(stats.mean, dtype=np.float64)
    if mean.shape != (len(columns),):
        raise ValueError(
            f"observation statistics of shape {mean.shape} do not fit the initial policy's "
            f"{len(columns)} observation elements"
        )
    if len(columns) and (columns.min() < 0 or columns.max() >= size):
        raise ValueError(f"observation columns {columns.tolist()} do not fit {size} elements")
    wide = stats.copy()
    wide.mean = np.zeros(size, dtype=np.float64)
    wide.var = np.ones(size, dtype=np.float64)
    wide.mean[columns] = mean
    wide.var[columns] = np.asarray(stats.var, dtype=np.float64)
    return wide
