"""Tests of the bench package: every measurement of every section runs, its rows hold sane and
self-consistent values (rates from the timed medians, ratios from the rows they compare, shares
that add up, plausible magnitudes) and land in the report; the harness interleaves, isolates
failures and tears down.

No assertions on speed itself: speeds on shared machines are noise; the magnitude bounds are
orders of magnitude wide and only catch a wrong unit. The default run measures each section in
process at the tiny sizes of ``bench.config.TINY`` (a few envs, a few steps, a 256-step PPO
learn); the full tiny run, with the SubprocVecEnv rows, the memory section's child processes and
the report of every section, is ``slow``.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bench
from bench import cli, config, decisions, harness, memory, suite, vector
from bench.config import CARTPOLE, DEBRIS_IDS, DEFAULT_OBSTACLES, ID_2D, ID_3D, ID_V1, TINY
from debris_gym.files import write_atomic
from tests.helpers import flies_old_ids

# the bench measures every registered ID, the v0 ones included
pytestmark = flies_old_ids

ROOT = Path(__file__).resolve().parents[1]


IN_PROCESS = {**TINY, "subproc_envs": ()}
"""The tiny sizes without SubprocVecEnv rows (their worker processes are the slow run's)."""


def tiny_run(*sections: str, sizes: dict | None = None) -> list[dict]:
    return bench.run(
        quick=True, steps=20, resets=1, progress=False, sections=sections, sizes=sizes or TINY
    )


@pytest.fixture(scope="module")
def all_rows():
    """Every section at the tiny sizes, SubprocVecEnv and the memory children included."""
    return tiny_run(*bench.SECTIONS)


@pytest.fixture(scope="module")
def rows():
    return tiny_run("single")


def _finite_positive(x):
    return x is not None and math.isfinite(x) and x > 0


def _report_of(section_rows: list[dict], heading: str) -> str:
    report = bench.format_report(section_rows, command="x", elapsed=1.0)
    assert heading in report and "## Errors" not in report
    return report


def test_every_env_has_a_step_row_at_both_wrapper_levels(rows):
    for env_id in (*DEBRIS_IDS, CARTPOLE):
        for level in ("make", "unwrapped"):
            found = [
                r
                for r in rows
                if (r["section"], r["env_id"], r["level"], r["variant"])
                == ("step", env_id, level, "")
            ]
            assert len(found) == 1, (env_id, level)
            row = found[0]
            assert row["error"] is None
            assert row["count"] == 20
            assert 0 < row["min_us"] <= row["median_us"]
            assert row["steps_per_s"] == pytest.approx(1e6 / row["median_us"])
            # a step of any of these envs takes more than 0.1 µs and less than 0.1 s
            assert 1e1 < row["steps_per_s"] < 1e7, row
            cartpole = [
                r for r in rows
                if (r["section"], r["env_id"], r["level"], r["variant"])
                == ("step", CARTPOLE, level, "")
            ]  # fmt: skip
            assert row["ratio"] == pytest.approx(row["median_us"] / cartpole[0]["median_us"])
    cartpole = [r for r in rows if r["section"] == "step" and r["env_id"] == CARTPOLE]
    assert all(r["ratio"] == pytest.approx(1.0) for r in cartpole)


def test_variants_scaling_and_resets_are_measured(rows):
    variants = {r["variant"] for r in rows if r["section"] == "step"}
    assert {"observation=lidar", "action=discrete", "actions=random"} <= variants
    explored_rows = [r for r in rows if r["variant"] == "actions=random"]
    assert {r["env_id"] for r in explored_rows} == {ID_2D, config.ID_V1}  # v2 and v1
    for explored in explored_rows:
        assert explored["level"] == "make"
        assert _finite_positive(explored["ratio_wall"])  # resets included on both sides
        low, high = explored["ratio_wall_range"]
        assert low <= explored["ratio_wall"] <= high
    scaling = {r["n_obstacles"]: r for r in rows if r["section"] == "scaling"}
    assert sorted(scaling) == sorted(config.SCALING_COUNTS)
    for n, row in scaling.items():
        assert row["field_size"] == pytest.approx(config.field_size_for(n))
        # A generator failure is reported in the row, not raised; either way the row exists.
        assert row["error"] is not None or row["steps_per_s"] > 0
    resets = {r["env_id"]: r for r in rows if r["section"] == "reset"}
    assert set(resets) == {*DEBRIS_IDS, CARTPOLE}
    # a reset takes more than 0.1 µs and less than 10 s (a DebrisGym field draw included)
    assert all(0.1 < r["median_us"] < 1e7 for r in resets.values()), resets
    assert all(r["min_us"] <= r["median_us"] for r in resets.values())


def test_report_has_machine_header_and_a_line_per_row(rows):
    report = bench.format_report(rows, command="python bench/run.py --quick", elapsed=1.0)
    assert report.startswith("# DebrisGym benchmark")
    assert "- CPU: " in report and "gymnasium" in report and "numba" in report
    for env_id in (*DEBRIS_IDS, CARTPOLE):
        assert report.count(f"`{env_id}`") >= 3  # make, unwrapped, reset
    assert "| 200 | 3,162 |" in report


def test_write_atomic_replaces_the_file(tmp_path):
    out = tmp_path / "sub" / "table.md"
    write_atomic(str(out), "old\n")
    write_atomic(str(out), "new\n")
    assert out.read_text() == "new\n"
    assert [p.name for p in out.parent.iterdir()] == ["table.md"]  # no temp file left behind


def test_sections_are_selectable():
    assert bench.SECTIONS is suite.SECTIONS
    assert suite.SECTIONS == (
        "single", "vector", "scaling", "shield", "swarm", "memory", "train", "decisions"
    )  # fmt: skip
    assert suite.choose_sections(["train", "vector"]) == ("vector", "train")  # run order
    assert suite.choose_sections(None) == suite.SECTIONS
    with pytest.raises(ValueError, match="unknown section"):
        suite.choose_sections(["single", "nope"])
    rows = bench.run(
        quick=True,
        steps=3,
        progress=False,
        sections=["scaling"],
        sizes={**TINY, "scaling_rows": ((10, 2),)},
    )
    assert {r["section"] for r in rows} == {"vector_scaling"}
    assert sorted(r["n_obstacles"] for r in rows) == [10, 20]  # the reference is added


def check_vector_rows(vec: list[dict], sizes: dict) -> None:
    keys = {(r["level"], r["env_id"], r["variant"], r["num_envs"]) for r in vec}
    expected = {("native", CARTPOLE, "", sizes["cartpole_envs"])}
    expected |= {("native", ID_2D, "", n) for n in sizes["vector_envs"]}
    expected |= {("native", ID_3D, "", sizes["vector_variant_envs"])}
    expected |= {("native", ID_2D, "observation=lidar", sizes["vector_variant_envs"])}
    expected |= {("sync", ID_2D, "", sizes["sync_envs"])}
    expected |= {("subproc", ID_2D, "", n) for n in sizes["subproc_envs"]}
    # uniformly random actions, v2 and v1: the native env at CartPole's N and SyncVectorEnv
    for env_id in (ID_2D, ID_V1):
        expected |= {("native", env_id, "actions=random", sizes["cartpole_envs"])}
        expected |= {("sync", env_id, "actions=random", sizes["sync_envs"])}
    if vector.numba_threads() >= 2:  # the default env again, stepped by two threads
        threaded = {sizes["cartpole_envs"], sizes["vector_envs"][-1]}
        expected |= {("native", ID_2D, "num_threads=2", n) for n in threaded}
    assert keys == expected
    for row in vec:
        assert row["error"] is None, row["error"]
        assert row["count"] == 20 and row["repeats"] == 3
        assert row["warmup_steps"] == sizes["warmup_steps"]
        assert _finite_positive(row["env_steps_per_s"])
        assert 1e1 < row["env_steps_per_s"] < 1e9, row  # 1 ns to 0.1 s an env-step
        assert row["us_per_env_step"] == pytest.approx(1e6 / row["env_steps_per_s"])
        assert row["env_steps_per_s_best"] >= row["env_steps_per_s"]
        assert 0 <= row["ends_per_1000"] <= 1000
        assert _finite_positive(row["reset_ms_per_env"])
    (cartpole,) = [r for r in vec if r["env_id"] == CARTPOLE]
    (sync,) = [r for r in vec if r["level"] == "sync" and not r["variant"]]
    native_2d = [r for r in vec if r["level"] == "native" and r["env_id"] == ID_2D]
    for row in native_2d:
        want = row["env_steps_per_s"] / cartpole["env_steps_per_s"]
        assert row["ratio_cartpole"] == pytest.approx(want)
    same_env = [r for r in native_2d if not r["variant"] or r["variant"] == "num_threads=2"]
    for env_id in (ID_2D, ID_V1):  # each against SyncVectorEnv of its own world
        (explored,) = [
            r for r in vec
            if r["level"] == "native" and r["env_id"] == env_id and r["variant"] == "actions=random"
        ]  # fmt: skip
        (sync_random,) = [
            r for r in vec
            if r["level"] == "sync" and r["env_id"] == env_id and r["variant"] == "actions=random"
        ]  # fmt: skip
        assert explored["ratio_sync"] == pytest.approx(
            explored["env_steps_per_s"] / sync_random["env_steps_per_s"]
        )
        want = explored["env_steps_per_s"] / cartpole["env_steps_per_s"]
        assert explored["ratio_cartpole"] == pytest.approx(want)
    assert {r["actions"] for r in vec if r["variant"] == "actions=random"} == {"random"}
    assert {r["actions"] for r in vec if r["variant"] != "actions=random"} == {"gentle"}
    subproc = [r for r in vec if r["level"] == "subproc"]
    for row in same_env + subproc:
        assert row["ratio_sync"] == pytest.approx(row["env_steps_per_s"] / sync["env_steps_per_s"])


def test_vector_section_rows():
    vec = tiny_run("vector", sizes=IN_PROCESS)
    assert {r["section"] for r in vec} == {"vector"}
    check_vector_rows(vec, IN_PROCESS)
    report = _report_of(vec, "## Vector env throughput")
    assert "SyncVectorEnv" in report
    for env_id in (ID_2D, ID_V1):  # the random-action goals, for each world
        assert f"- uniformly random actions, `{env_id}` native N=" in report


@pytest.mark.slow
def test_vector_section_rows_with_subprocesses(all_rows):
    vec = [r for r in all_rows if r["section"] == "vector"]
    check_vector_rows(vec, TINY)
    assert any(r["level"] == "subproc" for r in vec)


def test_vector_scaling_rows():
    scaling = tiny_run("scaling")
    assert {r["section"] for r in scaling} == {"vector_scaling"}
    _report_of(scaling, "## Vector env: scaling with debris count")
    pairs = {(r["n_obstacles"], r["num_envs"]) for r in scaling}
    wanted = set(TINY["scaling_rows"])
    wanted |= {(DEFAULT_OBSTACLES, n) for _, n in TINY["scaling_rows"]}
    assert pairs == wanted
    assert {n for n, _ in pairs} >= set(config.SCALING_COUNTS)
    for row in scaling:
        assert row["error"] is None, row["error"]
        assert row["field_size"] == pytest.approx(config.field_size_for(row["n_obstacles"]))
        assert _finite_positive(row["env_steps_per_s"])
        assert _finite_positive(row["reset_ms_per_env"])
        assert _finite_positive(row["ratio"])
        (reference,) = [
            r for r in scaling
            if r["num_envs"] == row["num_envs"] and r["n_obstacles"] == DEFAULT_OBSTACLES
        ]  # fmt: skip
        # a cost ratio: the reference's rate over this row's
        assert row["ratio"] == pytest.approx(reference["env_steps_per_s"] / row["env_steps_per_s"])
        if row["n_obstacles"] == DEFAULT_OBSTACLES:
            assert row["ratio"] == pytest.approx(1.0)


@pytest.mark.slow
def test_memory_row(all_rows):
    (row,) = [r for r in all_rows if r["section"] == "memory"]
    assert row["error"] is None, row["error"]
    small, large = TINY["memory_envs"]
    assert (row["small_envs"], row["large_envs"]) == (small, large)
    assert set(row["rss_growth"]) == {small, large}
    assert math.isfinite(row["rss_per_env"])  # RSS moves in pages: at tiny N it may be 0
    assert _finite_positive(row["array_bytes_per_env"])
    assert _finite_positive(row["obs_buffer_bytes_per_env"])
    names = {(a["owner"], a["name"]) for a in row["arrays"]}
    assert {("field", "centers"), ("batch", "missions.state"), ("env", "observation")} <= names
    assert [a["nbytes"] for a in row["arrays"]] == sorted(
        (a["nbytes"] for a in row["arrays"]), reverse=True
    )
    state = sum(a["nbytes"] for a in row["arrays"] if not a["observation_buffer"])
    assert row["array_bytes_per_env"] == pytest.approx(state / large)
    assert _finite_positive(row["python_bytes_per_env"]["scenarios"])
    assert _finite_positive(row["python_bytes_per_env"]["rngs"])


def test_memory_child_counts_every_array():
    out = memory.memory_child(2)
    assert out["num_envs"] == 2 and out["n_bodies"] >= 21
    obs = [a for a in out["arrays"] if a["observation_buffer"]]
    assert [a["name"] for a in obs] == ["observation"]
    width = gym.make(ID_2D).observation_space.shape[0]
    assert obs[0]["shape"] == [2, width] and obs[0]["nbytes"] == 2 * width * 4  # float32
    # the fields drawn ahead are per sub-env memory too
    assert any(a["owner"] == "supply" and a["name"] == "_store.centers" for a in out["arrays"])
    # the env's own arrays: more than nothing, less than a megabyte a sub-env at this size
    state = sum(a["nbytes"] for a in out["arrays"] if not a["observation_buffer"])
    assert 2 * 64 < state < 2 * 2**20, state
    # every field array is per sub-env
    assert all(2 in a["shape"] for a in out["arrays"] if a["owner"] == "field")
    assert out["rss_after_reset"] > 0


def test_memory_child_counts_an_array_held_twice_once(monkeypatch):
    """Regression: an array reachable through two attributes of the env's batches (here a second
    reference to the vertex array) is counted once, not twice."""
    from debris_gym.envs import vector

    reset = vector.DebrisFieldVectorEnv.reset

    def reset_and_alias(self, *args, **kwargs):
        out = reset(self, *args, **kwargs)
        self.batch.alias_of_vertices = self.batch.field.vertices
        return out

    monkeypatch.setattr(vector.DebrisFieldVectorEnv, "reset", reset_and_alias)
    out = memory.memory_child(2)
    names = [a["name"] for a in out["arrays"]]
    assert names.count("vertices") + names.count("alias_of_vertices") == 1


def test_deep_size_counts_shared_objects_once():
    shared = tuple(float(i) for i in range(100))
    one = memory.deep_size([shared])
    assert memory.deep_size([shared, shared]) == one + 8  # one more list slot only
    assert memory.deep_size(np.zeros(1000)) >= 8000


def test_train_rows():
    train = tiny_run("train")
    tiny = TINY
    assert [(r["level"], r["num_envs"]) for r in train] == [
        *(("NativeVecEnv", n) for n in tiny["train_envs"]),
        ("DummyVecEnv", tiny["dummy_envs"]),
    ]
    for row in train:
        assert row["error"] is None, row["error"]
        assert row["n_steps"] * row["num_envs"] == tiny["train_rollout"]
        assert row["timesteps"] == tiny["train_rollout"] * tiny["train_rollouts"]
        assert row["batch_size"] == tiny["train_batch"] and row["n_epochs"] == tiny["train_epochs"]
        assert _finite_positive(row["env_steps_per_s"])
        assert 1e0 < row["env_steps_per_s"] < 1e8, row
        shares = (row["env_share"], row["policy_share"], row["update_share"])
        assert all(0 <= s <= 1 for s in shares)
        assert sum(shares) == pytest.approx(1.0)
        assert 1e-4 < row["forward_ms"] < 1e4, row  # one policy forward: 0.1 µs to 10 s
        assert 0 <= row["ends_per_1000"] <= 1000
    native, dummy = train
    assert native["ratio_dummy"] == pytest.approx(
        native["env_steps_per_s"] / dummy["env_steps_per_s"]
    )
    _report_of(train, "## Training throughput")


def test_decision_agents_take_the_pretrained_policy_once_one_ships_for_the_env(monkeypatch):
    """The pretrained rows follow the shipped policies (as the default evaluation does): none
    while no policy ships for the bench's env, both once an entry names one."""
    from agents.policies import learned

    api = decisions.agents_api()
    baselines = list(api.baselines)
    ships = api.pretrained_ships(config.ID_2D)
    if not ships:
        assert decisions.decision_agents() == [*baselines, "apf-mpc+shield"]
    shipped = {**learned.PRETRAINED_POLICIES, config.ID_2D: ("ppo", "rendezvous2d_finetuned.zip")}
    monkeypatch.setattr(learned, "PRETRAINED_POLICIES", shipped)
    assert decisions.decision_agents() == [
        *baselines, "pretrained", "apf-mpc+shield", "pretrained+shield"
    ]  # fmt: skip
    monkeypatch.setattr(learned, "PRETRAINED_POLICIES", {})
    assert decisions.decision_agents() == [*baselines, "apf-mpc+shield"]


def test_decision_rows():
    timed = tiny_run("decisions")
    assert [r["agent"] for r in timed] == decisions.decision_agents()
    assert "apf-mpc" in decisions.decision_agents()
    assert "apf-mpc+shield" in decisions.decision_agents()
    assert {r["env_id"] for r in timed} == {config.ID_2D}
    limit = TINY["decision_max_steps"]
    for row in timed:
        assert row["error"] is None, row["error"]
        assert row["episodes"] == TINY["decision_episodes"]
        assert 1 <= row["decisions"] <= limit * row["episodes"]
        assert 0 <= row["successes"] <= row["episodes"]
        assert 0 < row["p50_ms"] <= row["p95_ms"] <= row["max_ms"] < 6e4  # under a minute
        assert 0 < row["first_ms"] <= row["max_ms"]
        assert 0.1 < row["env_step_us"] < 1e6, row
        assert row["p50_steps"] == pytest.approx(row["p50_ms"] * 1e3 / row["env_step_us"])
    # every agent flew the same missions: the same env-step reference in every row
    assert len({r["env_step_us"] for r in timed}) == 1
    _report_of(timed, "## Decision times")


def test_decision_agent_that_cannot_be_built_is_reported(monkeypatch):
    monkeypatch.setattr(
        decisions, "decision_agents", lambda: ["zero", "ppo=/nonexistent/model.zip"]
    )
    rows = bench.run(steps=20, progress=False, sections=["decisions"], sizes=TINY)
    zero, broken = rows
    assert zero["error"] is None and zero["decisions"] >= 1
    assert "nonexistent" in broken["error"] and math.isnan(broken["p50_ms"])
    report = bench.format_report(rows, command="x", elapsed=1.0)
    assert "| `ppo` | error: " in report and "## Errors" in report


@pytest.mark.slow
def test_report_has_every_section(all_rows):
    report = bench.format_report(all_rows, command="python bench/run.py --quick", elapsed=1.0)
    for heading in (
        "## Single-env step cost",
        "## Vector env throughput",
        "## Vector env: scaling with debris count",
        "## Swarm throughput",
        "## Memory per sub-env",
        "## Training throughput",
        "## Decision times",
    ):
        assert heading in report
    assert "SyncVectorEnv" in report and "SubprocVecEnv" in report
    assert "Goal ≥ 20,000 env-steps/s end to end" in report
    assert "## Errors" not in report
    only_vector = bench.format_report(
        [r for r in all_rows if r["section"] == "vector"], command="x", elapsed=1.0
    )
    assert (
        "## Single-env step cost" not in only_vector and "## Vector env throughput" in only_vector
    )


def test_cli_rejects_unknown_sections(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--only", "single,bogus"])
    assert "unknown section" in capsys.readouterr().err


class _Probe:
    """A stand-in measurement that logs every call the harness makes."""

    def __init__(self, name, log, fail_in=None, fail_with=RuntimeError):
        self.name, self.log, self.error = name, log, None
        self.fail_in, self.fail_with = fail_in, fail_with

    def describe(self):
        return self.name

    def _call(self, what):
        self.log.append((what, self.name))
        if what == self.fail_in:
            raise self.fail_with("boom")

    def set_up(self):
        self._call("set_up")

    def measure(self, round_index):
        self._call(f"measure {round_index}")

    def tear_down(self):
        self._call("tear_down")


def test_harness_interleaves_rounds_and_drops_what_failed():
    log = []
    a, b, c = _Probe("a", log), _Probe("b", log, "set_up"), _Probe("c", log, "measure 0")
    harness.interleave([a, b, c], 2, "test", progress=False)
    assert log == [
        ("set_up", "a"), ("set_up", "b"), ("set_up", "c"),
        ("measure 0", "a"), ("measure 0", "c"),
        ("measure 1", "a"),
        ("tear_down", "a"), ("tear_down", "b"), ("tear_down", "c"),
    ]  # fmt: skip
    assert a.error is None
    assert b.error == c.error == "RuntimeError: boom"


def test_harness_tears_everything_down_when_interrupted():
    log = []
    a, b = _Probe("a", log), _Probe("b", log, "measure 0", KeyboardInterrupt)
    with pytest.raises(KeyboardInterrupt):
        harness.interleave([a, b], 3, "test", progress=False)
    assert log[-2:] == [("tear_down", "a"), ("tear_down", "b")]
    assert ("measure 1", "a") not in log


def test_draw_actions_are_valid_for_every_kind_of_space():
    rng = np.random.default_rng(0)
    box = harness.draw_actions(gym.spaces.Box(-1, 1, (2,), np.float32), ID_2D, (50, 3), rng)
    assert box.shape == (50, 3, 2) and box.dtype == np.float32
    assert np.abs(box).max() <= config.THRUST
    thrusts = harness.draw_actions(gym.spaces.Discrete(5), ID_2D, (2000,), rng)
    assert set(np.unique(thrusts)) <= set(range(5))
    assert np.mean(thrusts == 0) == pytest.approx(config.DISCRETE_COAST, abs=0.05)
    cartpole = harness.draw_actions(gym.spaces.Discrete(2), CARTPOLE, (2000,), rng)
    assert np.mean(cartpole == 0) == pytest.approx(0.5, abs=0.05)


@pytest.mark.parametrize("entry", ["script", "module"])
def test_both_entry_points_take_the_options(entry, tmp_path, monkeypatch):
    if entry == "script":  # from another folder, with nothing on the path: the script finds it
        monkeypatch.delenv("PYTHONPATH", raising=False)
        args, cwd = [str(ROOT / "bench" / "run.py")], tmp_path
    else:
        args, cwd = ["-m", "bench"], ROOT
    done = subprocess.run(
        [sys.executable, *args, "--only", "single,bogus"],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 2
    assert "unknown section" in done.stderr and "--quick" in done.stderr


# --- --out and --only are checked before any section runs ------------------------------------


@pytest.fixture
def no_sections(monkeypatch):
    """Replace the measurements by a recorder: a refused command line must not reach them."""
    calls = []
    monkeypatch.setattr(cli, "run", lambda **kwargs: calls.append(kwargs) or [])
    return calls


@pytest.mark.parametrize(
    "out, message",
    [
        ("{tmp}/afile/x.md", "argument --out: {tmp}/afile is a file, not a directory"),
        ("{tmp}/afile/sub/x.md", "lies under {tmp}/afile, which is a file"),
        ("", "argument --out: must name a report file, got an empty string"),
        ("{tmp}", "argument --out: {tmp} is a directory"),
    ],
)
def test_a_report_path_that_cannot_be_written_is_refused_before_any_section(
    out, message, tmp_path, capsys, no_sections
):
    """Regression: ``bench/run.py --out afile/x.md`` ran every section, then failed writing."""
    (tmp_path / "afile").write_text("")
    with pytest.raises(SystemExit) as exc:
        cli.main(["--out", out.replace("{tmp}", str(tmp_path)), "--only", "single"])
    assert exc.value.code == 2
    assert message.replace("{tmp}", str(tmp_path)) in capsys.readouterr().err
    assert no_sections == []


def test_a_report_in_a_new_directory_is_accepted(tmp_path, no_sections):
    """The parent may be created (the report is written atomically into it)."""
    assert cli.main(["--out", str(tmp_path / "new" / "x.md"), "--only", "single"]) == 0
    assert len(no_sections) == 1 and (tmp_path / "new" / "x.md").is_file()


@pytest.mark.parametrize("only", ["", ",", " , "])
def test_an_empty_only_is_refused_listing_the_sections(only, capsys, no_sections):
    """Regression: ``--only ''`` ran every section."""
    with pytest.raises(SystemExit) as exc:
        cli.main(["--only", only])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "argument --only: names no section" in err
    assert ", ".join(suite.SECTIONS) in err
    assert no_sections == []


def test_the_shield_section_times_the_shield_off_and_on_and_reports_its_cost():
    rows = tiny_run("shield")
    assert [(r["env_id"], r["shield"]) for r in rows] == [
        (ID_2D, False), (ID_2D, True), (ID_3D, False), (ID_3D, True)
    ]  # fmt: skip
    for row in rows:
        assert row["error"] is None and row["actions"] == "random"
        assert _finite_positive(row["env_steps_per_s"])
        if row["shield"]:
            assert math.isfinite(row["us_per_decision"])
            lo, hi = row["us_per_decision_range"]
            assert lo <= row["us_per_decision"] <= hi
        else:
            assert row["intervened_per_1000"] == 0.0  # the off rows count nothing
            assert math.isnan(row["us_per_decision"])
    report = bench.format_report(rows, command="bench", elapsed=1.0, machine=[])
    assert "Compiled safety shield in the vector env" in report
    assert report.count("| `DebrisGym/") == 4
