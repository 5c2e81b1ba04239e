"""Off-screen rendering of the arm scene, with the exercise path and the human force drawn in.

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported; on a headless
Linux machine :mod:`langenv.robot` sets ``MUJOCO_GL=egl`` unless the variable or a display is
already present (set ``MUJOCO_GL=osmesa`` yourself where only OSMesa exists).
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from langenv.errors import ConfigError
from langenv.robot.gl import ensure_headless_context

PATH_RGBA = np.array([0.1, 0.75, 0.3, 0.9], dtype=np.float32)
"""Colour of the exercise path."""

FORCE_RGBA = np.array([0.95, 0.2, 0.15, 1.0], dtype=np.float32)
"""Colour of the force arrow."""

FORCE_SCALE = 0.01
"""Length of the force arrow per newton (m/N)."""

MAX_PATH_SEGMENTS = 400
"""The path is subsampled to at most this many capsules."""


def add_polyline(
    scene: mujoco.MjvScene,
    points: NDArray[np.float64],
    radius: float = 0.004,
    rgba: NDArray[np.float32] = PATH_RGBA,
) -> None:
    """Append a polyline of thin capsules to a scene (skipped when the scene is full).

    Args:
        scene: the scene, after ``update_scene``.
        points: (N, 3) vertices (m), N >= 2.
        radius: capsule radius (m).
        rgba: (4,) colour.
    """
    step = max(1, int(np.ceil((len(points) - 1) / MAX_PATH_SEGMENTS)))
    pts = points[::step]
    if not np.array_equal(pts[-1], points[-1]):
        pts = np.vstack([pts, points[-1:]])
    for a, b in itertools.pairwise(pts):
        if scene.ngeom >= scene.maxgeom:
            return
        if float(np.linalg.norm(b - a)) < 1e-9:
            continue
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(
            geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.zeros(9), rgba
        )
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, radius, a, b)
        geom.category = mujoco.mjtCatBit.mjCAT_DECOR
        scene.ngeom += 1


def add_arrow(
    scene: mujoco.MjvScene,
    start: NDArray[np.float64],
    vector: NDArray[np.float64],
    width: float = 0.01,
    rgba: NDArray[np.float32] = FORCE_RGBA,
) -> None:
    """Append an arrow from ``start`` to ``start + vector`` (skipped if tiny or scene full).

    Args:
        scene: the scene, after ``update_scene``.
        start: (3,) tail (m).
        vector: (3,) arrow (m).
        width: shaft width (m).
        rgba: (4,) colour.
    """
    if scene.ngeom >= scene.maxgeom or float(np.linalg.norm(vector)) < 1e-6:
        return
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(
        geom, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.zeros(9), rgba
    )
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, width, start, start + vector)
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR
    scene.ngeom += 1


class SceneRenderer:
    """A ``mujoco.Renderer`` of fixed size that draws the exercise path and a force arrow.

    Args:
        model: the model to render.
        width: image width (px), at most the model's ``offwidth``.
        height: image height (px), at most the model's ``offheight``.

    Raises:
        ConfigError: width/height not positive or larger than the offscreen buffer.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int) -> None:
        if not (isinstance(width, int) and isinstance(height, int)) or width <= 0 or height <= 0:
            raise ConfigError(f"width and height must be positive ints, got {width!r}, {height!r}")
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ConfigError(
                f"width x height {width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
            )
        self.model = model
        self.size = (width, height)
        ensure_headless_context()  # MuJoCo imported before langenv on a headless machine
        self._renderer = mujoco.Renderer(model, height=height, width=width)

    def render(
        self,
        data: mujoco.MjData,
        camera: str = "overview",
        *,
        path: ArrayLike | None = None,
        force: ArrayLike | None = None,
        force_at: ArrayLike | None = None,
    ) -> NDArray[np.uint8]:
        """Render one RGB frame.

        Args:
            data: the state to draw.
            camera: name of a camera in the model.
            path: optional (N, 3) points (m), drawn as a polyline.
            force: optional (3,) force (N), drawn as an arrow of :data:`FORCE_SCALE` m/N.
            force_at: (3,) tail of the force arrow (m); required with ``force``.

        Returns:
            (height, width, 3) uint8.

        Raises:
            ConfigError: unknown camera or malformed path/force.
        """
        cam = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cam < 0:
            raise ConfigError(f"camera {camera!r} not found in the model")
        pts: NDArray[np.float64] | None = None
        if path is not None:
            pts = np.asarray(path, dtype=np.float64)
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2 or not np.all(np.isfinite(pts)):
                raise ConfigError(f"path must be finite (N >= 2, 3) points, got shape {pts.shape}")
        vec: NDArray[np.float64] | None = None
        tail: NDArray[np.float64] | None = None
        if force is not None:
            vec = np.asarray(force, dtype=np.float64)
            tail = np.asarray(force_at, dtype=np.float64) if force_at is not None else None
            if vec.shape != (3,) or not np.all(np.isfinite(vec)):
                raise ConfigError(f"force must be a finite (3,) vector, got {force!r}")
            if tail is None or tail.shape != (3,):
                raise ConfigError("force_at must be a (3,) point when force is given")
        self._renderer.update_scene(data, camera=cam)
        scene = self._renderer.scene
        if pts is not None:
            add_polyline(scene, pts)
        if vec is not None and tail is not None:
            add_arrow(scene, tail, vec * FORCE_SCALE)
        return self._renderer.render()

    def close(self) -> None:
        """Free the GL context."""
        self._renderer.close()
