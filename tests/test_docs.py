"""Docs match the code: generated tables are current, every option and ID is documented."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym

import agents
import debris_gym
from agents.policies.registry import BASELINES
from debris_gym.config import OPTIONS, EnvConfig

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


def generated_block(name: str) -> str:
    """The lines between ``<!-- table:NAME -->`` and its end marker in docs/environments.md."""
    text = (ROOT / "docs" / "environments.md").read_text()
    match = re.search(rf"<!-- table:{name} -->\n(.*?)<!-- /table:{name} -->", text, re.S)
    assert match, name
    return match.group(1)


def test_the_observation_table_is_the_registered_default_env():
    """The documented layout is what ``gym.make`` of the default ID observes (77 elements in
    2D v2), not the constructor's defaults (58, the v0 layout)."""
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    assert env.observation_space.shape == (77,)
    names = re.findall(r"^\| (\d+) \| `(\w+)` \|", generated_block("obs-2d"), re.M)
    assert [int(i) for i, _ in names] == list(range(env.observation_space.shape[0]))
    assert [name for _, name in names] == env.unwrapped.observation_names()
    env.close()


def test_the_option_table_gives_the_registered_value_beside_the_constructor_default():
    cells = {}
    for line in generated_block("options").splitlines()[2:]:
        key, _unit, registered, default = (c.strip() for c in line.split(" | ")[:4])
        cells[key.strip("| `")] = (registered, default)
    assert set(cells) == set(OPTIONS)
    defaults = {f.name: f.default for f in dataclasses.fields(EnvConfig)}
    v2 = {**defaults, **debris_gym.ENV_SPECS["DebrisGym/Rendezvous2D-v2"]["kwargs"]}
    for key, (registered, default) in cells.items():
        assert registered.strip("*") == f"`{v2[key]!r}`", key
        assert default == f"`{defaults[key]!r}`", key
    assert cells["capture_speed"] == ("**`0.1`**", "`0.5`")
    assert cells["capture_rule"] == ("**`'hold'`**", "`'dwell'`")


def anchors(text: str) -> set[str]:
    """The anchors of a Markdown page as GitHub makes them: each heading lower-cased, stripped
    of punctuation but hyphens, spaces turned to hyphens, repeats suffixed ``-1``, ``-2`` …;
    plus every ``<a id="…">``. Headings inside fenced code do not count."""
    found: set[str] = set()
    seen: dict[str, int] = {}
    fenced = False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
            continue
        heading = None if fenced else re.match(r"#{1,6} (.*)", line)
        if heading:
            slug = re.sub(r"[^\w\- ]", "", heading.group(1).strip().lower()).replace(" ", "-")
            found.add(f"{slug}-{seen[slug]}" if slug in seen else slug)
            seen[slug] = seen.get(slug, 0) + 1
    return found | set(re.findall(r'<a id="([^"]+)"', text))


def test_every_relative_link_and_anchor_resolves():
    """Links between the docs (``[text](page.md#section)``) name a file that exists and, for a
    page, a heading it has: renaming a section must update the links to it."""
    pages = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
    pages += sorted((ROOT / "agents").rglob("*.md"))
    broken = []
    for page in pages:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text()):
            if re.match(r"[a-z]+:", target):  # https:, mailto:
                continue
            path, _, anchor = target.partition("#")
            linked = page.parent / path if path else page
            if not linked.exists():
                broken.append(f"{page.name}: {target} (no such file)")
            elif anchor and linked.suffix == ".md" and anchor not in anchors(linked.read_text()):
                broken.append(f"{page.name}: {target} (no such section)")
    assert not broken, "\n".join(broken)


def test_the_agents_docstring_names_every_baseline():
    for name in BASELINES:
        assert f"``{name}``" in agents.__doc__, name


def test_every_option_has_a_meaning():
    assert all(opt.doc for opt in OPTIONS.values())


def test_the_ladder_table_counts_success_returns_and_legs(tmp_path):
    """docs/ladder_table.py on a hand-written evaluation: 3 missions of 2 targets."""
    import csv as csv_module
    import json

    from tests.helpers import load_script

    ladder = load_script("docs/ladder_table.py")
    folder = tmp_path / "eval"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"env_id": "DebrisGym/Rendezvous2D-Medium-v1"}))
    rows = [  # agent, success, captured, return, task score
        ("a", True, 2, 90.0, 68.0),
        ("a", False, 1, -30.0, -40.0),
        ("a", False, 2, 10.0, -20.0),
    ]
    with open(folder / "episodes.csv", "w", newline="") as fh:
        writer = csv_module.writer(fh)
        writer.writerow(
            ["agent", "success", "targets_captured", "n_targets", "return", "task_score"]
        )
        for agent, success, captured, ret, score in rows:
            writer.writerow([agent, success, captured, 2, ret, score])
    text = ladder.table([folder])
    assert "| a | 33% · 10.0 (23.3) · 2.7 · legs 100%/67%/50% |" in text
    legs = ladder.leg_table(folder)
    assert "| a | 3/3 | 2/3 | 1/2 |" in legs  # leg 1 all, leg 2 two of three, home one of two
