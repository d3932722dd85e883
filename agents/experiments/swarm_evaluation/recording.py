"""Pictures of swarm episodes: a trajectory plot of every chaser (``evaluate.py --plots N``) and
videos (``--video N``) of each team's first episodes.

The team's env is made with ``render_mode="rgb_array"`` when either is asked for; its frames
(:meth:`~debris_gym.swarm.parallel.SwarmParallelEnv.render`) show every chaser still in the
field, each one's path this episode and its goal slot. The last frame of an episode is its
trajectory plot (``trajectories_ep<i>_<team>.png`` in the output set); a video holds a frame
per step (``DIR/videos/<team>/episode-<i>.mp4``, written by moviepy, which the ``video``
extra installs).
"""

from __future__ import annotations

import importlib.util
import io
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.evaluation.plan import UsageError
from agents.experiments.evaluation.specs import file_label

__all__ = [
    "DEFAULT_SWARM_PLOTS",
    "PLOT_PATTERN",
    "EpisodeFrames",
    "check_video_support",
    "plot_name",
    "png_bytes",
    "write_video",
]

DEFAULT_SWARM_PLOTS = 3
"""Trajectory plots per team when ``--plots`` is not given (as the single-agent evaluation)."""

PLOT_PATTERN = "trajectories_ep*.png"
"""The names of the plots in the output set."""

VIDEO_FPS = 15


def check_video_support(video: int) -> None:
    """Raise :class:`UsageError` for ``--video N`` (N > 0) without moviepy."""
    if video and importlib.util.find_spec("moviepy") is None:
        raise UsageError("--video", "needs moviepy to write mp4: pip install 'debris-gym[video]'")


def plot_name(episode: int, label: str) -> str:
    """The trajectory plot's file name of ``label``'s episode ``episode``."""
    return f"trajectories_ep{episode}_{file_label(label)}.png"


class EpisodeFrames:
    """What one episode records: every frame (a video) or only the last (a plot).

    Args:
        every_step: keep a frame after the reset and after every step (else only the last).
    """

    def __init__(self, every_step: bool) -> None:
        self.every_step = every_step
        self.frames: list[np.ndarray] = []

    def after(self, env: Any) -> None:
        """The env has just been reset or stepped."""
        if self.every_step:
            self.frames.append(env.render())

    def finish(self, env: Any) -> None:
        """The episode is over: its last frame (drawn now when frames were not kept)."""
        if not self.every_step:
            self.frames.append(env.render())

    @property
    def last(self) -> np.ndarray:
        """The episode's last frame."""
        return self.frames[-1]


def png_bytes(frame: np.ndarray) -> bytes:
    """An (H, W, 3) uint8 frame as PNG bytes."""
    from matplotlib import image

    buffer = io.BytesIO()
    image.imsave(buffer, frame, format="png")
    return buffer.getvalue()


def write_video(out: Path, label: str, episode: int, frames: list[np.ndarray]) -> Path:
    """Write ``frames`` as ``out/videos/<label>/episode-<episode>.mp4`` (moviepy); returns the
    path."""
    from moviepy import ImageSequenceClip

    folder = out / "videos" / file_label(label)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"episode-{episode}.mp4"
    partial = folder / f".episode-{episode}.partial.mp4"
    clip = ImageSequenceClip(list(frames), fps=VIDEO_FPS)
    clip.write_videofile(str(partial), logger=None)
    partial.replace(path)  # a video appears whole or not at all
    return path
