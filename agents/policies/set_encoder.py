"""A permutation-invariant encoder of the observation's body slots (Deep Sets), for SB3 policies.

The flat observation lists the nearest obstacles (and, without ``obs_targets: 1``, several
targets) in slots of identical layout, sorted by distance. An MLP over the flat vector must learn
the same obstacle response once per slot; a set encoder applies one small network ``phi`` to every
slot of a kind and pools the results with a mean and a max, so the features do not depend on the
slots' order and every slot trains the same weights [Zaheer17]. The remaining elements (the
chaser's state, the dock, the goal, the budget and the clock) pass through unchanged.

The slot layout is read from the env's ``observation_names()``: a name ``KIND{k}_FEATURE``
(``obstacle3_rel_vel_x``, ``target0_captured``) belongs to slot ``k`` of kind ``KIND``, wherever
it sits in the vector (a moving field lists the obstacles' velocities in a block of their own).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

__all__ = ["SLOT_KINDS", "SlotLayout", "SlotSetExtractor", "slot_layout"]

SLOT_KINDS = ("target", "obstacle")
"""The kinds of body slots the encoder pools; every other element is context."""

_SLOT_NAME = re.compile(r"^(?P<kind>[a-z]+)(?P<index>\d+)_(?P<feature>.+)$")

SlotLayout = tuple[list[int], dict[str, list[list[int]]]]
"""``(context indices, {kind: [slot 0's indices, slot 1's, ...]})``."""


def slot_layout(names: Sequence[str]) -> SlotLayout:
    """Split observation element names into context elements and slots per kind.

    Every slot of one kind lists its features in the same order (that of slot 0), so one
    network reads them all.

    Raises:
        ValueError: two slots of a kind with different features (the names do not describe a
            set), or no slot at all (nothing to pool: use the plain MLP).
    """
    context: list[int] = []
    slots: dict[str, dict[int, dict[str, int]]] = {}
    for i, name in enumerate(names):
        match = _SLOT_NAME.match(name)
        if match is None or match["kind"] not in SLOT_KINDS:
            context.append(i)
            continue
        features = slots.setdefault(match["kind"], {}).setdefault(int(match["index"]), {})
        features[match["feature"]] = i
    if not slots:
        raise ValueError(
            f"no body slots ({', '.join(k + '{k}_...' for k in SLOT_KINDS)}) among the "
            f"observation names; a set encoder has nothing to pool"
        )
    layout: dict[str, list[list[int]]] = {}
    for kind, by_index in slots.items():
        order = list(by_index[min(by_index)])
        rows = []
        for index in sorted(by_index):
            if sorted(by_index[index]) != sorted(order):
                raise ValueError(
                    f"{kind} slot {index} has features {sorted(by_index[index])}, slot "
                    f"{min(by_index)} has {sorted(order)}: slots of a kind must match"
                )
            rows.append([by_index[index][feature] for feature in order])
        layout[kind] = rows
    return context, layout


class SlotSetExtractor(BaseFeaturesExtractor):
    """Features = context elements ‖ per slot kind: mean and max over slots of ``phi_kind(slot)``.

    Args:
        observation_space: the flat ``Box`` observation space.
        context: indices of the elements passed through.
        slots: per kind, the indices of each slot's features (see :func:`slot_layout`).
        embed_dim: output size of each ``phi`` (so each kind adds ``2 * embed_dim`` features).
        hidden_dim: width of ``phi``'s hidden layer.
    """

    context_index: torch.Tensor  # a registered buffer (so it follows the module's device)

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        context: list[int],
        slots: dict[str, list[list[int]]],
        embed_dim: int = 64,
        hidden_dim: int = 64,
    ) -> None:
        if embed_dim < 1 or hidden_dim < 1:
            raise ValueError(
                f"embed_dim and hidden_dim must be >= 1, got {embed_dim}, {hidden_dim}"
            )
        size = int(observation_space.shape[0])
        used = list(context) + [i for rows in slots.values() for row in rows for i in row]
        if sorted(used) != list(range(size)):
            raise ValueError(
                f"the layout must use each of the {size} observation elements exactly once"
            )
        super().__init__(observation_space, len(context) + 2 * embed_dim * len(slots))
        self.kinds = sorted(slots)
        self.register_buffer("context_index", torch.as_tensor(context, dtype=torch.long))
        for kind in self.kinds:
            self.register_buffer(f"{kind}_index", torch.as_tensor(slots[kind], dtype=torch.long))
        self.phi = nn.ModuleDict(
            {
                kind: nn.Sequential(
                    nn.Linear(len(slots[kind][0]), hidden_dim),
                    nn.Tanh(),
                    nn.Linear(hidden_dim, embed_dim),
                    nn.Tanh(),
                )
                for kind in self.kinds
            }
        )

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        parts = [observations[:, self.context_index]]
        for kind in self.kinds:
            index = getattr(self, f"{kind}_index")  # (slots, features)
            embedded = self.phi[kind](observations[:, index])  # (batch, slots, embed)
            parts += [embedded.mean(dim=1), embedded.amax(dim=1)]
        return torch.cat(parts, dim=1)
