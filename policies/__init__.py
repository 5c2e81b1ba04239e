"""Policies of LangCtrl-v0: the paper's analytic controllers and learned aligners.

``load_policy(spec)`` builds one from its command-line name: an analytic policy of
:data:`policies.analytic.ANALYTIC` (``"ac"``, ``"lc-noap"``, ``"lc"``, ``"lc-em"``, ``"lc-end"``,
``"lc-em-end"``, ``"lc-fill"``) or ``"ppo:PATH"`` (a trained model saved by
``langctrl train``, or an ensemble manifest ``ppo:PATH.yaml`` written by
``langctrl ensemble``).
"""

from __future__ import annotations

from typing import Any

from langenv.errors import ConfigError
from policies.analytic import AdmittanceController, LanguageController, make_analytic
from policies.base import Policy

__all__ = ["AdmittanceController", "LanguageController", "Policy", "load_policy"]


def load_policy(spec: str) -> Any:
    """Build a policy from a name of :data:`policies.analytic.ANALYTIC` or ``ppo:PATH``.

    Raises:
        KeyError: unknown policy name.
        FileNotFoundError: ``ppo:PATH`` whose model file (or a member's) does not exist.
        ValueError: a corrupt or inconsistent model or ensemble manifest (naming the file);
            :class:`~langenv.errors.ConfigError` (a ValueError) for ``ppo:`` without a path.
    """
    if spec.startswith("ppo:"):
        path = spec.removeprefix("ppo:")
        if not path.strip():
            raise ConfigError(
                "ppo:PATH needs the path of a model (.zip) or an ensemble manifest (.yaml), "
                "e.g. ppo:models/ppo_aligner.zip"
            )
        if path.endswith((".yaml", ".yml")):
            from policies.ensemble import PPOEnsemble

            return PPOEnsemble.load(path)
        from policies.learned import PPOPolicy

        return PPOPolicy.load(path)
    return make_analytic(spec)
