"""An ensemble of learned aligners: the mean of several PPO models' corrections.

Policies trained with different seeds make different mistakes on users they never saw; averaging
their corrections (all members correct the same base controller, so their corrections add up in
the same units) keeps what they agree on. An ensemble is a YAML *manifest* beside its members::

    kind: ppo-ensemble
    members:
      - file: ppo_langctrl_s1000000.zip        # relative to the manifest
        sha256: 3f1c...                        # of the zip, checked at load
      - ...

``ppo:PATH.yaml`` loads one (:func:`policies.load_policy`); ``langctrl ensemble`` writes one.
Every member must share the residual design, the decision rate, the phrase graph it was trained
on and the env arguments, since one env serves them all; like any learned policy, the ensemble
speaks the exercise's phrase graph (:meth:`PPOEnsemble.use_graph`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from langenv.exercise.script import SpokenGraph
from langenv.files import temp_file
from policies.learned import PPOPolicy, file_sha256

__all__ = ["MANIFEST_KIND", "PPOEnsemble", "write_manifest"]

#: The ``kind`` of an ensemble manifest.
MANIFEST_KIND = "ppo-ensemble"


@dataclass
class PPOEnsemble:
    """Several :class:`~policies.learned.PPOPolicy` members acting as one.

    At each observation every member computes its correction ``r_i``; the ensemble applies
    ``mean(r_i)`` through the (shared) residual map. Build it with :meth:`load`.

    Attributes:
        members: The member policies (at least one).
        path: The manifest.
        name: ``"ppo"``.
    """

    members: tuple[PPOPolicy, ...]
    path: Path = Path()
    name: str = "ppo"
    graph_role: str = "graph"
    decision_hz: int = field(init=False)
    env_kwargs: dict[str, Any] = field(init=False)

    def __post_init__(self) -> None:
        if not self.members:
            raise ValueError(f"{self.path}: an ensemble needs at least one member")
        first = self.members[0]
        for m in self.members[1:]:
            for what, a, b in (
                ("residual design", m.residual.spec, first.residual.spec),
                ("decision rate", m.decision_hz, first.decision_hz),
                ("training phrase graph", m.trained_graph, first.trained_graph),
                ("env arguments", m.env_kwargs, first.env_kwargs),
            ):
                if a != b:
                    raise ValueError(
                        f"{self.path}: member {m.path} differs from {first.path} in its {what}: "
                        f"{a!r} != {b!r}"
                    )
        self.decision_hz = first.decision_hz
        self.env_kwargs = dict(first.env_kwargs)

    @property
    def trained_graph(self) -> str | None:
        """The phrase graph the members were trained on (see :class:`PPOPolicy`)."""
        return self.members[0].trained_graph

    @property
    def widened_from(self) -> int | None:
        """The members' number of choices before :meth:`use_graph` widened them, or None."""
        return self.members[0].widened_from

    def use_graph(self, spoken: SpokenGraph) -> None:
        """Fit every member to the graph spoken (:meth:`PPOPolicy.use_graph`).

        Raises:
            GraphChoicesError: naming the first member that cannot act on it.
        """
        for m in self.members:
            m.use_graph(spoken)
        self.env_kwargs = dict(self.members[0].env_kwargs)

    @classmethod
    def load(cls, path: str | Path) -> PPOEnsemble:
        """Load a manifest and its members.

        Raises:
            FileNotFoundError: naming the manifest or a member file that does not exist.
            ValueError: naming the file, if the manifest is malformed, a member's checksum does
                not match, or the members cannot act as one.
        """
        manifest = Path(path)
        if not manifest.is_file():
            raise FileNotFoundError(f"PPO ensemble manifest not found: {manifest}")
        try:
            data = yaml.safe_load(manifest.read_text())
        except (OSError, yaml.YAMLError, UnicodeDecodeError) as exc:
            raise ValueError(f"{manifest}: cannot read ensemble manifest: {exc}") from None
        if not isinstance(data, dict) or data.get("kind") != MANIFEST_KIND:
            raise ValueError(f"{manifest}: not an ensemble manifest (needs kind: {MANIFEST_KIND})")
        entries = data.get("members")
        if not isinstance(entries, list) or not entries:
            raise ValueError(f"{manifest}: 'members' must be a non-empty list")
        members = []
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
                raise ValueError(f"{manifest}: members[{i}] needs a 'file' (a model zip)")
            zip_path = manifest.parent / entry["file"]
            if not zip_path.is_file():
                raise FileNotFoundError(f"{manifest}: members[{i}]: not found: {zip_path}")
            want = entry.get("sha256")
            if want is not None and want != file_sha256(zip_path):
                raise ValueError(
                    f"{manifest}: members[{i}]: {zip_path} does not match its sha256 "
                    "(the file changed since the ensemble was written)"
                )
            members.append(PPOPolicy.load(zip_path))
        return cls(members=tuple(members), path=manifest)

    def reset(self) -> None:
        """Start a new episode."""
        for m in self.members:
            m.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The env's action: the mean of the members' corrections, applied to the base."""
        r = np.mean([m.correction(observation) for m in self.members], axis=0)
        action = self.members[0].residual.action(r)
        for m in self.members[1:]:  # keep each member's "previous correction" feature in step
            m.residual.action(r)
        return action


def write_manifest(out: Path, models: list[Path]) -> Path:
    """Write an ensemble manifest for model zips and check that it loads.

    Args:
        out: The manifest to write (``.yaml``); members are stored relative to its folder,
            which must contain them (directly or below).
        models: The member model zips (each with its ``_vecnormalize.pkl`` and ``_config.yaml``).

    Returns:
        The manifest path.

    Raises:
        FileNotFoundError: naming a missing member.
        ValueError: if a member is not under the manifest's folder or the ensemble does not load.
    """
    out = Path(out)
    entries = []
    for model in models:
        model = Path(model)
        if not model.is_file():
            raise FileNotFoundError(f"langctrl ensemble: not found: {model}")
        try:
            rel = model.resolve().relative_to(out.parent.resolve())
        except ValueError:
            raise ValueError(
                f"langctrl ensemble: {model} must lie in the manifest's folder {out.parent}"
            ) from None
        entries.append({"file": rel.as_posix(), "sha256": file_sha256(model)})
    text = (
        "# LangCtrl PPO ensemble: the policy applies the mean of its members' corrections\n"
        "# (policies/ensemble.py). Written by langctrl ensemble.\n"
        + yaml.safe_dump({"kind": MANIFEST_KIND, "members": entries}, sort_keys=False)
    )
    fd, tmp = temp_file(out.parent, prefix=f".{out.name}.", suffix=out.suffix)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        PPOEnsemble.load(tmp)
        tmp.replace(out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return out
