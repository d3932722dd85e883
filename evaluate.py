"""Evaluate guidance agents on the same seeded debris fields; write tables and trajectory plots.

Every agent flies the same episodes: episode i starts with env.reset(seed=SEED + i), and the
debris field comes from that seed. With --suite NAME every agent flies the frozen suite's
missions instead (shipped with the package, evaluation-only; suites: standard-2d-v2,
standard-3d-v2, hard-v2, and the v1 ones, ...): episode i pins mission i's field, and
--episodes N flies the first N.
Outputs in --out DIR:

  episodes.csv              one row per agent x episode; outcome is success, collision,
                            out_of_bounds, delta_v_budget (the Δv budget ran out: a failure,
                            also flagged in budget_spent) or time_limit
  summary.json              per agent: success_rate, targets_captured_mean, delta_v_mean,
                            time_mean, path_length_mean, collision_rate, budget_spent_rate,
                            min_clearance_min, decision_ms_p50/p95, with 95 %
                            confidence intervals inside
                            each metric's range (Wilson for rates, seeded percentile
                            bootstrap for means) and constant_columns; paired_success:
                            each agent against apf-mpc (or the first agent, or
                            --reference) on the same seeds, exact McNemar test (b, c,
                            p_value); paired_delta_v: Δv and time of flight minus the
                            reference's on the episodes both complete; suite: name and
                            content hash, with --suite
  summary.md                the Markdown tables also printed to stdout
  trajectories_epNNN.png    all agents' trajectories over the field, first --plots episodes
  paper_table.md/.json      with --paper: [APF-MPC] Table I side by side with ours (not a
                            reproduction; the reasons are in the table)
  manifest.json             the files of the set and the run's options (suite and hash)

With --shield every agent flies behind the safety shield (run-time assurance; see
docs/baselines.md): episodes.csv counts the commands it replaced (shield_interventions) and
their size (shield_size_mean/max, a fraction of the thrust limit), summary.json and the
table summarise them, and the title says the run was shielded.

The files land together or not at all: they are written aside and moved into place at the end,
and files of an earlier evaluation that this one does not write (trajectory plots of episodes no
longer plotted, say) are removed. One run at a time may use a directory (a second is refused).
Without --out a run writes to runs/eval, or to runs/eval-2, -3, ... when runs/eval holds another
run (the path is printed): it never replaces another run's results.
While it runs, DIR/unfinished/ holds the run's options and every finished episode; Ctrl-C keeps
them and prints the command that finishes the run, `python evaluate.py --resume DIR`. An agent
that fails mid-run (its predict raises or returns no valid action) or a file that cannot be
written (a full disk) stops the run the same way, naming the agent, episode and step (or the
file); exit status 1.

The episodes are flown by worker processes, one per core (--workers N to choose; 1 = in this
process), each building its envs and agents once; the results are those of one process, row for
row (apart from decision times). With --backend ray they are flown by Ray workers instead (a
local Ray, or the cluster given by --address). The journal and --resume work the same (a
resumed run may change --backend, --address and --workers). See docs/distributed.md.

Code that runs: --agents LABEL=MODULE:ATTR imports MODULE (from the working directory if it is
there, else from PYTHONPATH / installed packages; no other file of the working directory is
imported), and a learned model's files are read by Stable-Baselines3, whose model zip holds
pickled objects: evaluate only models and modules you trust (docs/validation.md).

Agents (--agents, comma-separated):
  apf, astar, ...           a baseline by name
  ALGO=PATH or ALGO:PATH    a policy trained by train.py, ALGO one of ppo, sac, td3, dqn,
                            recurrent_ppo
                            (models restore their VecNormalize statistics)
  ALGO=RUN_DIR              a train.py run directory: its model.zip, else (a run stopped
                            early) its newest checkpoint, with a note saying which
  pretrained                the policy shipped for the env (see docs/training.md)
  LABEL=MODULE:ATTR         your own policy, labelled LABEL: ATTR in module MODULE (a dotted
                            name found in the current directory or on PYTHONPATH, not a
                            file path) is a policy object with SB3's predict(obs, state,
                            episode_start, deterministic), a factory ATTR(env) -> policy, or
                            a plain function ATTR(obs) -> action
  MODULE:ATTR               the same, labelled ATTR
The colon of ALGO:PATH and MODULE:ATTR is told apart by the word before it: ppo, sac, td3, dqn
and recurrent_ppo name an algorithm, anything else a module. From Python, evaluate_agents() also
takes policy objects: see agents.experiments.evaluation and docs/training.md.

Swarm IDs (--env DebrisGym/Swarm2D-v0, Swarm3D-v0, Swarm2D-Easy-v0, Reconfigure2D-v0,
Reconfigure3D-v0) fly teams, one single-agent policy per chaser behind an assignment of the
targets or slots (docs/swarm.md, "Baselines"), or a multi-agent team:
  team-AGENT@RULE           AGENT a baseline (apf-mpc, zero, ...), pretrained (the policy
                            shipped for the swarm's single-agent world) or ALGO:PATH; RULE
                            balanced (the env's; the default), greedy, optimal, minmax or
                            auction; team-st-rrt plans in space-time around the plans of the
                            chasers ahead of each (prioritised planning)
  ma-se-scp[@RULE]          multi-agent SE-SCP (docs/baselines.md)
Default: team-apf-mpc and team-pretrained under every rule, and team-zero@balanced. Every
team flies episode i from reset(seed=SEED + i), or the missions of a swarm suite (--suite
swarm-2d-v0, reconfigure-3d-v0); the run writes episodes.csv (one row per team x episode:
team success, per-chaser outcomes, debris and teammate collisions, min separation, Δv, time,
the assignment with its tour cost and gap to the optimal, decision time per chaser),
assignments.csv (every rule on every field), summary.json, summary.md and trajectory plots
(--plots N), and videos (--video N), in one process, or on --workers N processes (the same
records apart from the timing columns; default --out runs/eval-swarm). Every finished episode
is journaled in DIR/unfinished/, so a run stopped by Ctrl-C or a failing team is finished by
--resume DIR (a 48-chaser reconfiguration episode takes about half an hour).
With --shield every chaser of every team flies behind a safety shield of its own that counts
its teammates as bodies on their predicted tracks (shield_interventions in episodes.csv, per
team and chaser; summary.json and the table summarise them; the title says so).
--paper and --backend ray do not apply and are refused.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from agents.experiments import cli

EXAMPLES = """\
examples:
  python evaluate.py                                   # every baseline, 20 episodes, runs/eval
  python evaluate.py --agents apf,apf-mpc,astar --episodes 50 --seed 100 --out runs/cmp
  python evaluate.py --env DebrisGym/Rendezvous3D-v0 --env-kwargs '{"n_obstacles": 40}'
  python evaluate.py --agents apf,ppo=runs/ppo/model.zip
  python evaluate.py --agents apf,mine=my_pkg.my_mod:make_policy   # your own policy
  python evaluate.py --suite standard-2d-v2 --agents apf-mpc,astar --episodes 10
  python evaluate.py --paper --out runs/paper          # [APF-MPC] Table I side by side
  python evaluate.py --agents apf,apf-mpc --shield     # every agent behind the safety shield
  python evaluate.py --agents apf-mpc,pretrained --video 2   # mp4s of the first 2 episodes
  python evaluate.py --suite standard-2d-v2 --episodes 20 --robustness   # under every error
  python evaluate.py --resume runs/cmp                 # finish a run stopped by Ctrl-C
  python evaluate.py --workers 1                       # everything in this one process
  python evaluate.py --backend ray --workers 2 --episodes 200    # episodes on a local Ray
  python evaluate.py --backend ray --address auto ...  # on the Ray cluster this node is part of
  python evaluate.py --env DebrisGym/Swarm2D-v0 --episodes 30        # every swarm team
  python evaluate.py --env DebrisGym/Swarm2D-v0 --agents team-apf-mpc@minmax,team-zero
  python evaluate.py --env DebrisGym/Swarm2D-v0 --agents team-pretrained@minmax --shield
"""


def _out_dir(text: str) -> Path:
    """``--out DIR`` checked before anything runs: not empty, not a file, not under a file,
    writable."""
    from agents.experiments.run_directory import OutputDirError, check_output_dir

    try:
        return check_output_dir(text)
    except OutputDirError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _run_dir(text: str) -> Path:
    """``--resume DIR``: an existing directory (whether it holds a journal is checked later)."""
    path = _out_dir(text)
    if not path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is not a directory")
    return path


def _suite_names() -> list[str]:
    from debris_gym.suites import list_suites

    return list_suites()


def build_parser() -> argparse.ArgumentParser:
    from agents import BASELINES
    from agents.experiments.evaluation.command import DEFAULT_ENV, DEFAULT_EPISODES, DEFAULT_OUT
    from agents.experiments.evaluation.specs import LEARNED_ALGOS

    parser = cli.script_parser("evaluate.py", __doc__, EXAMPLES)
    parser.add_argument(
        "--env",
        default=None,
        metavar="ID",
        help=f"environment ID (default: {DEFAULT_ENV})",
    )
    parser.add_argument(
        "--agents",
        default=None,
        metavar="LIST",
        help="comma-separated agents: baselines "
        + ", ".join(BASELINES)
        + "; ALGO=PATH for a learned policy ("
        + ", ".join(LEARNED_ALGOS)
        + "); 'pretrained'; "
        "LABEL=MODULE:ATTR for your own policy object, factory or function (see above). Default: "
        "every "
        "baseline, plus 'pretrained' when a pretrained policy is available",
    )
    parser.add_argument(
        "--episodes",
        type=cli.integer(1, cli.MAX_EPISODES),
        default=None,
        metavar="N",
        help=f"episodes per agent, >= 1 (default: {DEFAULT_EPISODES})",
    )
    parser.add_argument(
        "--seed",
        type=cli.integer(0, cli.MAX_SEED),
        default=None,
        help="reset seed of episode 0, >= 0; episode i uses SEED + i (default: 0)",
    )
    parser.add_argument(
        "--suite",
        default=None,
        metavar="NAME",
        help="fly the frozen evaluation suite NAME shipped with the package ("
        + ", ".join(_suite_names())
        + "): its env, options and missions; --episodes N flies its first N (default: all). "
        "Not combinable with --env, --seed, --env-kwargs, --paper",
    )
    parser.add_argument(
        "--out",
        type=_out_dir,
        default=None,
        metavar="DIR",
        help=f"output directory, created if needed; checked before anything runs (default: "
        f"{DEFAULT_OUT}, or {DEFAULT_OUT}-2, -3, … when it holds another run: a run without "
        "--out never replaces one)",
    )
    parser.add_argument(
        "--resume",
        type=_run_dir,
        default=None,
        metavar="DIR",
        help="finish the evaluation that Ctrl-C (or a failing agent, or a full disk) stopped in "
        "DIR: its options are read from DIR/unfinished/, its finished episodes kept, the rest "
        "run, and the outputs written as usual. No other option but --no-progress, --workers, "
        "--backend and --address",
    )
    parser.add_argument(
        "--plots",
        type=cli.integer(0, cli.MAX_EPISODES),
        default=None,
        metavar="N",
        help="trajectory plots of the first N episodes (default: 3; 0 = none)",
    )
    parser.add_argument(
        "--env-kwargs",
        type=cli.json_object,
        default=None,
        metavar="JSON",
        help="extra gym.make keyword arguments as a JSON object, e.g. '{\"n_obstacles\": 40}'",
    )
    parser.add_argument(
        "--max-steps",
        type=cli.integer(1, cli.MAX_EPISODE_STEPS),
        default=None,
        metavar="N",
        help="override the env's time limit (max_episode_steps) — for quick checks; headline "
        "numbers use the registered limit",
    )
    parser.add_argument(
        "--reference",
        default=None,
        metavar="AGENT",
        help="agent the others are paired with by seed — success (exact McNemar test), and "
        "Δv and time on the episodes both complete (default: apf-mpc if evaluated, else the "
        "first agent)",
    )
    parser.add_argument(
        "--robustness",
        action="store_true",
        help="fly the evaluation again under each error of the uncertain world at three "
        "levels (navigation, actuation, truth model, sensing) into OUT/<condition>/ and "
        "gather OUT/robustness.md and .json (default --out runs/robustness; "
        "docs/baselines.md, 'Robustness')",
    )
    parser.add_argument(
        "--shield",
        action="store_true",
        help="fly every agent behind the safety shield (run-time assurance): each command is "
        "checked against the bodies' predicted motion over a short horizon and replaced by "
        "the closest safe one; interventions are counted in episodes.csv, summary.json and "
        "the table (docs/baselines.md, 'The safety shield'); on swarm IDs one shield per "
        "chaser, its teammates counted as bodies (docs/swarm.md)",
    )
    parser.add_argument(
        "--video",
        type=cli.integer(0, cli.MAX_EPISODES),
        default=0,
        metavar="N",
        help="record each agent's first N episodes as mp4 in DIR/videos/<agent>/ "
        "(gymnasium's RecordVideo; needs moviepy: pip install 'debris-gym[video]')",
    )
    parser.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help="where the episodes run: local (worker processes on this machine, see --workers; "
        "default) or ray (fanned out to Ray workers, one env and agent each; the same results; "
        "needs pip install 'debris-gym[distributed]'; docs/distributed.md)",
    )
    parser.add_argument(
        "--address",
        default=None,
        metavar="ADDR",
        help="with --backend ray: the Ray cluster to join (auto, HOST:6379, ray://HOST:10001); "
        "default: start a local Ray for the run",
    )
    parser.add_argument(
        "--workers",
        type=cli.integer(1, cli.MAX_WORKERS),
        default=None,
        metavar="N",
        help="processes flying the episodes, >= 1: local worker processes (default: one per "
        "core; 1 = this process alone; --video records in this process) or, with --backend "
        "ray, Ray workers (default: one per CPU of the cluster); on swarm IDs, processes "
        "each flying whole team episodes (default 1). The results are the same whatever the "
        "count",
    )
    parser.add_argument(
        "--no-progress",
        dest="progress",
        action="store_false",
        help="no progress bar (it goes to stderr)",
    )
    parser.add_argument(
        "--paper",
        action="store_true",
        help="a side-by-side with seed 000's Table I [APF-MPC], NOT a reproduction: one "
        "episode of DebrisGym/PaperField2D-v0 (our reconstruction of the paper's world) with "
        "apf, apf-mpc and astar; prints Table I beside our measurements and writes "
        "DIR/paper_table.md and .json, with the reasons the numbers are not comparable (the "
        "world is reconstructed; units, time step and metric definitions differ). Not "
        "combinable with --env, --agents, --episodes, --suite",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.interrupt_on_signals()  # also when started in the background, where SIGINT is ignored

    from agents.experiments.distributed.evaluation import RayRemote
    from agents.experiments.evaluation.command import (
        EvaluateOptions,
        EvaluationInterrupted,
        EvaluationStopped,
        UsageError,
        run_evaluation,
    )
    from agents.experiments.swarm_evaluation import is_swarm_id, is_swarm_suite

    arguments = vars(args)
    robustness = arguments.pop("robustness")
    from agents.experiments.swarm_evaluation.journal import is_swarm_journal

    swarm_resume = args.resume is not None and is_swarm_journal(args.resume)
    if swarm_resume or is_swarm_id(args.env) or (args.env is None and is_swarm_suite(args.suite)):
        if robustness:
            parser.error("argument --robustness: swarms fly the exact world only")
        return _swarm(parser, args)
    options = EvaluateOptions(**arguments)  # the parser's destinations are the option names
    try:
        if robustness:
            text = _robustness(options, lambda o: run_evaluation(o, remote={"ray": RayRemote()}))
        else:
            text = run_evaluation(options, remote={"ray": RayRemote()})
    except UsageError as exc:
        parser.error(f"argument {exc.flag}: {exc}")
    except EvaluationInterrupted as exc:
        print(f"\n{exc.message()}", file=sys.stderr)
        return 130
    except EvaluationStopped as exc:
        print(f"\n{exc.message()}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # while the arguments were checked: nothing ran
        kept = f"{args.resume}/unfinished/ is unchanged" if args.resume else "nothing saved"
        print(f"\ninterrupted before any episode ran; {kept}", file=sys.stderr)
        return 130
    print(text, end="")
    return 0


def _robustness(options: Any, run: Any) -> str:
    """``--robustness``: the evaluation under every condition of the robustness table."""
    from agents.experiments.evaluation.plan import UsageError
    from agents.experiments.evaluation.robustness import run_robustness

    if options.resume is not None:
        raise UsageError("--resume", "not allowed with --robustness (resume each condition)")
    out = Path("runs/robustness") if options.out is None else options.out
    text = run_robustness(options, out, run, echo=lambda line: print(line, file=sys.stderr))
    return text + f"\nwritten: {out / 'robustness.md'}, {out / 'robustness.json'}\n"


def _swarm(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``--env SWARM_ID``: teams on the swarm IDs (agents.experiments.swarm_evaluation)."""
    from agents.experiments.evaluation.plan import UsageError
    from agents.experiments.swarm_evaluation import (
        SwarmEvaluateOptions,
        SwarmRunStopped,
        run_swarm_evaluation,
    )

    try:
        text = run_swarm_evaluation(SwarmEvaluateOptions.from_arguments(vars(args)))
    except UsageError as exc:
        parser.error(f"argument {exc.flag}: {exc}")
    except SwarmRunStopped as exc:
        print(f"\n{exc.message()}", file=sys.stderr)
        return 130 if exc.interrupted else 1
    except KeyboardInterrupt:  # before the first episode began
        kept = f"{args.resume}/unfinished/ is unchanged" if args.resume else "nothing saved"
        print(f"\ninterrupted before any episode ran; {kept}", file=sys.stderr)
        return 130
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
