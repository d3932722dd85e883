"""Evaluate guidance agents on the same seeded debris fields; write tables and trajectory plots.

Every agent flies the same episodes: episode i starts with env.reset(seed=SEED + i), and the
debris field comes from that seed. Outputs in --out DIR:

  episodes.csv              one row per agent x episode
  summary.json              per agent: success_rate, targets_captured_mean, delta_v_mean,
                            time_mean, path_length_mean, collision_rate, min_clearance_min,
                            decision_ms_p50/p95, with 95 % confidence intervals; and
                            paired_delta_v: each agent's Δv minus apf-mpc's (or the
                            first agent's, or --reference's) on the episodes both
                            complete, paired by seed
  summary.md                the Markdown table also printed to stdout
  trajectories_epNNN.png    all agents' trajectories over the field, first --plots episodes
  paper_table.md/.json      with --paper: seed 000's Table I beside our measurements

Agents: baseline names (see --agents), ALGO=PATH for a learned policy (ppo, sac, td3, dqn), or
'pretrained' (the policy shipped for the env, see docs/training.md). Learned agents are
loaded with agents.load_agent; models trained by train.py restore their VecNormalize statistics.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

EXAMPLES = """\
examples:
  python evaluate.py                                   # every baseline, 20 episodes, runs/eval
  python evaluate.py --agents apf,apf-mpc,astar --episodes 50 --seed 100 --out runs/cmp
  python evaluate.py --env DebrisGym/Rendezvous3D-v0 --env-kwargs '{"n_obstacles": 40}'
  python evaluate.py --agents apf,ppo=runs/ppo/model.zip
  python evaluate.py --paper --out runs/paper          # seed 000 Table I, ours beside theirs
"""

DEFAULT_ENV = "DebrisGym/Rendezvous2D-v0"
DEFAULT_EPISODES = 20
DEFAULT_OUT = "runs/eval"


def _positive_int(text: str) -> int:
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _non_negative_int(text: str) -> int:
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None


def _json_object(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"invalid JSON ({exc}): {text!r}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(
            f"must be a JSON object such as '{{\"n_obstacles\": 40}}', got {text!r}"
        )
    return value


def build_parser() -> argparse.ArgumentParser:
    from agents import BASELINES

    parser = argparse.ArgumentParser(
        prog="evaluate.py",
        description=__doc__,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
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
        + "; ALGO=PATH for a learned policy (ppo, sac, td3, dqn); 'pretrained'. Default: every "
        "baseline, plus 'pretrained' when a pretrained policy is available",
    )
    parser.add_argument(
        "--episodes",
        type=_positive_int,
        default=None,
        metavar="N",
        help=f"episodes per agent, >= 1 (default: {DEFAULT_EPISODES})",
    )
    parser.add_argument(
        "--seed", type=_int, default=0, help="reset seed of episode 0; episode i uses SEED + i"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(DEFAULT_OUT),
        metavar="DIR",
        help=f"output directory, created if needed (default: {DEFAULT_OUT})",
    )
    parser.add_argument(
        "--plots",
        type=_non_negative_int,
        default=3,
        metavar="N",
        help="trajectory plots of the first N episodes (default: 3; 0 = none)",
    )
    parser.add_argument(
        "--env-kwargs",
        type=_json_object,
        default=None,
        metavar="JSON",
        help="extra gym.make keyword arguments as a JSON object, e.g. '{\"n_obstacles\": 40}'",
    )
    parser.add_argument(
        "--max-steps",
        type=_positive_int,
        default=None,
        metavar="N",
        help="override the env's time limit (max_episode_steps) — for quick checks; headline "
        "numbers use the registered limit",
    )
    parser.add_argument(
        "--reference",
        default=None,
        metavar="AGENT",
        help="agent the others' Δv is paired with on the episodes both complete (default: "
        "apf-mpc if evaluated, else the first agent)",
    )
    parser.add_argument(
        "--no-progress", action="store_true", help="no progress bar (it goes to stderr)"
    )
    parser.add_argument(
        "--paper",
        action="store_true",
        help="seed 000 reproduction: one episode of DebrisGym/PaperField2D-v0 (its world is "
        "fixed) with apf, apf-mpc and astar; prints Table I beside our measurements and writes "
        "DIR/paper_table.md and .json. Not combinable with --env, --agents, --episodes",
    )
    return parser


def _note(text: str) -> None:
    print(f"note: {text}", file=sys.stderr)


def _default_agents(
    env_id: str, env_kwargs: dict[str, Any], max_steps: int | None
) -> tuple[list[str], dict[str, str]]:
    """Every baseline, and 'pretrained' if agents.load_agent exists and can load it.

    Returns the agent names and {skipped agent: reason}.
    """
    import agents
    from agents.evaluation import PRETRAINED, agent_env_options, make_env

    names = list(agents.BASELINES)
    load_agent = getattr(agents, "load_agent", None)
    if load_agent is None:
        reason = (
            "learned agents arrive with the training issue (agents.load_agent does not exist yet)"
        )
    else:
        env = make_env(env_id, {**env_kwargs, **agent_env_options(PRETRAINED, env_id)}, max_steps)
        try:
            load_agent(PRETRAINED, env)
        except (FileNotFoundError, NotImplementedError, ValueError, KeyError) as exc:
            reason = f"no pretrained policy for {env_id} ({exc})"
        else:
            return [*names, PRETRAINED], {}
        finally:
            env.close()
    _note(f"skipped 'pretrained' — {reason}")
    return names, {PRETRAINED: reason}


def _usable(
    specs: list, explicit: bool, parser: argparse.ArgumentParser, flag: str, make_env: Any
) -> tuple:
    """Check each agent can be built: an error naming it if listed explicitly, else a note.

    Learned and pretrained agents are loaded once here (``make_env(spec)`` gives the env), so a
    wrong file, a space mismatch or a missing pretrained policy fails before any episode runs.
    """
    from agents.evaluation import build_agent, check_agent_available

    keep, skipped = [], {}
    for spec in specs:
        try:
            check_agent_available(spec)
            if spec.kind != "baseline":
                env = make_env(spec)
                try:
                    build_agent(spec, env)
                finally:
                    env.close()
        except (ImportError, FileNotFoundError, NotImplementedError, ValueError) as exc:
            if explicit:
                parser.error(f"argument {flag}: {exc}")
            _note(f"skipped — {exc}")
            skipped[spec.label] = str(exc)
            continue
        keep.append(spec)
    return keep, skipped


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)

    import gymnasium as gym

    from agents import BASELINES
    from agents import evaluation as ev

    env_kwargs = args.env_kwargs or {}
    if args.paper:
        for flag, value in (("--env", args.env), ("--agents", args.agents)):
            if value is not None:
                parser.error(f"argument {flag}: not allowed with --paper (it fixes the env/agents)")
        if args.episodes is not None:
            parser.error("argument --episodes: not allowed with --paper (its world is fixed)")
        env_id, episodes = ev.PAPER_ENV_ID, 1
    else:
        env_id = args.env or DEFAULT_ENV
        episodes = args.episodes or DEFAULT_EPISODES

    try:  # validate the env ID and its keyword arguments before any agent runs
        ev.make_env(env_id, env_kwargs, args.max_steps).close()
    except gym.error.Error as exc:
        parser.error(f"argument --env: {exc}")
    except (TypeError, ValueError) as exc:
        parser.error(f"argument --env-kwargs: {exc}")

    explicit = args.agents is not None
    unregistered: dict[str, str] = {}
    if args.paper:
        agent_text: list[str] | str = [a for a in ev.PAPER_AGENTS if a in BASELINES]
        for name in sorted(set(ev.PAPER_AGENTS) - set(agent_text)):
            unregistered[name] = f"agent {name!r} is not in agents.BASELINES"
            _note(f"skipped — {unregistered[name]}")
    elif explicit:
        agent_text = args.agents
    else:
        agent_text, unregistered = _default_agents(env_id, env_kwargs, args.max_steps)
    try:
        specs = ev.parse_agent_specs(agent_text) if agent_text else []
    except ValueError as exc:
        parser.error(f"argument --agents: {exc}")
    specs, skipped = _usable(
        specs, explicit, parser, "--agents",
        lambda spec: ev.make_env(
            env_id, {**env_kwargs, **ev.agent_env_options(spec, env_id)}, args.max_steps
        ),
    )  # fmt: skip
    skipped = {**unregistered, **skipped}
    if not specs:
        flag = "--paper" if args.paper else "--agents"
        parser.error(f"argument {flag}: none of its agents can be built (see the notes above)")

    labels = [spec.label for spec in specs]
    if args.reference is not None and args.reference not in labels:
        parser.error(
            f"argument --reference: {args.reference!r} is not an evaluated agent; "
            f"agents: {', '.join(labels)}"
        )

    results = ev.evaluate_agents(
        env_id,
        specs,
        episodes=episodes,
        seed=args.seed,
        env_kwargs=env_kwargs,
        progress=not args.no_progress,
        max_episode_steps=args.max_steps,
    )
    summary = ev.summarize(results, reference=args.reference)
    if skipped:
        summary["skipped"] = skipped
    written = ev.write_outputs(results, args.out, plots=args.plots, summary=summary)

    print(ev.summary_markdown(summary), end="")
    if args.paper:
        table = ev.paper_table(results, skipped)
        text = ev.paper_table_markdown(table)
        for name, content in (("paper_table.md", text), ("paper_table.json", ev.to_json(table))):
            ev.write_atomic(args.out / name, content)
            written.append(args.out / name)
        print("\nSeed 000 Table I, paper vs ours:\n")
        print(text, end="")
    print(f"\nwrote {len(written)} files to {args.out}/ ({results.elapsed:.1f} s):")
    for path in written:
        print(f"  {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
