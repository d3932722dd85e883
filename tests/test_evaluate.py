"""evaluate.py and agents.experiments.evaluation: same scenarios, statistics, output files, CLI
errors, your own policies."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

import agents
from agents.experiments import evaluation as ev
from tests.helpers import flies_old_ids, load_script

# evaluations on the frozen-world default field (v0) too
pytestmark = flies_old_ids

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "evaluate.py"
SMALL = {"n_obstacles": 5}

DESIGN_KEYS = (
    "success_rate",
    "targets_captured_mean",
    "delta_v_mean",
    "time_mean",
    "path_length_mean",
    "collision_rate",
    "min_clearance_min",
    "decision_ms_p50",
    "decision_ms_p95",
)
CI_KEYS = (
    "success_rate_ci95",
    "collision_rate_ci95",
    "budget_spent_rate_ci95",
    "targets_captured_mean_ci95",
    "delta_v_mean_ci95",
    "time_mean_ci95",
    "path_length_mean_ci95",
)


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


@pytest.fixture(scope="module")
def results():
    return ev.evaluate_agents(
        "DebrisGym/Rendezvous2D-v0",
        "zero,random",
        episodes=3,
        seed=7,
        env_kwargs=SMALL,
        progress=False,
        max_episode_steps=40,
    )


# --- the evaluate.py script end to end -------------------------------------------------------


def test_script_writes_every_output(tmp_path):
    out = tmp_path / "eval"
    proc = subprocess.run(
        [
            sys.executable, str(SCRIPT), "--agents", "zero,random", "--episodes", "2",
            "--env-kwargs", json.dumps(SMALL), "--max-steps", "60", "--plots", "2",
            "--no-progress", "--out", str(out),
        ],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "| agent | success |" in proc.stdout and "| random |" in proc.stdout
    assert str(out / "summary.json") in proc.stdout

    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2
    assert [(r["agent"], r["episode"]) for r in rows] == [
        ("zero", "0"), ("zero", "1"), ("random", "0"), ("random", "1"),
    ]  # fmt: skip
    assert {"delta_v", "time", "path_length", "decision_ms_p95", "return"} <= set(rows[0])
    assert all(int(r["steps"]) <= 60 for r in rows)

    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["agents"]) == {"zero", "random"}
    for entry in summary["agents"].values():
        for key in (*DESIGN_KEYS, *CI_KEYS):
            assert key in entry, key
        for key in CI_KEYS:
            assert key in summary["ci_method"]
            lo, hi = entry[key]
            assert lo <= entry[key.removesuffix("_ci95")] <= hi
    assert summary["agents"]["zero"]["delta_v_mean"] == 0.0
    assert (out / "summary.md").read_text().startswith("Env `DebrisGym/Rendezvous2D-v2`")

    pngs = sorted(out.glob("trajectories_ep*.png"))
    assert [p.name for p in pngs] == ["trajectories_ep000.png", "trajectories_ep001.png"]
    import matplotlib.image

    for png in pngs:
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert matplotlib.image.imread(png).shape[2] in (3, 4)
    assert not list(out.glob(".*.tmp"))  # atomic writes leave no temporaries


def test_running_out_of_delta_v_is_a_failure_in_every_output(cli, capsys, tmp_path):
    """An episode whose Δv budget runs out (0.3 m/s: random thrust spends it in a few steps)
    ends failed with outcome ``delta_v_budget``, and every output says so: the CSV's
    ``budget_spent`` column, ``budget_spent_rate`` with its Wilson interval in summary.json, the
    Markdown table's column (printed and in summary.md) and the trajectory plot's legend."""
    from agents.experiments.evaluation.plots import episode_figure

    out = tmp_path / "eval"
    argv = ["--agents", "zero,random", "--episodes", "3", "--max-steps", "40", "--plots", "1",
            "--env-kwargs", json.dumps({**SMALL, "delta_v_budget": 0.3}), "--no-progress",
            "--workers", "1", "--out", str(out)]  # fmt: skip
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    spent = {(r["agent"], r["episode"]): r["budget_spent"] for r in rows}
    assert spent == {("zero", e): "False" for e in "012"} | {("random", e): "True" for e in "012"}
    for r in rows:
        assert r["outcome"] == ("delta_v_budget" if r["agent"] == "random" else "time_limit")
        assert r["success"] == "False"
        if r["agent"] == "random":
            assert float(r["delta_v"]) == pytest.approx(0.3)
            assert int(r["steps"]) < 40  # ended by the budget, not the time limit
    summary = json.loads((out / "summary.json").read_text())
    random_entry, zero_entry = summary["agents"]["random"], summary["agents"]["zero"]
    assert random_entry["budget_spent_rate"] == 1.0 and zero_entry["budget_spent_rate"] == 0.0
    assert random_entry["budget_spent_rate_ci95"] == list(ev.wilson_interval(3, 3))
    assert zero_entry["budget_spent_rate_ci95"] == list(ev.wilson_interval(0, 3))
    assert "Wilson" in summary["ci_method"]["budget_spent_rate_ci95"]
    md = (out / "summary.md").read_text()
    lines = md.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| agent | success |"))
    column = lines[start].split(" | ").index("Δv budget spent")
    cells = {
        line.split(" | ")[0].strip("| "): line.split(" | ")[column]
        for line in lines[start + 2 : start + 4]
    }
    low, _ = ev.wilson_interval(3, 3)
    assert cells == {"zero": "0 [0, 0.56]", "random": f"1 [{low:.2g}, 1]"}
    assert md in printed  # the printed table is summary.md
    results = ev.evaluate_agents(
        "DebrisGym/Rendezvous2D-v2", "random", episodes=1, seed=0, progress=False,
        env_kwargs={**SMALL, "delta_v_budget": 0.3}, max_episode_steps=40,
    )  # fmt: skip
    legend = [t.get_text() for leg in episode_figure(results, 0).legends for t in leg.get_texts()]
    assert any(text.startswith("random: Δv budget spent (failed)") for text in legend), legend


def test_a_journal_written_before_the_budget_column_reads_its_outcome():
    """A journaled record without ``budget_spent`` (an unfinished run of an earlier version)
    takes it from its outcome, so a resumed run still counts the failure."""
    from agents.experiments.evaluation.journal import record_from_json, record_to_json

    results = ev.evaluate_agents(
        "DebrisGym/Rendezvous2D-v2", "random,zero", episodes=1, seed=0, progress=False,
        env_kwargs={**SMALL, "delta_v_budget": 0.3}, max_episode_steps=10,
    )  # fmt: skip
    for record in results.records:
        data = record_to_json(record)
        del data["budget_spent"]
        back = record_from_json(json.loads(json.dumps(data)))
        assert back.budget_spent == (record.outcome == "delta_v_budget") == record.budget_spent
    assert [r.budget_spent for r in results.records] == [True, False]


@pytest.mark.filterwarnings("ignore:.*no VecNormalize statistics:UserWarning")  # a bare model
def test_the_default_run_flies_v2_and_takes_a_pretrained_policy_once_one_ships(
    monkeypatch, tmp_path
):
    """A plain ``python evaluate.py`` flies the v2 default with every baseline. Without a policy
    shipped for it, 'pretrained' is left out with the reason; an entry in PRETRAINED_POLICIES
    naming a file that fits the env is all it takes for the default run to fly it."""
    from stable_baselines3 import PPO

    from agents.experiments.evaluation.plan import EvaluateOptions
    from agents.experiments.evaluation.resolve import fresh_plan
    from agents.policies import learned

    plan = fresh_plan(EvaluateOptions(out=tmp_path / "eval"))
    assert plan.env_id == "DebrisGym/Rendezvous2D-v2" and plan.episodes == 20
    labels = [label for _, label in plan.agents]
    assert labels[: len(agents.BASELINES)] == list(agents.BASELINES)
    if plan.env_id not in learned.PRETRAINED_POLICIES:
        assert "pretrained" not in labels
        assert plan.skipped["pretrained"].startswith(
            "no pretrained policy for DebrisGym/Rendezvous2D-v2"
        )
    env = gym.make(plan.env_id)
    PPO("MlpPolicy", env, n_steps=8, batch_size=8, device="cpu").save(tmp_path / "v2.zip")
    env.close()
    monkeypatch.setattr(learned, "PRETRAINED_DIR", tmp_path)
    monkeypatch.setitem(learned.PRETRAINED_POLICIES, plan.env_id, ("ppo", "v2.zip"))
    shipped = fresh_plan(EvaluateOptions(out=tmp_path / "eval"))
    assert [label for _, label in shipped.agents] == [*agents.BASELINES, "pretrained"]
    assert shipped.skipped == {}


def test_the_table_names_the_agents_left_out_and_why(results):
    summary = {**ev.summarize(results), "skipped": {"pretrained": "no policy | for this env"}}
    md = ev.summary_markdown(summary)
    assert md.splitlines()[-1] == "Not evaluated — pretrained: no policy | for this env"


def test_script_rejects_an_unknown_agent_by_name(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--agents", "zero,warp-drive", "--out", str(tmp_path)],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2
    assert "--agents" in proc.stderr and "'warp-drive'" in proc.stderr
    assert "apf-mpc" in proc.stderr  # lists the known ones
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("argv", "flag", "text"),
    [
        (["--episodes", "0"], "--episodes", ">= 1"),
        (["--episodes", "two"], "--episodes", "integer"),
        (["--env-kwargs", "{n_obstacles: 4}"], "--env-kwargs", "invalid JSON"),
        (["--env-kwargs", "[1, 2]"], "--env-kwargs", "JSON object"),
        (["--env-kwargs", '{"n_obstacle": 4}'], "--env-kwargs", "n_obstacle"),
        (["--env", "DebrisGym/Nowhere-v0"], "--env", "Nowhere"),
        (["--agents", "ppo"], "--agents", "ppo=path/to/model.zip"),
        (["--agents", "xgboost=m.zip"], "--agents", "xgboost"),
        (["--agents", "zero,zero"], "--agents", "more than once"),
        (["--agents", "ppo=/no/such/model.zip"], "--agents", "not found"),
        (["--paper", "--episodes", "3"], "--episodes", "--paper"),
        (["--paper", "--agents", "zero"], "--agents", "--paper"),
        (["--plots", "-1"], "--plots", ">= 0"),
        (["--agents", "zero,random", "--reference", "apf"], "--reference", "agents: zero, random"),
        # each of these is a usage error, not a traceback (some after running every episode)
        (["--agents", "zero", "--seed", "-1"], "--seed", ">= 0"),
        (["--agents", "zero", "--env", "CartPole-v1"], "--env", "DebrisGym/Rendezvous2D-v0"),
        (["--agents", "zero", "--env", ""], "--env", "DebrisGym/Rendezvous3D-v0"),
        (["--agents", "zero", "--env", "nosuchmodule:Foo-v0"], "--env", "nosuchmodule"),
        (["--agents", "apf", "--env-kwargs", '{"action": "discrete"}'], "--agents", "dqn=PATH"),
        (["--agents", ""], "--agents", "empty list"),
        (["--agents", "mine=os:getcwd"], "--agents", "'getcwd' is neither a factory"),
    ],
)
def test_cli_errors_name_the_flag(cli, capsys, tmp_path, argv, flag, text):
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--max-steps", "20", "--no-progress", "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {flag}" in err and text in err, err
    assert not (tmp_path / "out").exists()  # refused before the directory changed


def test_help_explains_outputs_and_agents(cli):
    text = re.sub(r"-\s+", "-", cli.build_parser().format_help())  # argparse wraps at hyphens
    for word in ("--agents", "--paper", "--env-kwargs", "--max-steps", "episodes.csv", "apf-rrt"):
        assert word in text


def test_paper_mode_writes_table_i_beside_ours(cli, monkeypatch, tmp_path, capsys):
    # Stand-ins while the real planners are being written: the table's shape is what is tested.
    monkeypatch.setitem(agents.BASELINES, "apf", "agents.policies.simple:RandomAgent")
    monkeypatch.setitem(agents.BASELINES, "apf-mpc", "agents.policies.simple:ZeroAgent")
    monkeypatch.setitem(agents.BASELINES, "astar", "agents.policies.simple:ZeroAgent")
    out = tmp_path / "paper"
    argv = ["--paper", "--max-steps", "30", "--no-progress", "--workers", "1"]  # the stand-ins
    assert cli.main([*argv, "--out", str(out)]) == 0  # are set in this process only
    text = (out / "paper_table.md").read_text()
    assert "not a reproduction" in text.splitlines()[0]  # the label comes first
    assert (
        "| metric | paper APF | ours APF | paper APF-MPC | ours APF-MPC | ours A* |"
        in text.splitlines()
    )
    assert "| Path length [m] | 841.7818 |" in text and "| 105.1884 |" in text
    assert "| 83790 |" in text and "0.00038684" in text
    table = json.loads((out / "paper_table.json").read_text())
    assert set(table["ours"]) == {"apf", "apf-mpc", "astar"}
    assert table["ours"]["apf-mpc"]["fuel"] == 0.0 and table["ours"]["astar"]["waypoints"] == 30
    assert table["paper"]["apf"]["fuel"] == 2367.9007
    assert "not a reproduction" in table["title"] and len(table["not_a_reproduction"]) >= 4
    for reason in ("reconstruction", "Units", "Time step", "Metric definitions"):
        assert reason in text and any(reason in r for r in table["not_a_reproduction"])
    printed = capsys.readouterr().out
    assert "[APF-MPC] Table I side by side with ours — not a reproduction:" in printed


# --- the library ------------------------------------------------------------------------------


def test_every_agent_meets_the_same_scenarios(results):
    env = gym.make("DebrisGym/Rendezvous2D-v0", **SMALL)
    for i in range(results.episodes):
        env.reset(seed=7 + i)
        expected = ev.scenario_fingerprint(env.unwrapped.scenario)
        group = results.for_episode(i)
        assert [r.agent for r in group] == ["zero", "random"]
        assert {r.scenario_id for r in group} == {expected}
        assert all(r.seed == 7 + i for r in group)
        assert all(r.scenario == results.scenarios[i] for r in group)
        assert all(np.array_equal(r.trajectory.positions[0], env.unwrapped.trail[0]) for r in group)
    env.close()
    assert len({ev.scenario_fingerprint(s) for s in results.scenarios}) == results.episodes


def test_records_match_the_env(results):
    for rec in results.records:
        traj = rec.trajectory
        assert rec.steps == len(traj.decision_ms) == len(traj.accelerations) <= 40
        assert traj.positions.shape == (rec.steps + 1, 2)
        assert rec.time == pytest.approx(rec.steps * traj.dt)
        assert rec.metrics.fuel == pytest.approx(rec.delta_v)  # accelerations rebuilt exactly
        assert rec.decision_ms_p50 <= rec.decision_ms_p95 <= rec.decision_ms_max
        assert rec.collision == (traj.collision_point is not None)
    zero = results.for_agent("zero")
    assert all(r.path_length == 0.0 and r.outcome == "time_limit" for r in zero)


def test_fuel_is_rebuilt_when_the_delta_v_budget_cuts_the_last_burn():
    res = ev.evaluate_agents(
        "DebrisGym/Rendezvous2D-v0",
        ["random"],
        episodes=1,
        seed=0,
        env_kwargs={**SMALL, "delta_v_budget": 1.2, "thrust_model": "box"},
        progress=False,
    )
    rec = res.records[0]
    assert rec.delta_v == pytest.approx(1.2)
    assert rec.outcome in ("delta_v_budget", "collision", "out_of_bounds")
    assert rec.trajectory.thrust_model == "box"
    assert rec.metrics.fuel == pytest.approx(rec.delta_v)  # Σ|u_i|·dt, the last burn cut


def test_recorded_accelerations_are_the_commanded_ones_without_a_budget():
    """No spurious budget cut: the recorded acceleration is exactly max_accel times the action
    (scaled onto the unit ball), even where Δv summed over steps loses its last bits."""
    from debris_gym.thrust import commanded_accel

    env = gym.make("DebrisGym/Rendezvous2D-v0", **SMALL)
    random_agent = agents.make_agent("random", env)
    actions = []

    class Recorder:
        def predict(self, observation, **kwargs):
            action, state = random_agent.predict(observation, **kwargs)
            actions.append(action)
            return action, state

    rec = ev.run_episode(env, Recorder(), "random", 0, seed=0)
    max_accel = env.unwrapped.scenario.max_accel
    expected = commanded_accel(np.array(actions, dtype=float), max_accel, "ball")
    assert rec.steps > 10
    assert np.array_equal(rec.trajectory.accelerations, expected)
    env.close()


def test_summary_statistics(results):
    summary = ev.summarize(results)
    rnd = summary["agents"]["random"]
    recs = results.for_agent("random")
    dv = [r.delta_v for r in recs]
    assert rnd["delta_v_mean"] == pytest.approx(np.mean(dv))
    assert rnd["delta_v_mean_ci95"] == pytest.approx(list(ev.bootstrap_interval(dv, 0.0)))
    k = sum(r.collision for r in recs)
    assert rnd["collision_rate_ci95"] == pytest.approx(list(ev.wilson_interval(k, 3)))
    all_ms = np.concatenate([r.trajectory.decision_ms for r in recs])
    assert rnd["decision_ms_p95"] == pytest.approx(np.percentile(all_ms, 95))
    assert rnd["decisions"] == all_ms.size
    md = ev.summary_markdown(summary)
    table = md.split("\n\n")[1]  # the first table; the paired Δv table follows
    rows = [line for line in table.splitlines() if line.startswith("| ")]
    assert [row.split(" | ")[0] for row in rows] == ["| agent", "| zero", "| random"]
    json.loads(ev.to_json(summary))  # strict JSON


def test_paired_delta_v_hand_computed(results):
    """Δv paired by seed on the episodes both agents complete, against a reference agent."""
    import dataclasses

    # episodes 0-2: reference (zero) succeeds on 0, 1, 2; random on 0, 2 only
    outcomes = {
        ("zero", 0): (True, 10.0), ("zero", 1): (True, 20.0), ("zero", 2): (True, 30.0),
        ("random", 0): (True, 12.5), ("random", 1): (False, 1.0), ("random", 2): (True, 26.0),
    }  # fmt: skip
    records = [
        dataclasses.replace(r, success=outcomes[r.agent, r.episode][0],
                            delta_v=outcomes[r.agent, r.episode][1])
        for r in results.records
    ]  # fmt: skip
    rigged = dataclasses.replace(results, records=records)
    paired = ev.paired_delta_v(rigged, reference="zero")
    assert paired["reference"] == "zero" and list(paired["agents"]) == ["random"]
    e = paired["agents"]["random"]
    assert e["both_succeeded"] == 2
    assert e["delta_v_mean"] == pytest.approx((12.5 + 26.0) / 2)
    assert e["reference_delta_v_mean"] == pytest.approx((10.0 + 30.0) / 2)
    assert e["difference_mean"] == pytest.approx((2.5 - 4.0) / 2)  # episode 1 left out
    # t interval of {2.5, -4}: mean -0.75, sem 3.25, t(0.975, 1) = 12.706
    assert e["difference_mean_ci95"] == pytest.approx(
        [-0.75 - 12.7062 * 3.25, -0.75 + 12.7062 * 3.25], rel=1e-4
    )
    # the reference defaults to the first agent when apf-mpc was not evaluated
    assert ev.paired_delta_v(rigged)["reference"] == "zero"
    other = ev.summarize(rigged, reference="random")["paired_delta_v"]
    assert other["reference"] == "random" and other["agents"]["zero"]["difference_mean"] == (
        pytest.approx(-e["difference_mean"])
    )
    md = ev.summary_markdown(ev.summarize(rigged))
    assert "| random | 2 / 3 | 19.2 | 20 | -0.75 [" in md
    assert ev.paired_delta_v(results)["agents"]["random"]["difference_mean"] is None  # none
    with pytest.raises(ValueError, match="reference='apf'"):
        ev.paired_delta_v(results, reference="apf")


def test_wilson_interval_hand_computed():
    # z = 1.959964; centre (p + z²/2n)/(1 + z²/n), half-width z/(1 + z²/n)·sqrt(p(1−p)/n + z²/4n²)
    assert ev.wilson_interval(0, 20) == pytest.approx((0.0, 0.161125), abs=1e-6)
    assert ev.wilson_interval(20, 20) == pytest.approx((0.838875, 1.0), abs=1e-6)
    assert ev.wilson_interval(10, 20) == pytest.approx((0.299298, 0.700702), abs=1e-6)
    assert ev.wilson_interval(1, 3) == pytest.approx((0.061492, 0.792340), abs=1e-6)
    with pytest.raises(ValueError):
        ev.wilson_interval(3, 2)


def test_t_interval_matches_scipy():
    x = [3.1, 4.7, 2.2, 5.9, 4.0, 3.3]
    expected = stats.t.interval(0.95, len(x) - 1, loc=np.mean(x), scale=stats.sem(x))
    assert ev.t_interval(x) == pytest.approx(expected)
    assert ev.t_interval([2.0, 2.0, 2.0]) == pytest.approx((2.0, 2.0))
    assert ev.t_interval([1.0]) == (None, None)


def test_agent_spec_parsing():
    a, b, c, d = ev.parse_agent_specs("apf, ppo=runs/a/model.zip,ppo:runs/b/best.zip,pretrained")
    assert (a.kind, a.name, a.label) == ("baseline", "apf", "apf")
    assert (b.kind, b.name, b.path, b.label) == ("learned", "ppo", "runs/a/model.zip", "ppo:model")
    assert (c.path, c.label, c.load_string) == (
        "runs/b/best.zip",
        "ppo:best",
        "ppo:runs/b/best.zip",
    )
    assert (d.kind, d.load_string) == ("pretrained", "pretrained")
    same_stem = ev.parse_agent_specs(["sac=x/model.zip", "sac=y/model.zip"])
    assert [s.label for s in same_stem] == ["sac:model", "sac:model#2"]
    for name in agents.BASELINES:
        assert ev.parse_agent_spec(name).kind == "baseline"
    with pytest.raises(ValueError, match="known baselines: zero, random"):
        ev.parse_agent_spec("nope")


def test_learned_agents_are_loaded_by_load_agent(monkeypatch, tmp_path):
    model = tmp_path / "model.zip"
    spec = ev.parse_agent_spec(f"ppo={model}")
    with pytest.raises(FileNotFoundError, match="not found"):
        ev.check_agent_available(spec)
    model.write_bytes(b"")
    ev.check_agent_available(spec)
    calls = []
    monkeypatch.setattr(agents, "load_agent", lambda s, e: calls.append(s) or "policy")
    env = gym.make("DebrisGym/Rendezvous2D-v0", **SMALL)
    assert ev.build_agent(spec, env) == "policy"
    assert ev.build_agent("pretrained", env) == "policy"
    assert calls == [f"ppo:{model}", "pretrained"]
    env.close()


# --- your own policy: objects, factories and MODULE:ATTR ---------------------------------------


class _Hover:
    """A policy written in the test: never thrusts, so it must fly exactly like ``zero``."""

    def __init__(self, shape):
        self.shape = shape
        self.calls = 0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.calls += 1
        return np.zeros(self.shape, dtype=np.float32), state


def _flights(results, label):
    return [r.trajectory.positions for r in results.for_agent(label)]


def test_policy_objects_and_factories_fly_like_the_baseline_they_copy():
    hover = _Hover((2,))
    res = ev.evaluate_agents(
        "DebrisGym/Rendezvous2D-v0",
        {"zero": "zero", "object": hover, "factory": lambda env: _Hover(env.action_space.shape)},
        episodes=2, seed=3, env_kwargs=SMALL, progress=False, max_episode_steps=25,
    )  # fmt: skip
    assert [s.label for s in res.agents] == ["zero", "object", "factory"]
    assert [s.kind for s in res.agents] == ["baseline", "object", "object"]
    assert hover.calls == sum(r.steps for r in res.for_agent("object")) == 2 * 25
    for label in ("object", "factory"):
        for mine, ref in zip(_flights(res, label), _flights(res, "zero"), strict=True):
            assert np.array_equal(mine, ref)
    assert [r.delta_v for r in res.for_agent("factory")] == [0.0, 0.0]


def test_module_attr_specs_parse_apart_from_learned_paths():
    mine = ev.parse_agent_spec("mine=example_policies:make_policy")
    assert (mine.kind, mine.name, mine.label) == ("python", "example_policies:make_policy", "mine")
    short = ev.parse_agent_spec("example_policies:CoastPolicy")
    assert (short.kind, short.label) == ("python", "CoastPolicy")
    learned = ev.parse_agent_spec("PPO:runs/a=b/model.zip")  # the algorithm decides, not "="
    assert (learned.kind, learned.name, learned.path) == ("learned", "ppo", "runs/a=b/model.zip")
    with pytest.raises(ValueError, match="MODULE:ATTR"):
        ev.parse_agent_spec("mine=my-file.py:make")


@pytest.mark.parametrize("attr", ["make_policy", "CoastPolicy"])
def test_module_attr_factory_and_class_build_a_policy(attr):
    env = gym.make("DebrisGym/Rendezvous2D-v0", **SMALL)
    policy = ev.build_agent(f"example_policies:{attr}", env)
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert action.shape == env.action_space.shape and not action.any()
    env.close()


@pytest.mark.parametrize(
    ("spec", "error", "text"),
    [
        ("mine=no_such_module_xyz:make", ImportError, "'no_such_module_xyz' cannot be imported"),
        ("mine=example_policies:missing", ImportError, "has no attribute 'missing'"),
        ("mine=example_policies:NOT_A_POLICY", TypeError, "no predict"),
        ("mine=example_policies:make_nothing", TypeError, "no predict"),
    ],
)
def test_module_attr_problems_are_named(spec, error, text):
    env = gym.make("DebrisGym/Rendezvous2D-v0", **SMALL)
    with pytest.raises(error, match=re.escape(text)):
        ev.build_agent(spec, env)
    env.close()


def test_a_mapping_value_without_predict_or_call_is_refused():
    with pytest.raises(TypeError, match=r"'mine'.*no predict"):
        ev.parse_agent_specs({"mine": 3.5})


def test_script_evaluates_a_module_attr_policy_from_the_current_directory(tmp_path):
    out = tmp_path / "eval"
    proc = subprocess.run(
        [
            sys.executable, str(SCRIPT), "--agents", "zero,mine=example_policies:make_policy",
            "--episodes", "1", "--env-kwargs", json.dumps(SMALL), "--max-steps", "20",
            "--plots", "0", "--no-progress", "--out", str(out),
        ],
        cwd=Path(__file__).parent, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    rows = {r["agent"]: r for r in csv.DictReader(open(out / "episodes.csv", newline=""))}
    assert set(rows) == {"zero", "mine"}
    assert rows["mine"]["delta_v"] == "0.0" and rows["mine"]["steps"] == "20"
    assert rows["mine"]["path_length"] == rows["zero"]["path_length"]


def test_script_names_a_broken_module_attr_agent(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--agents", "mine=example_policies:NOT_A_POLICY",
         "--out", str(tmp_path / "out")],
        cwd=Path(__file__).parent, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2
    assert "argument --agents" in proc.stderr and "no predict" in proc.stderr


def test_plot_is_a_png_for_3d(tmp_path):
    res = ev.evaluate_agents(
        "DebrisGym/Rendezvous3D-v0", "zero,random", episodes=1, seed=0,
        env_kwargs=SMALL, progress=False, max_episode_steps=20,
    )  # fmt: skip
    written = ev.write_outputs(res, tmp_path, plots=5)
    names = [p.name for p in written]
    assert names == ["episodes.csv", "summary.json", "summary.md", "trajectories_ep000.png"]
    assert (tmp_path / "trajectories_ep000.png").read_bytes().startswith(b"\x89PNG")
