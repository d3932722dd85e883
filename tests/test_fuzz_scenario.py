"""Fuzzing pinned scenarios: every mutated scenario dict is either refused with a ValueError that
names the offending key, or flies: observations inside the observation space, finite rewards.

Each example starts from a valid generated field (2D with polygons, or 3D) in its ``to_dict()``
form and applies one mutation: a key dropped, a value of the wrong type, NaN / ±inf in a number,
bodies moved onto each other, out of the bounds or onto the dock, the dock moved onto a body or out
of the bounds, a bad polygon, tiny or huge bounds, or bad physics. The field is pinned with
``env.reset(options={"scenario": d})`` on the registered env and flown for a few steps.
"""

from __future__ import annotations

import copy
import json
import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401 - registers the IDs
from debris_gym.envs.common import PHYSICS_DIFFER, field_spec
from debris_gym.generators import random_field
from debris_gym.scenario import Scenario
from tests.helpers import flies_old_ids

ENV_IDS = {2: "DebrisGym/Rendezvous2D-v0", 3: "DebrisGym/Rendezvous3D-v0"}
STEPS = 3
FUZZ = settings(
    max_examples=120,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

Path = tuple[Any, ...]


def _base(dim: int) -> dict[str, Any]:
    """A valid field of the env's own kind, with the env's physics, as a plain dict."""
    with warnings.catch_warnings():  # at import: the v0 ID on purpose (see flies_old_ids)
        warnings.filterwarnings("ignore", ".*is out of date", DeprecationWarning)
        env = gym.make(ENV_IDS[dim])
    cfg = env.unwrapped.config
    scen = random_field(
        np.random.default_rng(7), field_spec(cfg), mean_motion=cfg.n, dt=cfg.dt,
        max_accel=cfg.max_accel, capture_radius=cfg.capture_radius,
    )  # fmt: skip
    env.close()
    return json.loads(json.dumps(scen.to_dict()))


BASES = {dim: _base(dim) for dim in (2, 3)}
ENVS: dict[int, gym.Env] = {}


def _env(dim: int) -> gym.Env:
    if dim not in ENVS:
        ENVS[dim] = gym.make(ENV_IDS[dim])
        # gymnasium's PassiveEnvChecker fails the first step() with a TypeError if the first
        # reset() after make raised: start from a reset that succeeds, as a user would
        ENVS[dim].reset(seed=0)
    return ENVS[dim]


# --- paths into the dict --------------------------------------------------------------------------


def _name(path: Path) -> str:
    """``("targets", 2, "radius")`` -> ``"targets[2].radius"``, the form errors name keys in."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else part)
    return out


def _body_level(path: Path) -> str:
    """The name of the body a path lies in (``"obstacles[3]"``), or of its top-level key."""
    if path[0] in ("targets", "obstacles") and len(path) >= 2:
        return _name(path[:2])
    return _name(path[:1])


def _nodes(value: Any, path: Path = ()) -> list[Path]:
    """Every path in the dict (containers and leaves), the root excluded."""
    out = [path] if path else []
    if isinstance(value, dict):
        for key, item in value.items():
            out += _nodes(item, (*path, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            out += _nodes(item, (*path, index))
    return out


def _get(data: Any, path: Path) -> Any:
    for part in path:
        data = data[part]
    return data


def _set(data: Any, path: Path, value: Any) -> None:
    _get(data, path[:-1])[path[-1]] = value


# --- mutations: each returns the name an error must contain ---------------------------------------


def drop(data: dict, draw) -> str:
    path = draw(st.sampled_from(_nodes(data)))
    parent = _get(data, path[:-1])
    del parent[path[-1]]
    if isinstance(path[-1], str):  # a key: the message names it
        return _name(path)
    return _body_level(path)  # an element of a list: the list's body, or the top-level key


WRONG = st.sampled_from(["x", "5", None, True, [], {}, [1.0], {"a": 1}])


def wrong_type(data: dict, draw) -> str:
    path = draw(st.sampled_from(_nodes(data)))
    _set(data, path, draw(WRONG))
    return _body_level(path) if path[-1] == "vertices" else _name(path)


def non_finite(data: dict, draw) -> str:
    leaves = [p for p in _nodes(data) if isinstance(_get(data, p), (int, float))]
    leaves = [p for p in leaves if not isinstance(_get(data, p), bool)]
    path = draw(st.sampled_from(leaves))
    _set(data, path, draw(st.sampled_from([math.nan, math.inf, -math.inf])))
    return _name(path)


def _body(data: dict, draw) -> tuple[str, int]:
    kinds = [k for k in ("targets", "obstacles") if data[k]]
    kind = draw(st.sampled_from(kinds))
    return kind, draw(st.integers(0, len(data[kind]) - 1))


def body_onto_body(data: dict, draw) -> str:
    kind, i = _body(data, draw)
    other_kind, j = _body(data, draw)
    if (kind, i) == (other_kind, j):
        return f"{kind}[{i}]"  # unchanged: it must fly
    data[kind][i]["position"] = list(data[other_kind][j]["position"])
    return f"{kind}[{i}]"


def body_out_of_bounds(data: dict, draw) -> str:
    kind, i = _body(data, draw)
    axis = draw(st.integers(0, data["dim"] - 1))
    side = draw(st.sampled_from([0, 1]))
    overshoot = draw(st.floats(-0.99, 1e6))  # negative: the body only pokes out
    radius = data[kind][i]["radius"]
    edge = data["bounds"][axis][side]
    data[kind][i]["position"][axis] = edge + (1 if side else -1) * overshoot * radius
    return f"{kind}[{i}]"


def body_onto_dock(data: dict, draw) -> str:
    kind, i = _body(data, draw)
    data[kind][i]["position"] = list(data["dock"])
    return f"{kind}[{i}]"


def dock_onto_body(data: dict, draw) -> str:
    kind, i = _body(data, draw)
    data["dock"] = list(data[kind][i]["position"])
    return "dock"


def dock_out_of_bounds(data: dict, draw) -> str:
    axis = draw(st.integers(0, data["dim"] - 1))
    data["dock"][axis] = data["bounds"][axis][draw(st.sampled_from([0, 1]))] * draw(
        st.floats(1.0, 1e9)
    )
    return "dock"


STAR = [[math.cos(4 * math.pi * k / 5), math.sin(4 * math.pi * k / 5)] for k in range(5)]


def bad_polygon(data: dict, draw) -> str:
    polygons = [i for i, b in enumerate(data["obstacles"]) if "vertices" in b]
    if not polygons:  # 3D: a polygon where none is allowed
        kind, i = _body(data, draw)
        data[kind][i]["vertices"] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]
        return f"{kind}[{i}]"
    i = draw(st.sampled_from(polygons))
    body = data["obstacles"][i]
    how = draw(st.sampled_from(["star", "reversed", "two", "repeat", "collinear", "radius"]))
    vertices = body["vertices"]
    if how == "star":
        body["vertices"] = [[body["radius"] * x, body["radius"] * y] for x, y in STAR]
    elif how == "reversed":
        body["vertices"] = vertices[::-1]
    elif how == "two":
        body["vertices"] = vertices[:2]
    elif how == "repeat":
        body["vertices"] = [vertices[0], *vertices]
    elif how == "collinear":
        middle = [(a + b) / 2.0 for a, b in zip(vertices[0], vertices[1])]
        body["vertices"] = [vertices[0], middle, *vertices[1:]]
    else:
        body["radius"] *= draw(st.sampled_from([0.5, 0.999, 1.001, 3.0]))
    return f"obstacles[{i}]"


def resize_bounds(data: dict, draw) -> str:
    half = draw(st.floats(1e-3, 1e8))
    axes = draw(st.sampled_from(["all", "one"]))
    for axis in range(data["dim"]) if axes == "all" else [draw(st.integers(0, data["dim"] - 1))]:
        data["bounds"][axis] = [-half, half]
    return "bounds"  # too small or too large, or a body or the dock left outside them


def scale_world(data: dict, draw) -> str:
    """The whole field scaled: a small or a huge world that is still valid, or one too large."""
    factor = draw(st.floats(0.03, 2000.0))
    data["bounds"] = [[factor * lo, factor * hi] for lo, hi in data["bounds"]]
    data["dock"] = [factor * x for x in data["dock"]]
    for body in data["targets"] + data["obstacles"]:
        body["position"] = [factor * x for x in body["position"]]
        body["radius"] *= factor
        if "vertices" in body:
            body["vertices"] = [[factor * x, factor * y] for x, y in body["vertices"]]
    return "bounds"


def jitter(data: dict, draw) -> str:
    """A body moved a little: it may stay valid, or meet a neighbour, the dock or the bounds."""
    kind, i = _body(data, draw)
    position = data[kind][i]["position"]
    reach = draw(st.floats(0.0, 200.0))
    for axis in range(len(position)):
        position[axis] += draw(st.floats(-reach, reach))
    return f"{kind}[{i}]"


def physics(data: dict, draw) -> str:
    key = draw(st.sampled_from(["dt", "mean_motion", "max_accel"]))
    data[key] = draw(
        st.one_of(
            st.floats(-1e3, 1e3, allow_nan=False),
            st.sampled_from([0.0, 1e-9, 1e-3, 600.0, 601.0, 100.0, 1e-2, 1e6, 1e300, -1e-12]),
        )
    )
    return key


def extra_key(data: dict, draw) -> str:
    nodes = [p for p in _nodes(data) if isinstance(_get(data, p), dict)]
    target = draw(st.sampled_from([(), *nodes]))
    key = draw(st.sampled_from(["colour", "radious", "velocity_", "t"]))
    _get(data, target)[key] = 1.0
    return key


MUTATIONS = [
    drop,
    wrong_type,
    non_finite,
    body_onto_body,
    body_out_of_bounds,
    body_onto_dock,
    dock_onto_body,
    dock_out_of_bounds,
    bad_polygon,
    resize_bounds,
    scale_world,
    jitter,
    physics,
    extra_key,
]


# --- the property ---------------------------------------------------------------------------------


def _refused_or_flies(dim: int, data: dict, key: str) -> str:
    """The property: a ValueError naming ``key``, or a short episode that stays in the space.

    Returns which of the two happened ("refused" / "flew")."""
    env = _env(dim)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=PHYSICS_DIFFER)
        try:
            obs, _ = env.reset(seed=0, options={"scenario": data})
        except ValueError as exc:
            assert key in str(exc), f"{key!r} not named in: {exc}"
            return "refused"
    space = env.observation_space
    assert space.contains(obs), obs
    rng = np.random.default_rng(0)
    for _ in range(STEPS):
        action = rng.uniform(-1.0, 1.0, dim).astype(np.float32)
        obs, reward, terminated, truncated, _ = env.step(action)
        assert space.contains(obs), obs
        assert math.isfinite(reward)
        if terminated or truncated:
            break
    return "flew"


@flies_old_ids
@pytest.mark.parametrize("dim", [2, 3])
@FUZZ
@given(data=st.data())
def test_mutated_scenarios_are_refused_by_key_or_fly(dim, data):
    scenario = copy.deepcopy(BASES[dim])
    mutate = data.draw(st.sampled_from(MUTATIONS), label="mutation")
    key = mutate(scenario, data.draw)
    event(f"{mutate.__name__}: {_refused_or_flies(dim, scenario, key)}")


@pytest.mark.parametrize("dim", [2, 3])
def test_the_unmutated_bases_fly(dim):
    """The fuzz starts from scenarios that pass (else every refusal above would be vacuous)."""
    assert _refused_or_flies(dim, copy.deepcopy(BASES[dim]), key="(no error expected)") == "flew"
    assert Scenario.from_dict(BASES[dim]).to_dict() == BASES[dim]


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(cut=st.floats(0.0, 1.0, exclude_max=True), junk=st.sampled_from(["", "}", ",", "x", "\x00"]))
def test_a_damaged_scenario_file_is_refused_naming_the_file_and_line(tmp_path, cut, junk):
    text = json.dumps(BASES[2], indent=1)
    damaged = text[: int(cut * len(text))] + junk
    try:
        json.loads(damaged)
    except ValueError:
        pass
    else:
        assume(False)  # the cut happened to leave valid JSON (e.g. only the last brace, put back)
    path = tmp_path / "damaged.json"
    path.write_text(damaged)
    with pytest.raises(ValueError, match=r"damaged\.json.*line \d+, column \d+"):
        Scenario.load(path)
