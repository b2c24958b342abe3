"""Property-based fuzzing of the cache-entry readers: arbitrary bytes, and mutations of
real entries (a mesh entry's JSON header and arrays, a decomposition's ``.npz``
members, a hull gap's JSON), read through ``MeshCache.load`` and the decomposition
cache. Each read gives either a consistent entry or None (a miss); never an
exception, never a hang (each example runs under an alarm)."""

from __future__ import annotations

import functools
import io
import json
import math
import shutil
import signal
import struct
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, get_args

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import urdf2mjcf
from urdf2mjcf import untrusted
from urdf2mjcf.ir import MeshData, NoteKind
from urdf2mjcf.passes import meshes
from urdf2mjcf.passes.collision.convexity import HullFigures
from urdf2mjcf.passes.collision.decompositions import DecompositionCache
from urdf2mjcf.passes.meshes import cache as mesh_cache

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
MAGIC = b"urdf2mjcf-mesh\0\0"
KEY = "5" * 64
SECONDS = 20
"""Wall-clock bound of one example (a hang fails the test)."""
SETTINGS = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
URDF = """<robot name="fuzz">
  <link name="base">
    <visual><geometry><mesh filename="meshes/textured_quad.obj"/></geometry></visual>
    <visual><geometry><mesh filename="meshes/colored_box.dae"/></geometry></visual>
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>
"""


@contextmanager
def bounded(seconds: float = SECONDS) -> Iterator[None]:
    def expired(signum: int, frame: Any) -> None:
        raise AssertionError(f"an entry took more than {seconds} s to read")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# -- real entries -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def real(tmp_path_factory) -> dict[str, Any]:
    """Mesh entries from a real conversion (a textured OBJ with a side .mtl and PNG, a
    coloured DAE) by key, the side-file reader of each, and a folder to fuzz in."""
    tmp = tmp_path_factory.mktemp("fuzz")
    (tmp / "robot" / "meshes").mkdir(parents=True)
    for name in ("textured_quad.obj", "textured_quad.mtl", "quadrants.png", "colored_box.dae"):
        shutil.copy(MESHES / name, tmp / "robot" / "meshes" / name)
    (tmp / "robot" / "robot.urdf").write_text(URDF)
    store = tmp / "cache"
    urdf2mjcf.convert(
        tmp / "robot" / "robot.urdf",
        tmp / "out" / "robot.xml",
        use_environment=False,
        cache_dir=store,
        validate_model=False,
    )
    entries = {p.stem: p.read_bytes() for p in (store / "meshes").glob("*.bin")}
    assert len(entries) == 2
    textured = next(k for k, data in entries.items() if b"textured_quad.mtl" in data)
    read = functools.partial(meshes._side_file, tmp / "robot" / "meshes" / "textured_quad.obj")
    for key in entries:  # unchanged, each is a hit
        assert mesh_cache.MeshCache(store).load(key, read) is not None
    return {"entries": entries, "textured": textured, "read": read, "root": tmp / "fuzzed"}


def load_mesh(real: dict[str, Any], key: str, data: bytes) -> mesh_cache.Entry | None:
    cache = mesh_cache.MeshCache(real["root"])
    cache.dir.mkdir(parents=True, exist_ok=True)
    cache.path(key).write_bytes(data)
    with bounded():
        entry = cache.load(key, real["read"])
    if entry is not None:
        assert_consistent(entry)
    return entry


def assert_mesh(mesh: MeshData) -> None:
    v, f, uv = mesh.vertices, mesh.faces, mesh.uv
    assert v.dtype == np.float64 and v.ndim == 2 and v.shape[1] == 3
    assert np.isfinite(v).all()
    assert f.dtype == np.int64 and f.ndim == 2 and f.shape[1] == 3 and len(f) > 0
    assert f.min() >= 0 and f.max() < len(v)
    if uv is not None:
        assert uv.shape == (len(v), 2) and np.isfinite(uv).all()


def assert_consistent(entry: mesh_cache.Entry) -> None:
    """What the meshes pass may use without a second look: plain names, file names
    that stay in ``assets/``, finite in-range arrays, references that resolve."""
    assert entry.parts
    for part in entry.parts:
        assert_mesh(part.mesh)
        assert part.material is None or part.material in entry.palette
    assert_mesh(entry.merged)
    for name, (material, texture) in entry.palette.items():
        assert untrusted.is_plain_name(name) and material.name == name
        assert len(material.rgba) == 4 and all(0.0 <= c <= 1.0 for c in material.rgba)
        assert (texture is None) == (material.texture is None)
        if texture is not None:
            assert untrusted.is_plain_name(texture.name) and texture.name == material.texture
            assert texture.file == f"{texture.name}.png"
            assert texture.data.startswith(b"\x89PNG\r\n\x1a\n")
    for kind, message in entry.notes:
        assert kind in get_args(NoteKind) and isinstance(message, str)
    for name, digest in entry.deps:
        assert isinstance(name, str) and untrusted.printable(name) == name
        assert digest is None or len(digest) == 64


def unpack(data: bytes) -> tuple[dict, bytes]:
    (size,) = struct.unpack_from("<Q", data, len(MAGIC))
    base = len(MAGIC) + 8 + size
    return json.loads(data[len(MAGIC) + 8 : base]), data[base:]


def pack(meta: Any, body: bytes) -> bytes:
    header = json.dumps(meta).encode()
    header += b" " * (-len(header) % 8)
    return MAGIC + struct.pack("<Q", len(header)) + header + body


# -- strategies ---------------------------------------------------------------------------

NASTY = st.sampled_from(
    [
        "../../../../../../x/victim.txt",
        "/dev/zero",
        "/etc/passwd",
        "..",
        ".",
        "",
        "a/b",
        "\x1b[31mred",
        "x\x00y",
        "quadrants_f4f2f616ce",
        "quadrants_f4f2f616ce.png",
        "CON",
        "a" * 300,
    ]
)
JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=20)
    | NASTY,
    lambda inner: (
        st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)


def paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path (keys and indices) into a JSON value."""
    out = [prefix]
    if isinstance(value, dict):
        for k, v in value.items():
            out += paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += paths(v, (*prefix, i))
    return out


def mutate(meta: Any, path: tuple, op: str, new: Any) -> Any:
    if not path:
        return new if op != "delete" else {}
    parent = meta
    for step in path[:-1]:
        parent = parent[step]
    last = path[-1]
    if op == "delete":
        del parent[last]
    elif op == "append" and isinstance(parent[last], list):
        parent[last].append(new)
    else:
        parent[last] = new
    return meta


# -- the mesh cache -----------------------------------------------------------------------


@SETTINGS
@given(data=st.binary(max_size=2048) | st.binary(max_size=2048).map(lambda b: MAGIC + b))
def test_arbitrary_bytes_are_a_miss(real, data):
    assert load_mesh(real, KEY, data) is None


@SETTINGS
@given(header=JSON, body=st.binary(max_size=512))
def test_arbitrary_headers_are_a_miss(real, header, body):
    assert load_mesh(real, KEY, pack(header, body)) is None


@SETTINGS
@given(
    which=st.sampled_from(["textured", "other"]),
    edits=st.lists(
        st.tuples(st.integers(0, 10**6), st.sampled_from(["set", "delete", "append"]), JSON),
        min_size=1,
        max_size=3,
    ),
)
def test_mutated_headers_of_real_entries_are_consistent_or_a_miss(real, which, edits):
    key = real["textured"]
    if which == "other":
        key = next(k for k in real["entries"] if k != real["textured"])
    meta, body = unpack(real["entries"][key])
    for index, op, new in edits:
        choices = paths(meta)
        try:
            meta = mutate(meta, choices[index % len(choices)], op, new)
        except (KeyError, IndexError, TypeError):
            continue
    load_mesh(real, key, pack(meta, body))


@SETTINGS
@given(
    flips=st.lists(st.tuples(st.integers(0, 10**7), st.integers(1, 255)), min_size=1, max_size=8),
    cut=st.integers(0, 10**7) | st.none(),
)
def test_corrupted_bytes_of_real_entries_are_consistent_or_a_miss(real, flips, cut):
    data = bytearray(real["entries"][real["textured"]])
    for at, xor in flips:
        data[at % len(data)] ^= xor
    if cut is not None:
        del data[cut % len(data) :]
    load_mesh(real, real["textured"], bytes(data))


def test_the_fuzzed_reader_still_hits_on_real_entries(real):
    for key, data in real["entries"].items():
        assert load_mesh(real, key, data) is not None


# -- the decomposition cache ----------------------------------------------------------------

TETRA = MeshData(
    np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64),
    np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64),
)


@pytest.fixture(scope="module")
def decomposition(tmp_path_factory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("decomp")
    cache = DecompositionCache(root)
    cache.store(KEY, [TETRA, TETRA])
    cache.store_hull(KEY, TETRA)
    cache.store_gap(KEY, 0.25)
    with np.load(cache.path(KEY)) as npz:
        arrays = {name: npz[name] for name in npz.files}
    return {"cache": cache, "root": root, "arrays": arrays}


def assert_parts(parts: list[MeshData] | None) -> None:
    if parts is not None:
        assert 0 < len(parts)
        for part in parts:
            assert_mesh(part)


def load_all(d: dict[str, Any], coacd: bytes | None = None, gap: bytes | None = None) -> None:
    cache: DecompositionCache = d["cache"]
    root: Path = d["root"]
    if coacd is not None:
        cache.path(KEY).write_bytes(coacd)
        (root / "hulls" / f"{KEY}.npz").write_bytes(coacd)
    if gap is not None:
        (root / "hull_gap" / f"{KEY}.json").write_bytes(gap)
    with bounded():
        assert_parts(cache.load(KEY))
        hull = cache.load_hull(KEY)
        if hull is not None:
            assert_mesh(hull)
        value = cache.load_gap(KEY)
        figures = cache.load_hull_figures(KEY)
    assert value is None or (isinstance(value, float) and math.isfinite(value) and value >= 0)
    if figures is not None:
        numbers = [figures.hausdorff_m, figures.diagonal_m]
        numbers += [] if figures.volume_ratio is None else [figures.volume_ratio]
        assert all(isinstance(x, float) and math.isfinite(x) and x >= 0 for x in numbers)


@SETTINGS
@given(data=st.binary(max_size=2048) | st.binary(max_size=2048).map(lambda b: b"PK\x03\x04" + b))
def test_decomposition_arbitrary_bytes_are_a_miss(decomposition, data):
    load_all(decomposition, coacd=data, gap=data)
    assert decomposition["cache"].load(KEY) is None


@SETTINGS
@given(value=JSON)
def test_hull_gap_arbitrary_json_is_a_number_or_a_miss(decomposition, value):
    load_all(decomposition, gap=json.dumps({"key": KEY, "gap": value}).encode())
    load_all(decomposition, gap=json.dumps(value).encode())
    load_all(decomposition, gap=json.dumps({"key": KEY, "gap": 0.1, "hull": value}).encode())
    hull = {"volume_ratio": value, "hausdorff_m": value, "diagonal_m": 0.1}
    load_all(decomposition, gap=json.dumps({"key": KEY, "gap": 0.1, "hull": hull}).encode())


ARRAYS = hnp.arrays(
    dtype=st.sampled_from(["<f8", "<f4", "<i8", "<i4", "|u1", "|b1", "<c16", "<U3", "|S2"]),
    shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5),
)


@SETTINGS
@given(
    member=st.sampled_from(["format", "key", "count", "v0", "f0", "v1", "f1", "v2", "extra"]),
    op=st.sampled_from(["replace", "delete"]),
    array=ARRAYS,
    compressed=st.booleans(),
)
def test_mutated_npz_members_are_consistent_or_a_miss(decomposition, member, op, array, compressed):
    arrays = dict(decomposition["arrays"])
    if op == "delete":
        arrays.pop(member, None)
    else:
        arrays[member] = array
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    load_all(decomposition, coacd=buf.getvalue())


def test_a_deflate_bomb_member_is_refused_before_it_is_read(decomposition):
    """A member declaring 2**31 float64s, deflated to a few kB: np.load would allocate and
    inflate 16 GB; the reader refuses any compressed member first."""
    header = np.lib.format.header_data_from_array_1_0(np.zeros((1, 3)))
    header["shape"] = (2**31 // 3, 3)
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, header)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, value in decomposition["arrays"].items():
            if name != "v0":
                item = io.BytesIO()
                np.lib.format.write_array(item, value)
                archive.writestr(f"{name}.npy", item.getvalue())
        with archive.open("v0.npy", "w", force_zip64=True) as member:
            member.write(out.getvalue())
            zeros = bytes(2**20)
            for _ in range(64):  # 64 MB of zeros: enough to prove the point, quick to write
                member.write(zeros)
    load_all(decomposition, coacd=buf.getvalue())
    assert decomposition["cache"].load(KEY) is None


def test_the_decomposition_reader_still_hits_on_real_entries(decomposition):
    cache: DecompositionCache = decomposition["cache"]
    cache.store(KEY, [TETRA, TETRA])
    cache.store_hull(KEY, TETRA)
    cache.store_gap(KEY, 0.25)
    assert len(cache.load(KEY) or []) == 2
    assert cache.load_hull(KEY) is not None
    assert cache.load_gap(KEY) == 0.25
    assert cache.load_hull_figures(KEY) is None  # a gap stored without the hull's figures
    figures = HullFigures(volume_ratio=None, hausdorff_m=0.003, diagonal_m=0.2)
    cache.store_gap(KEY, 0.25, figures)
    assert cache.load_gap(KEY) == 0.25 and cache.load_hull_figures(KEY) == figures
