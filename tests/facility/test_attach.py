"""A facility is assembled, not pasted: each component is compiled once on its own into
``components/`` and that model is attached into the world at its placement
(urdf2mjcf/facility/attach.py). Checked against what the scene holds, and the attach
itself against MuJoCo's own (``MjSpec.attach``)."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf import api
from urdf2mjcf.errors import InputError
from urdf2mjcf.facility import attach
from urdf2mjcf.facility.build import NAMED_PACKAGES, PACKAGE_DIRS, build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]

# every component of the iMETRO table, with the flags that change components on
EVERYTHING = {
    "hatch_4040": "true",
    "second_trainer": "true",
    "shelf": "true",
    "cable_housing": "true",
    "strap_stiffness": "400",
    "trainer_bench": "deck",
}


@pytest.fixture(scope="module")
def everything(tmp_path_factory) -> Path:
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", sets=EVERYTHING)
    out = tmp_path_factory.mktemp("attach") / "everything"
    build_facility(recipe, out, root=ROOT)
    return out


def _home(m: mujoco.MjModel) -> mujoco.MjData:
    d = mujoco.MjData(m)
    if m.nkey:  # a model without joints has no home key
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return d


def _frame(pos: np.ndarray, mat: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = np.asarray(mat).reshape(3, 3), pos
    return t


def _names(m: mujoco.MjModel, kind: str, count: int) -> list[str]:
    return [getattr(m, kind)(i).name for i in range(count) if getattr(m, kind)(i).name]


def _compare(scene: mujoco.MjModel, part: mujoco.MjModel, root: str) -> list[str]:
    """What differs between the component file ``part`` and its bodies in ``scene``:
    everything relative to the component's root body, at both models' home keys. The
    collision geoms' contype and conaffinity are the scene's (its contact classes)."""
    ds, dp = _home(scene), _home(part)
    rs = np.linalg.inv(_frame(ds.body(root).xpos, ds.body(root).xmat))
    rp = np.linalg.inv(_frame(dp.body(root).xpos, dp.body(root).xmat))
    out: list[str] = []

    def close(what: str, a, b) -> None:
        if not np.allclose(a, b, rtol=1e-9, atol=1e-9):
            out.append(f"{what}: {a} != {b}")

    for name in _names(part, "body", part.nbody):
        if name == "world":
            continue
        bs, bp = scene.body(name), part.body(name)
        close(f"{name} mass", bs.mass, bp.mass)
        close(f"{name} inertia", bs.inertia, bp.inertia)
        close(
            f"{name} pose",
            rs @ _frame(ds.body(name).xpos, ds.body(name).xmat),
            rp @ _frame(dp.body(name).xpos, dp.body(name).xmat),
        )
        if bp.mass[0] > 0:  # a massless body's centre is not defined
            close(
                f"{name} com",
                (rs @ [*ds.body(name).xipos, 1])[:3],
                (rp @ [*dp.body(name).xipos, 1])[:3],
            )
    for name in _names(part, "joint", part.njnt):
        js, jp = scene.joint(name), part.joint(name)
        close(f"{name} type", js.type, jp.type)
        close(f"{name} range", js.range, jp.range)
        close(f"{name} stiffness", js.stiffness, jp.stiffness)
        for field in ("dof_damping", "dof_armature", "dof_frictionloss"):
            close(
                f"{name} {field}",
                getattr(scene, field)[js.dofadr[0]],
                getattr(part, field)[jp.dofadr[0]],
            )
        if jp.type[0] != mujoco.mjtJoint.mjJNT_FREE:
            close(f"{name} home", ds.qpos[js.qposadr[0]], dp.qpos[jp.qposadr[0]])
    for name in _names(part, "geom", part.ngeom):
        gs, gp = scene.geom(name), part.geom(name)
        close(f"{name} type", gs.type, gp.type)
        close(f"{name} size", gs.size, gp.size)
        for field in ("friction", "solref", "solimp", "condim", "margin", "priority"):
            close(f"{name} {field}", getattr(gs, field), getattr(gp, field))
        close(
            f"{name} pose",
            rs @ _frame(ds.geom(name).xpos, ds.geom(name).xmat),
            rp @ _frame(dp.geom(name).xpos, dp.geom(name).xmat),
        )
    for name in _names(part, "actuator", part.nu):
        a_s, a_p = scene.actuator(name), part.actuator(name)
        for field in ("gainprm", "biasprm", "ctrlrange", "forcerange", "gear"):
            close(f"{name} {field}", getattr(a_s, field), getattr(a_p, field))
        close(f"{name} home ctrl", ds.ctrl[a_s.id], dp.ctrl[a_p.id])
    for name in _names(part, "sensor", part.nsensor):
        close(
            f"{name} sensor",
            (scene.sensor(name).type, scene.sensor(name).dim),
            (part.sensor(name).type, part.sensor(name).dim),
        )
    for name in _names(part, "eq", part.neq):
        close(f"{name} equality", scene.eq(name).data, part.eq(name).data)
        close(f"{name} solref", scene.eq(name).solref, part.eq(name).solref)
    for name in _names(part, "site", part.nsite) + _names(part, "cam", part.ncam):
        kind = "site" if name in _names(part, "site", part.nsite) else "cam"
        close(
            f"{name} pose",
            rs @ _frame(getattr(ds, kind)(name).xpos, getattr(ds, kind)(name).xmat),
            rp @ _frame(getattr(dp, kind)(name).xpos, getattr(dp, kind)(name).xmat),
        )
    return out


def _roots(m: mujoco.MjModel) -> list[str]:
    return [m.body(b).name for b in range(1, m.nbody) if m.body_parentid[b] == 0]


def test_every_component_file_is_the_model_the_scene_holds(everything):
    manifest = json.loads((everything / "facility.json").read_text())
    scene = mujoco.MjModel.from_xml_path(str(everything / "scene.xml"))
    files = {
        "robot": "components/imetro_robot/imetro_robot.xml",
        "trainer": "components/trainer/stowage_unit.xml",
        "second_trainer": "components/second_trainer/stowage_unit.xml",
        "hatch_4060": "components/hatch_4060/hatch.xml",
        "hatch_4040": "components/hatch_4040/hatch.xml",
        "express_rack": "components/express_rack/express_rack.xml",
        "shelf": "components/shelf/shelf.xml",
        "ctb": "components/ctb/ctb.xml",
    }
    assert sorted(manifest["components"]) == sorted(files)
    counted = {"body": 1, "joint": 0, "geom": 0, "actuator": 0, "sensor": 0, "eq": 0}
    for file in files.values():
        part = mujoco.MjModel.from_xml_path(str(everything / file))
        roots = _roots(part)
        assert roots, file
        assert not (diff := _compare(scene, part, roots[0])), (file, diff[:5])
        for kind, count in (
            ("body", part.nbody - 1),
            ("joint", part.njnt),
            ("geom", part.ngeom),
            ("actuator", part.nu),
            ("sensor", part.nsensor),
            ("eq", part.neq),
        ):
            counted[kind] += count
    # the scene is its world (the floor) and these parts, nothing pasted twice or lost
    floor = 1
    assert scene.nbody == counted["body"] + floor
    assert scene.njnt == counted["joint"]
    assert scene.nu == counted["actuator"] and scene.nsensor == counted["sensor"]
    assert scene.neq == counted["eq"]


def test_flags_reach_their_components(everything):
    robot = mujoco.MjModel.from_xml_path(
        str(everything / "components/imetro_robot/imetro_robot.xml")
    )
    assert mujoco.mj_name2id(robot, mujoco.mjtObj.mjOBJ_BODY, "cable_housing") >= 0
    ctb = mujoco.MjModel.from_xml_path(str(everything / "components/ctb/ctb.xml"))
    assert ctb.joint("ctb_strap_joint").stiffness[0] == 400
    assert mujoco.mj_name2id(ctb, mujoco.mjtObj.mjOBJ_BODY, "floor") < 0  # floor: false
    small = mujoco.MjModel.from_xml_path(str(everything / "components/hatch_4040/hatch.xml"))
    big = mujoco.MjModel.from_xml_path(str(everything / "components/hatch_4060/hatch.xml"))
    door = "hatch_{}_door_joint"
    assert small.dof_damping[small.joint(door.format(4040)).dofadr[0]] == 0.5
    assert big.dof_damping[big.joint(door.format(4060)).dofadr[0]] == 3
    unit = mujoco.MjModel.from_xml_path(str(everything / "components/trainer/stowage_unit.xml"))
    assert mujoco.mj_name2id(unit, mujoco.mjtObj.mjOBJ_BODY, "trainer_frame") >= 0


# -------------------------------------------------------------- against MjSpec.attach


def _emitted(source: Path, **args: str):
    _model, result = api.build(
        source, api.make_options(args=args, use_environment=False, **_packages())
    )
    return result


def _packages() -> dict:
    return {
        "package_paths": [ROOT / d for d in PACKAGE_DIRS],
        "packages": {name: ROOT / d for name, d in NAMED_PACKAGES.items()},
    }


def _compiled(result) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(result.xml.decode(), result.files)


def test_attach_places_a_component_as_mujocos_own_attach():
    """The hatch attached at a pose by our pass and by ``MjSpec.attach`` into the same
    world: every body, joint and geom where MuJoCo puts it."""
    world = _emitted(ROOT / "facility/worlds/imetro_world/urdf/imetro_facility.urdf.xacro")
    hatch = _emitted(ROOT / "facility/mockups/hatch/urdf/hatch.urdf.xacro", variant="4060")
    pos, yaw = (1.5, -0.75, 0.25), 2.5
    ours = _compiled(attach.Attach([attach.Part("hatch", hatch, pos, attach.yaw_quat(yaw))])(world))

    spec = mujoco.MjSpec.from_string(world.xml.decode(), assets=world.files)
    child = mujoco.MjSpec.from_string(hatch.xml.decode(), assets=hatch.files)
    frame = spec.worldbody.add_frame(pos=pos, quat=attach.yaw_quat(yaw))
    spec.attach(child, prefix="theirs/", frame=frame)
    theirs = spec.compile()

    d1, d2 = mujoco.MjData(ours), mujoco.MjData(theirs)
    mujoco.mj_forward(ours, d1)
    mujoco.mj_forward(theirs, d2)
    checked = 0
    for kind, count in (("body", ours.nbody), ("geom", ours.ngeom), ("joint", ours.njnt)):
        for i in range(count):
            name = getattr(ours, kind)(i).name
            if not name.startswith("hatch_4060_"):
                continue
            other = getattr(theirs, kind)("theirs/" + name)
            if kind == "joint":
                np.testing.assert_allclose(d1.xanchor[i], d2.xanchor[other.id], atol=1e-12)
                np.testing.assert_allclose(d1.xaxis[i], d2.xaxis[other.id], atol=1e-12)
                np.testing.assert_allclose(ours.jnt_range[i], theirs.jnt_range[other.id])
            else:
                a, b = getattr(d1, kind)(i), getattr(d2, kind)(other.id)
                np.testing.assert_allclose(a.xpos, b.xpos, atol=1e-12)
                np.testing.assert_allclose(a.xmat, b.xmat, atol=1e-12)
            if kind == "body":
                np.testing.assert_allclose(ours.body_mass[i], theirs.body_mass[other.id])
                np.testing.assert_allclose(d1.xipos[i], d2.xipos[other.id], atol=1e-12)
            checked += 1
    assert checked > 20


def test_a_name_twice_or_a_different_compiler_is_an_error_naming_the_component():
    world = _emitted(ROOT / "facility/worlds/imetro_world/urdf/imetro_facility.urdf.xacro")
    shelf = _emitted(ROOT / "facility/mockups/shelf/urdf/shelf.urdf.xacro", prefix="shelf_")
    twice = attach.Attach(
        [
            attach.Part("a", shelf, (0, 0, 0), (1, 0, 0, 0)),
            attach.Part("b", shelf, (2, 0, 0), (1, 0, 0, 0)),
        ],
        recipe="r.yaml",
    )
    with pytest.raises(InputError) as err:
        twice(world)
    assert "components.b" in str(err.value) and "already in the scene" in str(err.value)
    root = shelf.edit()
    root.find("compiler").set("angle", "degree")
    other = attach.Attach(
        [attach.Part("c", type(shelf)(root, shelf.files, shelf.qpos_home), (0, 0, 0), (1, 0, 0, 0))]
    )
    with pytest.raises(InputError, match="compiler"):
        other(world)


def test_the_deliver_world_names_the_rovers_it_is_assembled_with(tmp_path):
    """MIRA3D's pair: the world's regolith grains are welded to the rovers' bases, which
    only the assembled scene holds. Each rover file is the model the scene holds, and the
    welds join the world's grains to them."""
    recipe = load_recipe(ROOT / "recipes" / "mira3d-pair-floor.yaml")
    out = tmp_path / "pair"
    build_facility(recipe, out, root=ROOT)
    scene = mujoco.MjModel.from_xml_path(str(out / "scene.xml"))
    for rover in ("collector", "printer"):
        part = mujoco.MjModel.from_xml_path(str(out / "components" / rover / "mira3d_rover.xml"))
        assert not (diff := _compare(scene, part, _roots(part)[0])), (rover, diff[:5])
        weld = scene.eq(f"regolith_0_{rover}")
        assert scene.body(weld.obj1id[0]).name == f"{rover}_base_link"
        assert scene.body(weld.obj2id[0]).name == "regolith_0"


WORLD_WITH_A_WELD = """<?xml version="1.0"?>
<robot name="w">
  <link name="world"/>
  <mujoco>
    <worldbody>
      <body name="grain" pos="1 2 0.5"><freejoint name="grain_free"/>
        <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
        <geom type="sphere" size="0.05"/></body>
    </worldbody>
    <equality><weld name="held" body1="part_base" body2="grain"/></equality>
  </mujoco>
</robot>
"""


def test_a_world_may_name_what_is_attached_to_it_only_when_it_is_assembled(tmp_path):
    """``ExtensionConfig.assembly``: a world's weld to a part's body is no error before the
    part is attached, and the assembled home key starts its free body at its pose; on its
    own, the weld names no body of the model: it is dropped, with a warning naming it
    (docs/extension.md, "Names the model merged or lacks")."""
    from dataclasses import replace

    world = tmp_path / "w.urdf"
    world.write_text(WORLD_WITH_A_WELD)
    _model, alone = api.build(world, api.make_options())
    assert alone.root.find("equality/weld") is None
    warnings = [n.message for n in alone.notes if n.kind == "warning"]
    assert any("body1='part_base' names no body" in w and "dropped" in w for w in warnings)
    options = api.make_options()
    options = replace(options, extension=replace(options.extension, assembly=True))
    _model, result = api.build(world, options)
    shelf = _emitted(ROOT / "facility/mockups/shelf/urdf/shelf.urdf.xacro", prefix="part_")
    root = shelf.edit()
    root.find("worldbody/body").set("name", "part_base")
    part = attach.Part(
        "part", type(shelf)(root, shelf.files, shelf.qpos_home), (3, 0, 0), (1, 0, 0, 0)
    )
    m = _compiled(attach.Attach([part])(result))
    assert m.body(m.eq("held").obj1id[0]).name == "part_base"
    np.testing.assert_allclose(m.key("home").qpos[:3], [1, 2, 0.5])


@pytest.mark.parametrize("path", sorted((ROOT / "recipes").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_recipe_we_ship_is_assembled(path):
    """docs/facility.md, "Assembly": every component of our recipes is attached, and no
    world xacro includes a component's package."""
    recipe = load_recipe(path)
    assert all(c.attach is not None for c in recipe.components.values())
    world = (ROOT / recipe.xacro).read_text()
    packages = {Path(c.standalone).parts[2] for c in recipe.components.values()}
    assert not [p for p in packages if f"$(find {p})" in world]


@pytest.mark.parametrize(
    ("attach_value", "element", "message"),
    [
        ([1, 2], "components.shelf.attach", "mapping"),
        ({"bad name": 1}, "components.shelf.attach", "not a xacro argument name"),
        ({"prefix": [1]}, "components.shelf.attach.prefix", "one value"),
        ({"size": float("nan")}, "components.shelf.attach.size", "finite"),
        ({"prefix": "x" * 5000}, "components.shelf.attach.prefix", "characters"),
    ],
)
def test_a_bad_attach_names_its_component_and_key(attach_value, element, message):
    from urdf2mjcf.facility.recipe import parse_recipe

    shelf = {
        "asset": "shelf",
        "standalone": "facility/mockups/shelf/urdf/shelf.urdf.xacro",
        "attach": attach_value,
    }
    data = {"name": "r", "xacro": "w.xacro", "components": {"shelf": shelf}}
    with pytest.raises(InputError) as err:
        parse_recipe(data, None)
    assert element in str(err.value) and message in str(err.value)


def test_a_flag_in_attach_is_the_recipes_value_or_the_standalones_default():
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", sets={"trainer_bench": "deck"})
    trainer = recipe.components["trainer"]
    assert trainer.attach_args(recipe.flags) == {
        "prefix": "trainer_",
        "frame": "true",
        "bench": "deck",
    }
    assert trainer.attach_args({}) == {"prefix": "trainer_", "frame": "true"}
