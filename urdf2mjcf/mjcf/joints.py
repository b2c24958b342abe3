"""The joints of an MJCF document and their ``qpos`` layout: how wide each joint is,
where MuJoCo starts it, and keyframes re-padded when joints are added (the extension
pass's bodies, the facility's attached components)."""

from __future__ import annotations

from lxml import etree

from ..fmt import fmt_vec

Layout = list[tuple[str | None, int]]
"""(name, qpos width) of each joint in document order."""


def _kind(joint: etree._Element) -> str:
    return "free" if joint.tag == "freejoint" else joint.get("type", "hinge")


def joint_width(joint: etree._Element) -> int:
    """Numbers of ``qpos`` a ``<joint>`` or ``<freejoint>`` takes."""
    return {"free": 7, "ball": 4}.get(_kind(joint), 1)


def joint_qpos0(joint: etree._Element) -> list[float]:
    """Where MuJoCo starts a joint given by pos and quat: a free joint at its body's pose,
    a ball at identity, a hinge or slide at its ``ref``."""
    kind = _kind(joint)
    if kind == "free":
        body = joint.getparent()
        assert body is not None
        pose = body.get("pos", "0 0 0").split() + body.get("quat", "1 0 0 0").split()
        return [float(v) for v in pose]
    if kind == "ball":
        return [1.0, 0.0, 0.0, 0.0]
    return [float(joint.get("ref", "0"))]


def joints(root: etree._Element) -> list[etree._Element]:
    """Every joint of the world body in document order (MuJoCo's order for our output)."""
    world = root.find("worldbody")
    return [] if world is None else list(world.iter("joint", "freejoint"))


def layout(root: etree._Element) -> Layout:
    """(name, qpos width) of each joint in document order (MuJoCo's order for our output)."""
    return [(el.get("name"), joint_width(el)) for el in joints(root)]


def repad(
    keys: list[etree._Element], old: Layout, starts: list[tuple[str | None, list[float]]]
) -> None:
    """Re-pad ``keys``, written for the joints of ``old``, to the joints ``starts``
    (name, where it starts) now has: a joint of ``old`` keeps its values, an added
    one gets its start."""
    widths = dict(old)
    for key in keys:
        values = [float(x) for x in (key.get("qpos") or "").split()]
        if len(values) != sum(widths.values()) or len(widths) != len(old):
            continue
        kept: dict[str | None, list[float]] = {}
        pos = 0
        for name, width in old:
            kept[name] = values[pos : pos + width]
            pos += width
        new: list[float] = []
        for name, start in starts:
            mine = kept.get(name)
            new += mine if mine is not None and len(mine) == len(start) else start
        if new != values:
            key.set("qpos", fmt_vec(new))
