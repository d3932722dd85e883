"""Agent specs: what to evaluate, parsed from text or given as Python objects, and built for an env.

An agent is named by a *spec*:

* a baseline name from :data:`agents.BASELINES` (``apf``, ``astar``, …), built with
  :func:`agents.make_agent`;
* ``ALGO=PATH`` (or ``ALGO:PATH``) for a policy trained by ``train.py``, ALGO one of
  :data:`LEARNED_ALGOS`, e.g. ``ppo=runs/ppo/model.zip``; loaded with :func:`agents.load_agent`;
* ``pretrained``, the policy shipped with the package;
* ``LABEL=MODULE:ATTR`` (or just ``MODULE:ATTR``, labelled ATTR) for your own policy:
  ``MODULE`` is a dotted module name found on ``sys.path`` (not a file path), ``ATTR`` an object
  in it — a policy (anything with SB3's ``predict(obs, state, episode_start, deterministic)``)
  or a factory ``ATTR(env) -> policy`` (a class counts as a factory).

The colon is shared by ``ppo:PATH`` and ``MODULE:ATTR``: a spec whose part before the first ``:``
or ``=`` is one of :data:`LEARNED_ALGOS` is a learned model; any other ``X=Y`` is a label and a
``MODULE:ATTR``; any other ``MODULE:ATTR`` is a Python policy. So a module cannot be called
``ppo`` (or ``sac``, ``td3``, ``dqn``), and a label cannot be an algorithm's name.

From Python, :func:`parse_agent_specs` also takes a mapping ``{label: spec}`` whose values may be
spec strings, policy objects or factories (``{"mine": MyPolicy()}``, ``{"mine": make_policy}``).
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym

from agents.policies.model_files import LEARNED_ALGOS

__all__ = [
    "LEARNED_ALGOS",
    "PRETRAINED",
    "AgentSpec",
    "agent_env_options",
    "build_agent",
    "check_agent_available",
    "known_specs_text",
    "parse_agent_spec",
    "parse_agent_specs",
    "resolve_python_agent",
]

"""Algorithms a learned-agent spec ``ALGO=PATH`` may name (those ``train.py`` trains)."""

PRETRAINED = "pretrained"
"""Spec of the policy shipped with the package."""

_MODULE_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
_ATTR_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class AgentSpec:
    """One agent to evaluate.

    Attributes:
        text: the spec as given (``"apf"``, ``"ppo=model.zip"``, ``"mine=pkg.mod:make"``), or
            ``"<python object>"`` for an object handed in from Python.
        kind: ``"baseline"``, ``"learned"``, ``"pretrained"``, ``"python"`` (a ``MODULE:ATTR``)
            or ``"object"`` (a policy or factory handed in from Python).
        name: the baseline name, the algorithm (``"ppo"``), ``"pretrained"``, or the
            ``MODULE:ATTR`` target of a Python policy.
        path: model file of a learned agent, else None.
        label: the agent's name in tables, CSV and plots (unique within one evaluation).
        obj: the policy or factory of an ``"object"`` spec, else None.
    """

    text: str
    kind: str
    name: str
    path: str | None = None
    label: str = ""
    obj: Any = field(default=None, compare=False, repr=False)

    @property
    def load_string(self) -> str:
        """What ``agents.load_agent`` takes: ``"ppo:path/model.zip"`` or ``"pretrained"``."""
        return f"{self.name}:{self.path}" if self.kind == "learned" else self.name


def known_specs_text() -> str:
    """Every kind of agent spec, with examples (for error messages)."""
    from agents import BASELINES

    return (
        f"known baselines: {', '.join(BASELINES)}; learned agents: "
        f"{'|'.join(LEARNED_ALGOS)}=PATH (e.g. ppo=runs/ppo/model.zip); {PRETRAINED!r}; "
        "your own policy: LABEL=MODULE:ATTR (e.g. mine=my_pkg.my_mod:make_policy)"
    )


def _python_spec(spec: str, label: str, target: str) -> AgentSpec:
    module, _, attr = target.partition(":")
    module, attr = module.strip(), attr.strip()
    if not (_MODULE_RE.match(module) and _ATTR_RE.match(attr)):
        raise ValueError(
            f"agent {spec!r}: expected MODULE:ATTR after the label, a dotted module name and an "
            f"attribute (e.g. mine=my_pkg.my_mod:make_policy), got {target!r}"
        )
    return AgentSpec(text=spec, kind="python", name=f"{module}:{attr}", label=label or attr)


def parse_agent_spec(text: str) -> AgentSpec:
    """Parse one agent spec string (see the module docstring).

    Raises:
        ValueError: unknown name, a learned spec without a path, a label used with something
            other than ``MODULE:ATTR``; the message lists what is known.
    """
    from agents import BASELINES

    spec = str(text).strip()
    if not spec:
        raise ValueError(f"empty agent name; {known_specs_text()}")
    sep = min((i for i in (spec.find("="), spec.find(":")) if i >= 0), default=-1)
    if sep >= 0:
        head, rest = spec[:sep].strip(), spec[sep + 1 :].strip()
        if head.lower() in LEARNED_ALGOS:
            algo = head.lower()
            if not rest:
                raise ValueError(f"agent {spec!r} needs a model path: {algo}=path/to/model.zip")
            return AgentSpec(text=spec, kind="learned", name=algo, path=rest, label=algo)
        if spec[sep] == "=":
            if ":" not in rest:
                raise ValueError(
                    f"unknown learning algorithm {head!r} in agent {spec!r}; use one of "
                    f"{', '.join(LEARNED_ALGOS)} as ALGO=PATH, or LABEL=MODULE:ATTR for your "
                    "own policy"
                )
            return _python_spec(spec, head, rest)
        return _python_spec(spec, "", spec)
    if spec in BASELINES:
        return AgentSpec(text=spec, kind="baseline", name=spec, label=spec)
    if spec == PRETRAINED:
        return AgentSpec(text=spec, kind="pretrained", name=PRETRAINED, label=PRETRAINED)
    if spec.lower() in LEARNED_ALGOS:
        raise ValueError(f"agent {spec!r} needs a model path: {spec.lower()}=path/to/model.zip")
    raise ValueError(f"unknown agent {spec!r}; {known_specs_text()}")


def _spec_of(label: str, value: Any) -> AgentSpec:
    """The spec of one ``{label: value}`` entry: a spec string, or a policy object / factory."""
    if isinstance(value, AgentSpec):
        return dataclasses.replace(value, label=label)
    if isinstance(value, str):
        return dataclasses.replace(parse_agent_spec(value), label=label)
    if not (hasattr(value, "predict") or callable(value)):
        raise TypeError(
            f"agent {label!r}: {type(value).__name__} is neither a policy (no predict method) "
            "nor a factory callable(env) -> policy"
        )
    return AgentSpec(text="<python object>", kind="object", name=label, label=label, obj=value)


def parse_agent_specs(
    specs: str | Iterable[str | AgentSpec] | Mapping[str, Any],
) -> list[AgentSpec]:
    """Parse specs: a comma-separated string, a list, or a mapping ``{label: spec}``.

    A mapping's values may be spec strings, :class:`AgentSpec`\\ s, policy objects or factories;
    its keys are the labels. Otherwise labels come from the specs: two learned agents of the same
    algorithm are labelled ``ppo:model_a``, ``ppo:model_b`` (the file stems), further clashes get
    ``#2``, ``#3``. The same spec string twice is an error.

    Raises:
        ValueError: an unparsable spec, a repeated spec, an empty label, or no agents at all.
        TypeError: a mapping value that is neither a spec, a policy nor a callable.
    """
    if isinstance(specs, Mapping):
        if not specs:
            raise ValueError(f"no agents given; {known_specs_text()}")
        for label in specs:
            if not isinstance(label, str) or not label.strip():
                raise ValueError(f"agent labels must be non-empty strings, got {label!r}")
        return [_spec_of(label.strip(), value) for label, value in specs.items()]
    items = specs.split(",") if isinstance(specs, str) else list(specs)
    parsed = [s if isinstance(s, AgentSpec) else parse_agent_spec(s) for s in items]
    if not parsed:
        raise ValueError(f"no agents given; {known_specs_text()}")
    texts = [p.text for p in parsed if p.kind != "object"]
    repeated = sorted({t for t in texts if texts.count(t) > 1})
    if repeated:
        raise ValueError(f"agent(s) listed more than once: {', '.join(repeated)}")
    base = [p.label or p.name for p in parsed]
    labels = [
        f"{p.name}:{Path(p.path or '').stem}" if p.kind == "learned" and base.count(b) > 1 else b
        for p, b in zip(parsed, base, strict=True)
    ]
    seen: dict[str, int] = {}
    for i, label in enumerate(labels):
        seen[label] = seen.get(label, 0) + 1
        if seen[label] > 1:
            labels[i] = f"{label}#{seen[label]}"
    return [dataclasses.replace(p, label=label) for p, label in zip(parsed, labels, strict=True)]


def resolve_python_agent(target: str) -> Any:
    """The object ``MODULE:ATTR`` names (a policy or a factory), imported.

    Raises:
        ImportError: the module cannot be imported, or has no such attribute.
    """
    module_name, _, attr = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ImportError(
            f"agent {target!r}: module {module_name!r} cannot be imported ({exc}); it must be "
            "importable from sys.path (the current directory or PYTHONPATH)"
        ) from exc
    if not hasattr(module, attr):
        raise ImportError(f"agent {target!r}: module {module_name!r} has no attribute {attr!r}")
    return getattr(module, attr)


def _as_policy(label: str, obj: Any, env: gym.Env) -> Any:
    """``obj`` itself if it is a policy instance, else ``obj(env)``; checked for ``predict``."""
    is_instance_policy = callable(getattr(obj, "predict", None)) and not isinstance(obj, type)
    policy = obj
    if not is_instance_policy and callable(obj):
        try:
            policy = obj(env)
        except (TypeError, ValueError) as exc:
            kind = TypeError if isinstance(exc, TypeError) else ValueError
            raise kind(
                f"agent {label!r}: its factory {getattr(obj, '__name__', obj)!r} failed on the "
                f"env ({exc}); give a policy or a factory callable(env) -> policy"
            ) from exc
    if not callable(getattr(policy, "predict", None)):
        raise TypeError(
            f"agent {label!r}: {type(policy).__name__} has no predict(obs, state, episode_start, "
            "deterministic) method; give a policy or a factory callable(env) -> policy"
        )
    return policy


def check_agent_available(spec: AgentSpec) -> None:
    """Fail early, with a clear message, if ``spec`` cannot be built; do nothing otherwise.

    Baselines: their module must import. Learned agents: the model file must exist. Python
    policies: the module must import and have the attribute. Whether a pretrained policy ships
    is for ``agents.load_agent`` to say when the agent is built.

    Raises:
        ImportError: a baseline's or Python policy's module does not import (e.g. a missing
            optional dependency), or lacks the named class / attribute.
        FileNotFoundError: a learned agent's model file is missing.
    """
    import agents

    if spec.kind == "baseline":
        module_name, class_name = agents.BASELINES[spec.name].split(":")
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            raise ImportError(
                f"agent {spec.label!r}: its module {module_name} cannot be imported ({exc})"
            ) from exc
        if not hasattr(module, class_name):
            raise ImportError(f"agent {spec.label!r}: {module_name} has no class {class_name}")
    elif spec.kind == "learned" and not Path(spec.path or "").is_file():
        raise FileNotFoundError(f"agent {spec.label!r}: model file {spec.path!r} not found")
    elif spec.kind == "python":
        resolve_python_agent(spec.name)


def agent_env_options(spec: AgentSpec | str, env_id: str) -> dict[str, Any]:
    """Env options an agent needs beyond the evaluation's: for a learned policy, the
    observation options it was trained with (fields, dynamics and rules stay the same)."""
    if isinstance(spec, str):
        spec = parse_agent_spec(spec)
    if spec.kind not in ("learned", "pretrained"):
        return {}
    from agents import observation_options

    try:
        return observation_options(spec.load_string, env_id)
    except (FileNotFoundError, ValueError):
        return {}  # load_agent reports the problem when the agent is built


def build_agent(spec: AgentSpec | str, env: gym.Env) -> Any:
    """The policy for ``spec`` acting in ``env`` (anything with SB3's ``predict``).

    Raises:
        ImportError: a Python policy's module or attribute is missing.
        TypeError: a Python policy (or what its factory returns) has no ``predict``.
    """
    import agents

    if isinstance(spec, str):
        spec = parse_agent_spec(spec)
    if spec.kind == "baseline":
        return agents.make_agent(spec.name, env)
    if spec.kind == "python":
        return _as_policy(spec.label, resolve_python_agent(spec.name), env)
    if spec.kind == "object":
        return _as_policy(spec.label, spec.obj, env)
    return agents.load_agent(spec.load_string, env)
