"""The hard evaluation suites: seeded 2D missions where plain APF falls into a local minimum, so
that APF-RRT's escape ([An23] §3) is exercised; selected, written and flown here.

Two suites follow the same rule (:data:`HARD_SUITES`): ``hard-v2`` on the v2 world (the
default, :data:`ENV_ID`) and ``hard`` on the v1 world, kept as it was for reproducing v1
figures. Selection rule (docs/baselines.md, "The hard suites"):

* fields: the suite's env (``DebrisGym/Rendezvous2D-v2``, or ``-v1`` for ``hard``) with
  :data:`ENV_KWARGS` (60 obstacles instead of 20, a 4 m smallest gap instead of 10 m: gaps the
  chaser cannot pass, so the debris forms the concave clusters where APF's minima live); reset
  seeds tried in order from the suite's first seed (``hard-v2``: 904 000 000, ``hard``:
  902 000 000; in the range kept for evaluation suites, ``debris_gym.suites.RESERVED_SEEDS``); a
  seed whose field the generator cannot place is skipped;
* kept when **plain APF stalls** — it fails, or its flight falls into a local minimum by the
  APF-RRT test (:class:`~agents.policies.apf_rrt.APFRRTAgent` with ``RRTParams(max_escapes=0)``
  flies exactly as APF and only counts the minima) — **and the mission is solvable**: the
  ``astar`` baseline completes it (success, no collision), or else ``apf-mpc`` does;
* the first :data:`SUITE_SIZE` kept missions, in seed order, are the suite.

Each file, ``debris_gym/suites/hard-v2.json.gz`` (``hard.json.gz`` for v1), is a
:mod:`debris_gym.suites` suite: ``evaluate.py --suite hard-v2`` flies it. Command lines::

    python -m agents.experiments.hard_suite select            # writes hard-v2.json.gz
    python -m agents.experiments.hard_suite select --suite hard   # the v1 file, as shipped
    python -m agents.experiments.hard_suite measure --agents apf,apf-rrt,apf-mpc,astar

``measure`` adds what ``evaluate.py`` does not record: how often APF-RRT detected a minimum and
escaped.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import debris_gym  # registers the IDs; locates the suite folder
from agents.experiments.cli import MAX_EPISODES, MAX_SEED, integer
from agents.planners.rrt import RRTParams
from agents.policies.base import unwrap
from agents.policies.registry import make_agent
from debris_gym.scenario import Scenario
from debris_gym.suites import RESERVED_SEEDS, Mission, Suite, read_suite, write_suite
from debris_gym.suites.build import git_commit

__all__ = [
    "DEFAULT_SUITE",
    "ENV_ID",
    "ENV_KWARGS",
    "FIRST_SEED",
    "HARD_SUITES",
    "SUITE_PATH",
    "SUITE_SIZE",
    "HardSuite",
    "MissionRow",
    "Screen",
    "fly_mission",
    "hard_suite",
    "main",
    "measure",
    "rows_markdown",
    "screen_seed",
    "select_missions",
]

ENV_KWARGS: dict[str, Any] = {"n_obstacles": 60, "min_gap": 4.0}
"""Options on top of the registered world: a denser field with gaps the chaser cannot pass."""

SUITE_SIZE = 30
"""Missions in a suite."""

SOLVERS = ("astar", "apf-mpc")
"""Baselines tried in turn to show that a mission is solvable."""

_SUITE_DIR = Path(debris_gym.__file__).resolve().parent / "suites"


@dataclass(frozen=True)
class HardSuite:
    """One hard suite: its name, the env its missions are drawn from and flown in, the first
    reset seed tried, and its file."""

    name: str
    env_id: str
    first_seed: int

    @property
    def path(self) -> Path:
        """Where the suite file is shipped."""
        return _SUITE_DIR / f"{self.name}.json.gz"

    @property
    def description(self) -> str:
        """The suite file's description."""
        world = self.env_id.split("/")[-1]
        return (
            f"{world} missions (60 obstacles, 4 m smallest gap) where plain APF stalls - it fails "
            "or its flight falls into a local minimum by the APF-RRT test - and a baseline "
            f"(astar, else apf-mpc) completes the mission; the first {SUITE_SIZE} such seeds from "
            f"{self.first_seed}. Selection: agents/experiments/hard_suite.py, docs/baselines.md."
        )


HARD_SUITES: dict[str, HardSuite] = {
    "hard-v2": HardSuite("hard-v2", "DebrisGym/Rendezvous2D-v2", 904_000_000),
    "hard": HardSuite("hard", "DebrisGym/Rendezvous2D-v1", 902_000_000),
}
"""The hard suites by name: ``hard-v2`` on the v2 world, ``hard`` on the v1 world (as shipped
for reproducing v1 figures)."""

DEFAULT_SUITE = "hard-v2"
"""The suite ``select`` and ``measure`` work on unless told otherwise."""

ENV_ID = HARD_SUITES[DEFAULT_SUITE].env_id
"""The env the default suite's missions are flown in."""

FIRST_SEED = HARD_SUITES[DEFAULT_SUITE].first_seed
"""First reset seed tried for the default suite (its seeds are this and above, inside the
reserved range)."""

SUITE_PATH = HARD_SUITES[DEFAULT_SUITE].path
"""Where the default suite's file is shipped."""


@dataclass(frozen=True)
class Screen:
    """What screening one seed found.

    Attributes:
        seed: the reset seed.
        apf_success: plain APF completed the mission.
        detections: local minima APF's flight fell into (the APF-RRT test).
        solved_by: the first baseline of :data:`SOLVERS` that completed it, or None (only
            tried when APF stalled).
        scenario: the field.
    """

    seed: int
    apf_success: bool
    detections: int
    solved_by: str | None
    scenario: Scenario

    @property
    def apf_stalled(self) -> bool:
        """Plain APF failed or fell into a local minimum."""
        return not self.apf_success or self.detections > 0

    @property
    def kept(self) -> bool:
        """The selection rule: APF stalled and the mission is solvable."""
        return self.apf_stalled and self.solved_by is not None


@dataclass(frozen=True)
class MissionRow:
    """One agent on one mission (Δv in m/s, time in s)."""

    agent: str
    seed: int
    success: bool
    collision: bool
    targets_captured: int
    delta_v: float
    time: float
    detections: int | None
    escapes: int | None


def _make_env(env_id: str = ENV_ID, env_kwargs: dict[str, Any] | None = None) -> gym.Env:
    # the checker wrapper cannot take a reset that raised (an unplaceable seed) and go on
    kwargs = ENV_KWARGS if env_kwargs is None else env_kwargs
    return gym.make(env_id, disable_env_checker=True, **kwargs)


def fly_mission(
    env: gym.Env, agent: Any, seed: int, scenario: Scenario | None = None
) -> dict[str, Any]:
    """Fly one episode from ``env.reset(seed=seed)`` (the field pinned if given); the last
    step's ``info``."""
    options = None if scenario is None else {"scenario": scenario}
    obs, info = env.reset(seed=seed, options=options)
    done = False
    while not done:
        action, _ = agent.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return info


def screen_seed(env: gym.Env, watcher: Any, solvers: dict[str, Any], seed: int) -> Screen | None:
    """Apply the selection rule to one seed (None: the generator cannot place its field).

    Args:
        env: the suite's env.
        watcher: an APF-RRT agent with ``RRTParams(max_escapes=0)`` built for ``env``.
        solvers: baseline name → agent built for ``env``, tried in order.
        seed: the reset seed.
    """
    try:
        info = fly_mission(env, watcher, seed)
    except ValueError as error:
        if "could not place" in str(error):
            return None
        raise
    scenario = unwrap(env).scenario
    if scenario is None:
        raise RuntimeError(f"the env has no field after reset(seed={seed})")
    apf_success = bool(info["is_success"])
    detections = int(watcher.detections)
    solved_by = None
    if not apf_success or detections > 0:
        for name, agent in solvers.items():
            result = fly_mission(env, agent, seed, scenario)
            if result["is_success"] and not result["collision"]:
                solved_by = name
                break
    return Screen(seed, apf_success, detections, solved_by, scenario)


def select_missions(
    count: int = SUITE_SIZE,
    first_seed: int = FIRST_SEED,
    progress: bool = True,
    env_id: str = ENV_ID,
) -> Iterator[Screen]:
    """Screen seeds of ``env_id`` (with :data:`ENV_KWARGS`) from ``first_seed`` in order; yield
    every screen, stop after ``count`` kept.

    Raises:
        ValueError: ``count`` < 1 or ``first_seed`` < 0.
    """
    from tqdm import tqdm

    if isinstance(count, bool) or int(count) != count or count < 1:
        raise ValueError(f"count must be an integer >= 1, got {count!r}")
    if isinstance(first_seed, bool) or int(first_seed) != first_seed or first_seed < 0:
        raise ValueError(f"first_seed must be an integer >= 0, got {first_seed!r}")
    env = _make_env(env_id)
    watcher = make_agent("apf-rrt", env, rrt=RRTParams(max_escapes=0))
    solvers = {name: make_agent(name, env) for name in SOLVERS}
    kept = 0
    seed = int(first_seed)
    bar = tqdm(
        total=count, desc="hard suite", unit="mission", file=sys.stderr, disable=not progress
    )
    try:
        while kept < count:
            screen = screen_seed(env, watcher, solvers, seed)
            seed += 1
            if screen is None:
                continue
            kept += screen.kept
            bar.update(int(screen.kept))
            bar.set_postfix_str(f"seed {screen.seed}, tried {seed - first_seed}", refresh=False)
            yield screen
    finally:
        bar.close()
        env.close()


def hard_suite(
    missions: Sequence[Screen], command: str, git: str, which: str = DEFAULT_SUITE
) -> Suite:
    """The suite ``which`` (a :data:`HARD_SUITES` name) of the kept ``missions``.

    Raises:
        ValueError: a seed outside the range reserved for suites.
    """
    spec = HARD_SUITES[which]
    outside = [m.seed for m in missions if m.seed not in RESERVED_SEEDS]
    if outside:
        raise ValueError(
            f"seeds {outside[:3]} lie outside the range reserved for suites "
            f"{RESERVED_SEEDS.start}…{RESERVED_SEEDS.stop - 1}; choose --first-seed inside it"
        )
    return Suite(
        name=spec.name,
        env_id=spec.env_id,
        description=spec.description,
        env_kwargs=dict(ENV_KWARGS),
        missions=tuple(Mission(m.seed, m.scenario) for m in missions),
        provenance={"command": command, "git": git},
    )


def measure(suite: Suite, agent_names: Sequence[str], progress: bool = True) -> list[MissionRow]:
    """Fly every agent on every mission of ``suite``; one row each."""
    from tqdm import tqdm

    missions = suite.missions
    env = gym.make(suite.env_id, **suite.env_kwargs)
    rows: list[MissionRow] = []
    bar = tqdm(
        total=len(agent_names) * len(missions),
        desc="measure",
        unit="ep",
        file=sys.stderr,
        disable=not progress,
    )
    try:
        for name in agent_names:
            agent = make_agent(name, env)
            for mission in missions:
                info = fly_mission(env, agent, mission.seed, mission.scenario)
                rows.append(
                    MissionRow(
                        agent=name,
                        seed=mission.seed,
                        success=bool(info["is_success"]),
                        collision=bool(info["collision"]),
                        targets_captured=int(info["targets_captured"]),
                        delta_v=float(info["delta_v"]),
                        time=float(info["time"]),
                        detections=getattr(agent, "detections", None),
                        escapes=getattr(agent, "escapes", None),
                    )
                )
                bar.update()
    finally:
        bar.close()
        env.close()
    return rows


def rows_markdown(rows: Sequence[MissionRow]) -> str:
    """Per-agent table: success, collisions, mean Δv and time over all missions and over the
    missions every agent completes, and the missions with an escape / detection."""
    names = list(dict.fromkeys(r.agent for r in rows))
    seeds = sorted({r.seed for r in rows})
    ok = {s for s in seeds if all(r.success for r in rows if r.seed == s)}
    lines = [
        f"{len(seeds)} missions; 'all complete' = the {len(ok)} every agent completes.",
        "",
        "| agent | success | collisions | Δv [m/s] | time [s] | Δv, all complete [m/s] | "
        "time, all complete [s] | missions escaped / detected |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in names:
        mine = [r for r in rows if r.agent == name]
        both = [r for r in mine if r.seed in ok]
        fired = "-"
        if mine[0].escapes is not None:
            esc = sum(1 for r in mine if r.escapes)
            det = sum(1 for r in mine if r.detections)
            fired = f"{esc} / {det} ({sum(r.escapes or 0 for r in mine)} escapes)"
        lines.append(
            f"| {name} | {sum(r.success for r in mine)} / {len(mine)} | "
            f"{sum(r.collision for r in mine)} | {np.mean([r.delta_v for r in mine]):.1f} | "
            f"{np.mean([r.time for r in mine]):.0f} | "
            f"{np.mean([r.delta_v for r in both]) if both else float('nan'):.1f} | "
            f"{np.mean([r.time for r in both]) if both else float('nan'):.0f} | {fired} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agents.experiments.hard_suite select|measure``."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.experiments.hard_suite", description=__doc__.split("\n\n")[0]
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sel = sub.add_parser("select", help="screen seeds and write the suite file")
    sel.add_argument(
        "--suite",
        choices=tuple(HARD_SUITES),
        default=DEFAULT_SUITE,
        help=f"which suite: its env, first seed and file (default: {DEFAULT_SUITE})",
    )
    sel.add_argument("--count", type=integer(1, MAX_EPISODES), default=SUITE_SIZE, help="missions")
    sel.add_argument(
        "--first-seed",
        type=integer(0, MAX_SEED),
        default=None,
        help="first seed tried (default: the suite's)",
    )
    sel.add_argument(
        "--out", type=Path, default=None, help="suite file to write (default: the suite's)"
    )
    sel.add_argument("--log", type=Path, default=None, help="also write every screen (JSONL)")
    mea = sub.add_parser("measure", help="fly baselines on the suite, print a table")
    mea.add_argument(
        "--suite",
        type=Path,
        default=SUITE_PATH,
        help=f"suite file to read (default: {DEFAULT_SUITE}'s, {SUITE_PATH.name})",
    )
    mea.add_argument("--agents", default="apf,apf-rrt,apf-mpc,astar", help="baselines, comma-sep")
    mea.add_argument(
        "--episodes", type=integer(1, MAX_EPISODES), default=None, help="fly the first N missions"
    )
    mea.add_argument("--json", type=Path, default=None, help="also write the rows (JSON)")
    args = parser.parse_args(argv)
    if args.command == "select":
        spec = HARD_SUITES[args.suite]
        first_seed = spec.first_seed if args.first_seed is None else args.first_seed
        out = spec.path if args.out is None else args.out
        if args.count < 1 or first_seed < 0:
            parser.error("--count must be >= 1 and --first-seed >= 0")
        command = "python -m agents.experiments.hard_suite " + " ".join(
            sys.argv[1:] if argv is None else argv
        )
        kept: list[Screen] = []
        log = None if args.log is None else open(args.log, "w", encoding="utf-8")
        try:
            for screen in select_missions(args.count, first_seed, env_id=spec.env_id):
                if screen.kept:
                    kept.append(screen)
                if log is not None:
                    row = {k: v for k, v in vars(screen).items() if k != "scenario"}
                    row["kept"] = screen.kept
                    log.write(json.dumps(row) + "\n")
                    log.flush()
        finally:
            if log is not None:
                log.close()
        write_suite(hard_suite(kept, command.strip(), git_commit(), spec.name), out)
        print(f"wrote {len(kept)} missions to {out}")
        return 0
    suite = read_suite(args.suite)
    if args.episodes is not None:
        if args.episodes < 1:
            parser.error("--episodes must be >= 1")
        suite = dataclasses.replace(suite, missions=suite.missions[: args.episodes])
    names = [n.strip() for n in args.agents.split(",") if n.strip()]
    rows = measure(suite, names)
    print(rows_markdown(rows))
    if args.json is not None:
        args.json.write_text(json.dumps([vars(r) for r in rows], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
