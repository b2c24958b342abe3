"""The demo's step kinds: one registered class each, with its schema, its check
against the loaded facility, and what it does.

A waypoints file names each step's ``kind``; :data:`STEPS` maps the kind to its
class. ``keys`` and ``required`` are the step's schema (checked, with the keys
every step shares, before anything moves: :mod:`urdf2mjcf.runner.waypoints`);
:meth:`Step.check` checks the step against the facility (names, vector lengths);
:meth:`Step.run` executes it on the running demo (:class:`urdf2mjcf.runner.demo.Demo`,
the simulation with its controller, planner, cameras and estimates).

``joints``   ``q`` (all the robot's joints) or ``arm`` (its arm joints), or ``set``
             {joint: value}; with ``relative_to`` (a component the file's
             ``nominal`` places: where it stood when the pose was taught) the grasp
             site's pose at those joints is carried along with the component's
             estimated pose (IK from them); all planned collision-free
             (runner/plan.py: OMPL's RRT* with MuJoCo as the collision checker,
             TOPP-RA timing), as the paper's MoveIt stack did; a carried bag moves
             with the hand and may touch only it
``pose``     the grasp site to ``position`` with tool axes ``z``/``x`` (or the rotation
             ``orientation_xyzw``, a quaternion x, y, z, w) given in ``frame``
             (``world``, a body of the model, or ``handle``: the perceived strap);
             ``site`` names another of the robot's sites (``tool``: tool0, as
             published poses give it); ``relative_to``: as for ``joints``, a world
             pose carried along; a straight Cartesian line through dense IK, or with
             ``joint_space`` the IK solution reached by a planned joint move
``relative`` a straight move by ``tool`` (tool-frame offset) or ``world`` offset
``hinge``    the arc around ``joint``: ``steps`` x ``step_deg``, orientation held or not
``gripper``  ``open`` / ``close`` (or an opening in m)
``look``     render the wrist camera, find the red handle, set the ``handle`` frame
``localize`` render ``camera`` (wrist or lift), find ``component``'s AprilTags
             (runner/localize.py) and keep its estimated pose: from then on every
             frame and hinge of that component is the estimate x the body's pose
             relative to the component's root in the description
``wait``     ``seconds``
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import mujoco
import numpy as np

from ..errors import StepError
from . import ik, localize, perception
from .checks import (
    Check,
    Waypoints,
)
from .control import path_duration
from .hinge import arc, hinge_axis, turned
from .load import DEMO_ROBOT
from .task_kinds import GRIPPER, HINGE, JOINTS, LOCALIZE, LOOK, POSE, RELATIVE, WAIT, TaskKind


def _keys(kind: TaskKind) -> dict[str, Check]:
    """A step's schema, read from its declaration (:mod:`.task_kinds`)."""
    return {p.name: p.check for p in kind.params}


def _required(kind: TaskKind) -> tuple[str, ...]:
    return tuple(p.name for p in kind.params if p.required)


def _value(kind: TaskKind, step: dict, key: str) -> Any:
    """``step``'s value of ``key``, or the declared default."""
    return step[key] if key in step else kind.default(key)


class Step:
    """A kind of demo step."""

    kind: ClassVar[str]
    keys: ClassVar[dict[str, Check]] = {}
    """The step's own keys (beside the ones every step has) and their checks."""
    required: ClassVar[tuple[str, ...]] = ()
    settles: ClassVar[bool] = True
    """Whether the robot settles after it unless the step says (``settle``)."""

    def check(self, step: dict, at: str, fac: Any, w: Waypoints) -> None:
        """Raise ``w.fail`` where the step names what the facility ``fac`` lacks."""

    def run(self, demo: Any, step: dict) -> None:
        raise NotImplementedError


STEPS: dict[str, Step] = {}
"""Kind -> its step, in the order the docs list them."""


def register(cls: type[Step]) -> type[Step]:
    STEPS[cls.kind] = cls()
    return cls


def _length(value: list, want: int, where: str, w: Waypoints) -> None:
    if len(value) != want:
        raise w.fail(where, f"has {len(value)} values; the robot needs {want}")


def _camera(step: dict, at: str, fac: Any, w: Waypoints) -> None:
    camera = step.get("camera", LOOK.default("camera"))
    if camera not in fac.robot.cameras:
        roles = ", ".join(fac.robot.cameras)
        raise w.fail(f"{at}.camera", f"'{camera}' is not a camera role; roles: {roles}")


@register
class Joints(Step):
    kind = "joints"
    keys = _keys(JOINTS)
    required = _required(JOINTS)

    def check(self, step: dict, at: str, fac: Any, w: Waypoints) -> None:
        robot = fac.robot
        for key, want in (("q", len(robot.joints)), ("arm", len(robot.arm))):
            if key in step:
                _length(step[key], want, f"{at}.{key}", w)
        for joint in step.get("set", {}):
            if joint not in robot.joint_names:
                valid = ", ".join(robot.joint_names)
                message = f"'{joint}' is not a joint of the robot; joints: {valid}"
                raise w.fail(f"{at}.set.{joint}", message)

    def run(self, demo: Any, step: dict) -> None:
        q = demo.ctl.target.copy()
        if "q" in step:
            q = np.array(step["q"], float)
        if "arm" in step:
            q[demo.r.arm] = step["arm"]
        for joint, value in step.get("set", {}).items():
            q[demo.r.joint_names.index(joint)] = value
        if "relative_to" in step:
            q = demo.carried_along(q, step["relative_to"])
        demo.planned_move(q, step.get("carried", False))


@register
class Pose(Step):
    kind = "pose"
    keys = _keys(POSE)
    required = _required(POSE)

    def check(self, step: dict, at: str, fac: Any, w: Waypoints) -> None:
        if "seed" in step:
            _length(step["seed"], len(fac.robot.joints), f"{at}.seed", w)

    def run(self, demo: Any, step: dict) -> None:
        pos, R = demo.target_pose(step)
        if _value(POSE, step, "joint_space"):
            seed = np.array(step["seed"], float) if "seed" in step else demo.ctl.target
            demo.planned_move(demo.ik(pos, R, q0=seed), step.get("carried", False))
            return
        path = demo.cartesian_path([(pos, R)], demo.ctl.target.copy())
        demo.ctl.follow(path, step.get("duration"))


@register
class Relative(Step):
    kind = "relative"
    keys = _keys(RELATIVE)
    required = _required(RELATIVE)

    def run(self, demo: Any, step: dict) -> None:
        p, R = ik.site_pose(demo.m, demo.d, demo.site, demo.ctl.target, demo.r.qpos)
        if "tool" in step:
            p = p + R @ np.asarray(step["tool"], float)
        if "world" in step:
            p = p + np.asarray(step["world"], float)
        path = demo.cartesian_path([(p, R)], demo.ctl.target.copy())
        demo.ctl.follow(path, step.get("duration"))


@register
class Hinge(Step):
    kind = "hinge"
    keys = _keys(HINGE)
    required = _required(HINGE)

    def check(self, step: dict, at: str, fac: Any, w: Waypoints) -> None:
        if mujoco.mj_name2id(fac.model, mujoco.mjtObj.mjOBJ_JOINT, step["joint"]) < 0:
            raise w.fail(f"{at}.joint", f"the facility has no joint named '{step['joint']}'")

    def run(self, demo: Any, step: dict) -> None:
        m = demo.m
        j = demo.fac.joint(step["joint"])
        # the axis where the robot believes the hinge is (the estimate, for a mockup's)
        anchor, direction = hinge_axis(m, j, demo.body_pose(int(m.jnt_bodyid[j])))
        p, R = ik.site_pose(m, demo.d, demo.site, demo.ctl.target, demo.r.qpos)
        hold = _value(HINGE, step, "hold_orientation")
        poses = arc(
            anchor,
            direction,
            p,
            R,
            steps=_value(HINGE, step, "steps"),
            step_deg=_value(HINGE, step, "step_deg"),
            hold_orientation=hold,
        )
        q = demo.ctl.target.copy()
        prev = 0.0
        for ang, _, _ in poses:  # each pose of the arc, reached along the circle
            n = max(2, int(math.ceil(math.degrees(ang - prev))))
            waypoints = [q]
            for k in range(1, n + 1):
                sp, sR = turned(anchor, direction, p, R, prev + (ang - prev) * k / n, hold)
                q = demo.ik(sp, sR, q0=q)
                waypoints.append(q)
            path = np.array(waypoints)
            demo.ctl.follow(
                path,
                max(_value(HINGE, step, "step_time"), path_duration(path, demo.ctl.vmax)),
            )
            demo.ctl.settle(timeout=0.5)
            prev = ang


@register
class Gripper(Step):
    kind = "gripper"
    keys = _keys(GRIPPER)
    required = _required(GRIPPER)
    settles = False

    def run(self, demo: Any, step: dict) -> None:
        what = step["action"]
        opening = {"open": demo.r.gripper_open, "close": demo.r.gripper_closed}.get(what, what)
        demo.ctl.set_gripper(float(opening), _value(GRIPPER, step, "seconds"))


@register
class Look(Step):
    kind = "look"
    keys = _keys(LOOK)
    settles = False

    def check(self, step: dict, at: str, fac: Any, w: Waypoints) -> None:
        _camera(step, at, fac, w)

    def run(self, demo: Any, step: dict) -> None:
        m, d = demo.m, demo.d
        cam = demo.camera(_value(LOOK, step, "camera"))
        rgb, depth = cam.rgbd(d)
        g = perception.find_handle(m, d, cam.cam, rgb, depth, _value(LOOK, step, "min_pixels"))
        mask = perception.red_mask(rgb)
        demo.snapshot(step["name"], (mask[..., None] * np.array([255, 255, 255])).astype(np.uint8))
        if g is None:
            raise StepError(
                f"the CTB handle is not in the wrist camera's view ({int(mask.sum())} red pixels)"
            )
        border = _value(LOOK, step, "border_px")
        vs, us = np.nonzero(g.segment.mask)
        h, w = mask.shape
        if (
            us.min() < border
            or vs.min() < border
            or us.max() >= w - border
            or vs.max() >= h - border
        ):
            raise StepError("the CTB handle is cut by the edge of the wrist camera's image")
        R = np.column_stack([g.axis, np.cross([0, 0, 1.0], g.axis), [0, 0, 1.0]])
        demo.handle = (g.position, R)
        demo.handle_info = {
            "position": np.round(g.position, 4).tolist(),
            "yaw_deg": round(math.degrees(g.yaw), 2),
            "pixels": g.segment.pixels,
            "centroid_px": np.round(g.segment.centroid, 1).tolist(),
            "aspect": round(g.segment.aspect, 2),
            "depth": round(g.depth, 4),
        }
        demo.log(
            f"  handle at {demo.handle_info['position']} yaw {demo.handle_info['yaw_deg']} deg "
            f"({g.segment.pixels} px)"
        )


@register
class Localize(Step):
    kind = "localize"
    keys = _keys(LOCALIZE)
    required = _required(LOCALIZE)
    settles = False

    def check(self, step: dict, at: str, fac: Any, w: Waypoints) -> None:
        comps = sorted(c for c in fac.manifest.components if c != DEMO_ROBOT)
        if step["component"] not in comps:
            message = f"'{step['component']}' is not a component; components: "
            raise w.fail(f"{at}.component", message + ", ".join(comps))
        _camera(step, at, fac, w)

    def run(self, demo: Any, step: dict) -> None:
        comp, role = step["component"], _value(LOCALIZE, step, "camera")
        found = localize.locate(demo.camera(role), demo.d, demo.fac.manifest)
        est = found.get(comp)
        need = _value(LOCALIZE, step, "min_tags")
        if est is None or len(est.tags) < need:
            seen = sorted(t for e in found.values() for t in e.tags)
            raise StepError(
                f"{len(est.tags) if est else 0} tag(s) of the {comp} in the {role} camera's "
                f"view, {need} needed (tags seen: {seen or 'none'})"
            )
        demo.estimates[comp] = est
        demo.log(
            f"  {comp} at {np.round(est.position, 4).tolist()} yaw "
            f"{math.degrees(est.yaw):.2f} deg (tags {list(est.tags)})"
        )


@register
class Wait(Step):
    kind = "wait"
    keys = _keys(WAIT)
    required = _required(WAIT)
    settles = False

    def run(self, demo: Any, step: dict) -> None:
        demo.ctl.wait(step["seconds"])
