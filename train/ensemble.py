"""Write an ensemble manifest: several exported PPO models acting as one (``ppo:OUT.yaml``).

Run::

    langctrl ensemble --out models/ppo_langctrl.yaml \\
        models/ppo_langctrl_s1000000.zip models/ppo_langctrl_s2000000.zip ...

The members (made with ``langctrl export``) must lie in the manifest's folder and share
their residual design, decision rate, phrase graph and env arguments. The manifest records each
member's SHA-256 and is loaded once before it is written, so a broken ensemble fails here. An
existing manifest is replaced only with ``--overwrite``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["EnsembleArgs", "ensemble"]


@dataclass(frozen=True)
class EnsembleArgs:
    """Arguments of ``langctrl ensemble``.

    Attributes:
        models: The member model zips.
        out: The manifest to write (``.yaml``).
        overwrite: Replace an existing manifest.
    """

    models: tuple[Path, ...]
    out: Path
    overwrite: bool = False


def ensemble(args: EnsembleArgs) -> Path:
    """Write the manifest ``args`` asks for (:func:`policies.ensemble.write_manifest`); its path.

    Raises:
        FileExistsError: ``args.out`` exists and ``args.overwrite`` is off.
        FileNotFoundError, ValueError: a missing member, or members that cannot act as one.
    """
    from policies.ensemble import write_manifest

    if args.out.exists() and not args.overwrite:
        raise FileExistsError(f"{args.out} exists; give --overwrite to replace it")
    return write_manifest(args.out, list(args.models))
