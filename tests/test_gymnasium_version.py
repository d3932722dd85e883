"""debris_gym refuses a gymnasium older than 1.0 at import, naming the version and the fix (with
gymnasium 0.29, which CleanRL pins, the first reset died with an AttributeError)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from debris_gym.registration import require_gymnasium
from tests.helpers import ROOT


@pytest.mark.parametrize("version", ["0.29.1", "0.26.3", "0.9", "nightly"])
def test_an_old_gymnasium_is_refused_with_the_fix(version):
    with pytest.raises(ImportError, match=rf"needs gymnasium >= 1\.0, found gymnasium {version}"):
        require_gymnasium(version)


@pytest.mark.parametrize("version", ["1.0.0", "1.0.0a1", "1.2.2", "2.0", "10.1.0"])
def test_gymnasium_1_and_later_are_accepted(version):
    require_gymnasium(version)


def test_importing_debris_gym_under_gymnasium_0_29_says_so():
    code = "import gymnasium; gymnasium.__version__ = '0.29.1'; import debris_gym"
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 1
    last = proc.stderr.strip().splitlines()[-1]
    assert last == (
        "ImportError: debris-gym needs gymnasium >= 1.0, found gymnasium 0.29.1; upgrade it: "
        "pip install 'gymnasium>=1.0'"
    )
