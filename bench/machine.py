"""A description of the machine and of the code measured, for the head of the report."""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np

import debris_gym


def machine_description() -> list[str]:
    """Lines describing the machine and library versions."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    try:
        load = "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        load = "n/a"
    source = _source_fingerprint()

    return [
        f"- CPU: {cpu}",
        f"- Cores: {os.cpu_count()} logical ({usable} usable by this process)",
        f"- Load average at start (1/5/15 min): {load}",
        f"- OS: {platform.platform()}",
        f"- Python {platform.python_version()} ({platform.python_implementation()})",
        f"- numpy {np.__version__}, gymnasium {gym.__version__}, numba {_version('numba')}, "
        f"debris_gym {debris_gym.__version__}, torch {_version('torch')}, "
        f"stable-baselines3 {_version('stable-baselines3')}, vmas {_version('vmas')}",
        f"- debris_gym source measured: {source}",
    ]


def _version(dist: str) -> str:
    """Installed version of ``dist`` without importing it, or "not installed"."""
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def _source_fingerprint() -> str:
    """Git commit, whether ``debris_gym/`` has uncommitted changes, and a hash of its sources.

    The hash identifies the exact code measured when the working tree is being edited.
    """
    package = Path(debris_gym.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    text = f"sources sha256 {digest.hexdigest()[:12]}"
    try:
        git = ["git", "-C", str(package.parent)]
        head = subprocess.run(
            [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "--", str(package)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        text = f"git {head}" + (" + uncommitted changes" if dirty else "") + f", {text}"
    except (OSError, subprocess.CalledProcessError):
        pass
    return text
