"""The Markdown report: a machine header, then one block of tables per section present.

:func:`format_report` takes the rows of :func:`bench.suite.run` (any subset of sections) and
returns the whole report; a section without rows leaves no trace in it. Cells show "–" for
what was not measured and ``error: …`` where a measurement failed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from bench.config import CARTPOLE, DEFAULT_OBSTACLES, ID_2D, ID_V1, field_size_for
from bench.decisions import DECISION_SEED
from bench.harness import RANDOM
from bench.machine import machine_description
from bench.swarm import SWARM_ID, VMAS_LABEL, VMAS_TASK

GOAL_CARTPOLE = 0.075
"""Goal: native 2D env-steps/s at CartPole's N ≥ this × CartPole-v1's native vector env."""
GOAL_CARTPOLE_RANDOM = 0.06
"""Goal: the same with uniformly random actions (episodes end often; resets included)."""
GOAL_SINGLE_RANDOM = 0.33
"""Goal: single 2D env steps/s through ``gym.make`` with uniformly random actions, resets
included, ≥ this × CartPole-v1's."""
GOAL_SYNC = 25.0
"""Goal: native env-steps/s ≥ this × gymnasium's SyncVectorEnv."""
GOAL_MEMORY = 12 * 1024
"""Limit: bytes of state per sub-env."""
GOAL_TRAIN = 20_000
"""Goal: end-to-end SB3 PPO env-steps/s."""
GOAL_VMAS = 5.0
"""Goal: swarm-core chaser-steps/s ≥ this × VMAS navigation's agent-steps/s at equal envs ×
agents, one thread, uniformly random actions on both sides."""
GOAL_VMAS_CHASERS = 48
"""The chasers per field K the VMAS goal is stated at (the other K are reported beside it)."""

BACKENDS = {
    "native": "native",
    "sync": "gymnasium `SyncVectorEnv`",
    "subproc": "SB3 `SubprocVecEnv`",
}
"""Vector row ``level`` → its name in the report."""


def format_report(
    rows: list[dict[str, Any]],
    *,
    command: str,
    elapsed: float,
    machine: list[str] | None = None,
) -> str:
    """Markdown report: machine description, then one block of tables per section present.

    Args:
        rows: rows of :func:`bench.suite.run`, of any sections.
        command: the command line to quote in the header.
        elapsed: wall time of the run (s).
        machine: the header's machine lines (default: :func:`machine_description` now; the CLI
            takes them before the run, so the load average is the one at its start).

    Returns:
        The report, ending in one newline; an "Errors" list closes it if any row has an error.
    """
    machine = machine_description() if machine is None else machine
    lines = ["# DebrisGym benchmark", "", *machine]
    lines += [f"- Command: `{command}`", f"- Wall time of the run: {elapsed:.0f} s", ""]
    tables: list[tuple[tuple[str, ...], Callable[[list[dict[str, Any]]], list[str]]]] = [
        (("step", "scaling", "reset"), _single_lines),
        (("vector",), _vector_lines),
        (("vector_scaling",), _vector_scaling_lines),
        (("shield",), _shield_lines),
        (("swarm",), _swarm_lines),
        (("memory",), _memory_lines),
        (("train",), _train_lines),
        (("decisions",), _decision_lines),
    ]
    for sections, table in tables:
        chosen = [r for r in rows if r["section"] in sections]
        if chosen:
            lines += table(chosen)
    errors = [r for r in rows if r["error"]]
    if errors:
        lines += ["## Errors", ""]
        lines += [f"- {_name_row(r)}: `{r['error']}`" for r in errors]
        lines.append("")
    while lines and not lines[-1]:
        lines.pop()
    return "\n".join(lines) + "\n"


def _single_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The single-env step, scaling and reset tables of the rows of those sections."""
    repeats = max((r["repeats"] for r in rows), default=0)
    lines = [
        f"Each cell: {repeats} interleaved repeats; *median* and *min* are µs per step over the "
        "repeats. Ratios come from the medians; in brackets the smallest and largest ratio of "
        "two measurements taken in the same repeat.",
        "",
        "## Single-env step cost",
        "",
        "Time inside `reset()` is excluded from step time; *steps/s incl. resets* includes it.",
        "",
        "| env | wrappers | steps/repeat | median µs/step | min µs/step | steps/s (median) "
        "| steps/s incl. resets | resets / 1000 steps | cost × CartPole (same wrappers) |",
        "|---|---|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for row in rows:
        if row["section"] != "step":
            continue
        wrappers = "gym.make" if row["level"] == "make" else "unwrapped"
        lines.append(_step_line(row, [_env_name(row), wrappers], _ratio(row)))
    explored = [
        r for r in rows
        if r["section"] == "step" and r["variant"] == RANDOM and math.isfinite(r["ratio_wall"])
    ]  # fmt: skip
    if explored:
        lines.append("")
    for r in explored:
        low, high = r["ratio_wall_range"]
        speed = 1.0 / r["ratio_wall"]
        lines.append(
            f"- uniformly random actions, resets included, `{r['env_id']}` through gym.make: "
            f"{speed:.3f}× CartPole's steps/s [{1.0 / high:.3f}, {1.0 / low:.3f}] "
            f"(goal ≥ {GOAL_SINGLE_RANDOM}×): {_verdict(speed, GOAL_SINGLE_RANDOM)}"
        )
    lines += [
        "",
        f"## Scaling with debris count (`{ID_2D}`, unwrapped)",
        "",
        "field_size = 1000 m · sqrt(max(1, n/20)), i.e. constant debris density above 20.",
        "",
        "| n_obstacles | field_size (m) | steps/repeat | median µs/step | min µs/step "
        "| steps/s (median) | steps/s incl. resets | resets / 1000 steps | cost × 20-debris "
        "| ms per in-loop reset |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    ref = next(
        (r for r in rows if (r["section"], r["env_id"], r["level"], r["variant"])
         == ("step", ID_2D, "unwrapped", "")),
        None,
    )  # fmt: skip
    scaling = [r for r in rows if r["section"] == "scaling"]
    if ref is not None:
        ref = {**ref, "n_obstacles": DEFAULT_OBSTACLES, "field_size": field_size_for(20)}
        ref["ratio"], ref["ratio_range"] = 1.0, (1.0, 1.0)
        scaling.append(ref)
    for row in sorted(scaling, key=lambda r: r["n_obstacles"]):
        n = row["n_obstacles"]
        label = f"{n} (default, reference)" if row is ref else str(n)
        extra = [_f(row["loop_reset_ms"], 1)]
        lines.append(_step_line(row, [label, _f(row["field_size"], 0)], _ratio(row), extra))
    lines += [
        "",
        "## Reset cost (through `gym.make`)",
        "",
        "| env | resets/repeat | median ms/reset | min ms/reset | cost × CartPole reset |",
        "|---|--:|--:|--:|--:|",
    ]
    for row in rows:
        if row["section"] != "reset":
            continue
        first = [_env_name(row), str(row["count"])]
        if row["error"]:
            lines.append(_error_row(first, row["error"], 2))
            continue
        cells = [*first, _f(row["median_us"] / 1e3, 3), _f(row["min_us"] / 1e3, 3), _ratio(row)]
        lines.append(_table_row(cells))
    return [*lines, ""]


def _vector_lines(vec: list[dict[str, Any]]) -> list[str]:
    """The vector throughput table and the goals it is held against."""
    warm = max(r["warmup_steps"] for r in vec)
    repeats = max(r["repeats"] for r in vec)
    sync = next((r for r in vec if r["level"] == "sync" and not r["variant"]), None)
    cart = next((r for r in vec if r["env_id"] == CARTPOLE), None)
    sync_n = sync["num_envs"] if sync else "–"
    cart_n = cart["num_envs"] if cart else "–"
    lines = _heading(
        "## Vector env throughput",
        f"env-steps/s = vector steps × N / seconds; {repeats} interleaved repeats after {warm} "
        "warm-up steps from `reset(seed=0)` (steady state: episodes end and autoreset all the "
        "time). Autoresets run inside `step` and are included. Actions: uniform in [-0.05, 0.05] "
        "of `max_accel` (DebrisGym), uniform {0, 1} (CartPole); rows `actions=random`: uniform "
        "in [-1, 1], as an exploring policy acts, so episodes end often (their × Sync is "
        "against Sync with random actions too). `SubprocVecEnv` runs one process "
        "per env (on 2 cores). *× Sync* is env-steps/s over `SyncVectorEnv`'s at "
        f"N={sync_n}: at equal N where N={sync_n}, otherwise against Sync's per-env rate (Sync "
        "steps its envs one after the other, so its env-steps/s does not depend on N). *× "
        f"CartPole* is env-steps/s over CartPole-v1's native vector env at N={cart_n}. In "
        "brackets: the smallest and largest ratio of two measurements taken in the same repeat.",
        "| backend | env | N | steps/repeat | env-steps/s (median) | env-steps/s (best) "
        "| µs per env-step | episodes ended / 1000 env-steps | `reset(seed)` ms per sub-env "
        f"| × Sync (N={sync_n}) | × CartPole native (N={cart_n}) |",
        "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    )
    for row in vec:
        first = [BACKENDS.get(row["level"], row["level"]), _env_name(row), str(row["num_envs"])]
        reset = "–" if row["level"] == "subproc" else _f(row["reset_ms_per_env"], 2)
        rest = [
            *_throughput_cells(row),
            reset,
            _range(row, "ratio_sync"),
            _range(row, "ratio_cartpole", 4),
        ]
        lines.append(_line(row, first, rest, "env_steps_per_s"))

    def native(n: int | None = None) -> list[dict[str, Any]]:
        return [
            r for r in vec
            if r["level"] == "native" and r["env_id"] == ID_2D and not r["variant"]
            and (n is None or r["num_envs"] == n) and math.isfinite(r["env_steps_per_s"])
        ]  # fmt: skip

    lines += ["", "Goals (2D, 20 debris, kinematics observations):", ""]
    explored = [
        r for r in vec
        if r["level"] == "native" and r["env_id"] in (ID_2D, ID_V1) and r["variant"] == RANDOM
        and math.isfinite(r["env_steps_per_s"])
    ]  # fmt: skip
    for r in explored:
        lines.append(
            f"- uniformly random actions, `{r['env_id']}` native N={r['num_envs']} / CartPole "
            f"native N={cart_n}: {_against(r['ratio_cartpole'], '.4f', GOAL_CARTPOLE_RANDOM)}; "
            f"/ SyncVectorEnv's per-env rate, random actions too: {_sync_goal(r['ratio_sync'])}"
        )
    at_cart = native(cart["num_envs"]) if cart else []
    if at_cart:
        r = at_cart[0]
        lines.append(
            f"- native N={r['num_envs']} / CartPole native N={cart_n}: "
            f"{_against(r['ratio_cartpole'], '.4f', GOAL_CARTPOLE)}"
        )
    if sync:
        equal = native(sync["num_envs"])
        if equal:
            r = equal[0]
            lines.append(
                f"- native / SyncVectorEnv at equal N={sync_n}: {_sync_goal(r['ratio_sync'])}"
            )
        best = max(native(), key=lambda r: r["ratio_sync"], default=None)
        if best is not None and math.isfinite(best["ratio_sync"]):
            lines.append(
                f"- best native (N={best['num_envs']}) / SyncVectorEnv's per-env rate: "
                f"{_sync_goal(best['ratio_sync'])}"
            )
    threaded = [
        r for r in vec
        if r["level"] == "native" and r["variant"].startswith("num_threads=")
        and math.isfinite(r["env_steps_per_s"])
    ]  # fmt: skip
    if threaded:
        lines += [
            "",
            "The same env with `num_threads=2` (two threads step the sub-envs; CartPole's "
            "native env and SyncVectorEnv use one):",
            "",
        ]
    for r in threaded:
        if r["num_envs"] == cart_n and cart:
            lines.append(
                f"- native N={r['num_envs']}, {r['variant']} / CartPole native N={cart_n}: "
                f"{_against(r['ratio_cartpole'], '.4f', GOAL_CARTPOLE)}; "
                f"{r['env_steps_per_s']:,.0f} env-steps/s"
            )
        if sync and math.isfinite(r["ratio_sync"]):
            lines.append(
                f"- native N={r['num_envs']}, {r['variant']} / SyncVectorEnv's per-env rate: "
                f"{_sync_goal(r['ratio_sync'])}"
            )
    return [*lines, ""]


def _vector_scaling_lines(scal: list[dict[str, Any]]) -> list[str]:
    """The vector env's table against the debris count."""
    lines = _heading(
        f"## Vector env: scaling with debris count (`{ID_2D}`, native)",
        "field_size = 1000 m · sqrt(max(1, n/20)). Timed right after `reset(seed=0)` (a few "
        "warm-up steps, then at most "
        f"{max(r['warmup_steps'] + r['count'] * r['repeats'] for r in scal)} steps in all), so "
        "this is the *step* cost with (almost) no autoresets; the reset cost per sub-env is the "
        "first `reset(seed=0)` of all N sub-envs divided by N. Cost is relative to 20 debris at "
        "the same N.",
        "| n_obstacles | field_size (m) | N | steps/repeat | env-steps/s (median) "
        "| env-steps/s (best) | µs per env-step | episodes ended / 1000 env-steps "
        "| `reset(seed)` ms per sub-env | cost × 20 debris (same N) |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    )
    for row in scal:
        n = row["n_obstacles"]
        label = f"{n} (reference)" if n == DEFAULT_OBSTACLES else str(n)
        first = [label, _f(row["field_size"], 0), str(row["num_envs"])]
        rest = [*_throughput_cells(row), _f(row["reset_ms_per_env"], 2), _range(row, "ratio")]
        lines.append(_line(row, first, rest, "env_steps_per_s"))
    return [*lines, ""]


def _shield_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The compiled shield's cost per decision in the vector env."""
    n = rows[0]["num_envs"]
    lines = _heading(
        f"## Compiled safety shield in the vector env (native, N={n}, one thread)",
        "Uniformly random actions; each env timed with `shield=False` and `shield=True` in "
        "interleaved rounds. µs per decision = µs per env-step with the shield − without, "
        "per round (median and range over the rounds); decisions changed per 1000 counted "
        "from `info['shield_intervened']`.",
        "| env | shield | steps/repeat | env-steps/s (median) | env-steps/s (best) "
        "| µs per env-step | episodes ended / 1000 env-steps | decisions changed / 1000 "
        "| µs per decision (range) |",
        "|:--|:--|--:|--:|--:|--:|--:|--:|--:|",
    )
    for row in rows:
        cost = "–"
        if math.isfinite(row["us_per_decision"]):
            lo, hi = row["us_per_decision_range"]
            cost = f"{row['us_per_decision']:.1f} ({lo:.1f}–{hi:.1f})"
        first = [f"`{row['env_id']}`", "on" if row["shield"] else "off"]
        rest = [*_throughput_cells(row), _f(row["intervened_per_1000"], 1), cost]
        lines.append(_line(row, first, rest, "env_steps_per_s"))
    return [*lines, ""]


def _swarm_lines(swarm: list[dict[str, Any]]) -> list[str]:
    """The swarm table against VMAS and the goal it is held against."""
    repeats = max(r["repeats"] for r in swarm)
    warm = {r["level"]: r["warmup_steps"] for r in swarm}
    lines = _heading(
        f"## Swarm throughput (`{SWARM_ID}` swarm core against {VMAS_LABEL})",
        "chaser-steps/s = steps × E fields × K chasers / seconds, all on one thread (torch "
        f"pinned to 1). {repeats} interleaved repeats after {warm.get('native', '–')} warm-up "
        f"steps (swarm core) and {warm.get('vmas', '–')} (VMAS) from the first reset. A swarm "
        "step: the (E·K, 2) actions checked, `SwarmCore.step`, `restart` of the fields whose "
        "chasers have all ended, `observe()` of every chaser; a chaser that ended keeps its row, "
        "idle, until its field restarts (*rows flying*). Actions: uniform in [-0.05, 0.05] of "
        "`max_accel`, rows `actions=random` uniform in [-1, 1]. VMAS: `env.step` of K (E, 2) "
        "uniformly random actions, the done envs reset as TorchRL's `VmasWrapper` does "
        f"(BenchMARL's navigation task: `max_steps={VMAS_TASK['max_steps']}`, collisions and "
        "lidar on, no obstacles; spawn square grown with K). *× VMAS* = chaser-steps/s over the "
        "VMAS row's at the same E and K; in brackets the smallest and largest ratio of two "
        "measurements taken in the same repeat; *flying rows only* counts the swarm's rows that "
        "flew (× rows flying), as every VMAS agent moves every step. *% of time in restarts*: "
        "the swarm core's `restart`, VMAS's resets and the observations read after them, "
        "clocked inside the timed loop.",
        "| simulator | K | E | steps/repeat | chaser-steps/s (median) | chaser-steps/s (best) "
        "| µs per chaser-step | rows flying % | chasers ended / 1000 chaser-steps "
        "| fields restarted / 1000 chaser-steps | % of time in restarts | obs size "
        "| × VMAS (same E × K) | × VMAS, flying rows only |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    )
    for row in swarm:
        name = "swarm core" if row["level"] == "native" else VMAS_LABEL
        if row["variant"]:
            name += f" {row['variant']}"
        first = [name, str(row["chasers"]), str(row["num_envs"])]
        rest = [
            str(row["count"]),
            _f(row["chaser_steps_per_s"], 0),
            _f(row["chaser_steps_per_s_best"], 0),
            _f(row["us_per_chaser_step"], 2),
            _f(100 * row["flying_share"], 0),
            _f(row["ends_per_1000"], 2),
            _f(row["resets_per_1000"], 2),
            _f(100 * row["reset_share"], 1),
            str(row["obs_size"] or "–"),
            _range(row, "ratio_vmas", 1),
            _f(row["ratio_vmas_flying"], 1),
        ]
        lines.append(_line(row, first, rest, "chaser_steps_per_s"))
    lines += [
        "",
        f"Goal: swarm core ≥ {GOAL_VMAS:g}× VMAS at equal envs × agents, one thread, uniformly "
        f"random actions (stated at K = {GOAL_VMAS_CHASERS}):",
        "",
    ]
    for row in swarm:
        if row["level"] != "native" or row["variant"] != RANDOM:
            continue
        lines.append(
            f"- K={row['chasers']}, E={row['num_envs']}: {_range(row, 'ratio_vmas', 1)}× "
            f"(goal ≥ {GOAL_VMAS:g}×): {_verdict(row['ratio_vmas'], GOAL_VMAS)}; flying rows "
            f"only {_f(row['ratio_vmas_flying'], 1)}×: "
            f"{_verdict(row['ratio_vmas_flying'], GOAL_VMAS)}"
            + (" (the goal's K)" if row["chasers"] == GOAL_VMAS_CHASERS else "")
        )
    return [*lines, ""]


def _memory_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The memory summary (of the first memory row) and its biggest arrays."""
    row = rows[0]
    lines = [f"## Memory per sub-env (`{ID_2D}`, native, {DEFAULT_OBSTACLES} debris)", ""]
    if row["error"]:
        return [*lines, f"error: {row['error']}", ""]
    small, large = row["small_envs"], row["large_envs"]
    py = row["python_bytes_per_env"]
    a = row["array_bytes_per_env"]
    b = row["rss_per_env"]
    lines += [
        "Each instance is built in a fresh process (`python bench/run.py --memory-child N`), "
        "after a 1-env instance was built, reset and dropped (imports and one-off caches are not "
        f"counted). Bodies per field: {row['n_bodies']} (targets + debris).",
        "",
        "- (a) numpy arrays held by the env, its `MissionBatch` and its `FieldBatch` at "
        f"N={large}, observation "
        f"buffer excluded: **{a:,.0f} B per sub-env ({a / 1024:.2f} KiB)**; the observation "
        f"buffer adds {row['obs_buffer_bytes_per_env']:,.0f} B",
        f"- Python objects per sub-env (deep `sys.getsizeof`): `scenarios` "
        f"{py.get('scenarios', math.nan):,.0f} B, per-sub-env generators "
        f"{py.get('rngs', math.nan):,.0f} B",
        f"- (b) RSS growth on build + `reset(seed=0)`: {row['rss_growth'][small] / 2**20:,.2f} MiB "
        f"at N={small}, {row['rss_growth'][large] / 2**20:,.2f} MiB at N={large}; (difference) "
        f"/ {large - small} envs = **{b:,.0f} B per sub-env ({b / 1024:.2f} KiB)**; after 10 "
        f"more steps {row['rss_steps_per_env']:,.0f} B",
        f"- Goal ≤ {GOAL_MEMORY // 1024} KiB per sub-env: arrays only (a) "
        f"{_verdict(a, GOAL_MEMORY, higher=False)}; RSS (b) {_verdict(b, GOAL_MEMORY, False)}",
        "",
        f"Biggest arrays (N={large}):",
        "",
        "| array | shape | dtype | bytes | bytes per sub-env |",
        "|---|---|---|--:|--:|",
    ]
    for arr in row["arrays"][:10]:
        name = f"`{arr['owner']}.{arr['name']}`"
        if arr["observation_buffer"]:
            name += " (observation buffer, excluded)"
        shape = "×".join(str(s) for s in arr["shape"])
        cells = [name, shape, arr["dtype"], f"{arr['nbytes']:,}", f"{arr['nbytes'] / large:,.0f}"]
        lines.append(_table_row(cells))
    rest = row["arrays"][10:]
    if rest:
        total = sum(x["nbytes"] for x in rest)
        lines.append(f"| {len(rest)} more | | | {total:,} | {total / large:,.0f} |")
    return [*lines, ""]


def _train_lines(train: list[dict[str, Any]]) -> list[str]:
    """The PPO throughput table and the goal it is held against."""
    lines = _heading(
        f"## Training throughput (SB3 PPO on `{ID_2D}`)",
        '`PPO("MlpPolicy", venv, n_steps, batch_size, n_epochs, device="cpu")`, torch with 1 '
        "thread. Timed: `model.learn(rollouts × n_steps × N, reset_num_timesteps=False)` after "
        "one warm-up rollout + update (which also did the env reset). The split: *env* = time "
        "in the VecEnv's `step` (adapter included), *policy & rest* = the rest of "
        "`collect_rollouts` (policy forward, buffer, SB3 bookkeeping), *update* = the rest of "
        "`learn` (`train()`). *× Dummy* = end-to-end env-steps/s over the DummyVecEnv row's "
        "(paired range in brackets). The DummyVecEnv holds single envs made by `gym.make`.",
        "| VecEnv | N | n_steps | batch | epochs | timed env-steps | env-steps/s end to end "
        "(median) | best | × Dummy | env % | policy & rest % | update % | rollout env-steps/s "
        "| env-only env-steps/s | policy forward ms (N obs) | episodes ended / 1000 |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    )
    for row in train:
        first = [f"`{row['level']}`", str(row["num_envs"])]
        rest = [
            str(row["n_steps"]),
            str(row["batch_size"]),
            str(row["n_epochs"]),
            f"{row['timesteps']:,}",
            _f(row["env_steps_per_s"], 0),
            _f(row["env_steps_per_s_best"], 0),
            _range(row, "ratio_dummy"),
            _f(100 * row["env_share"], 0),
            _f(100 * row["policy_share"], 0),
            _f(100 * row["update_share"], 0),
            _f(row["rollout_env_steps_per_s"], 0),
            _f(row["env_only_steps_per_s"], 0),
            _f(row["forward_ms"], 2),
            _f(row["ends_per_1000"], 2),
        ]
        lines.append(_line(row, first, rest, "env_steps_per_s"))
    lines += ["", f"Goal ≥ {GOAL_TRAIN:,} env-steps/s end to end:", ""]
    for row in train:
        if row["level"] == "NativeVecEnv":
            lines.append(
                f"- `NativeVecEnv` N={row['num_envs']}: {_f(row['env_steps_per_s'], 0)} "
                f"env-steps/s: {_verdict(row['env_steps_per_s'], GOAL_TRAIN)}"
            )
    return [*lines, ""]


def _decision_lines(decisions: list[dict[str, Any]]) -> list[str]:
    """The decision-time table."""
    episodes = max((r["episodes"] for r in decisions), default=0)
    step_us = next((r["env_step_us"] for r in decisions if math.isfinite(r["env_step_us"])), None)
    lines = _heading(
        f"## Decision times (`{ID_2D}`)",
        f"Every agent flies the same {episodes} mission(s) of the default evaluation (`python "
        f"evaluate.py`, reset seeds {DECISION_SEED}, {DECISION_SEED + 1}, …), mission by mission "
        "in turn, and every `agent.predict(obs, state, episode_start, deterministic=True)` call "
        "is timed (`time.perf_counter`); a few untimed calls on another mission come first "
        "(compilation, model loading). A classical agent plans inside the first call of a "
        "mission (APF-MPC and A* plan again after each capture, or when the chaser strays from "
        "the path), so *p95* and *max* include planning; *first call* is the median over the "
        "missions' first calls, *later calls* the median of all the others. `NAME+shield` "
        "flies behind the safety shield (`evaluate.py --shield`): its calls include the "
        "shield's check of each command and, when one is unsafe, its search for a safe one. "
        "*p50 in env "
        "steps* = p50 over the median "
        "`env.step` of the same env through `gym.make`"
        + (f" ({step_us:.1f} µs)" if step_us is not None else "")
        + ", timed between the missions in the same run.",
        "| agent | missions | decisions | successes | p50 ms | p95 ms | max ms "
        "| first call ms | later calls p50 ms | p50 in env steps |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    )
    for row in decisions:
        where = f" on `{row['env_id']}`" if row["env_id"] != ID_2D else ""
        first = [f"`{row['agent']}`{where}"]
        rest = [
            str(row["episodes"]),
            f"{row['decisions']:,}",
            str(row["successes"]),
            _f(row["p50_ms"], 3),
            _f(row["p95_ms"], 3),
            _f(row["max_ms"], 2),
            _f(row["first_ms"], 2),
            _f(row["later_p50_ms"], 3),
            _f(row["p50_steps"], 1),
        ]
        lines.append(_line(row, first, rest, "p50_ms"))
    return [*lines, ""]


def _step_line(
    row: dict[str, Any], first: list[str], ratio: str, extra: list[str] | None = None
) -> str:
    rest = [
        str(row["count"]),
        _f(row["median_us"], 2),
        _f(row["min_us"], 2),
        _f(row["steps_per_s"], 0),
        _f(row["steps_per_s_wall"], 0),
        _f(row["resets_per_1000"], 2),
        ratio,
        *(extra or []),
    ]
    return _line(row, first, rest, "median_us")


def _throughput_cells(row: dict[str, Any]) -> list[str]:
    """A vector row's steps per repeat, env-steps/s (median, best), µs per env-step and
    episodes ended per 1000 env-steps."""
    return [
        str(row["count"]),
        _f(row["env_steps_per_s"], 0),
        _f(row["env_steps_per_s_best"], 0),
        _f(row["us_per_env_step"], 2),
        _f(row["ends_per_1000"], 2),
    ]


def _name_row(row: dict[str, Any]) -> str:
    extra = f" n_obstacles={row['n_obstacles']}" if row["n_obstacles"] is not None else ""
    if row.get("num_envs") is not None:
        extra += f" N={row['num_envs']}"
    return f"{row['section']} {_env_name(row)}{extra} ({row['level']})"


def _env_name(row: dict[str, Any]) -> str:
    name = f"`{row['env_id']}`"
    return f"{name} {row['variant']}" if row["variant"] else name


def _f(x: float, digits: int = 1) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:,.{digits}f}"


def _ratio(row: dict[str, Any]) -> str:
    lo, hi = row["ratio_range"]
    if not math.isfinite(row["ratio"]):
        return "–"
    return f"{row['ratio']:.2f} ({lo:.2f}–{hi:.2f})"


def _range(row: dict[str, Any], key: str, digits: int = 2) -> str:
    value = row.get(key, math.nan)
    if value is None or not math.isfinite(value):
        return "–"
    lo, hi = row[key + "_range"]
    return f"{value:.{digits}f} ({lo:.{digits}f}–{hi:.{digits}f})"


def _verdict(value: float, goal: float, higher: bool = True) -> str:
    """ "met" / "missed", with the value as a multiple of the goal (a floor, or a limit)."""
    if not math.isfinite(value):
        return "not measured"
    met = value >= goal if higher else value <= goal
    what = "the goal" if higher else "the limit"
    return f"{'met' if met else 'missed'} ({value / goal:.2f}× {what})"


def _against(ratio: float, digits: str, goal: float, goal_digits: str = "") -> str:
    """A measured ratio against the goal it is held to, and the verdict: ``ratio`` (formatted
    with ``digits``, e.g. ``".4f"``) ``× (goal ≥ goal×): met (…)``."""
    return f"{ratio:{digits}}× (goal ≥ {goal:{goal_digits}}×): {_verdict(ratio, goal)}"


def _sync_goal(ratio: float) -> str:
    """A native / SyncVectorEnv ratio against :data:`GOAL_SYNC` (:func:`_against`)."""
    return _against(ratio, ".1f", GOAL_SYNC, ".0f")


def _heading(title: str, text: str, header: str, align: str) -> list[str]:
    """The lines that open a section: its title, a paragraph, a table's header and alignment."""
    return [title, "", text, "", header, align]


def _table_row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _line(row: dict[str, Any], first: list[str], rest: list[str], measured: str) -> str:
    """A table row of ``first`` and ``rest`` cells; where the measurement failed and left
    ``row[measured]`` unmeasured, the error message and empty cells in place of ``rest``."""
    if row["error"] and not math.isfinite(row[measured]):
        return _error_row(first, row["error"], len(rest) - 1)
    return _table_row([*first, *rest])


def _error_row(first: list[str], error: str, blanks: int) -> str:
    """A table row whose measurement failed: the leading cells, the message, empty cells."""
    return _table_row([*first, f"error: {error}"] + [""] * blanks)
