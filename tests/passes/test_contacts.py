"""The contacts the conversion creates at home are resolved by the conversion, and the
certificate then judges the result.

Each case is a small description made for it, converted for real; the reference is
MuJoCo's own contacts at home in the model converted with ``keep_contacts`` (the same
document without the exclusions), and the description's shapes measured here
(trimesh's exact distances, analytic clearances). Each asserts the certificate's
verdict and the reason it gives.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from lxml import etree

from tests.security.attack import assert_one_error, run
from urdf2mjcf import api
from urdf2mjcf.solids import PENETRATION_M

INERTIAL = (
    '<inertial><mass value="0.5"/>'
    '<inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def link(name: str, geometry: str, xyz: str = "0 0 0") -> str:
    shape = f'<origin xyz="{xyz}"/><geometry>{geometry}</geometry>'
    return f'<link name="{name}"><collision>{shape}</collision>{INERTIAL}</link>'


def joint(name: str, kind: str, parent: str, child: str, xyz: str, axis: str = "0 0 1") -> str:
    limit = '<limit lower="-0.5" upper="0.5" effort="10" velocity="1"/>'
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>{limit if kind != "fixed" else ""}</joint>'
    )


def mesh_file(folder: Path, name: str, mesh: trimesh.Trimesh) -> str:
    mesh.export(folder / name)
    return f'<mesh filename="{name}"/>'


def write(folder: Path, body: str, name: str = "robot") -> Path:
    src = folder / f"{name}.urdf"
    src.write_text(f'<robot name="{name}">{body}</robot>')
    return src


def convert(src: Path, out: Path, **kw):
    return api.convert(src, out / "robot.xml", scene=False, overwrite=True, **kw)


def home_contacts(xml: Path) -> dict[frozenset[str], float]:
    """MuJoCo's own contacts at home: body pair -> the deepest (m)."""
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home"))
    mujoco.mj_forward(m, d)
    out: dict[frozenset[str], float] = {}
    for c in d.contact[: d.ncon]:
        pair = frozenset(m.body(int(m.geom_bodyid[g])).name for g in (c.geom1, c.geom2))
        out[pair] = max(out.get(pair, 0.0), -float(c.dist))
    return out


def excludes(xml: Path) -> list[tuple[str, str]]:
    root = etree.parse(str(xml)).getroot()
    return [(e.get("body1"), e.get("body2")) for e in root.iterfind("contact/exclude")]


def excluded_notes(report) -> dict[str, str]:
    return {n.element: n.message for n in report.notes if n.kind == "excluded"}


def interpenetration_failures(certificate) -> list[str]:
    return [f for f in certificate.failures if f.startswith("checks.interpenetration")]


# -- the fixed base and its children -------------------------------------------------------


def pocketed_base() -> trimesh.Trimesh:
    """A 200 x 200 x 100 mm block with a 100 x 100 x 50 mm pocket in its top: its hull
    passes the hull gap and the certificate's figures, so it stays one hull, which
    fills the pocket."""
    block = trimesh.creation.box(extents=[0.2, 0.2, 0.1])
    pocket = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    pocket.apply_translation([0, 0, 0.05])  # its floor at z = 0
    return trimesh.boolean.difference([block, pocket], engine="manifold")


def arm_in_a_pocket(folder: Path) -> Path:
    """base (the pocketed block, z = -0.05..0.05, the pocket's floor at 0) - j1 (z) -
    link1, a 60 mm cylinder standing in the pocket 10 mm clear of its floor and 20 mm
    of its walls (z = 0.01..0.21)."""
    base = mesh_file(folder, "base.stl", pocketed_base())
    body = (
        link("base", base)
        + link("link1", '<cylinder radius="0.03" length="0.2"/>', "0 0 0.1")
        + joint("j1", "revolute", "base", "link1", "0 0 0.01")
    )
    return write(folder, body, "pocket_arm")


def test_fixed_base_does_not_collide_with_its_child(tmp_path: Path) -> None:
    src = arm_in_a_pocket(tmp_path)
    kept = convert(src, tmp_path / "kept", keep_contacts=True)
    reference = home_contacts(tmp_path / "kept" / "robot.xml")
    # MuJoCo collides the welded base's hull with link 1: 40 mm (the pocket's 50 mm less
    # the 10 mm clearance), where the description's shapes are 10 mm apart
    depth = reference[frozenset({"base", "link1"})]
    assert depth == pytest.approx(0.04, abs=1e-3)
    assert not kept.certificate.passed
    (line,) = interpenetration_failures(kept.certificate)
    assert "base_collision / link1_collision: 40.0 mm deep at home" in line
    assert line.endswith("added by the conversion (the description's shapes: 0.0 mm)")

    report = convert(src, tmp_path / "resolved")
    xml = tmp_path / "resolved" / "robot.xml"
    assert excludes(xml) == [("base", "link1")]
    assert frozenset({"base", "link1"}) not in home_contacts(xml)
    message = excluded_notes(report)["contact link 'base' / link 'link1'"]
    assert "child of the fixed base" in message
    assert f"removes a contact {depth * 1e3:.1f} mm deep at home" in message
    certificate = report.certificate
    assert certificate.passed, certificate.failures
    (change,) = [c for c in certificate.changes if c["kind"] == "excluded"]
    assert change["link"] == "base" and change["message"] == message
    check = certificate.sections["checks"]["checks"]["interpenetration"]
    assert check["ok"] and check["pairs"] == []


def test_keep_contacts_from_the_command_line_the_description_and_the_actuator_file(
    tmp_path: Path,
) -> None:
    src = arm_in_a_pocket(tmp_path)
    res = run(
        "urdf2mjcf",
        str(src),
        "-o",
        str(tmp_path / "cli" / "robot.xml"),
        "--no-scene",
        "--keep-contacts",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert excludes(tmp_path / "cli" / "robot.xml") == []
    assert "interpenetration base_collision / link1_collision" in res.stdout

    said = src.read_text().replace(
        "</robot>", '<mujoco><collision contacts="keep"/></mujoco></robot>'
    )
    (tmp_path / "said.urdf").write_text(said)
    convert(tmp_path / "said.urdf", tmp_path / "said")
    assert excludes(tmp_path / "said" / "robot.xml") == []

    config = tmp_path / "actuators.yaml"
    config.write_text("collision:\n  contacts: keep\n")
    convert(src, tmp_path / "file", actuator_config=config)
    assert excludes(tmp_path / "file" / "robot.xml") == []
    # the description's word beats the file's
    resolve = src.read_text().replace(
        "</robot>", '<mujoco><collision contacts="resolve"/></mujoco></robot>'
    )
    (tmp_path / "resolve.urdf").write_text(resolve)
    convert(tmp_path / "resolve.urdf", tmp_path / "both", actuator_config=config)
    assert excludes(tmp_path / "both" / "robot.xml") == [("base", "link1")]


def test_a_bad_contacts_setting_is_one_error_naming_it(tmp_path: Path) -> None:
    src = arm_in_a_pocket(tmp_path)
    bad = src.read_text().replace(
        "</robot>", '<mujoco><collision contacts="sometimes"/></mujoco></robot>'
    )
    (tmp_path / "bad.urdf").write_text(bad)
    res = run(
        "urdf2mjcf", str(tmp_path / "bad.urdf"), "-o", str(tmp_path / "o" / "r.xml"), cwd=tmp_path
    )
    assert_one_error(res, "bad.urdf", "mujoco collision contacts='sometimes'", "keep, resolve")
    config = tmp_path / "actuators.yaml"
    config.write_text("collision:\n  contacts: [keep]\n")
    res = run(
        "urdf2mjcf",
        str(src),
        "-o",
        str(tmp_path / "o" / "r.xml"),
        "--actuator-config",
        str(config),
        cwd=tmp_path,
    )
    assert_one_error(res, "actuators.yaml", "collision: contacts")
    assert not (tmp_path / "o").exists()


def test_adjacency_is_moveits_through_bare_frames_and_fused_links(tmp_path: Path) -> None:
    """A bare mount frame (no geometry) between the base and link 1 leaves them
    adjacent; a plate with geometry fixed between them makes the plate link 1's
    neighbour instead, and fused into the base (--fuse-fixed) it is the base's body."""
    base = mesh_file(tmp_path, "base.stl", pocketed_base())
    cylinder = '<cylinder radius="0.03" length="0.2"/>'
    bare = (
        link("base", base)
        + '<link name="mount"/>'
        + link("link1", cylinder, "0 0 0.1")
        + joint("fix", "fixed", "base", "mount", "0 0 0")
        + joint("j1", "revolute", "mount", "link1", "0 0 0.01")
    )
    convert(write(tmp_path, bare, "bare"), tmp_path / "bare")
    assert excludes(tmp_path / "bare" / "robot.xml") == [("base", "link1")]
    plate = (
        link("base", base)
        + link("plate", '<box size="0.08 0.08 0.004"/>', "0 0 0.005")
        + link("link1", cylinder, "0 0 0.1")
        + joint("fix", "fixed", "base", "plate", "0 0 0")
        + joint("j1", "revolute", "plate", "link1", "0 0 0.01")
    )
    src = write(tmp_path, plate, "plate")
    report = convert(src, tmp_path / "plate")
    xml = tmp_path / "plate" / "robot.xml"
    # link 1 lies in the base's hull 40 mm deep: not its neighbour, but the hull's doing
    assert excludes(xml) == [("plate", "link1"), ("base", "link1")]
    notes = excluded_notes(report)
    assert "child of the fixed base" in notes["contact link 'plate' / link 'link1'"]
    assert notes["contact link 'base' / link 'link1'"].startswith(
        "excluded: the conversion's collision geoms overlap at home"
    )
    convert(src, tmp_path / "fused", fuse_fixed=True)
    assert excludes(tmp_path / "fused" / "robot.xml") == [("base", "link1")]


def test_a_world_link_with_geometry_does_not_collide_with_its_children(tmp_path: Path) -> None:
    body = (
        link("world", '<box size="1 1 0.02"/>', "0 0 -0.005")
        + link("arm", '<box size="0.05 0.05 0.3"/>', "0 0 0.1")
        + joint("j", "revolute", "world", "arm", "0 0 0")
    )
    report = convert(write(tmp_path, body, "table"), tmp_path / "out")
    assert excludes(tmp_path / "out" / "robot.xml") == [("world", "arm")]
    assert "child of the fixed base" in excluded_notes(report)["contact link 'world' / link 'arm'"]
    assert report.certificate.passed, report.certificate.failures


def test_a_floating_base_gets_no_base_exclusion(tmp_path: Path) -> None:
    """With a free root MuJoCo filters the root's children itself: nothing to add."""
    report = convert(arm_in_a_pocket(tmp_path), tmp_path / "free", floating_base=True)
    assert excludes(tmp_path / "free" / "robot.xml") == []
    assert not excluded_notes(report)
    assert frozenset({"base", "link1"}) not in home_contacts(tmp_path / "free" / "robot.xml")


def test_a_free_body_beside_a_welded_floor_still_lands_on_it(tmp_path: Path) -> None:
    """A floating joint's child is nobody's neighbour: a bag dropped beside a floor fixed
    to the same world link keeps its contact with the floor, and rests on it."""
    body = (
        '<link name="world"/>'
        + link("floor", '<box size="2 2 0.05"/>')
        + link("bag", '<box size="0.4 0.3 0.2"/>')
        + joint("floor_joint", "fixed", "world", "floor", "0 0 -0.025")
        + '<joint name="bag_joint" type="floating"><parent link="world"/><child link="bag"/>'
        '<origin xyz="0 0 0.15"/></joint>'
    )
    report = convert(write(tmp_path, body, "drop"), tmp_path / "out")
    xml = tmp_path / "out" / "robot.xml"
    assert excludes(xml) == [] and not excluded_notes(report)
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    for _ in range(int(1.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    bag = m.body("bag").id
    assert d.xpos[bag][2] == pytest.approx(0.1, abs=0.005)  # on the floor's top (z = 0)


# -- a hull reaching into a neighbour ------------------------------------------------------


def notched_finger() -> trimesh.Trimesh:
    """A 100 x 40 x 100 mm finger with a 30 mm deep, 40 mm high notch across its +x
    face: one hull (small gap, 20 mm Hausdorff), which fills the notch."""
    finger = trimesh.creation.box(extents=[0.1, 0.04, 0.1])
    notch = trimesh.creation.box(extents=[0.06, 0.06, 0.04])
    notch.apply_translation([0.05, 0, 0])
    return trimesh.boolean.difference([finger, notch], engine="manifold")


def gripper(folder: Path, tip_x: float) -> Path:
    """A fixed base, a hand on a revolute joint, two sibling fingers on prismatic joints:
    finger_a (notched, x = -0.05..0.05 with its notch x > 0.02) and finger_b, a
    50 x 30 x 20 mm bar coming from +x whose tip reaches to x = ``tip_x``, at the
    notch's middle height (10 mm clear of its walls)."""
    a = mesh_file(folder, "finger_a.stl", notched_finger())
    body = (
        link("base", '<box size="0.3 0.3 0.05"/>')
        + link("hand", '<box size="0.3 0.1 0.05"/>')
        + link("finger_a", a)
        + link("finger_b", '<box size="0.05 0.03 0.02"/>', f"{tip_x + 0.025} 0 0")
        + joint("j_hand", "revolute", "base", "hand", "0 0 0.1")
        + joint("j_a", "prismatic", "hand", "finger_a", "0 0 0.1", "1 0 0")
        + joint("j_b", "prismatic", "hand", "finger_b", "0 0 0.1", "1 0 0")
    )
    return write(folder, body, "gripper")


def test_a_hull_filling_a_notch_gets_an_exclusion_the_certificate_lists(tmp_path: Path) -> None:
    # finger_b's tip 20 mm into the notch: 10 mm clear of its floor (x = 0.02)
    src = gripper(tmp_path, tip_x=0.03)
    convert(src, tmp_path / "kept", keep_contacts=True)
    depth = home_contacts(tmp_path / "kept" / "robot.xml")[frozenset({"finger_a", "finger_b"})]
    assert depth == pytest.approx(0.02, abs=1e-3)  # the bar's tip in the hull
    # the reference for the description's shapes: the bar's corners against the notched
    # mesh, exactly: all outside it, 10 mm from its nearest face
    finger = notched_finger()
    corners = np.array(
        [[x, y, z] for x in (0.03, 0.08) for y in (-0.015, 0.015) for z in (-0.01, 0.01)]
    )
    assert not finger.contains(corners).any()
    assert trimesh.proximity.closest_point(finger, corners)[1].min() == pytest.approx(0.01)

    report = convert(src, tmp_path / "resolved")
    xml = tmp_path / "resolved" / "robot.xml"
    assert ("finger_a", "finger_b") in excludes(xml)
    message = excluded_notes(report)["contact link 'finger_a' / link 'finger_b'"]
    assert message == (
        "excluded: the conversion's collision geoms overlap at home; removes a contact "
        f"{depth * 1e3:.1f} mm deep at home (the description's shapes: 0.0 mm)"
    )
    assert report.certificate.passed, report.certificate.failures
    assert frozenset({"finger_a", "finger_b"}) not in home_contacts(xml)


def test_an_overlap_the_description_has_is_left_and_listed_as_its_own(tmp_path: Path) -> None:
    # finger_b 15 mm into finger_a's solid beyond the notch's floor (x = 0.02 - 0.015)
    src = gripper(tmp_path, tip_x=0.005)
    report = convert(src, tmp_path / "own")
    xml = tmp_path / "own" / "robot.xml"
    assert ("finger_a", "finger_b") not in excludes(xml)
    assert "contact link 'finger_a' / link 'finger_b'" not in excluded_notes(report)
    assert home_contacts(xml)[frozenset({"finger_a", "finger_b"})] > PENETRATION_M
    assert report.certificate.passed, report.certificate.failures
    (pair,) = report.certificate.sections["checks"]["checks"]["interpenetration"]["pairs"]
    # MuJoCo separates the bar from the hull sideways (y: 20 + 15 mm, the least of its
    # ways out); along that normal the described bar must move the same 35 mm to
    # clear the finger's solid, more than the 15 mm its tip lies in it
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    (normal,) = {tuple(np.round(np.abs(c.frame[:3]), 6)) for c in d.contact[: d.ncon]}
    assert normal == (0.0, 1.0, 0.0)
    assert pair["by"] == "description" and pair["source_depth_m"] == pytest.approx(0.035, abs=1e-3)


def test_a_finger_through_a_plate_is_the_descriptions_overlap(tmp_path: Path) -> None:
    """A bar the description puts through a 10 mm plate at home (a trifinger's fingers
    through its stage): its deepest point lies only 5 mm inside the plate, but it
    must rise 40 mm to clear it, as MuJoCo's depth says. The description's overlap:
    no exclusion, and the certificate lists it as the description's."""
    body = (
        link("base", '<box size="0.3 0.3 0.01"/>', "0 0 -0.005")  # the plate: z = -0.01..0
        + link("link1", '<box size="0.05 0.05 0.05"/>')
        + link("finger", '<box size="0.02 0.02 0.19"/>', "0 0 -0.145")  # z = -0.04..0.15
        + joint("j1", "revolute", "base", "link1", "0.1 0 0.3")
        + joint("j2", "revolute", "link1", "finger", "0 0 -0.1", "0 1 0")
    )
    src = write(tmp_path, body, "plate")
    report = convert(src, tmp_path / "out")
    xml = tmp_path / "out" / "robot.xml"
    assert home_contacts(xml)[frozenset({"base", "finger"})] == pytest.approx(0.04, abs=1e-6)
    assert ("base", "finger") not in excludes(xml)
    assert report.certificate.passed, report.certificate.failures
    (pair,) = report.certificate.sections["checks"]["checks"]["interpenetration"]["pairs"]
    assert set(pair["links"]) == {"base", "finger"} and pair["by"] == "description"
    assert pair["source_depth_m"] == pytest.approx(0.04, abs=1e-3)


# -- a tube sliding in a tube --------------------------------------------------------------


def tube(outer: float, inner: float, length: float) -> trimesh.Trimesh:
    return trimesh.creation.annulus(r_min=inner, r_max=outer, height=length, sections=48)


def telescope(folder: Path) -> Path:
    """A fixed base, then three nested tubes on prismatic joints along z, each inside the
    last with 1 mm of radial clearance (outer tube 60/54 mm, a hull 5.3 times its
    volume), all 200 mm long and centred at home."""
    t1 = mesh_file(folder, "t1.stl", tube(0.030, 0.027, 0.2))
    t2 = mesh_file(folder, "t2.stl", tube(0.026, 0.023, 0.2))
    t3 = mesh_file(folder, "t3.stl", tube(0.022, 0.019, 0.2))
    body = (
        link("base", '<box size="0.2 0.2 0.02"/>', "0 0 -0.12")
        + link("tube1", t1)
        + link("tube2", t2)
        + link("tube3", t3)
        + joint("s1", "prismatic", "base", "tube1", "0 0 0")
        + joint("s2", "prismatic", "tube1", "tube2", "0 0 0")
        + joint("s3", "prismatic", "tube2", "tube3", "0 0 0")
    )
    return write(folder, body, "telescope")


def test_nested_tubes_are_decomposed_so_they_do_not_overlap(tmp_path: Path) -> None:
    """The outer tube is cut into parts that leave its bore open, so the innermost tube
    (not its neighbour: MuJoCo filters those) does not touch it; hulled, it would be
    inside a solid cylinder, which the contacts pass then excludes."""
    src = telescope(tmp_path)
    report = convert(src, tmp_path / "parts")
    xml = tmp_path / "parts" / "robot.xml"
    decomposed = [n for n in report.notes if n.kind in ("decomposed", "cached")]
    assert any("t1.stl" in n.element for n in decomposed)
    contacts = home_contacts(xml)
    assert contacts.get(frozenset({"tube1", "tube3"}), 0.0) <= PENETRATION_M
    assert ("tube1", "tube3") not in excludes(xml)
    assert report.certificate.passed, report.certificate.failures
    links = report.certificate.sections["collision"]["links"]
    assert links["tube1"]["volume_ratio"] < 5.0

    hulled = convert(src, tmp_path / "hull", link_collision={"tube1": "hull"}, keep_contacts=True)
    depth = home_contacts(tmp_path / "hull" / "robot.xml")[frozenset({"tube1", "tube3"})]
    assert depth > 0.015  # tube3 (22 mm) inside tube1's solid hull
    assert not hulled.certificate.passed
    assert any("tube1" in f and "tube3" in f for f in interpenetration_failures(hulled.certificate))
    resolved = convert(src, tmp_path / "hull_resolved", link_collision={"tube1": "hull"})
    assert ("tube1", "tube3") in excludes(tmp_path / "hull_resolved" / "robot.xml")
    assert (
        f"removes a contact {depth * 1e3:.1f} mm deep"
        in excluded_notes(resolved)["contact link 'tube1' / link 'tube3'"]
    )
    assert not interpenetration_failures(resolved.certificate)


def test_the_same_description_gives_the_same_bytes(tmp_path: Path) -> None:
    src = gripper(tmp_path, tip_x=0.03)
    convert(src, tmp_path / "a")
    convert(src, tmp_path / "b")
    assert (tmp_path / "a" / "robot.xml").read_bytes() == (
        tmp_path / "b" / "robot.xml"
    ).read_bytes()


def test_containment_is_exact_on_a_concave_solid_and_the_same_every_time() -> None:
    """solids.contains: the pocketed block's inside, point by point, against the block
    minus its pocket written as inequalities; and the same answer on every call (trimesh's
    own test casts a random ray where its two rays disagree)."""
    from urdf2mjcf.solids import contains

    mesh = pocketed_base()
    rng = np.random.default_rng(7)
    points = rng.uniform(-0.12, 0.12, (20000, 3))
    in_block = (np.abs(points[:, :2]) < 0.1).all(axis=1) & (np.abs(points[:, 2]) < 0.05)
    in_pocket = (np.abs(points[:, :2]) < 0.05).all(axis=1) & (points[:, 2] > 0.0)
    truth = in_block & ~in_pocket
    got = contains(mesh, points)
    assert (got == truth).mean() > 0.9995  # points within float noise of a face may differ
    for _ in range(3):
        assert np.array_equal(contains(mesh, points), got)
