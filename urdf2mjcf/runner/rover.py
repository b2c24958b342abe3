"""Drive the MIRA3D rovers of a built facility and measure how far the odometry drifts.

The runner knows only a compiled facility: ``scene.xml`` and ``facility.json``,
whose components with wheel roles (``facility/robots/mira3d_rover/config/roles.yaml``,
with each rover's prefix added by make-facility) are the rovers. It commands
them only through their actuators: wheel velocity servos (rad/s) and the arm's
position servos (rad), one step of MuJoCo at a time, every rover at once.

Odometry is what the real rover could know, integrated after every step:

* **wheel odometry**: differential drive from the wheel joint velocity sensors,
  the wheel radius and the track, on the plane: ``v = r (wl + wr) / 2``,
  ``yaw rate = r (wr - wl) / track`` (each side the mean of its two wheels);
* **wheel + IMU odometry**: the same wheel speed along the rover's x axis, turned
  into the world by the IMU's orientation (its ``framequat`` sensor: what an
  attitude filter gives), so it follows slopes and the gyro, not the scrubbing
  wheels, gives the heading.

Both are compared with the true pose of the rover's base body, which shows the
wheel slip of a skid-steer rover: turning in place, its wheels scrub sideways,
and the wheels' yaw estimate is far too large (the MIRA3D paper: "odometry data
... differ from reality very fast").

Tasks (``Straight``, ``Turn``, ``Hold``) are small closed loops on the odometry, as a
rover's own controller runs them: a trapezoidal speed profile in the odometry's
distance or heading. ``RoverSim.run`` runs one task per rover at the same time,
with an optional arm motion each (``ArmWave``).

Command line (``rover_drive_command``)::

    rover-drive build/mira3d-floor --distance 10 --speed 0.5 --report r.json
    rover-drive build/mira3d-pair --rover collector --distance 5 --turn 90 --arm
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import click
import mujoco
import numpy as np

from .load import LoadError, lookup, open_facility

HOLD_GAIN = 10.0
"""Wheel hold (brake): commanded wheel speed per radian of wheel drift, 1/s."""


class RoverError(LoadError):
    """The facility lacks something the rover runner needs."""


def _id(m: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    try:
        return lookup(m, kind, name)
    except LoadError as exc:
        raise RoverError(str(exc)) from None


def _sensor_adr(m: mujoco.MjModel, name: str) -> int:
    return int(m.sensor_adr[_id(m, mujoco.mjtObj.mjOBJ_SENSOR, name)])


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _rotation(quat: np.ndarray) -> np.ndarray:
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, np.asarray(quat, float))
    return r.reshape(3, 3)


@dataclass
class Rover:
    """One rover's roles as MuJoCo ids and addresses."""

    name: str
    prefix: str
    base: int
    """Body id of the base (its pose is the rover's pose)."""
    left: np.ndarray
    """Actuator ids of the left wheels."""
    right: np.ndarray
    left_vel: np.ndarray
    """sensordata addresses of the left wheels' jointvel sensors."""
    right_vel: np.ndarray
    radius: float
    track: float
    arm: np.ndarray
    """Actuator ids of the arm joints (roles order)."""
    arm_qpos: np.ndarray
    """qpos addresses of the arm joints."""
    accel: int
    gyro: int
    orientation: int
    """sensordata addresses of the IMU's accelerometer, gyro and framequat."""
    wheel_ctrl: tuple[float, float]
    """Command range of the wheel servos, rad/s."""
    wheel_qpos: np.ndarray
    """qpos addresses of the wheel joints (left, then right)."""
    roles: dict = field(default_factory=dict, repr=False)

    def bodies(self, m: mujoco.MjModel) -> set[int]:
        """Every body of this rover (the base's subtree)."""
        out = {self.base}
        for b in range(self.base + 1, m.nbody):
            if m.body_parentid[b] in out:
                out.add(b)
        return out


def find_rovers(m: mujoco.MjModel, manifest: Mapping) -> dict[str, Rover]:
    """The components of the manifest whose roles name wheels, by component name."""
    A = mujoco.mjtObj.mjOBJ_ACTUATOR
    out: dict[str, Rover] = {}
    for name, comp in sorted(manifest.get("components", {}).items()):
        roles = comp.get("roles") or {}
        if "wheel_actuators" not in roles:
            continue
        acts = roles["wheel_actuators"]
        left = np.array([_id(m, A, a) for a in acts["left"]])
        right = np.array([_id(m, A, a) for a in acts["right"]])
        lo = float(max(m.actuator_ctrlrange[np.r_[left, right], 0]))
        hi = float(min(m.actuator_ctrlrange[np.r_[left, right], 1]))
        imu = roles["imu"]
        out[name] = Rover(
            name=name,
            prefix=comp.get("prefix", ""),
            base=_id(m, mujoco.mjtObj.mjOBJ_BODY, roles["base"]),
            left=left,
            right=right,
            left_vel=np.array([_sensor_adr(m, s) for s in roles["wheel_sensors"]["left"]]),
            right_vel=np.array([_sensor_adr(m, s) for s in roles["wheel_sensors"]["right"]]),
            radius=float(roles["wheel_radius"]),
            track=float(roles["track"]),
            arm=np.array([_id(m, A, a) for a in roles["arm_actuators"]]),
            arm_qpos=np.array(
                [m.jnt_qposadr[_id(m, mujoco.mjtObj.mjOBJ_JOINT, j)] for j in roles["arm_joints"]]
            ),
            accel=_sensor_adr(m, imu["accelerometer"]),
            gyro=_sensor_adr(m, imu["gyro"]),
            orientation=_sensor_adr(m, imu["orientation"]),
            wheel_ctrl=(lo, hi),
            wheel_qpos=np.array(
                [
                    m.jnt_qposadr[_id(m, mujoco.mjtObj.mjOBJ_JOINT, j)]
                    for j in [*roles["wheels"]["left"], *roles["wheels"]["right"]]
                ]
            ),
            roles=roles,
        )
    return out


@dataclass
class Odometry:
    """Dead reckoning of one rover; starts at the true pose (the rover's map origin)."""

    x: float
    y: float
    yaw: float
    fused: np.ndarray
    """Wheel + IMU position (3D)."""
    distance: float = 0.0
    """Path length from the wheels (m, signed: backwards counts negative)."""
    turned: float = 0.0
    """Yaw turned according to the wheels (rad, unwrapped)."""
    turned_imu: float = 0.0
    """Yaw turned according to the IMU's orientation (rad, unwrapped)."""
    _imu_yaw: float = 0.0

    def update(self, rover: Rover, d: mujoco.MjData, dt: float) -> None:
        wl = float(np.mean(d.sensordata[rover.left_vel]))
        wr = float(np.mean(d.sensordata[rover.right_vel]))
        v = rover.radius * (wl + wr) / 2
        w = rover.radius * (wr - wl) / rover.track
        mid = self.yaw + w * dt / 2
        self.x += v * math.cos(mid) * dt
        self.y += v * math.sin(mid) * dt
        self.yaw = _wrap(self.yaw + w * dt)
        self.turned += w * dt
        self.distance += v * dt
        q = d.sensordata[rover.orientation : rover.orientation + 4]
        self.fused = self.fused + _rotation(q)[:, 0] * v * dt
        yaw = _yaw(q)
        self.turned_imu += _wrap(yaw - self._imu_yaw)
        self._imu_yaw = yaw


@dataclass
class Pose:
    x: float
    y: float
    z: float
    yaw: float
    roll: float
    pitch: float
    tilt: float
    """Angle between the rover's z axis and the world's (rad)."""


def true_pose(m: mujoco.MjModel, d: mujoco.MjData, rover: Rover) -> Pose:
    p = d.xpos[rover.base]
    r = d.xmat[rover.base].reshape(3, 3)
    yaw = math.atan2(r[1, 0], r[0, 0])
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    roll = math.atan2(r[2, 1], r[2, 2])
    tilt = math.acos(max(-1.0, min(1.0, r[2, 2])))
    return Pose(float(p[0]), float(p[1]), float(p[2]), yaw, roll, pitch, tilt)


# -- tasks: what each rover does, one command per step --------------------------------


class Task:
    """A closed loop on the odometry: ``command`` gives (v m/s, yaw rate rad/s) each step."""

    done: bool = False

    def start(self, sim: RoverSim, rover: Rover) -> None:
        pass

    def command(self, sim: RoverSim, rover: Rover) -> tuple[float | None, float]:
        """(v m/s, yaw rate rad/s); v None: brake."""
        raise NotImplementedError


def _profile(remaining: float, elapsed: float, top: float, accel: float) -> float:
    """Trapezoidal speed: ramp up at ``accel``, cruise at ``top``, brake to stop at the goal."""
    return max(0.0, min(top, accel * (elapsed + 0.05), math.sqrt(2 * accel * max(0.0, remaining))))


@dataclass
class Straight(Task):
    """Drive ``distance`` m (wheel odometry; negative: backwards), holding the start heading
    with the IMU (a rover's heading hold), then stop."""

    distance: float
    speed: float = 0.5
    accel: float = 0.5
    hold_heading: bool = True
    heading_gain: float = 1.5
    tolerance: float = 0.002

    def start(self, sim: RoverSim, rover: Rover) -> None:
        odo = sim.odometry[rover.name]
        self._d0, self._t0, self._h0 = odo.distance, sim.d.time, odo.turned_imu
        self._stopping = False
        self.done = False

    def command(self, sim: RoverSim, rover: Rover) -> tuple[float | None, float]:
        odo = sim.odometry[rover.name]
        sign = 1.0 if self.distance >= 0 else -1.0
        remaining = abs(self.distance) - sign * (odo.distance - self._d0)
        if remaining <= self.tolerance:
            self._stopping = True
        if self._stopping:
            self.done = sim.wheel_speed(rover) < 0.01
            return None, 0.0
        v = sign * _profile(remaining, sim.d.time - self._t0, self.speed, self.accel)
        w = -self.heading_gain * (odo.turned_imu - self._h0) if self.hold_heading else 0.0
        return v, w


@dataclass
class Turn(Task):
    """Turn in place by ``angle`` rad (positive: left), measured by the IMU (``imu=True``)
    or by the wheels, then stop."""

    angle: float
    rate: float = 0.5
    accel: float = 1.0
    imu: bool = True
    tolerance: float = math.radians(0.3)

    def start(self, sim: RoverSim, rover: Rover) -> None:
        odo = sim.odometry[rover.name]
        self._a0 = odo.turned_imu if self.imu else odo.turned
        self._t0 = sim.d.time
        self._stopping = False
        self.done = False

    def command(self, sim: RoverSim, rover: Rover) -> tuple[float | None, float]:
        odo = sim.odometry[rover.name]
        turned = (odo.turned_imu if self.imu else odo.turned) - self._a0
        sign = 1.0 if self.angle >= 0 else -1.0
        remaining = abs(self.angle) - sign * turned
        if remaining <= self.tolerance:
            self._stopping = True
        if self._stopping:
            self.done = sim.wheel_speed(rover) < 0.01
            return None, 0.0
        return 0.0, sign * _profile(remaining, sim.d.time - self._t0, self.rate, self.accel)


@dataclass
class Hold(Task):
    """Stand still for ``duration`` s."""

    duration: float = 1.0

    def start(self, sim: RoverSim, rover: Rover) -> None:
        self._t_end = sim.d.time + self.duration
        self.done = False

    def command(self, sim: RoverSim, rover: Rover) -> tuple[float | None, float]:
        self.done = sim.d.time >= self._t_end - 1e-9
        return None, 0.0


@dataclass
class ArmWave:
    """Swing one arm joint (index in the roles' arm_joints) about its home target:
    ``amplitude`` rad, ``period`` s, eased in over the first period."""

    joint: int = 0
    amplitude: float = 0.4
    period: float = 6.0

    def targets(self, home: np.ndarray, t: float) -> np.ndarray:
        q = home.copy()
        ease = min(1.0, t / self.period)
        q[self.joint] += ease * self.amplitude * math.sin(2 * math.pi * t / self.period)
        return q


# -- the simulation ---------------------------------------------------------------------


@dataclass
class TaskReport:
    """What a task did: commanded, estimated, true, and the errors (SI units, angles in deg)."""

    rover: str
    task: str
    commanded: float
    """m (Straight) or deg (Turn)."""
    duration: float
    odometry: dict
    fused: dict
    true: dict
    true_distance: float
    """Straight-line displacement of the base, 3D (m)."""
    true_path: float
    """Path length of the base, 3D (m)."""
    true_turn: float
    """deg, unwrapped."""
    odometry_position_error: float
    """|wheel odometry - true| in the plane (m)."""
    fused_position_error: float
    """|wheel + IMU odometry - true|, 3D (m)."""
    odometry_heading_error: float
    """deg."""
    slip: float
    """Straight: 1 - true path / wheel odometry path; turn: 1 - true turn / wheel odometry
    turn. The share of the wheels' motion that did not move the rover."""
    max_tilt: float
    max_roll: float
    max_pitch: float
    min_pitch: float
    tipped: bool
    arm_error: float
    """Largest arm tracking error while the task ran (rad)."""

    def summary(self) -> str:
        unit = "deg" if self.task == "turn" else "m"
        return (
            f"{self.rover}: {self.task} {self.commanded:g} {unit} in {self.duration:.1f} s; "
            f"true {self.true_distance:.3f} m moved, {self.true_turn:.1f} deg turned; "
            f"odometry error {self.odometry_position_error:.3f} m / "
            f"{self.odometry_heading_error:.1f} deg "
            f"(wheel + IMU {self.fused_position_error:.3f} m); "
            + (f"wheels counted {self.odometry['turn']:.0f} deg; " if self.task == "turn" else "")
            + f"slip {100 * self.slip:.1f} %; tilt up to {self.max_tilt:.1f} deg"
            + ("; TIPPED" if self.tipped else "")
        )


class _Track:
    """What one rover's task did, measured after every step: true path and turn, worst
    attitude, arm tracking; the odometry at the start."""

    def __init__(self, sim: RoverSim, rover: Rover):
        self.rover = rover
        odo = sim.odometry[rover.name]
        self.odo0 = (odo.distance, odo.turned, odo.turned_imu)
        self.start = sim.d.xpos[rover.base].copy()
        self.last = self.start.copy()
        self.last_yaw = true_pose(sim.m, sim.d, rover).yaw
        self.path = 0.0
        self.turned = 0.0
        self.tilt = self.roll = self.pitch = self.min_pitch = self.arm = 0.0

    def update(self, sim: RoverSim) -> None:
        r = self.rover
        pose = true_pose(sim.m, sim.d, r)
        self.tilt = max(self.tilt, pose.tilt)
        self.roll = max(self.roll, abs(pose.roll))
        self.pitch = max(self.pitch, pose.pitch)
        self.min_pitch = min(self.min_pitch, pose.pitch)
        err = np.abs(sim.d.qpos[r.arm_qpos] - sim.arm_targets[r.name])
        self.arm = max(self.arm, float(err.max()))
        p = sim.d.xpos[r.base]
        self.path += float(np.linalg.norm(p - self.last))
        self.last = p.copy()
        self.turned += _wrap(pose.yaw - self.last_yaw)
        self.last_yaw = pose.yaw

    def report(self, sim: RoverSim, task: Task, duration: float) -> TaskReport:
        r, odo = self.rover, sim.odometry[self.rover.name]
        pose = true_pose(sim.m, sim.d, r)
        p = sim.d.xpos[r.base]
        kind = type(task).__name__.lower()
        commanded = {
            "straight": getattr(task, "distance", 0.0),
            "turn": math.degrees(getattr(task, "angle", 0.0)),
        }.get(kind, 0.0)
        wheel_path = abs(odo.distance - self.odo0[0])
        wheel_turn = abs(odo.turned - self.odo0[1])
        if kind == "turn":  # the share of the wheels' rotation that did not turn the rover
            slip = 1.0 - abs(self.turned) / wheel_turn if wheel_turn > 1e-6 else 0.0
        else:  # the share of the wheels' travel that did not move the rover
            slip = 1.0 - self.path / wheel_path if wheel_path > 1e-6 else 0.0
        return TaskReport(
            rover=r.name,
            task=kind,
            commanded=commanded,
            duration=duration,
            odometry={
                "x": odo.x,
                "y": odo.y,
                "yaw": math.degrees(odo.yaw),
                "distance": odo.distance - self.odo0[0],
                "turn": math.degrees(odo.turned - self.odo0[1]),
            },
            fused={
                "x": float(odo.fused[0]),
                "y": float(odo.fused[1]),
                "z": float(odo.fused[2]),
                "turn": math.degrees(odo.turned_imu - self.odo0[2]),
            },
            true={
                "x": pose.x,
                "y": pose.y,
                "z": pose.z,
                "yaw": math.degrees(pose.yaw),
                "roll": math.degrees(pose.roll),
                "pitch": math.degrees(pose.pitch),
            },
            true_distance=float(np.linalg.norm(p - self.start)),
            true_path=self.path,
            true_turn=math.degrees(self.turned),
            odometry_position_error=math.hypot(odo.x - pose.x, odo.y - pose.y),
            fused_position_error=float(np.linalg.norm(odo.fused - p)),
            odometry_heading_error=math.degrees(abs(_wrap(odo.yaw - pose.yaw))),
            slip=slip,
            max_tilt=math.degrees(self.tilt),
            max_roll=math.degrees(self.roll),
            max_pitch=math.degrees(self.pitch),
            min_pitch=math.degrees(self.min_pitch),
            tipped=self.tilt > math.radians(45),
            arm_error=self.arm,
        )


class RoverSim:
    """A built facility with its rovers, stepped with wheel and arm commands."""

    def __init__(self, folder: str | Path, *, keyframe: str | None = "home"):
        self.folder, path, self.manifest, self.m, self.d = open_facility(folder, keyframe=keyframe)
        try:
            self.rovers = find_rovers(self.m, self.manifest)
        except (AttributeError, KeyError, TypeError, ValueError, IndexError) as exc:
            # a hand-edited facility.json: name the file, not a traceback
            raise RoverError(
                f"malformed wheel roles ({type(exc).__name__}: {exc})", file=path
            ) from None
        except LoadError as exc:
            raise RoverError(exc.detail, file=path, element="components.*.roles") from None
        if not self.rovers:
            raise RoverError(
                "the facility has no rover (no component with wheel roles); "
                "rover-drive needs a MIRA3D world (recipes/mira3d-*.yaml)",
                file=path,
                element="components",
            )
        self.home = {n: self.d.ctrl[r.arm].copy() for n, r in self.rovers.items()}
        self.arm_targets = {n: q.copy() for n, q in self.home.items()}
        self.odometry: dict[str, Odometry] = {}
        self._hold: dict[str, np.ndarray] = {}
        self.reset_odometry()

    @property
    def dt(self) -> float:
        return float(self.m.opt.timestep)

    def reset_odometry(self, name: str | None = None) -> None:
        """Odometry of ``name`` (or every rover) restarted at its true pose."""
        for n, r in self.rovers.items():
            if name is not None and n != name:
                continue
            pose = true_pose(self.m, self.d, r)
            q = self.d.sensordata[r.orientation : r.orientation + 4]
            self.odometry[n] = Odometry(
                pose.x, pose.y, pose.yaw, self.d.xpos[r.base].copy(), _imu_yaw=_yaw(q)
            )

    def rover(self, name: str | None = None) -> Rover:
        if name is None:
            if len(self.rovers) != 1:
                raise RoverError(f"name a rover: {', '.join(self.rovers)}")
            return next(iter(self.rovers.values()))
        if name not in self.rovers:
            raise RoverError(
                f"no rover '{name}'; rovers: {', '.join(self.rovers)}",
                file=self.folder / "facility.json",
                element="--rover",
            )
        return self.rovers[name]

    def drive(self, rover: Rover, v: float | None, w: float = 0.0) -> None:
        """Wheel velocity commands for a body speed ``v`` (m/s) and yaw rate ``w`` (rad/s);
        ``v=None``: brake (hold the wheels)."""
        if v is None:
            self.brake(rover)
            return
        self._hold.pop(rover.name, None)
        lo, hi = rover.wheel_ctrl
        left = (v - w * rover.track / 2) / rover.radius
        right = (v + w * rover.track / 2) / rover.radius
        # scale both sides together so a saturated command keeps its curvature
        scale = max(1.0, abs(left) / hi, abs(right) / hi)
        self.d.ctrl[rover.left] = np.clip(left / scale, lo, hi)
        self.d.ctrl[rover.right] = np.clip(right / scale, lo, hi)

    def brake(self, rover: Rover) -> None:
        """Hold the wheels where they are: a position loop through the velocity servos
        (``HOLD_GAIN`` rad/s per rad), as a motor controller holds a rover on a slope; a
        velocity servo alone lets it creep downhill."""
        if rover.name not in self._hold:
            self._hold[rover.name] = self.d.qpos[rover.wheel_qpos].copy()
        lo, hi = rover.wheel_ctrl
        err = self._hold[rover.name] - self.d.qpos[rover.wheel_qpos]
        n = len(rover.left)
        cmd = np.clip(HOLD_GAIN * err, lo, hi)
        self.d.ctrl[rover.left] = cmd[:n]
        self.d.ctrl[rover.right] = cmd[n:]

    def wheel_speed(self, rover: Rover) -> float:
        """Largest wheel speed (rad/s)."""
        return float(np.max(np.abs(self.d.sensordata[np.r_[rover.left_vel, rover.right_vel]])))

    def step(self, n: int = 1) -> None:
        """Step the physics ``n`` times with the current commands; update every odometry."""
        for _ in range(n):
            for name, r in self.rovers.items():
                self.d.ctrl[r.arm] = self.arm_targets[name]
            mujoco.mj_step(self.m, self.d)
            for name, r in self.rovers.items():
                self.odometry[name].update(r, self.d, self.dt)

    def settle(self, seconds: float = 1.0) -> None:
        """Stand still (wheels held, arm at its targets) for ``seconds``; odometry restarts."""
        for _ in range(int(round(seconds / self.dt))):
            for r in self.rovers.values():
                self.brake(r)
            self.step()
        self.reset_odometry()

    def warnings(self) -> dict[str, int]:
        return {
            mujoco.mjtWarning(i).name: int(w.number)
            for i, w in enumerate(self.d.warning)
            if w.number
        }

    def run(
        self,
        tasks: Mapping[str, Task],
        arm: Mapping[str, ArmWave] | None = None,
        timeout: float = 120.0,
        on_step: Callable[[RoverSim], None] | None = None,
    ) -> dict[str, TaskReport]:
        """Run one task per rover at the same time until all are done; return a report per
        task, taken when that task ended. Rovers without a task, and rovers whose task has
        ended, brake; an arm motion stops (back to the home targets) with its rover's task.
        ``on_step`` is called after every physics step."""
        arm = dict(arm or {})
        t0 = self.d.time
        for name, task in tasks.items():
            task.start(self, self.rover(name))
        track = {n: _Track(self, self.rovers[n]) for n in tasks}
        out: dict[str, TaskReport] = {}
        while len(out) < len(tasks):
            if self.d.time - t0 > timeout:
                late = ", ".join(n for n in tasks if n not in out)
                raise RoverError(f"{late}: not done after {timeout:g} s")
            for name, r in self.rovers.items():
                current = tasks.get(name)
                if current is None or name in out:
                    self.brake(r)
                    continue
                self.drive(r, *current.command(self, r))
                if name in arm:
                    self.arm_targets[name] = arm[name].targets(self.home[name], self.d.time - t0)
            self.step()
            for name, task in tasks.items():
                if name in out:
                    continue
                track[name].update(self)
                if task.done:
                    out[name] = track[name].report(self, task, self.d.time - t0)
                    self.arm_targets[name] = self.home[name].copy()
            if on_step is not None:
                on_step(self)
        return out

    def imu_up(self, rover: Rover) -> tuple[float, float]:
        """(magnitude, vertical component in the world) of the accelerometer reading, m/s^2."""
        a = self.d.sensordata[rover.accel : rover.accel + 3]
        q = self.d.sensordata[rover.orientation : rover.orientation + 4]
        world = _rotation(q) @ a
        return float(np.linalg.norm(a)), float(world[2])


# -- command line ------------------------------------------------------------------------


@click.command("rover-drive", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("scene", type=click.Path(exists=True, path_type=Path))
@click.option(
    "--rover",
    "names",
    multiple=True,
    help="rover (component) to drive, repeatable; default: every rover",
)
@click.option(
    "--distance",
    type=float,
    default=10.0,
    show_default=True,
    help="m to drive straight (wheel odometry; negative: backwards; 0: none)",
)
@click.option("--speed", type=float, default=0.5, show_default=True, help="m/s")
@click.option(
    "--turn",
    type=float,
    default=0.0,
    show_default=True,
    help="deg to turn in place after the drive (positive: left; 0: none)",
)
@click.option("--rate", type=float, default=30.0, show_default=True, help="deg/s while turning")
@click.option(
    "--arm/--no-arm",
    default=False,
    show_default=True,
    help="swing the shoulder pan joint +-0.4 rad while driving",
)
@click.option(
    "--settle",
    type=float,
    default=1.0,
    show_default=True,
    help="s standing still before the first command",
)
@click.option(
    "--report",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write the reports as JSON",
)
@click.option("--overwrite", is_flag=True, help="replace a --report file we did not write")
def rover_drive_command(
    scene: Path, names, distance, speed, turn, rate, arm, settle, report, overwrite
) -> None:
    """Drive the rovers of a built facility (SCENE: its folder or scene.xml) straight, then
    turn in place; print wheel odometry against the true pose."""
    from .. import output as out

    if report is not None:
        out.check_file(report, overwrite, "rover-drive")  # before driving, not after
    try:
        sim = RoverSim(scene)
        chosen = list(names) or list(sim.rovers)
        for n in chosen:
            sim.rover(n)
        sim.settle(settle)
        results: list[dict] = []
        plans: list[tuple[str, Callable[[], Task]]] = []
        if distance:
            plans.append(("straight", lambda: Straight(distance, speed=speed)))
        if turn:
            plans.append(("turn", lambda: Turn(math.radians(turn), rate=math.radians(rate))))
        for _, make in plans:
            waves = {n: ArmWave() for n in chosen} if arm else None
            for r in sim.run({n: make() for n in chosen}, arm=waves).values():
                click.echo(r.summary())
                results.append(asdict(r))
        warnings = sim.warnings()
    except RoverError as exc:
        raise click.ClickException(str(exc)) from None
    if report is not None:
        data = {"scene": str(scene), "tasks": results, "warnings": warnings}
        out.write_json(report, data, "rover-drive")
    if warnings:
        raise click.ClickException(f"MuJoCo warned while driving: {warnings}")
