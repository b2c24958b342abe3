"""What a model changed from its description, and why.

For our own conversion the notes say it (inertials repaired or estimated, geoms
and meshes dropped, decimations, convex decompositions, contact exclusions,
liberties taken as warnings), and its intermediate representation gives the inertials it
supplied. For a model we did not write, the links whose inertial the model may
supply are found by rule: those the description leaves without one (no
``<inertial>``, or mass 0) and those whose tensor MuJoCo rejects.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..ir import Model, Note
from .mass import LinkInertial, urdf_inertial
from .reference import Reference

CHANGE_KINDS = (
    "repaired", "estimated", "decimated", "hull", "decomposed", "cached", "primitive",
    "excluded", "warning",
)
"""Note kinds that say the model differs from the description (``info`` notes do not);
``excluded``: a pair of bodies the conversion does not collide, with the depth that
removes at home."""

_LINK = re.compile(r"link '([^']*)'")


def from_notes(notes: Iterable[Note]) -> list[dict[str, Any]]:
    """The conversion's notes that change the model, as the certificate lists them."""
    out = []
    for n in notes:
        if n.kind not in CHANGE_KINDS:
            continue
        entry: dict[str, Any] = {"element": n.element, "kind": n.kind, "message": n.message}
        found = _LINK.search(n.element)
        if found:
            entry["link"] = found[1]
        out.append(entry)
    return out


def amended_by_conversion(model: Model) -> dict[str, LinkInertial | None]:
    """Links whose inertial our conversion supplied (repaired or estimated): the value it
    wrote, in the link frame."""
    from ..passes.inertia import full_matrix

    out: dict[str, LinkInertial | None] = {}
    for name, inertial in model.inertials.items():
        if inertial is not None and inertial.source != "urdf":
            out[name] = LinkInertial(
                inertial.mass, np.array(inertial.pos, float), full_matrix(inertial.fullinertia)
            )
    return out


def amended_by_rule(ref: Reference, free_root: bool = False) -> dict[str, LinkInertial | None]:
    """Links of the description whose inertial a model has to supply (the model's own
    value is then taken): a tensor MuJoCo rejects, or no mass (no ``<inertial>``, or
    mass 0) on a link with geometry to estimate it from or with a joint that MuJoCo
    requires mass behind (``free_root``: the root has a free joint). A massless frame on
    a fixed joint (tool0) stays massless."""
    from ..passes.inertia import mujoco_rejects
    from ..transforms import mujoco_fullinertia

    moving = {j.child for j in ref.urdf.robot.joints if j.type != "fixed"}
    if free_root:
        moving.add(str(ref.urdf.base_link))
    out: dict[str, LinkInertial | None] = {}
    for link in ref.urdf.robot.links:
        inertial = urdf_inertial(link)
        if inertial is None:
            if link.visuals or link.collisions or link.name in moving:
                out[link.name] = None
            continue
        moments = np.linalg.eigvalsh(inertial.inertia)
        point = link.name in moving and moments.min() < 1e-15  # MuJoCo's moving-body check
        if point or mujoco_rejects(mujoco_fullinertia(inertial.inertia)):
            out[link.name] = None
    return out


def massless_with_inertia(ref: Reference) -> list[dict[str, Any]]:
    """Links with mass 0 and a rotational inertia: massless in a MuJoCo model (a body's
    inertia needs mass), where urdfdom keeps the inertia."""
    out = []
    for link in ref.urdf.robot.links:
        inertial = link.inertial
        if inertial is None or inertial.mass or inertial.inertia is None:
            continue
        if np.any(np.asarray(inertial.inertia, float)):
            out.append(
                {
                    "element": f"link '{link.name}'",
                    "link": link.name,
                    "kind": "massless",
                    "message": "mass 0 with a rotational inertia: massless in MuJoCo, which has "
                    "no inertia without mass (urdfdom keeps it); compared without it",
                }
            )
    return out
