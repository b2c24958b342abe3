"""Nothing native kills a conversion: CoACD crashing or hanging costs one mesh (its
convex hull and a warning), a corrupt cache entry is rebuilt, and conversions
sharing one cache run side by side.

The crash and the hang are real CoACD 1.0.14 behaviour on real inputs, not
stand-ins: a sliver tetrahedron lying on a face of a closed U bracket makes
its self-intersection test abort with ``Assertion `d0 != d2' failed`` (the
ROS-Industrial report), and a small triangle soup keeps it busy for a minute.
"""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from scipy.spatial import ConvexHull

import urdf2mjcf
from urdf2mjcf.cli import urdf2mjcf_command

WORKER_LOG = "urdf2mjcf.passes.collision.worker"


# ---------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------


def u_bracket(scale: float = 1.0) -> trimesh.Trimesh:
    """A closed 0.9 x 0.3 x 0.6 m block with a 0.6 m wide channel cut 0.45 m deep."""
    outer = trimesh.creation.box((0.9, 0.3, 0.6))
    cut = trimesh.creation.box((0.6, 0.6, 0.6))
    cut.apply_translation((0.0, 0.0, 0.15))
    u = trimesh.boolean.difference([outer, cut], engine="manifold")
    u.apply_scale(scale)
    return u


def aborting_bracket() -> trimesh.Trimesh:
    """The U bracket plus a closed sliver tetrahedron lying on its bottom face.

    The sliver's first triangle has two corners 2.25e-7 m below the face and one
    on it, and stands at about 65 degrees to it. CoACD (coordinates normalised
    to about [-1, 1], then float) rounds all three distances below 1e-6 to zero,
    restores the first, and its Moeller test then asserts that the first and
    third distances differ: they are equal, and the process aborts.
    """
    u = u_bracket()
    z = u.vertices[:, 2].min()
    h, d, y = 2.25e-7, 1e-7, 0.01
    sliver = np.array([(-0.2, y, z - h), (0.0, y + d, z), (0.2, y, z - h), (0.0, y - d, z)])
    tet = trimesh.Trimesh(sliver, [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]], process=False)
    assert tet.volume > 0, "outward winding, so CoACD's edge check passes"
    return trimesh.Trimesh(
        np.vstack([sliver, u.vertices]), np.vstack([tet.faces, u.faces + 4]), process=False
    )


def lattice_soup(count: int = 40, seed: int = 1) -> trimesh.Trimesh:
    """``count`` loose triangles with corners on a 4 x 4 x 4 lattice 1 cm apart.

    Hull gap 0.039, so it goes to CoACD, which works on it for about a minute
    (63 s on one core here). Corners come from a fixed LCG, so the soup never
    changes; zero-area triangles are left out (the meshes pass would drop them).
    """
    x, coords = seed, []
    while len(coords) < 9 * count:
        x = (1103515245 * x + 12345) % 2**31
        coords.append((x >> 16) % 4)
    tri = np.array(coords, dtype=float).reshape(-1, 3, 3) * 0.01
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    tri = tri[area > 1e-9]
    return trimesh.Trimesh(
        tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3), process=False
    )


def write_robot(root: Path, meshes: dict[str, trimesh.Trimesh]) -> Path:
    """A URDF with one link per mesh (in the given order), each its collision geometry."""
    (root / "meshes").mkdir(parents=True, exist_ok=True)
    links, joints = [], []
    for i, (name, mesh) in enumerate(meshes.items()):
        mesh.export(root / "meshes" / name)
        links.append(
            f'<link name="l{i}"><collision><geometry>'
            f'<mesh filename="meshes/{name}"/></geometry></collision></link>'
        )
        if i:
            joints.append(
                f'<joint name="j{i}" type="fixed"><parent link="l{i - 1}"/>'
                f'<child link="l{i}"/><origin xyz="1.5 0 0"/></joint>'
            )
    urdf = root / "robot.urdf"
    urdf.write_text(f'<robot name="robot">{"".join(links)}{"".join(joints)}</robot>\n')
    return urdf


def cli(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "urdf2mjcf", *args, "--no-ros-env"],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc: subprocess.Popen) -> tuple[int, str]:
    """Exit code, and stdout + stderr."""
    out, err = proc.communicate(timeout=600)
    return proc.returncode, err + out


def files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def collision_assets(out_dir: Path, stem: str) -> list[trimesh.Trimesh]:
    return [
        trimesh.load(p, process=True) for p in sorted((out_dir / "assets").glob(f"{stem}_*.stl"))
    ]


def assert_is_hull_of(out_dir: Path, stem: str, source: trimesh.Trimesh) -> None:
    """The mesh's only collision asset is ``<stem>_hull``, the convex hull of its vertices."""
    (asset,) = collision_assets(out_dir, stem)
    assert next((out_dir / "assets").glob(f"{stem}_hull_*.stl"))
    expected = ConvexHull(np.asarray(source.vertices)).volume  # the reference hull
    assert asset.volume == pytest.approx(expected, rel=1e-6)


def worker_pids(caplog: pytest.LogCaptureFixture) -> list[int]:
    return [
        int(m.group(1))
        for r in caplog.records
        if r.name == WORKER_LOG
        and (m := re.match(r"decomposition worker (\d+) started", r.message))
    ]


def running(pid: int) -> bool:
    """Still there, running or a zombie nobody reaped (unless the pid went to another program)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return True
    return cmdline == b"" or b"passes.collision.worker" in cmdline


# ---------------------------------------------------------------------------
# A native crash
# ---------------------------------------------------------------------------


def test_coacd_abort_gives_the_hull_and_a_warning_and_the_rest_is_decomposed(tmp_path):
    """The issue's robot: CoACD aborts on one mesh. The command still exits 0, names
    the mesh in a warning and writes its convex hull; with ``-j 1`` the next mesh
    needs a fresh worker, and gets decomposed."""
    crashing = aborting_bracket()
    urdf = write_robot(tmp_path, {"crash.stl": crashing, "bracket.stl": u_bracket(0.5)})
    out = tmp_path / "out"
    code, err = finish(
        cli(str(urdf), "-o", str(out / "robot.xml"), "-j", "1", "--no-cache", cwd=tmp_path)
    )

    assert code == 0, err
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert warnings == [
        "warning: mesh 'meshes/crash.stl': convex decomposition crashed "
        "(SIGABRT: Assertion `d0 != d2' failed); using the convex hull"
    ], err
    assert "1 decomposed" in err
    assert_is_hull_of(out, "crash", crashing)
    parts = collision_assets(out, "bracket")
    assert len(parts) >= 2 and all(p.is_convex for p in parts)


# ---------------------------------------------------------------------------
# A hang
# ---------------------------------------------------------------------------


def test_overlong_decomposition_is_killed_and_the_mesh_gets_its_hull(tmp_path, caplog):
    soup = lattice_soup()
    urdf = write_robot(tmp_path, {"soup.stl": soup})
    out = tmp_path / "out"
    args = [str(urdf), "-o", str(out / "robot.xml"), "--no-ros-env", "--no-cache"]
    with caplog.at_level(logging.DEBUG, logger=WORKER_LOG):
        result = CliRunner().invoke(urdf2mjcf_command, [*args, "--decompose-timeout", "2"])

    assert result.exit_code == 0, result.output
    assert (
        "warning: mesh 'meshes/soup.stl': convex decomposition timed out after 2 s; "
        "using the convex hull"
    ) in result.stderr.splitlines()
    assert_is_hull_of(out, "soup", soup)
    pids = worker_pids(caplog)
    assert len(pids) == 1
    assert not running(pids[0]), "the overdue worker was killed and reaped"


def test_decompose_timeout_must_not_be_negative(tmp_path):
    result = CliRunner().invoke(
        urdf2mjcf_command, ["x.urdf", "-o", str(tmp_path / "o.xml"), "--decompose-timeout", "-1"]
    )
    assert result.exit_code == 2 and "--decompose-timeout" in result.output


# ---------------------------------------------------------------------------
# The cache
# ---------------------------------------------------------------------------


def test_corrupt_cache_entries_are_rebuilt_with_identical_output(tmp_path, caplog):
    urdf = write_robot(tmp_path, {"bracket.stl": u_bracket(0.5)})
    cache = tmp_path / "cache"

    def convert(name: str) -> tuple[dict[str, bytes], list[str]]:
        out = tmp_path / name
        report = urdf2mjcf.convert(urdf, out / "robot.xml", use_environment=False, cache_dir=cache)
        return files(out), [n.kind for n in report.notes]

    clean, kinds = convert("clean")
    assert "decomposed" in kinds
    (entry,) = (cache / "coacd").glob("*.npz")
    (gap,) = (cache / "hull_gap").glob("*.json")
    good_entry, good_gap = entry.read_bytes(), gap.read_bytes()

    with caplog.at_level(logging.DEBUG, logger=WORKER_LOG):
        warm, kinds = convert("warm")
    assert warm == clean and "cached" in kinds and "decomposed" not in kinds
    assert worker_pids(caplog) == [], "a warm run starts no worker"

    for i, garbage in enumerate((good_entry[: len(good_entry) // 2], b"", b"PK\x03\x04junk")):
        entry.write_bytes(garbage)
        again, kinds = convert(f"entry{i}")
        assert again == clean and "decomposed" in kinds
        assert entry.read_bytes() == good_entry, "rebuilt"

    for i, garbage in enumerate((good_gap[:10], b"[1, 2]", good_gap.replace(b"0.", b"NaN"))):
        gap.write_bytes(garbage)
        again, kinds = convert(f"gap{i}")
        assert again == clean and "cached" in kinds
        assert gap.read_bytes() == good_gap, "rebuilt"
    assert not list(cache.rglob("*.tmp"))


def test_two_conversions_in_parallel_share_one_empty_cache(tmp_path):
    tall = u_bracket(0.5)
    tall.apply_scale((1.0, 1.0, 2.0))
    urdf = write_robot(tmp_path, {"a.stl": u_bracket(0.5), "b.stl": tall})
    cache = tmp_path / "cache"
    runs = [
        cli(
            str(urdf),
            "-o",
            str(tmp_path / f"out{i}" / "robot.xml"),
            "--cache-dir",
            str(cache),
            "-j",
            "2",
            cwd=tmp_path,
        )
        for i in range(2)
    ]
    results = [finish(p) for p in runs]
    assert [code for code, _ in results] == [0, 0], results
    reference = tmp_path / "reference"
    code, err = finish(
        cli(str(urdf), "-o", str(reference / "robot.xml"), "--no-cache", cwd=tmp_path)
    )
    assert code == 0, err

    assert files(tmp_path / "out0") == files(tmp_path / "out1") == files(reference)
    assert len(list((cache / "coacd").glob("*.npz"))) == 2
    assert not list(cache.rglob("*.tmp"))
