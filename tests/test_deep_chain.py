"""A 2000-link chain through the command line: no recursion limit in any pass.

The chain hangs from a fixed root; every link is a 5 cm cylinder with an
inertial; every 7th joint is a hinge about x and the rest are fixed (a snake
robot of 285 modules, each a motor link and six welded shell links). With
``--fuse-fixed`` it is 286 bodies deep, within what MuJoCo reads, and MuJoCo's
own forward kinematics must put the tip where the planar chain formula says.
Without fusing it is 2000 bodies deep: one error line naming MuJoCo's limit.
A 400-link snake lying on the floor overflows MuJoCo's default arena: one
error line naming the arena and the ``<size memory>`` that fixes it.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
from click.testing import CliRunner

from urdf2mjcf.cli import urdf2mjcf_command

LINKS = 2000
MODULE = 7  # joint k is a hinge when k % MODULE == 0, else fixed
L = 0.05  # link length, m
MASS = 0.1  # kg per link
HINGES = [k for k in range(1, LINKS) if k % MODULE == 0]
LAST_HINGE = HINGES[-1]
MARKER = 0.25  # the marker site, below the last hinge's link origin (m)


def _chain_urdf() -> str:
    i = MASS * L**2 / 12
    parts = ['<robot name="snake">']
    for k in range(LINKS):
        parts.append(
            f'<link name="link{k}"><inertial><origin xyz="0 0 {-L / 2}"/>'
            f'<mass value="{MASS}"/><inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" '
            f'izz="{i / 10}"/></inertial><collision><origin xyz="0 0 {-L / 2}"/>'
            f'<geometry><cylinder radius="0.01" length="{L}"/></geometry></collision></link>'
        )
        if k:
            kind = "revolute" if k % MODULE == 0 else "fixed"
            parts.append(
                f'<joint name="joint{k}" type="{kind}"><parent link="link{k - 1}"/>'
                f'<child link="link{k}"/><origin xyz="0 0 {-L}"/><axis xyz="1 0 0"/>'
                '<limit lower="-1" upper="1" effort="5" velocity="1"/></joint>'
            )
    # A site added by the <mujoco> extension: that pass re-reads the emitted MJCF,
    # deeper than libxml2 reads by default (256 nested elements).
    parts.append(
        f'<mujoco><site name="marker" parent="link{LAST_HINGE}" pos="0 0 {-MARKER}"/></mujoco>'
    )
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def _planar_chain(q: dict[int, float]) -> tuple[np.ndarray, np.ndarray]:
    """World positions of the tip link's origin and of the marker: each link
    adds L along its parent's -z, turned about x by the hinges above it."""
    y = z = theta = 0.0
    for k in range(1, LINKS):
        y, z = y + L * math.sin(theta), z - L * math.cos(theta)
        theta += q.get(k, 0.0)
        if k == LAST_HINGE:
            marker = np.array([0.0, y + MARKER * math.sin(theta), z - MARKER * math.cos(theta)])
    return np.array([0.0, y, z]), marker


def test_2000_link_chain_fused_matches_the_chain_formula(tmp_path: Path) -> None:
    urdf = tmp_path / "snake.urdf"
    urdf.write_text(_chain_urdf())
    out = tmp_path / "out" / "snake.xml"
    result = CliRunner().invoke(urdf2mjcf_command, [str(urdf), "-o", str(out), "--fuse-fixed"])
    assert result.exit_code == 0, result.output

    m = mujoco.MjModel.from_xml_path(str(out.with_name("scene.xml")))
    assert m.nbody == 1 + 1 + len(HINGES)  # world, the root link, one body per hinge
    assert m.njnt == m.nq == len(HINGES) == 285
    assert math.isclose(m.body_mass.sum(), LINKS * MASS, rel_tol=1e-9)
    # every welded link left a site where its frame is, on the body of the hinge above it
    welded = [k for k in range(1, LINKS) if k % MODULE]
    assert m.nsite == len(welded) + 1  # and the marker
    for k in (welded[0], welded[-1]):
        assert m.body(m.site_bodyid[m.site(f"link{k}").id]).name == f"link{k - k % MODULE}"

    q = {k: 0.8 * math.sin(0.37 * k) for k in HINGES}
    d = mujoco.MjData(m)
    for k, value in q.items():
        d.qpos[m.joint(f"joint{k}").qposadr[0]] = value
    mujoco.mj_kinematics(m, d)
    tip, marker = _planar_chain(q)
    np.testing.assert_allclose(d.site_xpos[m.site(f"link{LINKS - 1}").id], tip, atol=1e-9)
    np.testing.assert_allclose(d.site_xpos[m.site("marker").id], marker, atol=1e-9)
    # the chain formula is not trivially met: the tip is far from hanging straight down
    assert np.linalg.norm(tip - [0.0, 0.0, -(LINKS - 1) * L]) > 10 * L


def test_2000_link_chain_deeper_than_mujoco_reads_is_one_error(tmp_path: Path) -> None:
    urdf = tmp_path / "snake.urdf"
    urdf.write_text(_chain_urdf())
    out = tmp_path / "out" / "snake.xml"
    # the installed command's entry point, as a user runs it
    code = "from urdf2mjcf.cli import urdf2mjcf_main; urdf2mjcf_main()"
    proc = subprocess.run(
        [sys.executable, "-c", code, str(urdf), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    message = lines[0]
    assert "snake.urdf" in message and "link 'link496'" in message
    assert f"{LINKS} bodies deep" in message
    assert "at most 496 nested bodies" in message and "--fuse-fixed" in message
    assert not out.parent.exists() or not any(out.parent.iterdir())


def _snake_on_the_floor(links: int, extra: str = "") -> str:
    """A chain lying along x, hinges about z: every link rests on the scene's floor."""
    parts = ['<robot name="floor_snake">']
    for k in range(links):
        parts.append(
            f'<link name="s{k}"><inertial><origin xyz="{L / 2} 0 0"/><mass value="{MASS}"/>'
            '<inertia ixx="1e-5" ixy="0" ixz="0" iyy="2e-5" iyz="0" izz="2e-5"/></inertial>'
            f'<collision><origin xyz="{L / 2} 0 0"/><geometry><box size="{L} 0.02 0.02"/>'
            "</geometry></collision></link>"
        )
        if k:
            parts.append(
                f'<joint name="s{k}" type="revolute"><parent link="s{k - 1}"/>'
                f'<child link="s{k}"/><origin xyz="{L} 0 0"/><axis xyz="0 0 1"/>'
                '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
            )
    return "\n".join([*parts, extra, "</robot>"]) + "\n"


def test_snake_on_the_floor_past_mujocos_arena_names_the_fix(tmp_path: Path) -> None:
    # 400 links on the floor: about 1600 contacts, more than MuJoCo's default arena holds
    urdf = tmp_path / "floor_snake.urdf"
    urdf.write_text(_snake_on_the_floor(400))
    out = tmp_path / "out" / "floor_snake.xml"
    code = "from urdf2mjcf.cli import urdf2mjcf_main; urdf2mjcf_main()"
    proc = subprocess.run(
        [sys.executable, "-c", code, str(urdf), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert "scene.xml" in lines[0] and "arena" in lines[0] and "internal error" not in lines[0]
    fix = re.search(r'<mujoco><size memory="(\d+)M"/></mujoco>', lines[0])
    assert fix, lines[0]
    assert not out.exists()

    # the fix the message names, put in the URDF, converts it
    urdf.write_text(_snake_on_the_floor(400, fix.group(0)))
    result = CliRunner().invoke(urdf2mjcf_command, [str(urdf), "-o", str(out)])
    assert result.exit_code == 0, result.output
    m = mujoco.MjModel.from_xml_path(str(out.with_name("scene.xml")))
    assert m.nbody == 401 and m.narena == int(fix.group(1)) * 2**20
