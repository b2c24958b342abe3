"""Compiling our MJCF with MuJoCo: one helper for every pass that needs a model.

A conversion compiles up to four documents, each different: the robot
without actuators (actuators: gains depend on the robot's dynamics), the
merged ``<mujoco>`` extension without keyframes (extension), the finished
robot (scene: where the floor goes) and ``scene.xml`` around it (validate).
The actuators and scene passes read the dynamics and the colliding geoms,
never a visual geom: they compile the document without its visual geoms and
the meshes only those use (``collision_only``), which are most of the faces
MuJoCo would process, so the full robot is compiled once, by validation. The
scene pass needs only where bodies and geoms are at home, which the actuators
pass's model already says when the documents differ only in actuators,
sensors, sites and cameras: then it is reused, not compiled again
(``shape_only``). And the compiles share the mesh work: MuJoCo caches
processed mesh assets per process, keyed by asset name and content, so every
compile here goes through memory with the same relative names
(``assets/<name>``) and the later ones skip decoding and processing the
meshes an earlier one did.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Mapping
from typing import Any

LOCK = threading.RLock()
"""MuJoCo's user warning callback is process-global: whoever sets it holds this
(re-entrant: validation holds it while it compiles and steps)."""


def compile_xml(
    xml: bytes | str, files: Mapping[str, bytes], warnings: list[str] | None = None
) -> Any:
    """``mujoco.MjModel`` of ``xml`` with ``files`` (relative names) as its assets.

    Raises MuJoCo's ``ValueError``. Warnings MuJoCo gives while compiling are
    appended to ``warnings`` (they are dropped when it is None).
    """
    import mujoco

    text = xml.decode() if isinstance(xml, bytes) else xml
    sink = warnings if warnings is not None else []
    with LOCK:
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(lambda msg: sink.append(str(msg).strip()))
        try:
            return mujoco.MjModel.from_xml_string(text, dict(files))
        finally:
            mujoco.set_mju_user_warning(previous)


_last: tuple[bytes, dict[str, bytes], Any] | None = None
"""(shape, files, model) of the last :func:`compile_home` in this process."""


def make_room() -> None:
    """Keep MuJoCo's asset cache from staying full; call before a conversion compiles.

    Once full it caches nothing more (it evicts only when its capacity is
    lowered): after some 30 robots converted in one process every compile
    would pay for its meshes again. Past half full, lowering the capacity to
    half and back drops the least used entries and leaves room for this
    conversion's meshes. Not before each compile: the entries dropped first
    are the ones used least, which a conversion's first compile just added.
    """
    import mujoco

    global _last
    with LOCK:
        _last = None  # another conversion: no model of the last one is kept alive
    get_cache = getattr(mujoco, "mj_getCache", None)  # a MuJoCo without it: nothing to do
    if get_cache is None:
        return
    cache = get_cache()
    capacity = mujoco.mj_getCacheCapacity(cache)
    if mujoco.mj_getCacheSize(cache) > capacity // 2:
        mujoco.mj_setCacheCapacity(cache, capacity // 2)
        mujoco.mj_setCacheCapacity(cache, capacity)


def home_data(m: Any) -> Any:
    """``mujoco.MjData`` of ``m`` at its first keyframe (our ``home``), if it has one."""
    import mujoco

    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    return d


def compile_home(
    xml: bytes | str,
    files: Mapping[str, bytes],
    *,
    shape_only: bool = False,
    collision_only: bool = False,
) -> tuple[Any, Any]:
    """(model, data at home) of ``xml`` with ``files``; raises MuJoCo's ``ValueError``.

    ``collision_only``: the caller reads the dynamics and the colliding geoms,
    never a visual one: the document is compiled without its visual geoms
    where :func:`without_visuals` finds that safe. ``shape_only``: the caller
    reads only where bodies and geoms are at home: the model of the previous
    call is returned when its document had the same :func:`shape` and the
    same files, instead of compiling this one.
    """
    global _last
    whole = xml if isinstance(xml, bytes) else xml.encode()
    doc = (without_visuals(whole) if collision_only else None) or whole
    key = shape(doc)
    with LOCK:
        last = _last
    if shape_only and last is not None and last[0] == key and last[1] == files:
        m = last[2]
    else:
        try:
            m = compile_xml(doc, files if doc is whole else files_named(files, doc))
        except ValueError:
            if doc is whole:
                raise
            m = compile_xml(whole, files)  # something used what we left out: its error, if any
    with LOCK:
        _last = (key, dict(files), m)
    return m, home_data(m)


_FILE_ATTR = re.compile(rb'\bfile="([^"]*)"')


def files_named(files: Mapping[str, bytes], *docs: bytes) -> dict[str, bytes]:
    """The ``files`` whose name one of ``docs`` mentions in a ``file`` attribute:
    MuJoCo copies every file it is given into its VFS and hashes it, and the visual
    meshes and textures a collision-only document leaves out are most of the bytes."""
    named = {m.rsplit(b"/", 1)[-1].decode() for doc in docs for m in _FILE_ATTR.findall(doc)}
    return {name: data for name, data in files.items() if name.rsplit("/", 1)[-1] in named}


def without_visuals(xml: bytes) -> bytes | None:
    """``xml`` without its visual geoms and the meshes, materials and texture files
    only they use; None where that could change the dynamics or the contacts.

    Safe for emit's documents: bodies take their mass from ``<inertial>`` alone
    (``inertiafromgeom="false"``) and the ``visual`` default class neither
    collides nor is collided with; a geom of that class that sets its own
    ``contype``/``conaffinity`` stays.
    """
    from lxml import etree

    root = etree.fromstring(xml, etree.XMLParser(huge_tree=True))
    compiler = root.find("compiler")
    visual = root.find(".//default[@class='visual']/geom")
    if (
        compiler is None
        or compiler.get("inertiafromgeom") != "false"
        or visual is None
        or visual.get("contype") != "0"
        or visual.get("conaffinity") != "0"
    ):
        return None
    dropped = [
        g
        for g in root.iter("geom")
        if g.get("class") == "visual" and g.get("contype") is None and g.get("conaffinity") is None
    ]
    if not dropped:
        return None
    for g in dropped:
        g.getparent().remove(g)

    def used(attr: str) -> set[str]:
        return {v for el in root.iter() if (v := el.get(attr)) is not None}

    for section in root.findall("asset"):
        meshes = used("mesh")
        for el in section.findall("mesh"):
            if el.get("name") not in meshes:
                section.remove(el)
        materials = used("material")
        for el in section.findall("material"):
            if el.get("name") not in materials:
                section.remove(el)
        textures = used("texture")
        for el in section.findall("texture"):
            skybox = el.get("type") == "skybox"  # used by being there
            if el.get("file") and not skybox and el.get("name") not in textures:
                section.remove(el)
    return etree.tostring(root)


def shape(xml: bytes | str) -> bytes:
    """The document without what moves or shapes nothing: actuators, sensors,
    ``<visual>``, sites, cameras, the model name and the keyframes' controls.
    Two documents of one shape put every body and geom in the same place."""
    from lxml import etree

    data = xml if isinstance(xml, bytes) else xml.encode()
    root = etree.fromstring(data, etree.XMLParser(remove_blank_text=True, huge_tree=True))
    root.attrib.pop("model", None)
    for tag in ("actuator", "sensor", "visual"):
        for el in root.findall(tag):
            root.remove(el)
    for el in list(root.iter("site", "camera")):
        el.getparent().remove(el)
    for key in root.iter("key"):
        key.attrib.pop("ctrl", None)
    return etree.tostring(root)
