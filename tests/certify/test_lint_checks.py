"""The certificate's lint checks: each one passes on a sane robot and fails, naming
the culprit, on a model altered (or a description written) to break it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from lxml import etree

from tests.corpus import example_robot_data_urdfs
from urdf2mjcf import api
from urdf2mjcf.certify import reference
from urdf2mjcf.certify.checks import lint_section
from urdf2mjcf.passes import xacro


def box_link(name: str, size: tuple[float, float, float], z: float, mass: float, **kw: str) -> str:
    """A link holding one box (visual and collision) whose centre is ``z`` up its axis."""
    x, y, h = size
    ixx, iyy, izz = (mass / 12 * (b * b + c * c) for b, c in ((y, h), (x, h), (x, y)))
    ixx, iyy, izz = (float(kw.get(k, v)) for k, v in (("ixx", ixx), ("iyy", iyy), ("izz", izz)))
    geometry = f'<origin xyz="0 0 {z}"/><geometry><box size="{x} {y} {h}"/></geometry>'
    inertial = (
        ""
        if kw.get("no_inertial")
        else f'<inertial><origin xyz="0 0 {z}"/><mass value="{mass}"/>'
        f'<inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial>'
    )
    return (
        f'<link name="{name}"><visual>{geometry}</visual><collision>{geometry}</collision>'
        f"{inertial}</link>"
    )


def arm(
    tmp_path: Path,
    *,
    j2_origin: str = 'xyz="0 0 0.3"',
    l2_length: float = 0.3,
    j1_limits: tuple[float, float] = (-1.0, 1.0),
    l2: dict[str, str] | None = None,
) -> Path:
    """base (a slab) - j1 (z) - l1 (a post) - j2 (y) - l2 (a post): upright at home."""
    lo, hi = j1_limits
    tmp_path.mkdir(parents=True, exist_ok=True)
    src = tmp_path / "arm.urdf"
    src.write_text(
        '<robot name="arm">'
        + box_link("base", (0.2, 0.2, 0.1), 0.0, 2.0)
        + box_link("l1", (0.05, 0.05, 0.3), 0.15, 0.5)
        + box_link("l2", (0.05, 0.05, l2_length), l2_length / 2, 0.5, **(l2 or {}))
        + '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
        f'<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>'
        f'<limit lower="{lo}" upper="{hi}" effort="10" velocity="1"/></joint>'
        '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>'
        f'<origin {j2_origin}/><axis xyz="0 1 0"/>'
        '<limit lower="-3" upper="3" effort="10" velocity="1"/></joint>'
        "</robot>"
    )
    return src


def converted(source: Path, out_dir: Path) -> tuple[reference.Reference, Path]:
    out = out_dir / "robot.xml"
    api.convert(source, out, scene=False)
    return reference.load(xacro.run(source, api.make_options().xacro)), out


def edited(xml: Path, xpath: str, **attrs: str) -> mujoco.MjModel:
    """The written MJCF with the attributes of the elements at ``xpath`` set."""
    tree = etree.parse(str(xml))
    found = tree.getroot().xpath(xpath)
    assert found, xpath
    for el in found:
        for key, value in attrs.items():
            el.set(key, value)
    tree.write(str(xml))
    return mujoco.MjModel.from_xml_path(str(xml))


def lint(
    ref: reference.Reference, xml: Path, m: mujoco.MjModel | None = None, **kw: Any
) -> dict[str, Any]:
    model = m if m is not None else mujoco.MjModel.from_xml_path(str(xml))
    return lint_section(ref, model, model_path=xml, **kw)


def test_sane_arm_passes_every_check(tmp_path: Path) -> None:
    ref, xml = converted(arm(tmp_path), tmp_path)
    section = lint(ref, xml)
    assert section["failures"] == []
    checks = section["checks"]
    assert set(checks) == {
        "inertia",
        "interpenetration",
        "home_in_limits",
        "collision_matrix",
        "visual_massless",
        "passive_energy",
    }
    assert all(c["ok"] and c["detail"] for c in checks.values())
    assert checks["inertia"]["checked"] == 3
    assert checks["inertia"]["worst_factor"] == pytest.approx(1.0, abs=0.01)
    assert checks["visual_massless"]["mass_measured"]
    assert checks["passive_energy"]["steps"] == 500  # 1 s at MuJoCo's 2 ms


def test_body_moved_into_another_is_the_conversions_overlap(tmp_path: Path) -> None:
    ref, xml = converted(arm(tmp_path), tmp_path)
    # l2 pushed down through the base slab: MuJoCo collides them (not parent and child).
    m = edited(xml, "//body[@name='l2']", pos="0 0 -0.3")
    check = lint(ref, xml, m)["checks"]["interpenetration"]
    assert not check["ok"]
    (pair,) = check["pairs"]
    assert set(pair["links"]) == {"base", "l2"} and pair["by"] == "conversion"
    assert pair["depth_m"] > 0.05 and pair["source_depth_m"] == 0.0


def test_overlap_written_in_the_description_is_attributed_to_it(tmp_path: Path) -> None:
    # l2 hangs down from the post's top at x = 0.1 into the base slab: 25 mm deep
    # along x (its side at 0.075, the slab's at 0.1).
    src = arm(tmp_path, j2_origin='xyz="0.1 0 0.3" rpy="0 3.141592653589793 0"', l2_length=0.4)
    ref, xml = converted(src, tmp_path)
    section = lint(ref, xml)
    check = section["checks"]["interpenetration"]
    (pair,) = check["pairs"]
    assert set(pair["links"]) == {"base", "l2"} and pair["by"] == "description"
    assert pair["depth_m"] == pytest.approx(0.025, abs=2e-3)
    assert pair["source_depth_m"] == pytest.approx(0.025, abs=2e-3)
    assert check["ok"]  # the description's own overlap is listed, not the conversion's fault
    assert not [f for f in section["failures"] if f.startswith("interpenetration")]


def test_home_outside_a_joint_range_is_flagged(tmp_path: Path) -> None:
    ref, xml = converted(arm(tmp_path, j1_limits=(0.5, 1.0)), tmp_path)
    m = mujoco.MjModel.from_xml_path(str(xml))
    # The written home keyframe clamps j1 to 0.5: inside; the zero pose is noted.
    check = lint(ref, xml, m)["checks"]["home_in_limits"]
    assert check["ok"] and check["zero_outside"] == ["j1"]
    # A home at 0 is outside [0.5, 1].
    section = lint(ref, xml, m, d_home=mujoco.MjData(m))
    assert not section["checks"]["home_in_limits"]["ok"]
    (line,) = [f for f in section["failures"] if f.startswith("home")]
    assert "j1" in line and "[0.5, 1]" in line


def test_visual_geom_given_mass_or_contacts_is_flagged(tmp_path: Path) -> None:
    ref, xml = converted(arm(tmp_path), tmp_path)
    # Geoms weigh only where inertia comes from geoms; then a visual with mass shows.
    edited(xml, "//compiler", inertiafromgeom="true")
    m = edited(xml, "//body[@name='l1']/geom[@class='visual']", mass="1")
    check = lint(ref, xml, m)["checks"]["visual_massless"]
    assert not check["ok"] and check["heavy_bodies"] == ["l1"]
    m = edited(xml, "//body[@name='l2']/geom[@class='visual']", contype="1")
    section = lint(ref, xml, m)
    assert section["checks"]["visual_massless"]["colliding"] == 1
    assert any(f.startswith("visual l2 geom") and "collides" in f for f in section["failures"])


def test_collision_matrix_that_touches_nothing_is_flagged(tmp_path: Path) -> None:
    ref, xml = converted(arm(tmp_path), tmp_path)
    m = edited(xml, "//geom[@class='collision']", contype="2", conaffinity="2")
    section = lint(ref, xml, m)
    assert not section["checks"]["collision_matrix"]["ok"]
    assert any(f.startswith("collision:") for f in section["failures"])


def test_energy_growth_flags_an_unstable_model(tmp_path: Path) -> None:
    # The top post leans 0.3 rad at home: it falls (and lands on the base).
    ref, xml = converted(arm(tmp_path, j2_origin='xyz="0 0 0.3" rpy="0 0.3 0"'), tmp_path)
    stable = lint(ref, xml)["checks"]["passive_energy"]
    assert stable["ok"] and stable["max_growth_j"] <= stable["allowed_j"]
    assert stable["start_j"] > 0
    # Negative damping pumps energy into the falling post.
    m = edited(xml, "//joint[@name='j2']", damping="-2")
    section = lint(ref, xml, m)
    check = section["checks"]["passive_energy"]
    assert not check["ok"] and (check["diverged"] or check["max_growth_j"] > check["allowed_j"])
    assert any(f.startswith("passive_energy") for f in section["warnings"])


def test_implausible_inertia_is_flagged(tmp_path: Path) -> None:
    # l2 is a 0.3 m post along z: its smallest moment is about z, 18 times smaller.
    long, thin = 0.5 / 12 * (0.3**2 + 0.05**2), 0.5 / 12 * (2 * 0.05**2)
    for kw, what in (
        ({"ixx": str(20 * long), "iyy": str(20 * long), "izz": str(20 * thin)}, "moments"),
        ({"ixx": str(thin), "iyy": str(long), "izz": str(long)}, "axes swapped"),
    ):
        ref, xml = converted(arm(tmp_path / what, l2=kw), tmp_path / what)
        section = lint(ref, xml)
        entry = section["checks"]["inertia"]["links"]["l2"]
        assert not entry["ok"], what
        # the description's flaw: a warning, never a failure of the conversion
        (line,) = [f for f in section["warnings"] if f.startswith("inertia")]
        assert "l2" in line and what.split()[0] in line
        assert not [f for f in section["failures"] if f.startswith("inertia")]
    # A link without <inertial> has the conversion's estimate: not checked.
    ref, xml = converted(arm(tmp_path / "none", l2={"no_inertial": "1"}), tmp_path / "none")
    check = lint(ref, xml)["checks"]["inertia"]
    assert check["skipped"]["l2"] == "estimated by the conversion" and check["ok"]


def test_real_robot_overlap_found_in_its_description(tmp_path: Path) -> None:
    """Panda (example-robot-data): its link5 and hand collision meshes overlap at home
    (joint 4 clamped into its range) in the description itself."""
    (src,) = [p for p in example_robot_data_urdfs() if p.name == "panda.urdf"]
    ref, xml = converted(src, tmp_path)
    section = lint(ref, xml)
    pairs = section["checks"]["interpenetration"]["pairs"]
    assert pairs and all(p["by"] == "description" for p in pairs)
    for p in pairs:
        assert p["source_depth_m"] == pytest.approx(p["depth_m"], rel=0.25)
    assert section["checks"]["passive_energy"]["ok"]
    assert section["checks"]["home_in_limits"]["zero_outside"] == ["panda_joint4"]
    assert np.isfinite(section["checks"]["inertia"]["worst_factor"])
