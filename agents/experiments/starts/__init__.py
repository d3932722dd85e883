"""Missions that start part-way for training: a bank of recorded start states and a sampler
that favours the legs a learner fails (docs/training.md, "Starting part-way")."""

from agents.experiments.starts.bank import build_start_bank, fly_and_record
from agents.experiments.starts.sampler import LegSampler, SamplerParams

__all__ = ["LegSampler", "SamplerParams", "build_start_bank", "fly_and_record"]
