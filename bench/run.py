"""Step and reset throughput of the DebrisGym environments, relative to CartPole-v1.

Run as a script::

    python bench/run.py            # full run (~2-3 min on a 2-core machine)
    python bench/run.py --quick    # ~30 s, fewer / shorter repeats
    python bench/run.py --out docs/bench_table.md

Everything is measured in one process, in one run, and reported as *ratios* measured within that
run: absolute speeds on shared machines are noisy and only comparable inside a run. Measurements
are interleaved across repeats (A, B, C, A, B, C, …) so that machine noise hits them alike; each
cell reports the median and the best (minimum time) of the repeats.

What is timed:

* Step rows: ``env.step(a)`` over pre-generated valid actions (small random thrusts, uniform in
  [-0.05, 0.05] of ``max_accel``, for continuous DebrisGym envs; mostly coasting for discrete
  ones; uniform {0, 1} for CartPole), both through ``gym.make`` (default wrappers) and on
  ``env.unwrapped``. On termination / truncation the env is reset; the step that ended the
  episode counts as a step, but the time spent *inside* ``reset()`` is excluded from the step
  time (the clock is stopped around it). "steps/s incl. resets" is the plain wall-clock rate with
  the resets included. Resets are costed separately in the reset table.
* Scaling rows: the unwrapped 2D env with ``n_obstacles`` debris in a field whose edge grows as
  ``1000 m * sqrt(max(1, n / 20))`` (constant debris density), relative to the 20-debris default.
* Reset rows: ``env.reset()`` through ``gym.make``; a random-field env draws a new field (and
  checks it is solvable) on every reset.

The number of steps (resets) per repeat is calibrated per measurement during a warm-up so every
repeat lasts about the same wall time, unless fixed with ``run(steps=…, resets=…)``.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import debris_gym

if "torch" in sys.modules:  # not needed here; only pin threads if something imported it
    sys.modules["torch"].set_num_threads(1)

DEBRIS_IDS = tuple(debris_gym.ENV_SPECS)
CARTPOLE = "CartPole-v1"
ID_2D = "DebrisGym/Rendezvous2D-v0"
SCALING_COUNTS = (10, 50, 200, 1000)
DEFAULT_OBSTACLES = 20
THRUST = 0.05  # continuous actions are uniform in [-THRUST, THRUST] (fraction of max_accel)
DISCRETE_COAST = 0.9  # share of coast (0) actions for discrete DebrisGym envs

QUICK = {"repeats": 3, "step_seconds": 0.12, "reset_seconds": 0.1, "min_steps": 50}
FULL = {"repeats": 5, "step_seconds": 0.9, "reset_seconds": 0.6, "min_steps": 200}
MAX_STEPS = 300_000
MAX_RESETS = 20_000


def field_size_for(n_obstacles: int) -> float:
    """Field edge (m) for ``n_obstacles`` debris at the default density (20 per 1000 m square)."""
    return 1000.0 * math.sqrt(max(1.0, n_obstacles / DEFAULT_OBSTACLES))


# --- measurements ---------------------------------------------------------------------------------


@dataclass
class Measurement:
    """One thing to time: set up once, then timed once per repeat (interleaved with the others)."""

    section: str  # "step", "scaling" or "reset"
    label: str
    env_id: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    level: str = "make"  # "make" (default wrappers) or "unwrapped"
    n_obstacles: int | None = None
    count: int = 0  # steps (or resets) per repeat
    times: list[float] = field(default_factory=list)  # seconds per repeat, excluding resets
    walls: list[float] = field(default_factory=list)  # seconds per repeat, including resets
    resets: int = 0  # resets during step repeats
    reset_time: float = 0.0  # seconds spent in those resets
    error: str | None = None
    env: Any = None
    actions: list[Any] = field(default_factory=list)


def _make(m: Measurement) -> Any:
    env = gym.make(m.env_id, **m.kwargs)
    return env.unwrapped if m.level == "unwrapped" else env


def _actions(m: Measurement, n: int, rng: np.random.Generator) -> list[Any]:
    """``n`` valid actions, generated up front so sampling is not timed."""
    space = m.env.action_space
    if isinstance(space, gym.spaces.Discrete):
        if m.env_id != CARTPOLE:
            thrust = rng.integers(1, int(space.n), size=n)
            values = np.where(rng.random(n) < DISCRETE_COAST, 0, thrust)
        else:
            values = rng.integers(0, int(space.n), size=n)
        return [int(v) for v in values]
    assert isinstance(space, gym.spaces.Box)
    values = rng.uniform(-THRUST, THRUST, size=(n, *space.shape)).astype(space.dtype)
    return list(values)


def _step_loop(env: Any, actions: list[Any]) -> tuple[float, float, int]:
    """Step through ``actions``; returns (step seconds excluding resets, wall seconds, resets).

    The clock is read only around resets, not around every step, so the per-step overhead of
    the harness is one loop iteration and one tuple unpack (the same for every env).
    """
    step, reset, clock = env.step, env.reset, time.perf_counter
    stepping = 0.0
    resets = 0
    start = segment = clock()
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            now = clock()
            stepping += now - segment
            reset()
            resets += 1
            segment = clock()
    end = clock()
    return stepping + (end - segment), end - start, resets


def _reset_loop(env: Any, n: int) -> float:
    reset, clock = env.reset, time.perf_counter
    start = clock()
    for _ in range(n):
        reset()
    return clock() - start


def _calibrated(per_item: float, seconds: float, low: int, high: int) -> int:
    return int(min(high, max(low, round(seconds / max(per_item, 1e-9)))))


def _setup(m: Measurement, cfg: dict[str, Any], steps: int | None, resets: int | None) -> None:
    """Build the env, warm it up, fix the count per repeat and pre-generate the actions."""
    m.env = env = _make(m)
    env.reset(seed=0)
    rng = np.random.default_rng(12345)
    if m.section == "reset":
        per = _reset_loop(env, 3) / 3
        m.count = (
            resets if resets is not None else _calibrated(per, cfg["reset_seconds"], 3, MAX_RESETS)
        )
        return
    warm = 200 if steps is None else min(steps, 20)
    t, _, _ = _step_loop(env, _actions(m, warm, rng))
    if steps is not None:
        m.count = steps
    else:
        m.count = _calibrated(t / warm, cfg["step_seconds"], cfg["min_steps"], MAX_STEPS)
    m.actions = _actions(m, m.count, rng)
    env.reset(seed=1)


def _measure(m: Measurement) -> None:
    if m.section == "reset":
        t = _reset_loop(m.env, m.count)
        m.times.append(t)
        m.walls.append(t)
        return
    t, wall, r = _step_loop(m.env, m.actions)
    m.times.append(t)
    m.walls.append(wall)
    m.resets += r
    m.reset_time += wall - t


def measurements() -> list[Measurement]:
    """The measurement list, in the order they are interleaved."""
    out: list[Measurement] = []
    variants: list[tuple[str, str, dict[str, Any]]] = [(CARTPOLE, "", {})]
    variants += [(env_id, "", {}) for env_id in DEBRIS_IDS]
    variants += [(ID_2D, "observation=lidar", {"observation": "lidar"})]
    variants += [(ID_2D, "action=discrete", {"action": "discrete"})]
    for level in ("make", "unwrapped"):
        for env_id, label, kwargs in variants:
            out.append(Measurement("step", label, env_id, kwargs, level))
    for n in SCALING_COUNTS:
        kwargs = {"n_obstacles": n, "field_size": field_size_for(n)}
        out.append(Measurement("scaling", "", ID_2D, kwargs, "unwrapped", n_obstacles=n))
    for env_id in (*DEBRIS_IDS, CARTPOLE):
        out.append(Measurement("reset", "", env_id, {}, "make"))
    return out


# --- run ------------------------------------------------------------------------------------------


def run(
    quick: bool = False,
    steps: int | None = None,
    *,
    resets: int | None = None,
    repeats: int | None = None,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Run every measurement and return one row (dict) per measurement.

    Args:
        quick: fewer and shorter repeats (~30 s in total).
        steps: fixed steps per repeat for every step measurement (default: calibrated so a
            repeat lasts about the same time for every env).
        resets: fixed resets per repeat for the reset measurements (default: calibrated).
        repeats: number of interleaved repeats (default 3 quick, 5 full).
        progress: show a tqdm bar on stderr.

    Rows carry ``section`` ("step", "scaling", "reset"), ``env_id``, ``variant``, ``level``,
    ``count`` (steps or resets per repeat), ``repeats``, ``median_us`` / ``min_us`` (µs per step
    or per reset, resets excluded from step time), ``steps_per_s`` (median), ``steps_per_s_wall``
    (median, resets included), ``resets_per_1000``, ``loop_reset_ms`` (mean ms per reset done
    inside the step loop, at that wrapper level), ``ratio`` (cost relative to CartPole at the
    same wrapper level for "step" rows; relative to the 20-debris default for "scaling" rows)
    and ``error`` (None, or the message if the env could not be built or stepped).
    """
    cfg = dict(QUICK if quick else FULL)
    n_repeats = repeats if repeats is not None else cfg["repeats"]
    todo = measurements()
    bar = tqdm(
        total=len(todo) * (n_repeats + 1),
        desc="bench",
        unit="meas",
        file=sys.stderr,
        disable=not progress,
        leave=False,
    )
    with bar:
        for m in todo:
            bar.set_postfix_str(f"setup {_name(m)}", refresh=False)
            _guard(m, lambda m=m: _setup(m, cfg, steps, resets))
            bar.update()
        for rep in range(n_repeats):
            for m in todo:
                bar.set_postfix_str(f"rep {rep + 1}/{n_repeats} {_name(m)}", refresh=False)
                if m.error is None:
                    _guard(m, lambda m=m: _measure(m))
                bar.update()
    for m in todo:
        if m.env is not None:
            m.env.close()
            m.env = None
        m.actions = []
    return _rows(todo)


def _guard(m: Measurement, fn: Callable[[], None]) -> None:
    try:
        fn()
    except Exception as exc:  # report, don't hide: e.g. the field generator giving up
        m.error = f"{type(exc).__name__}: {exc}"


def _name(m: Measurement) -> str:
    extra = m.label or (f"n={m.n_obstacles}" if m.n_obstacles is not None else "")
    return " ".join(x for x in (m.env_id, extra, m.level) if x)


def _rows(todo: list[Measurement]) -> list[dict[str, Any]]:
    rows = []
    for m in todo:
        row: dict[str, Any] = {
            "section": m.section,
            "env_id": m.env_id,
            "variant": m.label,
            "level": m.level,
            "n_obstacles": m.n_obstacles,
            "field_size": m.kwargs.get("field_size"),
            "count": m.count,
            "repeats": len(m.times),
            "median_us": math.nan,
            "min_us": math.nan,
            "steps_per_s": math.nan,
            "steps_per_s_wall": math.nan,
            "resets_per_1000": math.nan,
            "loop_reset_ms": math.nan,
            "ratio": math.nan,
            "ratio_range": (math.nan, math.nan),
            "error": m.error,
            "_per_item": [],
        }
        if m.times and m.count:
            per = [t / m.count for t in m.times]
            row["_per_item"] = per
            row["median_us"] = statistics.median(per) * 1e6
            row["min_us"] = min(per) * 1e6
            if m.section != "reset":
                row["steps_per_s"] = 1.0 / statistics.median(per)
                row["steps_per_s_wall"] = m.count / statistics.median(m.walls)
                row["resets_per_1000"] = 1000.0 * m.resets / (m.count * len(m.times))
                if m.resets:
                    row["loop_reset_ms"] = 1e3 * m.reset_time / m.resets
        rows.append(row)
    _add_ratios(rows)
    for row in rows:
        del row["_per_item"]
    return rows


def _add_ratios(rows: list[dict[str, Any]]) -> None:
    """Cost ratios from medians; ``ratio_range`` = min/max over paired (same-repeat) ratios."""

    def find(section: str, env_id: str, level: str, variant: str = "") -> dict[str, Any] | None:
        for r in rows:
            if (r["section"], r["env_id"], r["level"], r["variant"]) == (
                section,
                env_id,
                level,
                variant,
            ):
                return r
        return None

    def fill(row: dict[str, Any], ref: dict[str, Any] | None) -> None:
        if ref is None or not row["_per_item"] or not ref["_per_item"]:
            return
        row["ratio"] = row["median_us"] / ref["median_us"]
        paired = [a / b for a, b in zip(row["_per_item"], ref["_per_item"], strict=False)]
        row["ratio_range"] = (min(paired), max(paired))

    for row in rows:
        if row["section"] == "step":
            fill(row, find("step", CARTPOLE, row["level"]))
        elif row["section"] == "scaling":
            fill(row, find("step", ID_2D, "unwrapped"))
        elif row["section"] == "reset":
            fill(row, find("reset", CARTPOLE, "make"))


# --- report ---------------------------------------------------------------------------------------


def machine_description() -> list[str]:
    """Lines describing the machine and library versions."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    try:
        load = "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        load = "n/a"
    import pymunk

    source = _source_fingerprint()

    return [
        f"- CPU: {cpu}",
        f"- Cores: {os.cpu_count()} logical ({usable} usable by this process)",
        f"- Load average at start (1/5/15 min): {load}",
        f"- OS: {platform.platform()}",
        f"- Python {platform.python_version()} ({platform.python_implementation()})",
        f"- numpy {np.__version__}, gymnasium {gym.__version__}, pymunk {pymunk.version}, "
        f"debris_gym {debris_gym.__version__}",
        f"- debris_gym source measured: {source}",
    ]


def _source_fingerprint() -> str:
    """Git commit, whether ``debris_gym/`` has uncommitted changes, and a hash of its sources.

    The hash identifies the exact code measured when the working tree is being edited.
    """
    package = Path(debris_gym.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    text = f"sources sha256 {digest.hexdigest()[:12]}"
    try:
        git = ["git", "-C", str(package.parent)]
        head = subprocess.run(
            [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "--", str(package)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        text = f"git {head}" + (" + uncommitted changes" if dirty else "") + f", {text}"
    except (OSError, subprocess.CalledProcessError):
        pass
    return text


def _f(x: float, digits: int = 1) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:,.{digits}f}"


def _ratio(row: dict[str, Any]) -> str:
    lo, hi = row["ratio_range"]
    if not math.isfinite(row["ratio"]):
        return "–"
    return f"{row['ratio']:.2f} ({lo:.2f}–{hi:.2f})"


def _env_name(row: dict[str, Any]) -> str:
    name = f"`{row['env_id']}`"
    return f"{name} {row['variant']}" if row["variant"] else name


def format_report(
    rows: list[dict[str, Any]],
    *,
    command: str,
    elapsed: float,
    machine: list[str] | None = None,
) -> str:
    """Markdown report: machine description, then the step, scaling and reset tables."""
    repeats = max((r["repeats"] for r in rows), default=0)
    machine = machine_description() if machine is None else machine
    lines = ["# DebrisGym benchmark", "", *machine]
    lines += [f"- Command: `{command}`", f"- Wall time of the run: {elapsed:.0f} s", ""]
    lines += [
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
        cells = [_env_name(row), str(row["count"])]
        if row["error"]:
            cells += [f"error: {row['error']}", "", ""]
        else:
            cells += [_f(row["median_us"] / 1e3, 3), _f(row["min_us"] / 1e3, 3), _ratio(row)]
        lines.append("| " + " | ".join(cells) + " |")
    errors = [r for r in rows if r["error"]]
    if errors:
        lines += ["", "## Errors", ""]
        lines += [f"- {_name_row(r)}: `{r['error']}`" for r in errors]
    return "\n".join(lines) + "\n"


def _name_row(row: dict[str, Any]) -> str:
    extra = f" n_obstacles={row['n_obstacles']}" if row["n_obstacles"] is not None else ""
    return f"{row['section']} {_env_name(row)}{extra} ({row['level']})"


def _step_line(
    row: dict[str, Any], first: list[str], ratio: str, extra: list[str] | None = None
) -> str:
    extra = extra or []
    if row["error"] and not math.isfinite(row["median_us"]):
        cells = [*first, f"error: {row['error']}"] + [""] * (6 + len(extra))
        return "| " + " | ".join(cells) + " |"
    cells = [
        *first,
        str(row["count"]),
        _f(row["median_us"], 2),
        _f(row["min_us"], 2),
        _f(row["steps_per_s"], 0),
        _f(row["steps_per_s_wall"], 0),
        _f(row["resets_per_1000"], 2),
        ratio,
        *extra,
    ]
    return "| " + " | ".join(cells) + " |"


def write_atomic(path: str, text: str) -> None:
    """Write ``text`` to ``path`` via a temp file in the same directory and ``os.replace``."""
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".bench-", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer, shorter repeats (~30 s)")
    parser.add_argument("--out", metavar="FILE", help="also write the Markdown report to FILE")
    args = parser.parse_args(argv)
    command = "python bench/run.py" + (" --quick" if args.quick else "")
    if args.out:
        command += f" --out {args.out}"
    machine = machine_description()  # taken before the run (load average at start)
    start = time.perf_counter()
    rows = run(quick=args.quick)
    elapsed = time.perf_counter() - start
    report = format_report(rows, command=command, elapsed=elapsed, machine=machine)
    print(report, end="")
    if args.out:
        write_atomic(args.out, report)
    return 1 if any(r["error"] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
