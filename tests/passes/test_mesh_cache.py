"""The disk cache of loaded meshes, through ``urdf2mjcf.convert``: a second conversion
decodes no mesh file and writes the same bytes; a changed mesh file, side file
(texture) or option is loaded again; a corrupt entry is rebuilt; the cache is held
to its size bound, least recently used entries first.

The reference for "the same output" is a conversion with the cache switched off.
Hits and misses are read from ``urdf2mjcf.passes.meshes.cache.stats``, which counts what
the cache answered; every test also checks the files written.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

import urdf2mjcf
from urdf2mjcf import cache
from urdf2mjcf.passes.meshes import cache as mesh_cache

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"

URDF = """<robot name="cached">
  <link name="base">
    <visual><geometry><mesh filename="meshes/textured_quad.obj"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/box.stl" scale="{box_scale}"/></geometry>
    </collision>
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <link name="arm">
    <visual><geometry><mesh filename="meshes/colored_box.dae"/></geometry></visual>
    <visual><geometry><mesh filename="meshes/ball.stl"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/ball.stl"/></geometry></collision>
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <joint name="j" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/>
  </joint>
</robot>
"""
FILES = 4
"""Distinct mesh files (and scales) the robot loads: the OBJ, the DAE, the box, the ball."""


def make_robot(folder: Path, box_scale: str = "1 1 1") -> Path:
    meshes = folder / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    for name in ("textured_quad.obj", "textured_quad.mtl", "quadrants.png", "colored_box.dae"):
        shutil.copy(MESHES / name, meshes / name)
    shutil.copy(MESHES / "box.stl", meshes / "box.stl")
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.05)  # 1280 faces: decimated
    ball.export(meshes / "ball.stl")
    urdf = folder / "robot.urdf"
    urdf.write_text(URDF.format(box_scale=box_scale))
    return urdf


def convert(urdf: Path, out: Path, cache_dir: Path | None, **options):
    report = urdf2mjcf.convert(
        urdf,
        out / "robot.xml",
        use_environment=False,
        cache_dir=cache_dir,
        use_cache=cache_dir is not None,
        max_faces=options.pop("max_faces", 600),
        overwrite=True,
        **options,
    )
    return report, {
        str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()
    }


def counted(fn):
    """(fn's result, what the mesh caches answered meanwhile)."""
    before = dataclasses.replace(mesh_cache.stats)
    result = fn()
    after = mesh_cache.stats
    return result, {
        f.name: getattr(after, f.name) - getattr(before, f.name)
        for f in dataclasses.fields(after)
    }


def entries(root: Path) -> list[Path]:
    return sorted((root / "meshes").glob("*.bin"))


@pytest.fixture
def robot(tmp_path) -> Path:
    return make_robot(tmp_path / "robot")


def test_second_conversion_decodes_nothing_and_writes_the_same_bytes(robot, tmp_path):
    store = tmp_path / "cache"
    (first, files), cold = counted(lambda: convert(robot, tmp_path / "a", store))
    assert cold == {"hits": 0, "misses": FILES, "stored": FILES, "rejected": 0}
    assert len(entries(store)) == FILES
    (second, again), warm = counted(lambda: convert(robot, tmp_path / "b", store))
    assert warm == {"hits": FILES, "misses": 0, "stored": 0, "rejected": 0}
    _, reference = convert(robot, tmp_path / "c", None)  # no cache at all
    assert files == again == reference
    # what the load reported comes back with it: the ball's decimation, in order
    assert first.notes == second.notes
    assert any(n.kind == "decimated" and "ball.stl" in n.element for n in second.notes)
    # the texture and the DAE's own colours survived the trip
    assert any(name.endswith(".png") for name in again)
    assert b'rgba="0.8 0.102 0.102 1"' in again["robot.xml"]


def test_a_changed_mesh_file_is_loaded_again(robot, tmp_path):
    store = tmp_path / "cache"
    _, before = convert(robot, tmp_path / "a", store)
    bigger = trimesh.creation.icosphere(subdivisions=3, radius=0.08)
    bigger.export(robot.parent / "meshes" / "ball.stl")
    (_, after), stats = counted(lambda: convert(robot, tmp_path / "b", store))
    assert stats["misses"] == 1 and stats["hits"] == FILES - 1 and stats["stored"] == 1
    _, reference = convert(robot, tmp_path / "c", None)
    assert after == reference
    assert after != before


def test_changed_options_are_loaded_again(robot, tmp_path):
    store = tmp_path / "cache"
    convert(robot, tmp_path / "a", store)
    # the face limit shapes every mesh's entry
    (_, fewer), stats = counted(lambda: convert(robot, tmp_path / "b", store, max_faces=300))
    assert stats["misses"] == FILES and stats["hits"] == 0
    assert fewer == convert(robot, tmp_path / "c", None, max_faces=300)[1]
    # a URDF scale is part of the mesh's identity: only the box is loaded again
    scaled = make_robot(tmp_path / "scaled", box_scale="2 2 2")
    (_, files), stats = counted(lambda: convert(scaled, tmp_path / "d", store))
    assert stats["misses"] == 1 and stats["hits"] == FILES - 1
    assert files == convert(scaled, tmp_path / "e", None)[1]


def test_a_changed_texture_is_loaded_again(robot, tmp_path):
    # the OBJ's bytes are the same; its .mtl names a texture whose pixels changed
    store = tmp_path / "cache"
    _, before = convert(robot, tmp_path / "a", store)
    png = robot.parent / "meshes" / "quadrants.png"
    with Image.open(png) as img:
        Image.new(img.mode, img.size, "yellow").save(png)
    (_, after), stats = counted(lambda: convert(robot, tmp_path / "b", store))
    assert stats["rejected"] == 1 and stats["misses"] == 1 and stats["hits"] == FILES - 1
    reference = convert(robot, tmp_path / "c", None)[1]
    assert after == reference
    textures = {k for k in after if k.endswith(".png")}
    assert textures and textures != {k for k in before if k.endswith(".png")}
    # the rewritten entry holds: a third conversion hits everything
    _, stats = counted(lambda: convert(robot, tmp_path / "d", store))
    assert stats["hits"] == FILES


def test_corrupt_entries_are_rebuilt(robot, tmp_path):
    store = tmp_path / "cache"
    _, files = convert(robot, tmp_path / "a", store)
    paths = entries(store)
    valid_other = paths[3].read_bytes()
    paths[0].write_bytes(paths[0].read_bytes()[: len(paths[0].read_bytes()) // 2])  # truncated
    paths[1].write_bytes(os.urandom(2000))  # garbage
    paths[2].write_bytes(valid_other)  # a whole entry, but another mesh's
    paths[3].write_bytes(b"")  # empty
    (_, again), stats = counted(lambda: convert(robot, tmp_path / "b", store))
    assert stats["rejected"] == FILES and stats["stored"] == FILES
    assert again == files
    _, stats = counted(lambda: convert(robot, tmp_path / "c", store))
    assert stats == {"hits": FILES, "misses": 0, "stored": 0, "rejected": 0}


def test_without_the_cache_nothing_is_read_or_written(robot, tmp_path):
    store = tmp_path / "cache"
    convert(robot, tmp_path / "a", store)
    for path in entries(store):
        path.write_bytes(b"garbage")  # read, it would count as rejected
    _, stats = counted(
        lambda: urdf2mjcf.convert(
            robot, tmp_path / "b" / "robot.xml", cache_dir=store, use_cache=False
        )
    )
    assert stats == {"hits": 0, "misses": 0, "stored": 0, "rejected": 0}
    assert all(p.read_bytes() == b"garbage" for p in entries(store))


# -- the size bound ---------------------------------------------------------------


def test_least_recently_used_entries_go_first(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    blob = bytes(100_000)
    now = time.time()
    # entries are named as make_key names them: eviction deletes nothing else
    name = {k: cache.make_key({"entry": k}) + ".bin" for k in "abcd"}
    for age, k in ((3, "a"), (2, "b"), (1, "c")):  # hours since last use
        cache.write_entry(root / "meshes", name[k], blob)
        os.utime(root / "meshes" / name[k], (now - age * 3600,) * 2)
    assert cache.read_entry(root / "meshes" / name["a"]) == blob  # a is used again: newest
    # room for two and a half: writing a fourth deletes down to 90 % of the bound,
    # the least recently used first (b, then c; a was just read)
    monkeypatch.setenv("URDF2MJCF_CACHE_MAX_MB", str(250_000 / 2**20))
    cache.write_entry(root / "meshes", name["d"], blob)
    left = sorted(p.name for p in (root / "meshes").iterdir())
    assert left == sorted([name["a"], name["d"]])
    assert cache.info(root).bytes <= 250_000
    assert cache.is_ours(root), "the first write marked the folder as ours"


def test_a_conversion_keeps_the_cache_within_its_bound(robot, tmp_path, monkeypatch):
    store = tmp_path / "cache"
    convert(robot, tmp_path / "a", store)
    old = entries(store)
    size = cache.info(store).bytes
    for path in store.rglob("*.*"):
        os.utime(path, (time.time() - 3600,) * 2)  # used an hour ago
    # a second robot whose meshes are new: twice the room of the first
    other = make_robot(tmp_path / "other", box_scale="3 3 3")
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.07)
    ball.export(other.parent / "meshes" / "ball.stl")
    limit = int(size * 1.1)
    monkeypatch.setenv("URDF2MJCF_CACHE_MAX_MB", str(limit / 2**20))
    _, files = convert(other, tmp_path / "b", store)
    assert cache.info(store).bytes <= limit
    assert not all(p.exists() for p in old)  # the old robot's entries made the room
    # whatever was evicted, the output is what no cache gives
    assert files == convert(other, tmp_path / "c", None)[1]


def test_entries_hold_exact_arrays(robot, tmp_path):
    """The arrays a hit hands back are the arrays the load made, to the bit."""
    store = tmp_path / "cache"
    first, _ = convert(robot, tmp_path / "a", store)
    second, _ = convert(robot, tmp_path / "b", store)
    assert first.model is not None and second.model is not None
    for key, loaded in first.model.meshes.items():
        hit = second.model.meshes[key]
        assert hit.sha256 == loaded.sha256
        for a, b in zip((loaded.merged, *(p.mesh for p in loaded.parts)),
                        (hit.merged, *(p.mesh for p in hit.parts)), strict=True):
            assert a.vertices.dtype == b.vertices.dtype == np.float64
            assert a.faces.dtype == b.faces.dtype == np.int64
            np.testing.assert_array_equal(a.vertices, b.vertices)
            np.testing.assert_array_equal(a.faces, b.faces)
            assert (a.uv is None) == (b.uv is None)
            if a.uv is not None:
                np.testing.assert_array_equal(a.uv, b.uv)
        assert [p.material for p in loaded.parts] == [p.material for p in hit.parts]
