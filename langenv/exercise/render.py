"""A picture of an exercise: its path over the arm in MuJoCo, written to PNG.

The arm stands at the exercise's start (the pose its reset gives); each leg is drawn in its own
colour, the start as a white ball and each leg's end (its waypoint) as a ball of the leg's colour;
a leg that comes back near its end (a loop, whose end ball may hide in the start's) also gets an
arrow a quarter of the way along it, showing which way round it goes; a caption names the
exercise and its legs (loops marked). Needs an off-screen OpenGL backend (EGL on a headless
Linux machine: :mod:`langenv.robot.gl`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from langenv.control.guide import Guide
from langenv.exercise.spec import Exercise

__all__ = ["LEG_COLOURS", "render_exercise"]

LEG_COLOURS = (
    (0.12, 0.47, 0.71),
    (1.0, 0.5, 0.05),
    (0.17, 0.63, 0.17),
    (0.84, 0.15, 0.16),
    (0.58, 0.4, 0.74),
    (0.55, 0.34, 0.29),
    (0.89, 0.47, 0.76),
    (0.09, 0.75, 0.81),
)
"""Colours of the legs, in turn (matplotlib's tab10)."""
_START = (1.0, 1.0, 1.0)


def _ball(scene: object, pos: np.ndarray, rgb: tuple[float, float, float], r: float) -> None:
    import mujoco

    if scene.ngeom >= scene.maxgeom:  # type: ignore[attr-defined]
        return
    geom = scene.geoms[scene.ngeom]  # type: ignore[attr-defined]
    rgba = np.array([*rgb, 1.0], dtype=np.float32)
    size = np.array([r, r, r])
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_SPHERE, size, pos, np.eye(3).ravel(), rgba)
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR
    scene.ngeom += 1  # type: ignore[attr-defined]


def _arrow(
    scene: object, frm: np.ndarray, to: np.ndarray, rgb: tuple[float, float, float], w: float
) -> None:
    import mujoco

    if scene.ngeom >= scene.maxgeom:  # type: ignore[attr-defined]
        return
    geom = scene.geoms[scene.ngeom]  # type: ignore[attr-defined]
    rgba = np.array([*rgb, 1.0], dtype=np.float32)
    arrow = mujoco.mjtGeom.mjGEOM_ARROW
    mujoco.mjv_initGeom(geom, arrow, np.zeros(3), np.zeros(3), np.zeros(9), rgba)
    mujoco.mjv_connector(geom, arrow, w, frm, to)
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR
    scene.ngeom += 1  # type: ignore[attr-defined]


def render_exercise(
    exercise: Exercise,
    out: str | Path,
    *,
    width: int = 960,
    height: int = 720,
    camera: str = "overview",
    model_path: str | Path | None = None,
) -> Path:
    """Draw the exercise's path over the arm at its start and write it as PNG.

    Args:
        exercise: The exercise.
        out: The PNG file to write.
        width: Image width (px).
        height: Image height (px).
        camera: A camera of the model.
        model_path: The arm's MJCF; None: our UR5.

    Returns:
        The file written.

    Raises:
        ConfigError: no off-screen OpenGL, a bad size or camera, or a start out of reach.
    """
    import mujoco
    from PIL import Image, ImageDraw

    from langenv.robot.arm import Arm
    from langenv.robot.camera import SceneRenderer, add_polyline

    guide = Guide(exercise.trajectory, exercise.admittance())
    loops = [guide.returns(k) for k in range(guide.n_legs)]
    arm = Arm(model_path)
    arm.reset(exercise.start)
    renderer = SceneRenderer(arm.model, width, height)
    try:
        cam = mujoco.mj_name2id(arm.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        renderer.render(arm.data, camera)  # checks the camera
        raw = renderer._renderer
        raw.update_scene(arm.data, camera=cam)
        scene = raw.scene
        traj = exercise.trajectory
        for k in range(len(exercise.legs)):
            a, b = exercise.leg_span(k)
            n = max(80, math.ceil((b - a) / 0.005) + 1)  # a long loop stays round
            pts = np.array([traj.position(s) for s in np.linspace(a, b, n)])
            rgb = LEG_COLOURS[k % len(LEG_COLOURS)]
            add_polyline(scene, pts, 0.005, np.array([*rgb, 0.95], dtype=np.float32))
            _ball(scene, pts[-1], rgb, 0.012)
            if loops[k]:
                s = a + 0.25 * (b - a)
                p = traj.position(s)
                lift = np.array([0.0, 0.0, 0.012])  # above the path, not inside it
                _arrow(scene, p + lift, p + lift + 0.06 * traj.tangent(s), rgb, 0.006)
        _ball(scene, exercise.start, _START, 0.015)
        pixels = raw.render()
    finally:
        renderer.close()
    image = Image.fromarray(pixels)
    draw = ImageDraw.Draw(image)
    draw.text((10, 8), f"{exercise.name}: {exercise.title}", fill=(255, 255, 255))
    y = 26
    draw.text((10, y), "o start", fill=(255, 255, 255))
    for k, leg in enumerate(exercise.legs):
        y += 16
        r, g, b = (int(255 * c) for c in LEG_COLOURS[k % len(LEG_COLOURS)])
        kind = f"{leg.kind}, loop" if loops[k] else leg.kind
        draw.text((10, y), f"- leg {k + 1}: {leg.name} ({kind})", fill=(r, g, b))
    out = Path(out)
    image.save(out, format="PNG", dpi=(100, 100))
    return out
