"""The console's camera images: rendered on request by MuJoCo's offscreen renderer, from
a copy of the simulation's state, in one thread that owns the OpenGL context (a
context belongs to the thread that made it current). One image per camera and
simulated time: many requests between two steps render once."""

from __future__ import annotations

import io
import queue
import threading
from collections.abc import Callable, Mapping
from concurrent.futures import Future

import mujoco
import numpy as np

from ...bundle_manifest import Manifest
from ...errors import CameraUnavailable

WIDTH = 320
"""Pixels across every console image; the height keeps the camera's aspect."""
HEIGHT = 240
"""Pixels down where the facility gives no camera resolution."""
WAIT_S = 30.0
"""Longest a request waits for its image."""


def image_sizes(m: mujoco.MjModel, manifest: Manifest) -> dict[int, tuple[int, int]]:
    """Camera id -> (width, height) of its console image: ``WIDTH`` across, the aspect of
    its resolution in facility.json (its sensor's), else ``HEIGHT`` down."""
    aspect: dict[str, float] = {}
    for cam in manifest.cameras:
        w, h = cam.resolution
        if w > 0:  # else no resolution: the default size
            aspect[cam.name] = float(h) / float(w)
    out = {}
    for cid in range(m.ncam):
        a = aspect.get(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_CAMERA, cid) or "")
        h = int(round(WIDTH * a)) if a and 0.1 <= a <= 10 else HEIGHT
        out[cid] = (WIDTH, h)
    return out


def png_bytes(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, "PNG", compress_level=1)  # fast; the bytes are the same
    return buf.getvalue()


class Cameras:
    """Renders camera ``cid`` of ``m`` as a PNG (:meth:`png`); ``snapshot(into)`` copies
    the simulation's full physics state into ``into`` and returns its time."""

    def __init__(
        self,
        m: mujoco.MjModel,
        snapshot: Callable[[np.ndarray], float],
        sizes: Mapping[int, tuple[int, int]],
    ):
        self.m, self._snapshot, self.sizes = m, snapshot, dict(sizes)
        self._jobs: queue.Queue[tuple[int, Future] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="rover-console-camera", daemon=True)
        self._thread.start()

    def png(self, cid: int) -> tuple[float, bytes]:
        """(simulated time, PNG) of camera ``cid`` at the latest state."""
        if not self._thread.is_alive():
            raise CameraUnavailable("the renderer has stopped")
        done: Future[tuple[float, bytes]] = Future()
        self._jobs.put((cid, done))
        return done.result(timeout=WAIT_S)

    def close(self) -> None:
        self._jobs.put(None)
        self._thread.join(WAIT_S)

    def _run(self) -> None:
        sig = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.empty(mujoco.mj_stateSize(self.m, sig))
        d = mujoco.MjData(self.m)
        renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        shown = float("nan")  # the time whose state ``d`` holds
        cache: dict[int, tuple[float, bytes]] = {}
        failed: str | None = None
        try:
            while (job := self._jobs.get()) is not None:
                cid, done = job
                if failed is not None:
                    done.set_exception(CameraUnavailable(failed))
                    continue
                try:
                    t = self._snapshot(state)
                    if cid in cache and cache[cid][0] == t:
                        done.set_result(cache[cid])
                        continue
                    if t != shown:
                        mujoco.mj_setState(self.m, d, state, sig)
                        mujoco.mj_forward(self.m, d)
                        shown = t
                    w, h = self.sizes[cid]
                    if (w, h) not in renderers:
                        renderers[w, h] = mujoco.Renderer(self.m, h, w)
                    r = renderers[w, h]
                    r.update_scene(d, camera=cid)
                    cache[cid] = (t, png_bytes(r.render()))
                    done.set_result(cache[cid])
                except (ImportError, RuntimeError, ValueError) as exc:  # no OpenGL here
                    failed = f"no camera images: {type(exc).__name__}: {exc}"
                    done.set_exception(CameraUnavailable(failed))
                except Exception as exc:  # noqa: BLE001 - that request's error, not the thread's
                    done.set_exception(exc)
        finally:
            for r in renderers.values():
                r.close()
