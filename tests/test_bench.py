"""Smoke test of bench/run.py: every measurement runs and lands in the report.

No timing assertions: speeds on shared machines are noise; only their presence is checked.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "run.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("debris_bench_run", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while being built
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


@pytest.fixture(scope="module")
def rows(bench):
    return bench.run(quick=True, steps=20, resets=1, progress=False)


def test_every_env_has_a_step_row_at_both_wrapper_levels(bench, rows):
    for env_id in (*bench.DEBRIS_IDS, bench.CARTPOLE):
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
            assert row["steps_per_s"] > 0 and math.isfinite(row["steps_per_s"])
            assert row["ratio"] > 0
    cartpole = [r for r in rows if r["section"] == "step" and r["env_id"] == bench.CARTPOLE]
    assert all(r["ratio"] == pytest.approx(1.0) for r in cartpole)


def test_variants_scaling_and_resets_are_measured(bench, rows):
    variants = {r["variant"] for r in rows if r["section"] == "step"}
    assert {"observation=lidar", "action=discrete"} <= variants
    scaling = {r["n_obstacles"]: r for r in rows if r["section"] == "scaling"}
    assert sorted(scaling) == sorted(bench.SCALING_COUNTS)
    for n, row in scaling.items():
        assert row["field_size"] == pytest.approx(bench.field_size_for(n))
        # A generator failure is reported in the row, not raised; either way the row exists.
        assert row["error"] is not None or row["steps_per_s"] > 0
    resets = {r["env_id"]: r for r in rows if r["section"] == "reset"}
    assert set(resets) == {*bench.DEBRIS_IDS, bench.CARTPOLE}
    assert all(r["median_us"] > 0 for r in resets.values())


def test_report_has_machine_header_and_a_line_per_row(bench, rows):
    report = bench.format_report(rows, command="python bench/run.py --quick", elapsed=1.0)
    assert report.startswith("# DebrisGym benchmark")
    assert "- CPU: " in report and "gymnasium" in report and "pymunk" in report
    for env_id in (*bench.DEBRIS_IDS, bench.CARTPOLE):
        assert report.count(f"`{env_id}`") >= 3  # make, unwrapped, reset
    assert "| 1000 | 7,071 |" in report


def test_write_atomic_replaces_the_file(bench, tmp_path):
    out = tmp_path / "sub" / "table.md"
    bench.write_atomic(str(out), "old\n")
    bench.write_atomic(str(out), "new\n")
    assert out.read_text() == "new\n"
    assert [p.name for p in out.parent.iterdir()] == ["table.md"]  # no temp file left behind
