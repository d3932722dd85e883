"""The shipped hard suites (debris_gym/suites/hard-v2.json.gz, and hard.json.gz of the v1 world)
and their selection module: the files' format, every field re-drawn by the env's own generator
from its seed (the independent truth that the scenarios are the seeded fields the rule names),
the rule re-checked on a mission by flying it, and the suites' seeds kept inside the reserved
range."""

from __future__ import annotations

import gzip
import json

import gymnasium as gym
import numpy as np
import pytest

import agents
from agents.experiments import hard_suite
from agents.planners.rrt import RRTParams
from debris_gym.scenario import Scenario
from debris_gym.suites import RESERVED_SEEDS, load_suite
from tests.helpers import flies_old_ids

FORMAT_KEYS = {"name", "env_id", "description", "env_kwargs", "provenance", "missions"}


@pytest.fixture(
    scope="module",
    params=["hard-v2", pytest.param("hard", marks=flies_old_ids)],  # v1's, for reproduction
)
def suite(request) -> dict:
    return _read(request.param)


def _read(name: str) -> dict:
    with gzip.open(hard_suite.HARD_SUITES[name].path, "rt", encoding="utf-8") as f:
        return json.load(f)


def test_the_default_suite_is_the_v2_one():
    assert hard_suite.DEFAULT_SUITE == "hard-v2"
    assert hard_suite.ENV_ID == "DebrisGym/Rendezvous2D-v2"
    assert hard_suite.SUITE_PATH.name == "hard-v2.json.gz"
    assert hard_suite.HARD_SUITES["hard"].env_id == "DebrisGym/Rendezvous2D-v1"
    seeds = {name: set(load_suite(name).seeds) for name in hard_suite.HARD_SUITES}
    assert not seeds["hard"] & seeds["hard-v2"]


def test_the_file_has_the_suite_format(suite):
    spec = hard_suite.HARD_SUITES[suite["name"]]
    assert set(suite) == FORMAT_KEYS
    assert suite["env_id"] == spec.env_id and suite["description"] == spec.description
    assert suite["env_kwargs"] == hard_suite.ENV_KWARGS
    assert set(suite["provenance"]) == {"command", "git"}
    assert "agents.experiments.hard_suite select" in suite["provenance"]["command"]
    assert isinstance(suite["provenance"]["git"], str) and suite["provenance"]["git"]
    missions = suite["missions"]
    assert len(missions) == hard_suite.SUITE_SIZE
    seeds = [m["seed"] for m in missions]
    assert all(isinstance(s, int) for s in seeds)
    assert seeds == sorted(set(seeds)) and seeds[0] >= spec.first_seed
    assert all(s in RESERVED_SEEDS for s in seeds)
    assert load_suite(spec.name).seeds == tuple(seeds)  # the package's loader reads it
    for m in missions:
        assert set(m) == {"seed", "scenario"}
        scenario = Scenario.from_dict(m["scenario"])  # every rule of the scenario checks
        assert scenario.moving and scenario.dim == 2
        assert len(scenario.obstacles) == hard_suite.ENV_KWARGS["n_obstacles"]


@pytest.mark.parametrize("index", [0, 1, -1])
def test_missions_are_the_fields_the_env_draws_from_their_seeds(suite, index):
    mission = suite["missions"][index]
    env = gym.make(suite["env_id"], **suite["env_kwargs"])
    env.reset(seed=mission["seed"])
    assert env.unwrapped.scenario.to_dict() == mission["scenario"]
    # and the pinned replay starts from the same field
    env.reset(seed=mission["seed"], options={"scenario": Scenario.from_dict(mission["scenario"])})
    assert env.unwrapped.scenario.to_dict() == mission["scenario"]


def test_the_rule_holds_on_the_first_mission():
    """Flown again: plain APF stalls there (fails, or its flight falls into a local minimum by
    the APF-RRT test, whose watch-only agent flies exactly as APF), and a baseline completes it
    (on the default suite; the v1 file's fields are checked unchanged above)."""
    suite = _read(hard_suite.DEFAULT_SUITE)
    mission = suite["missions"][0]
    env = gym.make(suite["env_id"], **suite["env_kwargs"])
    scenario = Scenario.from_dict(mission["scenario"])
    watcher = agents.make_agent("apf-rrt", env, rrt=RRTParams(max_escapes=0))
    watched = hard_suite.fly_mission(env, watcher, mission["seed"], scenario)
    watched_trail = env.unwrapped.trail.copy()
    plain = hard_suite.fly_mission(env, agents.make_agent("apf", env), mission["seed"], scenario)
    np.testing.assert_array_equal(env.unwrapped.trail, watched_trail)
    assert watched["is_success"] == plain["is_success"]
    assert not plain["is_success"] or watcher.detections >= 1
    for name in hard_suite.SOLVERS:  # astar, else apf-mpc
        solved = hard_suite.fly_mission(
            env, agents.make_agent(name, env), mission["seed"], scenario
        )
        if solved["is_success"] and not solved["collision"]:
            break
    assert solved["is_success"] and not solved["collision"]


def test_screen_keeps_exactly_the_stalled_solvable_missions():
    def screen(success, detections, solved_by):
        return hard_suite.Screen(1, success, detections, solved_by, None)

    assert screen(False, 0, "astar").kept  # APF fails, A* completes
    assert screen(True, 2, "apf-mpc").kept  # APF caught twice, APF-MPC completes
    assert not screen(True, 0, "astar").kept  # APF never stalled
    assert not screen(False, 3, None).kept  # nobody completes it: not shown solvable


def test_the_suite_refuses_seeds_outside_the_reserved_range(suite):
    field = Scenario.from_dict(suite["missions"][0]["scenario"])
    inside = hard_suite.Screen(RESERVED_SEEDS.start, False, 1, "astar", field)
    built = hard_suite.hard_suite([inside], "cmd", "abc", suite["name"])
    assert built.name == suite["name"] and built.seeds == (RESERVED_SEEDS.start,)
    assert built.env_id == suite["env_id"]
    assert set(built.to_dict()) == FORMAT_KEYS
    outside = hard_suite.Screen(3_000_009, False, 1, "astar", field)
    with pytest.raises(ValueError, match="reserved"):
        hard_suite.hard_suite([outside], "cmd", "abc")


@pytest.mark.parametrize(("count", "first_seed"), [(0, hard_suite.FIRST_SEED), (2.5, 0), (1, -1)])
def test_select_refuses_bad_arguments(count, first_seed):
    with pytest.raises(ValueError, match=r"count|first_seed"):
        next(hard_suite.select_missions(count, first_seed, progress=False))
