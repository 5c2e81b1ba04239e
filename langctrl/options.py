"""The options the jobs share, each defined once: its name, its help, its type and check, where
its default comes from.

A job's parser takes them as parents (``job_parser(name, description, workers(), ...)``):
each function returns a small parser (``add_help=False``) holding one option, so that a job
takes exactly the shared options it needs. The arguments of a function say only what differs
from job to job (a seed's default, what an output file is); the help text around them, the
type and the check are the same everywhere. ``tests/test_architecture.py`` checks that no other
module adds these options.

    p = job_parser("fidelity", "Replay recorded sessions ...", workers(), seed())

:func:`job_parser` opens every job's parser (its name, where else it runs); :func:`args_of`
makes a job's arguments (a dataclass) of what it parsed; :func:`fail`, :func:`fail_lines`,
:func:`stopped`, :func:`run_job` and :func:`run_held_out` end every job the same way
(``langctrl NAME: error: ...`` on stderr and exit status 2; 130 on Ctrl-C).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

__all__ = [
    "COMMON_OPTIONS",
    "args_of",
    "audio_out",
    "bootstrap",
    "check_outputs",
    "device",
    "episode_log",
    "exercise",
    "fail",
    "fail_lines",
    "job_parser",
    "listening",
    "log_out",
    "non_negative_int",
    "out_dir",
    "out_file",
    "overwrite",
    "people",
    "policy",
    "positive_int",
    "role",
    "run_held_out",
    "run_job",
    "seed",
    "sessions",
    "stopped",
    "users",
    "users_spec",
    "warn_test_look",
    "workers",
]

#: The options only this module adds (``tests/test_architecture.py`` checks it).
COMMON_OPTIONS = ("--workers", "--seed", "--users", "--listening", "--out", "--overwrite")

_Checked = TypeVar("_Checked")
_Args = TypeVar("_Args", bound="DataclassInstance")


def _option(flag: str, **kwargs: Any) -> argparse.ArgumentParser:
    """A parent parser (``add_help=False``) holding the one option ``flag``, added with
    ``kwargs``."""
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument(flag, **kwargs)
    return p


def job_parser(
    name: str,
    description: str,
    *parents: argparse.ArgumentParser,
    more: str = "",
    epilog: str | None = None,
) -> argparse.ArgumentParser:
    """The parser of ``langctrl NAME``: ``description``, then where else the job runs
    (``python -m langctrl.jobs.MODULE``), then ``more``; it takes ``parents``' options."""
    text = f"{description} Also run as python -m langctrl.jobs.{name.replace('-', '_')}."
    return argparse.ArgumentParser(
        prog=f"langctrl {name}",
        description=f"{text} {more}" if more else text,
        epilog=epilog,
        parents=list(parents),
    )


def fail(name: str, error: object, status: int = 2) -> int:
    """Say ``langctrl NAME: error: ERROR`` on stderr; returns the exit status, ``status``."""
    print(f"langctrl {name}: error: {error}", file=sys.stderr)
    return status


def fail_lines(error: object, status: int = 1) -> int:
    """Say each line of ``error`` as ``error: LINE`` on stderr (a refusal that lists its
    problems); returns the exit status, ``status``."""
    for line in str(error).splitlines():
        print(f"error: {line}", file=sys.stderr)
    return status


def warn_test_look(name: str) -> None:
    """Say on stderr that ``langctrl NAME`` is about to look at the test exercises and people,
    which a study records and allows at most twice."""
    print(
        f"langctrl {name}: this is a look at the TEST exercises and people: record it and its "
        "figures in HISTORY.md (at most two looks per study)",
        file=sys.stderr,
    )


def stopped(name: str) -> int:
    """Say ``langctrl NAME: stopped`` on stderr (a Ctrl-C); returns the exit status, 130."""
    print(f"langctrl {name}: stopped", file=sys.stderr)
    return 130


def run_job(
    name: str,
    work: Callable[[], object],
    errors: tuple[type[Exception], ...],
    interruptible: bool = False,
) -> int:
    """Run ``work`` and print what it returns (exit status 0); one of ``errors`` is said by
    :func:`fail` (2), and with ``interruptible`` a Ctrl-C by :func:`stopped` (130)."""
    try:
        result = work()
    except errors as exc:
        return fail(name, exc)
    except KeyboardInterrupt:
        if not interruptible:
            raise
        return stopped(name)
    print(result)
    return 0


def args_of(cls: type[_Args], ns: argparse.Namespace, **given: Any) -> _Args:
    """The job's arguments ``cls`` (a dataclass) from its parsed command line ``ns``: each field
    ``ns``'s value of the same name, or its value in ``given`` (what the job worked out)."""
    from dataclasses import fields

    taken = {f.name: getattr(ns, f.name) for f in fields(cls) if f.init and f.name not in given}
    return cls(**taken, **given)


def run_held_out(
    name: str,
    ns: argparse.Namespace,
    check: Callable[[argparse.Namespace], _Checked],
    run: Callable[[argparse.Namespace, _Checked], str],
) -> int:
    """Run a job on held-out exercises and people (its :func:`role`): ``check`` its arguments
    ``ns`` before any episode (a bad config, model, file or key: :func:`fail`, 2), warn of a look
    at the test ones (:func:`warn_test_look`), then ``run`` and print what it returns (0)."""
    from langenv.errors import ConfigError, ModelError

    try:
        checked = check(ns)
    except (ConfigError, ModelError, FileNotFoundError, KeyError) as exc:
        return fail(name, exc)
    if ns.role == "test":
        warn_test_look(name)
    print(run(ns, checked))
    return 0


def positive_int(text: str) -> int:
    """An integer >= 1 (argparse's ``type``: a named error otherwise)."""
    value = non_negative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0 (argparse's ``type``: a named error otherwise)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def users_spec(text: str) -> str:
    """``KIND:N`` with a kind of :data:`eval.users.USER_KINDS` and ``N >= 1`` (checked by
    :func:`eval.users.parse_users`; ``--listening`` is checked with it by the job)."""
    from eval.users import parse_users

    try:
        parse_users(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--users").lstrip(": ")) from None
    return text


def workers() -> argparse.ArgumentParser:
    """``--workers N``: the processes that run the episodes (default: one per usable core)."""
    from langenv.kernels.cores import usable_cores

    return _option(
        "--workers",
        type=positive_int,
        default=usable_cores(),
        metavar="N",
        help="parallel worker processes that run the episodes, >= 1 (default: one per usable "
        "CPU core)",
    )


def seed(
    default: int | None = 0,
    of: str = "the first simulated user (user i: SEED + i)",
    otherwise: str = "%(default)s",
) -> argparse.ArgumentParser:
    """``--seed``: the seed ``of`` what the job seeds, ``default`` unless given (``otherwise``
    says what that is where it is not a number: None, for the job to find)."""
    return _option(
        "--seed",
        type=non_negative_int,
        default=default,
        help=f"seed of {of}, >= 0 (default: {otherwise})",
    )


def users(default: str | None, unless: str = "none") -> argparse.ArgumentParser:
    """``--users KIND:N``: simulated users (:func:`eval.users.parse_users`); ``unless`` says what
    the job does without it when ``default`` is None."""
    return _option(
        "--users",
        type=users_spec,
        default=default,
        metavar="synthetic:N",
        help="synthetic:N: N seeded synthetic users, user i with seed SEED + i; listening:N: the "
        "same people listening to what the robot says (default: "
        + ("%(default)s" if default is not None else unless)
        + ")",
    )


def people(default: int, per: str) -> argparse.ArgumentParser:
    """``--users N``: how many simulated users ``per`` run, candidate or exercise."""
    return _option(
        "--users",
        type=positive_int,
        default=default,
        metavar="N",
        help=f"synthetic users per {per}, >= 1: the first N user seeds (default: %(default)s)",
    )


def listening() -> argparse.ArgumentParser:
    """``--listening KEY=VALUE,...``: the listening people's parameters."""
    return _option(
        "--listening",
        default=None,
        metavar="KEY=VALUE,...",
        help="the listening people's parameters (langenv.users.ListeningParams, e.g. "
        "latency=1.2,comply=0.4), with --users listening:N (default: its defaults)",
    )


def exercise(before: str = "any episode runs") -> argparse.ArgumentParser:
    """``--exercise NAME|FILE``: the exercise, checked before ``before``."""
    return _option(
        "--exercise",
        default=None,
        metavar="NAME|FILE",
        help=f"exercise: a shipped name (langctrl exercise list) or a YAML path, checked before "
        f"{before} (default: the study's external_rotation)",
    )


def out_dir(
    holds: str, default: Path | None = None, otherwise: str | None = None
) -> argparse.ArgumentParser:
    """``--out DIR``: the job's output directory, which ``holds`` what the job writes; required
    unless ``default`` or ``otherwise`` (what the job does without it, the default None)."""
    if otherwise is not None:
        shown = f"default: {otherwise}"
    else:
        shown = "required" if default is None else "default: %(default)s"
    return _option(
        "--out",
        type=Path,
        default=default,
        required=default is None and otherwise is None,
        metavar="DIR",
        help=f"output directory: {holds} ({shown})",
    )


def out_file(
    what: str, default: str | None = None, metavar: str | None = None
) -> argparse.ArgumentParser:
    """``--out FILE``: the file (or file stem) the job writes, ``what``; required unless
    ``default`` (a phrase) says where it goes without it."""
    return _option(
        "--out",
        type=Path,
        default=None,
        required=default is None,
        metavar=metavar,
        help=f"{what} to write ({'required' if default is None else 'default: ' + default})",
    )


def policy() -> argparse.ArgumentParser:
    """``--policy NAME``: the policy that runs the session, by its registered name."""
    from langenv.live.registry import registered_policies

    return _option(
        "--policy",
        default="lc",
        metavar="NAME",
        help=f"policy by name: {', '.join(registered_policies())} (ppo:PATH: a learned model) "
        "(default: %(default)s)",
    )


def role(default: str, note: str) -> argparse.ArgumentParser:
    """``--role validation|test``: which held-out exercises and people the job runs on, ``note``
    saying what each is for (:func:`run_held_out` warns of a look at the test ones)."""
    return _option(
        "--role",
        choices=("validation", "test"),
        default=default,
        help=f"which held-out exercises and people; {note} (default: %(default)s)",
    )


def bootstrap(
    default: int,
    of: str = "per interval",
    flag: str = "--n-boot",
    check: Callable[[str], int] = int,
) -> argparse.ArgumentParser:
    """``--n-boot N`` (or ``flag``): the bootstrap resamples ``of`` what the job resamples
    (``check``: argparse's ``type``)."""
    return _option(
        flag,
        type=check,
        default=default,
        metavar="N",
        help=f"bootstrap resamples {of} (default: %(default)s)",
    )


def device() -> argparse.ArgumentParser:
    """``--device``: the sound card a live session speaks through."""
    return _option(
        "--device", default=None, help="sound card, by name or index (default: the system's)"
    )


def audio_out(more: str = "") -> argparse.ArgumentParser:
    """``--audio-out WAV``: a live session's speech written to a WAV instead of spoken through
    the sound card (``more``: what the default's note adds)."""
    return _option(
        "--audio-out",
        type=Path,
        default=None,
        metavar="WAV",
        help=f"write the speech to this WAV instead of the sound card (default: the sound card"
        f"{more})",
    )


def log_out(needs: str | None = None) -> argparse.ArgumentParser:
    """``--log-out CSV``: the session CSV a live session on a robot writes (only with the option
    ``needs``, where one is named)."""
    when = "" if needs is None else f"with {needs}: "
    return _option(
        "--log-out",
        type=Path,
        default=None,
        metavar="CSV",
        help=f"{when}write the session CSV here (default: none)",
    )


def sessions(holds: str) -> argparse.ArgumentParser:
    """``--sessions DIR``: the directory of the recorded sessions, which ``holds`` what the job
    reads (required)."""
    return _option(
        "--sessions",
        type=Path,
        required=True,
        metavar="DIR",
        help=f"directory of the recorded {holds} (required)",
    )


def episode_log() -> argparse.ArgumentParser:
    """``LOG.npz``: the episode log a job reads (a positional argument)."""
    return _option(
        "log",
        type=Path,
        metavar="LOG.npz",
        help="an episode log (.npz) written by langctrl compare",
    )


def check_outputs(
    parser: argparse.ArgumentParser, overwrite: bool, files: dict[str, Path | None]
) -> None:
    """Refuse (``parser.error``) an output file of ``files`` (option -> path, None: not given)
    whose directory is missing, or that exists without ``overwrite``."""
    for flag, path in files.items():
        if path is not None and not path.parent.is_dir():
            parser.error(f"{flag}: no directory {path.parent}")
        if path is not None and path.exists() and not overwrite:
            parser.error(f"{flag} {path}: exists; give --overwrite to replace it")


def overwrite(what: str) -> argparse.ArgumentParser:
    """``--overwrite``: replace ``what`` (without it the job refuses)."""
    return _option("--overwrite", action="store_true", help=f"replace {what} (default: refuse)")
