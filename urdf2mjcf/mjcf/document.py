"""The MJCF document in memory: its tree, the asset files beside it, its home pose,
its top-level sections, and the one writer that turns it into bytes.

Emit makes a :class:`Document` from the model; every later pass over it (extension,
contacts, scene, the facility's attach, fold and tags, calibration) takes one and
returns a new one, changing a copy (:meth:`Document.edit`). It becomes text once,
when it is written (:func:`mjcf_bytes`).
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass

from lxml import etree

from ..ir import Note

SECTIONS = (
    "compiler",
    "option",
    "size",
    "visual",
    "statistic",
    "default",
    "asset",
    "worldbody",
    "contact",
    "equality",
    "tendon",
    "actuator",
    "sensor",
    "custom",
    "keyframe",
)
"""Top-level MJCF sections in the order emit (and Menagerie) writes them."""


@dataclass(frozen=True)
class Document:
    root: etree._Element
    """The MJCF document (``<mujoco>``), in memory. Never changed once made: a pass that
    changes the document works on a copy (:meth:`edit`) and returns a new document."""
    files: dict[str, bytes]
    """Asset files by path relative to the MJCF file (``assets/<name>``)."""
    qpos_home: tuple[float, ...]
    notes: tuple[Note, ...] = ()

    @functools.cached_property
    def xml(self) -> bytes:
        """The document as it is written: our one writer's bytes."""
        return mjcf_bytes(self.root)

    def edit(self) -> etree._Element:
        """A copy of the document for a pass to change."""
        return copy.deepcopy(self.root)


def section(root: etree._Element, tag: str) -> etree._Element:
    """The top-level section ``tag`` of ``root``, created in Menagerie's order if missing."""
    found = root.find(tag)
    if found is not None:
        return found
    el = etree.Element(tag)
    rank = SECTIONS.index(tag)
    for existing in root:
        if existing.tag in SECTIONS and SECTIONS.index(existing.tag) > rank:
            existing.addprevious(el)
            return el
    root.append(el)
    return el


def mjcf_bytes(root: etree._Element) -> bytes:
    """The one writer of our MJCF documents: ``root`` indented two spaces, UTF-8, no
    declaration, a final newline. Whatever whitespace a pass left in the tree, the
    same elements give the same bytes (only whitespace of ``root`` is changed)."""
    etree.indent(root, space="  ")
    return etree.tostring(root, encoding="utf-8", xml_declaration=False) + b"\n"
