"""Train SB3 agents (PPO, SAC, TD3, DQN) on the DebrisGym envs: configs, callbacks, runs, resume.

The library behind ``train.py``, one job per module (import from them; this package file stays
empty so that reading a config does not import torch):

===========  =========================================================================
config       :class:`TrainConfig` (typed, validated recipes), the checked-in configs
validation   the checks behind :meth:`TrainConfig.from_dict`
models       the training / evaluation envs and the SB3 model's arguments
callbacks    SB3 callbacks: curriculum, episode log, held-out evaluation, checkpoints
checkpoints  saving a model with its sidecars atomically; the latest checkpoint
run_files    config.yaml, train_log.json, train_episodes.csv
run          :func:`train` (fresh or resumed) — what ``train.py`` calls
curve        the learning-curve plot
===========  =========================================================================

A run directory holds::

    DIR/model.zip                 final model (written atomically)
    DIR/vecnormalize.pkl          its VecNormalize statistics (when normalisation is on)
    DIR/replay_buffer.pkl         off-policy replay buffer (when small, or on request)
    DIR/config.yaml               the resolved config plus how the run was made (``run:``)
    DIR/train_log.json            wall time and env-steps/s of every segment (fresh run, resumes)
    DIR/learning_curve.png        evaluation return and success rate vs timesteps, training return
    DIR/evaluations.npz           EvalCallback's log (held-out seeds >= EVAL_SEED)
    DIR/best_model.zip            best evaluation so far (+ best_model_vecnormalize.pkl)
    DIR/train_episodes.csv        every finished training episode (VecMonitor), with its timestep
    DIR/checkpoints/              rl_model_<N>_steps.zip (+ _vecnormalize_, _replay_buffer_ .pkl),
                                  interrupted.zip (+ interrupted_vecnormalize.pkl …) after Ctrl-C
    DIR/tb/                       TensorBoard logs (if the ``tensorboard`` package is installed)
    DIR/.lock                     held by the run in progress (one run per directory at a time)

Training envs are :class:`~debris_gym.integrations.sb3.NativeVecEnv` (the native vector env) in
SB3's ``VecMonitor`` and, optionally, ``VecNormalize``. Sub-env ``i`` of a fresh run is seeded with
``seed + i``; evaluation uses seeds ``EVAL_SEED + i`` so it never flies a training field first.
"""
