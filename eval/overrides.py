"""Controller and env parameters set by name: ``k_c`` of LC, ``admittance.damping`` of the env.

A *parameter* is a ``float`` field of a policy's dataclass or of a dataclass it holds
(``LanguageController.k_em``, ``LanguageController.gains.k_c``), or of the env: a ``float``
keyword argument of :class:`~langenv.env.LangCtrlEnv` (``w_em``, ``deadband``...) or a ``float``
field of a frozen dataclass argument (``admittance.damping``, ``paces.a_max``,
``safety.max_speed``...). The names are read from the dataclasses themselves, never listed by
hand, so a new field is a new parameter.

A policy parameter may be named by its last part when that is unique (``k_c`` for
``gains.k_c``); an ambiguous or unknown name raises :class:`~langenv.errors.ConfigError` listing
the names there are. Values are checked by the dataclass that takes them (its ``__post_init__``).

:func:`apply_policy_params` and :func:`env_kwargs_with` apply resolved ``(path, value)`` pairs;
:mod:`eval.compare`'s episode runner calls them for a :class:`~eval.compare.Job` that carries
parameters (as :mod:`eval.sweep` builds them).
"""

from __future__ import annotations

import dataclasses
import functools
import typing
from collections.abc import Iterable, Mapping
from typing import Any

from langenv.errors import ConfigError

__all__ = [
    "Params",
    "apply_policy_params",
    "env_kwargs_with",
    "env_parameters",
    "policy_parameters",
    "resolve_env_param",
    "resolve_policy_param",
]

Params = tuple[tuple[str, float], ...]
"""Resolved parameters: ``(dotted path, value)`` pairs, sorted by path."""


@functools.cache
def _float_paths(cls: type) -> tuple[str, ...]:
    """Dotted paths of the ``float`` fields of dataclass ``cls`` and of the dataclasses it holds."""
    hints = typing.get_type_hints(cls)
    paths: list[str] = []
    for f in dataclasses.fields(cls):
        if not f.init or f.name.startswith("_"):
            continue
        kind = hints.get(f.name)
        if kind is float:
            paths.append(f.name)
        elif isinstance(kind, type) and dataclasses.is_dataclass(kind):
            paths.extend(f"{f.name}.{sub}" for sub in _float_paths(kind))
    return tuple(paths)


def policy_parameters(policy: Any) -> tuple[str, ...]:
    """Dotted paths of ``policy``'s parameters (empty for a policy that is not a dataclass)."""
    if not dataclasses.is_dataclass(policy):
        return ()
    cls: type = type(policy)
    return _float_paths(cls)


def resolve_policy_param(policy: Any, name: str) -> str:
    """The full path of parameter ``name`` of ``policy`` (``"k_c"`` -> ``"gains.k_c"``).

    Raises:
        ConfigError: unknown or ambiguous name (the message lists the parameters).
    """
    paths = policy_parameters(policy)
    if name in paths:
        return name
    matches = [p for p in paths if p.rsplit(".", 1)[-1] == name]
    if len(matches) == 1:
        return matches[0]
    known = ", ".join(paths) or "none"
    if matches:
        raise ConfigError(f"parameter {name!r} is ambiguous: give one of {', '.join(matches)}")
    raise ConfigError(f"unknown parameter {name!r}; known: {known}")


def _replace(obj: Any, path: str, value: float) -> Any:
    head, _, rest = path.partition(".")
    if rest:
        value = _replace(getattr(obj, head), rest, value)
    return dataclasses.replace(obj, **{head: value})


def apply_policy_params(policy: Any, params: Iterable[tuple[str, float]]) -> Any:
    """``policy`` with each ``(path, value)`` set; the dataclasses check the values.

    Raises:
        ConfigError: a value its dataclass refuses.
    """
    for path, value in params:
        policy = _replace(policy, path, float(value))
    return policy


@functools.cache
def env_parameters() -> Mapping[str, type | None]:
    """The env's parameters: path -> the dataclass argument it is a field of (None for a
    ``float`` keyword argument of :class:`~langenv.env.LangCtrlEnv` itself)."""
    from langenv.env import LangCtrlEnv

    params: dict[str, type | None] = {}
    for name, kind in typing.get_type_hints(LangCtrlEnv.__init__).items():
        if kind is float:
            params[name] = None
            continue
        for arg in typing.get_args(kind):  # ``X | None``
            if isinstance(arg, type) and dataclasses.is_dataclass(arg) and _has_defaults(arg):
                if arg.__dataclass_params__.frozen:  # type: ignore[attr-defined]
                    for sub in _float_paths(arg):
                        params[f"{name}.{sub}"] = arg
    return params


def _has_defaults(cls: type) -> bool:
    """Whether dataclass ``cls`` can be built from defaults alone (parameter sets like
    ``AdmittanceParams`` can; data like an exercise, which a file gives, cannot)."""
    return all(
        f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
        for f in dataclasses.fields(cls)
        if f.init
    )


def resolve_env_param(name: str) -> str:
    """``name`` if it is a parameter of the env.

    Raises:
        ConfigError: unknown name (the message lists the env's parameters).
    """
    if name not in env_parameters():
        raise ConfigError(f"unknown env parameter {name!r}; known: {', '.join(env_parameters())}")
    return name


def env_kwargs_with(
    kwargs: Mapping[str, Any], params: Iterable[tuple[str, float]]
) -> dict[str, Any]:
    """A copy of the env's keyword arguments with each ``(path, value)`` set.

    Raises:
        ConfigError: an unknown path, or a value its dataclass refuses.
    """
    out = dict(kwargs)
    for path, value in params:
        owner = env_parameters().get(resolve_env_param(path))
        if owner is None:
            out[path] = float(value)
            continue
        arg, _, rest = path.partition(".")
        out[arg] = _replace(out.get(arg) or owner(), rest, float(value))
    return out
