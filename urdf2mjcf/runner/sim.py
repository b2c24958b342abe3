"""The one place the runtime steps MuJoCo: a loaded bundle's model and data, its
manifest and roles, the trial's sensor noise, its camera models and the callbacks
around every physics step.

The facility demo's controller, the rovers, the Gymnasium environments and the
recorder all step through a :class:`Sim`, so every one of them sees the same order
at every physics step:

1. ``control``: callbacks that write ``d.ctrl`` (a controller's servo targets, the
   rovers' arm targets), in the order they were added;
2. ``mujoco.mj_step``;
3. ``monitor``: callbacks that judge or estimate from the new state before anyone
   else reads it (the demo's contact judge, the rovers' odometry);
4. ``on_step``: the hooks (recorders, live views, a test's probe).

With no callbacks at all, ``step(n)`` is one ``mj_step(m, d, nstep=n)``: MuJoCo
loops the same ``mj_step`` itself, without returning to Python in between.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco

from ..bundle_manifest import Manifest, Roles
from .camera import CameraModel
from .load import open_facility
from .noise import SensorNoise

Callback = Callable[[], None]

DEFAULT_SIZE = (640, 480)
"""(width, height) of a camera whose model gives no resolution (as perception's)."""


def component_roles(manifest: Manifest) -> dict[str, Roles]:
    """Each component's ``roles`` from facility.json (components without roles left out);
    the roles say what the robot is, the code never does."""
    return {n: c.roles for n, c in manifest.components.items() if c.roles is not None}


class Sim:
    """A loaded facility stepped with its callbacks (see the module's docstring)."""

    def __init__(
        self,
        m: mujoco.MjModel,
        d: mujoco.MjData,
        manifest: Manifest,
        *,
        folder: Path | None = None,
        manifest_path: Path | None = None,
        seed: int | None = None,
        sensor_noise: bool = True,
    ) -> None:
        """``manifest``: the bundle's facility.json, read and checked (``bundle.open_bundle``),
        ``manifest_path`` its file (for errors naming it);
        ``seed``: the trial's noise seed (None: 0, as SensorNoise takes it);
        ``sensor_noise``: False gives ideal sensors (noise that passes data through)."""
        self.m, self.d = m, d
        self.manifest = manifest
        self.folder = folder
        self.manifest_path = manifest_path
        self.roles = component_roles(manifest)
        """Component -> its roles (facility.json ``components.*.roles``)."""
        self.sensor_noise = bool(sensor_noise)
        self.noise = self._noise(seed)
        self.cameras: dict[str, CameraModel] = {}
        """Model camera name -> its camera model at its own resolution (named ones)."""
        for c in range(m.ncam):
            if m.camera(c).name:
                self.cameras[m.camera(c).name] = self._camera_model(c, None)
        self.control: list[Callback] = []
        """Before every physics step: write ``d.ctrl``."""
        self.monitor: list[Callback] = []
        """Right after every physics step, before the hooks: judges and estimators."""
        self.on_step: list[Callback] = []
        """After the monitor: recorders, live views."""

    @classmethod
    def open(
        cls,
        folder: str | Path,
        *,
        seed: int | None = None,
        keyframe: str | None = "home",
        sensor_noise: bool = True,
    ) -> Sim:
        """A built facility (its folder or scene.xml) at its ``keyframe``, read only from
        the bundle (``load.open_facility``); a LoadError naming what is wrong."""
        folder, path, manifest, m, d = open_facility(folder, keyframe=keyframe)
        return cls(
            m, d, manifest, folder=folder, manifest_path=path, seed=seed, sensor_noise=sensor_noise
        )

    # -- time -------------------------------------------------------------------------

    @property
    def dt(self) -> float:
        return float(self.m.opt.timestep)

    @property
    def time(self) -> float:
        return float(self.d.time)

    def step(self, n: int = 1) -> None:
        """``n`` physics steps, each with its control, monitor and hooks in that order."""
        if n <= 0:
            return
        control, monitor, hooks = self.control, self.monitor, self.on_step
        if not (control or monitor or hooks):
            mujoco.mj_step(self.m, self.d, nstep=n)
            return
        m, d = self.m, self.d
        for _ in range(n):
            for f in control:
                f()
            mujoco.mj_step(m, d)
            for f in monitor:
                f()
            for f in hooks:
                f()

    def reset(self, keyframe: int | str | None = None, *, forward: bool = True) -> None:
        """Back to ``keyframe`` (its id or name; None: the model's defaults); ``forward``
        False leaves ``mj_forward`` to a caller that changes the state first."""
        m, d = self.m, self.d
        key = keyframe
        if isinstance(key, str):
            key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, key)
            if key < 0:
                raise KeyError(f"the model has no keyframe '{keyframe}'")
        if key is None:
            mujoco.mj_resetData(m, d)
        else:
            mujoco.mj_resetDataKeyframe(m, d, int(key))
        if forward:
            mujoco.mj_forward(m, d)

    # -- sensors ----------------------------------------------------------------------

    def reseed(self, seed: int | None) -> SensorNoise:
        """New noise for the trial ``seed`` (every channel's stream restarted)."""
        self.noise = self._noise(seed)
        return self.noise

    def _noise(self, seed: int | None) -> SensorNoise:
        return SensorNoise.from_manifest(self.manifest if self.sensor_noise else None, seed)

    def camera(self, name: str, size: tuple[int, int] | None = None) -> CameraModel:
        """The camera model of the model camera ``name`` rendering ``size`` (width,
        height; None: the camera's own resolution); KeyError for an unknown name."""
        if name not in self.cameras:
            raise KeyError(f"the model has no camera '{name}'")
        if size is None:
            return self.cameras[name]
        return self._camera_model(mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_CAMERA, name), size)

    def _camera_model(self, cam: int, size: tuple[int, int] | None) -> CameraModel:
        if size is None:
            w, h = (int(v) for v in self.m.cam_resolution[cam])
            size = (w, h) if w > 0 and h > 0 else DEFAULT_SIZE
        return CameraModel.of(self.m, cam, int(size[0]), int(size[1]))
