"""What a task did: commanded, estimated and true motion, measured after every step."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .drift import DriftStart
from .odometry import true_pose, wrap_angle
from .roles import Rover
from .state import SimState
from .tasks import Task


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
    turn. The share of the wheels' motion that did not move the rover (hold: 0)."""
    max_tilt: float
    max_roll: float
    max_pitch: float
    min_pitch: float
    tipped: bool
    arm_error: float
    """Largest arm tracking error while the task ran (rad)."""
    drift: dict = field(default_factory=dict)
    """The odometry's drift this task added against the truth (``drift.DriftStart``)."""

    def summary(self) -> str:
        unit = "deg" if self.task == "turn" else "m"
        what = (
            f"hold {self.duration:.1f} s"
            if self.task == "hold"
            else f"{self.task} {self.commanded:g} {unit} in {self.duration:.1f} s"
        )
        return (
            f"{self.rover}: {what}; "
            f"true {self.true_distance:.3f} m moved, {self.true_turn:.1f} deg turned; "
            f"odometry error {self.odometry_position_error:.3f} m / "
            f"{self.odometry_heading_error:.1f} deg "
            f"(wheel + IMU {self.fused_position_error:.3f} m); "
            + (f"wheels counted {self.odometry['turn']:.0f} deg; " if self.task == "turn" else "")
            + (f"slip {100 * self.slip:.1f} %; " if self.task != "hold" else "")
            + f"tilt up to {self.max_tilt:.1f} deg"
            + ("; TIPPED" if self.tipped else "")
        )


class Track:
    """What one rover's task did, measured after every step: true path and turn, worst
    attitude, arm tracking; the odometry at the start."""

    def __init__(self, sim: SimState, rover: Rover):
        self.rover = rover
        odo = sim.odometry[rover.name]
        self.odo0 = (odo.distance, odo.turned, odo.turned_imu)
        self.drift = DriftStart(sim, rover)
        self.start = sim.d.xpos[rover.base].copy()
        self.last = self.start.copy()
        self.last_yaw = true_pose(sim.m, sim.d, rover).yaw
        self.path = 0.0
        self.turned = 0.0
        self.tilt = self.roll = self.pitch = self.min_pitch = self.arm = 0.0

    def update(self, sim: SimState) -> None:
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
        self.turned += wrap_angle(pose.yaw - self.last_yaw)
        self.last_yaw = pose.yaw

    def report(self, sim: SimState, task: Task, duration: float) -> TaskReport:
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
        if kind == "hold":  # braked: the wheels' creep is no drive to compare against
            slip = 0.0
        elif kind == "turn":  # the share of the wheels' rotation that did not turn the rover
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
            odometry_heading_error=math.degrees(abs(wrap_angle(odo.yaw - pose.yaw))),
            slip=slip,
            max_tilt=math.degrees(self.tilt),
            max_roll=math.degrees(self.roll),
            max_pitch=math.degrees(self.pitch),
            min_pitch=math.degrees(self.min_pitch),
            tipped=self.tilt > math.radians(45),
            arm_error=self.arm,
            drift=self.drift.figures(sim, r, self.path, self.turned),
        )
