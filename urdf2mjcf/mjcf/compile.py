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
(``shape_only``, through the conversion's :class:`HomeCompiles`). Every
function here takes a document as bytes or as the element tree the passes
hand on, and compiles a copy: the document itself is never changed. And the
compiles share the mesh work: MuJoCo caches processed mesh assets per
process, keyed by asset name and content, so every compile here goes through
memory with the same relative names (``assets/<name>``) and the later ones
skip decoding and processing the meshes an earlier one did.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

LOCK = threading.RLock()
"""MuJoCo's user warning callback is process-global: whoever sets it holds this
(re-entrant: validation holds it while it compiles and steps)."""


_route = threading.local()
"""Per thread: where MuJoCo's warnings go instead (the passive second's thread)."""


def warning_handler(sink: list[str]) -> Callable[[str], None]:
    """A MuJoCo warning handler that appends to ``sink``, except in a thread that
    routes its warnings elsewhere: MuJoCo's handler is process-wide, and a
    passive second stepping in the background must not warn into a compile."""

    def handle(msg: str) -> None:
        routed: list[str] | None = getattr(_route, "sink", None)
        (sink if routed is None else routed).append(str(msg).strip())

    return handle


@contextmanager
def warnings_into(sink: list[str]) -> Iterator[None]:
    """MuJoCo's warnings appended to ``sink`` meanwhile (:func:`warning_handler`),
    :data:`LOCK` held; the handler before is restored after."""
    import mujoco

    with LOCK:
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(warning_handler(sink))
        try:
            yield
        finally:
            mujoco.set_mju_user_warning(previous)


def compile_xml(
    xml: bytes | str, files: Mapping[str, bytes], warnings: list[str] | None = None
) -> Any:
    """``mujoco.MjModel`` of ``xml`` with ``files`` (relative names) as its assets.

    Raises MuJoCo's ``ValueError``. Warnings MuJoCo gives while compiling are
    appended to ``warnings`` (they are dropped when it is None).
    """
    import mujoco

    text = xml.decode() if isinstance(xml, bytes) else xml
    with warnings_into(warnings if warnings is not None else []):
        return mujoco.MjModel.from_xml_string(text, dict(files))


Xml = Any
"""An MJCF document: its bytes, or its root element in memory (lxml), left unchanged."""


def _tree(doc: Xml) -> Any:
    """A root element of ``doc`` that the caller may change (a copy of a tree)."""
    import copy

    from lxml import etree

    if isinstance(doc, (bytes, str)):
        data = doc if isinstance(doc, bytes) else doc.encode()
        # huge_tree: libxml2 otherwise stops at 256 nested elements, a chain of ~250 links
        return etree.fromstring(data, etree.XMLParser(remove_blank_text=True, huge_tree=True))
    root = copy.deepcopy(doc)
    for el in root.iter():  # as the parser above leaves it: no whitespace-only text
        if el.text is not None and not el.text.strip():
            el.text = None
        if el.tail is not None and not el.tail.strip():
            el.tail = None
    return root


def _text(doc: Xml) -> bytes:
    from lxml import etree

    return (
        doc
        if isinstance(doc, bytes)
        else doc.encode()
        if isinstance(doc, str)
        else etree.tostring(doc)
    )


class HomeCompiles:
    """One conversion's last :func:`compile_home`, for the next one of the same shape.

    The actuators pass compiles the robot to size its gains; the scene pass needs only
    where the same bodies and geoms are at home. A conversion makes one of these and
    hands it to both (no model outlives its conversion)."""

    def __init__(self) -> None:
        self._last: tuple[bytes, dict[str, bytes], Any] | None = None
        self._lock = threading.Lock()

    def get(self, key: bytes, files: Mapping[str, bytes]) -> Any:
        with self._lock:
            last = self._last
        return last[2] if last is not None and last[0] == key and last[1] == files else None

    def put(self, key: bytes, files: Mapping[str, bytes], m: Any) -> None:
        with self._lock:
            self._last = (key, dict(files), m)


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


def data_from(m: Any, start: Any) -> Any:
    """A new ``mujoco.MjData`` of ``m`` in the state of ``start`` (an MjData or a
    :func:`state_of` snapshot): positions, velocities, activations, mocap poses."""
    import mujoco

    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = start.qpos, start.qvel
    if m.na:
        d.act[:] = start.act
    d.mocap_pos[:], d.mocap_quat[:] = start.mocap_pos, start.mocap_quat
    return d


def state_of(d: Any) -> Any:
    """What :func:`data_from` reads of ``d``, copied now (the caller's data may change
    while another thread starts from it)."""
    from types import SimpleNamespace

    return SimpleNamespace(
        qpos=d.qpos.copy(),
        qvel=d.qvel.copy(),
        act=d.act.copy(),
        mocap_pos=d.mocap_pos.copy(),
        mocap_quat=d.mocap_quat.copy(),
    )


def compile_home(
    xml: Xml,
    files: Mapping[str, bytes],
    *,
    shape_only: bool = False,
    collision_only: bool = False,
    compiles: HomeCompiles | None = None,
) -> tuple[Any, Any]:
    """(model, data at home) of the document ``xml`` with ``files``; raises MuJoCo's
    ``ValueError``. The document itself is left as it is: a copy is compiled.

    ``collision_only``: the caller reads the dynamics and the colliding geoms,
    never a visual one: the document is compiled without its visual geoms where
    :func:`without_visuals` finds that safe. ``compiles``: where this conversion keeps
    its last compile; with ``shape_only`` (the caller reads only where bodies and geoms
    are at home), the model kept there is returned when its document had the same
    :func:`shape` and the same files, instead of compiling this one.
    """
    lean = without_visuals(xml) if collision_only else None
    doc = lean if lean is not None else xml
    key = shape(doc) if compiles is not None else b""
    m = compiles.get(key, files) if compiles is not None and shape_only else None
    if m is None:
        try:
            text = _text(doc)
            m = compile_xml(text, files if lean is None else files_named(files, text))
        except ValueError:
            if lean is None:
                raise
            m = compile_xml(_text(xml), files)  # something used what we left out: its error, if any
    if compiles is not None:
        compiles.put(key, files, m)
    return m, home_data(m)


_FILE_ATTR = re.compile(rb'\bfile="([^"]*)"')


def files_named(files: Mapping[str, bytes], *docs: bytes) -> dict[str, bytes]:
    """The ``files`` whose name one of ``docs`` mentions in a ``file`` attribute:
    MuJoCo copies every file it is given into its VFS and hashes it, and the visual
    meshes and textures a collision-only document leaves out are most of the bytes."""
    named = {m.rsplit(b"/", 1)[-1].decode() for doc in docs for m in _FILE_ATTR.findall(doc)}
    return {name: data for name, data in files.items() if name.rsplit("/", 1)[-1] in named}


def without_visuals(xml: Xml) -> Any:
    """``xml`` without its visual geoms and the meshes, materials and texture files
    only they use (bytes for bytes, a new tree for a tree); None where that could
    change the dynamics or the contacts. This is the physics twin that validation
    steps and the passes compile.

    Safe for emit's documents: bodies take their mass from ``<inertial>`` alone
    (``inertiafromgeom="false"``) and the ``visual`` default class neither
    collides nor is collided with; a geom of that class that sets its own
    ``contype``/``conaffinity`` stays.
    """
    from lxml import etree

    root = _tree(xml)
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
    return etree.tostring(root) if isinstance(xml, (bytes, str)) else root


def shape(xml: Xml) -> bytes:
    """The document without what moves or shapes nothing: actuators, sensors,
    ``<visual>``, ``<contact>`` (pairs and exclusions only filter contacts), sites,
    cameras, the model name and the keyframes' controls. Two documents of one shape
    put every body and geom in the same place."""
    from lxml import etree

    root = _tree(xml)
    root.attrib.pop("model", None)
    for tag in ("actuator", "sensor", "visual", "contact"):
        for el in root.findall(tag):
            root.remove(el)
    for el in list(root.iter("site", "camera")):
        el.getparent().remove(el)
    for key in root.iter("key"):
        key.attrib.pop("ctrl", None)
    return etree.tostring(root)


MAX_PASSIVE_STEPS = 2000
"""Most steps of :func:`passive_second`, whatever the model's timestep."""
PASSIVE_CHUNK = 10
"""Steps between two readings of the energy (20 ms at MuJoCo's default timestep): each
reading needs the GIL, which a busy thread beside holds for up to 5 ms at a time."""


@dataclass(frozen=True)
class PassiveRun:
    """One second from home with actuation and sensors off and MuJoCo's energy on:
    what the certificate's passive-energy check judges."""

    steps: int
    timestep: float
    start_j: float
    """Kinetic plus potential energy at home."""
    peak_j: float
    """The most it reached (at least ``start_j``), read every :data:`PASSIVE_CHUNK` steps."""
    peak_step: int
    diverged_at: int | None
    """The chunk's last step where the state stopped being finite (MuJoCo's bad
    position, velocity or acceleration warnings, or a fatal error)."""


def passive_steps(m: Any) -> int:
    """Steps of :func:`passive_second` at ``m``'s timestep."""
    import math

    ts = float(m.opt.timestep)
    return MAX_PASSIVE_STEPS if not ts > 0 else int(min(MAX_PASSIVE_STEPS, math.ceil(1.0 / ts)))


def passive_second(m: Any, start: Any) -> PassiveRun:
    """Step ``m`` passively for a second (:func:`passive_steps`) from the state of the
    ``mujoco.MjData`` ``start`` (left alone). ``m``'s flags are changed while it steps
    and restored after; what MuJoCo warns meanwhile is dropped (a divergence is in
    the figures)."""
    import mujoco

    d = data_from(m, start)
    flags = m.opt.disableflags
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    _route.sink = []
    try:
        run, _ = step_with_energy(m, d, passive_steps(m))
    finally:
        m.opt.disableflags = flags
        _route.sink = None
    return run


def step_with_energy(m: Any, d: Any, steps: int) -> tuple[PassiveRun, Exception | None]:
    """Step ``d`` ``steps`` times from its state with MuJoCo's energy on and the sensors
    off (they read the state and never change it: a lidar's rays would cost thirty
    times the physics), reading the energy every :data:`PASSIVE_CHUNK` steps; stops
    where the state stops being finite. (The figures, and MuJoCo's fatal error if one
    stopped it.) ``m``'s flags are restored after."""
    import mujoco
    import numpy as np

    flags = (m.opt.enableflags, m.opt.disableflags)
    m.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    diverged: int | None = None
    fatal: Exception | None = None
    bad = [
        mujoco.mjtWarning.mjWARN_BADQACC,
        mujoco.mjtWarning.mjWARN_BADQVEL,
        mujoco.mjtWarning.mjWARN_BADQPOS,
    ]
    start_j = peak = 0.0
    at = done = 0
    try:
        try:
            mujoco.mj_forward(m, d)
        except mujoco.FatalError as exc:  # out of arena at home already
            return PassiveRun(steps, float(m.opt.timestep), 0.0, 0.0, 0, 0), exc
        start_j = peak = float(d.energy.sum())
        while done < steps:
            # MuJoCo steps a chunk without the GIL; the energy is read between chunks
            chunk = min(PASSIVE_CHUNK, steps - done)
            try:
                mujoco.mj_step(m, d, nstep=chunk)
            except mujoco.FatalError as exc:
                diverged, fatal = done + chunk, exc
                break
            done += chunk
            if not np.isfinite(d.qacc).all() or any(d.warning[w].number for w in bad):
                diverged = done
                break
            e = float(d.energy.sum())
            if e > peak:
                peak, at = e, done
    finally:
        m.opt.enableflags, m.opt.disableflags = flags
    return PassiveRun(steps, float(m.opt.timestep), start_j, peak, at, diverged), fatal


def start_passive_second(m: Any, start: Any) -> Future[PassiveRun]:
    """:func:`passive_second` of ``m`` in a thread of its own: MuJoCo releases the GIL
    while it steps, so it overlaps other work (validation's second, the certificate's
    other figures) where a core is free. ``m`` is the thread's until the result is in
    (its flags change)."""
    future: Future[PassiveRun] = Future()
    d = state_of(start)

    def work() -> None:
        try:
            future.set_result(passive_second(m, d))
        except BaseException as exc:  # handed to whoever waits for the result
            future.set_exception(exc)

    threading.Thread(target=work, name="urdf2mjcf-passive", daemon=True).start()
    return future
