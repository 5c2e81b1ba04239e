"""Policies by name, through package entry points: langenv never imports a policy package.

A package that provides policies declares, in its ``pyproject.toml``::

    [project.entry-points."langctrl.policies"]
    lc = "policies:load_policy"
    ppo = "policies:load_policy"

Each entry point's name is a policy *kind* (the part of a spec before ``:``, e.g. ``ppo`` in
``ppo:models/x.zip``) and its object a factory ``f(spec: str) -> policy``, the policy offering
``act(observation)``, ``reset()``, ``graph_role``, ``decision_hz`` and ``env_kwargs`` (see
``policies.Policy``; the exercise gives it its phrase graph by role,
:mod:`langenv.exercise.script`). LangCtrl's own ``policies`` package registers ``ac``,
``lc-noap``, ``lc``, ``lc-em``, ``lc-end`` and ``ppo``; entry points appear once the package is
installed (for an editable install, after running its ``pip install -e`` line again).
"""

from __future__ import annotations

from importlib.metadata import EntryPoint, entry_points
from typing import Any

from langenv.errors import ConfigError

__all__ = ["POLICY_GROUP", "load_registered_policy", "registered_policies"]

POLICY_GROUP = "langctrl.policies"
"""Entry-point group of policy factories."""


def registered_policies() -> dict[str, EntryPoint]:
    """The registered policy kinds, by name (the first registration of a name wins)."""
    found: dict[str, EntryPoint] = {}
    for ep in entry_points(group=POLICY_GROUP):
        found.setdefault(ep.name, ep)
    return found


def load_registered_policy(spec: str) -> Any:
    """Build the policy ``spec`` (``"lc"``, ``"ppo:PATH"``...) with its registered factory.

    Raises:
        ConfigError: naming the spec, when no policy of its kind is registered (listing those
            that are), or when the factory rejects it (unknown name, missing or corrupt file).
    """
    kind = spec.partition(":")[0]
    known = registered_policies()
    if kind not in known:
        listed = ", ".join(sorted(known)) or "none"
        raise ConfigError(
            f"policy {spec!r}: no policy {kind!r} is registered (entry-point group "
            f"{POLICY_GROUP!r}; registered: {listed}). Install the package that provides it; "
            "after adding entry points to an editable install, run its pip install line again"
        )
    try:
        factory = known[kind].load()
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"policy {spec!r}: cannot load {known[kind].value}: {exc}") from None
    try:
        return factory(spec)
    except (KeyError, FileNotFoundError, ValueError, OSError) as exc:
        raise ConfigError(f"policy {spec!r}: {exc}") from None
