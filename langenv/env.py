"""LangCtrl-v0: a UR5 that guides a person's hand along an exercise and talks them through it."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from langenv import env_kernels as ek
from langenv.compiled_steps import CompiledSteps, LawSteps, run_law
from langenv.control.admittance import AdmittanceParams
from langenv.control.cooperation import CooperationFilter
from langenv.control.pacing import PaceActuator, PaceLaw, PaceLimits, command_from_action
from langenv.control.trajectory import Trajectory
from langenv.errors import ConfigError
from langenv.exercise import Exercise, resolve_exercise
from langenv.motion.tick import GuidedArm
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.robot.io import RobotIO
from langenv.robot.io_arm import IOArm, MeasuredUser
from langenv.robot.safety import SafetyLimits
from langenv.speech.audio import ClipLibrary
from langenv.speech.choice import duration_factor
from langenv.speech.graph import PhraseGraph, graph_path
from langenv.speech.hearing import Ear
from langenv.speech.legs import LegPlan, leg_plan
from langenv.speech.repeat import reopen_time
from langenv.speech.shared import shared_clips, shared_graph
from langenv.speech.timeline import SpeechTimeline
from langenv.task import reward
from langenv.task.action import parse_action
from langenv.task.info import step_info
from langenv.task.observation import TREND_WINDOW, ObservationEncoder, observation_size
from langenv.users import Listener, User
from langenv.users.make import make_user
from langenv.validation import (
    check_rates,
    check_render_mode,
    child_blocks,
    non_negative,
    pixels,
    session_length,
)

__all__ = ["LangCtrlEnv", "make_env"]

PHYSICS_HZ = 500


class LangCtrlEnv(gym.Env[np.ndarray, np.ndarray]):
    r"""A UR5 guides a person's hand along a therapy exercise and talks them through it.

    The arm (MuJoCo, 500 Hz) follows the exercise under the paper's variable admittance
    :math:`M_0\dot v = p^2 (F_{ext} + F_{virtual}) - (p D_0 - \tfrac{\dot p}{p} M_0) v`; a simulated
    person pushes on its handle; the robot speaks phrases from a phrase graph, played at audio
    pace ``a`` by a phase vocoder. The agent sets the pace commands and chooses the next phrase; the
    goal (the Language Controller's) is that **speech and motion end together** while both paces
    stay near 1. The analytic controllers of the paper are policies of this env (``policies/``):
    at ``decision_hz=500`` the LC policy is exactly the paper's controller.

    ## The plant (measured against the study's recordings: ``langctrl fidelity``)

    * Exercise (``exercise``, a file of :mod:`langenv.exercise`; by default the study's
      ``external_rotation``, the same path as :func:`~langenv.control.trajectory.default_exercise`):
      an arc of 43 deg out, straight back, the arc again; one leg each (the arc angle is fitted to
      the recorded legs). Any checked exercise works the same way (``langctrl exercise
      list``): its legs, its nominal speed (the guide's plateau) and its phrase graph.
    * Legs (:mod:`langenv.control.guide`), as in the study's lab code: the full propelling force
      up to a leg's end, and the next leg as soon as the hand's 6-D pose is within 0.1 of the
      leg's end pose (3.5 cm before it), without slowing down; the last leg ends the motion the
      same way, and the hand then brakes to rest. Nominal session without resistance: 10.1 s,
      plateaus at 0.125 m/s with short V-shaped dips at the corners. ``info["leg"]`` is the
      index of the leg being guided (the exercise's order, from 0; the number of legs once the
      last is done).
    * The velocity command sent to the arm follows ``v_ref`` changing at most at 0.14 m/s^2 (a
      UR's ``speedL`` acceleration, fitted to the recordings' dips and final ramps); a speed
      governor keeps a hand that a person pushes along from overshooting the corners.
    * The person's force above the 5 N deadband drives the admittance and the cooperation filter.

    ## Speech in step with every leg

    A phrase graph whose script marks the leg each line speaks about (``@leg NAME``,
    :mod:`langenv.speech.legs`) is aligned leg by leg: ``t_x`` below (observation, rewards, the
    choice and pause rules, ``info["t_x"]``) is the motion's time to the end of the *horizon*
    segment, the later of the motion's current leg's segment and the one the speech's plan
    reaches (a gate's: the next leg's), and ``t_a`` the speech's time to the end of that
    segment's lines; a leg's words wait for their leg (a gate); a choice compares its children's
    ``(t_min + t_max)/2``, counted to the end of their own leg, with the motion's time to it.
    ``t_x`` therefore starts again at each leg. An unmarked graph (the study's) is one segment:
    ``t_x`` is the whole motion's, as in the paper.

    ## Action space

    ``Box(-1, 1, (2 + n_choice,), float32)``:

    | index | name | meaning |
    |---|---|---|
    | 0 | ``u_p`` | physical pace command: ``p_cmd = 1 + 0.4 u`` for ``u >= 0``, ``1 + 2.5 u`` below (``u = -1`` is -1.5) |
    | 1 | ``u_a`` | audio pace command, same map |
    | 2.. | choice | next-phrase choice, used only when a phrase ends (see ``choice_mode``) |

    The env applies ``dp/dt = k_p (p_cmd - p)``, ``da/dt = k_a (a_cmd - a)`` at every tick and clips
    ``p, a`` to ``[0.6, 1.4]``. ``choice_mode="target"`` (``n_choice = 1``): ``u`` sets a target
    speech duration ``t_x 2^{2u}`` s and the child whose mid-length ``(t_min + t_max)/2`` is
    closest to it is said next (``u = 0`` is the paper's rule). ``choice_mode="scores"``
    (``n_choice = max_children`` of the graph): the valid child with the highest score is said
    next. An invalid child can never be chosen. A pause vertex's length is chosen within its
    bounds by the graph's rule (:meth:`~langenv.speech.graph.PhraseGraph.pause_length`: the
    speech from there ends at a target duration) when the pause is entered and again at every
    tick while it lasts: with ``choice_mode="target"`` for the same target ``t_x 2^{2u}``
    (``u = 0`` is the rule with ``t_x``), with ``"scores"`` for ``t_x`` itself. An action that is not an array of shape
    ``(2 + n_choice,)`` of numbers in ``[-1, 1]`` (NaN, inf, ``None``, a string, ...) raises
    :class:`~langenv.errors.ActionError`.

    ## Observation space

    ``Box(-1, 1, (16 + 3 max_children,), float32)``; times are divided by ``T_SCALE = 40`` s. The
    layout's one home is :mod:`langenv.task.observation`: the field names of :class:`~langenv.task.observation.Obs`
    index it, and its decoders (``seconds``, ``pace``, ``fraction``, ``flag``, ``child``...) read it.

    | index | field | name | unit / scaling |
    |---|---|---|---|
    | 0 | ``T_X`` | ``t_x`` motion ETC at base pace | s / 40 |
    | 1 | ``T_A`` | ``t_a`` speech ETC at base pace | s / 40 |
    | 2 | ``MISALIGNMENT`` | misalignment at current paces ``t_a/a - t_x/p`` | s / 40 |
    | 3 | ``P`` | ``p`` | ``(p - 1)/0.4`` |
    | 4 | ``A`` | ``a`` | ``(a - 1)/0.4`` |
    | 5 | ``COOPERATION`` | cooperation ``c`` | ``2c - 1`` |
    | 6 | ``COOPERATION_TREND`` | cooperation trend ``dc/dt`` over 0.5 s | 1/s, clipped |
    | 7 | ``PROGRESS`` | progress ``d`` along the path | ``2d - 1`` |
    | 8 | ``HAND_SPEED`` | hand speed | m/s / 0.25 |
    | 9 | ``PHRASE_SAID`` | share of the current phrase said | ``2f - 1`` |
    | 10 | ``PHRASE_LEFT`` | rest of the current vertex's slot at ``a = 1`` (a pause vertex: of its chosen length) | s / 40 |
    | 11 | ``IN_PAUSE`` | in silence: the pause after a clip, or a pause vertex | ±1 |
    | 12 | ``SPEECH_DONE`` | speech over | ±1 |
    | 13 | ``MOTION_DONE`` | motion over | ±1 |
    | 14 | ``BOUNDARY_DUE`` | a phrase boundary is due before the next decision | ±1 |
    | 15 | ``ELAPSED`` | elapsed time | s / 60 |
    | 16 + 3k | child ``VALID`` | child ``k`` is a valid next phrase | ±1 |
    | 17 + 3k | child ``T_MIN`` | its ``t_min`` (pauses at their minimum) | s / 40 |
    | 18 + 3k | child ``T_MAX`` | its ``t_max`` | s / 40 |

    The scales normalise; they do not bound: a pace outside ``[0.6, 1.4]`` (wider ``paces``) or a
    time beyond the scale reads as ±1.

    ## Rewards

    Weighted terms, each reported in ``info`` (``reward_em``, ``reward_pace``, ``reward_am``):

    * ``reward_em = -w_em ∫ |t_a/a - t_x/p| dt / T_SCALE`` over the step (misalignment at current
      paces, while speech or motion goes on);
    * ``reward_pace = -w_pace ∫ ((p-1)^2 [motion on] + (a-1)^2 [speech on]) dt`` (the paper's
      objective);
    * ``reward_am = -w_am |AM|`` (s) once, when the episode ends, ``AM = t_speech_end - t_motion_end``.

    ## Episode end

    Terminates when both speech and motion are over, or at a **protective stop** (below). A speech
    over while the hand, pushed back, still moves 1 s later goes on (:mod:`langenv.speech.repeat`).
    Truncates at the session's length, ``max_seconds`` (60 s), whatever the decision rate: the
    step that reaches it returns ``truncated=True`` (``info["am"]`` is then None). A
    ``max_episode_steps`` given to ``gymnasium.make`` adds Gymnasium's step-counting limit on top.

    ## Safety

    Modelled on a UR5's safety functions (:mod:`langenv.robot.safety`; limits in ``safety``, a
    :class:`~langenv.robot.safety.SafetyLimits`). The arm never *commands* a hand speed above
    ``max_speed`` (0.5 m/s) nor motion away from the path beyond ``hold_deviation`` (0.08 m). At
    every tick a monitor checks what happens anyway (a person's force acts on the arm itself); a
    breach is a protective stop: the arm halts and holds still, and the episode terminates with
    ``info["safety_stop"]`` naming the limit and ``info["safety_message"]`` saying why:

    | limit | default | breach |
    |---|---|---|
    | ``"speed"`` | 0.5 m/s | measured hand speed above ``max_speed + speed_tolerance`` (0.525 m/s) |
    | ``"path_deviation"`` | 0.10 m | hand farther than ``max_deviation`` from its closest path point |
    | ``"force"`` | 150 N | force on the handle above ``max_force`` (a UR5's default force limit) |
    | ``"joint_limit"`` | 0.01 rad | a joint within ``joint_margin`` of the end of its range (the UR5's ±360° ranges are out of reach of the exercise) |

    After a stop ``info["am"]`` is ``None`` and no ``reward_am`` is paid. Every step's ``info``
    reports ``path_deviation`` (m, the hand's distance from its closest path point at the end of
    the step), ``max_hand_speed`` (m/s, the highest over the step's ticks), ``safety_stop`` (the
    limit's name, or ``None``) and ``safety_message`` (``""`` without a stop).

    ## Pace laws in compiled code (``run_law``)

    A policy that is the paper's aligner law (:class:`~langenv.control.pacing.PaceLaw`; ``policies``' LC
    and LC-noAP give theirs with ``pace_law()``) can let the env take its steps:
    ``env.unwrapped.run_law(law, max_steps)`` (``decision_hz=500``) applies the law at every tick
    inside the compiled ticks, exactly as the policy would through the observation and the action,
    and returns each step's info values and reward (:class:`~langenv.compiled_steps.LawSteps`). It stops where a step needs
    Python: a step it began and the env finished in Python (the episode's end, a protective stop)
    comes back as ``last``; without one, take the next step with
    ``env.step(policy.act(env.unwrapped.observation()))`` (a phrase boundary) and call it again. The episode is the
    same, bit for bit, as the policy taking every step, at a few times the speed (``eval.compare``
    runs 500 Hz aligners this way). Steps it takes bypass wrappers (count them for a
    ``max_episode_steps`` wrapper); it stops a step before ``max_seconds``, so that the step that
    truncates is ``env.step``'s.

    ## Arguments

    | argument | default | meaning |
    |---|---|---|
    | ``users`` | ``"synthetic"`` | ``"synthetic"``, ``"listening"`` (a synthetic person who responds to the words' intents, :class:`~langenv.users.ListeningUser`), ``"replay"`` (with ``session``), a :class:`~langenv.users.User` or a callable ``f(t, hand_velocity, tangent) -> (3,)`` N |
    | ``session`` | ``None`` | session CSV (``t, cooperation``) for ``users="replay"`` |
    | ``exercise`` | ``"external_rotation"`` | a shipped exercise's name (``langctrl exercise list``), an exercise YAML path or an :class:`~langenv.exercise.Exercise` |
    | ``phrase_graph`` | the exercise's (``script.graph``: for the study's exercise ``"default"``) | YAML path or a shipped graph: ``"default"`` (= ``"lc"``, LC's graph with pauses and fillers), ``"study"`` (the study's LC graph), ``"lc-noap"``, ``"ac"`` |
    | ``trajectory`` | ``None`` | a :class:`~langenv.control.trajectory.Trajectory` instead of the exercise's path; with ``exercise``, that exercise's path in another frame (its legs, which name the script's) |
    | ``decision_hz`` | 25 | agent decisions per second; must divide 500 (an analytic policy holds the paper's law at its own rate, ``policy.decision_hz``) |
    | ``max_seconds`` | 60 | the session's length (s): the episode truncates there at any ``decision_hz``; ``None``: no limit |
    | ``choice_mode`` | ``"target"`` | next-phrase action design: ``"target"`` or ``"scores"`` |
    | ``w_em``, ``w_pace``, ``w_am`` | 1, 1, 1 | reward weights |
    | ``sensor_noise`` | 0 | force sensor noise std (N) |
    | ``deadband`` | 5 | force sensor deadband (N) |
    | ``admittance`` | SPEC §2, ``propel_force = speed * D0`` | :class:`~langenv.control.admittance.AdmittanceParams` (given: its own propelling force, not the exercise's speed) |
    | ``paces`` | SPEC §2 | :class:`~langenv.control.pacing.PaceLimits` (bounds, ``k_p``, ``k_a``) |
    | ``safety`` | see Safety | :class:`~langenv.robot.safety.SafetyLimits` |
    | ``model_path``, ``handle_site`` | our UR5, ``"handle"`` | another arm MJCF and its handle site |
    | ``render_mode`` | ``None`` | ``"rgb_array"`` (off-screen; needs ``MUJOCO_GL=egl`` or ``osmesa``); for a window wrap the env in ``gymnasium.wrappers.HumanRendering`` (needs pygame) |
    | ``width``, ``height`` | 640, 480 | render size (pixels) |
    | ``robot`` | ``None`` | a :class:`~langenv.robot.io.RobotIO` to drive instead of the simulation (a real UR, its fake, or :class:`~langenv.robot.sim_io.MujocoRobot`): each tick sends ``speedL`` and waits for the robot's next period; the person's force is the wrist sensor's reading (``users`` is ignored); robot faults are stops too (:data:`~langenv.robot.safety.ROBOT_STOPS`) |
    | ``robot_acceleration`` | 1.0 | ``speedL``'s acceleration (m/s^2) with ``robot`` |
    | ``max_children`` | ``None`` | child blocks of the observation (and choices in ``"scores"`` mode), at least the graph's largest out-degree (the default): envs of different graphs then share one observation layout, the extra blocks empty |

    ``reset(options=...)`` accepts ``{"user": User}`` to swap the user for that episode.

    ## Version history

    What changed in each release of ``LangCtrl-v0``: the environment guide
    (``docs/environment.md``, "Version history").
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 25}  # noqa: RUF012

    def __init__(
        self,
        *,
        users: str | User | Callable[..., np.ndarray] = "synthetic",
        session: str | Path | None = None,
        exercise: str | Path | Exercise | None = None,
        phrase_graph: str | Path | None = None,
        decision_hz: int = 25,
        choice_mode: Literal["target", "scores"] = "target",
        w_em: float = 1.0,
        w_pace: float = 1.0,
        w_am: float = 1.0,
        sensor_noise: float = 0.0,
        deadband: float = 5.0,
        admittance: AdmittanceParams | None = None,
        paces: PaceLimits | None = None,
        safety: SafetyLimits | None = None,
        trajectory: Trajectory | None = None,
        model_path: str | Path | None = None,
        handle_site: str = "handle",
        render_mode: str | None = None,
        width: int = 640,
        height: int = 480,
        clips: ClipLibrary | None = None,
        robot: RobotIO | None = None,
        robot_acceleration: float = 1.0,
        max_children: int | None = None,
        max_seconds: float | None = 60.0,
    ) -> None:
        super().__init__()
        check_rates(decision_hz, choice_mode, PHYSICS_HZ)
        weights = [
            non_negative(n, w) for n, w in (("w_em", w_em), ("w_pace", w_pace), ("w_am", w_am))
        ]
        check_render_mode(render_mode)
        self.render_mode = render_mode
        self.width, self.height = pixels("width", width), pixels("height", height)
        self.decision_hz = int(decision_hz)
        self.ticks_per_step = PHYSICS_HZ // self.decision_hz
        self.max_seconds, self.max_ticks = session_length(max_seconds, PHYSICS_HZ)
        self.choice_mode = choice_mode
        self.w_em, self.w_pace, self.w_am = weights
        if safety is not None and not isinstance(safety, SafetyLimits):
            raise ConfigError(f"safety must be SafetyLimits or None, got {type(safety).__name__}")

        self.exercise: Exercise = resolve_exercise(exercise)
        if trajectory is not None and not isinstance(trajectory, Trajectory):
            raise ConfigError(f"trajectory must be a Trajectory, got {type(trajectory).__name__}")
        if exercise is not None and trajectory is not None:
            n = len(trajectory.waypoint_s)
            if n != len(self.exercise.legs):
                raise ConfigError(
                    f"trajectory has {n} legs, exercise {self.exercise.name!r} "
                    f"{len(self.exercise.legs)}: give the exercise's own path (in any frame), "
                    "or the trajectory alone"
                )
        arm: Arm | IOArm
        if robot is None:
            arm = Arm(model_path, handle_site)
            self.user: User = make_user(users, session)
        else:
            if render_mode is not None:
                raise ConfigError("render_mode needs the simulation: pass robot=None")
            arm = IOArm(robot, acceleration=robot_acceleration)
            self.user = MeasuredUser(arm)
        self.clips = clips if clips is not None else shared_clips()
        graph = phrase_graph if phrase_graph is not None else self.exercise.graph
        self.graph = shared_graph(graph_path(graph), self.clips)  # one per process: read-only
        self.max_children = child_blocks(self.graph.max_children, max_children)

        params = admittance if admittance is not None else self.exercise.admittance()
        self.motion = GuidedArm(
            arm,
            trajectory if trajectory is not None else self.exercise.trajectory,
            params,
            ForceSensor(noise_std=sensor_noise, deadband=deadband),
            CooperationFilter(),
            safety,
        )
        self.paces = PaceActuator(paces if paces is not None else PaceLimits())
        self._legs = self._leg_plan(self.graph)
        self.speech = SpeechTimeline(self.graph)
        self.dt = self.motion.dt
        if not math.isclose(self.dt * PHYSICS_HZ, 1.0, rel_tol=1e-9):
            raise ConfigError(f"the arm model's timestep must be 0.002 s, got {self.dt}")

        n_choice = 1 if choice_mode == "target" else self.max_children
        self._action_shape = (2 + n_choice,)
        self.action_space = spaces.Box(-1.0, 1.0, self._action_shape, np.float32)
        durations = {u: (self.graph.t_min(u), self.graph.t_max(u)) for u in self.graph.phrases}
        self._encoder = ObservationEncoder(self.max_children, durations)
        size = observation_size(self.max_children)
        self.observation_space = spaces.Box(-1.0, 1.0, (size,), np.float32)
        self._obs = np.zeros(size, np.float32)
        self._choice_u: list[float] = [0.0] * n_choice
        self._init_state()
        self._steps = CompiledSteps(self) if self.motion.compiled else None

    def _init_state(self) -> None:
        """The env's state before its first reset (the episode's own in :meth:`reset`)."""
        self._pause_factor = 1.0  # the pause rule's target over t_x (target mode: 2**(2u))
        self._ear: Ear | None = None
        self.time = 0.0
        self.t_a = 0.0
        self.t_h = 0.0
        self._hz: Sequence[float] = (0.0,)
        self.t_speech_end: float | None = None
        self.am = 0.0
        self._terminated = False
        self._am_paid = False
        self._reset_episode_state()

    def _leg_plan(self, graph: PhraseGraph) -> LegPlan:
        """The plan of ``graph``'s legs on the exercise (:mod:`langenv.speech.legs`)."""
        names = self.exercise.leg_names
        n_legs = len(self.motion.trajectory.waypoint_s)
        if graph.segment_names and n_legs != len(names):
            raise ConfigError(
                f"{graph.path}: a script marked with legs needs the exercise's own path "
                f"({len(names)} legs), got a trajectory of {n_legs}"
            )
        return leg_plan(graph, names, self.motion.etc.nominal_rest, self.exercise.name)

    @property
    def motion_legs(self) -> tuple[str, ...]:
        """The names of the legs the motion goes through, which ``info["leg"]`` indexes: the
        exercise's, unless a trajectory of other legs replaced the exercise's path (then none)."""
        names = tuple(self.exercise.leg_names)
        return names if len(self.motion.trajectory.waypoint_s) == len(names) else ()

    @property
    def leg_plan(self) -> LegPlan:
        """The phrase graph's segments on the exercise's legs (one for an unmarked graph)."""
        return self._legs

    def use_phrase_graph(self, graph: PhraseGraph) -> None:
        """Speak ``graph`` from the next :meth:`reset` on, instead of the one given at
        construction (a variant of the script, :func:`langenv.speech.variant.vary_graph`, for
        training across worlds). Call it between episodes.

        Raises:
            ConfigError: if ``graph`` is not a :class:`PhraseGraph`, or its largest number of
                choices differs from the env's (the observation would change size).
        """
        if not isinstance(graph, PhraseGraph):
            raise ConfigError(f"use_phrase_graph: expected a PhraseGraph, got {graph!r}")
        if max(1, graph.max_children) != self.max_children:
            raise ConfigError(
                f"use_phrase_graph: the graph has {graph.max_children} choices at most, the "
                f"env's observation {self.max_children}"
            )
        self._legs = self._leg_plan(graph)
        self.graph = graph
        self.speech = SpeechTimeline(graph)
        durations = {u: (graph.t_min(u), graph.t_max(u)) for u in graph.phrases}
        self._encoder = ObservationEncoder(self.max_children, durations)
        if self._steps is not None:
            self._steps = CompiledSteps(self)

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if options and "user" in options:
            if isinstance(self.user, MeasuredUser):
                raise ConfigError("on a robot the person is real: reset(options={'user'}) refused")
            self.user = make_user(options["user"], None)
        self.user.reset(self.np_random)
        self.motion.reset()
        self.paces.reset()
        self.speech.reset()
        self._ear = Ear(self.speech) if isinstance(self.user, Listener) else None
        self._reset_episode_state()
        self._update_speech_eta()
        return self._observation(), step_info(self)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        values = parse_action(action, self._action_shape)
        lim = self.paces.limits
        p_cmd = command_from_action(values[0], lim.p_max)
        a_cmd = command_from_action(values[1], lim.a_max)
        self.take_choice(values[2:])
        self._max_speed = 0.0
        em_int, pace_int = self.run_ticks(p_cmd, a_cmd, self.ticks_per_step, 0.0, 0.0)
        return self._step_result(em_int, pace_int)

    def take_choice(self, values: list[float]) -> None:
        """The step's next-phrase values (the action's ``[2:]``, already checked): for a
        boundary (:meth:`_choose`) and the pause rule's target."""
        self._choice_u = values
        self._pause_factor = (
            duration_factor(float(values[0])) if self.choice_mode == "target" else 1.0
        )

    def run_ticks(
        self, p_cmd: float, a_cmd: float, left: int, em_int: float, pace_int: float
    ) -> tuple[float, float]:
        """The step's ``left`` remaining ticks (compiled where they may be, in Python where
        not), stopping early at the episode's end; returns the reward integrals with theirs
        added. What :meth:`step` runs, and a batch (:mod:`langenv.batch`) for a session that
        needs Python."""
        while left > 0 and not self._terminated:
            if self._steps is not None and self._steps.usable():  # the compiled ticks
                done, answer, code, em_int, pace_int = self._steps.run(
                    p_cmd, a_cmd, left, em_int, pace_int
                )
                left -= done
                if answer == ek.R_DONE:
                    continue
                if answer != ek.R_PYTHON:
                    em, pace = self._after_compiled(answer, code)
                    em_int += em * self.dt
                    pace_int += pace * self.dt
                    continue
            em, pace = self._tick(p_cmd, a_cmd)
            em_int += em * self.dt
            pace_int += pace * self.dt
            self._max_speed = max(self._max_speed, self.motion.hand_speed)
            left -= 1
        return em_int, pace_int

    def run_law(self, law: PaceLaw, max_steps: int) -> LawSteps:
        """Take up to ``max_steps`` steps whose actions are ``law``'s, in compiled code.

        The same episode, step for step and bit for bit, as a policy that is ``law`` stepping
        the env (``env.step(policy.act(obs))``), without returning to Python between steps:
        for analytic aligners at 500 Hz, whose steps cost several times their tick in Python.
        It takes at most :data:`~langenv.compiled_steps.LAW_CHUNK` steps per call and stops early where a step needs
        Python. A step the law began whose tick ended as only Python can finish it (the end of
        the episode, a protective stop, joint-limit avoidance) is finished and returned as
        ``last``; when ``last`` is None, the next step needs Python (a phrase's clip or slot
        ends) or the compiled ticks do not apply (:attr:`runs_compiled`): take it with
        ``env.step(policy.act(env.observation()))``, then call this again.

        Args:
            law: The law (``policies``' LC and LC-noAP give theirs with ``pace_law()``).
            max_steps: Most steps to take (a time limit's steps left), >= 0.

        Returns:
            The steps taken (:class:`~langenv.compiled_steps.LawSteps`): their info values and rewards, and ``last``.

        Raises:
            ConfigError: if the env does not step one tick at a time (``decision_hz=500``), or for
                a bad ``law`` or ``max_steps``.
        """
        return run_law(self, law, max_steps)

    # ------------------------------------------------------------------ a batch's hooks
    @property
    def compiled_steps(self) -> CompiledSteps | None:
        """The env's compiled ticks (:class:`~langenv.compiled_steps.CompiledSteps`), or None
        where the arm's tick is not compiled."""
        return self._steps

    @property
    def terminated(self) -> bool:
        """Whether the episode has ended (both over, or a protective stop)."""
        return self._terminated

    @property
    def t_speech(self) -> float | None:
        """When the speech ended (s), None while it goes on (``info["t_speech"]``)."""
        return self.t_speech_end

    def finish_event(
        self, answer: int, code: int, p_cmd: float, a_cmd: float
    ) -> tuple[float, float, int]:
        """Python's part where compiled ticks stopped with ``answer`` (and ``code``,
        :func:`langenv.env_kernels.run`'s): a whole tick in Python before
        :data:`~langenv.env_kernels.R_PYTHON`, the rest of the last tick otherwise. Returns its
        reward integrands and the ticks it took (1 or 0). The env's state must be in its Python
        objects (:meth:`CompiledSteps.store <langenv.compiled_steps.CompiledSteps.store>`)."""
        if answer == ek.R_PYTHON:
            em, pace = self._tick(p_cmd, a_cmd)
            self._max_speed = max(self._max_speed, self.motion.hand_speed)
            return em, pace, 1
        em, pace = self._after_compiled(answer, code)
        return em, pace, 0

    def observation_tails(self, order: tuple[str, ...]) -> np.ndarray:
        """The observation's child blocks of each vertex of ``order`` and of the speech's end,
        as :meth:`ObservationEncoder.tail_table
        <langenv.task.observation.ObservationEncoder.tail_table>` gives them for this env's graph."""
        graph = self.speech.graph
        return self._encoder.tail_table(order, {u: graph.children(u) for u in order})

    def step_result(
        self, em_int: float, pace_int: float
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """The step's return value from its reward integrals (what :meth:`step` returns)."""
        return self._step_result(em_int, pace_int)

    # ------------------------------------------------------------------ the compiled steps' state
    @property
    def coop_history(self) -> np.ndarray:
        """The cooperation samples of the last :data:`~langenv.task.observation.TREND_WINDOW`
        (a ring, written at :attr:`coop_index` modulo its size; the compiled ticks write it)."""
        return self._coop_hist

    @property
    def coop_index(self) -> int:
        """Cooperation samples taken since the reset."""
        return self._coop_i

    @property
    def max_speed(self) -> float:
        """The highest hand speed of the step so far (m/s; ``info["max_hand_speed"]``)."""
        return self._max_speed

    @property
    def pause_factor(self) -> float:
        """The pause rule's target over ``t_x`` for this step (the target action's factor)."""
        return self._pause_factor

    @property
    def reopen_at(self) -> float:
        """From when the speech may go on after its end (s; ``repeat.reopen_time``): the
        compiled ticks hand that tick to Python (:meth:`_reopen_due`)."""
        return reopen_time(self.speech.graph, self.t_speech_end, self._reopens)

    def take_times(
        self, time: float, t_a: float, t_h: float, max_speed: float, coop_index: int
    ) -> None:
        """Take the env's time, ``t_a``, ``t_h``, the step's highest hand speed and the
        cooperation samples' count back after compiled ticks
        (:class:`~langenv.compiled_steps.CompiledSteps`)."""
        self.time, self.t_a, self.t_h = time, t_a, t_h
        self._max_speed, self._coop_i = max_speed, coop_index

    @property
    def runs_compiled(self) -> bool:
        """Whether the next ticks run in compiled code (:meth:`run_law` takes steps): the arm's
        compiled tick, a synthetic or replayed user, no force sensor noise, no protective stop,
        the episode not over."""
        return not self._terminated and self._steps is not None and self._steps.usable()

    def observation(self) -> np.ndarray:
        """The current observation (as ``reset`` and ``step`` return it), e.g. after
        :meth:`run_law`."""
        return self._observation()

    def _step_result(
        self, em_int: float, pace_int: float
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """The step's return value: its reward terms from the integrals, the info, the
        observation."""
        r_em, r_pace = reward.step_terms(em_int, pace_int, self.w_em, self.w_pace)
        r_am = 0.0
        if self._terminated and not self._am_paid:
            if not self.motion.stopped:
                r_am = reward.am_term(self.am, self.w_am)
            self._am_paid = True
        total = reward.total(r_em, r_pace, r_am)
        info = step_info(self)
        info.update(reward_em=r_em, reward_pace=r_pace, reward_am=r_am)
        return self._observation(), float(total), self._terminated, self.truncated, info

    @property
    def truncated(self) -> bool:
        """Whether the episode has reached its length (``max_seconds``) without ending."""
        left = self.ticks_left
        return not self._terminated and left is not None and left <= 0

    @property
    def ticks_left(self) -> int | None:
        """Ticks left to the session's length (``max_seconds``); None without one."""
        if self.max_ticks is None:
            return None
        return self.max_ticks - round(self.time * PHYSICS_HZ)

    def render(self) -> np.ndarray | None:
        arm = self.motion.arm
        if self.render_mode != "rgb_array" or not isinstance(arm, Arm):
            return None
        return arm.render(
            self.width,
            self.height,
            path=self.motion.trajectory.sample(200),
            force=self.motion.f_user,
        )

    def close(self) -> None:
        self.motion.arm.close()
        super().close()

    # ------------------------------------------------------------------ internals
    def _reset_episode_state(self) -> None:
        self.time = 0.0
        self.t_a = 0.0
        self.t_h = 0.0
        self.t_speech_end = None
        self.am = 0.0
        self._terminated = False
        self._am_paid = False
        self._coop_hist = np.ones(max(1, round(TREND_WINDOW / self.dt)))
        self._coop_i = 0
        self._max_speed = self.motion.hand_speed
        self._reopens = 0

    def _tick(self, p_cmd: float, a_cmd: float) -> tuple[float, float]:
        """One 2 ms tick; returns the instantaneous misalignment and pace penalty."""
        motion = self.motion
        self.paces.step(p_cmd, a_cmd, self.dt)
        f_user = self.user.force(self.time, motion.hand_velocity, motion.tangent())
        motion.tick(f_user, self.paces.p, self.paces.p_dot, self.np_random)
        return self._after_motion()

    def _after_motion(self) -> tuple[float, float]:
        """The tick after the arm's part: stop, speech, ``t_a``, the reward integrands, the end."""
        motion, speech = self.motion, self.speech
        p, a = self.paces.p, self.paces.a
        if motion.stopped:  # protective stop: the episode ends here
            self.time += self.dt
            self._terminated = True
            return 0.0, 0.0
        hz = self._horizons()  # the motion's, after its tick: for the speech and its ETC
        if speech.done and self._reopen_due():
            assert speech.graph.reopen is not None
            speech.reopen(speech.graph.reopen, self.time, hz, self._pause_factor)
            self.t_speech_end = None
            self._reopens += 1
        if not speech.done:
            speech.step(self.dt, a, self._choose, hz, pause_factor=self._pause_factor)
        self.time += self.dt
        if self._ear is not None:
            self._listen(a)
        self._coop_hist[self._coop_i % self._coop_hist.size] = motion.cooperation
        self._coop_i += 1
        self._update_speech_eta(hz)
        if speech.done and self.t_speech_end is None:
            end = speech.t_end
            self.t_speech_end = end if end is not None else self.time
        motion_on, speech_on = not motion.motion_done, not speech.done
        em, pace = reward.integrands(self.t_a, a, self.t_h, p, motion_on, speech_on)
        if not motion_on and not speech_on:
            self._end_episode()
        return em, pace

    def _reopen_due(self) -> bool:
        """Whether the speech goes on now (the motion on, with time for the reopen's words)."""
        return (
            self.time >= self.reopen_at
            and not self.motion.motion_done
            and self.motion.t_x >= self.speech.graph.t_min(self.speech.graph.reopen)  # type: ignore[arg-type]
        )

    def _listen(self, a: float) -> None:
        """Tell a person who listens (:class:`~langenv.users.Listener`) the words heard in this
        tick and, if they need it, the speech's lead over the motion: the speech's progress
        minus the motion's, in seconds of the whole speech, while the speech runs (0 once it
        is over; :mod:`langenv.users.listening`)."""
        user: Any = self.user
        assert self._ear is not None
        for t, _, intent in self._ear.step(self.dt, a):
            user.hear(t, intent)
        if user.perceives:  # while the speech runs; once it is over there is nothing to follow
            sp = self.speech
            said = sp.content_time
            left = self.t_a if self._legs.segments == 1 else sp.eta(self._hz)
            lead = 0.0 if sp.done else said - self.motion.progress * (said + left)
            user.perceive(self.time, lead)

    def _end_episode(self) -> None:
        """Motion and speech are over: the episode terminates with its alignment ``am``."""
        motion = self.motion
        self._terminated = True
        t_motion = motion.t_motion_end if motion.t_motion_end is not None else self.time
        t_speech = self.t_speech_end if self.t_speech_end is not None else self.time
        self.am = t_speech - t_motion

    def _after_compiled(self, answer: int, code: int) -> tuple[float, float]:
        """Python's part of the compiled ticks' last tick (:mod:`langenv.env_kernels`)."""
        tick = self.motion.compiled_tick
        assert tick is not None
        f_user = self.motion.f_user
        if answer == ek.R_CONTROL:  # joint-limit avoidance or bad input, then the rest
            p, p_dot = self.paces.p, self.paces.p_dot
            tick.finish_rare(code, f_user, p, p_dot)
            tick.finish(*f_user.tolist())
            em, pace = self._after_motion()
            self._max_speed = max(self._max_speed, self.motion.hand_speed)
            return em, pace
        if answer == ek.R_STOP:
            tick.stop(*f_user.tolist())
            self._terminated = True
        elif answer == ek.R_OVER:
            self._end_episode()
        return 0.0, 0.0

    def _choose(self, candidates: tuple[str, ...]) -> str:
        """Next phrase among ``candidates`` from the latest action (never an invalid child)."""
        if len(candidates) == 1:
            return candidates[0]
        if self.choice_mode == "target":
            h = self._hz[self.graph.segment(candidates[0])]
            return self.graph.nearest(candidates, h * duration_factor(float(self._choice_u[0])))
        scores = self._choice_u[: len(candidates)]
        return candidates[int(np.argmax(scores))]

    def _horizons(self) -> float | Sequence[float]:
        """The motion's time to the end of each of the graph's segments (kept for the step's
        choices); a number for one segment: its ``t_x``."""
        m = self.motion
        if self._legs.segments == 1:
            self._hz = (m.t_x,)
            return m.t_x
        self._hz = self._legs.horizons(m.t_x, m.t_leg, m.state.leg)
        return self._hz

    def _update_speech_eta(self, hz: float | Sequence[float] | None = None) -> None:
        """``t_a`` and ``t_h``: the speech's and the motion's times to the end of the horizon
        segment (the later of the motion's and the speech's plan's; :mod:`langenv.speech.legs`),
        from the horizons ``hz`` of this tick (None: computed now)."""
        if hz is None:
            hz = self._horizons()
        if isinstance(hz, float):
            self.t_a, self.t_h = self.speech.eta(hz), hz
            return
        last = max(self._legs.motion_segment(self.motion.state.leg), self.speech.horizon_segment())
        self.t_a, self.t_h = self.speech.eta(hz, last), hz[last]

    def _observation(self) -> np.ndarray:
        """The observation (layout and scales: :mod:`langenv.task.observation`)."""
        m, sp = self.motion, self.speech
        a = self.paces.a
        hist, i = self._coop_hist, self._coop_i
        n = hist.size
        newest = hist.item((i - 1) % n)  # Python floats: cheaper arithmetic than NumPy scalars
        oldest = hist.item(i % n) if i >= n else 1.0
        self._encoder.encode(
            self._obs,
            t_x=self.t_h,
            t_a=self.t_a,
            p=self.paces.p,
            a=a,
            cooperation=m.cooperation,
            cooperation_trend=(newest - oldest) / TREND_WINDOW,
            progress=m.progress,
            hand_speed=m.hand_speed,
            phrase_said=sp.fraction_said,
            phrase_left=sp.remaining_in_phrase,
            in_pause=sp.in_pause,
            speech_done=sp.done,
            motion_done=m.motion_done,
            boundary_due=sp.boundary_due(self.ticks_per_step * self.dt, a),
            elapsed=self.time,
            children=sp.candidates,
        )
        return self._obs.copy()


def make_env(**kwargs: Any) -> LangCtrlEnv:
    """Entry point of ``LangCtrl-v0``: ``LangCtrlEnv(**kwargs)``.

    A function rather than the class, so that ``gymnasium.make`` hands ``render_mode`` to the env,
    which names a mode it does not support, instead of wrapping it for ``"human"`` on its own.
    """
    return LangCtrlEnv(**kwargs)
