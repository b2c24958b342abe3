"""The certificate's collision figures against figures computed here: analytic ones
for shapes we write, trimesh's proximity queries on a robot written by others."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from lxml import etree
from scipy.spatial import ConvexHull

from tests.corpus import example_robot_data_share, example_robot_data_urdfs
from urdf2mjcf import api
from urdf2mjcf.certify import reference
from urdf2mjcf.certify.collision import HAUSDORFF_MM, HAUSDORFF_REL, collision_section
from urdf2mjcf.mesh_distance import enclosed_volume
from urdf2mjcf.passes import xacro

INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def convert_and_load(source: Path, out_dir: Path) -> tuple[reference.Reference, Path]:
    out = out_dir / "robot.xml"
    api.convert(source, out, scene=False)
    return reference.load(xacro.run(source, api.make_options().xacro)), out


def one_link(tmp_path: Path, collision: str) -> Path:
    src = tmp_path / "robot.urdf"
    src.write_text(
        f'<robot name="r"><link name="body"><collision>{collision}</collision>'
        f"{INERTIAL}</link></robot>"
    )
    return src


def edit_geom(xml: Path, name: str, **attrs: str | None) -> mujoco.MjModel:
    """The written MJCF with geom ``name``'s attributes replaced, compiled from disk."""
    tree = etree.parse(str(xml))
    (geom,) = tree.getroot().iterfind(f".//geom[@name='{name}']")
    for key, value in attrs.items():
        if value is None:
            geom.attrib.pop(key, None)
        else:
            geom.set(key, value)
    tree.write(str(xml))
    return mujoco.MjModel.from_xml_path(str(xml))


def test_primitives_kept_exact_are_measured_exact(tmp_path: Path) -> None:
    src = tmp_path / "robot.urdf"
    links = {
        "box": '<box size="0.1 0.2 0.3"/>',
        "cyl": '<cylinder radius="0.04" length="0.25"/>',
        "ball": '<sphere radius="0.07"/>',
    }
    body = "".join(
        f'<link name="{n}"><collision><origin xyz="0.01 0.02 0.03" rpy="0.3 0.2 0.1"/>'
        f"<geometry>{g}</geometry></collision>{INERTIAL}</link>"
        for n, g in links.items()
    )
    joints = "".join(
        f'<joint name="j{n}" type="fixed"><parent link="box"/><child link="{n}"/>'
        f'<origin xyz="0 0 {k}"/></joint>'
        for k, n in enumerate(["cyl", "ball"], 1)
    )
    src.write_text(f'<robot name="p">{body}{joints}</robot>')
    ref, out = convert_and_load(src, tmp_path)
    section = collision_section(ref, mujoco.MjModel.from_xml_path(str(out)))
    assert section["failures"] == []
    for name in links:
        entry = section["links"][name]
        assert entry["source"] == "primitive" and entry["geoms"] == 1
        assert entry["volume_ratio"] == pytest.approx(1.0, abs=1e-9)
        assert entry["hausdorff_mm"] < 1e-6 and entry["uncovered_mm"] < 1e-6

    # A box 5 mm larger each side along x sticks out by exactly 5 mm.
    m = edit_geom(out, "box_collision", size="0.055 0.1 0.15")
    entry = collision_section(ref, m)["links"]["box"]
    assert entry["hausdorff_mm"] == pytest.approx(5.0, abs=1e-6)
    assert entry["volume_ratio"] == pytest.approx(0.055 / 0.05, rel=1e-9)
    assert entry["uncovered_mm"] < 1e-6
    # ... and one 5 mm smaller leaves the source's faces 5 mm outside it.
    m = edit_geom(out, "box_collision", size="0.045 0.1 0.15")
    entry = collision_section(ref, m)["links"]["box"]
    assert entry["uncovered_mm"] == pytest.approx(5.0, abs=1e-3)


def test_convex_mesh_is_its_own_hull(tmp_path: Path) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    mesh.export(tmp_path / "ball.stl")
    ref, out = convert_and_load(
        one_link(tmp_path, '<geometry><mesh filename="ball.stl"/></geometry>'), tmp_path
    )
    entry = collision_section(ref, mujoco.MjModel.from_xml_path(str(out)))["links"]["body"]
    assert entry["source"] == "mesh" and entry["geoms"] == 1
    assert mesh.convex_hull.volume / mesh.volume == pytest.approx(1.0, abs=1e-9)
    assert entry["volume_ratio"] == pytest.approx(1.0, abs=1e-6)
    assert entry["hausdorff_mm"] < 1e-3 and entry["uncovered_mm"] < 1e-3
    assert entry["ok"]


def test_l_shaped_mesh_hull_sticks_out_by_the_analytic_distance(tmp_path: Path) -> None:
    # An L of arms a x t (depth d): its hull adds the triangle (t,t) (a,t) (t,a),
    # whose hypotenuse's midpoint lies (a - t) / 2 from both inner faces: the
    # farthest any point of the hull is from the L.
    a, t, d = 0.2, 0.1, 0.05
    arm1 = trimesh.creation.box(extents=[a, t, d])
    arm1.apply_translation([a / 2, t / 2, 0])
    arm2 = trimesh.creation.box(extents=[t, a, d])
    arm2.apply_translation([t / 2, a / 2, 0])
    shape = trimesh.boolean.union([arm1, arm2], engine="manifold")
    shape.export(tmp_path / "l.stl")
    ref, out = convert_and_load(
        one_link(tmp_path, '<geometry><mesh filename="l.stl"/></geometry>'), tmp_path
    )
    m = mujoco.MjModel.from_xml_path(str(out))
    entry = collision_section(ref, m)["links"]["body"]
    assert entry["geoms"] == 1  # the conversion kept the hull (small hull gap)
    furthest = (a - t) / 2 * 1e3
    # The maximum over sampled points: exact for them, never beyond the true one.
    assert 0.85 * furthest <= entry["hausdorff_mm"] <= furthest + 1e-6
    l_area, corner = 2 * a * t - t * t, (a - t) ** 2 / 2
    assert entry["volume_ratio"] == pytest.approx((l_area + corner) / l_area, rel=1e-5)
    assert entry["uncovered_mm"] < 1e-6


@pytest.fixture(scope="module")
def ur5(tmp_path_factory: pytest.TempPathFactory) -> tuple[reference.Reference, Path]:
    (src,) = [p for p in example_robot_data_urdfs() if p.name == "ur5_robot.urdf"]
    return convert_and_load(src, tmp_path_factory.mktemp("ur5"))


def _placed_collision_hull(xml: Path, link: str) -> trimesh.Trimesh:
    """The link's written collision mesh, read here from its file and the MJCF's geom
    pose, as the convex hull MuJoCo collides with."""
    root = etree.parse(str(xml)).getroot()
    (geom,) = root.iterfind(f".//body[@name='{link}']/geom[@name='{link}_collision']")
    (asset,) = root.iterfind(f"asset/mesh[@name='{geom.get('mesh')}']")
    meshdir = root.find("compiler").get("meshdir")
    written = trimesh.load(xml.parent / meshdir / asset.get("file"), force="mesh")
    assert isinstance(written, trimesh.Trimesh)
    hull = written.convex_hull
    pose = np.eye(4)
    if geom.get("quat"):
        pose[:3, :3] = trimesh.transformations.quaternion_matrix(
            [float(x) for x in geom.get("quat").split()]
        )[:3, :3]
    if geom.get("pos"):
        pose[:3, 3] = [float(x) for x in geom.get("pos").split()]
    hull.apply_transform(pose)
    return hull


@pytest.mark.parametrize("link", ["forearm_link", "wrist_1_link"])
def test_real_robot_figures_agree_with_trimesh(
    ur5: tuple[reference.Reference, Path], link: str
) -> None:
    ref, xml = ur5
    section = collision_section(ref, mujoco.MjModel.from_xml_path(str(xml)))
    entry = section["links"][link]
    name = {"forearm_link": "forearm", "wrist_1_link": "wrist1"}[link]
    share = example_robot_data_share() / "example-robot-data/robots/ur_description"
    source = trimesh.load(share / f"meshes/ur5/collision/{name}.stl", force="mesh")
    assert isinstance(source, trimesh.Trimesh)
    hull = _placed_collision_hull(xml, link)
    # trimesh's own answer, on points of its own choosing.
    points, _ = trimesh.sample.sample_surface(hull, 3000, seed=7)
    _, dist, _ = trimesh.proximity.closest_point(source, points)
    assert entry["hausdorff_mm"] == pytest.approx(dist.max() * 1e3, rel=0.1, abs=1.0)
    assert entry["volume_ratio"] == pytest.approx(hull.volume / source.volume, rel=1e-3)
    on_source, _ = trimesh.sample.sample_surface(source, 1000, seed=7)
    assert hull.contains(on_source).mean() > 0.95 and entry["uncovered_mm"] < 0.5
    assert entry["ok"] and section["failures"] == []


def test_collision_mesh_swapped_for_a_big_box_is_flagged(
    ur5: tuple[reference.Reference, Path], tmp_path: Path
) -> None:
    ref, xml = ur5
    altered = tmp_path / "robot.xml"
    altered.write_bytes(xml.read_bytes())
    for sub in ("assets",):
        (tmp_path / sub).symlink_to(xml.parent / sub)
    m = edit_geom(altered, "forearm_link_collision", type="box", mesh=None, size="0.3 0.3 0.5")
    section = collision_section(ref, m)
    entry = section["links"]["forearm_link"]
    assert not entry["ok"]
    limit = max(HAUSDORFF_MM, HAUSDORFF_REL * entry["size_mm"])
    assert entry["hausdorff_mm"] > limit
    assert [f for f in section["failures"] if "forearm_link" in f]
    assert all("forearm_link" in f for f in section["failures"])


def test_figures_kept_in_the_cache_are_the_figures_measured(
    ur5: tuple[reference.Reference, Path], tmp_path: Path
) -> None:
    """A warm certificate reads each link's figures back by content; a tampered entry
    is a miss, measured again, never trusted."""
    ref, xml = ur5
    m = mujoco.MjModel.from_xml_path(str(xml))
    root = tmp_path / "cache"
    fresh = collision_section(ref, m)
    cold = collision_section(ref, m, cache_root=root)
    entries = sorted((root / "certificate").glob("*.json"))
    assert entries and cold == fresh
    warm = collision_section(ref, m, cache_root=root)
    assert warm == fresh
    for entry in entries:
        entry.write_text('{"hausdorff_mm": -1, "size_mm": "x"}')
    assert collision_section(ref, m, cache_root=root) == fresh


# -- volumes that a part wound inside out would cancel ------------------------------


def two_part_finger() -> tuple[trimesh.Trimesh, trimesh.Trimesh]:
    """A phalanx (20 x 20 x 40 mm) and a narrower one (18 x 18 x 36 mm) overlapping it
    by 8 mm, as two closed parts of one mesh."""
    proximal = trimesh.creation.box(extents=[0.02, 0.02, 0.04])
    distal = trimesh.creation.box(extents=[0.018, 0.018, 0.036])
    distal.apply_translation([0.0, 0.0, 0.03])  # from z = 12 mm: 8 mm into the first
    return proximal, distal


def test_enclosed_volume_takes_every_closed_part_outward() -> None:
    a, b = (0.1, 0.2, 0.3), (0.1, 0.1, 0.1)
    box = trimesh.creation.box(extents=a)
    far = trimesh.creation.box(extents=b)
    far.apply_translation([1.0, 0.0, 0.0])
    far.invert()
    assert abs(trimesh.util.concatenate([box, far]).volume - (0.006 - 0.001)) < 1e-12
    assert enclosed_volume(trimesh.util.concatenate([box, far])) == pytest.approx(0.007)
    near = trimesh.creation.box(extents=b)
    near.apply_translation([0.05, 0.0, 0.0])  # half inside the first box: 0.0005 m^3 shared
    near.invert()
    assert enclosed_volume(trimesh.util.concatenate([box, near])) == pytest.approx(0.0065, rel=1e-5)
    # an inner shell (a cavity no other part can reach) adds nothing
    outer, inner = trimesh.creation.box(extents=a), trimesh.creation.box(extents=b)
    inner.invert()
    assert enclosed_volume(trimesh.util.concatenate([outer, inner])) == pytest.approx(0.006)
    # a few faces turned the wrong way round in a single part
    faces = box.faces.copy()
    faces[:3] = faces[:3, ::-1]
    flipped = trimesh.Trimesh(box.vertices, faces, process=False)
    assert enclosed_volume(flipped) == pytest.approx(0.006)
    # an open part has no inside
    assert enclosed_volume(trimesh.Trimesh(box.vertices, box.faces[1:], process=False)) is None


def test_finger_with_a_part_wound_inside_out_measures_its_true_volume_ratio(
    tmp_path: Path,
) -> None:
    """The false alarm of a hand family: one of a finger mesh's two parts is wound inside
    out, so the signed volumes cancel and the hull measured 11.5 x the mesh. The ratio
    is the hull's volume over the union of the parts wound right (manifold3d)."""
    proximal, distal = two_part_finger()
    reference_union = trimesh.boolean.union([proximal, distal], engine="manifold").volume
    inverted = distal.copy()
    inverted.invert()
    finger = trimesh.util.concatenate([proximal, inverted])
    finger.export(tmp_path / "finger.stl")
    hull = ConvexHull(finger.vertices).volume
    assert hull / abs(trimesh.load(tmp_path / "finger.stl").volume) > 5  # what cancelled
    ref, out = convert_and_load(
        one_link(tmp_path, '<geometry><mesh filename="finger.stl"/></geometry>'), tmp_path
    )
    section = collision_section(ref, mujoco.MjModel.from_xml_path(str(out)))
    entry = section["links"]["body"]
    assert entry["geoms"] == 1
    assert entry["volume_ratio"] == pytest.approx(hull / reference_union, rel=1e-4)
    assert entry["ok"] and section["failures"] == []


def test_zero_size_shape_is_the_descriptions_flaw_said_as_such(tmp_path: Path) -> None:
    """A radius-0 sphere is the description's flaw: the conversion warns naming the
    description, and the certificate says why the model has no geom for it, as a
    warning, not the conversion's failure. A zero-size shape beside a real one is left
    out of that link's figures."""
    src = tmp_path / "tip.urdf"
    src.write_text(
        '<robot name="r">'
        f'<link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry>'
        f"</collision>{INERTIAL}</link>"
        f'<link name="tip"><collision><geometry><sphere radius="0"/></geometry></collision>'
        f"{INERTIAL}</link>"
        f'<link name="pad"><collision><geometry><sphere radius="0"/></geometry></collision>'
        f'<collision><geometry><sphere radius="0.02"/></geometry></collision>{INERTIAL}</link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="tip"/>'
        '<origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        '<joint name="k" type="fixed"><parent link="tip"/><child link="pad"/>'
        '<origin xyz="0 0 0.2"/></joint></robot>'
    )
    report = api.convert(src, tmp_path / "robot.xml", scene=False)
    (warning,) = [n for n in report.warnings if "link 'tip' collision" in n.element]
    assert str(src) in warning.element and "zero size" in warning.message
    certificate = report.certificate
    assert certificate.passed, certificate.failures
    assert not any("no colliding geom" in f for f in certificate.failures)
    section = certificate.sections["collision"]
    tip = section["links"]["tip"]
    assert tip["ok"] and tip["geoms"] == 0
    assert tip["zero_size"] == ["sphere of radius 0"]
    assert "the description's flaw" in tip["reason"]
    (line,) = section["warnings"]
    assert line.startswith("collision tip: no colliding geom because the description's")
    assert "sphere of radius 0" in line and "not the conversion's" in line
    pad = section["links"]["pad"]  # measured against its real sphere only
    assert pad["zero_size"] == ["sphere of radius 0"]
    assert pad["volume_ratio"] == pytest.approx(1.0, abs=1e-9) and pad["ok"]


def test_only_shapes_urdf_does_not_define_is_the_descriptions_choice(tmp_path: Path) -> None:
    """pybullet's plane_implicit.urdf collides through a <plane>, a kind URDF does not
    define: the conversion warns it drops it, and the certificate's floor check says the
    model has nothing to collide because of the description's choice, not a failure."""
    src = tmp_path / "plane.urdf"
    src.write_text(
        '<robot name="plane"><link name="planeLink">'
        '<collision><geometry><plane normal="0 0 1"/></geometry></collision>'
        f"{INERTIAL}</link></robot>"
    )
    report = api.convert(src, tmp_path / "robot.xml", scene=False)
    assert any("<plane>" in n.element for n in report.warnings)
    certificate = report.certificate
    assert certificate.passed, certificate.failures
    check = certificate.sections["checks"]["checks"]["collision_matrix"]
    assert check["ok"] and "kinds URDF does not define" in check["detail"]


def test_every_collision_mesh_missing_is_the_descriptions_flaw(tmp_path: Path) -> None:
    """qibullet's pepper.urdf and poppy-ergo-jr name meshes their packages do not ship
    (fetched later by the package's own installer): the model has no colliding geom, and
    the certificate passes saying it is the description's flaw and how many meshes it
    dropped."""
    src = tmp_path / "robot.urdf"
    src.write_text(
        '<robot name="r"><link name="base"><collision><geometry>'
        '<mesh filename="meshes/base.stl"/></geometry></collision>'
        f"{INERTIAL}</link>"
        '<link name="arm"><collision><geometry><mesh filename="package://nowhere/arm.stl"/>'
        f"</geometry></collision>{INERTIAL}</link>"
        '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>'
    )
    report = api.convert(src, tmp_path / "out" / "robot.xml", scene=False)
    certificate = report.certificate
    assert certificate.passed, certificate.failures
    check = certificate.sections["checks"]["checks"]["collision_matrix"]
    assert check["ok"] and "were not found or not readable (its flaw" in check["detail"]
    summary = certificate.summary()
    assert summary.startswith("certificate: passed")
    assert "the description's flaw: 2 meshes it names were not found" in summary


def test_a_missing_mesh_beside_a_box_leaves_the_box_colliding(tmp_path: Path) -> None:
    """A missing mesh drops only itself: the link's box still reaches the floor."""
    src = tmp_path / "robot.urdf"
    src.write_text(
        '<robot name="r"><link name="base"><collision><geometry>'
        '<mesh filename="meshes/base.stl"/></geometry></collision>'
        f'<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>{INERTIAL}'
        "</link></robot>"
    )
    report = api.convert(src, tmp_path / "out" / "robot.xml", scene=False)
    check = report.certificate.sections["checks"]["checks"]["collision_matrix"]
    assert check["ok"] and "can touch a default floor" in check["detail"]


def test_a_four_value_mesh_scale_is_measured_as_the_conversion_reads_it(tmp_path: Path) -> None:
    """pybullet's racecar_differential.urdf writes scale="1 1 1 1": the conversion reads
    the first three factors, and the certificate's figures are measured the same way
    (they crashed on it)."""
    trimesh.creation.box(extents=[0.2, 0.1, 0.05]).export(tmp_path / "box.stl")
    src = tmp_path / "car.urdf"
    src.write_text(
        '<robot name="car"><link name="chassis"><collision><geometry>'
        '<mesh filename="box.stl" scale="2 1 1 1"/></geometry></collision>'
        f"{INERTIAL}</link></robot>"
    )
    report = api.convert(src, tmp_path / "robot.xml", scene=False)
    certificate = report.certificate
    assert certificate.passed, certificate.failures
    chassis = certificate.sections["collision"]["links"]["chassis"]
    assert chassis["volume_ratio"] == pytest.approx(1.0, abs=1e-6)
