"""Compare aligners on simulated or recorded users: the study's evaluation, reproducible.

Run, for instance::

    langctrl compare --policies ac,lc-noap,lc --users synthetic:12 --seed 0 --out out/compare
    langctrl compare --policies lc,ppo:models/ppo_aligner.zip \
        --sessions ../shared/sessions --pattern '*_lc.csv' --out out/replay

Writes (only when every episode ran; nothing partial is left on error). The outputs are made in
a temporary directory beside ``OUT`` and moved into place whole; an existing non-empty ``OUT`` is
refused unless ``--overwrite`` is given, which replaces only the outputs named here and leaves any
other file in ``OUT`` alone:

* ``OUT/sessions.csv``: one row per episode (policy, user, the paper's metrics, whether it
  ended in a protective stop: ``protective_stop`` 1/0 and ``stop_limit``, the limit's name, and
  the phrase graph the policy spoke: ``graph``, its name or path as tables give it, and
  ``graph_role``);
* ``OUT/summary.md``: per policy median and IQR of each metric, bootstrap 95 % intervals of the
  differences against LC, and the study's findings checked on the data;
* ``OUT/summary.png``: the paper's violin figure;
* ``OUT/sessions/<policy>_<user>.png``: the paper's close-up figure of each session;
* ``OUT/sessions/<policy>_<user>.wav``: what the robot said, at the paces it used;
* ``OUT/sessions/<policy>_<user>.npz``: the episode log (``eval.episode.EpisodeLog.load_npz``);
* ``OUT/sessions/<policy>_<user>.mp4``: with ``--video``, the session video with the robot's
  speech as its sound track (:mod:`eval.video`);
* ``OUT/config.json``: the arguments of the run.

It ends with the verdict on the terminal: per policy the medians of the main metrics and the
graph it spoke, the study's findings (PASS/FAIL) and where the files are.

Every policy speaks the exercise's words (:mod:`langenv.exercise.script`): the policies that
choose phrases (LC, its variants, learned models) the exercise's phrase graph, AC and LC-noAP its
one wording. ``--graph GRAPH`` gives the phrase-choosing policies another graph, ``--graph
POLICY=GRAPH`` one of them only. A table of phrase-choosing policies that speak different graphs
compares scripts as well as controllers: the run refuses it (exit 2) unless
``--allow-mixed-graphs`` is given, and then marks them (``†``). AC and LC-noAP saying one wording
while LC chooses among many is the paper's comparison, not a mixed one.
"""

from __future__ import annotations

import functools
import json
import multiprocessing
import shutil
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from eval.atomic import OutTaken, move_into_place
from eval.metrics import METRIC_COLUMNS
from langenv.kernels.cores import usable_cores

__all__ = [
    "EPISODE_COLUMNS",
    "TEXT_COLUMNS",
    "CompareArgs",
    "Job",
    "UsageError",
    "policy_names",
    "policy_role",
    "run_compare",
    "run_episode",
    "run_jobs",
    "split_graphs",
]


@dataclass(frozen=True)
class CompareArgs:
    """Arguments of ``langctrl compare``.

    Attributes:
        policies: Comma-separated policies: ``ac``, ``lc-noap``, ``lc``, ``lc-em``, ``lc-end``,
            ``ppo:PATH``.
        users: ``synthetic:N`` (N seeded synthetic users) or ``listening:N`` (the same people,
            listening to the robot: :mod:`eval.users`), or None with ``sessions``.
        listening: ``KEY=VALUE,...`` of :class:`~langenv.users.ListeningParams` for
            ``listening:N`` (None: its defaults).
        sessions: Directory of session CSVs (at least ``t, cooperation``) to replay, one episode
            per CSV, the CSV's stem as the user name.
        pattern: Glob of the session CSVs in ``sessions``.
        seed: Seed of the first synthetic user (user ``i`` has seed ``seed + i``) and of the
            bootstrap.
        out: Output directory.
        workers: Parallel worker processes (default: one per CPU core this process may use).
        audio: Render each session's speech to WAV.
        figures: Draw the per-session close-up figures.
        decision_hz: Override every policy's decision rate (default: each policy's own).
        phrase_graph: Phrase graph for the policies that choose phrases (LC, its variants,
            learned), instead of the exercise's (the study's exercise: ``default``): a YAML path
            or a shipped graph's name (``study``: the study's graph, without pauses or fillers).
        policy_graphs: ``(policy spec, graph)`` pairs: a graph for one phrase-choosing policy,
            instead of ``phrase_graph`` or the exercise's.
        allow_mixed_graphs: Run phrase-choosing policies that speak different graphs (the
            tables mark them); without it such a run is refused.
        stat: Statistic of the differences against LC in ``summary.md``: ``median`` (of the
            per-user differences) or ``mean``.
        video: Render each session's video (MP4 with the speech as its sound track).
        overwrite: Replace the outputs of an earlier run in a non-empty ``out``.
        exercise: The exercise (a shipped name or a YAML path; ``langctrl exercise
            list``), checked before any episode runs; None: the study's. Its script's graphs
            are spoken: ``graph`` by the policies that choose phrases (unless ``phrase_graph``
            or ``policy_graphs``), ``single`` by AC and LC-noAP.
    """

    policies: str = "ac,lc-noap,lc"
    users: str | None = "synthetic:12"
    sessions: Path | None = None
    pattern: str = "*.csv"
    seed: int = 0
    out: Path = Path("out/compare")
    workers: int = field(default_factory=lambda: usable_cores())
    audio: bool = True
    figures: bool = True
    decision_hz: int | None = None
    phrase_graph: str | Path | None = None
    stat: str = "median"
    video: bool = False
    overwrite: bool = False
    exercise: str | None = None
    policy_graphs: tuple[tuple[str, str], ...] = ()
    allow_mixed_graphs: bool = False
    listening: str | None = None


#: Most synthetic users one run accepts (``--users synthetic:N``).
MAX_USERS = 10_000


@dataclass(frozen=True)
class Job:
    """One episode to run: a policy spec against a user."""

    policy: str
    user: str
    seed: int
    session: str | None
    out_dir: str
    audio: bool
    figures: bool
    decision_hz: int | None
    phrase_graph: str | None = None  # for a policy that chooses phrases: instead of the exercise's
    name: str | None = None  # the policy's name in outputs (default: its own name)
    video: bool = False
    user_params: Any = None  # SyntheticUserParams for synthetic users (default: calibrated)
    exercise: str | None = None  # a shipped exercise or an exercise YAML (default: the study's)
    params: tuple[tuple[str, float], ...] = ()  # the policy's parameters set (eval.overrides)
    env_params: tuple[tuple[str, float], ...] = ()  # the env's parameters set (eval.overrides)
    save_log: bool = True  # write the episode log (.npz) into out_dir
    user_model: Any = None  # a User to reset with ``seed`` instead (e.g. a PerturbedUser)


class UsageError(Exception):
    """Bad command-line arguments (reported without a traceback, exit code 2)."""


def split_graphs(
    values: Sequence[str], policies: str
) -> tuple[str | None, tuple[tuple[str, str], ...]]:
    """``--graph`` values as (the graph for every phrase-choosing policy, ``(spec, graph)`` for
    one policy each). ``POLICY=GRAPH`` counts as such only when ``POLICY`` is a spec of
    ``policies`` or its name in the outputs (``ppo``); any other value is a graph."""
    specs = [s.strip() for s in policies.split(",") if s.strip()]
    by_name = {**{s: s for s in specs}, **{n: s for s, n in policy_names(specs).items()}}
    common: str | None = None
    own: dict[str, str] = {}
    for value in values:
        name, sep, graph = value.partition("=")
        if sep and name.strip() in by_name:
            spec = by_name[name.strip()]
            if spec in own:
                raise UsageError(f"--graph: two graphs for {name.strip()}")
            own[spec] = graph.strip()
        elif common is not None:
            raise UsageError(
                f"--graph: two graphs for every policy ({common}, {value}); give POLICY=GRAPH "
                "for one policy"
            )
        else:
            common = value
    return common, tuple(own.items())


def _check_policies(spec: str) -> list[str]:
    names = [s.strip() for s in spec.split(",") if s.strip()]
    if not names:
        raise UsageError("--policies is empty")
    if len(set(names)) != len(names):
        raise UsageError(f"--policies lists a policy twice: {spec}")
    for name in names:
        try:
            _policy_rate(name)  # loads the policy (once: run_jobs orders episodes by its rate)
        except (KeyError, FileNotFoundError, ValueError, OSError) as exc:
            raise UsageError(f"--policies: {name}: {exc}") from None
    return names


def policy_role(spec: str) -> str:
    """The graph role of policy ``spec`` (:func:`langenv.exercise.script.graph_role`):
    ``"graph"`` for the policies that choose phrases, ``"single"`` for AC and LC-noAP."""
    return _policy_facts(spec)[1]


def _check_options(args: CompareArgs) -> None:
    if args.decision_hz is not None and (args.decision_hz <= 0 or 500 % args.decision_hz):
        raise UsageError(f"--decision-hz must divide 500, got {args.decision_hz}")
    graphs = [args.phrase_graph] if args.phrase_graph is not None else []
    for graph in [*graphs, *(g for _, g in args.policy_graphs)]:
        from langenv.errors import LangEnvError
        from langenv.speech.graph import PhraseGraph, graph_path

        try:
            PhraseGraph.load(graph_path(graph))
        except LangEnvError as exc:
            hint = ""
            if "=" in str(graph):
                hint = " (POLICY=GRAPH needs a POLICY of --policies or its name, e.g. ppo)"
            raise UsageError(f"--graph: {exc}{hint}") from None
    if args.exercise is not None:
        _check_exercise(args.exercise)


def _spoken_graphs(names: list[str], labels: dict[str, str], args: CompareArgs) -> dict[str, Any]:
    """The graph each policy will speak (:class:`~langenv.exercise.script.SpokenGraph`), found
    as the episodes will find it: a learned model that cannot act on its graph, an override for
    a one-wording policy and, without ``--allow-mixed-graphs``, phrase-choosing policies that
    speak different graphs are usage errors. Says on stderr what a learned model speaks when it
    is not the graph it was trained on."""
    from langenv.errors import LangEnvError
    from langenv.exercise.script import graph_role, speak
    from policies import load_policy

    own = dict(args.policy_graphs)
    spoken = {}
    for spec in names:
        policy = load_policy(spec)
        role = graph_role(policy)
        if spec in own and role != "graph":
            raise UsageError(
                f"--graph {labels[spec]}={own[spec]}: {labels[spec]} says the exercise's one "
                "wording (script.single), as the paper's baselines do; --graph applies to the "
                "policies that choose phrases"
            )
        try:
            spoken[spec] = speak(policy, args.exercise, own.get(spec, args.phrase_graph))
        except LangEnvError as exc:
            raise UsageError(f"--policies: {spec}: {exc}") from None
        trained = getattr(policy, "trained_graph", None)
        widened = getattr(policy, "widened_from", None)
        if widened is not None or (trained is not None and trained != spoken[spec].label):
            line = f"langctrl compare: {labels[spec]} speaks {spoken[spec].label}"
            line += f" (trained on {trained})" if trained is not None else ""
            if widened is not None:
                line += (
                    f"; the model reads {widened} choices and the graph has "
                    f"{spoken[spec].max_children}: widened as langctrl widen does (the "
                    "extra choices' inputs unseen)"
                )
            print(line, file=sys.stderr)
    choosing = {labels[s]: g.label for s, g in spoken.items() if g.role == "graph"}
    if len(set(choosing.values())) > 1 and not args.allow_mixed_graphs:
        said = ", ".join(f"{n} speaks {g}" for n, g in choosing.items())
        raise UsageError(
            f"the policies that choose phrases would speak different phrase graphs ({said}): "
            "their table would compare scripts as well as controllers. Give them one graph "
            "(--graph GRAPH), or --allow-mixed-graphs to compare them anyway (the tables mark "
            "them)"
        )
    return spoken


def _check_exercise(spec: str) -> None:
    """--exercise: loaded and checked (reach, margins, contacts, speed...) before any episode."""
    from langenv.errors import LangEnvError
    from langenv.exercise import resolve_exercise
    from langenv.exercise.check import check_exercise

    try:
        check_exercise(resolve_exercise(spec))
    except LangEnvError as exc:
        raise UsageError(f"--exercise: {exc}") from None


def _check_video() -> None:
    """--video: PyAV and an off-screen OpenGL context must work, checked before any episode runs.

    The GL check runs in a child process: a GL context made here would be inherited, broken, by
    the forked workers.
    """
    import subprocess

    try:
        import av  # noqa: F401
    except ImportError as exc:
        raise UsageError(f"--video needs PyAV ({exc}): pip install av") from None
    code = "from eval.video import SceneReplay; SceneReplay((16, 16)).close()"
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines() or ["unknown error"]
        raise UsageError(f"--video: {lines[-1]}")


def _users(args: CompareArgs) -> list[tuple[str, int, str | None]]:
    """(user name, seed, session path) for each user."""
    if args.sessions is not None:
        from langenv.errors import SessionDataError
        from langenv.users import load_session

        if not args.sessions.is_dir():
            raise UsageError(f"--sessions: {args.sessions} is not a directory")
        paths = sorted(args.sessions.glob(args.pattern))
        if not paths:
            raise UsageError(f"--sessions: no files match {args.pattern} in {args.sessions}")
        for path in paths:  # validate every CSV before running anything
            try:
                load_session(path)
            except SessionDataError as exc:
                raise UsageError(f"--sessions: {exc}") from None
        return [(p.stem, args.seed + i, str(p)) for i, p in enumerate(paths)]
    assert args.users is not None
    spec = _user_spec(args)
    return [(name, seed, None) for name, seed in spec.names(args.seed)]


def _user_spec(args: CompareArgs) -> Any:
    """``--users`` and ``--listening`` (:func:`eval.users.parse_users`), or :class:`UsageError`."""
    from eval.users import parse_users

    try:
        return parse_users(str(args.users), args.listening, MAX_USERS)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _check_out(out: Path, overwrite: bool) -> None:
    """Refuse an ``--out`` that is a file, lies under a file, or holds files (without
    ``--overwrite``), before any episode runs."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise UsageError(
            f"--out {out}: directory is not empty; choose another, or give --overwrite to replace "
            "the outputs of an earlier run in it (other files stay)"
        )
    parent = out.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise UsageError(f"--out {out}: {parent} is a file, not a directory")


#: The keys of :func:`run_episode`'s row, in ``sessions.csv``'s order: the paper's metrics, then
#: whether the episode was cut by the time limit or ended in a protective stop (and which), and
#: the phrase graph the policy spoke (:func:`langenv.exercise.script.graph_label`) and its role.
EPISODE_COLUMNS = (
    *METRIC_COLUMNS,
    "truncated",
    "protective_stop",
    "stop_limit",
    "graph",
    "graph_role",
)
#: Columns of :data:`EPISODE_COLUMNS` that hold text.
TEXT_COLUMNS = frozenset({"policy", "user", "stop_limit", "graph", "graph_role"})

_ENVS: dict[tuple[Any, ...], Any] = {}
#: Most envs one worker process keeps for reuse (a sweep over env parameters builds one per value).
MAX_ENVS = 8


def run_episode(job: Job) -> dict[str, Any]:
    """Run one episode, write its figure/audio/log into ``job.out_dir``; return its metrics row."""
    from eval.episode import EpisodeRecorder
    from eval.legs import graph_legs
    from eval.metrics import episode_metrics
    from langenv.exercise.script import speak

    policy = _job_policy(job)
    hz = job.decision_hz or policy.decision_hz
    spoken = speak(policy, job.exercise, job.phrase_graph)  # may adapt a learned model to it
    env = _job_env(job, policy, hz, spoken.ref)
    base: Any = env.unwrapped
    obs, info = env.reset(seed=job.seed, options=_reset_options(job, base))
    policy.reset()
    rec = EpisodeRecorder(policy=policy.name, user=job.user)
    rec.append(_with_scene(info, base))
    law = policy.pace_law() if hz == 500 and hasattr(policy, "pace_law") else None
    if law is not None and base.runs_compiled:
        ret, terminated, info = _run_law(base, policy, law, int(60 * hz), rec)
    else:
        ret, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy.act(obs))
            ret += float(reward)
            rec.append(_with_scene(info, base))
            done = terminated or truncated
    graph = base.graph
    texts = {u: (ph.text or u) for u, ph in graph.phrases.items() if not ph.is_pause}
    end_t = float(info["time"])
    leg_of, spoken_legs = graph_legs(graph)
    log = rec.build(
        ret,
        texts=texts,
        fillers=graph.fillers,
        t_motion=info["t_motion"] if info["t_motion"] is not None else end_t,
        t_speech=info["t_speech"] if info["t_speech"] is not None else end_t,
        utterances=base.speech.utterances(),
        phrase_graph=_graph_ref(spoken.ref),
        path=base.motion.trajectory.sample(200),
        voice=graph.voice,
        leg_of=leg_of,
        leg_names=base.motion_legs,
        spoken_legs=spoken_legs,
    )
    _write_session(job, log, base, Path(job.out_dir) / f"{policy.name}_{job.user}")
    row = episode_metrics(log)
    row["truncated"] = float(bool(info.get("TimeLimit.truncated", False)) or not terminated)
    row["protective_stop"] = float(info.get("safety_stop") is not None)
    row["stop_limit"] = info.get("safety_stop") or ""
    row["graph"] = spoken.label
    row["graph_role"] = spoken.role
    return row


def _job_policy(job: Job) -> Any:
    """The job's policy, its parameters set and its name given."""
    from policies import load_policy

    policy = load_policy(job.policy)
    if job.params:
        from eval.overrides import apply_policy_params

        policy = apply_policy_params(policy, job.params)
    if job.name is not None:
        policy.name = job.name
    return policy


def _job_env(job: Job, policy: Any, hz: int, graph: Any) -> Any:
    """The env for the job: one per policy, rate, graph, exercise and env parameters in each
    worker process (building one costs ~0.3 s), the oldest closed beyond :data:`MAX_ENVS`."""
    import gymnasium as gym

    import langenv

    key = (job.policy, hz, graph, job.exercise, job.env_params)
    env = _ENVS.get(key)
    if env is None:
        from eval.overrides import env_kwargs_with

        if len(_ENVS) >= MAX_ENVS:  # the oldest goes
            _ENVS.pop(next(iter(_ENVS))).close()
        kwargs = env_kwargs_with(policy.env_kwargs, job.env_params)
        if job.exercise is not None:
            kwargs["exercise"] = job.exercise
        env = _ENVS[key] = gym.make(
            langenv.ENV_ID,
            phrase_graph=graph,
            decision_hz=hz,
            max_episode_steps=int(60 * hz),
            **kwargs,
        )
    return env


def _reset_options(job: Job, base: Any) -> dict[str, Any] | None:
    """The reset's person: the session replayed, the job's model or parameters, else a
    calibrated synthetic person (also in place of a reused env's last one)."""
    from langenv.users import ReplayUser, SyntheticUser

    if job.session:
        return {"user": ReplayUser.from_csv(job.session)}
    if job.user_model is not None:
        return {"user": job.user_model}
    if job.user_params is not None:
        return {"user": SyntheticUser(job.user_params)}
    if type(base.user) is not SyntheticUser:  # a reused env's last person
        return {"user": SyntheticUser()}
    return None


def _write_session(job: Job, log: Any, base: Any, stem: Path) -> None:
    """The session's log, figure, audio and video, as the job asks."""
    if job.save_log:
        log.save_npz(stem.with_suffix(".npz"))
    if job.figures:
        from eval.plots import session_figure

        session_figure(log, stem.with_suffix(".png"))
    if job.audio or job.video:
        import soundfile as sf

        from langenv.speech.render import render_history

        clips, speech = base.clips, base.speech
        audio = render_history(
            base.graph, clips, speech.path, log.t, log.a, pause_lengths=speech.pause_lengths
        )
        if job.audio:
            sf.write(stem.with_suffix(".wav"), audio, clips.sr, subtype="PCM_16")
        if job.video:
            from eval.video import write_video

            write_video(log, stem.with_suffix(".mp4"), audio, clips.sr)


def _run_law(
    base: Any, policy: Any, law: Any, limit: int, rec: Any
) -> tuple[float, bool, dict[str, Any]]:
    """The episode of a policy that is a pace law, at 500 Hz: the env applies the law in
    compiled code (:meth:`LangCtrlEnv.run_law <langenv.env.LangCtrlEnv.run_law>`) and the policy
    takes the steps that need Python; the same episode, bit for bit, as the policy taking every
    step. Returns the return, whether the episode terminated (else the ``limit`` of steps cut it)
    and the last step's info."""
    ret, steps, terminated = 0.0, 0, False
    info: dict[str, Any] = {}
    while not terminated and steps < limit:
        run = base.run_law(law, limit - steps - 1)  # the last step is Python's: its info
        rec.extend(run.info, run.phrase, run.in_pause)
        for reward in run.rewards.tolist():
            ret += reward
        steps += run.steps
        if run.last is not None:
            _, reward, terminated, _, info = run.last
        else:
            _, reward, terminated, _, info = base.step(policy.act(base.observation()))
        steps += 1
        ret += float(reward)
        rec.append(_with_scene(info, base))
    return ret, terminated, info


def _with_scene(info: dict[str, Any], base: Any) -> dict[str, Any]:
    """``info`` with the state that replays the scene: joint positions and the person's force,
    as the env holds them (for :meth:`EpisodeRecorder.append`, which copies them at once)."""
    info["qpos"] = base.motion.arm.data.qpos
    info["f_user"] = base.motion.f_user
    return info


def _graph_ref(graph: str | Path) -> str:
    """How an episode log names its phrase graph: a shipped key, or the YAML's absolute path."""
    from langenv.speech.graph import SHIPPED_GRAPHS

    return str(graph) if str(graph) in SHIPPED_GRAPHS else str(Path(graph).resolve())


def run_compare(args: CompareArgs) -> tuple[Path, list[str], int]:
    """Check ``args``, run every episode and write the outputs into ``args.out``.

    Returns:
        The output directory (resolved), the policies' names in the tables and the number of
        episodes.

    Raises:
        UsageError: bad arguments, found before any episode ran (nothing written).
        OutTaken: ``out`` was taken while the episodes ran; the message says where the
            outputs are.
    """
    out = args.out.resolve()
    _check_out(out, args.overwrite)
    names = _check_policies(args.policies)
    _check_options(args)
    labels = policy_names(names)
    _spoken_graphs(names, labels, args)
    if args.video:
        _check_video()
    users = _users(args)
    if args.listening is not None and args.sessions is not None:
        raise UsageError("--listening sets listening people: give --users listening:N")
    person = _user_spec(args).model() if args.sessions is None else None
    tmp = _make_tmp(out)
    try:
        (tmp / "sessions").mkdir()
        own = dict(args.policy_graphs)
        jobs = [
            Job(
                n,
                u,
                s,
                sess,
                str(tmp / "sessions"),
                args.audio,
                args.figures,
                args.decision_hz,
                own.get(n, str(args.phrase_graph) if args.phrase_graph else None),
                labels[n],
                args.video,
                exercise=args.exercise,
                user_model=person,
            )
            for n in names
            for (u, s, sess) in users
        ]
        rows = run_jobs(jobs, args.workers)
        _write_outputs(rows, list(labels.values()), tmp, args)
        cfg = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(args).items()}
        (tmp / "config.json").write_text(json.dumps(cfg, indent=2) + "\n")
        move_into_place(tmp, out, args.overwrite)
    except OutTaken as exc:
        raise OutTaken(f"{exc}; the outputs are in {tmp}") from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(tmp, ignore_errors=True)  # emptied by a move entry by entry
    return out, list(labels.values()), len(rows)


def run_jobs(jobs: list[Job], workers: int) -> list[dict[str, Any]]:
    """Run ``jobs`` (in ``workers`` processes if > 1) with a progress bar; their rows, in order.

    With several workers the episodes start longest first (:func:`decision_rate`: a policy
    deciding at 500 Hz takes about ten times as long as one at 25 Hz), so that the short ones
    fill the workers' last gaps instead of one worker running a long episode alone at the end.
    """
    from tqdm import tqdm

    bar = tqdm(total=len(jobs), desc=bar_label(jobs), unit="ep", file=sys.stderr)
    rows: list[dict[str, Any] | None] = [None] * len(jobs)
    try:
        if workers == 1:
            for k, job in enumerate(jobs):
                bar.set_postfix_str(_job_name(job), refresh=False)
                rows[k] = run_episode(job)
                bar.update()
        else:
            order = sorted(range(len(jobs)), key=lambda k: -decision_rate(jobs[k]))
            context = multiprocessing.get_context()
            if context.get_start_method() == "fork":
                _preload()
            from langenv.batch.warm import warm_up

            warm_up()  # compiled once here: the workers inherit it or load it, never compile it
            with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
                futures = {pool.submit(run_episode, jobs[k]): k for k in order}
                try:
                    for future in as_completed(futures):
                        rows[futures[future]] = future.result()
                        bar.set_postfix_str(_job_name(jobs[futures[future]]), refresh=False)
                        bar.update()
                except BaseException:  # episodes not yet handed to a worker are not run
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
    finally:
        bar.close()
    done = [row for row in rows if row is not None]
    assert len(done) == len(jobs)
    return done


def bar_label(jobs: Sequence[Job]) -> str:
    """What a progress bar of ``jobs`` runs: their exercise(s) and policies (``"hand_to_mouth:
    ac, lc-noap, lc episodes"``), so that a job of several runs says which one it is on."""
    exercises = sorted({_exercise_name(j.exercise) for j in jobs})
    policies = list(dict.fromkeys(_job_name(j) for j in jobs))
    where = exercises[0] if len(exercises) == 1 else f"{len(exercises)} exercises"
    who = ", ".join(policies) if len(policies) <= 4 else f"{len(policies)} policies"
    return f"{where}: {who} episodes"


def _job_name(job: Job) -> str:
    return job.name if job.name is not None else job.policy


def _exercise_name(exercise: str | None) -> str:
    """An exercise argument as a bar names it: a shipped name, or a file's stem."""
    from langenv.exercise import DEFAULT_EXERCISE

    return DEFAULT_EXERCISE if exercise is None else Path(exercise).stem


def decision_rate(job: Job) -> int:
    """Decisions per second of ``job``'s policy (its episode's steps per simulated second).

    Loads the policy once per spec in this process (as :func:`main` does to check the specs
    before any worker is forked).
    """
    return job.decision_hz or _policy_rate(job.policy)


def _policy_rate(spec: str) -> int:
    return _policy_facts(spec)[0]


@functools.cache
def _policy_facts(spec: str) -> tuple[int, str]:
    """Policy ``spec``'s decision rate and graph role (it is loaded once per process)."""
    from langenv.exercise.script import graph_role
    from policies import load_policy

    policy = load_policy(spec)
    return int(policy.decision_hz), graph_role(policy)


def _preload() -> None:
    """Import what the workers and the final outputs use, once, before the workers are forked
    (they inherit it): each worker then skips its own imports (seconds of CPU on a small
    machine) and the summary figure at the end does not wait for matplotlib."""
    import soundfile  # noqa: F401

    import eval.episode
    import eval.metrics
    import eval.plots
    import eval.report  # noqa: F401
    import langenv.env
    import langenv.speech.render
    import langenv.speech.vocoder  # noqa: F401
    import policies  # noqa: F401


def _write_outputs(
    rows: list[dict[str, Any]], labels: list[str], tmp: Path, args: CompareArgs
) -> None:
    from eval.episode import EpisodeLog
    from eval.plots import violin_figure
    from eval.report import write_sessions_csv, write_summary_md

    write_sessions_csv(rows, tmp / "sessions.csv")
    logs: dict[str, list[EpisodeLog]] = {}
    for row in rows:
        log = EpisodeLog.load_npz(tmp / "sessions" / f"{row['policy']}_{row['user']}.npz")
        logs.setdefault(str(row["policy"]), []).append(log)
    order = [n for n in labels if n in logs]
    violin_figure({n: logs[n] for n in order}, tmp / "summary.png")
    reference = "lc" if "lc" in logs else order[0]
    write_summary_md(
        rows,
        tmp / "summary.md",
        reference,
        rng=np.random.default_rng(args.seed),
        policies=order,
        figure="summary.png",
        stat="mean" if args.stat == "mean" else "median",
    )


def policy_names(specs: Sequence[str]) -> dict[str, str]:
    """Name of each policy spec in the outputs (rows, files, tables), all distinct.

    Analytic policies keep their names; a single ``ppo:PATH`` is ``"ppo"``; several are
    ``"ppo-STEM"`` after their model files (``"ppo-STEM-2"``... if two stems are equal).
    """
    learned = [s for s in specs if s.startswith("ppo:")]
    names: dict[str, str] = {}
    for spec in specs:
        if not spec.startswith("ppo:"):
            names[spec] = spec
        elif len(learned) == 1:
            names[spec] = "ppo"
        else:
            path = Path(spec.removeprefix("ppo:"))
            name = base = "ppo-" + (
                path.stem if path.suffix in (".zip", ".yaml", ".yml") else path.name
            )
            k = 1
            while name in names.values():
                k += 1
                name = f"{base}-{k}"
            names[spec] = name
    return names


def _make_tmp(out: Path) -> Path:
    """The temporary directory the outputs are made in: beside ``out`` (same file system)."""
    from eval.atomic import make_tmp_dir

    try:
        return make_tmp_dir(out)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None
