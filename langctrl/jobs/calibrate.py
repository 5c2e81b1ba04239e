"""``langctrl calibrate``: fit the synthetic users to the recorded sessions, and (``--write``)
store the parameters the env ships (how: :mod:`eval.calibrate`).

    langctrl calibrate --sessions ../shared/sessions            # fit and show
    langctrl calibrate --sessions ../shared/sessions --write    # ... and store them

Exit status 0 when it ran, 2 on bad usage or bad session files.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from eval.calibrate import closed_loop_fit, fit_params, round_params, write_params
from langctrl import options
from langenv.users.synthetic import CALIBRATED_YAML

__all__ = ["build_parser", "main"]


def _floats(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None
    if not values or any(not (math.isfinite(v) and v > 0.0) for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers, got {text!r}")
    return values


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl calibrate`` (``python -m langctrl.jobs.calibrate``)."""
    parser = options.job_parser(
        "calibrate",
        "Calibrate the synthetic users against recorded sessions, and write the shipped "
        "parameters.",
        options.sessions("session CSVs"),
        options.people(48, per="candidate"),
        options.seed(1000, of="the first calibration user (>= 1000: calibration seeds)"),
        options.workers(),
    )
    parser.add_argument(
        "--duration",
        type=_floats,
        default=[4.5, 4.75, 5.0],
        metavar="LIST",
        help="candidate medians of a resistance episode's duration, s, comma-separated "
        "(default: 4.5,4.75,5.0)",
    )
    parser.add_argument(
        "--magnitude",
        type=_floats,
        default=[8.5, 9.0],
        metavar="LIST",
        help="candidate medians of a resistance episode's force, N, comma-separated "
        "(default: 8.5,9.0)",
    )
    parser.add_argument(
        "--write",
        action="store_true",
        help="store the result in langenv/assets/users/synthetic.yaml",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl calibrate``: the direct fit, the closed-loop fit, and (``--write``) the
    stored file; returns the exit status."""
    from langenv.errors import ConfigError, SessionDataError
    from langenv.users import load_sessions

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.seed < 1000:
        parser.error("--users must be >= 1 and --seed >= 1000 (calibration seeds)")
    try:
        sessions = load_sessions(args.sessions, "*.csv")
        direct, episodes = fit_params(sessions)
    except (SessionDataError, ConfigError) as exc:
        return options.fail("calibrate", exc)
    print(f"{len(sessions)} sessions, {len(episodes)} resistance episodes")
    print(f"direct fit: {round_params(direct)}")
    print(f"closed loop ({args.users} users, seeds {args.seed}-{args.seed + args.users - 1}):")
    best, tried = closed_loop_fit(
        sessions,
        direct,
        durations=args.duration,
        magnitudes=args.magnitude,
        n_users=args.users,
        seed=args.seed,
        workers=args.workers,
    )
    dur, mag, sc = min(tried, key=lambda row: row[2].loss)
    print(f"best: duration {dur:g} s, magnitude {mag:g} N: {sc.line()}")
    print(f"parameters: {best}")
    if args.write:
        grid = f"--duration {','.join(map(str, args.duration))} " + (
            f"--magnitude {','.join(map(str, args.magnitude))}"
        )
        provenance = (
            "Synthetic users calibrated against the study's recorded sessions (24 sessions).\n"
            f"Written by: langctrl calibrate --sessions DIR --users {args.users} "
            f"--seed {args.seed} {grid} --write\n"
            f"Closed loop of the chosen medians (duration {dur:g} s, magnitude {mag:g} N): "
            f"{sc.line()}"
        )
        write_params(best, CALIBRATED_YAML, provenance)
        print(f"wrote {CALIBRATED_YAML}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
