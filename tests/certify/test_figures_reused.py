"""What makes the certificate cheap gives the figures it would compute anyway.

The passive second validation steps beside its own equals one stepped alone; a
warm conversion reads the geometric figures back from the cache and its
certificate is the cold one's; an entry that is not what we wrote is a miss;
the reference's frames (yourdfpy's joint transforms composed down the tree)
are what yourdfpy's own scene graph says.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

import urdf2mjcf
from tests.certify.test_certificate import DEMO, GOLDEN, ROBOTIQ, _wild
from tests.certify.test_lint_checks import arm, converted, edited, lint
from tests.corpus import example_robot_data_share, example_robot_data_urdfs
from urdf2mjcf.certify import compile_written, reference
from urdf2mjcf.certify.checks import lint_section
from urdf2mjcf.passes import xacro

SIM_ARM = Path(__file__).parents[1] / "data" / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"


def _panda() -> Path:
    return next(p for p in example_robot_data_urdfs() if p.name == "panda.urdf")


def _certificate_json(report: urdf2mjcf.Report) -> str:
    assert report.certificate is not None and report.certificate.computed
    return json.dumps(report.certificate.to_dict(), sort_keys=True)


@pytest.mark.parametrize("visuals", [True, False], ids=["physics-twin", "whole-model"])
def test_passive_second_from_validation_equals_one_stepped_alone(
    tmp_path: Path, visuals: bool
) -> None:
    # With visual geoms validation steps its physics twin in a thread; without, the
    # model itself: the passive second runs beside either.
    src = arm(tmp_path, j2_origin='xyz="0 0 0.3" rpy="0 0.3 0"')  # the top post falls
    if not visuals:
        text = src.read_text()
        while "<visual>" in text:
            a = text.index("<visual>")
            text = text[:a] + text[text.index("</visual>") + len("</visual>") :]
        src.write_text(text)
    out = tmp_path / "out" / "robot.xml"
    report = urdf2mjcf.convert(src, out)
    assert report.certificate is not None
    given = report.certificate.sections["checks"]["checks"]["passive_energy"]
    files = [str(f.relative_to(out.parent)) for f in report.files]
    scene = compile_written(out.with_name("scene.xml"), files)
    assert (mujoco.mjtGeom.mjGEOM_MESH in scene.geom_type) is False  # boxes only
    assert (2 in scene.geom_group) is visuals
    ref = reference.load(xacro.run(src, urdf2mjcf.make_options().xacro))
    alone = lint_section(ref, scene, model_path=out.with_name("scene.xml"))
    stepped = alone["checks"]["passive_energy"]
    assert given == stepped
    assert given["max_growth_j"] >= 0 and given["start_j"] != 0 and given["steps"] == 500
    # no actuators: validation's second was the passive one, stepped once
    assert scene.nu == 0


def test_passive_second_of_an_actuated_robot_is_stepped_beside_validation(tmp_path: Path) -> None:
    # sim_arm: ros2_control servos, a lidar, cameras, visual meshes (the physics twin)
    out = tmp_path / "out" / "robot.xml"
    report = urdf2mjcf.convert(SIM_ARM, out, use_environment=False)
    assert report.certificate is not None
    given = report.certificate.sections["checks"]["checks"]["passive_energy"]
    files = [str(f.relative_to(out.parent)) for f in report.files]
    scene = compile_written(out.with_name("scene.xml"), files)
    assert scene.nu > 0  # its servos hold it in validation's second, not in this one
    ref = reference.load(xacro.run(SIM_ARM, urdf2mjcf.make_options(use_environment=False).xacro))
    alone = lint_section(ref, scene, model_path=out.with_name("scene.xml"))
    assert given == alone["checks"]["passive_energy"]
    assert given["steps"] > 0 and not given["diverged"]


def test_a_diverging_passive_second_writes_no_log_file(tmp_path: Path, monkeypatch) -> None:
    # MuJoCo's default warning handler appends to MUJOCO_LOG.TXT in the working folder.
    leaning = arm(tmp_path / "arm", j2_origin='xyz="0 0 0.3" rpy="0 0.3 0"')
    ref, xml = converted(leaning, tmp_path / "arm")
    m = edited(xml, "//joint[@name='j2']", damping="-100")  # MuJoCo warns, and resets
    monkeypatch.chdir(tmp_path)
    check = lint(ref, xml, m)["checks"]["passive_energy"]
    assert not check["ok"] and check["diverged"]
    assert not os.path.exists(tmp_path / "MUJOCO_LOG.TXT")


def test_warm_certificate_is_the_cold_one_and_a_foreign_entry_is_a_miss(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    out = tmp_path / "out" / "robot.xml"

    def convert() -> str:
        report = urdf2mjcf.convert(
            _panda(),
            out,
            package_paths=[example_robot_data_share()],
            use_environment=False,
            cache_dir=cache,
            overwrite=True,
        )
        return _certificate_json(report)

    cold = convert()
    entries = sorted((cache / "certificate").iterdir())
    # collision figures per link, the geometry's inertia per link, overlaps per pair
    sections = json.loads(cold)
    measured = [e for e in sections["collision"]["links"].values() if e["hausdorff_mm"]]
    checks = sections["checks"]["checks"]
    pairs = [p for p in checks["interpenetration"]["pairs"] if p["source_depth_m"] is not None]
    assert measured and checks["inertia"]["links"] and pairs
    # at most one entry per link and kind, one per pair (links of the same content share)
    links, overlaps = len(sections["collision"]["links"]), {tuple(p["links"]) for p in pairs}
    assert len(measured) < len(entries) <= 2 * links + len(overlaps)
    kept = {e.name: e.read_bytes() for e in entries}
    assert convert() == cold
    assert {e.name: e.read_bytes() for e in sorted((cache / "certificate").iterdir())} == kept
    # Entries of the wrong shape (each reader checks its own), or not JSON at all
    for k, entry in enumerate(entries):
        entry.write_bytes([b"not json", b'"x"', b"[1, 2]", b"-1", b'{"size_mm": "1"}'][k % 5])
    assert convert() == cold
    assert {e.name: e.read_bytes() for e in sorted((cache / "certificate").iterdir())} == kept


def _scene_graph_frames(ref: reference.Reference, q: np.ndarray) -> dict[str, np.ndarray]:
    """yourdfpy's own answer: its scene graph updated by ``update_cfg``."""
    import yourdfpy

    with reference.quiet_yourdfpy():
        urdf = yourdfpy.URDF.load(
            io.BytesIO(ref.document.xml),
            build_scene_graph=True,
            load_meshes=False,
            filename_handler=lambda f: f,
        )
        urdf.update_cfg(q)
    base = str(urdf.base_link)
    return {name: urdf.get_transform(name, base) for name in ref.link_names if name != base}


@pytest.mark.parametrize(
    "source, args, packages",
    [
        (DEMO, {"use_gripper": "true"}, []),  # mimic joints
        (GOLDEN / "joints.urdf", {}, []),  # floating, planar, continuous
        (_wild(ROBOTIQ)[0], {}, _wild(ROBOTIQ)[2]),
    ],
    ids=["demo_arm-gripper", "floating-planar", "robotiq-mimic"],
)
def test_reference_frames_are_yourdfpy_scene_graph_frames(
    source: Path, args: dict, packages: list
) -> None:
    options = urdf2mjcf.make_options(args=args, package_paths=packages, use_environment=False)
    ref = reference.load(xacro.run(source, options.xacro))
    rng = np.random.default_rng(3)
    for _ in range(4):
        q = rng.uniform(-1.0, 1.0, len(ref.actuated_joints))
        ours, theirs = ref.frames(q), _scene_graph_frames(ref, q)
        assert theirs and set(theirs) <= set(ours)
        for name, t in theirs.items():
            np.testing.assert_allclose(ours[name], t, atol=1e-12, err_msg=name)
