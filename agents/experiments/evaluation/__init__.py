"""Evaluate agents on the same seeded scenarios: episode records, summaries, tables and plots.

The library behind ``evaluate.py``, one job per module:

============  ======================================================================
specs         what to evaluate: baseline names, ``ppo=PATH``, ``pretrained``, your own
              ``LABEL=MODULE:ATTR`` or a policy object; building each for an env
runner        flying every agent on the same seeded episodes (:func:`evaluate_agents`)
episode       one episode flown and recorded (:func:`run_episode`)
workers       episodes apart from where they run: the worker, the plan that shares them out,
              the run's frame on any backend of workers (:class:`WorkerBackend`)
pool          the local process pool (``evaluate.py --workers N``; :class:`ProcessBackend`)
failures      an agent failing mid-run, an output that cannot be written
records       what a run produced (episode records, trajectories, the whole run)
metrics       [APF-MPC] Table I metrics of a trajectory
statistics    intervals inside each metric's range (Wilson, seeded bootstrap), per-agent
              summaries, success (exact McNemar), Δv and time paired by seed
report        the Markdown table, strict JSON, episodes.csv, writing the files as one set
journal       an unfinished run's options and finished episodes (Ctrl-C, ``--resume``)
plots         trajectory plots
video         mp4s of episodes (``--video``), the shield shown on the frames
paper         [APF-MPC] Table I side by side with ours, not a reproduction (``--paper``)
plan          ``evaluate.py``'s options as given and as resolved into a run
resolve       those options checked and resolved into a plan (env, suite, agents)
command       ``evaluate.py`` once its arguments are parsed: lock, journal, run, outputs
============  ======================================================================

Your own policy, from Python::

    from agents.experiments.evaluation import evaluate_agents, summarize, summary_markdown

    results = evaluate_agents(
        "DebrisGym/Rendezvous2D-v2",
        {"apf": "apf", "mine": MyPolicy()},  # or a factory: {"mine": lambda env: MyPolicy(env)}
        episodes=20,
        seed=0,
    )
    print(summary_markdown(summarize(results)))

A frozen suite (:mod:`debris_gym.suites`) from Python: its first N missions, each field pinned::

    from debris_gym.suites import load_suite

    suite = load_suite("standard-2d-v2")
    results = evaluate_agents(suite.env_id, "apf-mpc,astar", episodes=10, seed=0, suite=suite)

A policy is anything with SB3's ``predict(obs, state=None, episode_start=None,
deterministic=True) -> (action, state)``, a factory ``f(env) -> policy`` or a plain function
``f(obs) -> action``. On every core (worker processes; the same records; keep the script's main
code under ``if __name__ == "__main__":``, the workers import it again)::

    results = evaluate_agents(..., backend=ProcessBackend(workers=4))
"""

from agents.experiments.evaluation.failures import AgentFailure, OutputWriteError
from agents.experiments.evaluation.pool import ProcessBackend
from agents.experiments.evaluation.records import (
    CSV_COLUMNS,
    TIMING_COLUMNS,
    EpisodeRecord,
    EvaluationResults,
    Trajectory,
    scenario_fingerprint,
)
from agents.experiments.evaluation.report import (
    episodes_csv,
    summary_markdown,
    to_json,
    write_outputs,
)
from agents.experiments.evaluation.runner import evaluate_agents, make_env, run_episode
from agents.experiments.evaluation.specs import (
    LEARNED_ALGOS,
    PRETRAINED,
    AgentSpec,
    agent_env_options,
    build_agent,
    check_agent_available,
    parse_agent_spec,
    parse_agent_specs,
)
from agents.experiments.evaluation.statistics import (
    CONFIDENCE,
    bootstrap_interval,
    is_constant,
    mcnemar_exact,
    paired_delta_v,
    paired_success,
    summarize,
    t_interval,
    wilson_interval,
)

__all__ = [
    "CONFIDENCE",
    "CSV_COLUMNS",
    "LEARNED_ALGOS",
    "PRETRAINED",
    "TIMING_COLUMNS",
    "AgentFailure",
    "AgentSpec",
    "EpisodeRecord",
    "EvaluationResults",
    "OutputWriteError",
    "ProcessBackend",
    "Trajectory",
    "agent_env_options",
    "bootstrap_interval",
    "build_agent",
    "check_agent_available",
    "episodes_csv",
    "evaluate_agents",
    "is_constant",
    "make_env",
    "mcnemar_exact",
    "paired_delta_v",
    "paired_success",
    "parse_agent_spec",
    "parse_agent_specs",
    "run_episode",
    "scenario_fingerprint",
    "summarize",
    "summary_markdown",
    "t_interval",
    "to_json",
    "wilson_interval",
    "write_outputs",
]
