"""Gymnasium environments of debris-gym."""

from debris_gym.envs.debris_field import DebrisFieldEnv

__all__ = ["DebrisFieldEnv"]
