"""Your own code in evaluate.py: only the module you name runs, a policy that fails mid-run is
named with its episode and step (the finished episodes kept, the resume command printed), a
module or factory that fails (``SystemExit`` included) is refused by name, a plain function
``obs -> action`` is a policy, and labels cannot break the tables or the video files."""

from __future__ import annotations

import os
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from agents.experiments import evaluation as ev
from agents.experiments.evaluation.journal import EvaluationJournal
from agents.experiments.evaluation.specs import check_label, file_label
from tests.helpers import load_script
from tests.helpers_evaluate import episode_rows, run_evaluate

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
QUICK = ["--env", EASY, "--max-steps", "20", "--plots", "0", "--no-progress", "--workers", "1"]


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


def _module(where: Path, name: str, text: str) -> None:
    (where / f"{name}.py").write_text(textwrap.dedent(text))


# --- only the named module runs -------------------------------------------------------------


def test_a_stray_module_in_the_working_directory_never_runs(tmp_path):
    """Regression: the working directory went first on sys.path, so its tqdm.py ran (and here
    would have broken the run) even with --agents zero."""
    marker = tmp_path / "tqdm_ran"
    _module(tmp_path, "tqdm", f"open({str(marker)!r}, 'w').close()\nraise SystemExit(3)\n")
    out = tmp_path / "eval"
    proc = run_evaluate(tmp_path, "--agents", "zero", "--episodes", "1", *QUICK, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()
    assert len(episode_rows(out)) == 1


def test_the_named_module_is_found_in_the_working_directory_and_nothing_else(tmp_path):
    _module(tmp_path, "helper_of_mine", "VALUE = 0.0\n")
    _module(
        tmp_path,
        "mine",
        """
        import numpy as np

        def act(obs):
            return np.zeros(2)
        """,
    )
    _module(tmp_path, "needs_helper", "import helper_of_mine\nPolicy = None\n")
    out = tmp_path / "eval"
    proc = run_evaluate(
        tmp_path, "--agents", "mine:act", "--episodes", "1", *QUICK, "--out", str(out)
    )
    assert proc.returncode == 0, proc.stderr
    proc = run_evaluate(tmp_path, "--agents", "needs_helper:Policy", *QUICK, "--out", str(out))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "argument --agents" in proc.stderr and "No module named 'helper_of_mine'" in proc.stderr
    assert "not put on sys.path" in proc.stderr


# --- code that fails before the run: refused, named -----------------------------------------


@pytest.mark.parametrize(
    ("source", "attr", "text"),
    [
        ("raise RuntimeError('no licence')\n", "P", "failed at import: RuntimeError: no licence"),
        ("def broken(:\n", "P", "failed at import: SyntaxError"),
        ("import sys\nsys.exit(0)\n", "P", "failed at import: SystemExit"),
        (
            "def make(env):\n    raise RuntimeError('no GPU')\n",
            "make",
            "its factory 'make' failed on the env: RuntimeError: no GPU",
        ),
        ("import sys\ndef make(env):\n    sys.exit(0)\n", "make", "factory 'make' failed"),
    ],
)
def test_a_module_or_factory_that_fails_is_refused_by_name(tmp_path, source, attr, text):
    """Regression: a RuntimeError or SyntaxError at import gave a raw traceback, and
    sys.exit(0) ended evaluate.py with status 0 and no output."""
    (tmp_path / "userpol.py").write_text(source)
    out = tmp_path / "eval"
    proc = run_evaluate(tmp_path, "--agents", f"mine=userpol:{attr}", *QUICK, "--out", str(out))
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "argument --agents: agent 'userpol:" in proc.stderr or "agent 'mine'" in proc.stderr
    assert text in proc.stderr
    assert not out.exists()


# --- code that fails mid-run: named, finished episodes kept, resumable ----------------------

BAD_ANSWERS = {
    "nan": "np.full(2, np.nan)",
    "shape": "np.zeros(3)",
    "none": "None",
    "string": "'thrust'",
}


@pytest.mark.parametrize("answer", [*BAD_ANSWERS, "raises", "exits", "no_tuple"])
def test_a_policy_that_fails_mid_run_is_named_and_the_run_resumes(cli, capsys, tmp_path, answer):
    """Regression: NaN from step 4 (a wrong shape, None, a string, an exception, sys.exit) gave
    a raw traceback naming no agent, episode or step, or ended the run with status 0."""
    if answer in BAD_ANSWERS:
        bad, returned = f"return {BAD_ANSWERS[answer]}, state", "refused its action"
    elif answer == "raises":
        bad, returned = "raise ZeroDivisionError('oops')", "ZeroDivisionError: oops"
    elif answer == "exits":
        bad, returned = "sys.exit(0)", "SystemExit: 0"
    else:
        bad, returned = "return np.zeros(2)", "predict must return (action, state)"
    _module(
        tmp_path,
        f"flaky_{answer}",
        f"""
        import sys
        import numpy as np

        class Flaky:
            def __init__(self, env):
                self.env = env

            def predict(self, obs, state=None, episode_start=None, deterministic=True):
                u = self.env.unwrapped
                if u.np_random_seed == 1 and u.elapsed >= 4 * u.scenario.dt:
                    {bad}
                return np.zeros(2, dtype=np.float32), state
        """,
    )
    out = tmp_path / "eval"
    argv = ["--agents", f"zero,mine=flaky_{answer}:Flaky", "--episodes", "3", *QUICK]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert cli.main([*argv, "--out", str(out)]) == 1
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "agent 'mine' failed in episode 1 (reset seed 1) at step 4" in err
    assert returned in err
    assert "4 of 6 episodes finished" in err  # zero's three and mine's episode 0
    assert f"fix the agent, then resume with: python evaluate.py --resume {out}" in err
    done = {(r.agent, r.episode) for r in EvaluationJournal(out).read_records()}
    assert done == {("zero", 0), ("zero", 1), ("zero", 2), ("mine", 0)}

    _module(
        tmp_path,
        f"flaky_{answer}",
        """
        import numpy as np

        class Flaky:
            def __init__(self, env):
                pass

            def predict(self, obs, state=None, episode_start=None, deterministic=True):
                return np.zeros(2, dtype=np.float32), state
        """,
    )  # the fix
    sys.modules.pop(f"flaky_{answer}", None)
    os.chdir(tmp_path)
    try:
        assert cli.main(["--resume", str(out), "--no-progress", "--workers", "1"]) == 0
    finally:
        os.chdir(cwd)
    assert [(r["agent"], r["episode"]) for r in episode_rows(out)] == [
        (a, str(i)) for a in ("zero", "mine") for i in range(3)
    ]


def test_run_episode_names_the_agent_episode_and_step():
    env = gym.make(EASY)

    class Late:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            if env.unwrapped.elapsed >= 2 * env.unwrapped.scenario.dt:
                return np.array([np.nan, 0.0]), state
            return np.zeros(2), state

    with pytest.raises(ev.AgentFailure) as caught:
        ev.run_episode(env, Late(), "late", 7, seed=12)
    expected = "agent 'late' failed in episode 7 (reset seed 12) at step 2: the env refused"
    assert str(caught.value).startswith(expected)
    env.close()


# --- a plain function obs -> action is a policy ---------------------------------------------


def test_a_plain_function_flies_like_the_baseline_it_copies(tmp_path):
    """Regression: a plain ``obs -> action`` function was taken for a factory and refused."""
    _module(
        tmp_path,
        "funcs",
        """
        import numpy as np

        def coast(obs):
            return np.zeros(2)

        def unnamed(x):  # neither 'env' nor 'obs': tried as a factory, then as a function
            return np.zeros(2)
        """,
    )
    out = tmp_path / "eval"
    agents = "zero,a=funcs:coast,b=funcs:unnamed"
    proc = run_evaluate(tmp_path, "--agents", agents, "--episodes", "2", *QUICK, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    rows = episode_rows(out)
    for label in ("a", "b"):
        mine = [r["path_length"] for r in rows if r["agent"] == label]
        assert mine == [r["path_length"] for r in rows if r["agent"] == "zero"]


def test_function_policies_from_python_take_one_observation_or_a_batch():
    env = gym.make(EASY)
    policy = ev.build_agent(ev.parse_agent_specs({"f": lambda obs: -obs[:2]})[0], env)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs, state="s")
    assert np.array_equal(action, -obs[:2]) and state == "s"
    batch, _ = policy.predict(np.stack([obs, 2 * obs]))
    assert batch.shape == (2, 2) and np.array_equal(batch[1], -2 * obs[:2])
    with pytest.raises(ValueError, match="given an observation it returned an action of shape"):
        ev.build_agent(ev.parse_agent_specs({"g": lambda obs: obs})[0], env)
    env.close()


# --- labels ---------------------------------------------------------------------------------


@given(st.lists(st.text(min_size=1, max_size=12), min_size=2, max_size=6, unique=True))
def test_file_labels_are_distinct_plain_names_inside_their_folder(labels):
    names = [file_label(label) for label in labels]
    assert len(set(names)) == len(names)
    for name in names:
        assert name and "/" not in name and "\0" not in name
        assert name not in (".", "..") and not name.startswith(".")
        assert Path("videos", name).resolve().parent == Path("videos").resolve()


def test_labels_with_control_characters_are_refused_and_pipes_escaped():
    """Regression: a label with '|' or a newline broke summary.md's table."""
    with pytest.raises(ValueError, match="control character"):
        ev.parse_agent_spec("a\nb=mod:attr")
    with pytest.raises(ValueError, match="control character"):
        check_label("tab\there")
    res = ev.evaluate_agents(
        EASY, {"a|b": "zero", "c": "zero"}, episodes=1, seed=0, progress=False,
        max_episode_steps=5,
    )  # fmt: skip
    table = ev.summary_markdown(ev.summarize(res)).split("\n\n")[1]
    for row in [line for line in table.splitlines() if line.startswith("| ")]:
        assert row.replace("\\|", "").count("|") == 12, row  # eleven cells in every row
    assert "| a\\|b |" in table


def test_video_files_of_look_alike_and_dotted_labels_stay_apart(tmp_path):
    """Regression: labels 'a b' and 'a_b' wrote the same video, and '..' wrote outside
    videos/."""
    pytest.importorskip("moviepy", reason="--video needs moviepy: pip install -e '.[video]'")
    agents = {"a b": "zero", "a_b": "zero", "..": "zero"}
    ev.evaluate_agents(
        EASY, agents, episodes=1, seed=0, progress=False, max_episode_steps=4,
        video=(tmp_path / "videos", 1),
    )  # fmt: skip
    videos = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.mp4"))
    assert len(videos) == 3
    assert all(v.parts[0] == "videos" and len(v.parts) == 3 for v in videos)
    assert len({v.parent for v in videos}) == 3
