"""AprilTag fiducials: declared per component in the table, checked like every recipe
key, added by the builder as textured visual boxes, listed in facility.json.

References: OpenCV's own detector reads each tag's texture back to its id; MuJoCo's
compiler places each tag geom, which must sit where the table says on its body."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest
from lxml import etree

from urdf2mjcf.errors import InputError
from urdf2mjcf.facility import fiducials
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe, parse_recipe
from urdf2mjcf.mjcf.document import mjcf_bytes
from urdf2mjcf.schema import load
from urdf2mjcf.transforms import rpy_to_matrix

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", root=ROOT)
    out = tmp_path_factory.mktemp("fiducials") / "imetro"
    return build_facility(recipe, out, root=ROOT, components=False).output


def test_every_declared_tag_is_in_the_facility_once_and_listed(built: Path) -> None:
    manifest = json.loads((built / "facility.json").read_text())
    table, _ = load(ROOT / "recipes" / "components" / "imetro.yaml", "table")
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", root=ROOT)
    declared = {
        t["id"]: name
        for name, spec in table.items()
        if recipe.places(name)
        for t in spec.get("fiducials") or []
    }
    listed = {f["id"]: f["component"] for f in manifest["fiducials"]}
    assert listed == declared
    assert {"trainer", "hatch_4060", "express_rack"} <= set(listed.values())
    for f in manifest["fiducials"]:
        assert set(f) >= {"id", "component", "body", "size", "pose_in_body", "pose_in_component"}
        assert f"tag36h11_{f['id']}" in {Path(p).stem.rsplit("_", 1)[0] for p in manifest["files"]}


def test_each_tag_texture_reads_back_as_its_id_with_opencvs_detector(built: Path) -> None:
    manifest = json.loads((built / "facility.json").read_text())
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    detector = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
    for f in manifest["fiducials"]:
        png = next((built / "assets").glob(f"tag36h11_{f['id']}_*.png"))
        image = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
        corners, ids, _ = detector.detectMarkers(image)
        assert ids is not None and ids.ravel().tolist() == [f["id"]]
        # The black square is 8 of the 10 cells: the white border is part of the print.
        edge = np.linalg.norm(corners[0][0][1] - corners[0][0][0])
        assert edge == pytest.approx(image.shape[0] * 0.8, abs=2)


def test_tag_geoms_are_visual_only_and_sit_where_the_table_puts_them(built: Path) -> None:
    manifest = json.loads((built / "facility.json").read_text())
    m = mujoco.MjModel.from_xml_path(str(built / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    for f in manifest["fiducials"]:
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"tag36h11_{f['id']}")
        assert g >= 0
        assert (m.geom_contype[g], m.geom_conaffinity[g], m.geom_group[g]) == (0, 0, 2)
        b = int(m.geom_bodyid[g])
        assert mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) == f["body"]
        # The plate's +z face is the tag's face, the plate 10/8 of the tag's size.
        assert m.geom_size[g][:2] == pytest.approx([f["size"] * 0.625] * 2)
        r_body = d.xmat[b].reshape(3, 3)
        r_tag = r_body @ rpy_to_matrix(f["pose_in_body"]["rpy"])
        face = d.xpos[b] + r_body @ np.array(f["pose_in_body"]["xyz"])
        r_geom = d.geom_xmat[g].reshape(3, 3)
        assert r_geom == pytest.approx(r_tag, abs=1e-9)
        assert d.geom_xpos[g] + r_geom[:, 2] * m.geom_size[g][2] == pytest.approx(face, abs=1e-9)
        # Its pose in the component: from the component's placement pose (the truth).
        pose = manifest["components"][f["component"]]["pose"]
        c, s = math.cos(pose["yaw"]), math.sin(pose["yaw"])
        r_comp = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        local = r_comp.T @ (face - np.array(pose["xyz"]))
        assert f["pose_in_component"]["xyz"] == pytest.approx(local, abs=1e-8)
        rot = np.reshape(f["pose_in_component"]["matrix"], (3, 3))
        assert rot == pytest.approx(r_comp.T @ r_tag, abs=1e-8)


def test_tags_face_out_of_their_surfaces_towards_open_space(built: Path) -> None:
    """A ray from just in front of each tag, along its normal, leaves without hitting
    the tag's own component within 5 cm: no tag is buried in or faces into a part."""
    manifest = json.loads((built / "facility.json").read_text())
    m = mujoco.MjModel.from_xml_path(str(built / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for f in manifest["fiducials"]:
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"tag36h11_{f['id']}")
        normal = d.geom_xmat[g].reshape(3, 3)[:, 2].copy()
        start = d.geom_xpos[g] + normal * 0.002
        hit = np.zeros(1, np.int32)
        groups = np.array([0, 0, 1, 0, 0, 0], np.uint8)  # the visual geoms
        dist = mujoco.mj_ray(m, d, start, normal, groups, 1, -1, hit)
        assert dist < 0 or dist > 0.05, f"tag {f['id']} faces {hit[0]} at {dist:.3f} m"


def test_each_tag_lies_flat_on_a_surface_of_its_own_body(built: Path) -> None:
    """Behind each plate, within 1 mm, is the visual surface of the body it is on: no
    tag floats in the air or hides inside a part (MuJoCo's ray against the geoms)."""
    manifest = json.loads((built / "facility.json").read_text())
    m = mujoco.MjModel.from_xml_path(str(built / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    groups = np.array([0, 0, 1, 0, 0, 0], np.uint8)
    for f in manifest["fiducials"]:
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"tag36h11_{f['id']}")
        rot = d.geom_xmat[g].reshape(3, 3)
        half = m.geom_size[g]
        m.geom_group[g] = 5  # the rays see through the tag itself, to what is behind it
        for cx, cy in [(0, 0), (0.8, 0.8), (-0.8, 0.8), (0.8, -0.8), (-0.8, -0.8)]:
            # From 5 mm in front of the face: the surface lies behind the 2 mm plate.
            start = d.geom_xpos[g] + rot @ [cx * half[0], cy * half[1], half[2] + 0.005]
            hit = np.zeros(1, np.int32)
            dist = mujoco.mj_ray(m, d, start, -rot[:, 2], groups, 1, -1, hit)
            body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[hit[0]]))
            gap = dist - 0.005 - 2 * half[2]
            assert abs(gap) < 0.001 and body == f["body"], (f["id"], cx, cy, gap, body)


TABLE = {
    "box": {
        "asset": "box",
        "standalone": "box.urdf.xacro",
        "prefix": "box_",
        "fiducials": [{"id": 3, "link": "base", "xyz": [0, 0, 0.1], "size": 0.08}],
    },
    "crate": {
        "asset": "crate",
        "standalone": "crate.urdf.xacro",
        "prefix": "crate_",
        "fiducials": [{"id": 4, "link": "base", "xyz": [0, 0, 0.1], "size": 0.08}],
    },
}


def _recipe_text(tmp_path: Path, table: str) -> Path:
    (tmp_path / "table.yaml").write_text(table)
    (tmp_path / "r.yaml").write_text("name: r\nxacro: w.urdf.xacro\ncomponents: table.yaml\n")
    return tmp_path / "r.yaml"


@pytest.mark.parametrize(
    ("tags", "key", "message"),
    [
        (
            "[{id: 3, link: base, xyz: [0, 0, 0], size: 0.1}, {id: 3, link: top, xyz: [0, 0, 1], "
            "size: 0.1}]",
            "box.fiducials[1].id",
            "tag id 3 is already used by 'box'",
        ),
        (
            "[{id: 587, link: base, xyz: [0, 0, 0], size: 0.1}]",
            "box.fiducials[0].id",
            "is not a tag36h11 id (0 .. 586)",
        ),
        (
            "[{id: 1, link: base, xyz: [0, 0], size: 0.1}]",
            "box.fiducials[0].xyz",
            "is not three numbers",
        ),
        (
            "[{id: 1, link: base, xyz: [0, 0, 0], size: 0}]",
            "box.fiducials[0].size",
            "out of range (above 0 to 10)",
        ),
        (
            "[{id: 1, link: base, xyz: [0, 0, 0], size: 0.1, colour: red}]",
            "box.fiducials[0].colour",
            "unknown key",
        ),
        ("{id: 1}", "box.fiducials", "a list of tags"),
    ],
)
def test_a_bad_tag_is_an_error_naming_file_key_and_line(
    tmp_path: Path, tags: str, key: str, message: str
) -> None:
    table = f"box:\n  asset: box\n  standalone: box.urdf.xacro\n  fiducials: {tags}\n"
    path = _recipe_text(tmp_path, table)
    with pytest.raises(InputError) as err:
        load_recipe(path, root=tmp_path)
    text = str(err.value)
    assert "table.yaml" in text and key in text and message in text and "(line 4)" in text


def test_ids_are_unique_across_components_of_a_table() -> None:
    table = {k: dict(v) for k, v in TABLE.items()}
    table["crate"]["fiducials"] = [{"id": 3, "link": "base", "xyz": [0, 0, 0], "size": 0.1}]
    data = {"name": "r", "xacro": "w.xacro", "components": table}
    with pytest.raises(InputError, match=r"components\.crate\.fiducials\[0\]\.id.*'box'"):
        parse_recipe(data, None)
    ok = parse_recipe({**data, "components": TABLE}, None)
    assert [t.id for c in ok.components.values() for t in c.fiducials] == [3, 4]


def test_a_tag_on_a_link_the_facility_lacks_names_the_component(tmp_path: Path) -> None:
    scene = tmp_path / "scene.xml"
    scene.write_text(
        '<mujoco model="w">\n  <worldbody>\n    <body name="box_base">\n'
        '      <geom type="box" size="0.1 0.1 0.1"/>\n    </body>\n  </worldbody>\n</mujoco>\n'
    )
    root, files = etree.fromstring(scene.read_bytes()), {}
    tag = fiducials.Fiducial(id=5, link="lid", xyz=(0, 0, 0.1), size=0.05)
    with pytest.raises(InputError, match=r"components\.box\.fiducials.*'lid'.*'box_lid'"):
        fiducials.add_to_scene(root, files, [("box", "box_", tag)], recipe="r.yaml")
    good = fiducials.Fiducial(id=5, link="base", xyz=(0, 0, 0.1), size=0.05)
    fiducials.add_to_scene(root, files, [("box", "box_", good)])
    assert [n.startswith("assets/tag36h11_5") and n.endswith(".png") for n in files] == [True]
    scene.write_bytes(mjcf_bytes(root))
    for name, data in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(data)
    m = mujoco.MjModel.from_xml_path(str(scene))  # MuJoCo compiles what we wrote
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "tag36h11_5")
    assert (m.geom_contype[g], m.geom_conaffinity[g], m.geom_group[g]) == (0, 0, 2)
    assert m.ntex == 1 and m.nmat == 1


def test_a_users_own_component_carries_tags_the_builder_knows_nothing_about(
    tmp_path: Path, gl_context: None
) -> None:
    """The user's crate (a free body of their own) with a tag on its lid: placed,
    listed and found by the localizer from above, under the crate's own jitter."""
    from tests.facility import test_own_facility as own
    from urdf2mjcf.runner.camera import CameraModel
    from urdf2mjcf.runner.localize import camera_pose, localize

    tag = "  fiducials:\n    - {id: 7, link: crate, xyz: [0, 0, 0.102], rpy: [0, 0, 0.3], size: 0.08}\n"
    recipe = load_recipe(own._lab(tmp_path / "lab", table=own.TABLE + tag), root=ROOT)
    out = build_facility(recipe, tmp_path / "out", root=ROOT, seed=4, components=False).output
    manifest = json.loads((out / "facility.json").read_text())
    assert [(f["id"], f["component"], f["body"]) for f in manifest["fiducials"]] == [
        (7, "crate", "crate_crate")
    ]
    truth = manifest["components"]["crate"]["pose"]
    spec = mujoco.MjSpec.from_file(str(out / "scene.xml"))
    eye = np.array(truth["xyz"]) + [0.2, -0.1, 1.0]  # ~1 m above the lid, a little aside
    spec.worldbody.add_camera(name="top", pos=eye, fovy=58, resolution=[640, 480])
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    with mujoco.Renderer(m, 480, 640) as r:
        r.update_scene(d, camera="top")
        rgb = r.render().copy()
        r.enable_depth_rendering()
        r.update_scene(d, camera="top")
        depth = r.render().copy()
    cam = m.camera("top").id
    pose = camera_pose(d.cam_xpos[cam], d.cam_xmat[cam])
    found = localize(rgb, depth, CameraModel(640, 480, 58.0), pose, manifest["fiducials"])
    assert found["crate"].tags == (7,)
    assert np.linalg.norm(found["crate"].position - truth["xyz"]) < 0.005
    assert abs(math.degrees(found["crate"].yaw - truth["yaw"])) < 0.5
