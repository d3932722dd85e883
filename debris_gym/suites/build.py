"""Build the standard evaluation suites: ``python -m debris_gym.suites.build [NAME ...]``.

Each standard suite is the first ``count`` fields the registered env draws from consecutive
reset seeds starting at its ``first_seed`` (inside :data:`~debris_gym.suites.RESERVED_SEEDS`),
stored as scenarios so that a later change to the field generator cannot change the suite. The
command and the git commit go into the file's provenance. Without names, every standard suite is
(re)built into ``debris_gym/suites/``; ``--out DIR`` writes elsewhere (to compare with the
shipped files).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from debris_gym.suites import RESERVED_SEEDS, Mission, Suite, write_suite

__all__ = ["STANDARD_SUITES", "StandardSuite", "build_suite", "git_commit", "main"]


@dataclass(frozen=True)
class StandardSuite:
    """How a standard suite is drawn.

    Attributes:
        env_id: registered env that draws (and then flies) the fields.
        first_seed: reset seed of mission 0; mission i uses ``first_seed + i``.
        count: number of missions.
        description: the suite file's description.
        env_kwargs: ``gym.make`` options besides ``env_id``.
    """

    env_id: str
    first_seed: int
    count: int
    description: str
    env_kwargs: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if self.count < 1:
            raise ValueError(f"count must be >= 1, got {self.count}")
        last = self.first_seed + self.count - 1
        if self.first_seed not in RESERVED_SEEDS or last not in RESERVED_SEEDS:
            raise ValueError(
                f"seeds {self.first_seed}…{last} must lie in the reserved range "
                f"{RESERVED_SEEDS.start}…{RESERVED_SEEDS.stop - 1}"
            )


STANDARD_SUITES: dict[str, StandardSuite] = {
    "standard-2d-v1": StandardSuite(
        env_id="DebrisGym/Rendezvous2D-v1",
        first_seed=900_000_000,
        count=100,
        description="100 missions of DebrisGym/Rendezvous2D-v1 as registered (moving CWH "
        "field, 3 targets, 20 obstacles, return to dock), drawn from reset seeds "
        "900000000-900000099",
    ),
    "standard-3d-v1": StandardSuite(
        env_id="DebrisGym/Rendezvous3D-v1",
        first_seed=901_000_000,
        count=100,
        description="100 missions of DebrisGym/Rendezvous3D-v1 as registered (moving CWH "
        "field, 3 targets, 20 obstacles, return to dock), drawn from reset seeds "
        "901000000-901000099",
    ),
    "standard-2d-v2": StandardSuite(
        env_id="DebrisGym/Rendezvous2D-v2",
        first_seed=902_000_000,
        count=100,
        description="100 missions of DebrisGym/Rendezvous2D-v2 as registered (moving CWH "
        "field, 3 targets, 20 obstacles, return to dock; capture is a hold), drawn from reset "
        "seeds 902000000-902000099",
    ),
    "standard-3d-v2": StandardSuite(
        env_id="DebrisGym/Rendezvous3D-v2",
        first_seed=903_000_000,
        count=100,
        description="100 missions of DebrisGym/Rendezvous3D-v2 as registered (moving CWH "
        "field, 3 targets, 20 obstacles, return to dock; capture is a hold), drawn from reset "
        "seeds 903000000-903000099",
    ),
    "swarm-2d-v0": StandardSuite(
        env_id="DebrisGym/Swarm2D-v0",
        first_seed=906_000_000,
        count=50,
        description="50 missions of DebrisGym/Swarm2D-v0 as registered (3 chasers share 6 "
        "targets among 20 other debris, moving CWH field, each back at its own dock slot), "
        "drawn from reset seeds 906000000-906000049",
    ),
    "reconfigure-3d-v0": StandardSuite(
        env_id="DebrisGym/Reconfigure3D-v0",
        first_seed=907_000_000,
        count=20,
        description="20 missions of DebrisGym/Reconfigure3D-v0 with 48 chasers (the swarm of "
        "[Bandyopadhyay17]: 48 formation slots on shells around a body, 20 frozen debris), "
        "drawn from reset seeds 907000000-907000019",
        env_kwargs=(("n_chasers", 48),),
    ),
}
"""The standard suites, by name."""


def git_commit() -> str:
    """The checkout's commit (``git rev-parse HEAD``) for a suite's provenance, or "unknown"
    outside a git checkout."""
    root = Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() or "unknown"


def _swarm_missions(recipe: StandardSuite) -> list[Mission]:
    """The fields a swarm ID draws from the recipe's seeds (its PettingZoo env: the
    ``multiagent`` extra)."""
    from debris_gym import swarm

    env = swarm.make(recipe.env_id, **dict(recipe.env_kwargs))
    try:
        missions = []
        for i in range(recipe.count):
            seed = recipe.first_seed + i
            env.reset(seed=seed)
            scenario = env.core.shell.scenario(0)
            if scenario is None:
                raise RuntimeError(f"{recipe.env_id} has no field after reset(seed={seed})")
            missions.append(Mission(seed, scenario))
    finally:
        env.close()
    return missions


def build_suite(name: str, recipe: StandardSuite, command: str) -> Suite:
    """Draw ``recipe``'s fields from its env and return them as suite ``name``."""
    import gymnasium as gym

    import debris_gym  # noqa: F401  (registers the IDs)
    from debris_gym.envs import DebrisFieldEnv
    from debris_gym.swarm import SWARM_SPECS

    kwargs = dict(recipe.env_kwargs)
    if recipe.env_id in SWARM_SPECS:
        return Suite(
            name=name,
            env_id=recipe.env_id,
            description=recipe.description,
            env_kwargs=kwargs,
            missions=tuple(_swarm_missions(recipe)),
            provenance={"command": command, "git": git_commit()},
        )
    env = gym.make(recipe.env_id, **kwargs)
    try:
        field_env = env.unwrapped
        if not isinstance(field_env, DebrisFieldEnv):
            raise ValueError(f"env_id {recipe.env_id!r} is not a DebrisGym env")
        missions = []
        for i in range(recipe.count):
            seed = recipe.first_seed + i
            env.reset(seed=seed)
            scenario = field_env.scenario
            if scenario is None:
                raise RuntimeError(f"{recipe.env_id} has no field after reset(seed={seed})")
            missions.append(Mission(seed, scenario))
    finally:
        env.close()
    return Suite(
        name=name,
        env_id=recipe.env_id,
        description=recipe.description,
        env_kwargs=kwargs,
        missions=tuple(missions),
        provenance={"command": command, "git": git_commit()},
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m debris_gym.suites.build",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help=f"suites to build (default: all of {', '.join(STANDARD_SUITES)})",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).resolve().parent,
        metavar="DIR",
        help="directory for NAME.json.gz (default: the package's suites directory)",
    )
    args = parser.parse_args(argv)
    names = args.names or list(STANDARD_SUITES)
    unknown = [n for n in names if n not in STANDARD_SUITES]
    if unknown:
        parser.error(f"unknown suite(s) {unknown}; standard suites: {', '.join(STANDARD_SUITES)}")
    args.out.mkdir(parents=True, exist_ok=True)
    for name in names:
        suite = build_suite(
            name, STANDARD_SUITES[name], f"python -m debris_gym.suites.build {name}"
        )
        path = args.out / f"{name}.json.gz"
        write_suite(suite, path)
        print(f"{path}: {len(suite)} missions of {suite.env_id}, hash {suite.content_hash}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
