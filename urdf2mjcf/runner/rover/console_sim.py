"""The simulation behind the console (``rover-drive --console``): a :class:`RoverSim`
stepped in its own thread at a pace, with each rover's wheel and arm commands and its
latched emergency stop. Everything is behind one lock: the web server's threads read
and command through the methods here, never the MuJoCo data directly."""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from ...errors import CommandError
from .odometry import true_pose, yaw_of
from .roles import Rover
from .sim import RoverSim

CHUNK_S = 0.02
"""Simulated seconds stepped per hold of the lock (the server waits at most this long)."""
LAG_MAX_S = 0.5
"""Wall-clock seconds the simulation may fall behind its pace before it gives up
catching up (a slow machine runs slower than asked, never in bursts)."""
STOPPED = 0.05
"""rad/s: a braking wheel slower than this is held where it stands."""


@dataclass
class _Driven:
    """One rover's commands as the console holds them."""

    rover: Rover
    joints: list[str]
    """Arm joint names without the rover's prefix (roles order)."""
    limits: np.ndarray
    """(n, 2): each arm joint's target range, rad."""
    cameras: dict[str, int]
    """Camera role -> MuJoCo camera id."""
    wheels: tuple[float, float] = (0.0, 0.0)
    estop: bool = False
    holding: bool = False
    z0: float = 0.0
    """Height of the base when the odometry started (planar odometry keeps it)."""


def _limits(m: mujoco.MjModel, rover: Rover) -> np.ndarray:
    """Each arm servo's target range: the joint's range where limited, narrowed by the
    actuator's control range where limited."""
    out = np.tile([-math.inf, math.inf], (len(rover.arm), 1))
    for k, act in enumerate(rover.arm):
        joint = int(m.actuator_trnid[act, 0])
        if m.jnt_limited[joint]:
            out[k] = m.jnt_range[joint]
        if m.actuator_ctrllimited[act]:
            lo, hi = m.actuator_ctrlrange[act]
            out[k] = max(out[k, 0], lo), min(out[k, 1], hi)
    return out


def _strip(name: str, prefix: str) -> str:
    return name[len(prefix) :] if prefix and name.startswith(prefix) else name


class ConsoleSim:
    """``sim``'s rovers ``names`` (default: all), stepped at ``pace`` simulated seconds per
    wall-clock second by :meth:`start` until :meth:`stop`."""

    def __init__(self, sim: RoverSim, names: list[str] | None = None, pace: float = 1.0):
        self.sim, self.pace = sim, pace
        self.lock = threading.Lock()
        self.rovers: dict[str, _Driven] = {}
        m = sim.m
        for name in names or list(sim.rovers):
            r = sim.rover(name)
            cams = {}
            for role, cam in r.spec.cameras.items():
                cid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, cam)
                if cid >= 0:
                    cams[role] = cid
            joints = [_strip(j, r.prefix) for j in r.spec.arm_joints]
            self.rovers[name] = _Driven(r, joints, _limits(m, r), cams)
        self._odometry_started()
        self.error: BaseException | None = None
        """What stopped the stepping thread, if anything did."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _odometry_started(self) -> None:
        for name, c in self.rovers.items():
            c.z0 = float(self.sim.odometry[name].fused[2])

    # -- the stepping thread ---------------------------------------------------------

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="rover-console-sim", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        try:
            dt = self.sim.dt
            chunk = max(1, int(round(CHUNK_S / dt)))
            wall0, sim0 = time.perf_counter(), float(self.sim.d.time)
            while not self._stop.is_set():
                now = time.perf_counter()
                due = sim0 + self.pace * (now - wall0) - float(self.sim.d.time)
                if due < dt:
                    self._stop.wait(min(0.05, (dt - due) / self.pace))
                    continue
                if due > LAG_MAX_S * self.pace:  # behind: run as fast as we can from here
                    wall0, sim0 = now, float(self.sim.d.time)
                with self.lock:
                    for _ in range(min(chunk, max(1, int(due / dt)))):
                        self._apply()
                        self.sim.step()
        except BaseException as exc:  # noqa: BLE001 - reported by the server and the command
            self.error = exc

    def _apply(self) -> None:
        """Every rover's wheel commands for the next step (under the lock)."""
        for c in self.rovers.values():
            left, right = (0.0, 0.0) if c.estop else c.wheels
            if left or right:
                c.holding = False
                self.sim.wheels(c.rover, left, right)
            elif c.holding or self.sim.wheel_speed(c.rover) < STOPPED:
                c.holding = True  # stopped: held where it stands, as on a slope
                self.sim.brake(c.rover)
            else:
                self.sim.wheels(c.rover, 0.0, 0.0)  # braking to a stop

    # -- commands ---------------------------------------------------------------------

    def driven(self, name: object) -> _Driven:
        if not isinstance(name, str) or name not in self.rovers:
            raise CommandError(f"no rover {name!r}; rovers: {', '.join(self.rovers)}", 404)
        return self.rovers[name]

    def command(
        self,
        name: str,
        wheels: tuple[float, float] | None = None,
        arm: dict[str, float] | None = None,
    ) -> dict:
        """Set ``name``'s wheel velocities (rad/s, left and right) and/or arm joint targets
        (rad), clipped to their ranges; what was set, and what was clipped. Refused (409)
        while the rover's emergency stop is latched."""
        c = self.driven(name)
        arm = arm or {}
        numbers = [*(wheels or ()), *arm.values()]
        if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in numbers):
            raise CommandError(f"{name}: a command is not a finite number")
        unknown = [j for j in arm if j not in c.joints]
        if unknown:
            raise CommandError(
                f"{name}: no arm joint {unknown[0]!r}; joints: {', '.join(c.joints)}"
            )
        out: dict = {"rover": name, "clipped": []}
        with self.lock:
            if c.estop:
                raise CommandError(f"{name}: emergency stop latched; POST /release first", 409)
            out["time"] = self._t()
            if wheels is not None:
                lo, hi = c.rover.wheel_ctrl
                set_to = tuple(float(np.clip(w, lo, hi)) for w in wheels)
                out["clipped"] += [
                    s for s, a, b in zip(("left", "right"), wheels, set_to, strict=True) if a != b
                ]
                c.wheels = (set_to[0], set_to[1])
                out["wheels"] = {"left": set_to[0], "right": set_to[1]}
            if arm:
                targets = self.sim.arm_targets[name]
                out["arm"] = {}
                for joint, value in arm.items():
                    k = c.joints.index(joint)
                    q = float(np.clip(value, *c.limits[k]))
                    if q != value:
                        out["clipped"].append(joint)
                    targets[k] = q
                    out["arm"][joint] = q
        return out

    def estop(self, names: list[str] | None = None) -> dict:
        """Latch the emergency stop of ``names`` (default: every rover): wheels brake to a
        stop and are held, the arm holds where it is (its targets set to its positions
        now). The rovers and the simulated time it latched at."""
        chosen = [self.driven(n) for n in names] if names else list(self.rovers.values())
        with self.lock:
            for c in chosen:
                if not c.estop:
                    c.estop, c.wheels = True, (0.0, 0.0)
                    arm = self.sim.arm_targets[c.rover.name]
                    arm[:] = self.sim.d.qpos[c.rover.arm_qpos]
            return {"estop": True, "rovers": [c.rover.name for c in chosen], "time": self._t()}

    def release(self, names: list[str] | None = None) -> dict:
        """Unlatch the emergency stop; the rover stays stopped until commanded."""
        chosen = [self.driven(n) for n in names] if names else list(self.rovers.values())
        with self.lock:
            for c in chosen:
                c.estop = False
            return {"estop": False, "rovers": [c.rover.name for c in chosen], "time": self._t()}

    def _t(self) -> float:
        return float(self.sim.d.time)

    # -- reading ----------------------------------------------------------------------

    def info(self) -> dict:
        """What does not change: each rover's cameras, arm joints with their target ranges,
        and the wheels' command range."""
        return {
            name: {
                "cameras": list(c.cameras),
                "arm": {j: [float(x) for x in c.limits[k]] for k, j in enumerate(c.joints)},
                "wheels": list(c.rover.wheel_ctrl),
            }
            for name, c in self.rovers.items()
        }

    def state(self) -> dict:
        """The simulation now: time and, per rover, its true pose, odometry, IMU, wheel
        speeds, arm positions, commands and emergency stop (``GET /state``)."""
        with self.lock:
            return {
                "time": float(self.sim.d.time),
                "pace": self.pace,
                "rovers": {name: self._rover_state(name, c) for name, c in self.rovers.items()},
                "warnings": self.sim.warnings(),
            }

    def _rover_state(self, name: str, c: _Driven) -> dict:
        d, r = self.sim.d, c.rover
        pose = true_pose(self.sim.m, d, r)
        odo = self.sim.odometry[name]
        q = d.sensordata[r.orientation : r.orientation + 4]

        def floats(a: np.ndarray) -> list[float]:
            return [float(v) for v in a]

        def joints(values: np.ndarray) -> dict[str, float]:
            return dict(zip(c.joints, floats(values), strict=True))

        return {
            "pose": {
                "xyz": [pose.x, pose.y, pose.z],
                "yaw": pose.yaw,
                "roll": pose.roll,
                "pitch": pose.pitch,
            },
            "odometry": {"xyz": [odo.x, odo.y, c.z0], "yaw": odo.yaw},
            "odometry_imu": {"xyz": floats(odo.fused), "yaw": yaw_of(q)},
            "imu": {
                "orientation": floats(q),
                "angular_velocity": floats(d.sensordata[r.gyro : r.gyro + 3]),
                "linear_acceleration": floats(d.sensordata[r.accel : r.accel + 3]),
            },
            "wheels": {
                "left": float(np.mean(d.sensordata[r.left_vel])),
                "right": float(np.mean(d.sensordata[r.right_vel])),
            },
            "arm": joints(d.qpos[r.arm_qpos]),
            "targets": {
                "wheels": {"left": c.wheels[0], "right": c.wheels[1]},
                "arm": joints(self.sim.arm_targets[name]),
            },
            "estop": c.estop,
        }

    def snapshot(self, into: np.ndarray) -> float:
        """The simulation's full physics state copied into ``into`` (size
        ``mj_stateSize(m, mjSTATE_FULLPHYSICS)``); its time."""
        with self.lock:
            mujoco.mj_getState(self.sim.m, self.sim.d, into, mujoco.mjtState.mjSTATE_FULLPHYSICS)
            return float(self.sim.d.time)
