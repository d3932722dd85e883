"""Fuzzing the env options, reset options and actions of the single and the vector env: every
input either gets a ``ValueError`` whose message names the key (or ``action``), or
gives a few steps whose observations lie inside the observation space with finite rewards.

Values are drawn across and beyond each option's allowed range (:data:`debris_gym.config.OPTIONS`):
in range, whole floats for integer keys, fractions, ±inf, NaN, huge, negative, booleans,
strings, None, complex numbers, lists. Bounded examples, derandomised so that CI is repeatable;
sizes are kept small (few debris) so that an example takes milliseconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from debris_gym.config import OPTIONS, EnvConfig
from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.common import FIELD_KEYS
from debris_gym.envs.vector import DebrisFieldVectorEnv

FUZZ = settings(
    max_examples=120,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)

INT_KEYS = {k for k, v in EnvConfig.__dataclass_fields__.items() if str(v.type).startswith("int")}

SMALL_HIGH = {
    "n_targets": 4,
    "n_obstacles": 12,
    "obs_targets": 4,
    "obs_obstacles": 6,
    "lidar_rays": 16,
    "collision_substeps": 8,
    "field_size": 5e4,
}
"""In-range draws stop here (keeps each example fast); out-of-range draws go beyond the
option's real limit."""

BAD_VALUES = [
    math.inf, -math.inf, math.nan, 1e300, -1e300, 10**400, -1, -0.5, 0, 3.5,
    True, False, "3", "", None, 3 + 0j, [1.0], np.float32("nan"), np.int64(-7),
]  # fmt: skip


def in_range(key: str) -> st.SearchStrategy:
    opt = OPTIONS[key]
    if opt.choices is not None:
        return st.sampled_from(opt.choices)
    high = min(SMALL_HIGH.get(key, opt.high), opt.high)
    if key in INT_KEYS:
        whole = st.integers(int(opt.low), int(high))
        return st.one_of(whole, whole.map(float))  # 3.0 for an integer key is 3
    return st.floats(opt.low, high, allow_nan=False)


def beyond(key: str) -> st.SearchStrategy:
    opt = OPTIONS[key]
    edges = []
    if opt.choices is None:
        edges = [opt.low - 1.0, opt.low - 1e-9, opt.high * 2.0 + 1.0, opt.high + 1]
    return st.sampled_from(BAD_VALUES + edges)


def value_for(key: str) -> st.SearchStrategy:
    return st.one_of(in_range(key), in_range(key), beyond(key))


@st.composite
def env_options(draw) -> dict:
    keys = draw(st.lists(st.sampled_from(sorted(OPTIONS)), unique=True, max_size=4))
    kwargs = {key: draw(value_for(key)) for key in keys}
    if "n_obstacles" not in kwargs:
        kwargs["n_obstacles"] = draw(st.integers(0, 6))  # few debris: fast examples
    return kwargs


def assert_names_a_key(err: ValueError, kwargs: dict) -> None:
    """The message names an option the user passed (or, for a field the generator could not
    place, states so with the field options it depends on, one of which the user passed)."""
    text = str(err)
    if "could not place" in text:
        assert set(kwargs) & set(FIELD_KEYS), text
        return
    assert any(key in text for key in kwargs), text


def assert_finite_steps(env, obs, actions) -> None:
    space = env.observation_space
    assert space.contains(obs), obs
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        assert space.contains(obs), obs
        assert np.isfinite(reward).all(), reward
        assert np.isfinite(info["chaser_state"]).all()
        if np.any(terminated):
            break


def single_env(kwargs: dict) -> DebrisFieldEnv:
    return DebrisFieldEnv(**kwargs)


def vector_env(kwargs: dict) -> DebrisFieldVectorEnv:
    return DebrisFieldVectorEnv(num_envs=2, max_episode_steps=3, **kwargs)


@pytest.mark.parametrize("make", [single_env, vector_env])
@FUZZ
@given(kwargs=env_options(), seed=st.integers(0, 2**31 - 1))
def test_env_options_either_refused_by_name_or_finite(make, kwargs, seed):
    try:
        env = make(kwargs)
        obs, _ = env.reset(seed=seed)
    except ValueError as err:
        assert_names_a_key(err, kwargs)
        return
    env.action_space.seed(seed)
    assert_finite_steps(env, obs, [env.action_space.sample() for _ in range(4)])


# --- actions ---------------------------------------------------------------------------------

ODD_NUMBERS = st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, 0.0])
NUMBERS = st.one_of(st.floats(-2.0, 2.0), ODD_NUMBERS, st.integers(-3, 5))
DTYPES = st.sampled_from(
    [np.float64, np.float32, np.float16, np.int64, np.int8, np.uint8, np.bool_, np.complex128]
)


@st.composite
def arrays(draw, shapes) -> np.ndarray:
    dtype = np.dtype(draw(DTYPES))
    shape = draw(shapes)
    if dtype.kind == "b":
        elements = st.booleans()
    elif dtype.kind in "iu":
        info = np.iinfo(dtype)
        elements = st.integers(max(info.min, -3), min(info.max, 5))
    elif dtype.kind == "c":
        elements = st.complex_numbers(max_magnitude=2.0)
    else:
        elements = NUMBERS.map(lambda v, t=dtype.type: t(v))  # float16 overflows to inf
    with np.errstate(over="ignore"):
        return draw(hnp.arrays(dtype, shape, elements=elements))


def actions_for(shape: tuple[int, ...]) -> st.SearchStrategy:
    shapes = st.one_of(st.just(shape), hnp.array_shapes(min_dims=0, max_dims=3, max_side=4))
    return st.one_of(
        arrays(shapes),
        arrays(shapes).map(lambda a: a.tolist()),
        arrays(shapes).map(lambda a: np.ma.masked_array(a, mask=np.zeros(a.shape, bool))),
        NUMBERS,
        st.sampled_from([None, "0.5", "", b"1", [0.5, "a"], [[0.1], 0.2], object(), 1 + 2j]),
    )


@pytest.fixture(scope="module", params=["continuous", "discrete"])
def single_env(request):
    return DebrisFieldEnv(action=request.param, delta_v_budget=None)


@FUZZ
@given(data=st.data())
def test_single_env_actions_either_refused_by_name_or_finite(single_env, data):
    env = single_env
    obs, _ = env.reset(seed=data.draw(st.integers(0, 50)))
    shape = (2,) if env.config.action == "continuous" else ()
    action = data.draw(actions_for(shape))
    state = env.chaser_state
    try:
        obs, reward, _, _, _ = env.step(action)
    except ValueError as err:
        assert "action" in str(err)
        np.testing.assert_array_equal(env.chaser_state, state)  # nothing propagated
        return
    assert env.observation_space.contains(obs) and math.isfinite(reward)


@pytest.fixture(scope="module", params=["continuous", "discrete"])
def vector_env(request):
    return DebrisFieldVectorEnv(num_envs=2, action=request.param, delta_v_budget=None)


@FUZZ
@given(data=st.data())
def test_vector_env_actions_either_refused_by_name_or_finite(vector_env, data):
    env = vector_env
    obs, _ = env.reset(seed=data.draw(st.integers(0, 50)))
    shape = (2, 2) if env.config.action == "continuous" else (2,)
    action = data.draw(actions_for(shape))
    state = env.batch.missions.state.copy()
    try:
        obs, reward, _, _, _ = env.step(action)
    except ValueError as err:
        assert "action" in str(err)
        np.testing.assert_array_equal(env.batch.missions.state, state)
        return
    assert env.observation_space.contains(obs) and np.isfinite(reward).all()


# --- reset options ---------------------------------------------------------------------------

STATE_VALUES = st.one_of(
    st.floats(-600.0, 600.0), st.floats(-200.0, 200.0), ODD_NUMBERS, st.just(5e2), st.just(99.0)
)


@FUZZ
@given(
    state=st.one_of(
        hnp.arrays(
            np.float64, st.sampled_from([(4,), (2, 4), (3,), (1, 4)]), elements=STATE_VALUES
        ),
        st.sampled_from([None, "dock", [0, 0, 0, "x"], {"x": 1}, 3.0]),
    ),
    seed=st.integers(0, 50),
)
def test_reset_chaser_state_either_refused_by_name_or_finite(single_env, state, seed):
    env = single_env
    env.reset(seed=seed)
    before = env.chaser_state, env.elapsed
    try:
        obs, _ = env.reset(seed=seed + 1, options={"chaser_state": state})
    except ValueError as err:
        assert "chaser_state" in str(err)
        np.testing.assert_array_equal(env.chaser_state, before[0])
        assert env.elapsed == before[1]
        return
    actions = [env.action_space.sample() for _ in range(3)]
    assert_finite_steps(env, obs, actions)
