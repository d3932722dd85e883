"""The native vector env against N single envs (gymnasium's SyncVectorEnv), and its geometry."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numba
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import debris_gym
from debris_gym.batch_geometry import FieldBatch
from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.generators import FieldSpec, random_field
from debris_gym.geometry import lidar_directions
from debris_gym.scenario import Body, Scenario
from tests.geometry_oracle import OracleField
from tests.helpers import assert_same, assert_same_step, flies_old_ids, simple_scenario

# some tests fly the free-space simple_scenario in envs with the default LEO orbit on purpose;
# the native vector env is held to SyncVectorEnv on every ID, the v0 ones included
pytestmark = [
    pytest.mark.filterwarnings("ignore:the pinned scenario's physics differ"),
    flies_old_ids,
]

INFO_KEYS = ["chaser_state", "time", "delta_v", "targets_captured", "min_clearance", "collision"]
INFO_KEYS += ["out_of_bounds", "is_success", "captured", "task_score"]


def make_pair(env_id: str, n: int, mode: AutoresetMode = AutoresetMode.NEXT_STEP, **kwargs):
    native = gym.make_vec(
        env_id, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs
    )
    sync = gym.make_vec(
        env_id, num_envs=n, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode},
        **kwargs,
    )  # fmt: skip
    return native, sync


def compare_run(
    env_id: str, n: int, steps: int, scale: float, seed: int = 0,
    mode: AutoresetMode = AutoresetMode.NEXT_STEP, **kwargs,
) -> int:  # fmt: skip
    """Step both with the same actions; everything must agree. Returns episodes ended."""
    native, sync = make_pair(env_id, n, mode, **kwargs)
    obs_n, info_n = native.reset(seed=seed)
    obs_s, info_s = sync.reset(seed=seed)
    assert_same(obs_n, obs_s, "reset obs")
    rng = np.random.default_rng(seed)
    ended = 0
    for step in range(steps):
        if native.unwrapped.config.action == "discrete":
            actions = rng.integers(0, native.single_action_space.n, size=n)
            actions[rng.uniform(size=n) < 0.8] = 0
        else:
            actions = (rng.uniform(-1, 1, (n, native.unwrapped.dim)) * scale).astype(np.float32)
        out_n = native.step(actions)
        out_s = sync.step(actions)
        assert_same_step(out_n, out_s, INFO_KEYS, f"step {step}")
        if "final_obs" in out_s[4]:
            final = out_s[4]["_final_obs"]
            assert_same(out_n[4]["_final_obs"], final, "final_obs mask")
            for i in np.flatnonzero(final):
                assert_same(out_n[4]["final_obs"][i], out_s[4]["final_obs"][i], "final_obs")
                for key in INFO_KEYS:
                    assert_same(out_n[4]["final_info"][key][i], out_s[4]["final_info"][key][i], key)
        assert native.observation_space.contains(out_n[0])
        ended += int(np.sum(out_n[2] | out_n[3]))
    native.close()
    sync.close()
    return ended


@pytest.mark.parametrize(
    "env_id, kwargs, scale",
    [
        ("DebrisGym/Rendezvous2D-v0", {}, 0.3),
        ("DebrisGym/Rendezvous2D-v0", {"max_episode_steps": 40}, 0.3),
        ("DebrisGym/Rendezvous2D-v0", {"observation": "lidar", "lidar_rays": 16}, 0.3),
        ("DebrisGym/Rendezvous2D-v0", {"action": "discrete"}, 1.0),
        ("DebrisGym/Rendezvous2D-v0", {"shaping_terminal": "hold", "shaping_gamma": 1.0}, 0.5),
        ("DebrisGym/Rendezvous2D-v0", {"shaping_speed": 1.0, "obs_goal": True}, 0.5),
        ("DebrisGym/Rendezvous2D-v0", {"shaping_clearance": 1.0, "n_obstacles": 40}, 0.5),
        ("DebrisGym/Rendezvous2D-v0", {"obs_other_targets": True, "obs_obstacles": 30}, 0.5),
        ("DebrisGym/Rendezvous2D-v0", {"shaping_closing": 1.0, "n_obstacles": 40}, 0.5),
        (
            "DebrisGym/Rendezvous2D-v0",
            {"target_order": "queued", "thrust_model": "box", "delta_v_budget": 15.0},
            0.5,
        ),
        ("DebrisGym/Rendezvous2D-v0", {"n_obstacles": 60, "obs_obstacles": 3}, 0.3),
        ("DebrisGym/Rendezvous3D-v0", {}, 0.3),
        ("DebrisGym/Rendezvous3D-v0", {"observation": "lidar", "lidar_rays": 16}, 0.3),
        ("DebrisGym/PaperField2D-v0", {"max_episode_steps": 60}, 0.1),
        ("DebrisGym/Rendezvous2D-v1", {}, 0.3),
        ("DebrisGym/Rendezvous2D-v2", {}, 0.3),
        ("DebrisGym/Rendezvous2D-v2", {"observation": "lidar", "spin_max": 0.05}, 0.3),
        ("DebrisGym/Rendezvous2D-v2", {"action": "discrete", "obs_goal": True}, 1.0),
        ("DebrisGym/Rendezvous2D-v2", {"debris_motion": "drifting", "target_order": "queued"}, 0.3),
        ("DebrisGym/Rendezvous3D-v2", {}, 0.3),
    ],
)
def test_native_vector_env_equals_sync_vector_env(env_id, kwargs, scale):
    ended = compare_run(env_id, n=5, steps=250, scale=scale, **kwargs)
    assert ended > 0  # autoreset was exercised


def test_same_step_autoreset_equals_sync_vector_env():
    ended = compare_run(
        "DebrisGym/Rendezvous2D-v0", n=4, steps=200, scale=0.3, mode=AutoresetMode.SAME_STEP,
        max_episode_steps=30,
    )  # fmt: skip
    assert ended > 0


def test_make_vec_returns_the_native_env_for_every_id():
    for env_id in debris_gym.ENV_SPECS:
        env = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
        assert isinstance(env.unwrapped, DebrisFieldVectorEnv)
        obs, info = env.reset(seed=1)
        assert obs.shape == (3, *env.single_observation_space.shape)
        assert obs.dtype == np.float32 and env.observation_space.contains(obs)
        assert env.action_space.shape[0] == 3
        env.close()


@pytest.mark.parametrize("action", ["continuous", "discrete"])
def test_vector_env_api_contract(action):
    """What gymnasium's VectorEnv API promises (it has no checker for vector envs): batched
    spaces of the single spaces, returns of the right shapes and dtypes inside the spaces,
    info entries with their ``_key`` masks, data not reused between steps, and a same-seed run
    that repeats exactly."""
    from gymnasium.vector.utils import batch_space

    def run():
        env = gym.make_vec(
            "DebrisGym/Rendezvous2D-v0", num_envs=4, vectorization_mode="vector_entry_point",
            action=action, max_episode_steps=30,
        )  # fmt: skip
        assert env.observation_space == batch_space(env.single_observation_space, 4)
        assert env.action_space == batch_space(env.single_action_space, 4)
        assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        env.action_space.seed(0)
        obs, info = env.reset(seed=5)
        assert env.observation_space.contains(obs) and isinstance(info, dict)
        history = []
        for _ in range(70):
            out = env.step(env.action_space.sample())
            obs, reward, terminated, truncated, info = out
            assert env.observation_space.contains(obs)
            assert reward.shape == (4,) and reward.dtype == np.float64
            assert terminated.dtype == bool and truncated.dtype == bool
            for key in INFO_KEYS:
                assert len(info[key]) == 4 and info["_" + key].dtype == bool
            history.append([np.copy(x) for x in out[:4]] + [out])
        for saved in history:  # earlier returns were not overwritten by later steps
            for a, b in zip(saved[:4], saved[4][:4]):
                np.testing.assert_array_equal(a, b)
        env.close()
        return [h[:4] for h in history]

    first, second = run(), run()
    assert any(np.any(h[3]) for h in first)  # the time limit was reached (and autoreset)
    for a, b in zip(first, second):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_seeding_is_per_env_and_deterministic():
    a = DebrisFieldVectorEnv(num_envs=3)
    b = DebrisFieldVectorEnv(num_envs=3)
    a.reset(seed=7)
    b.reset(seed=[7, 8, 9])
    for x, y in zip(a.unwrapped.scenarios, b.unwrapped.scenarios):
        assert x == y
    assert a.unwrapped.scenarios[0] != a.unwrapped.scenarios[1]
    single = gym.make("DebrisGym/Rendezvous2D-v0")
    single.reset(seed=8)
    assert single.unwrapped.scenario == a.unwrapped.scenarios[1]


def test_bad_actions_and_arguments_raise():
    env = DebrisFieldVectorEnv(num_envs=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[0.0, 0.0], [np.nan, 0.0]], dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((3, 2), dtype=np.float32))
    with pytest.raises(ValueError, match="num_envs"):
        DebrisFieldVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="unknown config key"):
        DebrisFieldVectorEnv(num_envs=2, n_tragets=3)
    with pytest.raises(ValueError, match="seed list"):
        env.reset(seed=[1, 2, 3])
    with pytest.raises(RuntimeError, match="reset"):
        DebrisFieldVectorEnv(num_envs=1).step(np.zeros((1, 2), dtype=np.float32))


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 numba threads")
@pytest.mark.parametrize("observation", ["kinematics", "lidar"])
def test_two_threads_fly_exactly_the_episodes_of_one(observation):
    """num_threads splits the sub-envs into row ranges; nothing else may change (37 sub-envs:
    unequal ranges; a time limit of 60 steps: autoresets inside the threaded step)."""
    kw = dict(num_envs=37, max_episode_steps=60, observation=observation, n_obstacles=30)
    one, two = DebrisFieldVectorEnv(**kw), DebrisFieldVectorEnv(num_threads=2, **kw)
    (obs_1, info_1), (obs_2, info_2) = one.reset(seed=11), two.reset(seed=11)
    assert two.num_threads == 2 and one.num_threads == 1
    np.testing.assert_array_equal(obs_1, obs_2)
    np.testing.assert_array_equal(info_1["chaser_state"], info_2["chaser_state"])
    rng = np.random.default_rng(3)
    ended = 0
    for step in range(150):
        actions = rng.uniform(-0.6, 0.6, (37, 2)).astype(np.float32)
        out_1, out_2 = one.step(actions), two.step(actions)
        for name, a, b in zip(("obs", "reward", "terminated", "truncated"), out_1, out_2):
            np.testing.assert_array_equal(a, b, err_msg=f"{name} at step {step}")
        for key in INFO_KEYS:
            np.testing.assert_array_equal(out_1[4][key], out_2[4][key], err_msg=key)
        ended += int(np.sum(out_1[2] | out_1[3]))
    assert ended > 37  # every sub-env ended at least once


@pytest.mark.parametrize("bad", [0, 3.5, True, "2", 10_000])
def test_num_threads_out_of_range_is_refused(bad):
    with pytest.raises(ValueError, match=r"num_threads.*\[1, \d+\]"):
        DebrisFieldVectorEnv(num_envs=2, num_threads=bad)


def test_pinned_scenario_and_chaser_state():
    env = DebrisFieldVectorEnv(num_envs=2, delta_v_budget=None)
    scen = simple_scenario()
    states = np.array([[0.0, 92.0, 0.0, 0.0], [0.0, 50.0, 0.0, 0.0]])
    env.reset(seed=0, options={"scenario": scen, "chaser_state": states})
    assert all(s == scen for s in env.scenarios)
    _, _, _, _, info = env.step(np.zeros((2, 2), dtype=np.float32))
    np.testing.assert_array_equal(info["targets_captured"], [1, 0])
    with pytest.raises(ValueError, match="touches debris"):
        env.reset(options={"scenario": scen, "chaser_state": [200.0, 0.0, 0.0, 0.0]})


def test_a_random_field_after_a_pinned_one_gets_the_random_world():
    """The vector env sets the dock, bounds and length scale of random fields only where they
    may have changed: rows that held a pinned field (another size) must get them back."""
    env = DebrisFieldVectorEnv(num_envs=2)
    fresh = DebrisFieldVectorEnv(num_envs=2)
    env.reset(seed=1)
    scen = dataclasses.replace(env.scenarios[0], bounds=((-800.0, 800.0), (-700.0, 900.0)))
    env.reset(seed=0, options={"scenario": scen})
    assert env.batch.length_scale[0] == scen.size / 2.0
    obs, _ = env.reset(seed=4)
    ref, _ = fresh.reset(seed=4)
    np.testing.assert_array_equal(obs, ref)
    m, f = env.batch, fresh.batch
    for name in ("dock", "low", "high", "length_scale", "speed_scale"):
        np.testing.assert_array_equal(getattr(m, name), getattr(f, name), err_msg=name)


def test_a_pinned_field_of_other_targets_gets_a_batch_of_its_own():
    """Regression: a field with the same number of bodies but other targets was read with the
    batch's target count; a reset of every sub-env now makes the batch for the field's shape."""
    env = DebrisFieldVectorEnv(num_envs=2)
    env.reset(seed=0)
    scen = env.scenarios[0]
    last = scen.targets[-1]
    moved = Scenario(
        dim=2,
        bounds=scen.bounds,
        dock=scen.dock,
        targets=scen.targets[:-1],
        obstacles=(Body(position=last.position, radius=last.radius), *scen.obstacles),
        mean_motion=scen.mean_motion,
        dt=scen.dt,
        max_accel=scen.max_accel,
    )
    assert len(moved.bodies) == len(scen.bodies)
    _, info = env.reset(options={"scenario": moved})
    assert env.batch.n_targets == 2
    np.testing.assert_array_equal(info["n_targets"], [2, 2])


def test_a_pinned_field_flies_through_autoresets_until_the_next_reset():
    """Regression: a fresh vector env took a pinned field of other sizes, and the first
    autoreset drew a field of the env's own sizes into its batch and raised mid-step. A field
    pinned by ``reset`` is now every sub-env's field until the next ``reset``."""
    env = DebrisFieldVectorEnv(num_envs=2, max_episode_steps=3, delta_v_budget=None)
    scen = simple_scenario()
    with pytest.warns(UserWarning, match="physics differ"):
        env.reset(seed=0, options={"scenario": scen})
    for _ in range(6):  # a truncation, its autoreset, two steps of the next episode
        env.step(np.zeros((2, 2), dtype=np.float32))
    assert all(s is scen for s in env.scenarios)
    assert env.batch.missions.time[0] > 0.0
    env.reset(seed=0)
    fresh = DebrisFieldVectorEnv(num_envs=2, max_episode_steps=3, delta_v_budget=None)
    fresh.reset(seed=0)
    assert env.scenarios[1] == fresh.scenarios[1]  # the random fields of the seeds again


def test_pinned_polygons_with_many_vertices_load():
    """Regression: the batch held at most 8 polygon vertices; it now grows for a pinned field."""
    angles = np.linspace(0, 2 * math.pi, 12, endpoint=False)
    ring = tuple((30.0 * math.cos(a), 30.0 * math.sin(a)) for a in angles)
    scen = simple_scenario(
        obstacles=(
            Body(position=(200.0, 0.0), radius=30.0, vertices=ring),
            Body(position=(-200.0, 50.0), radius=20.0),
        )
    )
    kwargs = dict(n_targets=1, n_obstacles=2, mean_motion=0.0)
    env = DebrisFieldVectorEnv(num_envs=2, **kwargs)
    states = [[150.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]
    env.reset(options={"scenario": scen, "chaser_state": states})
    assert env.scenarios[1] == scen
    oracle = OracleField(scen)
    for point in ([150.0, 0.0], [200.0, 10.0], [-100.0, 40.0]):
        pts = np.array([point, point])
        expected = np.stack([oracle.point_gaps(pts[0])] * 2)
        np.testing.assert_allclose(env.batch.field.gaps(pts), expected, rtol=1e-9, atol=1e-9)
    # later random fields (at most 7 vertices) still load and read back exactly
    env.reset(seed=3)
    single_env = gym.make("DebrisGym/Rendezvous2D-v0", **kwargs)
    single_env.reset(seed=4)
    assert env.scenarios[1] == single_env.unwrapped.scenario


def test_scenarios_view_follows_autoresets():
    """``env.scenarios`` is built from the arrays on access; after an autoreset sub-env i holds
    the field the single env draws on its second reset from the same seed."""
    env = DebrisFieldVectorEnv(num_envs=3, max_episode_steps=2)
    env.reset(seed=10)
    assert len(env.scenarios) == 3
    assert env.scenarios[-1] == env.scenarios[2]
    assert env.scenarios[1:] == [env.scenarios[1], env.scenarios[2]]
    with pytest.raises(IndexError):
        env.scenarios[3]
    for _ in range(3):  # two steps end the episodes, the third resets them
        env.step(np.zeros((3, 2), dtype=np.float32))
    single = gym.make("DebrisGym/Rendezvous2D-v0")
    single.reset(seed=11)
    single.reset()
    assert env.scenarios[1] == single.unwrapped.scenario
    assert DebrisFieldVectorEnv(num_envs=2).scenarios[0] is None  # before the first reset


@pytest.mark.parametrize("kwargs", [{}, {"debris_motion": "bounded", "solid_targets": True}])
def test_field_arrays_stay_within_10_kib_per_sub_env(kwargs):
    """The default 2D field (23 bodies), frozen and moving: arrays held by the env and its batch,
    observation buffer excluded (as bench/run.py's memory section counts them)."""
    env = DebrisFieldVectorEnv(num_envs=8, **kwargs)
    env.reset(seed=0)
    owners = (vars(env), vars(env.batch), vars(env.batch.field))
    arrays = {id(v): v for owner in owners for v in owner.values() if isinstance(v, np.ndarray)}
    obs_shape = env.observation_space.shape  # the observation buffer is not state
    per_env = sum(a.nbytes for a in arrays.values() if a.shape != obs_shape) / env.num_envs
    assert per_env <= 10 * 1024


def random_fields(n: int, dim: int, seed: int = 0):
    spec = FieldSpec(dim=dim, n_obstacles=30)
    return [
        random_field(
            np.random.default_rng(seed + i), spec, mean_motion=0.0, dt=10.0, max_accel=0.05,
            capture_radius=5.0,
        )
        for i in range(n)
    ]  # fmt: skip


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("compact", [False, True])
def test_batch_geometry_matches_the_oracle(dim, compact):
    """Clearance, swept contacts and lidar of FieldBatch agree with the tests' independent
    geometry (pymunk in 2D, closed forms for spheres). ``compact``: polygon storage for the
    obstacles only, as the vector env keeps it.
    """
    n = 12
    fields = random_fields(n, dim, seed=10 * dim)
    start = len(fields[0].targets) if compact else 0
    batch = FieldBatch(n, len(fields[0].bodies), dim, polygon_start=start)
    for i, f in enumerate(fields):
        batch.load(i, f)
    singles = [OracleField(f, inflate=1.0) for f in fields]
    rng = np.random.default_rng(dim)
    dirs = lidar_directions(dim, 24)
    hits = 0
    for _ in range(60):
        a = rng.uniform(-500, 500, (n, dim))
        # aim half of the paths at a random body so that contacts are frequent
        aim = np.stack([f.body_positions()[rng.integers(len(f.bodies))] for f in fields])
        b = np.where(rng.uniform(size=(n, 1)) < 0.5, aim, a + rng.uniform(-120, 120, (n, dim)))
        t = np.linspace(0.0, 1.0, 4)[None, :, None]
        paths = a[:, None, :] * (1 - t) + b[:, None, :] * t
        gaps = batch.gaps(paths[:, 0])
        ref = np.stack([g.point_gaps(paths[i, 0]) for i, g in enumerate(singles)])
        np.testing.assert_allclose(gaps, ref, rtol=1e-9, atol=1e-9)
        touched = batch.touched(paths, gaps, 1.0)
        for i, g in enumerate(singles):
            assert list(np.flatnonzero(touched[i])) == g.touched(paths[i], ref[i])
        hits += int(touched.any(axis=1).sum())
        ranges = batch.lidar(paths[:, 0], dirs, 200.0)
        ref_ranges = np.stack([g.lidar(paths[i, 0], dirs, 200.0) for i, g in enumerate(singles)])
        np.testing.assert_allclose(ranges, ref_ranges, rtol=1e-9, atol=1e-9)
    assert hits > 20  # the comparison covered real contacts


def test_lidar_culling_changes_no_range():
    """FieldBatch.lidar tests a polygon's edges only for rays that enter its bounding circle
    before their nearest entry so far. Against every ray tested against every body (the same
    per-body primitives, no culling), the ranges must be equal exactly, from origins far out,
    near surfaces and at polygon centres (inside)."""
    from debris_gym import batch_geometry as bg

    n = 4
    fields = random_fields(n, 2, seed=77)
    batch = FieldBatch(n, len(fields[0].bodies), 2, polygon_start=len(fields[0].targets))
    for i, f in enumerate(fields):
        batch.load(i, f)
    dirs = lidar_directions(2, 16)
    rng = np.random.default_rng(5)
    for scale in (0.0, 2.0, 20.0, 400.0):
        k = rng.integers(batch.polygon_start, batch.n_bodies, n)
        origins = batch.centers[np.arange(n), k] + rng.normal(0.0, scale, (n, 2))
        for max_range in (60.0, 1e4):
            ranges = batch.lidar(origins, dirs, max_range)
            for i in range(n):
                ox, oy = origins[i]
                for r, (dx, dy) in enumerate(dirs):
                    best = math.inf
                    for b in range(batch.n_bodies):
                        j = b - batch.polygon_start
                        m = int(batch.n_vertices[i, j]) if j >= 0 else 0
                        cx, cy = batch.centers[i, b]
                        if m:
                            entry = bg._ray_polygon(ox, oy, dx, dy, cx, cy, batch.vertices[i, j], m)
                        else:
                            relx, rely = cx - ox, cy - oy
                            proj = dx * relx + dy * rely
                            perp2 = (relx * relx + rely * rely) - proj * proj
                            r2 = batch.radii[i, b] ** 2
                            half = math.sqrt(max(r2 - perp2, 0.0))
                            hit = perp2 <= r2 and proj + half >= 0.0
                            entry = max(proj - half, 0.0) if hit else math.inf
                        best = min(best, entry)
                    assert ranges[i, r] == min(best, max_range), (scale, i, r)


def test_fields_drawn_ahead_are_the_fields_drawn_at_reset_time():
    """The moving world's fields are drawn ahead on a worker thread; every episode must get the
    field a draw at its reset gives: the same observations, rewards and fields as with
    ``draw_ahead=False``, across autoresets, a failed reset, a mission change and reseeding."""
    n, rng = 16, np.random.default_rng(5)
    default = debris_gym.ENV_SPECS["DebrisGym/Rendezvous2D-v2"]["kwargs"]
    kwargs = dict(num_envs=n, max_episode_steps=25, **default)
    ahead = DebrisFieldVectorEnv(**kwargs, draw_ahead=True)
    plain = DebrisFieldVectorEnv(**kwargs, draw_ahead=False)
    easy = {"n_targets": 1, "n_obstacles": 5, "return_to_dock": False}
    resets = {
        0: dict(seed=3),
        60: dict(options={"mission": easy}),  # the same pending words, the new mission's fields
        90: dict(options={"mission": {}}),
        130: dict(seed=[7] * n),
        150: dict(),
    }
    for t in range(200):
        if t in resets:
            got = ahead.reset(**resets[t])[0], plain.reset(**resets[t])[0]
            np.testing.assert_array_equal(*got)
            with pytest.raises(ValueError, match="chaser_state"):
                ahead.reset(options={"chaser_state": [0.0, 0.0]})  # fails: nothing changes
            continue
        actions = rng.uniform(-1, 1, (n, 2))
        a, p = ahead.step(actions), plain.step(actions)
        for x, y in zip(a[:4], p[:4]):
            np.testing.assert_array_equal(x, y)
    assert ahead.scenarios[:] == plain.scenarios[:]
    assert ahead.shell.supply.moving  # the fields were drawn ahead
    ahead.close()
    plain.close()


def test_a_row_that_restarts_before_its_gathered_draw_is_handed_over_gets_its_own_field():
    """The rows to draw ahead are gathered over a few steps before the worker is woken
    (``field_supply.GATHER_CALLS``): with episodes of 2 steps every row restarts before its
    next field was handed over, so it is drawn at the restart, from the word a draw at reset
    time uses; the episodes equal those of ``draw_ahead=False``."""
    from debris_gym.envs import field_supply

    assert field_supply.GATHER_CALLS > 2  # else this test would not reach the path
    n, rng = 8, np.random.default_rng(11)
    default = debris_gym.ENV_SPECS["DebrisGym/Rendezvous2D-v2"]["kwargs"]
    kwargs = dict(num_envs=n, max_episode_steps=2, **default)
    ahead = DebrisFieldVectorEnv(**kwargs, draw_ahead=True)
    plain = DebrisFieldVectorEnv(**kwargs, draw_ahead=False)
    np.testing.assert_array_equal(ahead.reset(seed=4)[0], plain.reset(seed=4)[0])
    words = set()
    for _ in range(20):
        actions = rng.uniform(-1, 1, (n, 2))
        a, p = ahead.step(actions), plain.step(actions)
        for x, y in zip(a[:4], p[:4]):
            np.testing.assert_array_equal(x, y)
        words.update(ahead.shell.supply.taken_words.tolist())
    assert ahead.scenarios[:] == plain.scenarios[:]
    assert len(words) > 4 * n  # the rows went through many fields
    ahead.close()
    plain.close()


def test_a_vector_env_refused_at_construction_is_collected_quietly():
    """A constructor that refuses its options leaves a half-built env, which gymnasium's
    ``VectorEnv.__del__`` (gymnasium < 1.3) closes when it is collected: that close must not
    raise (it did, for want of a shell)."""
    import gc
    import sys

    DebrisFieldVectorEnv.__new__(DebrisFieldVectorEnv).close_extras()  # no shell: nothing to close
    seen = []
    hook, sys.unraisablehook = sys.unraisablehook, seen.append
    try:
        with pytest.raises(ValueError, match="num_threads"):
            DebrisFieldVectorEnv(num_envs=2, num_threads=0)
        gc.collect()
    finally:
        sys.unraisablehook = hook
    assert not seen, [str(s.exc_value) for s in seen]
