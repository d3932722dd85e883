"""Docs match the code: generated tables are current, every option and ID is documented."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import debris_gym
from debris_gym.config import OPTIONS

ROOT = Path(__file__).resolve().parents[1]


def test_generated_tables_are_up_to_date():
    result = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "gen_tables.py"), "--check"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr


def test_every_option_and_id_is_in_the_docs():
    text = (ROOT / "docs" / "environments.md").read_text()
    for key in OPTIONS:
        assert f"`{key}`" in text, key
    for env_id in debris_gym.ENV_SPECS:
        assert env_id in text
        assert env_id.split("/")[1] in (ROOT / "README.md").read_text()


def test_every_option_has_a_meaning():
    assert all(opt.doc for opt in OPTIONS.values())
