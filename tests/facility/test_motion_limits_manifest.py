"""make-facility's URDF 1.2 motion limits: collected from the conversions of a small 1.2
robot and written under the component that owns the joints in facility.json."""

from __future__ import annotations

from pathlib import Path

import mujoco

from urdf2mjcf import api
from urdf2mjcf.facility.build import component_motion_limits
from urdf2mjcf.facility.manifest import _components
from urdf2mjcf.facility.recipe import Component
from urdf2mjcf.report import motion_limits

INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def _robot(tmp_path: Path, name: str, joints: list[tuple[str, str]]) -> Path:
    """A chain of hinges, one per ``(name, extra <limit> attributes)``, URDF 1.2."""
    body = '<link name="base"/>'
    parent = "base"
    for joint, extra in joints:
        body += (
            f'<link name="{joint}_link">{INERTIAL}</link>'
            f'<joint name="{joint}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{joint}_link"/><axis xyz="0 0 1"/>'
            f'<limit lower="-1" upper="1" effort="10" velocity="2"{extra}/></joint>'
        )
        parent = f"{joint}_link"
    path = tmp_path / f"{name}.urdf"
    path.write_text(f'<?xml version="1.0"?><robot name="{name}" version="1.2">{body}</robot>')
    return path


def _convert(path: Path):
    model, result = api.build(path, api.make_options(scene=False, use_environment=False))
    return model, result


def test_the_limits_of_a_1_2_robot_go_under_the_component_that_owns_them(tmp_path):
    robot_src = _robot(
        tmp_path,
        "arm",
        [("j1", ' acceleration="2" deceleration="1.5" jerk="30"'), ("j2", "")],
    )
    world_src = _robot(
        tmp_path, "world", [("door_hinge", ' acceleration="0.5"'), ("fan", ' jerk="9"')]
    )
    robot_model, robot_doc = _convert(robot_src)
    world_model, _ = _convert(world_src)
    attached = {"robot": motion_limits(robot_model)}
    world = motion_limits(world_model)
    # what the conversions give: only the stated limits, only the joints stating any
    assert attached["robot"] == {"j1": {"acceleration": 2.0, "deceleration": 1.5, "jerk": 30.0}}
    # (a deceleration not given is the acceleration, as urdfdom reads it)
    door = {"door_hinge": {"acceleration": 0.5, "deceleration": 0.5}}
    assert world == {**door, "fan": {"jerk": 9.0}}
    table = {
        "robot": Component("arm", "arm.urdf", attach={}),
        "door": Component("door", "door.urdf", prefix="door_"),
        "shelf": Component("shelf", "shelf.urdf", prefix="shelf_", attach={}),
    }
    owned = component_motion_limits(
        table, ["robot", "door", "shelf"], world, {**attached, "shelf": {}}
    )
    # 'fan' is under no component's prefix: the world's own joint, listed nowhere
    assert owned == {"robot": attached["robot"], "door": door}
    # facility.json's components: the limits under the component, none where none stated
    m = mujoco.MjModel.from_xml_string(robot_doc.xml)
    roles = {
        "robot": {"prefix": "", "roles": None, "free": False, "motion_limits": owned["robot"]},
        "shelf": {"prefix": "shelf_", "roles": None, "free": False},
    }
    entries = {n: c.to_json() for n, c in _components(m, {}, roles).items()}
    assert entries["robot"]["motion_limits"] == attached["robot"]
    assert "motion_limits" not in entries["shelf"]


def test_the_default_bundle_states_no_motion_limits(imetro_bundle):
    import json

    data = json.loads((imetro_bundle / "facility.json").read_text())
    assert all("motion_limits" not in c for c in data["components"].values())
