"""Scenario files and dicts a user or a hostile file hands over are refused early and by name:
body counts before any body is built, huge files before they are read whole, numbers too long
for Python and keys that are not strings naming the file and the key, a directory naming it."""

from __future__ import annotations

import json
import tracemalloc

import pytest

from debris_gym.scenario import MAX_FILE_BYTES, MAX_OBJECTS, Scenario, as_scenario
from debris_gym.scenario_values import MAX_VERTICES
from tests.helpers import simple_scenario


def base() -> dict:
    return simple_scenario().to_dict()


def write(tmp_path, text: str, name: str = "s.json"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_a_file_of_many_bodies_is_refused_while_parsed_in_little_memory(tmp_path):
    body = '{"position": [100.0, 200.0], "radius": 1.5}'
    count = 200_000
    data = base()
    text = json.dumps({**data, "obstacles": []}).replace(
        '"obstacles": []', '"obstacles": [' + ",".join([body] * count) + "]"
    )
    path = write(tmp_path, text)
    size = path.stat().st_size
    tracemalloc.start()
    try:
        with pytest.raises(ValueError) as err:
            Scenario.load(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(err.value)
    assert str(path) in message and "obstacles" in message and "[0, 2000]" in message
    assert f"more than {MAX_OBJECTS - 1} bodies" in message
    # the file's bytes and text, not 200 000 dicts of Python objects (tens of times more)
    assert peak < 3 * size + 10 * 2**20, (peak, size)


def test_a_file_larger_than_any_scenario_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.json"
    with open(path, "wb") as fh:
        fh.truncate(MAX_FILE_BYTES + 1)  # sparse: no disk, and nothing to read if it were read
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"huge\.json.*larger than 64 MiB"):
            Scenario.load(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2**20


def test_body_counts_are_checked_before_any_body_is_built():
    data = base()
    good = data["targets"][0]
    targets = [dict(good) for _ in range(30)]
    targets[25]["radius"] = "not a number"  # built one by one, this body would be named first
    with pytest.raises(ValueError, match=r"targets has 30 bodies; allowed: \[1, 20\]"):
        Scenario.from_dict({**data, "targets": targets})
    with pytest.raises(ValueError, match=r"obstacles has 2001 bodies; allowed: \[0, 2000\]"):
        Scenario.from_dict({**data, "obstacles": [{"bad": 1}] * 2001})


@pytest.mark.parametrize("digits", [400, 5000])
def test_a_number_too_long_names_the_file_and_the_key(tmp_path, digits):
    data = base()
    text = json.dumps(data)
    radius = json.dumps(data["targets"][0]["radius"])
    text = text.replace(f'"radius": {radius}', '"radius": 1' + "0" * (digits - 1), 1)
    path = write(tmp_path, text)
    with pytest.raises(ValueError) as err:
        Scenario.load(path)
    message = str(err.value)
    assert str(path) in message and "targets[0].radius must be finite" in message
    assert len(message) < 400  # the number is named, not printed


def test_a_huge_integer_in_a_dict_is_named_not_printed():
    with pytest.raises(ValueError, match=r"mean_motion must be finite, got an integer of about"):
        Scenario.from_dict({**base(), "mean_motion": 10**5000})


@pytest.mark.parametrize(
    ("where", "expected"),
    [("scenario", r"scenario has a key 7 of type int"), ("body", r"targets\[0\] has a key")],
)
def test_keys_that_are_not_strings_are_named(where, expected):
    data = base()
    if where == "scenario":
        data[7] = "x"
    else:
        data["targets"][0][("a", "tuple")] = 1
    with pytest.raises(ValueError, match=expected):
        Scenario.from_dict(data)


def test_a_key_twice_in_a_file_is_refused_naming_it(tmp_path):
    text = json.dumps(base()).replace('"radius":', '"radius": 4.0, "radius":', 1)
    with pytest.raises(ValueError, match=r"s\.json.*key 'radius' twice"):
        Scenario.load(write(tmp_path, text))


def test_a_directory_is_refused_naming_it(tmp_path):
    folder = tmp_path / "fields"
    folder.mkdir()
    with pytest.raises(ValueError, match=r"fields.* is a directory"):
        Scenario.load(folder)
    with pytest.raises(ValueError, match=r"is a directory"):
        as_scenario(str(folder))


def test_a_polygon_with_too_many_vertices_is_refused_by_key():
    import math

    data = base()
    m = MAX_VERTICES + 1
    ring = [
        [10.0 * math.cos(2 * math.pi * k / m), 10.0 * math.sin(2 * math.pi * k / m)]
        for k in range(m)
    ]
    data["obstacles"] = [{"position": [0.0, -300.0], "vertices": ring}]
    with pytest.raises(ValueError, match=rf"obstacles\[0\]\.vertices has {m} vertices"):
        Scenario.from_dict(data)
    data["obstacles"][0]["vertices"] = ring[:-2]  # 63 vertices
    assert len(Scenario.from_dict(data).obstacles[0].vertices) == m - 2


def test_a_saved_scenario_still_loads(tmp_path):
    scenario = simple_scenario()
    path = tmp_path / "ok.json"
    scenario.save(path)
    assert Scenario.load(path) == scenario
