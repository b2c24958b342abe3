"""How much work an MJCF model may ask of MuJoCo, checked before MuJoCo does it.

MuJoCo builds much of a model while it parses: a ``<replicate>`` is copied
``count`` times (nested ones multiply), a ``<flexcomp>`` makes a body per point, a
``<composite>`` a body per count, a built-in mesh its vertices, an ``<attach>`` a
copy of another model; and it parses in time that grows faster than the elements
(10,000 bodies take 20 s here). A 773-byte document can ask for 10^12 bodies. So
:func:`check_model` counts all of that on the element tree before MuJoCo parses
it; :func:`check_spec` bounds what MuJoCo would allocate while compiling (textures,
height fields, the arena, keyframes, user fields) from its parse, before it
compiles; and :func:`check_compiled` refuses a model whose numbers are not finite
(``timestep="nan"``) or whose solver could iterate without end. Each bound is a
constant here, listed in docs/security.md.
"""

from __future__ import annotations

import math
import os
import re
import stat
from typing import Any

import numpy as np

from . import untrusted
from .errors import ForgeError
from .mjcf_files import ELEMENTS_MAX, POINTS, Model, label, origin

BODIES_MAX = 10_000
"""Bodies, counting replicated ones and those flexcomps and composites make (iMETRO:
81; 10,000 bodies compile in about 20 s here)."""
FLEX_POINTS_MAX = 100_000
"""Points of all flexcomps (a 100 x 100 cloth has 10,000)."""
DEPTH_MAX = 1_000
"""Nesting of elements through includes (MuJoCo reads one file to about 500)."""
MESH_VERTICES_MAX = 1_000_000
"""Vertices of one built-in mesh (``<mesh builtin>``: its resolution squared) or one
written into the model (``<mesh vertex>``)."""
PIXELS_MAX = 2**26
"""Pixels of one texture, built in or read from an image (8192 x 8192; our
skyboxes have 3.8 million)."""
HFIELD_SAMPLES_MAX = 2**26
"""Samples of one height field (our lunar terrain has 501 x 501)."""
MEMORY_MAX = 16 * 2**30
"""``<size memory>``, bytes: MuJoCo allocates it for every ``MjData`` (``njmax``,
``nconmax`` and ``nstack``, the older ways to size it, at most this many 8-byte
numbers)."""
SIZE_COUNT_MAX = 100_000
"""``<size nkey>``, ``<size nuserdata>`` and ``<numeric size>``."""
USER_FIELDS_MAX = 100
"""Each ``<size nuser_*>``: numbers MuJoCo allocates for every body, geom, ..."""
RENDER_SIZE_MAX = 16_384
"""Pixels of the offscreen buffer's sides and of the shadow map."""
ITERATIONS_MAX = 10_000
"""Each of ``<option>``'s iteration counts (``iterations``, ``ls_iterations``,
``noslip_iterations``, ``ccd_iterations``, ``sdf_iterations``, ``sdf_initpoints``)."""

_INT = re.compile(r"[+-]?[0-9]+")
_BIG = 10**18  # totals are clamped here: a bomb's count stays a small integer
_FLEX_BODIES_FEW = {"trilinear": 8, "quadratic": 27}


def check_model(model: Model, error: type[ForgeError]) -> None:
    """``model`` (and its ``<model>`` assets) within the bounds above, counted on its
    expanded element tree; ``error`` naming the first element past one."""
    totals: dict[str, tuple[int, int, int]] = {}
    for sub in reversed(list(model.models())):  # a sub-model before those attaching it
        if sub.path not in totals:
            totals[sub.path] = _Count(sub, error, totals).run()
    elements, bodies, points = totals[model.path]
    _over(elements, ELEMENTS_MAX, "elements", model.path, None, error)
    _over(bodies, BODIES_MAX, "bodies", model.path, None, error)
    _over(points, FLEX_POINTS_MAX, "flexcomp points", model.path, None, error)


def _over(n: int, limit: int, what: str, file: str, el: Any, error: type[ForgeError]) -> None:
    if n > limit:
        where = "expands to" if el is not None and el.tag in ("replicate", "attach") else "has"
        raise error(
            f"{where} more than {limit:,} {what} (refused: MuJoCo would build every one)",
            file=file,
            element=label(el) if el is not None else None,
        )


class _Count:
    """Elements, bodies and flexcomp points of one model's tree, counted bottom up."""

    def __init__(self, model: Model, error: type[ForgeError], done: dict):
        self.model, self.error, self.done = model, error, done

    def fail(self, message: str, el: Any) -> ForgeError:
        return self.error(message, file=origin(el, self.model), element=label(el))

    def run(self) -> tuple[int, int, int]:
        order: list[tuple[Any, int]] = []
        stack: list[tuple[Any, int, int]] = [(self.model.root, -1, 0)]
        while stack:
            el, parent, depth = stack.pop()
            if depth > DEPTH_MAX:
                raise self.fail(f"is nested more than {DEPTH_MAX:,} elements deep (refused)", el)
            order.append((el, parent))
            if len(order) > ELEMENTS_MAX:
                _over(len(order), ELEMENTS_MAX, "elements", self.model.path, None, self.error)
            here = len(order) - 1
            stack.extend((c, here, depth + 1) for c in reversed(el) if isinstance(c.tag, str))
        sums = [[0, 0, 0] for _ in order]
        result = (0, 0, 0)
        for i in range(len(order) - 1, -1, -1):
            el, parent = order[i]
            own = self.own(el)
            times = self.replicas(el) if el.tag == "replicate" else 1
            total = [min(_BIG, own[k] + times * sums[i][k]) for k in range(3)]
            where = origin(el, self.model)
            _over(total[0], ELEMENTS_MAX, "elements", where, el, self.error)
            _over(total[1], BODIES_MAX, "bodies", where, el, self.error)
            _over(total[2], FLEX_POINTS_MAX, "flexcomp points", where, el, self.error)
            if parent < 0:
                result = (total[0], total[1], total[2])
            else:
                for k in range(3):
                    sums[parent][k] = min(_BIG, sums[parent][k] + total[k])
        return result

    def own(self, el: Any) -> list[int]:
        """What ``el`` itself makes: ``[elements, bodies, points]``."""
        tag = el.tag
        if tag == "body":
            return [1, 1, 0]
        if tag == "flexcomp":
            points = self.flex_points(el)
            dof = (el.get("dof") or "full").strip()
            bodies = _FLEX_BODIES_FEW.get(dof, points)
            return [1 + points, bodies, points]
        if tag == "composite":
            n = self.composite_bodies(el)
            return [1 + 3 * n, n, 0]
        if tag == "attach":
            sub = self.model.submodels.get(str(el.get("model")))
            if sub is not None and sub.path in self.done:
                e, b, p = self.done[sub.path]
                return [1 + e, b, p]
        if tag == "flex" and el.get("vertex") is not None:  # a flex written out point by point
            points = len(str(el.get("vertex")).split()) // 3
            return [1 + points, 0, points]
        if tag == "mesh" and el.get("builtin") is not None:
            self.builtin_mesh(el)
        if tag == "mesh" and el.get("vertex") is not None:
            vertices = len(str(el.get("vertex")).split()) // 3
            if vertices > MESH_VERTICES_MAX:
                raise self.fail(f"has more than {MESH_VERTICES_MAX:,} vertices (refused)", el)
        if tag == "hfield":  # its samples are allocated while MuJoCo parses
            rows, cols = (max(0, self.ints(el, a, 1, 0)[0]) for a in ("nrow", "ncol"))
            if rows * cols > HFIELD_SAMPLES_MAX:
                raise self.fail(
                    f"{rows:,} x {cols:,} samples is over {HFIELD_SAMPLES_MAX:,} (refused)", el
                )
        return [1, 0, 0]

    def ints(self, el: Any, attr: str, n: int, default: int) -> list[int]:
        """Up to ``n`` whole numbers as MuJoCo reads them (missing ones ``default``)."""
        raw = el.get(attr)
        tokens = raw.split() if raw is not None else []
        if len(tokens) > n or not all(_INT.fullmatch(t) for t in tokens):
            raise self.fail(f"{attr}='{untrusted.excerpt(raw or '')}' is not {n} whole numbers", el)
        values = [int(t) for t in tokens]
        return values + [default] * (n - len(values))

    def replicas(self, el: Any) -> int:
        if el.get("count") is None:
            raise self.fail("'count' is missing", el)
        return max(0, self.ints(el, "count", 1, 0)[0])

    def flex_points(self, el: Any) -> int:
        if el.get(POINTS) is not None:
            return int(str(el.get(POINTS)))
        if el.get("point") is not None:
            return len(str(el.get("point")).split()) // 3
        x, y, z = (max(0, c) for c in self.ints(el, "count", 3, 10))
        kind = (el.get("type") or "grid").strip()
        if kind in ("box", "cylinder", "ellipsoid"):
            return min(_BIG, max(x * y * z, 2 * (x * y + y * z + z * x)))
        return min(_BIG, x * y * z)

    def composite_bodies(self, el: Any) -> int:
        if el.get("vertex") is not None:
            return len(str(el.get("vertex")).split()) // 3
        x, y, z = (max(0, c) for c in self.ints(el, "count", 3, 1))
        return min(_BIG, x * y * z)

    def builtin_mesh(self, el: Any) -> None:
        kind = (el.get("builtin") or "").strip()
        raw = (el.get("params") or "").split()
        try:
            params = [float(p) for p in raw]
        except ValueError:
            raise self.fail(f"params='{untrusted.excerpt(el.get('params') or '')}' are not numbers",
                            el) from None  # fmt: skip
        if not all(math.isfinite(p) for p in params):
            raise self.fail("params must be finite numbers", el)
        res = [abs(p) for p in params] + [0.0, 0.0]
        vertices = {
            "supersphere": res[0] ** 2,
            "supertorus": res[0] ** 2,
            "wedge": res[0] * res[1],
            "plate": res[0] * res[1],
            "cone": res[0],
        }.get(kind, 0.0)
        if vertices > MESH_VERTICES_MAX:
            raise self.fail(
                f"a built-in {kind} of this resolution has more than {MESH_VERTICES_MAX:,} "
                "vertices (refused)",
                el,
            )


# -- what MuJoCo would allocate compiling, from its parse --------------------------------

_SIZE_COUNTS = ("nkey", "nuserdata")
_ARENA_COUNTS = ("njmax", "nconmax", "nstack")  # sizes of the arena, in numbers
_USER_FIELDS = (
    "nuser_body", "nuser_jnt", "nuser_geom", "nuser_site", "nuser_cam", "nuser_tendon",
    "nuser_actuator", "nuser_sensor",
)  # fmt: skip
_ITERATIONS = (
    "iterations", "ls_iterations", "noslip_iterations", "ccd_iterations", "sdf_iterations",
    "sdf_initpoints",
)  # fmt: skip
_CUBE_TYPES = ("mjTEXTURE_CUBE", "mjTEXTURE_SKYBOX")


def check_spec(spec: Any, file: str, error: type[ForgeError]) -> None:
    """MuJoCo's parse of a model (an ``MjSpec``) within the bounds on what compiling
    it allocates; ``error`` naming the element past one."""

    def past(value: Any, limit: int, what: str, element: str) -> None:
        if int(value) > limit:
            raise error(f"{what} {int(value):,} is over {limit:,} (refused)", file=file,
                        element=element)  # fmt: skip

    if spec.memory > MEMORY_MAX:
        raise error(
            f"memory {spec.memory:,} bytes is over {MEMORY_MAX // 2**30} GiB (refused)",
            file=file,
            element="<size memory>",
        )
    for key in _SIZE_COUNTS:
        past(getattr(spec, key), SIZE_COUNT_MAX, key, f"<size {key}>")
    for key in _ARENA_COUNTS:
        past(getattr(spec, key), MEMORY_MAX // 8, key, f"<size {key}>")
    for key in _USER_FIELDS:
        past(getattr(spec, key), USER_FIELDS_MAX, key, f"<size {key}>")
    for key in _ITERATIONS:
        past(getattr(spec.option, key), ITERATIONS_MAX, key, f"<option {key}>")
    g, q = spec.visual.global_, spec.visual.quality
    for value, key, element in (
        (g.offwidth, "offwidth", "<visual><global offwidth>"),
        (g.offheight, "offheight", "<visual><global offheight>"),
        (q.shadowsize, "shadowsize", "<visual><quality shadowsize>"),
    ):
        past(value, RENDER_SIZE_MAX, key, element)
    for tex in spec.textures:
        w, h = max(0, int(tex.width)), max(0, int(tex.height))
        pixels = w * h
        if str(tex.type).rsplit(".", 1)[-1] in _CUBE_TYPES:
            pixels = max(pixels, 6 * w * w)
        past(pixels, PIXELS_MAX, "pixels", _named("texture", tex))
    for hf in spec.hfields:
        past(max(0, hf.nrow) * max(0, hf.ncol), HFIELD_SAMPLES_MAX, "samples", _named("hfield", hf))
    for num in spec.numerics:
        past(num.size, SIZE_COUNT_MAX, "size", _named("numeric", num))


def _named(tag: str, obj: Any) -> str:
    name = getattr(obj, "name", "")
    return f'<{tag} name="{untrusted.excerpt(name, 40)}">' if name else f"<{tag}>"


def image_pixels(head: bytes) -> int | None:
    """Width times height of a PNG from its first 24 bytes; None for anything else."""
    if len(head) >= 24 and head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        return int.from_bytes(head[16:20], "big") * int.from_bytes(head[20:24], "big")
    return None


def check_images(found: list[tuple[str, str]], file: str, error: type[ForgeError]) -> None:
    """The texture and height-field images among ``found`` (``(path, tag)``) within
    :data:`PIXELS_MAX` and :data:`HFIELD_SAMPLES_MAX`, read from their headers: a
    small PNG can claim 10^10 pixels, which decoding would allocate."""
    for path, tag in found:
        if tag not in ("texture", "hfield"):
            continue
        pixels = image_pixels(_head(path))
        limit, what = (
            (PIXELS_MAX, "pixels") if tag == "texture" else (HFIELD_SAMPLES_MAX, "samples")
        )
        if pixels is not None and pixels > limit:
            raise error(f"{path} has {pixels:,} {what}, over {limit:,} (refused)", file=file,
                        element=f"<{tag}>")  # fmt: skip


def _head(path: str) -> bytes:
    """The first 24 bytes of the regular file ``path`` (opened without blocking)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return b""
    try:
        return os.read(fd, 24) if stat.S_ISREG(os.fstat(fd).st_mode) else b""
    except OSError:
        return b""
    finally:
        os.close(fd)


# -- the compiled model ------------------------------------------------------------------

_PARTS = ("", "opt", "stat", "vis.global_", "vis.quality", "vis.headlight", "vis.map",
          "vis.scale", "vis.rgba")  # fmt: skip


def check_compiled(m: Any, file: str, error: type[ForgeError]) -> None:
    """Every number of the compiled model ``m`` finite (``timestep="nan"``, or a number
    too big for a 32-bit float, is refused: nothing computed from it would mean
    anything, and a NaN in a report is not JSON)."""
    for part in _PARTS:
        obj = m
        for attr in filter(None, part.split(".")):
            obj = getattr(obj, attr)
        for name in dir(obj):
            if name.startswith("_"):
                continue
            try:
                value = getattr(obj, name)
            except Exception:  # an accessor that needs arguments
                continue
            if isinstance(value, float):
                value = np.array([value])
            if not isinstance(value, np.ndarray) or value.dtype.kind != "f" or not value.size:
                continue
            bad = ~np.isfinite(value)
            if bad.any():
                at = tuple(int(i) for i in np.argwhere(bad)[0])
                index = "" if value.size == 1 else "[" + ", ".join(map(str, at)) + "]"
                field = f"{part}.{name}" if part else name
                raise error(
                    f"MuJoCo compiled {field}{index} = {float(value[at])}: every number of "
                    "a model must be finite (refused)",
                    file=file,
                )
