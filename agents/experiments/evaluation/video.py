"""Videos of evaluation episodes (``evaluate.py --video N``): each agent's first episodes as mp4,
recorded by gymnasium's ``RecordVideo`` from the env's ``rgb_array`` frames, in
``DIR/videos/<agent>/`` (the folder and file names are
:func:`~agents.experiments.evaluation.specs.file_label` of the agent's label).

With the safety shield on, every frame says so in a banner at its top, and the frames after a
command the shield replaced say that too, with a red border (:class:`ShieldFrames`).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from agents.experiments.evaluation.specs import file_label

__all__ = ["VIDEO_DIR", "ShieldFrames", "attach_shield", "recording_env", "video_files"]

VIDEO_DIR = "videos"
"""Where ``--video N`` puts each agent's recordings: ``DIR/videos/<agent>/``."""

BANNER_PX = 22
"""Height of the shield's banner at the top of a frame (pixels)."""

ON, INTERVENED = (32, 112, 64), (200, 30, 30)
"""Banner colours (RGB): shield on; the command just flown was replaced by the shield."""


class ShieldFrames(gym.Wrapper):
    """Marks the rendered frames of a shielded run: a banner "safety shield on" on every frame,
    turned red ("shield replaced the command", with a red border) on the frames that follow a
    step whose command the shield replaced.

    The shielded agent is attached after it is built (:func:`attach_shield`); its intervention
    counter (:class:`~agents.policies.shielded.ShieldStats`) tells whether the last command was
    replaced.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.agent: Any = None
        self._seen = 0
        self._intervened = False

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self._seen, self._intervened = 0, False
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        count = self.agent.stats.interventions if self.agent is not None else 0
        self._intervened = count > self._seen
        self._seen = count
        return self.env.step(action)

    def render(self) -> Any:
        frame = self.env.render()
        if not isinstance(frame, np.ndarray) or frame.ndim != 3:
            return frame
        return mark_frame(frame, self._intervened)


def mark_frame(frame: np.ndarray, intervened: bool) -> np.ndarray:
    """``frame`` (H, W, 3 uint8) with the shield's banner on top, and a red border if
    ``intervened``."""
    from PIL import Image, ImageDraw, ImageFont

    image = Image.fromarray(np.ascontiguousarray(frame[..., :3]))
    draw = ImageDraw.Draw(image)
    width, height = image.size
    colour = INTERVENED if intervened else ON
    draw.rectangle((0, 0, width, BANNER_PX), fill=colour)
    text = "safety shield on: it replaced this command" if intervened else "safety shield on"
    try:
        font = ImageFont.load_default(size=14)
    except TypeError:  # Pillow < 10.1: one bitmap size
        font = ImageFont.load_default()
    draw.text((8, 3), text, fill=(255, 255, 255), font=font)
    if intervened:
        draw.rectangle((0, 0, width - 1, height - 1), outline=INTERVENED, width=4)
    return np.asarray(image)


def recording_env(
    env: gym.Env, label: str, folder: Path, n: int, shielded: bool = False
) -> gym.Env:
    """``env`` (made with ``render_mode="rgb_array"``) with its first ``n`` episodes recorded as
    ``folder/<file label>/<file label>-episode-K.mp4``; with ``shielded`` the frames show the
    shield (:class:`ShieldFrames`; attach the agent with :func:`attach_shield`)."""
    from gymnasium.wrappers import RecordVideo

    if shielded:
        env = ShieldFrames(env)
    safe = file_label(label)
    with warnings.catch_warnings():  # a resumed run records into the folder it started
        warnings.filterwarnings("ignore", message=".*Overwriting existing videos.*")
        return RecordVideo(
            env,
            video_folder=str(folder / safe),
            episode_trigger=lambda episode: episode < n,
            name_prefix=safe,
            disable_logger=True,
        )


def attach_shield(env: gym.Env, agent: Any) -> None:
    """Let the :class:`ShieldFrames` wrapper in ``env`` (if any) read ``agent``'s counters."""
    while isinstance(env, gym.Wrapper):
        if isinstance(env, ShieldFrames):
            env.agent = agent
            return
        env = env.env


def video_files(out: Path) -> list[Path]:
    """The mp4 files under ``out/videos/``, sorted."""
    return sorted((out / VIDEO_DIR).glob("*/*.mp4"))
