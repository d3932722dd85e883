"""train.py's refusals: every bad option, config value, device and run
directory is a usage error (exit status 2) raised before the run directory is touched; one run at
a time per directory; a run that never saved a model can be started again; ``--resume`` names a
damaged checkpoint and falls back to the previous complete one.

Runs are tiny (a few hundred steps, 2 envs, small nets); the two-process race is ``slow``.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

pytest.importorskip("stable_baselines3")

from agents.experiments.config_files import load_config_file
from agents.experiments.run_directory import RunDirectoryLock
from agents.experiments.training.checkpoints import model_timesteps, scan_checkpoints
from agents.experiments.training.config import TrainConfig, default_config_path
from agents.experiments.training.run import TrainOptions, train
from agents.experiments.training.validation import ALGO_KWARG_RANGES, algo_kwarg_range
from tests.helpers import load_script

ROOT = Path(__file__).resolve().parents[1]
TRAIN = ROOT / "train.py"
ENV_ID = "DebrisGym/Rendezvous2D-v0"
SETS = [
    "eval.freq=0", "checkpoint.freq=128", "env_kwargs.max_episode_steps=40",
    "env_kwargs.n_obstacles=5", "algo_kwargs.n_steps=32", "algo_kwargs.batch_size=32",
    "algo_kwargs.n_epochs=1", "policy_kwargs.net_arch=[16]",
]  # fmt: skip
TINY = ["--no-progress", "--n-envs", "2", "--timesteps", "256"]
for _item in SETS:
    TINY += ["--set", _item]
SUBPROCESS_ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


@pytest.fixture(scope="module")
def train_cli():
    return load_script("train.py")


def refused(cli, argv: list[str], capsys) -> str:
    """The usage error of ``train.py argv`` (exit status 2, no traceback)."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert "Traceback" not in err
    return err


def snapshot(path: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``path`` with its size and modification time (ns), but the lock file
    (a run that takes the lock writes its process id there)."""
    return {
        str(p.relative_to(path)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in sorted(path.rglob("*"))
        if p.is_file() and p.name != ".lock"
    }


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    """A tiny completed run with checkpoints at 128 and 256 steps (copy it before changing it)."""
    out = tmp_path_factory.mktemp("finished") / "run"
    result = train(
        TrainOptions(
            out=out, overrides=SETS, timesteps=256, n_envs=2, seed=3, progress=False,
            argv=["test"],
        )
    )  # fmt: skip
    assert result.status == "completed"
    return out


# --- the run directory -------------------------------------------------------------------------


def test_a_second_run_on_a_busy_directory_is_refused_and_changes_nothing(
    train_cli, tmp_path, capsys
):
    """Regression: two ``train.py --out X`` both printed ``done``; one model was lost and
    train_episodes.csv interleaved. The lock is held for the whole run, so the second run is
    refused at its start, naming the process that holds it."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "note.txt").write_text("the other run's file\n")
    with RunDirectoryLock(out):  # stands in for a run in progress
        before = snapshot(out)
        err = refused(train_cli, [*TINY, "--out", str(out)], capsys)
        assert f"in use by another run (process {os.getpid()})" in err
        assert snapshot(out) == before
        err = refused(train_cli, ["--resume", str(out)], capsys)  # not even to resume it
        assert snapshot(out) == before


@pytest.mark.slow
def test_two_train_processes_on_one_directory(tmp_path):
    """The reproducer as it was found: two processes, the second one refused while the first
    trains, and the first one unharmed."""
    out = tmp_path / "run"
    args = [a if a != "256" else "10000000" for a in TINY]  # far too long to finish
    with open(tmp_path / "stderr", "w") as se:
        first = subprocess.Popen(
            [sys.executable, str(TRAIN), *args, "--out", str(out)],
            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=se, env=SUBPROCESS_ENV,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 120
            while not (out / "train_episodes.csv").exists():
                assert first.poll() is None, (tmp_path / "stderr").read_text()
                assert time.monotonic() < deadline, "training did not start"
                time.sleep(0.2)
            second = subprocess.run(
                [sys.executable, str(TRAIN), *TINY, "--out", str(out)],
                cwd=ROOT, capture_output=True, text=True, timeout=120, env=SUBPROCESS_ENV,
            )  # fmt: skip
            assert second.returncode == 2, second.stderr
            assert f"process {first.pid}" in second.stderr and "done" not in second.stdout
            first.send_signal(signal.SIGINT)
            assert first.wait(timeout=120) == 130
        finally:
            if first.poll() is None:
                first.kill()
    assert (out / "checkpoints" / "interrupted.zip").is_file()


@pytest.mark.parametrize("kind", ["under a file", "empty", "unwritable"])
def test_bad_out_directories_are_usage_errors_before_any_work(
    kind, train_cli, tmp_path, capsys, monkeypatch
):
    """Regression: ``--out afile/x`` ended in a NotADirectoryError traceback, ``--out ""``
    trained into the current directory."""
    monkeypatch.chdir(tmp_path)
    if kind == "under a file":
        (tmp_path / "afile").write_text("")
        out, message = str(tmp_path / "afile" / "x"), "lies under"
    elif kind == "empty":
        out, message = "", "empty"
    else:
        if os.geteuid() == 0:
            pytest.skip("root may write anywhere")
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        out, message = str(locked / "x"), "permission denied"
    before = snapshot(tmp_path)
    err = refused(train_cli, [*TINY, "--out", out], capsys)
    assert "argument --out" in err and message in err
    assert snapshot(tmp_path) == before


def test_a_run_that_never_saved_a_model_can_be_started_again(
    train_cli, tmp_path, capsys, monkeypatch
):
    """Regression: a run that crashed before its first checkpoint left a config.yaml that
    blocked the retry (``--out``: "already holds a run"; ``--resume``: "no checkpoint")."""
    from stable_baselines3 import PPO

    out = tmp_path / "run"

    def crash(*args, **kwargs):
        raise RuntimeError("crashed before the first checkpoint")

    monkeypatch.setattr(PPO, "learn", crash)
    with pytest.raises(RuntimeError, match="crashed"):
        train_cli.main([*TINY, "--out", str(out)])
    monkeypatch.undo()
    assert (out / "config.yaml").is_file() and not scan_checkpoints(out).latest
    (out / "train_episodes.csv").write_text("timesteps,return\n999999,1.0\n")  # its episodes
    capsys.readouterr()

    err = refused(train_cli, ["--resume", str(out)], capsys)
    assert "never saved a model" in err and f"--out {out}" in err
    assert train_cli.main([*TINY, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "never saved a model" in err and "starting afresh" in err
    assert "999999" not in (out / "train_episodes.csv").read_text()
    assert model_timesteps(out / "model.zip") >= 256
    # a directory with a model still refuses a fresh run
    assert "already holds a run" in refused(train_cli, [*TINY, "--out", str(out)], capsys)


def test_resume_skips_a_truncated_checkpoint_with_a_note(finished_run, train_cli, tmp_path, capsys):
    """Regression: a truncated checkpoint made ``--resume`` say "no checkpoint in DIR". It now
    names the damaged file and resumes from the previous complete checkpoint."""
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    for name in ("model.zip", "checkpoints/rl_model_256_steps.zip"):
        path = out / name
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    capsys.readouterr()
    assert train_cli.main(["--resume", str(out), "--timesteps", "64", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "checkpoints/model.zip" not in err  # paths are named relative to the run
    assert "run/model.zip is not a complete SB3 model" in err
    assert "checkpoints/rl_model_256_steps.zip is not a complete SB3 model" in err
    assert "resuming from the latest complete checkpoint rl_model_128_steps.zip" in err
    assert model_timesteps(out / "model.zip") >= 128 + 64


def test_resume_with_only_damaged_checkpoints_names_them(finished_run, train_cli, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    models = [out / "model.zip", *sorted((out / "checkpoints").glob("*.zip"))]
    for path in models:
        path.write_bytes(b"")
    stats = out / "checkpoints" / "rl_model_vecnormalize_128_steps.pkl"
    before = snapshot(out)
    err = refused(train_cli, ["--resume", str(out)], capsys)
    assert "no complete checkpoint" in err and "rl_model_128_steps.zip" in err
    assert "cannot be resumed" in err and "--out" in err
    assert snapshot(out) == before
    # statistics cut short make their checkpoint damaged too (when normalisation is on)
    shutil.copy(finished_run / "checkpoints" / "rl_model_128_steps.zip", models[1])
    stats.write_bytes(stats.read_bytes()[:10])
    damaged = dict(scan_checkpoints(out, needs_stats=True).damaged)
    assert "damaged VecNormalize statistics" in damaged[models[1]]
    assert scan_checkpoints(out, needs_stats=False).latest == models[1]


# --- options and config ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "setting, message",
    [
        ("algo_kwargs.n_steps=0", "'algo_kwargs.n_steps' must be an integer >= 1, got 0"),
        ("algo_kwargs.n_steps=abc", "'algo_kwargs.n_steps' must be an integer >= 1"),
        ("algo_kwargs.batch_size=1", "'algo_kwargs.batch_size' must be an integer >= 2, got 1"),
        ("algo_kwargs.n_epochs=0", "'algo_kwargs.n_epochs' must be an integer >= 1"),
        ("algo_kwargs.gae_lambda=2", "'algo_kwargs.gae_lambda' must be a number in [0, 1]"),
        ("algo_kwargs.clip_range=0", "'algo_kwargs.clip_range' must be a number > 0"),
        ("algo_kwargs.learning_rate=lin_-1", "'algo_kwargs.learning_rate' must be a number > 0"),
        ("algo_kwargs.ent_coef=abc", "'algo_kwargs.ent_coef' must be a number >= 0"),
        ("algo_kwargs.max_grad_norm=-1", "'algo_kwargs.max_grad_norm' must be a number > 0"),
        ("algo_kwargs.rollout_buffer_class=x", "cannot be set from a config file"),
        ("policy_kwargs.ortho_init=abc", "'policy_kwargs.ortho_init' must be true or false"),
        ("algo_kwargs.rollout_buffer_kwargs={bogus: 1}", "SB3 PPO rejects config keys"),
    ],
)
def test_bad_algo_kwargs_are_usage_errors_before_anything_is_written(
    setting, message, train_cli, tmp_path, capsys
):
    """Regression: ``--set algo_kwargs.n_steps=0`` ended in an AssertionError from SB3 (others
    in TypeErrors, or an UnboundLocalError after the first rollout)."""
    new, existing = tmp_path / "new", tmp_path / "existing"
    existing.mkdir()
    (existing / "keep.txt").write_text("")
    for out in (new, existing):
        err = refused(train_cli, [*TINY, "--out", str(out), "--set", setting], capsys)
        assert message in err
    assert not new.exists()
    assert [p.name for p in existing.iterdir()] == ["keep.txt"]


def test_a_ppo_rollout_needs_two_samples():
    data, _ = load_config_file(default_config_path(ENV_ID, "ppo"))
    data = {**data, "n_envs": 1, "algo_kwargs": {**data["algo_kwargs"], "n_steps": 1}}
    with pytest.raises(ValueError, match=r"'algo_kwargs.n_steps' must give a rollout of at"):
        TrainConfig.from_dict(data)


RANGED = sorted(ALGO_KWARG_RANGES)


@settings(max_examples=120, deadline=None)
@given(
    algo=st.sampled_from(["ppo", "sac", "td3", "dqn"]),
    key=st.sampled_from(RANGED),
    value=st.one_of(
        st.integers(-(10**6), 10**6),
        st.floats(allow_nan=True, allow_infinity=True),
        st.booleans(),
        st.none(),
        st.text(max_size=6),
    ),
)
@example(algo="ppo", key="batch_size", value="0\x1f")  # numeric text with a unit separator
def test_algo_kwargs_are_refused_by_name_or_lie_in_their_range(algo, key, value):
    """Fuzz over the ranged keyword arguments: either a ValueError naming the key, or a config
    whose value lies in the documented range."""
    data, _ = load_config_file(default_config_path(ENV_ID, algo))
    data = {**data, "algo_kwargs": {**data.get("algo_kwargs", {}), key: value}}
    try:
        config = TrainConfig.from_dict(data)
    except ValueError as exc:
        assert f"algo_kwargs.{key}" in str(exc) or "algo_kwargs.train_freq" in str(exc)
        return
    accepted = config.algo_kwargs[key]
    if accepted is None:
        assert key in ("clip_range_vf", "target_kl")
        return
    assert not isinstance(accepted, bool)
    assert algo_kwarg_range(algo, key).contains(accepted), (key, value, accepted)


@pytest.mark.parametrize(
    "device, message",
    [
        ("bogus", "--device 'bogus' is not a device; allowed: cpu, auto, cuda, cuda:<N>, mps"),
        ("", "is not a device"),
        ("cuda", "--device 'cuda': no such GPU on this machine"),
        ("cuda:7", "no such GPU on this machine"),
    ],
)
def test_bad_devices_are_usage_errors(device, message, train_cli, tmp_path, capsys):
    """Regression: ``--device bogus`` ended in a RuntimeError traceback; ``--device cuda`` on a
    machine without a GPU trained on the CPU and recorded ``cuda``."""
    import torch

    if device.startswith("cuda") and torch.cuda.device_count() > int(device[5:] or 0):
        pytest.skip("this machine has that GPU")
    out = tmp_path / "run"
    err = refused(train_cli, [*TINY, "--out", str(out), "--device", device], capsys)
    assert message in err and "available on this machine: cpu" in err
    assert not out.exists()


def test_auto_device_is_recorded_as_the_device_used():
    import torch

    from agents.experiments.training.models import resolve_device

    assert resolve_device("auto") == ("cuda" if torch.cuda.is_available() else "cpu")
    assert resolve_device(" CPU ") == "cpu"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--resume", ""], "--resume must name a run directory"),
        (["--resume", "{tmp}/nothere"], "no such run directory"),
        (["--resume", "{tmp}"], "not a run of train.py (no config.yaml)"),
        (["--resume", "{tmp}/afile"], "no such run directory"),
        ([*TINY, "--out", "{tmp}/r", "--timesteps", "inf"], "--timesteps: must be an integer"),
        ([*TINY, "--out", "{tmp}/r", "--set", "algo_kwargs=5"], "algo_kwargs must be a mapping"),
        ([*TINY, "--out", "{tmp}/r", "--config", "{tmp}"], "is a directory, not a config file"),
        ([*TINY, "--out", "{tmp}/r", "--config", "{tmp}/nothere.yaml"], "not found"),
        ([*TINY, "--out", "{tmp}/r", "--seed", "999999"], "seed + n_envs <= 1000000"),
    ],
)
def test_other_bad_options_are_usage_errors(argv, message, train_cli, tmp_path, capsys):
    (tmp_path / "afile").write_text("")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    before = snapshot(tmp_path)
    assert message in refused(train_cli, argv, capsys)
    assert snapshot(tmp_path) == before


def test_a_lock_that_cannot_be_created_is_an_output_dir_error(tmp_path):
    """A place check_output_dir cannot foresee (here: made a file after the check) is still an
    error naming the flag, not an OSError traceback."""
    from agents.experiments.run_directory import OutputDirError

    (tmp_path / "afile").write_text("")
    with pytest.raises(OutputDirError, match="cannot create") as info:
        RunDirectoryLock(tmp_path / "afile" / "x", flag="--out").acquire()
    assert info.value.flag == "--out"


@pytest.mark.slow
def test_resume_with_a_damaged_replay_buffer_starts_an_empty_one(train_cli, tmp_path, capsys):
    """A replay buffer cut short ended the resume in an unpickling traceback; it now resumes
    with an empty buffer and says so."""
    out = tmp_path / "run"
    argv = ["--algo", "sac", "--no-progress", "--n-envs", "2", "--timesteps", "64"]
    for item in ("eval.freq=0", "checkpoint.freq=0", "checkpoint.replay_buffer=always",
                 "env_kwargs.max_episode_steps=40", "env_kwargs.n_obstacles=5",
                 "algo_kwargs.buffer_size=2000", "algo_kwargs.learning_starts=32",
                 "algo_kwargs.batch_size=32", "policy_kwargs.net_arch=[16]"):  # fmt: skip
        argv += ["--set", item]
    assert train_cli.main([*argv, "--out", str(out)]) == 0
    buffer = out / "replay_buffer.pkl"
    buffer.write_bytes(buffer.read_bytes()[:100])
    capsys.readouterr()
    assert train_cli.main(["--resume", str(out), "--timesteps", "32", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "replay buffer replay_buffer.pkl is damaged" in err and "empty buffer" in err


# --- inputs that ended in a traceback ----------------------------------------------------------

CARTPOLE_RECIPE = "version: 1\nenv_id: CartPole-v1\nalgo: ppo\ntimesteps: 256\nn_envs: 2\n"
SAC = ["--no-progress", "--n-envs", "2", "--timesteps", "256", "--algo", "sac"]
for _item in ("eval.freq=0", "policy_kwargs.net_arch=[16]", "algo_kwargs.learning_starts=10"):
    SAC += ["--set", _item]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--out", "{tmp}/" + "x" * 300], "argument --out: the name xxx"),
        (["--out", "{tmp}/" + "/".join(["d"] * 2000)], "argument --out: the path is"),
        (["--set", "env_id=CartPole-v1"], "'env_id' is not a DebrisGym env: 'CartPole-v1'"),
        (["--config", "{tmp}/cartpole.yaml"], "'env_id' is not a DebrisGym env: 'CartPole-v1'"),
        (["--set", "x=!!python/name:os.system"], "--set 'x=!!python/name:os.system': the value"),
        (
            ["--set", "policy_kwargs.net_arch=[100000, 100000]"],
            "'policy_kwargs.net_arch' must be a list of at most 16 layer sizes in [1, 4096]",
        ),
        (
            [*SAC, "--set", "algo_kwargs.buffer_size=1e12"],
            "'algo_kwargs.buffer_size' must be an integer in [1, 1000000000]",
        ),
        (
            ["--set", "curriculum=[{until: .nan, mission: {}}]"],
            "'curriculum[0].until' must be an integer, got nan",
        ),
        (
            ["--set", "curriculum=[{until: .inf, mission: {}}]"],
            "'curriculum[0].until' must be an integer, got inf",
        ),
        (["--config", "{tmp}/binary.yaml"], "binary.yaml: not a YAML text file (byte 128 is"),
        (["--config", "/dev/null"], "/dev/null: is empty; a config file holds a mapping"),
    ],
)
def test_inputs_that_raised_tracebacks_are_usage_errors_naming_the_key(
    argv, message, train_cli, tmp_path, capsys
):
    (tmp_path / "cartpole.yaml").write_text(CARTPOLE_RECIPE)
    (tmp_path / "binary.yaml").write_bytes(bytes(range(256)) * 8)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "r")]
    base = [] if "--algo" in argv else TINY
    before = snapshot(tmp_path)
    assert message in refused(train_cli, [*base, *argv], capsys)
    assert snapshot(tmp_path) == before


def test_a_replay_buffer_larger_than_the_memory_is_refused(
    monkeypatch, train_cli, tmp_path, capsys
):
    """Regression: a buffer numpy cannot allocate (269 TiB) ended in an _ArrayMemoryError."""
    from agents.experiments.training import models

    monkeypatch.setattr(models, "machine_memory_bytes", lambda: 2**30)
    argv = [*SAC, "--set", "algo_kwargs.buffer_size=10_000_000", "--out", str(tmp_path / "r")]
    err = refused(train_cli, argv, capsys)
    assert "config key 'algo_kwargs.buffer_size' asks for a replay buffer of 5.9 GiB" in err
    assert "this machine has 1.0 GiB of memory" in err
    assert not (tmp_path / "r").exists()


def test_a_network_that_does_not_fit_in_memory_is_a_usage_error(
    monkeypatch, train_cli, tmp_path, capsys
):
    """torch reports a failed allocation as a RuntimeError; it names the config keys."""
    from agents.experiments.training import models

    def no_memory(*args, **kwargs):
        raise RuntimeError(
            "[enforce fail at alloc_cpu.cpp:127] err == 0. DefaultCPUAllocator: can't allocate "
            "memory: you tried to allocate 40000000000 bytes."
        )

    monkeypatch.setattr(models, "algo_class", lambda algo: no_memory)
    err = refused(train_cli, [*TINY, "--out", str(tmp_path / "r")], capsys)
    assert "does not fit in this machine's memory" in err and "policy_kwargs.net_arch" in err


def test_the_evaluate_command_train_py_prints_flies_the_model_on_its_own_env(
    train_cli, tmp_path, capsys
):
    """Regression: the printed command had no --env, so it flew an Easy-rung model on the
    default task."""
    out = tmp_path / "run"
    assert (
        train_cli.main([*TINY, "--env", "DebrisGym/Rendezvous2D-Easy-v2", "--out", str(out)]) == 0
    )
    printed = capsys.readouterr().out.splitlines()[-1]
    assert printed == (
        "evaluate with: python evaluate.py --env DebrisGym/Rendezvous2D-Easy-v2 --agents "
        f"apf,ppo={out / 'model.zip'}"
    )


def test_every_algorithm_the_readme_offers_for_an_env_has_a_recipe():
    """Regression: the README offered recurrent_ppo on the full task, which has no recipe."""
    import re

    from agents.experiments.training.config import ALGOS
    from agents.experiments.training.resolve import resolve_config

    text = (ROOT / "README.md").read_text()
    offered = []
    for line in text.splitlines():
        found = re.match(r"python train\.py --env (\S+) --algo (\S+) .*#(.*)$", line)
        if found:
            words = re.findall(r"[a-z_0-9]+", found[3])
            offered += [(found[1], a) for a in [found[2], *(w for w in words if w in ALGOS)]]
    assert ("DebrisGym/Rendezvous2D-v2", "ppo") in offered and len(offered) >= 4
    for env_id, algo in offered:
        config, _ = resolve_config(TrainOptions(env_id=env_id, algo=algo))
        assert (config.env_id, config.algo) == (env_id, algo)
