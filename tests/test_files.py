"""debris_gym.files: atomic writes keep the old file on failure and leave no scratch files."""

from __future__ import annotations

import os
import stat

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.files import save_atomic, write_atomic


@settings(max_examples=30, deadline=None)
@given(data=st.one_of(st.text(), st.binary()))
def test_write_atomic_round_trips_text_and_bytes(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("w") / "sub" / "out.json"  # parents are created
    write_atomic(path, "old")
    assert write_atomic(path, data) == path
    expected = data.encode("utf-8") if isinstance(data, str) else data
    assert path.read_bytes() == expected
    assert os.listdir(path.parent) == ["out.json"]


@pytest.mark.parametrize("error", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_a_failed_save_keeps_the_old_file_and_no_scratch(tmp_path, error):
    path = tmp_path / "model.zip"
    path.write_text("previous model")

    def save(tmp: str) -> None:
        with open(tmp, "w") as f:
            f.write("half a mod")
        raise error

    with pytest.raises(type(error)):
        save_atomic(path, save)
    assert path.read_text() == "previous model"
    assert os.listdir(tmp_path) == ["model.zip"]


def test_the_scratch_name_keeps_the_suffix_and_the_file_gets_umask_permissions(tmp_path):
    seen = []

    def save(tmp: str) -> None:
        seen.append(tmp)
        with open(tmp, "w") as f:
            f.write("x")

    umask = os.umask(0o022)
    try:
        path = save_atomic(tmp_path / "best_model.zip", save)
    finally:
        os.umask(umask)
    assert seen[0].endswith(".zip") and os.path.basename(seen[0]).startswith(".best_model.")
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # not mkstemp's 0600
