"""Collision shapes: what a collision mesh becomes (decompose, hull, primitive, auto),
robot-wide and per link, from the command line, the actuator file and ``<mujoco>``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from lxml import etree
from scipy.spatial import ConvexHull

from urdf2mjcf import api
from urdf2mjcf.errors import ConversionError
from urdf2mjcf.passes.collision import primitives

# The robot: a 0.3 x 0.2 x 0.1 box base, a capsule forearm lying along x beside it
# and an L-shaped bracket on top, all held by fixed joints (one rigid body to drop).
BOX = (0.3, 0.2, 0.1)
CAPSULE_RADIUS, CAPSULE_LENGTH = 0.05, 0.2  # cylinder part, metres
LINKS = ("base", "forearm", "bracket")


def l_shape() -> trimesh.Trimesh:
    """Two 0.2 x 0.05 x 0.05 arms meeting at a right angle in the xz plane."""
    a = trimesh.creation.box((0.2, 0.05, 0.05))
    a.apply_translation((0.1, 0.0, 0.025))
    b = trimesh.creation.box((0.05, 0.05, 0.2))
    b.apply_translation((0.025, 0.0, 0.1))
    return trimesh.boolean.union([a, b], engine="manifold")


def _link(name: str, mesh: str, mass: float) -> str:
    return f"""
  <link name="{name}">
    <inertial><mass value="{mass}"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
      ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="meshes/{mesh}"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/{mesh}"/></geometry></collision>
  </link>"""


def write_robot(root: Path, extension: str = "") -> Path:
    """The robot's URDF with its three STL meshes under ``root``."""
    meshes = root / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(BOX).export(meshes / "box.stl")
    trimesh.creation.capsule(height=CAPSULE_LENGTH, radius=CAPSULE_RADIUS, count=[48, 48]).export(
        meshes / "capsule.stl"
    )
    l_shape().export(meshes / "bracket.stl")
    urdf = f"""<?xml version="1.0"?>
<robot name="shapes">
  {_link("base", "box.stl", 2.0)}
  {_link("forearm", "capsule.stl", 0.5)}
  {_link("bracket", "bracket.stl", 0.2)}
  <joint name="forearm_joint" type="fixed"><parent link="base"/><child link="forearm"/>
    <origin xyz="0.3 0 0" rpy="0 1.5707963267948966 0"/></joint>
  <joint name="bracket_joint" type="fixed"><parent link="base"/><child link="bracket"/>
    <origin xyz="0 0 0.05" rpy="0 0 0.3"/></joint>
  {extension}
</robot>
"""
    path = root / "robot.urdf"
    path.write_text(urdf)
    return path


@pytest.fixture()
def robot(tmp_path: Path) -> Path:
    return write_robot(tmp_path / "src")


def convert(src: Path, out: Path, **kw) -> api.Report:
    kw.setdefault("use_cache", False)
    kw.setdefault("use_environment", False)
    kw.setdefault("certify", False)
    return api.convert(src, out, **kw)


def collision_geoms(xml: Path) -> dict[str, list[etree._Element]]:
    """Body name -> its collision geoms, as written."""
    root = etree.parse(str(xml)).getroot()
    return {
        body.get("name"): [g for g in body.findall("geom") if g.get("class") == "collision"]
        for body in root.iter("body")
    }


def types(xml: Path) -> dict[str, list[str]]:
    return {b: [g.get("type", "sphere") for g in gs] for b, gs in collision_geoms(xml).items()}


def floats(text: str | None) -> np.ndarray:
    return np.array([float(x) for x in (text or "").split()])


def run_cli(src: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", str(src), "-o", str(out), "--no-ros-env", *extra],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "URDF2MJCF_CACHE": str(out.parent.parent / "cache")},
    )


# ---------------------------------------------------------------------------
# The strategies
# ---------------------------------------------------------------------------


def test_default_is_decompose(robot: Path, tmp_path: Path) -> None:
    """Without options the meshes become hulls or convex parts, never primitives."""
    a = convert(robot, tmp_path / "a" / "r.xml")
    b = convert(robot, tmp_path / "b" / "r.xml", collision_shape="decompose")
    assert (tmp_path / "a" / "r.xml").read_bytes() == (tmp_path / "b" / "r.xml").read_bytes()
    assert all(t == "mesh" for ts in types(tmp_path / "a" / "r.xml").values() for t in ts)
    assert not a.of_kind("primitive") and "collision:" not in a.summary()
    assert b.summary() == a.summary()


def test_primitive(robot: Path, tmp_path: Path) -> None:
    out = tmp_path / "out" / "r.xml"
    report = convert(robot, out, collision_shape="primitive")
    geoms = collision_geoms(out)
    assert all(g.get("type") in primitives.KINDS for gs in geoms.values() for g in gs)
    # the box mesh: one box of the mesh's half extents, at the link origin
    (box,) = geoms["base"]
    assert box.get("type") == "box"
    np.testing.assert_allclose(
        sorted(floats(box.get("size"))), sorted(np.array(BOX) / 2), atol=1e-6
    )
    np.testing.assert_allclose(floats(box.get("pos")) if box.get("pos") else 0.0, 0.0, atol=1e-6)
    # the capsule mesh: a capsule of its radius and half length
    (cap,) = geoms["forearm"]
    assert cap.get("type") == "capsule"
    np.testing.assert_allclose(
        floats(cap.get("size")), (CAPSULE_RADIUS, CAPSULE_LENGTH / 2), atol=1e-3
    )
    notes = {n.element: n.message for n in report.of_kind("primitive")}
    assert notes["mesh 'meshes/box.stl'"].startswith("box (Hausdorff 0.0 mm, volume ratio 1.00)")
    assert "collision: 3 primitives" in report.summary()


def test_auto(robot: Path, tmp_path: Path) -> None:
    """auto: a capsule for the capsule, the box for the box, no single box for the L."""
    out = tmp_path / "out" / "r.xml"
    report = convert(robot, out, collision_shape="auto")
    t = types(out)
    assert t["forearm"] == ["capsule"] and t["base"] == ["box"]
    assert t["bracket"] and set(t["bracket"]) == {"mesh"}  # its hull or its convex parts
    summary = report.summary()
    assert "collision: 2 primitives (1 box, 1 capsule)" in summary
    # the L's fits all miss it by more than the tolerance: the reason it is not one
    l_mesh = l_shape()
    cands = primitives.candidates(l_mesh.vertices, l_mesh.faces)
    chosen = primitives.choose(cands, primitives.TOLERANCE_MM * 1e-3, primitives.MAX_VOLUME_RATIO)
    assert chosen is None or len(chosen.fits) > 1


def test_auto_tolerance_decides(robot: Path, tmp_path: Path) -> None:
    """A tolerance below every fit's deviation leaves auto where decompose is."""
    out = tmp_path / "out" / "r.xml"
    ref = tmp_path / "ref" / "r.xml"
    convert(robot, out, collision_shape="auto", primitive_tolerance=1e-6)
    convert(robot, ref)
    assert types(out)["forearm"] == types(ref)["forearm"] == ["mesh"]


def test_hull(robot: Path, tmp_path: Path) -> None:
    """hull: one mesh geom per link, the convex hull of the link's mesh, even for the L."""
    out = tmp_path / "out" / "r.xml"
    report = convert(robot, out, collision_shape="hull")
    assert types(out) == {name: ["mesh"] for name in LINKS}
    meshes = {m.name: m for m in report.model.mesh_assets}
    bracket = report.model.collision_geoms["bracket"][0]
    written = meshes[bracket.mesh]
    expected = ConvexHull(l_shape().vertices).volume
    assert trimesh.load(out.parent / "assets" / written.file).volume == pytest.approx(expected)
    assert {n.message for n in report.of_kind("hull")} == {"convex hull (collision shape hull)"}


def test_urdf_primitives_stay(tmp_path: Path) -> None:
    """Primitive geometry in the URDF is written as it is, whatever the shape."""
    src = tmp_path / "p.urdf"
    src.write_text(
        '<robot name="p"><link name="a"><collision><geometry><cylinder radius="0.1" '
        'length="0.4"/></geometry></collision></link></robot>'
    )
    for shape in ("hull", "primitive"):
        out = tmp_path / shape / "r.xml"
        convert(src, out, collision_shape=shape)
        (geom,) = collision_geoms(out)["a"]
        assert geom.get("type") == "cylinder"
        np.testing.assert_allclose(floats(geom.get("size")), (0.1, 0.2))


# ---------------------------------------------------------------------------
# Per-link routes and their precedence
# ---------------------------------------------------------------------------


def _changed(out: Path, ref: Path) -> set[str]:
    a, b = types(out), types(ref)
    return {name for name in LINKS if a[name] != b[name]}


def test_cli_link_override(robot: Path, tmp_path: Path) -> None:
    ref = tmp_path / "ref" / "r.xml"
    out = tmp_path / "out" / "r.xml"
    convert(robot, ref)
    result = run_cli(robot, out, "--no-validate", "--link-collision", "base=primitive")
    assert result.returncode == 0, result.stderr
    assert _changed(out, ref) == {"base"} and types(out)["base"] == ["box"]


def test_yaml_link_override(robot: Path, tmp_path: Path) -> None:
    config = tmp_path / "act.yaml"
    config.write_text("collision:\n  links: {forearm: primitive}\n")
    ref, out = tmp_path / "ref" / "r.xml", tmp_path / "out" / "r.xml"
    convert(robot, ref)
    convert(robot, out, actuator_config=config)
    assert _changed(out, ref) == {"forearm"} and types(out)["forearm"] == ["capsule"]


def test_yaml_default_and_unknown_link(robot: Path, tmp_path: Path) -> None:
    """``default`` applies to every link the file does not name; a link that is not in
    the robot is a warning (one file may serve variants), as for joint patterns."""
    config = tmp_path / "act.yaml"
    config.write_text("collision:\n  default: hull\n  links: {base: primitive, nope: hull}\n")
    out = tmp_path / "out" / "r.xml"
    report = convert(robot, out, actuator_config=config)
    assert types(out) == {"base": ["box"], "forearm": ["mesh"], "bracket": ["mesh"]}
    assert [n.element for n in report.warnings if "collision" in n.message] == ["link 'nope'"]


def test_mujoco_link_override(tmp_path: Path) -> None:
    ext = '<mujoco><collision link="bracket" shape="primitive"/></mujoco>'
    src = write_robot(tmp_path / "src", ext)
    ref, out = tmp_path / "ref" / "r.xml", tmp_path / "out" / "r.xml"
    convert(src, ref, mujoco_extension=False)
    report = convert(src, out)
    assert _changed(out, ref) == {"bracket"}
    assert set(types(out)["bracket"]) <= set(primitives.KINDS)
    assert not any(n.element == "mujoco" for n in report.notes)  # nothing else applied


def test_precedence(tmp_path: Path) -> None:
    """command line > <mujoco> > actuator file links > its default > --collision-shape."""
    ext = (
        '<mujoco><collision link="forearm" shape="primitive"/>'
        '<collision link="base" shape="hull"/></mujoco>'
    )
    src = write_robot(tmp_path / "src", ext)
    config = tmp_path / "act.yaml"
    config.write_text("collision:\n  default: primitive\n  links: {forearm: hull, base: auto}\n")
    out = tmp_path / "out" / "r.xml"
    convert(
        src,
        out,
        collision_shape="hull",
        actuator_config=config,
        link_collision={"base": "primitive"},
    )
    # base: the command line's primitive over <mujoco>'s hull; forearm: <mujoco>'s
    # primitive over the file's hull; bracket: the file's default over --collision-shape
    t = types(out)
    assert t["base"] == ["box"] and t["forearm"] == ["capsule"]
    assert set(t["bracket"]) <= set(primitives.KINDS)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("--link-collision", "base=sphere"), "'sphere' is not one of"),
        (("--link-collision", "elbow=hull"), "no link 'elbow' in the robot"),
        (("--collision-shape", "capsule"), "capsule"),
    ],
)
def test_bad_cli_input(robot: Path, tmp_path: Path, args: tuple[str, ...], named: str) -> None:
    out = tmp_path / "out" / "r.xml"
    result = run_cli(robot, out, "--no-validate", *args)
    assert result.returncode == 2
    errors = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(errors) == 1 and errors[0].startswith("error: ") and named in errors[0]
    assert not out.parent.exists() or not any(out.parent.iterdir())


def test_bad_mujoco_and_yaml(tmp_path: Path) -> None:
    src = write_robot(tmp_path / "a", '<mujoco><collision link="nope" shape="hull"/></mujoco>')
    with pytest.raises(ConversionError, match="mujoco collision link='nope'"):
        convert(src, tmp_path / "a" / "out" / "r.xml")
    src = write_robot(tmp_path / "b", '<mujoco><collision link="base" shape="cube"/></mujoco>')
    with pytest.raises(ConversionError, match="unknown shape 'cube'"):
        convert(src, tmp_path / "b" / "out" / "r.xml")
    config = tmp_path / "act.yaml"
    config.write_text("collision:\n  links: {base: cube}\n")
    with pytest.raises(ConversionError, match="collision: links: base.*unknown collision shape"):
        convert(src, tmp_path / "c" / "r.xml", actuator_config=config, mujoco_extension=False)
    config.write_text("collision:\n  shapes: {base: hull}\n")
    with pytest.raises(ConversionError, match="unknown key 'shapes'"):
        convert(src, tmp_path / "c" / "r.xml", actuator_config=config, mujoco_extension=False)


# ---------------------------------------------------------------------------
# Determinism, the cache, the physics
# ---------------------------------------------------------------------------


def test_deterministic(robot: Path, tmp_path: Path) -> None:
    a, b = tmp_path / "a" / "r.xml", tmp_path / "b" / "r.xml"
    convert(robot, a, collision_shape="auto")
    convert(robot, b, collision_shape="auto")
    assert a.read_bytes() == b.read_bytes()


def test_warm_conversion_does_not_refit(
    robot: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cache = tmp_path / "cache"
    cold, warm = tmp_path / "cold" / "r.xml", tmp_path / "warm" / "r.xml"
    convert(robot, cold, collision_shape="primitive", use_cache=True, cache_dir=cache)
    entries = [
        e
        for e in (cache / "primitive_fits").glob("*.json")
        if "candidates" in json.loads(e.read_text())
    ]
    assert len(entries) == 3  # one per distinct mesh

    def refit(*args, **kwargs):
        raise AssertionError("fitted again on a warm conversion")

    monkeypatch.setattr(primitives, "candidates", refit)
    convert(robot, warm, collision_shape="primitive", use_cache=True, cache_dir=cache)
    assert warm.read_bytes() == cold.read_bytes()
    monkeypatch.undo()

    # an entry that is not what the cache writes is a miss: fitted again, same output
    for i, entry in enumerate(entries):
        data = json.loads(entry.read_text())
        if i == 0:
            data["candidates"][0]["fits"][0]["size"] = [float("nan")]
            entry.write_text(json.dumps(data))
        elif i == 1:
            data["candidates"][0]["fits"][0]["type"] = "ellipsoid"
            entry.write_text(json.dumps(data))
        else:
            entry.write_text("{not json")
    again = tmp_path / "again" / "r.xml"
    convert(robot, again, collision_shape="primitive", use_cache=True, cache_dir=cache)
    assert again.read_bytes() == cold.read_bytes()


def _rest_height(scene: Path, drop: float = 0.05, seconds: float = 1.0) -> float:
    """The free body's height above the floor after falling ``drop`` metres onto it."""
    m = mujoco.MjModel.from_xml_path(str(scene))
    d = mujoco.MjData(m)
    mujoco.mj_resetData(m, d)
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    floor = m.geom(m.geom_type.tolist().index(mujoco.mjtGeom.mjGEOM_PLANE)).pos[2]
    d.qpos[2] = floor + BOX[2] / 2 + drop
    for _ in range(int(seconds / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert np.linalg.norm(d.qvel) < 1e-2  # at rest
    return float(d.qpos[2] - floor)


def test_auto_rests_like_the_meshes(robot: Path, tmp_path: Path) -> None:
    meshes = tmp_path / "meshes" / "r.xml"
    auto = tmp_path / "auto" / "r.xml"
    convert(robot, meshes, floating_base=True)
    convert(robot, auto, floating_base=True, collision_shape="auto")
    assert "capsule" in types(auto)["forearm"]
    h_mesh = _rest_height(meshes.parent / "scene.xml")
    h_auto = _rest_height(auto.parent / "scene.xml")
    # both stand on the box's bottom face (half its height above the floor, less MuJoCo's
    # contact penetration) and agree within the fit tolerance
    assert h_mesh == pytest.approx(BOX[2] / 2, abs=2e-3)
    assert abs(h_auto - h_mesh) <= primitives.TOLERANCE_MM * 1e-3


def test_batch_takes_the_shape_options(robot: Path, tmp_path: Path) -> None:
    out = tmp_path / "batch"
    result = subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", "batch", str(robot), "-o", str(out)]
        + ["--no-ros-env", "--no-validate", "--no-cache", "--collision-shape", "auto"]
        + ["--primitive-tolerance", "1e-6"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    (xml,) = [p for p in out.rglob("*.xml") if p.name != "scene.xml"]
    # the tolerance reached the conversion: nothing fits within 1 nm but the exact box
    assert types(xml)["base"] == ["box"] and types(xml)["forearm"] == ["mesh"]


def test_fit_entries_are_checked(tmp_path: Path) -> None:
    """An entry is used only when it is exactly what the cache writes."""
    from urdf2mjcf.passes.collision.decompositions import DecompositionCache

    cache = DecompositionCache(tmp_path)
    key = "a" * 64
    fit = primitives.Fit(
        type="capsule", pos=(0.0, 0.1, 0.2), quat=(1.0, 0.0, 0.0, 0.0), size=(0.05, 0.1)
    )
    dev = primitives.Deviation(hausdorff_m=0.001, uncovered_m=0.0, volume_ratio=1.1)
    cand = primitives.Candidate(fits=(fit,), deviation=dev, cost=1.5)
    cache.store_fits(key, [cand])
    assert cache.load_fits(key) == [cand]
    assert cache.load_fits("b" * 64) is None  # absent
    path = tmp_path / "primitive_fits" / f"{key}.json"
    good = json.loads(path.read_text())

    def edited(change) -> list | None:
        data = json.loads(json.dumps(good))
        change(data)
        path.write_text(json.dumps(data))
        return cache.load_fits(key)

    fit0 = lambda d: d["candidates"][0]["fits"][0]  # noqa: E731
    bad = [
        lambda d: d.update(key="c" * 64),  # another key's entry
        lambda d: d.update(extra=1),
        lambda d: fit0(d).update(type="cone"),
        lambda d: fit0(d).update(size=[0.05]),  # a capsule takes two
        lambda d: fit0(d).update(size=[0.05, -0.1]),
        lambda d: fit0(d).update(quat=[2.0, 0.0, 0.0, 0.0]),
        lambda d: fit0(d).update(pos=[True, 0.0, 0.0]),
        lambda d: fit0(d).update(pos=[10**400, 0.0, 0.0]),
        lambda d: fit0(d).update(pos="0 0 0"),
        lambda d: d["candidates"][0]["deviation"].update(hausdorff_m=-1.0),
        lambda d: d["candidates"][0].update(fits=[]),
        lambda d: d["candidates"][0].update(cost=None),
        lambda d: d.update(candidates={"a": 1}),
    ]
    for change in bad:
        assert edited(change) is None
    assert edited(lambda d: None) == [cand]
    path.write_text('{"key": "' + key + '", "candidates": [NaN]}')
    assert cache.load_fits(key) is None
