"""facility.json as typed values: a built bundle opens into them, they write the bytes the
builder writes, and a corrupted manifest is one error naming the file and the key."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from urdf2mjcf import bundle_manifest
from urdf2mjcf.bundle import MANIFEST, Bundle, open_bundle
from urdf2mjcf.bundle_manifest import ArmRoles, Manifest, from_json
from urdf2mjcf.errors import BundleError, LoadError


def test_a_built_bundle_opens_into_the_typed_manifest(imetro_bundle: Path) -> None:
    opened = open_bundle(imetro_bundle)
    assert isinstance(opened, Bundle) and isinstance(opened.manifest, Manifest)
    assert opened.folder == imetro_bundle and opened.manifest_path.name == MANIFEST
    man = opened.manifest
    robot = man.components["robot"]
    assert isinstance(robot.arm, ArmRoles) and robot.rover is None
    assert robot.arm.joints == tuple(robot.roles["joints"])
    assert len(robot.arm.actuators) == len(robot.arm.joints)
    assert robot.arm.gripper.open > robot.arm.gripper.closed
    assert set(robot.arm.arm_joints) <= set(robot.arm.joints)
    assert robot.pose is not None and len(robot.pose.xyz) == 3
    assert man.cameras and all(c.fovy > 0 for c in man.cameras)
    assert man.simulation is not None and man.simulation.timestep > 0
    assert opened.file("demo") == imetro_bundle / "demo.yaml"
    assert opened.file("recipe") == imetro_bundle / "recipe.yaml"
    with pytest.raises(AttributeError):  # frozen
        man.seed = 3  # type: ignore[misc]


def test_the_typed_manifest_writes_the_bytes_the_builder_wrote(imetro_bundle: Path) -> None:
    written = (imetro_bundle / MANIFEST).read_text()
    assert open_bundle(imetro_bundle).manifest.dumps() == written
    again = from_json(json.loads(from_json(json.loads(written)).dumps()))
    assert again.dumps() == written


def _corrupt(imetro_bundle: Path, tmp_path: Path, edit) -> Path:  # type: ignore[no-untyped-def]
    folder = tmp_path / "bundle"
    shutil.copytree(imetro_bundle, folder)
    path = folder / MANIFEST
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data, indent=2))
    return folder


def _set(*keys, value=None, delete=False):  # type: ignore[no-untyped-def]
    def edit(data):  # type: ignore[no-untyped-def]
        for k in keys[:-1]:
            data = data[k]
        if delete:
            del data[keys[-1]]
        else:
            data[keys[-1]] = value

    return edit


CORRUPTIONS = {
    "schema-version": (_set("schema_version", value=2), "schema_version", "is not 1"),
    "no-schema-version": (_set("schema_version", delete=True), "schema_version", "older"),
    "role-missing": (
        _set("components", "robot", "roles", "actuators", delete=True),
        "components.robot.roles.actuators",
        "missing or not a non-empty list",
    ),
    "gripper-field-missing": (
        _set("components", "robot", "roles", "gripper", "open", delete=True),
        "components.robot.roles.gripper.open",
        "missing or not a number",
    ),
    "non-finite": (
        _set("components", "robot", "pose", "yaw", value=float("inf")),
        "components.robot.pose.yaw",
        "is not a finite number",
    ),
    "nan-speed": (
        _set("components", "robot", "roles", "vmax", value=[float("nan")] * 8),
        "components.robot.roles.vmax",
        "positive speeds",
    ),
    "wrong-type": (
        _set("components", "robot", "roles", "sites", value=["tool0"]),
        "components.robot.roles.sites",
        "not a mapping",
    ),
    "name-not-a-string": (
        _set("components", "robot", "roles", "joints", value=["rail", 3]),
        "components.robot.roles.joints[1]",
        "is not a name",
    ),
    "camera-fovy": (
        _set("cameras", 0, "fovy", value="wide"),
        "cameras[0].fovy",
        "is not a positive number",
    ),
    "seed-type": (_set("seed", value=1.5), "seed", "is not a seed"),
    "noise-not-a-number": (
        _set("noise", "rgb", "read_std", value="x"),
        "noise.rgb.read_std",
        "is not a number in 0 .. 255",
    ),
    "noise-out-of-range": (
        _set("noise", "exposure", "gain", value=5),
        "noise.exposure.gain",
        "is not a number in 0 .. 1",
    ),
    "noise-channel": (_set("noise", "smell", value={}), "noise.smell", "not a sensor channel"),
    "fiducial-size": (
        _set("fiducials", 0, "size", value="big"),
        "fiducials[0].size",
        "is not a positive number",
    ),
    "fiducial-matrix": (
        _set("fiducials", 0, "pose_in_component", "matrix", value=[1]),
        "fiducials[0].pose_in_component.matrix",
        "not a list of 9 numbers",
    ),
    "fiducial-id": (_set("fiducials", 1, "id", value=True), "fiducials[1].id", "is not a tag id"),
    "bundle-escape": (
        _set("bundle", "demo", value="../demo.yaml"),
        "bundle.demo",
        "is not a file name inside the bundle",
    ),
}


@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_a_corrupted_manifest_is_one_error_naming_the_file_and_the_key(
    imetro_bundle: Path, tmp_path: Path, case: str
) -> None:
    edit, key, says = CORRUPTIONS[case]
    folder = _corrupt(imetro_bundle, tmp_path, edit)
    with pytest.raises(BundleError) as err:
        open_bundle(folder)
    text = str(err.value)
    assert "\n" not in text and says in text, text
    assert text.startswith(f"{folder / MANIFEST}: {key}: "), text
    assert err.value.element == key
    with pytest.raises(LoadError) as err2:  # the runtime's own error, the same words
        open_bundle(folder, error=LoadError)
    assert str(err2.value) == text


def test_a_rover_role_out_of_range_names_its_key(tmp_path: Path) -> None:
    roles = {
        "base": "base_link",
        "wheels": {"left": ["l"], "right": ["r"]},
        "wheel_actuators": {"left": ["l"], "right": ["r"]},
        "wheel_sensors": {"left": ["lv"], "right": ["rv"]},
        "wheel_radius": 0.0,
        "track": 0.6,
        "arm_joints": ["a"],
        "arm_actuators": ["a"],
        "imu": {"accelerometer": "acc", "gyro": "gyro", "orientation": "quat"},
    }
    data = {"schema_version": 1, "components": {"rover": {"prefix": "", "roles": roles}}}
    with pytest.raises(BundleError) as err:
        bundle_manifest.parse_manifest(data, tmp_path / MANIFEST)
    assert err.value.element == "components.rover.roles.wheel_radius"
    assert "is not above 0" in str(err.value)
    roles["wheel_radius"] = 0.2
    rover = from_json(data).components["rover"].rover
    assert rover is not None and rover.wheels.left == ("l",) and rover.track == 0.6


def test_a_minimal_manifest_opens(tmp_path: Path) -> None:
    man = from_json({"schema_version": 1, "components": {}})
    assert man.components == {} and man.cameras == () and man.seed is None


RUNTIME = ("runner", "envs", "ros2")
RAW = re.compile(r"manifest\[|manifest\.get\(|\[\"roles\"\]|\.get\(\"roles\"")


def test_the_runtime_reads_no_manifest_json() -> None:
    """The runtime's modules read the typed manifest only: no dict lookups into
    facility.json (its one reading is urdf2mjcf.bundle_manifest's)."""
    package = Path(__file__).resolve().parents[1] / "urdf2mjcf"
    files = [p for d in RUNTIME for p in sorted((package / d).rglob("*.py"))]
    files += [package / "cli.py", package / "bundle.py"]
    hits = [
        f"{p.relative_to(package)}:{n}: {line.strip()}"
        for p in files
        for n, line in enumerate(p.read_text().splitlines(), 1)
        if RAW.search(line)
    ]
    assert hits == []
