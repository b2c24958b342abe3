"""What the facility environments share: a facility built once and loaded, seeded
poses on reset, actuator targets as actions, an observation dict, rendering.

A subclass names its robot's pieces (from the manifest's roles, never hard-coded):
the actuators an action drives, the vectors it observes, the camera of the camera
observations, and its task (reward, termination).

The physics steps through the runtime's one :class:`~urdf2mjcf.runner.sim.Sim`
(``env.sim``: ``frame_skip`` steps per env step), whose sensor noise and camera models
the observations use.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from ..bundle_manifest import Manifest
from ..errors import InputError
from ..facility.recipe import JITTER_KEYS, Ranges, Recipe
from ..runner.camera import CameraModel
from ..runner.noise import SensorNoise
from ..runner.perception import render_rgbd
from ..runner.sim import Sim
from .build import facility_folder, resolve_recipe
from .poses import Poses

Obs = dict[str, np.ndarray]

DEFAULT_CONTROL_HZ = 25.0
"""Control rate when ``frame_skip`` is not given: 20 physics steps of 2 ms."""
MAX_SEED = 2**31 - 1


def _size(value: Any, what: str) -> tuple[int, int]:
    """A ``(width, height)`` of positive integers."""
    try:
        w, h = (int(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{what} is (width, height), got {value!r}", element=what) from None
    if w <= 0 or h <= 0:
        raise InputError(f"{what} must be positive, got {value!r}", element=what)
    return w, h


def _ranges(recipe: Recipe, names: list[str], jitter: Mapping[str, Any] | None) -> dict:
    """Each placed component's jitter ranges: the recipe's, replaced by ``jitter``'s."""
    out: dict[str, Ranges] = {n: recipe.jitter_ranges(n) for n in names}
    for name, value in (jitter or {}).items():
        if name not in names:
            valid = ", ".join(sorted(names))
            raise InputError(f"unknown component; placed ones: {valid}", element=f"jitter.{name}")
        if value is None or value is False:
            out[name] = None
            continue
        if not isinstance(value, Mapping) or set(value) - set(JITTER_KEYS):
            raise InputError("a mapping {position, yaw} or None", element=f"jitter.{name}")
        out[name] = {k: float(value.get(k, 0.0)) for k in JITTER_KEYS}
    return out


class FacilityEnv(gym.Env[Obs, np.ndarray]):
    """A built facility as a Gymnasium environment (see docs/envs.md)."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": DEFAULT_CONTROL_HZ}
    default_camera: str = ""
    """The roles key of the camera whose images ``camera_obs`` adds."""

    def __init__(
        self,
        recipe: str | Path,
        *,
        facility: str | Path | None = None,
        root: str | Path | None = None,
        cache_dir: str | Path | None = None,
        frame_skip: int | None = None,
        camera_obs: bool = False,
        camera: str | None = None,
        camera_size: tuple[int, int] = (128, 96),
        render_mode: str | None = None,
        render_size: tuple[int, int] = (480, 360),
        render_camera: str | None = None,
        jitter: Mapping[str, Any] | None = None,
        sensor_noise: bool = True,
    ):
        """``recipe``: a recipe file or name (``imetro``); ``facility``: a folder built
        earlier by make-facility to use instead of the cached build of the recipe;
        ``jitter``: component -> {position, yaw} ranges (m, rad) replacing the recipe's;
        ``sensor_noise``: the recipe's sensor noise (facility.json ``noise``) on the
        force-torque and camera observations, seeded by each reset's jitter seed."""
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            valid = ", ".join(self.metadata["render_modes"])
            raise InputError(f"'{render_mode}' is not one of {valid}", element="render_mode")
        root_path = Path(root) if root is not None else None
        if facility is None:
            folder, loaded = facility_folder(
                recipe, root=root_path, cache_dir=Path(cache_dir) if cache_dir else None
            )
        else:
            folder, loaded = Path(facility), resolve_recipe(recipe, root_path)[2]
        self.folder = folder
        self.recipe = loaded
        self.model, self.data, self.manifest, self.manifest_path = self._open(folder)
        m = self.model
        self.sensor_noise = sensor_noise
        self.sim = Sim(
            m,
            self.data,
            self.manifest,
            folder=folder,
            manifest_path=self.manifest_path,
            sensor_noise=sensor_noise,
        )
        """The Sim every step goes through; its noise is reseeded by every reset."""
        self.key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
        placed = self.manifest.placed()
        if jitter is None:
            jitter = self.default_jitter()
        self.poses = Poses(m, self.manifest, _ranges(loaded, placed, jitter), self.manifest_path)

        dt = float(m.opt.timestep)
        default_skip = max(1, round(1.0 / (DEFAULT_CONTROL_HZ * dt)))
        self.frame_skip = int(frame_skip) if frame_skip is not None else default_skip
        if self.frame_skip < 1:
            raise InputError(f"must be >= 1, got {frame_skip}", element="frame_skip")
        self.metadata = {**self.metadata, "render_fps": 1.0 / (dt * self.frame_skip)}
        self.render_mode = render_mode

        acts = self.actuators()
        if not np.all(m.actuator_ctrllimited[acts]):
            raise InputError("every actuator of the action needs a ctrlrange", file=folder)
        self._acts = acts
        lo, hi = m.actuator_ctrlrange[acts].T
        self.action_space = spaces.Box(lo.astype(np.float32), hi.astype(np.float32))
        self._lo, self._hi = lo.copy(), hi.copy()

        obs_spaces: dict[str, spaces.Space] = {
            k: spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float64)
            for k, n in self.vector_sizes().items()
        }
        self.camera_obs = bool(camera_obs)
        self._camera_size = self._fits(camera_size, "camera_size")
        self.camera_id = -1
        """The camera of the camera observations (-1: none)."""
        self.camera_model: CameraModel | None = None
        """The camera observations' intrinsics (the Sim's model of the camera)."""
        if self.camera_obs:
            role = camera or self.default_camera
            self.camera_id = self._camera_id(role, "camera")
            w, h = self._camera_size
            self.camera_model = self.sim.camera(m.camera(self.camera_id).name, (w, h))
            self._far = float(m.stat.extent * m.vis.map.zfar)
            obs_spaces["rgb"] = spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)
            obs_spaces["depth"] = spaces.Box(0.0, self._far, shape=(h, w), dtype=np.float32)
        self.observation_space = spaces.Dict(obs_spaces)  # type: ignore[assignment]

        self._render_size = self._fits(render_size, "render_size")
        self._render_camera = (
            self._camera_id(render_camera, "render_camera") if render_camera else None
        )
        self._renderers: dict[str, mujoco.Renderer] = {}
        self.jitter_seed: int | None = None

    @property
    def noise(self) -> SensorNoise:
        """The sensor noise of this episode (the Sim's; passes data through with
        ``sensor_noise=False``)."""
        return self.sim.noise

    # -- what a subclass provides -------------------------------------------------

    def _open(self, folder: Path) -> tuple[mujoco.MjModel, mujoco.MjData, Manifest, Path]:
        """Load the facility: ``(model, data, manifest, manifest path)``."""
        raise NotImplementedError

    def default_jitter(self) -> Mapping[str, Any]:
        """Jitter ranges replacing the recipe's when the caller gives none."""
        return {}

    def actuators(self) -> np.ndarray:
        """Actuator ids an action drives, in action order."""
        raise NotImplementedError

    def vector_sizes(self) -> dict[str, int]:
        """Observation name -> length of the vectors :meth:`vectors` returns."""
        raise NotImplementedError

    def vectors(self) -> Obs:
        """The observed vectors, fresh arrays."""
        raise NotImplementedError

    def cameras(self) -> Mapping[str, str]:
        """The robot's cameras by role (roles ``cameras``)."""
        raise NotImplementedError

    def task_reset(self) -> None:
        """Called after every reset, the model at its new poses."""

    def task_step(self) -> tuple[float, bool, dict[str, Any]]:
        """After each env step: ``(reward, terminated, info)``."""
        return 0.0, False, {}

    def free_camera(self, cam: mujoco.MjvCamera) -> None:
        """Point the free camera that :meth:`render` uses when no ``render_camera``."""
        mujoco.mjv_defaultFreeCamera(self.model, cam)

    # -- Gymnasium ------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        """Back to the home keyframe, every component at a pose drawn from the seeded
        jitter (``options={"jitter_seed": s}``: the poses of ``make-facility --seed s``)."""
        super().reset(seed=seed)
        m, d = self.model, self.data
        self.sim.reset(self.key if self.key >= 0 else None, forward=False)
        drawn = int(self.np_random.integers(MAX_SEED))
        given = (options or {}).get("jitter_seed")
        self.jitter_seed = int(given) if given is not None else drawn
        offsets = self.poses.apply(m, d, self.jitter_seed)
        self.sim.reseed(self.jitter_seed)
        mujoco.mj_forward(m, d)
        self.task_reset()
        return self._obs(), {"jitter_seed": self.jitter_seed, "offsets": offsets}

    def step(self, action: np.ndarray) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        d = self.data
        # MuJoCo clamps a limited control to its range anyway; NaN would poison the state
        target = np.nan_to_num(np.asarray(action, dtype=np.float64), nan=0.0)
        d.ctrl[self._acts] = np.clip(target, self._lo, self._hi)
        bad = mujoco.mjtWarning.mjWARN_BADQACC
        before = int(d.warning[bad].number)
        self.sim.step(self.frame_skip)
        reward, terminated, info = self.task_step()
        # MuJoCo resets the state itself when it diverges: end the episode instead
        unstable = int(d.warning[bad].number) > before or not np.all(np.isfinite(d.qpos))
        if unstable:
            terminated = True
        info = {**info, "time": float(d.time), "unstable": unstable}
        return self._obs(), float(reward), bool(terminated), False, info

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        if self.render_mode != "rgb_array":
            return None
        w, h = self._render_size
        r = self._renderer("render", w, h)
        if self._render_camera is not None:
            r.update_scene(self.data, camera=self._render_camera)
        else:
            cam = mujoco.MjvCamera()
            self.free_camera(cam)
            r.update_scene(self.data, camera=cam)
        return r.render()

    def close(self) -> None:
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    # -- helpers --------------------------------------------------------------------

    def _camera_id(self, role: str, what: str) -> int:
        """A camera by its role (``wrist``) or its model name."""
        cams = self.cameras()
        name = cams.get(role, role)
        i = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, name)
        if i < 0:
            valid = ", ".join(sorted(cams)) or "none"
            raise InputError(f"no camera '{role}'; the robot's: {valid}", element=what)
        return i

    def _fits(self, value: Any, what: str) -> tuple[int, int]:
        """An image size within the model's offscreen buffer (``<visual><global>``)."""
        w, h = _size(value, what)
        g = self.model.vis.global_
        if w > g.offwidth or h > g.offheight:
            limit = f"{g.offwidth} x {g.offheight}"
            raise InputError(f"{w} x {h} exceeds the offscreen buffer, {limit}", element=what)
        return w, h

    def _renderer(self, key: str, w: int, h: int) -> mujoco.Renderer:
        if key not in self._renderers:
            try:
                self._renderers[key] = mujoco.Renderer(self.model, height=h, width=w)
            except Exception as exc:  # MuJoCo raises FatalError, RuntimeError, ImportError
                gl = os.environ.get("MUJOCO_GL")
                raise RuntimeError(
                    f"cannot render (MUJOCO_GL={gl}): {exc}; set MUJOCO_GL=egl or osmesa, or "
                    "import urdf2mjcf.envs before mujoco (see urdf2mjcf/headless.py)"
                ) from exc
        return self._renderers[key]

    def _obs(self) -> Obs:
        obs = self.vectors()
        if self.camera_obs:
            w, h = self._camera_size
            r = self._renderer("camera", w, h)
            rgb, depth = render_rgbd(r, self.model, self.data, self.camera_id, self.noise)
            obs["rgb"] = rgb
            obs["depth"] = np.clip(depth, 0.0, self._far).astype(np.float32)
        return obs


def tilt(xmat: np.ndarray) -> float:
    """Angle (rad) between a body's z axis and the world's (from its rotation matrix)."""
    return math.acos(float(np.clip(xmat.reshape(3, 3)[2, 2], -1.0, 1.0)))
