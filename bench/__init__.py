"""Step and reset throughput of the DebrisGym environments, relative to CartPole-v1.

Run from the repo root::

    python bench/run.py                       # every section
    python bench/run.py --quick               # fewer / shorter repeats, smaller N
    python bench/run.py --only vector,train   # some sections only
    python bench/run.py --only swarm          # the swarm core against VMAS
    python bench/run.py --out docs/bench_table.md
    python -m bench --quick                   # the same command line

or from Python: ``bench.run(quick=True)`` returns the rows, ``bench.format_report(rows, ...)``
the Markdown report.

Sections (``--only`` takes a comma-separated list; default: all of them), one module each:

* ``single`` (:mod:`bench.single`): the single env's step cost against CartPole-v1
  (``gym.make`` and unwrapped), against the debris count, and reset cost.
* ``vector`` (:mod:`bench.vector`): env-steps/s of the native vector env at several N, next to
  gymnasium's SyncVectorEnv, SB3's SubprocVecEnv and CartPole-v1's native vector env.
* ``scaling`` (:mod:`bench.scaling`): the native vector env against the debris count.
* ``swarm`` (:mod:`bench.swarm`): chaser-steps/s of the native swarm core at K = 1, 8, 48, 256
  chasers per field, next to VMAS's navigation scenario at equal envs × agents (VMAS comes with
  the ``bench`` extra; without it those rows carry an error).
* ``memory`` (:mod:`bench.memory`): bytes of state per sub-env, measured in fresh processes.
* ``train`` (:mod:`bench.train`): end-to-end SB3 PPO env-steps/s on the native and on a
  Dummy VecEnv, split into env, the rest of the rollout, and the update.
* ``decisions`` (:mod:`bench.decisions`): decision times (p50 / p95 / max ms per ``predict``
  call) of every baseline and the pretrained policy on the default evaluation's missions.

The rest: :mod:`bench.harness` (set-up, interleaved repeats, tear-down, shared by every
section), :mod:`bench.config` (env IDs and the sizes of a quick, full or tiny run),
:mod:`bench.suite` (:func:`run`), :mod:`bench.report` and :mod:`bench.machine` (the Markdown
report) and :mod:`bench.cli` (the command line).

Within a section, measurements are interleaved across repeats (A, B, C, A, B, C, …) so that
machine noise hits them alike; each cell reports the median and the best (minimum time) of the
repeats, and ratios of two measurements come with the range of their same-repeat ratios.
"""

from bench.report import format_report
from bench.suite import SECTIONS, run

__all__ = ["SECTIONS", "format_report", "run"]
