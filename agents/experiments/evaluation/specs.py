"""Agent specs: what to evaluate, parsed from text or given as Python objects, and built for an env.

An agent is named by a *spec*:

* a baseline name from :data:`agents.BASELINES` (``apf``, ``astar``, …), built with
  :func:`agents.make_agent`;
* ``ALGO=PATH`` (or ``ALGO:PATH``) for a policy trained by ``train.py``, ALGO one of
  :data:`LEARNED_ALGOS`, e.g. ``ppo=runs/ppo/model.zip``; loaded with :func:`agents.load_agent`;
* ``pretrained``, the policy shipped with the package;
* ``LABEL=MODULE:ATTR`` (or just ``MODULE:ATTR``, labelled ATTR) for your own policy:
  ``MODULE`` is a dotted module name (not a file path) found in the working directory or on
  ``sys.path`` (:func:`resolve_python_agent`: only that module is imported from the working
  directory), ``ATTR`` an object in it — a policy (anything with SB3's ``predict(obs, state,
  episode_start, deterministic)``), a factory ``ATTR(env) -> policy`` (a class counts as a
  factory) or a plain function ``ATTR(obs) -> action`` (:func:`_as_policy` tells them apart).

The colon is shared by ``ppo:PATH`` and ``MODULE:ATTR``: a spec whose part before the first ``:``
or ``=`` is one of :data:`LEARNED_ALGOS` is a learned model; any other ``X=Y`` is a label and a
``MODULE:ATTR``; any other ``MODULE:ATTR`` is a Python policy. So a module cannot be called
``ppo`` (or ``sac``, ``td3``, ``dqn``), and a label cannot be an algorithm's name.

From Python, :func:`parse_agent_specs` also takes a mapping ``{label: spec}`` whose values may be
spec strings, policy objects, factories or functions (``{"mine": MyPolicy()}``,
``{"mine": make_policy}``, ``{"mine": lambda obs: -obs[:2]}``). A label is any text without
control characters (:func:`check_label`); files named after an agent use :func:`file_label`.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import importlib
import importlib.machinery
import importlib.util
import inspect
import os
import re
import sys
import unicodedata
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np

from agents.experiments.evaluation.failures import describe
from agents.policies.model_files import LEARNED_ALGOS, find_model_file
from agents.policies.simple import FunctionPolicy

__all__ = [
    "LEARNED_ALGOS",
    "PRETRAINED",
    "AgentSpec",
    "agent_env_options",
    "build_agent",
    "check_agent_available",
    "check_label",
    "file_label",
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


def check_label(label: str) -> str:
    """``label`` if it can name an agent: a non-empty string without control characters (a
    newline or a tab would break the Markdown tables and the progress line). Labels with
    characters a file name cannot hold are fine: files are named after a safe form of them
    (:func:`file_label`).

    Raises:
        ValueError: an empty label or one with a control character.
    """
    if not isinstance(label, str) or not label.strip():
        raise ValueError(f"agent labels must be non-empty strings, got {label!r}")
    bad = sorted({c for c in label if unicodedata.category(c) in ("Cc", "Zl", "Zp")})
    if bad:
        raise ValueError(
            f"agent label {label!r} holds the control character(s) "
            f"{', '.join(repr(c) for c in bad)}; a label names table rows and files"
        )
    return label


_FILE_CHARS = re.compile(r"[^A-Za-z0-9_.#=+-]+")


def file_label(label: str) -> str:
    """A file or folder name for agent ``label``, distinct for distinct labels: the label
    itself when it is made of letters, digits and ``_ . # = + -`` and starts with none of
    ``. -``; else those characters with the rest as ``_``, and 8 hex digits of the label's
    hash (so ``a b`` and ``a_b`` never share a file, and ``..`` stays inside its folder)."""
    if label and not _FILE_CHARS.search(label) and label[0] not in ".-":
        return label
    safe = _FILE_CHARS.sub("_", label).lstrip(".-") or "agent"
    digest = hashlib.sha256(label.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{safe[:64]}-{digest}"


def _python_spec(spec: str, label: str, target: str) -> AgentSpec:
    if label:
        check_label(label)
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
            check_label(label)
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


def _import_policy_module(name: str, module_dir: Path) -> ModuleType:
    """Import module ``name`` (dotted): its top-level package or module from ``module_dir`` if it
    is there, else from ``sys.path``. ``module_dir`` is never put on ``sys.path``, so nothing but
    the named module is imported from it."""
    top = name.partition(".")[0]
    if top not in sys.modules:
        found = importlib.machinery.PathFinder.find_spec(top, [str(module_dir)])
        if found is not None:
            module = importlib.util.module_from_spec(found)
            sys.modules[top] = module
            try:
                if found.loader is not None:  # None: a namespace package (a plain folder)
                    found.loader.exec_module(module)
            except BaseException:
                sys.modules.pop(top, None)
                raise
    return importlib.import_module(name)


def resolve_python_agent(target: str, module_dir: str | os.PathLike[str] | None = None) -> Any:
    """The object ``MODULE:ATTR`` names (a policy, a factory or a function), imported.

    ``MODULE``'s top-level package (or the module itself) is taken from ``module_dir`` (default:
    the working directory) if it is there, else from ``sys.path`` (PYTHONPATH, installed
    packages); a module already imported is not looked up again. ``module_dir`` is not added to
    ``sys.path``: no other file in it is ever imported (a stray ``tqdm.py`` there stays unrun).
    Importing the module runs its code.

    Raises:
        ImportError: the module cannot be found, raises while it is imported (any exception,
            ``SystemExit`` included; the message names it and where), or has no such attribute.
    """
    module_name, _, attr = target.partition(":")
    where = Path(os.getcwd() if module_dir is None else module_dir)
    try:
        module = _import_policy_module(module_name, where)
    except ModuleNotFoundError as exc:
        missing = exc.name or module_name
        if module_name == missing or module_name.startswith(missing + "."):
            raise ImportError(
                f"agent {target!r}: module {module_name!r} cannot be imported: {missing!r} is "
                f"neither in {where} nor on sys.path (PYTHONPATH, installed packages); give a "
                "dotted module name, not a file path"
            ) from exc
        raise ImportError(
            f"agent {target!r}: module {module_name!r} failed at import: {describe(exc)}; only "
            f"the named module is imported from {where} (it is not put on sys.path): a module "
            "it imports must be in its package or on PYTHONPATH"
        ) from exc
    except (Exception, SystemExit) as exc:  # the module's own code failed (SyntaxError too)
        raise ImportError(
            f"agent {target!r}: module {module_name!r} failed at import: {describe(exc)}"
        ) from exc
    if not hasattr(module, attr):
        raise ImportError(f"agent {target!r}: module {module_name!r} has no attribute {attr!r}")
    return getattr(module, attr)


FACTORY_NAMES = ("env",)
"""First-parameter names that make a callable a factory ``f(env) -> policy``."""

FUNCTION_NAMES = ("obs", "observation", "observations")
"""First-parameter names that make a callable a plain policy function ``f(obs) -> action``."""


def _callable_role(obj: Any) -> str | None:
    """``"factory"`` or ``"function"`` when the first parameter's name says so (a class is a
    factory), else None."""
    if isinstance(obj, type):
        return "factory"
    try:
        parameters = list(inspect.signature(obj).parameters)
    except (TypeError, ValueError):  # builtins without a signature
        return None
    if parameters and parameters[0] in FACTORY_NAMES:
        return "factory"
    if parameters and parameters[0] in FUNCTION_NAMES:
        return "function"
    return None


def _probe_observation(env: gym.Env) -> Any:
    """An observation to try a policy function on: a seeded sample of the env's observation
    space (the env itself is not touched)."""
    space = copy.deepcopy(env.observation_space)
    space.seed(0)
    return space.sample()


def _action_problem(action: Any, space: Any) -> str | None:
    """Why ``action`` cannot be an action of ``space``, or None."""
    shown = repr(action)
    shown = shown if len(shown) <= 60 else shown[:59] + "…"
    try:
        value = np.asarray(action)
    except Exception:  # anything numpy cannot read is not an action
        return f"returned {type(action).__name__}, not an action"
    if value.dtype.kind not in "iuf":
        return f"returned {shown}, not numbers"
    if isinstance(space, gym.spaces.Discrete):
        whole = value.dtype.kind != "f" or float(value.flat[0]).is_integer()
        if value.size != 1 or not whole:
            return f"returned {shown}, not one integer action in [0, {space.n})"
        return None
    shape = getattr(space, "shape", None)
    if shape is not None and value.shape != shape:
        return f"returned an action of shape {value.shape}, expected {shape}"
    if not np.all(np.isfinite(value)):
        return f"returned a non-finite action {shown}"
    return None


def _as_policy(label: str, obj: Any, env: gym.Env) -> Any:
    """``obj`` as a policy for ``env``: a policy instance itself, a factory's product
    (``obj(env)``), or a plain function ``obs -> action`` wrapped in
    :class:`~agents.policies.simple.FunctionPolicy`.

    A callable whose first parameter is named ``env`` (or a class) is a factory; one whose first
    parameter is named ``obs``, ``observation`` or ``observations`` a function. Any other
    callable is called with the env: if that returns a policy it is a factory, else it is tried
    as a function. A function is tried once on a seeded sample observation and must answer with
    an action of the env's action space.

    Raises:
        TypeError: not a policy, factory or function; a factory that returns no policy.
        ValueError: a factory or function that raises (any exception, ``SystemExit`` included)
            or answers with no action.
    """
    if callable(getattr(obj, "predict", None)) and not isinstance(obj, type):
        return obj
    name = getattr(obj, "__qualname__", None) or getattr(obj, "__name__", None) or repr(obj)
    if not callable(obj):
        raise TypeError(
            f"agent {label!r}: {type(obj).__name__} has no predict(obs, state, episode_start, "
            "deterministic) method and is not callable; give a policy, a factory "
            "callable(env) -> policy or a function obs -> action"
        )
    role = _callable_role(obj)
    as_factory = ""
    if role != "function":
        try:
            product = obj(env)
        except (Exception, SystemExit) as exc:
            if role == "factory":
                raise ValueError(
                    f"agent {label!r}: its factory {name!r} failed on the env: {describe(exc)}"
                ) from exc
            as_factory = f"called with the env it raised {describe(exc)}"
        else:
            if callable(getattr(product, "predict", None)):
                return product
            if role == "factory":
                raise TypeError(
                    f"agent {label!r}: its factory {name!r} returned a "
                    f"{type(product).__name__}, which has no predict(obs, state, episode_start, "
                    "deterministic) method; a factory must return a policy"
                )
            as_factory = f"called with the env it returned a {type(product).__name__}, no policy"
    problem: str | None
    try:
        action = obj(_probe_observation(env))
    except (Exception, SystemExit) as exc:
        problem = f"raised {describe(exc)}"
    else:
        problem = _action_problem(action, env.action_space)
        if problem is None:
            return FunctionPolicy(obj, env.observation_space)
    if role == "function":
        raise ValueError(
            f"agent {label!r}: its function {name!r} is no policy function obs -> action: "
            f"given an observation it {problem}"
        )
    raise ValueError(
        f"agent {label!r}: {name!r} is neither a factory callable(env) -> policy ({as_factory}) "
        f"nor a function obs -> action (given an observation it {problem}); name its first "
        "parameter env or obs to say which"
    )


def check_agent_available(
    spec: AgentSpec, module_dir: str | os.PathLike[str] | None = None
) -> None:
    """Fail early, with a clear message, if ``spec`` cannot be built; do nothing otherwise.

    Baselines: their module must import. Learned agents: the model file must exist (a run
    directory must hold a model; :func:`~agents.policies.model_files.find_model_file`). Python
    policies: the module must import (from ``module_dir`` or ``sys.path``, see
    :func:`resolve_python_agent`) and have the attribute. Whether a pretrained policy ships is
    for ``agents.load_agent`` to say when the agent is built.

    Raises:
        ImportError: a baseline's or Python policy's module does not import (e.g. a missing
            optional dependency, or its own code raising), or lacks the named class / attribute.
        FileNotFoundError: a learned agent's model file is missing (the message lists what the
            directory holds).
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
    elif spec.kind == "learned":
        try:
            find_model_file(spec.path or "")
        except FileNotFoundError as exc:
            raise FileNotFoundError(f"agent {spec.label!r}: {exc}") from None
    elif spec.kind == "python":
        resolve_python_agent(spec.name, module_dir)


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


def build_agent(
    spec: AgentSpec | str, env: gym.Env, module_dir: str | os.PathLike[str] | None = None
) -> Any:
    """The policy for ``spec`` acting in ``env`` (anything with SB3's ``predict``).

    Args:
        spec: the agent.
        env: the env it flies.
        module_dir: where a ``MODULE:ATTR`` agent's module is looked for first (default: the
            working directory; :func:`resolve_python_agent`).

    Raises:
        ImportError: a Python policy's module is missing, fails at import, or lacks the
            attribute.
        TypeError: a Python policy is neither a policy, a factory nor a function, or its
            factory returns no policy.
        ValueError: a factory or policy function that raises or answers with no action; a
            learned model that does not fit (see :func:`agents.load_agent`).
    """
    import agents

    if isinstance(spec, str):
        spec = parse_agent_spec(spec)
    if spec.kind == "baseline":
        return agents.make_agent(spec.name, env)
    if spec.kind == "python":
        return _as_policy(spec.label, resolve_python_agent(spec.name, module_dir), env)
    if spec.kind == "object":
        return _as_policy(spec.label, spec.obj, env)
    return agents.load_agent(spec.load_string, env)
