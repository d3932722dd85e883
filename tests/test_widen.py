"""Widening a fine-tune's initial policy to an observation with more elements
(agents.experiments.training.widen): the columns matched by name, the zero-weight input layer,
the statistics of the new elements."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("stable_baselines3")

import torch
from stable_baselines3.common.running_mean_std import RunningMeanStd

from agents.experiments.training.widen import (
    observation_columns,
    widen_running_stats,
    widen_state_dict,
)

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@st.composite
def widened_names(draw):
    """(init names, wider names): new names inserted anywhere among the init's."""
    init = [f"e{i}" for i in range(draw(st.integers(0, 12)))]
    wide = list(init)
    for j in range(draw(st.integers(1, 6))):
        wide.insert(draw(st.integers(0, len(wide))), f"new{j}")
    return init, wide


@settings(max_examples=200, deadline=None)
@given(widened_names())
def test_columns_place_every_init_element_where_its_name_is(names):
    init, wide = names
    columns = observation_columns(init, wide)
    assert [wide[c] for c in columns] == init
    assert np.all(np.diff(columns) > 0)


@settings(max_examples=100, deadline=None)
@given(widened_names(), st.data())
def test_a_removed_element_is_refused_by_name(names, data):
    init, wide = names
    if not init:
        return
    gone = data.draw(st.sampled_from(init))
    with pytest.raises(ValueError, match=rf"does not give: {gone} \(.*only add elements"):
        observation_columns(init, [n for n in wide if n != gone])


def test_reordered_elements_are_refused_naming_them():
    with pytest.raises(ValueError, match=r"orders .* differently: b after a no longer holds"):
        observation_columns(["a", "b", "c"], ["b", "new", "a", "c"])
    assert observation_columns(["a", "b"], ["a", "b"]).tolist() == [0, 1]


def _mlp(n_in: int, seed: int) -> torch.nn.Sequential:
    torch.manual_seed(seed)
    return torch.nn.Sequential(
        torch.nn.Linear(n_in, 32), torch.nn.Tanh(), torch.nn.Linear(32, 32), torch.nn.Tanh(),
        torch.nn.Linear(32, 2),
    )  # fmt: skip


@pytest.mark.parametrize("n_new", [1, 3])
def test_the_widened_network_computes_what_the_init_did_whatever_the_new_inputs(n_new):
    """Bit for bit on a batch (a matrix product: the zero columns add exact zeros in the same
    order), whatever values the new elements hold; every other tensor is copied unchanged."""
    init_names = [f"e{i}" for i in range(10)]
    wide_names = init_names[:4] + [f"new{j}" for j in range(n_new)] + init_names[4:]
    columns = observation_columns(init_names, wide_names)
    init, wide = _mlp(10, 0), _mlp(10 + n_new, 1)
    wide.load_state_dict(widen_state_dict(init.state_dict(), wide.state_dict(), columns))
    rng = np.random.default_rng(0)
    x = torch.as_tensor(rng.normal(size=(64, 10)), dtype=torch.float32)
    x_wide = torch.as_tensor(rng.normal(scale=5.0, size=(64, 10 + n_new)), dtype=torch.float32)
    x_wide[:, torch.as_tensor(columns)] = x
    with torch.no_grad():
        assert torch.equal(wide(x_wide), init(x))
    new = [i for i in range(10 + n_new) if i not in set(columns.tolist())]
    assert torch.count_nonzero(wide[0].weight[:, new]) == 0
    for name in ("0.bias", "2.weight", "2.bias", "4.weight", "4.bias"):
        assert torch.equal(wide.state_dict()[name], init.state_dict()[name])


def test_networks_that_differ_elsewhere_are_refused_naming_the_tensor():
    columns = np.arange(10)
    init, other = _mlp(10, 0), _mlp(11, 0)
    state = other.state_dict()
    state["2.weight"] = torch.zeros(16, 32)
    with pytest.raises(ValueError, match=r"2.weight has shape \(32, 32\).*\(16, 32\)"):
        widen_state_dict(init.state_dict(), state, columns)
    with pytest.raises(ValueError, match="other parameters"):
        extra = {**other.state_dict(), "extra": torch.zeros(1)}
        widen_state_dict(init.state_dict(), extra, columns)


def test_new_elements_get_mean_0_and_variance_1_the_others_keep_theirs():
    stats = RunningMeanStd(shape=(3,))
    stats.mean, stats.var, stats.count = np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0]), 77.0
    columns = np.array([0, 2, 4])
    wide = widen_running_stats(stats, columns, 5)
    assert wide.mean.tolist() == [1.0, 0.0, 2.0, 0.0, 3.0]
    assert wide.var.tolist() == [4.0, 1.0, 5.0, 1.0, 6.0]
    assert wide.count == 77.0
    assert stats.mean.tolist() == [1.0, 2.0, 3.0]  # the init's statistics are left as they were
    with pytest.raises(ValueError, match=r"shape \(3,\) do not fit .* 2 observation elements"):
        widen_running_stats(stats, np.array([0, 1]), 5)
    with pytest.raises(ValueError, match="do not fit 4 elements"):
        widen_running_stats(stats, columns, 4)
