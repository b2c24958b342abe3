"""Validation steps the model's physics twin (its visual geoms left out) beside the
whole model's compile. The reference is MuJoCo stepping the whole written scene:
the twin's trajectory must be the same bit for bit, and every failure the whole
model's stepping reports (warnings, MuJoCo's fatal errors) must still be reported."""

from __future__ import annotations

import struct
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.errors import ValidationError
from urdf2mjcf.mjcf.compile import home_data
from urdf2mjcf.passes import validate
from urdf2mjcf.passes.validate import ValidateConfig, _physics_files

SCENE = (
    '<mujoco model="scene"><include file="robot.xml"/>{size}'
    '<worldbody><geom name="floor" type="plane" size="0 0 0.05"/></worldbody></mujoco>'
)


def _tetra_stl() -> bytes:
    """A binary STL tetrahedron, 10 cm."""
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], dtype="<f4")
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    out = b"\0" * 80 + struct.pack("<I", len(faces))
    for f in faces:
        out += np.zeros(3, "<f4").tobytes() + v[list(f)].tobytes() + b"\0\0"
    return out


def _robot(boxes: int = 3, extra: str = "", gravity: str = "0 0 -9.81") -> str:
    """emit's layout: masses from <inertial>, a visual class that never collides; a
    free base with a mesh visual, hinged boxes, a rangefinder and a touch sensor."""
    links = []
    for k in range(boxes):
        links.append(
            f'<body name="b{k}" pos="0.12 0 0"><joint name="j{k}" axis="0 1 0" damping="0.01"/>'
            '<inertial pos="0.05 0 0" mass="0.2" diaginertia="1e-4 1e-4 1e-4"/>'
            '<geom class="collision" type="box" size="0.05 0.02 0.02" pos="0.05 0 0"/>'
            '<geom class="visual" type="mesh" mesh="tetra"/>'
            '<geom class="visual" type="sphere" size="0.03"/>'
        )
    chain = "".join(links) + "</body>" * boxes
    return (
        '<mujoco model="r"><compiler inertiafromgeom="false" meshdir="assets"/>'
        f'<option gravity="{gravity}"/>'
        '<default><default class="visual"><geom contype="0" conaffinity="0" group="2" '
        'density="0"/></default><default class="collision"><geom group="3"/></default>'
        '</default><asset><mesh name="tetra" file="tetra.stl"/></asset>'
        '<worldbody><body name="base" pos="0 0 0.3" euler="0.3 0.2 0.1"><freejoint/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>'
        '<geom class="collision" type="box" size="0.1 0.08 0.05"/>'
        '<geom name="shell" class="visual" type="mesh" mesh="tetra"/>'
        '<site name="eye" pos="0 0 -0.06" zaxis="0 0 -1"/>'
        f"{chain}</body></worldbody>"
        '<sensor><rangefinder site="eye"/><touch site="eye"/></sensor>'
        f"{extra}</mujoco>"
    )


def _folder(tmp_path: Path, robot: str, size: str = "") -> tuple[Path, list[str]]:
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "tetra.stl").write_bytes(_tetra_stl())
    (tmp_path / "robot.xml").write_text(robot)
    (tmp_path / "scene.xml").write_text(SCENE.format(size=size))
    return tmp_path / "scene.xml", ["scene.xml", "robot.xml", "assets/tetra.stl"]


def _trajectory(xml: str, files: dict[str, bytes], steps: int) -> list[np.ndarray]:
    m = mujoco.MjModel.from_xml_string(xml, files)
    d = home_data(m)
    out = []
    for _ in range(steps):
        mujoco.mj_step(m, d)
        out.append(np.concatenate([d.qpos, d.qvel, d.qacc, [d.ncon]]))
    return out


def _read(scene: Path, names: list[str]) -> dict[str, bytes]:
    return {n: (scene.parent / n).read_bytes() for n in names}


@pytest.fixture
def spied(monkeypatch) -> list[bool]:
    """Whether each validation's twin compiled (False: rejected, the whole stepped)."""
    seen: list[bool] = []
    original = validate._Stepper.run

    def run(self):
        original(self)
        seen.append(not self.rejected)

    monkeypatch.setattr(validate._Stepper, "run", run)
    return seen


def test_the_twin_moves_as_the_whole_model_bit_for_bit(tmp_path):
    scene, names = _folder(tmp_path, _robot())
    files = _read(scene, names)
    twin = _physics_files(files)
    assert twin is not None
    assert set(twin) == {"robot.xml"}, "the scene is compiled from its text; the mesh is visual"
    xml = files["scene.xml"].decode()
    lean = mujoco.MjModel.from_xml_string(xml, twin)
    assert (lean.ngeom, lean.nmesh) == (5, 0), "the floor and 4 boxes: no visual geom, no mesh"
    whole, physics = _trajectory(xml, files, 500), _trajectory(xml, twin, 500)
    assert whole[-1][-1] > 0, "the robot lands: contacts are part of what is compared"
    assert all(np.array_equal(a, b) for a, b in zip(whole, physics, strict=True))
    # made from the tree the robot file was written from, the twin is the same model
    from lxml import etree

    tree = etree.fromstring(files["robot.xml"])
    from_tree = _physics_files(files, {"robot.xml": tree})
    assert from_tree is not None and set(from_tree) == {"robot.xml"}
    assert etree.tostring(tree) == etree.tostring(etree.fromstring(files["robot.xml"]))
    again = _trajectory(xml, from_tree, 500)
    assert all(np.array_equal(a, b) for a, b in zip(whole, again, strict=True))


def test_validation_steps_the_twin_and_reports_the_whole_model(tmp_path, spied):
    scene, names = _folder(tmp_path, _robot())
    result = validate.run(scene, ValidateConfig(), files=names)
    assert spied == [True]
    whole = mujoco.MjModel.from_xml_path(str(scene))
    assert result is not None and result.steps == 500
    assert (result.ngeom, result.nmesh) == (whole.ngeom, whole.nmesh)  # the whole, visuals in
    assert result.model.ngeom == whole.ngeom


def test_a_warning_while_the_twin_steps_fails_validation(tmp_path, spied):
    scene, names = _folder(tmp_path, _robot(gravity="0 0 -1e30"))
    with pytest.raises(ValidationError, match="MuJoCo warned while simulating 1 s"):
        validate.run(scene, ValidateConfig(), files=names)
    assert spied == [True]


def test_mujocos_fatal_error_in_the_twin_names_the_arena(tmp_path, spied):
    # many boxes on the floor in a 40 kB arena: MuJoCo stops while stepping, not compiling
    scene, names = _folder(tmp_path, _robot(boxes=12), size='<size memory="40K"/>')
    mujoco.MjModel.from_xml_path(str(scene))  # it compiles
    with pytest.raises(ValidationError, match="arena") as info:
        validate.run(scene, ValidateConfig(), files=names)
    assert "<size memory=" in str(info.value)
    assert spied == [True]


def test_a_twin_that_misses_a_visual_geom_falls_back_to_the_whole(tmp_path, spied):
    # a sensor names a visual geom: the twin does not compile, the whole model is stepped
    extra = '<sensor><distance geom1="shell" geom2="floor"/></sensor>'
    scene, names = _folder(tmp_path, _robot(extra=extra))
    result = validate.run(scene, ValidateConfig(), files=names)
    assert spied == [False]
    assert result is not None and result.steps == 500
    # and the whole model's warnings still fail it
    (tmp_path / "robot.xml").write_text(_robot(extra=extra, gravity="0 0 -1e30"))
    with pytest.raises(ValidationError, match="MuJoCo warned"):
        validate.run(scene, ValidateConfig(), files=names)
