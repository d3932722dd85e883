"""Output directories as transactions (agents/experiments/run_directory.py): the --out check, the
one-run-at-a-time lock, and output sets that land whole or not at all."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from agents.experiments.run_directory import (
    MANIFEST,
    OutputDirError,
    OutputSet,
    RunDirectoryBusy,
    RunDirectoryLock,
    check_output_dir,
    deferred_interrupts,
)


def test_check_output_dir_accepts_new_and_existing_directories(tmp_path):
    assert check_output_dir(tmp_path) == tmp_path
    assert check_output_dir(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    assert not (tmp_path / "a").exists()  # nothing is created by the check


@pytest.mark.parametrize("text", ["", "   "])
def test_check_output_dir_rejects_an_empty_name(text):
    with pytest.raises(OutputDirError, match="empty") as info:
        check_output_dir(text, flag="--out")
    assert info.value.flag == "--out"


def test_check_output_dir_rejects_a_file_and_a_path_under_a_file(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(OutputDirError, match="is a file"):
        check_output_dir(afile)
    with pytest.raises(OutputDirError, match=r"lies under .*afile.*which is a file"):
        check_output_dir(afile / "x" / "y")


def test_check_output_dir_refuses_paths_the_file_system_cannot_hold(tmp_path):
    """Regression: a 300-character name raised OSError (ENAMETOOLONG) and 2 000 levels a
    RecursionError, where a usage error naming --out was due."""
    with pytest.raises(OutputDirError, match=r"is 300 bytes long; .* at most 255") as info:
        check_output_dir(tmp_path / ("x" * 300))
    assert info.value.flag == "--out"
    with pytest.raises(OutputDirError, match=r"levels\) made absolute; .* at most 3840"):
        check_output_dir(tmp_path.joinpath(*["d"] * 2000))
    with pytest.raises(OutputDirError, match="is 256 bytes long"):  # bytes, not characters
        check_output_dir(tmp_path / ("é" * 128))


def test_a_deep_output_directory_within_the_limits_is_created_and_locked(tmp_path):
    """``Path.mkdir(parents=True)`` recurses once per level: past Python's recursion limit for a
    path of 1 500 levels (3 000 bytes), which the file system holds."""
    deep = tmp_path.joinpath(*["d"] * 1500)
    try:
        assert check_output_dir(deep) == deep
        with RunDirectoryLock(deep):
            assert deep.is_dir()
        with OutputSet(deep) as files:
            (files.path("a.txt")).write_text("a")
            files.commit()
        assert (deep / "a.txt").read_text() == "a"
    finally:  # pytest's clean-up (shutil.rmtree) recurses once per level too
        level = deep
        while level != tmp_path:
            if level.is_dir():
                for child in level.iterdir():
                    child.unlink()
                level.rmdir()
            level = level.parent


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_check_output_dir_rejects_an_unwritable_place(tmp_path):
    locked = tmp_path / "ro"
    locked.mkdir(mode=0o500)
    with pytest.raises(OutputDirError, match="permission denied"):
        check_output_dir(locked / "out")


def test_second_lock_on_a_directory_is_refused_and_names_the_holder(tmp_path):
    with RunDirectoryLock(tmp_path / "run"):
        with pytest.raises(RunDirectoryBusy, match=f"process {os.getpid()}"):
            RunDirectoryLock(tmp_path / "run").acquire()
    with RunDirectoryLock(tmp_path / "run"):  # released at the end of the block
        pass


def test_lock_held_by_another_process_is_refused_until_that_process_dies(tmp_path):
    code = textwrap.dedent(
        f"""
        import sys, time
        from agents.experiments.run_directory import RunDirectoryLock
        lock = RunDirectoryLock({str(tmp_path)!r})
        lock.acquire()
        print("locked", flush=True)
        time.sleep(60)
        """
    )
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "locked"
        with pytest.raises(RunDirectoryBusy, match=f"process {child.pid}"):
            RunDirectoryLock(tmp_path).acquire()
    finally:
        child.kill()  # no clean-up in the child: the OS drops its lock
        child.wait()
    with RunDirectoryLock(tmp_path):
        pass


def test_output_set_lands_whole_and_removes_the_previous_sets_leftovers(tmp_path):
    out = tmp_path / "eval"
    out.mkdir()
    (out / "notes.txt").write_text("mine")  # not ours: never touched
    (out / "plot_ep005.png").write_text("stale, matches an owned pattern")
    with OutputSet(out, owned=("plot_ep*.png",)) as files:
        files.path("table.csv").write_text("first")
        files.path("extra.json").write_text("{}")
        files.commit(run="one")
    assert json.loads((out / MANIFEST).read_text()) == {
        "files": ["extra.json", "table.csv"],
        "run": "one",
    }
    assert not (out / "plot_ep005.png").exists()
    with OutputSet(out, owned=("plot_ep*.png",)) as files:
        files.path("table.csv").write_text("second")
        files.path("plot_ep000.png").write_text("new plot")
        written = files.commit()
    assert sorted(p.name for p in written) == ["plot_ep000.png", "table.csv"]
    assert (out / "table.csv").read_text() == "second"
    assert not (out / "extra.json").exists()  # named by the previous manifest, not this set
    assert (out / "notes.txt").read_text() == "mine"
    assert not list(out.glob(".staging-*"))


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_output_set_left_without_commit_changes_nothing(tmp_path, error):
    with OutputSet(tmp_path, owned=("*.csv",)) as files:
        files.path("table.csv").write_text("first")
        files.commit()
    with pytest.raises(error), OutputSet(tmp_path, owned=("*.csv",)) as files:
        files.path("table.csv").write_text("half a run")
        raise error
    assert (tmp_path / "table.csv").read_text() == "first"
    assert not list(tmp_path.glob(".staging-*"))


def test_output_set_removes_a_killed_runs_scratch_directory(tmp_path):
    (tmp_path / ".staging-dead").mkdir()
    (tmp_path / ".staging-dead" / "table.csv").write_text("orphan")
    with OutputSet(tmp_path) as files:
        files.path("table.csv").write_text("new")
        files.commit()
    assert not (tmp_path / ".staging-dead").exists()


def test_output_names_must_be_plain_file_names(tmp_path):
    with OutputSet(tmp_path) as files:
        for bad in ("../escape.csv", "sub/x.csv", MANIFEST):
            with pytest.raises(ValueError, match="plain file names"):
                files.path(bad)


def test_deferred_interrupts_deliver_ctrl_c_after_the_block():
    finished = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_interrupts():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            finished.append(True)  # reached: the signal waited for the block's end
    assert finished == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
