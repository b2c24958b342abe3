"""AprilTag fiducials on the facility's components, rendered as textures.

The real facility's mockups carry AprilTag (family 36h11) markers for the robot to
localize them by; a component declares its own in the component table::

    crate:
      asset: crate
      ...
      fiducials:
        - {id: 0, link: lid, xyz: [0.002, 0.3, 0.3], rpy: [1.5708, 0, 1.5708], size: 0.1}

``link`` is the component's link without its prefix; ``xyz`` / ``rpy`` (m, rad) give
the tag's frame in that link: the origin at the centre of the printed face, z out of
the face (towards whoever reads it), x to the reader's right and y up in the image,
which is OpenCV's marker frame (corners top-left, top-right, bottom-right,
bottom-left at (-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2)). ``size`` is the
edge of the black square, the outline a detector measures; the plate is a quarter
wider on each side, since the tag carries its one-cell white border (10 x 10 cells).

The builder adds each tag to the facility's document, in memory before it is written
and validated, as a PNG texture (the image
of ``cv2.aruco.generateImageMarker``), a material and a thin visual-only box geom
(no contacts, the visual group) on the link's body, whose +z face shows the tag. Ids
are unique in a component table, so in every facility built from it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..assets import content_name
from ..errors import InputError
from ..fmt import fmt_vec
from ..limits import TAG_COUNT, TAG_FAMILY
from ..mjcf.document import Document
from ..transforms import quat_from_rpy, rpy_to_matrix
from ..untrusted import excerpt
from .pose import Pose2D
from .values import ANGLE_MAX, number

if TYPE_CHECKING:
    import mujoco

    from ..schema import Source

FAMILY = TAG_FAMILY
CELLS = 8
"""The black square: 6 x 6 data cells and a one-cell black border."""
BORDER_CELLS = 1
"""The white border around it, part of the printed tag."""
CELL_PX = 32
"""Texture pixels per cell: sharp edges at the distances the robot's cameras read from."""
THICKNESS = 0.002
"""m, of the plate; it lies behind the tag's face (z <= 0 in the tag's frame)."""
KEYS = ("id", "link", "xyz", "rpy", "size")
SIZE_MAX = 10.0
"""m: the largest tag (the black square's edge); the real ones are 0.1 m."""
OFFSET_MAX = 1_000.0
"""m: the largest coordinate of a tag in its link's frame."""


@dataclass(frozen=True)
class Fiducial:
    """One tag on a component's link."""

    id: int
    """Tag id in the 36h11 family, unique in the component table."""
    link: str
    """The link it is fixed to, without the component's prefix."""
    xyz: tuple[float, float, float]
    """(3,) m: centre of the tag's face in the link frame."""
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """(3,) rad: the tag frame (z out of the face) in the link frame, URDF's convention."""
    size: float = 0.1
    """m: edge of the black square (the printed tag is 10/8 of it)."""

    @property
    def plate(self) -> float:
        """m: edge of the printed tag, white border included."""
        return self.size * (CELLS + 2 * BORDER_CELLS) / CELLS


def _vector(value: Any, src: Source, key: str, bound: float) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise src.fail(key, f"'{excerpt(str(value), 40)}' is not three numbers [x, y, z]")
    return tuple(  # type: ignore[return-value]
        number(v, src, f"{key}.{i}", low=-bound, high=bound) for i, v in enumerate(value)
    )


def parse_fiducials(value: Any, src: Source, where: str) -> tuple[Fiducial, ...]:
    """A component's ``fiducials`` list, checked: every error names the file, the key
    (``crate.fiducials[1].size``) and its line."""
    if value is None:
        return ()
    if not isinstance(value, list):
        raise src.fail(where, "a list of tags [{id, link, xyz, rpy, size}]")
    out = []
    for i, spec in enumerate(value):
        key = f"{where}[{i}]"
        if not isinstance(spec, Mapping) or not {"id", "link", "xyz", "size"} <= set(spec):
            raise src.fail(key, "a tag needs id, link, xyz and size (and optionally rpy)")
        src.known(spec, KEYS, key)
        tag_id = spec["id"]
        if isinstance(tag_id, bool) or not isinstance(tag_id, int) or not 0 <= tag_id < TAG_COUNT:
            shown = excerpt(str(tag_id), 40)
            raise src.fail(f"{key}.id", f"'{shown}' is not a {FAMILY} id (0 .. {TAG_COUNT - 1})")
        link = src.text(spec["link"], f"{key}.link", required=True)
        # m, the black square's edge
        size = number(spec["size"], src, f"{key}.size", low=0.0, high=SIZE_MAX, low_open=True)
        out.append(
            Fiducial(
                id=tag_id,
                link=str(link),
                xyz=_vector(spec["xyz"], src, f"{key}.xyz", OFFSET_MAX),
                rpy=_vector(spec.get("rpy", [0, 0, 0]), src, f"{key}.rpy", ANGLE_MAX),
                size=size,
            )
        )
    return tuple(out)


def check_unique(
    tables: Iterable[tuple[str, Sequence[Fiducial]]], src: Source, prefix: str = ""
) -> None:
    """Every id once in a component table (``tables``: component name -> its tags;
    ``prefix``: of the table's keys in ``src``, such as ``components.``)."""
    seen: dict[int, str] = {}
    for name, tags in tables:
        for i, tag in enumerate(tags):
            if tag.id in seen:
                key = f"{prefix}{name}.fiducials[{i}].id"
                raise src.fail(key, f"tag id {tag.id} is already used by '{seen[tag.id]}'")
            seen[tag.id] = name


def tag_image(tag_id: int, cell_px: int = CELL_PX) -> np.ndarray:
    """The printed tag, white border included: (10 * cell_px) square, uint8 grey."""
    from ..extras import require

    require("sim", "drawing AprilTags", ("cv2",))  # one error line, not a traceback
    import cv2

    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    black = cv2.aruco.generateImageMarker(dictionary, tag_id, CELLS * cell_px, borderBits=1)
    pad = BORDER_CELLS * cell_px
    return cv2.copyMakeBorder(black, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)


def tag_png(tag_id: int) -> bytes:
    """The printed tag as PNG bytes (deterministic: same id, same bytes)."""
    from ..extras import require

    require("sim", "drawing AprilTags", ("cv2",))  # one error line, not a traceback
    import cv2

    ok, data = cv2.imencode(".png", tag_image(tag_id))
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise RuntimeError(f"cannot encode tag {tag_id} as PNG")
    return bytes(data.tobytes())


def _geom_index(body: Any) -> int:
    """Where an added geom goes: after the body's own elements, before its child bodies."""
    for i, el in enumerate(body):
        if el.tag in ("body", "frame"):
            return i
    return len(body)


class Tags:
    """The tags as a pass on the facility's document in memory (``api.ModelPass``):
    each tag's texture, material and plate are added, its PNG goes among the
    document's files; what was placed is left in :attr:`placed`."""

    def __init__(
        self, tags: Sequence[tuple[str, str, Fiducial]], recipe: Path | str | None = None
    ) -> None:
        self.tags = list(tags)
        self.recipe = recipe
        self.placed: list[tuple[str, str, Fiducial]] = []

    def __call__(self, result: Document) -> Document:
        if not self.tags:
            return result
        root = result.edit()
        files = dict(result.files)
        self.placed = add_to_scene(root, files, self.tags, recipe=self.recipe)
        return replace(result, root=root, files=files)


def add_to_scene(
    root: Any,
    files: dict[str, bytes],
    tags: Sequence[tuple[str, str, Fiducial]],
    *,
    recipe: Path | str | None = None,
) -> list[tuple[str, str, Fiducial]]:
    """Add ``tags`` (component, prefix, tag) to the MJCF document ``root`` (changed in
    place) and each tag's PNG to ``files`` (paths relative to the document); returns
    them with their body names as (component, body, tag). A tag whose link the model
    lacks is an InputError naming ``recipe`` and the component's key."""
    from lxml import etree

    bodies = {b.get("name"): b for b in root.iter("body")}
    worldbody = root.find("worldbody")
    if worldbody is not None:
        bodies["world"] = worldbody
    asset = root.find("asset")
    if asset is None:
        asset = etree.Element("asset")
        root.insert(list(root).index(worldbody) if worldbody is not None else len(root), asset)
    visual_class = any(d.get("class") == "visual" for d in root.iter("default"))
    # Textures go where the model looks for them: its texturedir, else assets/.
    compiler = root.find("compiler")
    texdir = None
    if compiler is not None:
        texdir = compiler.get("texturedir") or compiler.get("assetdir")
    folder = (texdir or "assets").rstrip("/")
    placed = []
    for component, prefix, tag in tags:
        body_name = "world" if tag.link == "world" else prefix + tag.link
        body = bodies.get(body_name)
        if body is None:
            raise InputError(
                f"tag {tag.id} of '{component}' is on link '{tag.link}' (body '{body_name}'),"
                " which the facility does not contain",
                file=recipe or "scene.xml",
                element=f"components.{component}.fiducials",
            )
        name = f"{FAMILY}_{tag.id}"
        png = tag_png(tag.id)
        file = content_name(name, png) + ".png"
        files[f"{folder}/{file}"] = png
        file = file if texdir else f"assets/{file}"
        texture = etree.Element("texture", name=name, type="2d", file=file)
        # No specular highlight: a glossy tag washes out under the headlight.
        material = etree.Element("material", name=name, texture=name, specular="0")
        asset.append(texture)
        asset.append(material)
        rot = rpy_to_matrix(tag.rpy)
        # The plate lies behind the face: its centre half a thickness along -z of the tag.
        centre = np.asarray(tag.xyz) - rot[:, 2] * (THICKNESS / 2)
        half = tag.plate / 2
        geom = etree.Element("geom", name=name, type="box")
        geom.set("size", fmt_vec((half, half, THICKNESS / 2)))
        geom.set("pos", fmt_vec(centre.tolist()))
        geom.set("quat", fmt_vec(quat_from_rpy(tag.rpy)))
        geom.set("material", name)
        if visual_class:
            geom.set("class", "visual")
        else:
            for key, value in (("contype", "0"), ("conaffinity", "0"), ("group", "2")):
                geom.set(key, value)
        body.insert(_geom_index(body), geom)
        placed.append((component, body_name, tag))
    return placed


def _matrix(rot: np.ndarray) -> list[float]:
    return [round(float(v), 12) for v in rot.reshape(-1)]


def manifest_entries(
    m: mujoco.MjModel,
    placed: Sequence[tuple[str, str, Fiducial]],
    placements: Mapping[str, Pose2D],
) -> list[dict]:
    """``facility.json``'s ``fiducials``: each tag's id, component, body, size, its pose
    in its body and in its component's frame (the frame its placement pose gives:
    ``placements``, the poses the build used). The latter is read at the model's
    reference configuration (doors shut) and is the same for every seed: what a robot
    knows from the drawings, which a localizer turns into the component's pose."""
    import mujoco

    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    out = []
    for component, body, tag in sorted(placed, key=lambda p: p[2].id):
        entry: dict[str, Any] = {
            "id": tag.id,
            "family": FAMILY,
            "component": component,
            "body": body,
            "size": tag.size,
            "pose_in_body": {"xyz": list(tag.xyz), "rpy": list(tag.rpy)},
        }
        place = placements.get(component)
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
        if place is not None and b >= 0:
            c, s = math.cos(place.yaw), math.sin(place.yaw)
            r_comp = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            r_body = d.xmat[b].reshape(3, 3)
            world = d.xpos[b] + r_body @ np.asarray(tag.xyz)
            pos = r_comp.T @ (world - np.asarray(place.xyz))
            rot = r_comp.T @ r_body @ rpy_to_matrix(tag.rpy)
            # Rounded: the same for every seed, not only to the last bit.
            entry["pose_in_component"] = {
                "xyz": [round(float(v), 9) + 0.0 for v in pos],  # + 0.0: no -0.0
                "matrix": [round(float(v), 9) + 0.0 for v in rot.reshape(-1)],
            }
        out.append(entry)
    return out
