"""Regenerate the tables of docs/environments.md from the code (IDs, options, observation layout).

The observation tables and the option table's first value column describe the registered
default env, :data:`DEFAULT_ID` (its registration's keyword arguments over the constructor's
defaults); the option table also gives the constructor's own default.

python docs/gen_tables.py          # rewrite the tables in place
python docs/gen_tables.py --check  # exit 1 if the docs are out of date (used by the tests)
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from pathlib import Path

from debris_gym.config import OPTIONS, EnvConfig
from debris_gym.envs import DebrisFieldEnv
from debris_gym.files import write_atomic
from debris_gym.registration import ENV_SPECS

DOC = Path(__file__).with_name("environments.md")
DEFAULT_ID = "DebrisGym/Rendezvous2D-v2"
"""The ID the tables describe: the default of every script and headline figure."""

OBS_MEANING = [
    (r"chaser_pos_(\w)", "chaser position {0}", "m", "L"),
    (r"chaser_vel_(\w)", "chaser velocity {0}", "m/s", "V"),
    (r"target(\d+)_rel_pos_(\w)", "target slot {0}: target − chaser position, {1}", "m", "L"),
    (r"target(\d+)_rel_vel_(\w)", "target slot {0}: target − chaser velocity, {1}", "m/s", "V"),
    (r"target(\d+)_radius", "target slot {0}: target radius", "m", "L"),
    (r"target(\d+)_captured", "target slot {0}: 1 if captured (or empty slot), else 0", "", "1"),
    (
        r"target(\d+)_hold",
        "target slot {0}: step ends held / the step ends a capture needs (obs_hold)",
        "",
        "1",
    ),
    (r"dock_rel_pos_(\w)", "dock − chaser position, {0}", "m", "L"),
    (
        r"obstacle(\d+)_rel_pos_(\w)",
        "obstacle slot {0} (nearest first): centre − chaser {1}",
        "m",
        "L",
    ),
    (r"obstacle(\d+)_radius", "obstacle slot {0}: bounding radius", "m", "L"),
    (r"obstacle(\d+)_gap", "obstacle slot {0}: distance from chaser centre to surface", "m", "L"),
    (r"obstacle(\d+)_rel_vel_(\w)", "obstacle slot {0}: body − chaser velocity, {1}", "m/s", "V"),
    (r"lidar(\d+)", "lidar ray {0}: range to first surface", "m", "lidar_range"),
    (r"delta_v_remaining", "Δv budget left (1 without a budget)", "", "budget"),
    (r"time_remaining", "steps left of the registered limit", "", "max_episode_steps"),
    (r"goal_rel_pos_(\w)", "current goal − chaser position, {0} (obs_goal)", "m", "L/10"),
    (r"goal_rel_vel_(\w)", "current goal − chaser velocity, {0} (obs_goal)", "m/s", "V/10"),
    (r"goal_gap", "gap from the chaser's surface to the goal (obs_goal)", "m", "L/10"),
    (r"goal_near_gap", "gap to the goal, saturated at 4 (obs_near)", "m", "capture_radius"),
    (
        r"goal_near_closing",
        "speed toward the goal, saturated at ±4 (obs_near)",
        "m/s",
        "capture_speed",
    ),
]


def describe_obs(name: str) -> tuple[str, str, str]:
    for pattern, meaning, unit, scale in OBS_MEANING:
        m = re.fullmatch(pattern, name)
        if m:
            return meaning.format(*m.groups()), unit, scale
    raise KeyError(f"undocumented observation element {name!r}")


def registered_kwargs(env_id: str = DEFAULT_ID) -> dict:
    """The keyword arguments ``gym.make(env_id)`` passes to the env."""
    return dict(ENV_SPECS[env_id]["kwargs"])


def options_table() -> str:
    defaults = {f.name: f.default for f in dataclasses.fields(EnvConfig)}
    registered = {**defaults, **registered_kwargs()}
    name = DEFAULT_ID.split("/")[1]
    rows = [
        f"| key | unit | `{name}` | constructor default | allowed | meaning |",
        "|---|---|---|---|---|---|",
    ]
    for key, opt in OPTIONS.items():
        value = f"`{registered[key]!r}`"
        if registered[key] != defaults[key]:
            value = f"**{value}**"
        rows.append(
            f"| `{key}` | {opt.unit or '–'} | {value} | `{defaults[key]!r}` | {opt.describe()} "
            f"| {opt.doc} |"
        )
    return "\n".join(rows)


def ids_table() -> str:
    rows = ["| ID | max_episode_steps | keyword arguments |", "|---|---|---|"]
    for env_id, spec in ENV_SPECS.items():
        kwargs = ", ".join(f"`{k}={v!r}`" for k, v in spec["kwargs"].items())
        rows.append(f"| `{env_id}` | {spec['max_episode_steps']} | {kwargs} |")
    return "\n".join(rows)


def observation_table(env_id: str = DEFAULT_ID, **extra) -> str:
    env = DebrisFieldEnv(**{**registered_kwargs(env_id), **extra})
    low, high = env.observation_space.low, env.observation_space.high
    rows = ["| index | name | meaning | unit | divided by | min | max |", "|---" * 7 + "|"]
    for i, name in enumerate(env.observation_names()):
        meaning, unit, scale = describe_obs(name)
        bounds = f"{low[i]:g} | {high[i]:g}".replace("-", "−")
        rows.append(f"| {i} | `{name}` | {meaning} | {unit or '–'} | {scale} | {bounds} |")
    return "\n".join(rows)


def observation_sizes_table() -> str:
    """Observation length of every registered ID, in each observation mode at its defaults."""
    rows = [
        '| ID | `observation="kinematics"` | `observation="lidar"` |',
        "|---|--:|--:|",
    ]
    for env_id in ENV_SPECS:
        sizes = [
            DebrisFieldEnv(**{**registered_kwargs(env_id), "observation": mode}).observation_space
            for mode in ("kinematics", "lidar")
        ]
        rows.append(f"| `{env_id}` | {sizes[0].shape[0]} | {sizes[1].shape[0]} |")
    return "\n".join(rows)


def render(text: str) -> str:
    blocks = {
        "ids": ids_table(),
        "options": options_table(),
        "obs-2d": observation_table(),
        "obs-lidar-2d": observation_table(observation="lidar", lidar_rays=8),
        "obs-sizes": observation_sizes_table(),
    }
    for name, table in blocks.items():
        pattern = re.compile(rf"(<!-- table:{name} -->\n).*?(<!-- /table:{name} -->)", re.S)
        if not pattern.search(text):
            raise KeyError(f"marker for table {name!r} missing in {DOC}")
        text = pattern.sub(lambda m, t=table: m.group(1) + t + "\n" + m.group(2), text)
    return text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check, do not write")
    args = parser.parse_args()
    old = DOC.read_text()
    new = render(old)
    if args.check:
        if new != old:
            print(f"{DOC} is out of date: run python docs/gen_tables.py", file=sys.stderr)
            return 1
        return 0
    write_atomic(DOC, new)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
