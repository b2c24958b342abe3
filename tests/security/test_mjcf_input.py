"""An MJCF model or a bundle handed over by a stranger is untrusted input (issue 34,
item 3): every file it names is checked where MuJoCo would open it, at every include
depth and behind every kind of ``meshdir``; its size is bounded before MuJoCo builds
it; each failure is one error line within a time and memory bound; SIGTERM and
Ctrl-C end it at any point.

Where MuJoCo opens a file is not taken from our code: each layout below is first
loaded by MuJoCo itself with a regular file at the target (it compiles) and without
it (it fails), so the target is the file MuJoCo opens. Then the target becomes a
FIFO, a device or a socket, and the load must be refused, naming it.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import pytest

from tests.security.attack import MEMORY_LIMIT, ROOT, assert_one_error, run, snapshot
from tests.security.test_signals import descendants, running
from urdf2mjcf.bundle import SCHEMA_VERSION

MANIFEST = {"schema_version": SCHEMA_VERSION, "generator": "make-facility", "components": {}}
URDF = '<robot name="r"><link name="base"/></robot>\n'
REFUSED_WITHIN = 30.0
"""Seconds a refusal may take (a generous bound: it takes about one here)."""


# -- the files a model names -----------------------------------------------------------


def _stl() -> bytes:
    tris = [
        [(0, 0, 0), (1, 0, 0), (0, 1, 0)],
        [(0, 0, 0), (0, 1, 0), (0, 0, 1)],
        [(0, 0, 0), (0, 0, 1), (1, 0, 0)],
        [(1, 0, 0), (0, 1, 0), (0, 0, 1)],
    ]
    out = b"\0" * 80 + struct.pack("<I", len(tris))
    for tri in tris:
        out += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *v) for v in tri)
        out += b"\0\0"
    return out


def _png(side: int = 4) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (side, side), (90, 90, 90)).save(buf, format="PNG")
    return buf.getvalue()


def _skin() -> bytes:
    """A skin of one triangle bound to body ``b`` (MuJoCo's SKN format)."""
    head = struct.pack("<4i", 3, 0, 1, 1)  # vertices, texcoords, faces, bones
    verts = struct.pack("<9f", 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0)
    face = struct.pack("<3i", 0, 1, 2)
    bone = b"b".ljust(40, b"\0") + struct.pack("<3f", 0, 0, 0) + struct.pack("<4f", 1, 0, 0, 0)
    bone += struct.pack("<i", 3) + struct.pack("<3i", 0, 1, 2) + struct.pack("<3f", 1, 1, 1)
    return head + verts + face + bone


OBJ = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


@dataclass(frozen=True)
class Asset:
    """An element naming a file: its ``<asset>`` lines, what uses it, its folder kind."""

    ext: str
    content: Callable[[], bytes]
    xml: str
    use: str
    folder: str  # the compiler attribute that applies: meshdir or texturedir


SIDES = "".join(f' file{s}="side.png"' for s in ("left", "up", "down", "front", "back"))
ASSETS = {
    "mesh": Asset(".stl", _stl, '<mesh name="a" file="{f}"/>', '<geom type="mesh" mesh="a"/>',
                  "meshdir"),
    "texture": Asset(".png", _png, '<texture name="a" type="2d" file="{f}"/><material name="a" '
                     'texture="a"/>', '<geom size="1" material="a"/>', "texturedir"),
    "cube side": Asset(".png", _png, f'<texture name="a" type="cube" fileright="{{f}}"{SIDES}/>'
                       '<material name="a" texture="a"/>', '<geom size="1" material="a"/>',
                       "texturedir"),
    "hfield": Asset(".png", _png, '<hfield name="a" file="{f}" size="1 1 1 1"/>',
                    '<geom type="hfield" hfield="a"/>', "meshdir"),
    "skin": Asset(".skn", _skin, '<skin name="a" file="{f}"/>',
                  '<body name="b"><geom size="0.1"/></body>', "meshdir"),
}  # fmt: skip


@dataclass
class Layout:
    """A model and the one file (``target``) MuJoCo opens for the element under test."""

    model: Path
    target: Path
    content: bytes
    extra: list[Path]  # files beside the target it needs (a cube's other sides)


def _write(path: Path, data: str | bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data.encode() if isinstance(data, str) else data)


def _doc(body: str) -> str:
    return f"<mujoco>{body}</mujoco>\n"


def _asset_layout(folder: Path, element: str, place: str) -> Layout:
    a = ASSETS[element]
    name = "a" + a.ext
    lines = f"<asset>{a.xml.format(f=name)}</asset>"
    main = folder / "main.xml"
    world = f"<worldbody>{a.use}</worldbody>"
    here = folder  # where MuJoCo opens the file
    if place == "main":
        _write(main, _doc(lines + world))
    elif place in ("dir", "assetdir", "absolute dir", "dir twice"):
        attr = "assetdir" if place == "assetdir" else a.folder
        value = str(folder / "d") if place == "absolute dir" else "d"
        first = f'<compiler {attr}="x"/>' if place == "dir twice" else ""
        _write(main, _doc(f'{first}<compiler {attr}="{value}"/>' + lines + world))
        here = folder / "d"
    elif place == "dir in include":
        _write(folder / "conf" / "compiler.xml", _doc(f'<compiler {a.folder}="d"/>'))
        _write(main, _doc('<include file="conf/compiler.xml"/>' + lines + world))
        here = folder / "d"
    elif place == "depth 1":
        _write(folder / "sub" / "p.xml", _doc(lines))
        _write(main, _doc('<include file="sub/p.xml"/>' + world))
        here = folder / "sub"
    elif place == "depth 2":
        _write(folder / "sub" / "p.xml", _doc('<include file="deeper/q.xml"/>'))
        _write(folder / "sub" / "deeper" / "q.xml", _doc(lines))
        _write(main, _doc('<include file="sub/p.xml"/>' + world))
        here = folder / "sub" / "deeper"
    elif place == "depth 2, dir in main":
        _write(folder / "sub" / "p.xml", _doc('<include file="deeper/q.xml"/>'))
        _write(folder / "sub" / "deeper" / "q.xml", _doc(lines))
        _write(main, _doc(f'<compiler {a.folder}="d"/><include file="sub/p.xml"/>' + world))
        # MuJoCo's parse looks for a height field or skin under assetdir (unset here),
        # finds none, and falls back to the including file's folder
        here = folder / ("d" if a.folder != "meshdir" or element == "mesh" else "sub/deeper")
    elif place == "sub-model":
        robot = f'<compiler {a.folder}="d"/>{lines}<worldbody><body name="rb">{a.use}</body>'
        _write(folder / "robots" / "r.xml", _doc(robot + "</worldbody>"))
        attach = '<body name="mount"><attach model="r" body="rb" prefix="p_"/></body>'
        _write(main, _doc('<asset><model name="r" file="robots/r.xml"/></asset>'
                          f"<worldbody>{attach}</worldbody>"))  # fmt: skip
        here = folder / "robots" / "d"
    else:
        raise AssertionError(place)
    extra = []
    if element == "cube side":
        _write(here / "side.png", _png())
        extra.append(here / "side.png")
    return Layout(main, here / name, a.content(), extra)


ASSET_PLACES = [
    "main", "dir", "assetdir", "absolute dir", "dir twice", "dir in include", "depth 1",
    "depth 2", "depth 2, dir in main", "sub-model",
]  # fmt: skip
PART = _doc('<asset><material name="m" rgba="1 0 0 1"/></asset>')
ROBOT = _doc('<worldbody><body name="rb"><geom size="0.1"/></body></worldbody>')
MOUNT = '<worldbody><body name="mount"><attach model="r" body="rb" prefix="p_"/></body></worldbody>'
MODEL = '<asset><model name="r" file="r.xml"/></asset>'


def _file_layout(folder: Path, place: str) -> Layout:
    """``<include>``, ``<model>`` and ``<flexcomp file>``: read while MuJoCo parses."""
    main = folder / "main.xml"
    if place == "include":
        _write(main, _doc('<include file="part.xml"/>'))
        return Layout(main, folder / "part.xml", PART.encode(), [])
    if place == "include at depth 1":  # the including file's folder
        _write(folder / "sub" / "p.xml", _doc('<include file="q.xml"/>'))
        _write(main, _doc('<include file="sub/p.xml"/>'))
        return Layout(main, folder / "sub" / "q.xml", PART.encode(), [])
    if place == "include at depth 1, main folder first":
        _write(folder / "sub" / "p.xml", _doc('<include file="q.xml"/>'))
        # not opened while the main folder has one (MuJoCo would refuse its <oops/>)
        _write(folder / "sub" / "q.xml", _doc("<oops/>"))
        _write(main, _doc('<include file="sub/p.xml"/>'))
        return Layout(main, folder / "q.xml", PART.encode(), [])
    if place == "include at depth 2":
        _write(folder / "sub" / "p.xml", _doc('<include file="deeper/q.xml"/>'))
        _write(folder / "sub" / "deeper" / "q.xml", _doc('<include file="r.xml"/>'))
        _write(main, _doc('<include file="sub/p.xml"/>'))
        return Layout(main, folder / "sub" / "deeper" / "r.xml", PART.encode(), [])
    if place == "include in a sub-model":
        robot = '<include file="parts.xml"/><worldbody><body name="rb"><geom size="0.1"/></body>'
        _write(folder / "robots" / "r.xml", _doc(robot + "</worldbody>"))
        _write(main, _doc(MODEL.replace("r.xml", "robots/r.xml") + MOUNT))
        return Layout(main, folder / "robots" / "parts.xml", PART.encode(), [])
    if place == "model":
        _write(main, _doc(MODEL + MOUNT))
        return Layout(main, folder / "r.xml", ROBOT.encode(), [])
    if place == "model in an include":
        _write(folder / "sub" / "p.xml", _doc(MODEL))
        _write(main, _doc('<include file="sub/p.xml"/>' + MOUNT))
        return Layout(main, folder / "sub" / "r.xml", ROBOT.encode(), [])
    flex = '<body name="fb"><flexcomp name="f" type="mesh" file="c.obj" dim="2"/></body>'
    if place == "flexcomp":
        _write(main, _doc(f"<worldbody>{flex}</worldbody>"))
        return Layout(main, folder / "c.obj", OBJ, [])
    if place == "flexcomp, meshdir":
        _write(main, _doc(f'<compiler meshdir="d"/><worldbody>{flex}</worldbody>'))
        return Layout(main, folder / "d" / "c.obj", OBJ, [])
    if place == "flexcomp at depth 1":
        _write(folder / "sub" / "p.xml", _doc(f"<worldbody>{flex}</worldbody>"))
        _write(main, _doc('<include file="sub/p.xml"/>'))
        return Layout(main, folder / "sub" / "c.obj", OBJ, [])
    raise AssertionError(place)


FILE_PLACES = [
    "include", "include at depth 1", "include at depth 1, main folder first",
    "include at depth 2", "include in a sub-model", "model", "model in an include",
    "flexcomp", "flexcomp, meshdir", "flexcomp at depth 1",
]  # fmt: skip
CASES = [(e, p) for e in ASSETS for p in ASSET_PLACES if not (e == "skin" and p == "sub-model")]
CASES += [("file", p) for p in FILE_PLACES]


def _layout(folder: Path, element: str, place: str) -> Layout:
    folder.mkdir(parents=True)
    if element == "file":
        return _file_layout(folder, place)
    return _asset_layout(folder, element, place)


def _mujoco_loads(layout: Layout) -> str | None:
    """MuJoCo's own verdict on the layout (None: it compiles), in a fresh directory."""
    try:
        mujoco.MjModel.from_xml_path(str(layout.model))
    except ValueError as exc:
        return str(exc)
    return None


def _make_bad(target: Path, kind: str, keep: list[socket.socket]) -> None:
    target.unlink()
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "device":
        target.symlink_to("/dev/zero")
    else:
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(target))
        keep.append(s)


DRIVER = """
import json, sys, time
from urdf2mjcf import mjcf_input
from urdf2mjcf.errors import ConversionError
for path in json.load(open(sys.argv[1])):
    print(json.dumps({"start": path}), flush=True)
    t = time.monotonic()
    try:
        mjcf_input.load_model(path)
        error = None
    except ConversionError as exc:
        error = str(exc)
    print(json.dumps({"model": path, "error": error, "s": time.monotonic() - t}), flush=True)
"""


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _load_each(models: list[Path], work: Path) -> dict[str, dict]:
    """``mjcf_input.load_model`` of each model in a fresh process with the attack's
    memory limit; its verdict and time per model. A hang fails the test naming the
    model it hung on."""
    listing = work / "models.json"
    listing.write_text(json.dumps([str(m) for m in models]))
    empty = work / "cwd"
    empty.mkdir()
    timeout = 30 + 5 * len(models)
    proc = subprocess.Popen(
        [sys.executable, "-c", DRIVER, str(listing)],
        cwd=empty, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        stdin=subprocess.DEVNULL, preexec_fn=_limit_memory,
    )  # fmt: skip
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        started = [json.loads(line)["start"] for line in out.splitlines() if '"start"' in line]
        pytest.fail(f"loading hung on {started[-1] if started else '?'}")
    assert proc.returncode == 0, err[-3000:]
    results = [json.loads(line) for line in out.splitlines() if '"model"' in line]
    return {r["model"]: r for r in results}


def test_every_file_a_model_names_is_checked_where_mujoco_opens_it(tmp_path):
    layouts: dict[str, tuple[Layout, str]] = {}
    keep: list[socket.socket] = []
    for i, (element, place) in enumerate(CASES):
        kinds = ["fifo"] + (["device", "socket"] if place in ("main", "depth 2", "include") else [])
        for kind in kinds:
            layout = _layout(tmp_path / f"{i}-{kind}", element, place)
            _write(layout.target, layout.content)
            # MuJoCo opens exactly the target: it compiles with it, and fails without it
            verdict = _mujoco_loads(layout)
            assert verdict is None, (element, place, verdict)
            layout.target.rename(layout.target.with_suffix(".away"))
            assert _mujoco_loads(layout) is not None, (element, place)
            layout.target.with_suffix(".away").rename(layout.target)
            _make_bad(layout.target, kind, keep)
            layouts[str(layout.model)] = (layout, f"{element} / {place} / {kind}")
    results = _load_each([lay.model for lay, _ in layouts.values()], tmp_path)
    problems = []
    for model, (layout, case) in layouts.items():
        r = results[model]
        if r["error"] is None or layout.target.name not in r["error"]:
            problems.append(f"{case}: {r['error']}")
        elif "not a regular file" not in r["error"] or r["s"] > REFUSED_WITHIN:
            problems.append(f"{case}: {r['error']} ({r['s']:.1f} s)")
    for s in keep:
        s.close()
    assert not problems, "\n".join(problems)


def test_the_same_layouts_with_regular_files_load_as_mujoco_loads_them(tmp_path):
    """The checks refuse nothing MuJoCo would load from those layouts."""
    models = []
    for i, (element, place) in enumerate(CASES):
        layout = _layout(tmp_path / str(i), element, place)
        _write(layout.target, layout.content)
        models.append(layout.model)
    results = _load_each(models, tmp_path)
    refused = {m: r["error"] for m, r in results.items() if r["error"] is not None}
    assert refused == {}


# -- through the commands ------------------------------------------------------------------


def _bundle(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "facility.json").write_text(json.dumps(MANIFEST))
    return folder


@pytest.mark.parametrize("command", ["facility-demo", "rover-drive"])
@pytest.mark.parametrize(
    "place", ["dir in include", "depth 2", "depth 2, dir in main", "sub-model"]
)
def test_a_bundle_cannot_make_mujoco_open_a_fifo(tmp_path, command, place):
    """The bundle's own check missed each of these (issue 34): an include inside an
    include, a meshdir set in an included file, a sub-model."""
    layout = _layout(tmp_path / "src", "mesh", place)
    _write(layout.target, layout.content)
    folder = _bundle(tmp_path / "bundle")
    for path in layout.model.parent.rglob("*"):
        if path.is_file():
            dest = folder / path.relative_to(layout.model.parent)
            dest = dest.with_name("scene.xml") if path == layout.model else dest
            _write(dest, path.read_bytes())
    target = folder / layout.target.relative_to(layout.model.parent)
    target.unlink()
    os.mkfifo(target)
    before = snapshot(tmp_path)
    res = run(command, str(folder), cwd=tmp_path, timeout=REFUSED_WITHIN + 30)
    assert_one_error(res, target.name, "not a regular file")
    assert snapshot(tmp_path) == before


def test_a_bundle_with_an_undefined_entity_is_refused(tmp_path):
    folder = _bundle(tmp_path / "bundle")
    (folder / "evil.stl").symlink_to("/dev/zero")
    (folder / "scene.xml").write_text(
        '<mujoco><asset><mesh name="m" file="&evil;.stl"/></asset></mujoco>\n'
    )
    res = run("rover-drive", str(folder), cwd=tmp_path, timeout=REFUSED_WITHIN + 30)
    assert_one_error(res, "scene.xml", "Entity 'evil' not defined")


@pytest.mark.parametrize(
    "xml, needles",
    [
        ('<!DOCTYPE m [<!ENTITY e "evil.stl">]><mujoco><asset><mesh name="m" file="&e;"/>'
         "</asset></mujoco>", ("DOCTYPE",)),
        ('<mujoco><asset><mesh name="m" file="evil\tx.stl"/></asset></mujoco>', ("raw tab",)),
        ('<mujoco><include file="mjz:evil.xml"/></mujoco>', ("':'",)),
        ('<?xml version="1.0" encoding="ISO-8859-1"?><mujoco/>', ("encoding",)),
        ("<robot name='r'><link name='base'/></robot>", ("<robot>", "<mujoco>")),
        ('<mujoco><include file="part.xml"><geom/></include></mujoco>', ("children",)),
    ],
    ids=["doctype", "raw-tab", "colon", "latin-1", "urdf", "include-children"],
)  # fmt: skip
def test_a_document_both_readers_may_not_read_alike_is_refused(tmp_path, xml, needles):
    (tmp_path / "r.urdf").write_text(URDF)
    (tmp_path / "evil.stl").symlink_to("/dev/zero")
    (tmp_path / "model.xml").write_bytes(xml.encode("latin-1"))
    res = run("urdf2mjcf", "verify", "r.urdf", "model.xml", cwd=tmp_path, timeout=60)
    assert_one_error(res, "model.xml", *needles)


def test_verify_refuses_an_include_at_depth_two_that_is_a_fifo(tmp_path):
    layout = _layout(tmp_path / "m", "file", "include at depth 2")
    os.mkfifo(layout.target)
    (tmp_path / "r.urdf").write_text(URDF)
    res = run("urdf2mjcf", "verify", "r.urdf", str(layout.model), cwd=tmp_path, timeout=60)
    assert_one_error(res, "q.xml", "r.xml", "FIFO", "not a regular file")


def test_a_bundle_whose_timestep_would_step_forever_is_refused(tmp_path):
    folder = _bundle(tmp_path / "bundle")
    (folder / "scene.xml").write_text(_doc('<option timestep="1e-9"/>'))
    res = run("rover-drive", str(folder), cwd=tmp_path, timeout=REFUSED_WITHIN + 30)
    assert_one_error(res, "scene.xml", "<option timestep>", "1e-09")


def test_a_certificate_figure_that_is_not_finite_fails_and_is_null_in_json():
    from urdf2mjcf.certify import Certificate, not_finite
    from urdf2mjcf.certify.tolerances import Tolerances

    sections = {"mass": {"mjcf_kg": float("nan"), "links": [1.0, float("inf")]}}
    failures = not_finite(sections)
    assert failures == ["mass.links[1]: inf is not a finite number",
                        "mass.mjcf_kg: nan is not a finite number"]  # fmt: skip
    cert = Certificate("yourdfpy 1", Tolerances(), sections=sections, failures=failures)
    data = json.loads(json.dumps(cert.to_dict(), allow_nan=False))
    assert data["mass"] == {"mjcf_kg": None, "links": [1.0, None]} and not data["passed"]


@pytest.mark.parametrize(
    "asset",
    [
        '<asset><mesh name="m" file="/proc/self/status"/></asset>',
        '<include file="/proc/self/status"/>',
        '<asset><texture name="t" type="2d" file="/proc/self/root/proc/self/status"/></asset>',
    ],
    ids=["mesh", "include", "texture-through-a-link"],
)
def test_a_kernel_file_is_refused(tmp_path, asset):
    """A regular file of /proc or /sys may block its reader (/proc/kmsg, a trace pipe),
    and MuJoCo reads assets itself, waiting."""
    (tmp_path / "r.urdf").write_text(URDF)
    (tmp_path / "m.xml").write_text(_doc(asset))
    res = run("urdf2mjcf", "verify", "r.urdf", "m.xml", cwd=tmp_path, timeout=60)
    assert_one_error(res, "m.xml", "/proc/", "kernel file")


def test_includes_past_the_file_bound_are_refused(tmp_path):
    from urdf2mjcf import mjcf_files

    n = mjcf_files.DOCUMENTS_MAX
    for i in range(n + 1):  # the model and n included files: one too many
        _write(
            tmp_path / f"p{i}.xml", _doc(f'<include file="p{i + 1}.xml"/>' if i < n else "<asset/>")
        )
    (tmp_path / "r.urdf").write_text(URDF)
    res = run("urdf2mjcf", "verify", "r.urdf", "p0.xml", cwd=tmp_path, timeout=120)
    assert_one_error(res, f"more than {n:,} files")


# -- bombs ---------------------------------------------------------------------------------


def _nested_replicate() -> str:
    inner = '<body><geom size=".1"/></body>'
    for _ in range(8):
        inner = f'<replicate count="10">{inner}</replicate>'
    return _doc(f"<worldbody>{inner}</worldbody>")


BOMBS = {
    "nested replicate": (_nested_replicate(), ("<replicate>", "more than 50,000 elements")),
    "a million bodies": (
        _doc("<worldbody>" + "<body/>" * 1_000_000 + "</worldbody>"),
        ("more than 50,000 elements",),
    ),
    "flexcomp grid": (
        _doc('<worldbody><body name="b"><flexcomp name="f" type="grid" count="100000 100000 1" '
             'spacing="1 1 1" dim="2"/></body></worldbody>'),
        ("<flexcomp", "more than"),
    ),
    "flexcomp bodies": (
        _doc('<worldbody><body name="b"><flexcomp name="f" type="grid" count="120 100 1" '
             'spacing="1 1 1" dim="2"/></body></worldbody>'),
        ("<flexcomp", "more than 10,000 bodies"),
    ),
    "composite": (
        _doc('<worldbody><composite type="cable" count="10000000 1 1" size="1">'
             '<geom type="capsule" size=".01"/></composite></worldbody>'),
        ("<composite>", "more than"),
    ),
    "built-in mesh": (
        _doc('<asset><mesh name="m" builtin="supersphere" params="100000 1 1"/></asset>'),
        ("<mesh", "1,000,000 vertices"),
    ),
    "written-out mesh": (
        _doc('<asset><mesh name="m" vertex="' + "0 0 0 " * 1_000_001 + '"/></asset>'),
        ("<mesh", "1,000,000 vertices"),
    ),
    "texture": (
        _doc('<asset><texture name="t" builtin="checker" type="2d" width="100000" '
             'height="100000"/></asset>'),
        ("<texture", "pixels"),
    ),
    "height field": (
        _doc('<asset><hfield name="h" nrow="100000" ncol="100000" size="1 1 1 1"/></asset>'),
        ("<hfield", "samples"),
    ),
    "arena": (_doc('<size memory="1000G"/>'), ("<size memory>", "16 GiB")),
    "user fields": (_doc('<size nuser_geom="100000000"/>'), ("nuser_geom",)),
    "offscreen buffer": (
        _doc('<visual><global offwidth="1000000"/></visual>'), ("offwidth", "16,384")
    ),
    "solver iterations": (_doc('<option iterations="1000000000"/>'), ("iterations", "10,000")),
    "deep nesting": (
        _doc("<worldbody>" + "<frame>" * 1500 + "</frame>" * 1500 + "</worldbody>"),
        ("nested more than 1,000",),
    ),
    "nan timestep": (_doc('<option timestep="nan"/>'), ("opt.timestep = nan", "finite")),
    "infinite mass": (
        _doc('<worldbody><body><inertial pos="0 0 0" mass="inf" diaginertia="1 1 1"/>'
             "<joint/></body></worldbody>"),
        ("finite",),
    ),
    "huge size": (_doc('<worldbody><body><geom size="1e300"/><joint/></body></worldbody>'),
                  ("body_inertia", "finite")),
}  # fmt: skip


@pytest.mark.parametrize("bomb", sorted(BOMBS))
def test_a_bomb_is_one_error_line_within_its_bounds(tmp_path, bomb):
    xml, needles = BOMBS[bomb]
    (tmp_path / "r.urdf").write_text(URDF)
    (tmp_path / "bomb.xml").write_text(xml)
    res = run(
        "urdf2mjcf", "verify", "r.urdf", "bomb.xml", "--report", "report.json",
        cwd=tmp_path, timeout=REFUSED_WITHIN + 60,
    )  # fmt: skip
    assert_one_error(res, "bomb.xml", *needles)
    assert not (tmp_path / "report.json").exists()


def test_a_png_that_claims_ten_billion_pixels_is_refused(tmp_path):
    png = bytearray(_png(1))
    png[16:24] = (100_000).to_bytes(4, "big") * 2  # the header's width and height
    (tmp_path / "big.png").write_bytes(bytes(png))
    for tag, xml in (
        ("texture", '<texture name="t" type="2d" file="big.png"/>'),
        ("hfield", '<hfield name="h" file="big.png" size="1 1 1 1"/>'),
    ):
        (tmp_path / "r.urdf").write_text(URDF)
        (tmp_path / "m.xml").write_text(_doc(f"<asset>{xml}</asset>"))
        res = run("urdf2mjcf", "verify", "r.urdf", "m.xml", cwd=tmp_path, timeout=60)
        assert_one_error(res, "big.png", f"<{tag}>", "10,000,000,000")


# -- signals -------------------------------------------------------------------------------

BIG_BODIES = 9_000
"""Bodies of a model within the bounds that MuJoCo takes seconds to compile here."""


def _big_model(path: Path) -> None:
    bodies = "".join(
        f'<body pos="{i * 0.01} 0 0"><geom size="0.004"/></body>' for i in range(BIG_BODIES)
    )
    path.write_text(_doc(f"<worldbody>{bodies}</worldbody>"))


def _start(args: list[str], cwd: Path, interrupt: bool) -> subprocess.Popen:
    code = "from urdf2mjcf.cli import {0}; {0}()".format(
        "urdf2mjcf_main" if args[0] == "verify" else "facility_demo_main"
    )
    if interrupt:  # Ctrl-C as a terminal's shell gives it (a test runner may ignore it)
        code = "import signal; signal.signal(signal.SIGINT, signal.default_int_handler)\n" + code
    return subprocess.Popen(
        [sys.executable, "-c", code, *(args if args[0] == "verify" else args[1:])],
        cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        text=True, start_new_session=True,
    )  # fmt: skip


@pytest.mark.parametrize("command", ["verify", "facility-demo"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "Ctrl-C"])
def test_a_signal_during_a_long_compile_ends_the_command_at_once(tmp_path, command, sig):
    (tmp_path / "r.urdf").write_text(URDF)
    if command == "verify":
        _big_model(tmp_path / "big.xml")
        args = ["verify", "r.urdf", "big.xml"]
    else:
        folder = _bundle(tmp_path / "bundle")
        _big_model(folder / "scene.xml")
        args = ["facility-demo", str(folder)]
    proc = _start(args, tmp_path, interrupt=sig == signal.SIGINT)
    try:
        deadline = time.monotonic() + 120
        while not running(descendants(proc.pid)):  # MuJoCo's compiling process
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < deadline, "MuJoCo never started compiling"
            time.sleep(0.05)
        time.sleep(0.5)
        compiling = running(descendants(proc.pid))
        assert compiling, "MuJoCo compiled the model too fast for this test"
        start = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
        seconds = time.monotonic() - start
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 128 + sig, err
    assert seconds < 2.0, seconds
    assert "Traceback" not in err, err
    time.sleep(0.2)
    assert not running(compiling), "MuJoCo's process outlived the command"


# -- what stays the same ---------------------------------------------------------------------


def _third_party_models() -> list[Path]:
    site = Path(mujoco.__file__).parents[1]
    found = sorted((site / "gymnasium" / "envs" / "mujoco" / "assets").glob("*.xml"))
    found += sorted((site / "mujoco" / "testdata").glob("*.xml"))
    return found


@pytest.fixture(scope="module")
def imetro(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bundle") / "imetro"
    recipe = str(ROOT / "recipes" / "imetro.yaml")
    res = run(
        "make-facility", recipe, "--root", str(ROOT), "-o", str(out), "--no-components",
        cwd=ROOT, timeout=900, memory=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    return out


def _same_model(path: Path) -> None:
    """``path`` compiles through the checks to the model MuJoCo compiles from the file
    itself, field for field, the asset paths it recorded too (the compile comes back
    from another process as an MJB file, which has no signature)."""
    from tests.same_model import differences
    from urdf2mjcf import mjcf_input

    want = mujoco.MjModel.from_xml_path(str(path))
    got = mjcf_input.load_model(path)
    assert [d for d in differences(want, got) if d != "signature"] == [], path
    assert got.paths == want.paths, path


def test_models_we_did_not_write_compile_to_the_same_model():
    models = _third_party_models()
    assert len(models) >= 10, models
    for path in models:
        _same_model(path)


def test_our_bundle_compiles_to_the_same_model(imetro):
    _same_model(imetro / "scene.xml")
