"""Shared test fixtures.

Tests go through public names. The few private ones they touch, each a seam with no public
counterpart worth having:

- ``generators._draw_fields`` (test_scenario.py): the compiled placement kernel, held to a
  numpy decoding of the same random block;
- ``batch_geometry._ray_polygon`` (test_vector_env.py): one ray against one polygon, the
  un-culled reference of the lidar's culling;
- ``rendering._window_pyplot`` (test_rendering.py): replaced so that pyplot on Agg stands in for
  a display.
"""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest


@pytest.fixture(scope="session")
def display():
    """A display for render_mode="human": the user's, or a private Xvfb if installed, else None.

    CI installs Xvfb (Debian package ``xvfb``), so there the human window path runs for real.
    """
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        yield None
        return
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(
        [xvfb, "-displayfd", str(write_fd), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
        pass_fds=(write_fd,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write_fd)
    with os.fdopen(read_fd) as fh:
        number = fh.readline().strip()
    os.environ["DISPLAY"] = f":{number}"
    try:
        yield os.environ["DISPLAY"]
    finally:
        del os.environ["DISPLAY"]
        proc.terminate()
        proc.wait(timeout=10)


@pytest.fixture
def one_torch_thread():
    """One torch thread for the test, as training and imitation use: under ``pytest -n 2``
    more threads only contend. Modules that train ask for it with
    ``pytest.mark.usefixtures("one_torch_thread")``."""
    import torch  # here, not at the top: most tests never load torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
