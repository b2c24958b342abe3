"""The logistics demo: steps from a waypoints file, executed and judged one by one.

Step kinds (``kind:`` in the file) are the registered classes of
:mod:`urdf2mjcf.runner.steps`, each with its schema, its check against the facility
and what it does; the robot's shape (its joints, arm joints, speed limits) comes
from the bundle's roles (``facility.json``).

A mockup's pose is never read from the model: a frame or hinge on a component
(a body of the manifest's components other than the robot) before a ``localize``
step has estimated that component fails the step. The cameras see through the
trial's sensor noise (runner/noise.py, seeded by the facility's seed; the lights
scaled once per trial) unless the Demo is made with ``noise=False``. The demo steps
through one :class:`~.sim.Sim` (``Demo.sim``), its controller's.

Every step may give ``contacts`` (intended pairs of body-name globs), ``carried``
(the bag is in the hand: its contacts with the environment count too) and ``settle``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..bundle_manifest import Pose
from ..errors import PlanningError
from . import ik, localize, perception, plan
from .control import Controller
from .judge import ContactJudge, Verdict, stowed
from .load import DEMO_ROBOT, Facility, Robot
from .noise import SensorNoise
from .sim import Sim
from .steps import STEPS, StepError
from .task_kinds import POSE
from .waypoints import check_names, read_waypoints


@dataclass
class StepResult:
    name: str
    kind: str
    ok: bool
    duration: float  # simulated seconds
    contacts: list[str] = field(default_factory=list)
    message: str = ""
    # a planned joint move: planner ("straight" or "RRTstar"), iterations (RRT*'s),
    # planning_time_s (wall), path_length (joint space, rad and m mixed), duration_s
    plan: dict | None = None


# Joint acceleration limits for planned moves (rail, lift, arm; m/s^2, rad/s^2): ours,
# well inside what the servos follow without lag.
AMAX = (0.3, 0.5, 1.5, 1.5, 2.0, 3.0, 3.0, 3.0)


def planner_amax(robot: Robot) -> np.ndarray:
    """The planned moves' acceleration limit per joint: :data:`AMAX`, lowered to what the
    robot's description states (URDF 1.2, ``Robot.amax``) where it states less. Its jerk
    limits are not used: TOPP-RA times a path under speed and acceleration limits only."""
    ours = np.broadcast_to(np.asarray(AMAX, float), (len(robot.joints),)).copy()
    for i, limit in enumerate(robot.amax):
        if limit is not None:
            ours[i] = min(ours[i], limit)
    return ours


@dataclass
class DemoResult:
    ok: bool
    steps: list[StepResult]
    verdict: dict | None
    sim_time: float
    wall_time: float
    failed_step: str | None = None
    message: str = ""
    handle: dict | None = None
    # component -> {"position_error_m", "yaw_error_deg"}: each estimate minus the truth
    # (for the record only: the one place the runner reads a mockup's pose)
    localization: dict | None = None

    def to_json(self) -> dict:
        out = asdict(self)
        out["real_time_factor"] = self.sim_time / self.wall_time if self.wall_time else None
        return out


def load_waypoints(path: str | Path) -> dict:
    """The waypoints file, checked (an error names the file and the element)."""
    return read_waypoints(path)


def _pose(pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, pos
    return t


def _yaw(rot: np.ndarray) -> float:
    return math.atan2(float(rot[1, 0]), float(rot[0, 0]))


def _rotation(z: np.ndarray, x: np.ndarray) -> np.ndarray:
    z = np.asarray(z, float) / np.linalg.norm(z)
    x = np.asarray(x, float) - np.dot(x, z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


class Demo:
    def __init__(
        self,
        fac: Facility,
        spec: dict,
        *,
        frames: Path | None = None,
        log: Callable[[str], None] = print,
        noise: bool | SensorNoise = True,
    ) -> None:
        """``noise``: True, the sensor noise the facility's recipe asks for (facility.json
        ``noise``), seeded by its ``seed`` (0 without one); False, ideal sensors."""
        self.fac, self.spec = fac, spec
        self.m, self.d, self.r = fac.model, fac.data, fac.robot
        rs = spec.get("robot", {})
        # the file's speed limits, else the robot's own from its roles
        self.vmax = np.array(rs.get("vmax", self.r.vmax), float)
        self.weights = np.array(rs.get("ik_weights", [1.0] * len(self.r.joints)), float)
        self.site = self.r.sites[rs.get("site", "grasp")]
        self.bag = spec["bag"]
        self.judge = ContactJudge(fac, self.bag["body"])
        # the one Sim this demo steps through: the trial's noise seeded by the facility's seed
        self.sim = Sim(
            fac.model,
            fac.data,
            fac.manifest,
            folder=fac.folder,
            seed=fac.manifest.seed or 0,
            sensor_noise=bool(noise),
        )
        self.ctl = Controller(fac, self.vmax, monitor=self.judge, sim=self.sim)
        self.global_contacts = spec.get("contacts", [])
        self.handle: tuple[np.ndarray, np.ndarray] | None = None
        self.handle_info: dict | None = None
        self.frames = Path(frames) if frames else None
        self.log = log
        self._planner: plan.JointPlanner | None = None
        self.last_plan: dict | None = None
        self._cams: dict[int, perception.Camera] = {}
        if isinstance(noise, SensorNoise):
            self.sim.noise = noise
        self.noise: SensorNoise | None = self.sim.noise if noise else None
        if self.noise is not None:
            self.noise.light(self.m)  # this trial's lighting, once, before any rendering
        # component -> its pose estimated from its tags (a localize step)
        self.estimates: dict[str, localize.Estimate] = {}
        self._component_of: dict[int, str] = {}
        self._roots: dict[str, int] = {}
        for comp in sorted(fac.manifest.components):
            if comp == DEMO_ROBOT:
                continue
            bodies = fac.component_bodies(comp)
            for b in bodies:
                self._component_of[b] = comp
            roots = [b for b in sorted(bodies) if self.m.body_parentid[b] not in bodies]
            if roots:
                self._roots[comp] = roots[0]
        # The description's kinematics (joints at their reference): where a component's
        # bodies lie relative to its root is design knowledge; where the root lies is not.
        self._design = mujoco.MjData(self.m)
        mujoco.mj_kinematics(self.m, self._design)
        self._scene_renderer: mujoco.Renderer | None = None
        self._ik = ik.ArmIK(
            self.m,
            self.site,
            self.r.qpos,
            self.r.dofs,
            self.r.lower,
            self.r.upper,
            weights=self.weights,
        )

    # ------------------------------------------------------------ helpers
    def camera(self, role: str) -> perception.Camera:
        cam = self.r.cameras[role]
        if cam not in self._cams:
            size = self.spec.get("perception", {}).get("size")
            self._cams[cam] = perception.Camera(
                self.m, cam, tuple(size) if size else None, noise=self.noise
            )
        return self._cams[cam]

    def in_component(self, body: int) -> np.ndarray:
        """(4, 4) pose of ``body`` in its component's frame (its root body's), from the
        description: the two bodies' poses with every joint at its reference."""
        root = self._roots[self._component_of[body]]
        d = self._design
        t_root = _pose(d.xpos[root], d.xmat[root].reshape(3, 3))
        return np.linalg.inv(t_root) @ _pose(d.xpos[body], d.xmat[body].reshape(3, 3))

    def body_pose(self, body: int) -> np.ndarray:
        """(4, 4) world pose of ``body`` as the robot knows it: a body of a component is
        the component's estimate x its design pose in the component (a StepError when
        no localize step has estimated it: never the model's pose); the robot's own
        bodies, and the facility's fixed structure, from the model."""
        comp = self._component_of.get(body)
        if comp is None:
            return _pose(self.d.xpos[body], self.d.xmat[body].reshape(3, 3))
        est = self.estimates.get(comp)
        if est is None:
            raise StepError(
                f"'{self.m.body(body).name}' is on the {comp}, whose pose has not been "
                f"estimated: a 'localize' step must see its tags first"
            )
        return est.matrix() @ self.in_component(body)

    def frame(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Origin and axes of a frame of the waypoints file."""
        if name == "world":
            return np.zeros(3), np.eye(3)
        if name == "handle":
            if self.handle is None:
                raise StepError("no handle frame: the 'look' step has not found the strap")
            return self.handle
        t = self.body_pose(self.fac.body(name))
        return t[:3, 3].copy(), t[:3, :3].copy()

    def localization(self) -> dict[str, dict[str, float]]:
        """Each estimate minus the truth: the one place the runner reads a mockup's
        pose from the model (its root body's: the component's frame), for the record."""
        truth = {}
        for comp in self.estimates:
            b = self._roots[comp]
            rot = self.d.xmat[b].reshape(3, 3)
            x, y, z = (float(v) for v in self.d.xpos[b])
            truth[comp] = Pose((x, y, z), _yaw(rot))
        return localize.localization_record(self.estimates, truth)

    def close(self) -> None:
        for c in self._cams.values():
            c.close()
        if self._scene_renderer is not None:
            self._scene_renderer.close()

    def snapshot(self, name: str, extra: np.ndarray | None = None) -> None:
        if self.frames is None:
            return
        from PIL import Image

        self.frames.mkdir(parents=True, exist_ok=True)
        view = self.spec.get("view", {})
        if self._scene_renderer is None:
            self._scene_renderer = mujoco.Renderer(self.m, 480, 640)
        cam = mujoco.MjvCamera()
        cam.lookat[:] = view.get("lookat", [0.4, 0.7, 0.8])
        cam.distance = view.get("distance", 3.6)
        cam.azimuth = view.get("azimuth", -120)
        cam.elevation = view.get("elevation", -30)
        self._scene_renderer.update_scene(self.d, cam)
        Image.fromarray(self._scene_renderer.render()).save(self.frames / f"{name}.png")
        if extra is not None:
            Image.fromarray(extra).save(self.frames / f"{name}_wrist.png")

    def ik(
        self, pos: np.ndarray, rot: np.ndarray | None, q0: np.ndarray | None = None
    ) -> np.ndarray:
        res = self._ik.solve(self.d, pos, rot, q0=q0)
        if not res.ok:
            # near a joint limit the damping and posture tasks slow the last 0.1 mm down:
            # go on from where it stopped
            # (at the edge of the reach, stretched out, it creeps: within a millimetre and
            # half a degree is what the servos hold anyway, and the bin has centimetres)
            res = self._ik.solve(
                self.d, pos, rot, q0=res.q, max_iter=1000, tol_pos=1e-3, tol_rot=0.009
            )
        if not res.ok:
            raise StepError(
                f"no IK solution for the {self.m.site(self.site).name} pose at "
                f"{np.round(pos, 3).tolist()} (left {1000 * res.pos_err:.1f} mm, "
                f"{math.degrees(res.rot_err):.1f} deg)"
            )
        return res.q

    def cartesian_path(
        self, poses: list[tuple[np.ndarray, np.ndarray]], q0: np.ndarray, spacing: float = 0.01
    ) -> np.ndarray:
        """Dense IK along straight segments between poses (position and rotation)."""
        path: list[np.ndarray] = [q0]
        p_prev, R_prev = ik.site_pose(self.m, self.d, self.site, q0, self.r.qpos)
        q = q0
        for p, R in poses:
            dist = np.linalg.norm(p - p_prev)
            ang = np.linalg.norm(ik.rot_err(R, R_prev))
            n = max(1, int(math.ceil(max(dist / spacing, ang / math.radians(2)))))
            turn = Slerp([0.0, 1.0], Rotation.from_matrix([R_prev, R]))
            for k in range(1, n + 1):
                s = k / n
                q = self.ik(p_prev + s * (p - p_prev), turn(s).as_matrix(), q0=q)
                path.append(q)
            p_prev, R_prev = p, R
        joints = np.array(path)
        jump = np.abs(np.diff(joints, axis=0)).max(axis=0) if len(joints) > 1 else 0
        if np.any(jump > 0.5):
            raise StepError("the Cartesian path jumps in joint space (a branch change of the IK)")
        return joints

    def planned_move(self, q: np.ndarray, carried: bool) -> None:
        """A collision-free, timed joint move to ``q`` (a carried bag held by the hand)."""
        if self._planner is None:
            names = [self.m.body(b).name for b in range(self.m.nbody)]
            allowed = [  # the carriage runs 4.5 mm beside the base's cable tray, by design
                (names.index(a), names.index(b))
                for a, b in (
                    ("rail_base_link", "rail_carriage_link"),
                    ("rail_base_link", "carriage_link"),
                )
                if a in names and b in names
            ]
            self._planner = plan.JointPlanner(
                self.m,
                [int(self.m.dof_jntid[d]) for d in self.r.dofs],
                self.vmax,
                planner_amax(self.r),
                allowed_pairs=allowed,
                seed=0,
                link_of_geom=self.fac.link_of_geom,
            )
        self._planner.vmax = np.asarray(self.ctl.vmax, float).copy()
        start = self.d.qpos.copy()
        start[self.r.qpos] = self.ctl.target  # from where the servos are told to be
        bag = self.fac.body(self.bag["body"]) if carried else None
        try:
            move = self._planner.plan(start, q, attached_body=bag)
        except PlanningError as exc:
            raise StepError(f"no collision-free joint move: {exc}") from None
        duration = self.ctl.play(move.times, move.q)
        self.last_plan = {
            "planner": move.planner,
            "iterations": move.iterations,
            "planning_time_s": round(move.planning_time_s, 4),
            "path_length": round(move.path_length, 4),
            "duration_s": round(duration, 3),
        }

    # ------------------------------------------------------------ steps
    def run_step(self, step: dict) -> None:
        kind = STEPS[step["kind"]]
        self.ctl.vmax = self.vmax * float(step.get("speed", 1.0))
        kind.run(self, step)
        if step.get("settle", kind.settles):
            self.ctl.settle(timeout=step.get("settle_timeout", 1.5))

    def _moved(self, comp: str) -> np.ndarray:
        """(4, 4) how far ``comp`` stands from where the file's ``nominal`` placed it
        when its poses were taught: its estimated pose x the nominal one's inverse."""
        est = self.estimates.get(comp)
        if est is None:
            raise StepError(
                f"the pose was taught relative to the {comp}, whose pose has not been "
                f"estimated: a 'localize' step must see its tags first"
            )
        nominal = self.spec["nominal"][comp]
        c, s = math.cos(nominal["yaw"]), math.sin(nominal["yaw"])
        yaw = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return est.matrix() @ np.linalg.inv(_pose(np.asarray(nominal["xyz"], float), yaw))

    def carried_along(self, q: np.ndarray, comp: str) -> np.ndarray:
        """The joints that put the grasp site where ``q`` put it when ``comp`` stood at
        its nominal place, now that it stands where its estimate says."""
        moved = self._moved(comp)
        p, R = ik.site_pose(self.m, self.d, self.site, q, self.r.qpos)
        return self.ik(moved[:3, :3] @ p + moved[:3, 3], moved[:3, :3] @ R, q0=q)

    def target_pose(self, step: dict) -> tuple[np.ndarray, np.ndarray]:
        origin, R0 = self.frame(step.get("frame", POSE.default("frame")))
        pos = origin + R0 @ np.asarray(step["position"], float)
        _, Rcur = ik.site_pose(self.m, self.d, self.site, self.ctl.target, self.r.qpos)
        if "orientation_xyzw" in step:
            R = R0 @ Rotation.from_quat(step["orientation_xyzw"]).as_matrix()
        elif "z" in step:
            R = R0 @ _rotation(step["z"], step["x"])
            if step.get("x_sign_free") and R[:, 0] @ Rcur[:, 0] < 0:
                R = R @ np.diag([-1.0, -1.0, 1.0])
        else:
            R = Rcur
        if "relative_to" in step:  # a world pose taught with the mockup at its nominal place
            moved = self._moved(step["relative_to"])
            pos, R = moved[:3, :3] @ pos + moved[:3, 3], moved[:3, :3] @ R
        if "site" in step:
            # a pose of another site, rigid with the grasp site: the grasp site's pose
            # that puts it there
            s, g = self.r.sites[step["site"]], self.site
            rs = self.d.site_xmat[s].reshape(3, 3)
            rg = self.d.site_xmat[g].reshape(3, 3)
            p_rel = rs.T @ (self.d.site_xpos[g] - self.d.site_xpos[s])
            pos, R = pos + R @ p_rel, R @ (rs.T @ rg)
        return pos, R

    # ------------------------------------------------------------ run
    def run(self) -> DemoResult:
        t0 = time.perf_counter()
        sim0 = self.d.time
        results: list[StepResult] = []
        failed = None
        message = ""
        for step in self.spec["steps"]:
            name = step["name"]
            self.judge.begin(
                self.global_contacts + step.get("contacts", []), step.get("carried", False)
            )
            ts = self.d.time
            ok, msg = True, ""
            self.last_plan = None
            try:
                self.run_step(step)
            except StepError as exc:
                ok, msg = False, str(exc)
            bad = self.judge.message()
            if ok and bad:
                ok, msg = False, bad
            if ok and "check" in step:
                msg = self._check(step["check"])
                ok = not msg
            contacts = sorted(f"{a}~{b}" for a, b in self.judge.log.intended)
            res = StepResult(
                name, step["kind"], ok, round(self.d.time - ts, 3), contacts, msg, self.last_plan
            )
            results.append(res)
            self.log(
                f"{name:<24} {'ok' if ok else 'FAIL':<5} {res.duration:7.2f} s  "
                f"{', '.join(contacts) if contacts else '-'}" + (f"\n  {msg}" if msg else "")
            )
            if step.get("snapshot"):
                self.snapshot(name)
            if not ok:
                failed, message = name, msg
                self.snapshot(f"failed_{name}")
                break
        verdict = None
        if failed is None:
            self.ctl.wait(self.spec.get("final_wait", 1.5))
            v = self.success_check()
            verdict = asdict(v)
            message = v.message
            if not v.ok:
                failed = "success check"
            self.snapshot("final")
        return DemoResult(
            failed is None,
            results,
            verdict,
            round(self.d.time - sim0, 3),
            round(time.perf_counter() - t0, 3),
            failed,
            message,
            self.handle_info,
            self.localization() if self.estimates else None,
        )

    def success_check(self) -> Verdict:
        """The demo's verdict on the state it is in: the bag inside the stowage volume,
        upright and still."""
        st = self.spec["stowage"]
        return stowed(self.fac, self.bag["body"], self.bag["geom"], st["body"], tuple(st["inside"]))

    def _check(self, check: dict) -> str:
        if "joint_above_deg" in check:
            name, limit = check["joint_above_deg"]
            j = self.fac.joint(name)
            ang = math.degrees(self.d.qpos[self.m.jnt_qposadr[j]])
            if ang < limit:
                return f"'{name}' is at {ang:.1f} deg, not above {limit} deg"
        if "bag_lifted" in check:
            b = self.fac.body(self.bag["body"])
            if self.d.xpos[b][2] < check["bag_lifted"]:
                return (
                    f"the CTB is not in the gripper (its bottom is {self.d.xpos[b][2]:.3f} m "
                    f"above the floor, expected > {check['bag_lifted']})"
                )
        return ""


def run_demo(
    scene: str | Path,
    waypoints: str | Path,
    *,
    frames: Path | None = None,
    log: Callable[[str], None] = print,
    noise: bool = True,
) -> DemoResult:
    """The demo of ``waypoints`` on the facility at ``scene``; ``noise``: the recipe's
    sensor noise (False: ideal sensors)."""
    from .load import load

    spec = load_waypoints(waypoints)
    fac = load(scene)
    check_names(spec, Path(waypoints), fac)
    demo = Demo(fac, spec, frames=frames, log=log, noise=noise)
    try:
        return demo.run()
    finally:
        demo.close()
