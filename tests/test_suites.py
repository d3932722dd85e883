"""Frozen evaluation suites: the shipped files load, round-trip and fix the start of every
episode; their seeds are disjoint from every default training, model-selection and imitation
seed; train.py and imitate.py refuse them."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import debris_gym.suites as suites
from agents.experiments.evaluation.records import scenario_fingerprint
from agents.experiments.imitation.config import load_imitation_config
from agents.experiments.training.config import CONFIG_DIR, EVAL_SEED, TrainConfig
from debris_gym.scenario import Scenario
from debris_gym.suites.build import StandardSuite, build_suite
from tests.helpers import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _fresh_caches():
    suites.load_suite.cache_clear()
    suites.suite_seeds.cache_clear()
    yield
    suites.load_suite.cache_clear()
    suites.suite_seeds.cache_clear()


def test_standard_suites_ship_and_load():
    """The v2 suites (the default's) and the v1 ones, kept as they were for reproduction."""
    names = suites.list_suites()
    assert {"standard-2d-v2", "standard-3d-v2", "standard-2d-v1", "standard-3d-v1"} <= set(names)
    for name, env_id, dim in (
        ("standard-2d-v2", "DebrisGym/Rendezvous2D-v2", 2),
        ("standard-3d-v2", "DebrisGym/Rendezvous3D-v2", 3),
        ("standard-2d-v1", "DebrisGym/Rendezvous2D-v1", 2),
        ("standard-3d-v1", "DebrisGym/Rendezvous3D-v1", 3),
    ):
        suite = suites.load_suite(name)
        assert suite.name == name and suite.env_id == env_id and len(suite) == 100
        assert suite.env_kwargs == {} and suite.description
        assert set(suite.provenance) == {"command", "git"}
        assert all(isinstance(m.scenario, Scenario) for m in suite.missions)
        assert all(m.scenario.dim == dim for m in suite.missions)
        assert all(m.scenario.motion == "cwh" for m in suite.missions)  # the moving world
        assert len(set(suite.seeds)) == 100
        assert len({scenario_fingerprint(m.scenario) for m in suite.missions}) == 100


def test_suite_file_has_exactly_the_documented_format():
    path = Path(suites.__file__).parent / "standard-2d-v1.json.gz"
    data = json.loads(gzip.decompress(path.read_bytes()))
    assert list(data) == ["name", "env_id", "description", "env_kwargs", "provenance", "missions"]
    assert set(data["missions"][0]) == {"seed", "scenario"}
    # every scenario round-trips through Scenario.to_dict / from_dict unchanged
    suite = suites.load_suite("standard-2d-v1")
    for raw, mission in zip(data["missions"], suite.missions, strict=True):
        assert raw["seed"] == mission.seed
        assert mission.scenario.to_dict() == raw["scenario"]
        assert Scenario.from_dict(mission.scenario.to_dict()) == mission.scenario


def test_a_mission_fixes_the_start_whatever_env_instance_flies_it():
    suite = suites.load_suite("standard-3d-v2")
    first = gym.make(suite.env_id, **suite.env_kwargs)
    second = gym.make(suite.env_id, **suite.env_kwargs)
    for mission in suite.missions[:3]:
        second.reset(seed=12345)  # a different history before
        obs1, info1 = first.reset(seed=mission.seed, options={"scenario": mission.scenario})
        obs2, info2 = second.reset(seed=mission.seed, options={"scenario": mission.scenario})
        assert np.array_equal(obs1, obs2)
        assert np.array_equal(info1["chaser_state"], info2["chaser_state"])
        # the chaser starts at rest at the suite's dock, in the suite's field
        state = np.asarray(info1["chaser_state"])
        assert np.array_equal(state[:3], np.asarray(mission.scenario.dock)) and not state[3:].any()
        assert scenario_fingerprint(first.unwrapped.scenario) == scenario_fingerprint(
            mission.scenario
        )
    first.close()
    second.close()


def test_builder_draws_the_env_fields_and_writes_a_file_that_reads_back(tmp_path):
    recipe = StandardSuite(
        env_id="DebrisGym/Rendezvous2D-v2", first_seed=950_000_000, count=2, description="t"
    )
    suite = build_suite("tiny", recipe, "test")
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    for mission in suite.missions:
        env.reset(seed=mission.seed)  # the field a plain reset draws from that seed
        assert scenario_fingerprint(env.unwrapped.scenario) == scenario_fingerprint(
            mission.scenario
        )
    env.close()
    path = tmp_path / "tiny.json.gz"
    suites.write_suite(suite, path)
    again = suites.read_suite(path)
    assert again.content_hash == suite.content_hash and again.seeds == suite.seeds
    suites.write_suite(again, tmp_path / "again.json.gz")  # deterministic bytes (no mtime)
    assert (tmp_path / "again.json.gz").read_bytes() == path.read_bytes()
    with pytest.raises(ValueError, match="reserved range"):
        StandardSuite("DebrisGym/Rendezvous2D-v2", 5, 2, "outside")


def test_content_hash_covers_what_is_flown_only():
    suite = suites.load_suite("standard-2d-v1")
    import dataclasses

    assert dataclasses.replace(suite, description="x", provenance={}).content_hash == (
        suite.content_hash
    )
    assert dataclasses.replace(suite, missions=suite.missions[1:]).content_hash != (
        suite.content_hash
    )
    swapped = (suite.missions[0]._replace(seed=suite.missions[0].seed + 7), *suite.missions[1:])
    assert dataclasses.replace(suite, missions=swapped).content_hash != suite.content_hash


def test_bad_files_and_names_are_named(tmp_path):
    with pytest.raises(ValueError, match=r"suite must be one of .*standard-2d-v1"):
        suites.load_suite("nope")
    path = tmp_path / "bad.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"name": "bad"}).encode()))
    with pytest.raises(ValueError, match=r"missing .*env_id"):
        suites.read_suite(path)
    path.write_bytes(b"not gzip")
    with pytest.raises(ValueError, match="not a gzip-compressed JSON suite file"):
        suites.read_suite(path)


# --- evaluation-only: seeds apart from training, and the refusals ------------------------------


def _default_training_seeds() -> list[range]:
    """Every reset seed a checked-in training config uses at the default --seed 0."""
    from agents.experiments.config_files import load_config_file
    from agents.experiments.training.config import available_configs

    ranges = []
    for stem in available_configs():
        data, _ = load_config_file(CONFIG_DIR / f"{stem}.yaml")
        config = TrainConfig.from_dict(data, source=stem)
        ranges.append(range(0, config.n_envs + len(config.curriculum)))
        ranges.append(range(EVAL_SEED, EVAL_SEED + config.eval.n_envs))
    return ranges


def test_suite_seeds_are_disjoint_from_default_training_and_evaluation_seeds():
    imitation = load_imitation_config("DebrisGym/Rendezvous2D-v2")
    held_out = [range(10_000_000, 10_001_000), range(20_000_000, 20_001_000)]  # the docs'
    for seeds in [*_default_training_seeds(), imitation.field_seeds, *held_out]:
        assert suites.seeds_in_suites(seeds) == {}, seeds
    for name in suites.list_suites():
        assert all(s in suites.RESERVED_SEEDS for s in suites.load_suite(name).seeds)


def test_training_refuses_seeds_that_are_a_suites(monkeypatch, tmp_path):
    from agents.experiments.config_files import load_config_file
    from agents.experiments.training import resolve

    # a suite whose seeds sit where training would seed its envs
    base = suites.load_suite("standard-2d-v1")
    fake = suites.Suite("fake", base.env_id, "", {}, (base.missions[0]._replace(seed=3),))
    suites.write_suite(fake, tmp_path / "fake.json.gz")
    monkeypatch.setattr(suites, "_suite_dir", lambda: tmp_path)
    data, _ = load_config_file(CONFIG_DIR / "rendezvous2d_ppo.yaml")
    config = TrainConfig.from_dict(data, source="ppo")
    with pytest.raises(ValueError, match=r"training .*evaluation suite.*fake: 3.*evaluation-only"):
        resolve.refuse_suite_seeds_of(0, config)
    resolve.refuse_suite_seeds_of(10, config)  # clear of seed 3: accepted


def test_imitation_refuses_seeds_that_are_a_suites():
    # fields are seeded 5 000 000 + 100 000 · seed + k: seed 8950 lands on 900 000 000
    with pytest.raises(ValueError, match=r"imitation .*standard-2d-v1.*evaluation-only"):
        load_imitation_config("DebrisGym/Rendezvous2D-v2", seed=8950)
    load_imitation_config("DebrisGym/Rendezvous2D-v2", seed=1)


@pytest.mark.parametrize("script", ["train.py", "imitate.py"])
def test_scripts_refuse_a_suite_option(script, capsys):
    cli = load_script(script)
    with pytest.raises(SystemExit) as exc:
        cli.main(["--suite", "standard-2d-v2", "--out", "/nonexistent/never-written"])
    assert exc.value.code == 2
    assert "argument --suite: suites are evaluation-only" in capsys.readouterr().err
