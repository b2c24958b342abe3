"""URDFs with <mujoco> extensions (tests/data/extension) merge into MJCF that
matches stored golden files (tests/golden/extension) after canonical
normalisation, and MuJoCo 4.0 compiles each into a model with the intended
effects. Regenerate only with
``pytest tests/test_extension_golden.py --update-golden`` and review the diff."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from tests.golden import canonical
from urdf2mjcf.mjcf.document import Document
from urdf2mjcf.passes import collision, emit, extension, inertia, meshes, parse, validate, xacro

INPUTS = Path(__file__).parent / "data" / "extension"
GOLDEN = Path(__file__).parent / "golden" / "extension"
CASES = sorted(p.stem for p in INPUTS.glob("*.urdf"))


def convert(case: str) -> Document:
    doc = xacro.run(INPUTS / f"{case}.urdf", xacro.XacroConfig(use_environment=False))
    model = inertia.run(
        collision.run(meshes.run(parse.run(doc), meshes.MeshConfig()), collision.CollisionConfig()),
        inertia.InertiaConfig(),
    )
    result = emit.run(model, emit.EmitConfig())
    return extension.run(result, model, extension.ExtensionConfig(resolver=doc.resolver))


def compiled(result: Document) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(result.xml.decode(), dict(result.files))


@pytest.mark.parametrize("case", CASES)
def test_extension_matches_golden_file(case, update_golden):
    got = canonical(convert(case).xml)
    golden = GOLDEN / f"{case}.xml"
    if update_golden:
        golden.parent.mkdir(parents=True, exist_ok=True)
        golden.write_text(got)
        pytest.skip(f"rewrote {golden.name}")
    assert golden.is_file(), f"no golden file {golden}; run pytest --update-golden and review it"
    assert got == golden.read_text(), f"{case}: output differs from {golden} (see diff above)"


def test_raw_sections_take_effect_in_mujoco():
    result = convert("raw_sections")
    m = compiled(result)
    d = mujoco.MjData(m)
    # option merged, ours kept
    assert m.opt.timestep == 0.001
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # extra body with a mesh geom under the named link; the mesh file was copied
    gripper = m.body("gripper")
    assert m.body(gripper.parentid[0]).name == "forearm"
    box = m.geom("gripper_box")
    assert box.bodyid[0] == gripper.id and box.type[0] == mujoco.mjtGeom.mjGEOM_MESH
    np.testing.assert_allclose(box.friction, [1.5, 0.01, 0.001])  # class 'rubber'
    assert m.mesh("box").id == box.dataid[0]
    stl = (INPUTS.parent / "meshes" / "box.stl").read_bytes()
    assert [f for f, data in result.files.items() if data == stl][0].startswith("assets/box_")
    assert m.site("upper_marker").bodyid[0] == m.body("upper_arm").id
    assert m.body("target").mocapid[0] == 0
    # the existing collision class gained solref; the new class does not inherit it
    np.testing.assert_allclose(m.geom("base_collision").solref, [0.01, 1])
    # contact exclude (body ids packed as (body1 << 16) + body2) and pair
    base, forearm = m.body("base").id, m.body("forearm").id
    assert (base << 16) + forearm in m.exclude_signature
    assert m.npair == 1
    np.testing.assert_allclose(m.pair_friction[0], [1, 1, 0.005, 0.0001, 0.0001])
    # tendon driven by an actuator and read by a sensor
    assert m.ntendon == 1 and m.actuator_trntype[0] == mujoco.mjtTrn.mjTRN_TENDON
    assert m.equality("lock").id == 0 and not m.eq_active0[0]
    d.qpos[:] = [0.3, 0.1]
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(d.sensor("coupling_pos").data, [0.2])
    # keyframe 'home' replaced in place, 'ready' added
    assert [m.key(i).name for i in range(m.nkey)] == ["home", "ready"]
    np.testing.assert_allclose(m.key("home").qpos, [0.3, -0.6])
    assert result.qpos_home == (0.3, -0.6)
    assert any("meshdir" in n.message for n in result.notes)


def test_overrides_take_effect_in_mujoco():
    result = convert("overrides")
    m = compiled(result)
    elbow, shoulder = m.joint("elbow"), m.joint("shoulder")
    assert m.dof_armature[elbow.dofadr[0]] == 0.1
    assert m.dof_damping[elbow.dofadr[0]] == 2
    assert m.dof_damping[shoulder.dofadr[0]] == 0.5  # URDF dynamics kept
    assert m.dof_frictionloss[shoulder.dofadr[0]] == 0  # removed with frictionloss=""
    np.testing.assert_allclose(m.geom("base_collision").friction, [1.2, 0.005, 0.0001])
    assert m.body_gravcomp[m.body("forearm").id] == 1
    # the actuator added by the first <mujoco>, overridden there and by the second
    act = m.actuator("elbow")
    assert act.gainprm[0] == 5000 and act.biasprm[1] == -5000 and act.biasprm[2] == -50
    site = m.site("tool")
    assert site.type[0] == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(site.size, [0.01, 0.01, 0.01])


@pytest.mark.parametrize("case", CASES)
def test_merged_model_passes_validation(case, tmp_path):
    """Compiles from disk with its copied assets and steps 1 s without a warning."""
    result = convert(case)
    for rel, data in result.files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes(data)
    (tmp_path / f"{case}.xml").write_bytes(result.xml)
    checked = validate.run(tmp_path / f"{case}.xml", validate.ValidateConfig())
    assert checked is not None and checked.steps > 0
