"""Guidance baselines for the debris_gym environments."""
