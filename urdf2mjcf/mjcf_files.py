"""Every file an MJCF model makes MuJoCo open, found where MuJoCo will find it and
checked (a regular file within its size limit) before MuJoCo opens it.

MuJoCo opens files at two times. **While it parses**, it reads each ``<include>``
(whose elements replace it, at any depth), each ``<model>`` asset (a model of its
own, in its own folder) and each ``<flexcomp file>``. :func:`read_model` reads
those documents first, the same way: strict XML, every include resolved by
MuJoCo's rules (the main model's folder first, then the including file's), each
file read as a stranger's input (:func:`urdf2mjcf.untrusted.read_file`). **While it
compiles**, it opens the ``<mesh>``, ``<texture>`` (``file`` and the six cube
sides), ``<hfield>`` and ``<skin>`` files its parse recorded: :func:`check_asset_files`
takes those names from MuJoCo's own parse (the spec: its reading of ``meshdir``,
``texturedir`` and ``assetdir`` wherever they were set, and of the include folders
it fell back to) and checks the file in every folder MuJoCo may look in.

A document we cannot read as MuJoCo does is refused rather than handed on: a
``DOCTYPE`` or an entity, an encoding other than UTF-8, a raw tab or line break in a
file name (XML parsers disagree on those), a name with ``:`` (a URI or a drive), a
file that is in none of the folders MuJoCo looks in.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lxml import etree

from . import mjcf_paths as paths
from . import untrusted
from .errors import ForgeError

DOCUMENTS_MAX = 1_000
"""Files one model reads while MuJoCo parses it: itself, its includes and its
``<model>`` assets (ours read one)."""

DOCUMENT_BYTES_MAX = 256 * 2**20
"""Bytes of all those files together (each is within the description limit too)."""
ELEMENTS_MAX = 50_000
"""Elements of a model once its includes, replicates and attachments are expanded
(our iMETRO scene has 535, a Menagerie-sized humanoid about 100). Its files may
hold at most twice as many tags before they are parsed at all."""

_NS = "{urn:urdf2mjcf:mjcf-input}"
FROM = _NS + "from"
"""Set on an ``<include>`` of an expanded tree: the file its elements came from."""
_DIR = _NS + "dir"
"""Set on an ``<include>``: that file's folder (what MuJoCo writes into its ``dir``)."""
POINTS = _NS + "points"
"""Set on a ``<flexcomp file>``: an upper bound on the points its file holds."""

_DIR_ATTRS = ("meshdir", "texturedir", "assetdir")
_RAW_NAME = re.compile(
    rb"""\b(file\w*|meshdir|texturedir|assetdir)\s*=\s*("[^"]*"|'[^']*')""", re.I
)
_MODEL_TYPES = ("", "text/xml")


@dataclass
class Model:
    """One model MuJoCo parses: the main file or a ``<model>`` asset."""

    path: str
    """The file as MuJoCo opens it (absolute, reduced as MuJoCo reduces it)."""
    root: Any
    """Its element tree with every include expanded in place, as MuJoCo expands it."""
    dirs: set[str] = field(default_factory=set)
    """Every ``meshdir``, ``texturedir`` and ``assetdir`` its documents set."""
    strippath: bool = False
    """Whether a ``<compiler strippath="true">`` drops the folders of its file names."""
    submodels: dict[str, Model] = field(default_factory=dict)
    """Its ``<model>`` assets by name."""

    @property
    def folder(self) -> str:
        return paths.folder_of(self.path)

    def models(self) -> Iterator[Model]:
        """This model and every sub-model below it."""
        yield self
        for sub in self.submodels.values():
            yield from sub.models()


def origin(el: Any, model: Model) -> str:
    """The file ``el`` of an expanded tree was read from."""
    for up in el.iterancestors():
        if up.get(FROM) is not None:
            return str(up.get(FROM))
    return model.path


def label(el: Any) -> str:
    """``el`` as an error line names it: its tag, name and line."""
    name = el.get("name")
    shown = f' name="{untrusted.excerpt(name, 40)}"' if name else ""
    return f"<{el.tag}{shown}> (line {el.sourceline})"


def exists(path: str) -> bool:
    """Whether MuJoCo would take ``path`` as found: ``stat`` succeeds (whatever it is)."""
    try:
        os.stat(path)
    except (OSError, ValueError):
        return False
    return True


def read_model(path: Path | str, *, error: type[ForgeError], what: str = "model") -> Model:
    """The model at ``path`` (and every document it reads) read as MuJoCo will read
    it when given :attr:`Model.path`; every file it reads while MuJoCo parses it
    checked. ``error`` (naming the file and element) for anything else."""
    main = paths.reduce(os.path.abspath(str(path)))
    return _Reader(error).model(main, what=what, chain=())


class _Reader:
    def __init__(self, error: type[ForgeError]):
        self.error = error
        self.documents = 0
        self.tags = 0
        self.bytes = 0
        self.points: dict[str, int] = {}  # per flexcomp file, counted once

    def fail(self, message: str, file: str, el: Any | None = None) -> ForgeError:
        return self.error(message, file=file, element=label(el) if el is not None else None)

    def model(self, path: str, *, what: str, chain: tuple[str, ...]) -> Model:
        root = self.document(path, what=what)
        if not isinstance(root.tag, str) or root.tag.lower() != "mujoco":
            raise self.fail(f"<{root.tag}> is not an MJCF model (its root must be <mujoco>)", path)
        model = Model(path=path, root=root)
        self.expand(model)
        self.parse_time_files(model, (*chain, path))
        return model

    def document(self, path: str, *, what: str, el: Any = None, at: str = "") -> Any:
        self.documents += 1
        if self.documents > DOCUMENTS_MAX:
            raise self.fail(f"reads more than {DOCUMENTS_MAX:,} files (refused)", at or path, el)
        element = label(el) if el is not None else None
        try:
            untrusted.check_regular(path, "description", error=self.error, what=what)
            refuse_kernel_file(path, self.error, at or path, element)
            data = untrusted.read_file(path, "description", error=self.error, what=what)
        except ForgeError as exc:  # named by the file and element that name it
            raise self.error(exc.detail, file=at or path, element=element) from None
        self.tags += data.count(b"<")  # each element opens (and closes): bounded before parsing
        self.bytes += len(data)
        if self.tags > 2 * ELEMENTS_MAX:
            raise self.fail(f"has more than {ELEMENTS_MAX:,} elements (refused)", path)
        if self.bytes > DOCUMENT_BYTES_MAX:
            raise self.fail(
                f"reads more than {DOCUMENT_BYTES_MAX / 2**20:g} MB of MJCF (refused)",
                at or path,
                el,
            )
        return parse_document(data, path, self.error)

    def name(self, el: Any, attr: str, file: str) -> str:
        value = el.get(attr)
        if value is None or value == "":
            raise self.fail(f"'{attr}' is missing", file, el)
        check_name(value, attr, el, file, self.error)
        return str(value)

    def expand(self, model: Model) -> None:
        """Includes replaced by their files' elements as MuJoCo's ``IncludeXML`` does:
        an include is looked for in the main model's folder first, then (inside an
        included file) in that file's folder; the included elements go inside the
        ``<include>``, which MuJoCo then reads through."""
        included = {model.path}
        stack: list[tuple[Any, str]] = [(model.root, "")]
        while stack:
            el, folder = stack.pop()
            tag = el.tag.lower()
            if tag == "compiler":
                self.compiler(el, model)
            if tag != "include":
                stack.extend((c, folder) for c in reversed(_elements(el)))
                continue
            here = origin(el, model)
            if len(el):
                raise self.fail("an <include> cannot have children", here, el)
            value = self.name(el, "file", here)
            filename = value
            if not paths.is_absolute(value) and not exists(paths.join(model.folder, value)):
                outer = _include_folder(el)  # MuJoCo's fallback: the including file's folder
                if outer is not None:
                    filename = paths.join(outer, value)
            path = paths.join(model.folder, filename)
            if not exists(path) and not paths.is_absolute(filename):
                path = paths.join(model.folder, paths.join(folder, filename))
            if not exists(path):
                raise self.fail(f"included file not found: {untrusted.excerpt(value)}", here, el)
            key = paths.join(folder, filename)
            if key in included:
                raise self.fail(f"'{untrusted.excerpt(value)}' is included twice", here, el)
            included.add(key)
            doc = self.document(path, what="included file", el=el, at=here)
            children = _elements(doc)
            if not children:
                raise self.fail(f"the included file {path} is empty", here, el)
            el.set(FROM, path)
            el.set(_DIR, paths.folder_of(path))
            for child in children:
                el.append(child)  # moved, not copied: each document is read once
            stack.extend((c, paths.folder_of(path)) for c in reversed(children))

    def compiler(self, el: Any, model: Model) -> None:
        here = origin(el, model)
        for attr in _DIR_ATTRS:
            value = el.get(attr)
            if value is not None:
                check_name(value, attr, el, here, self.error)
                model.dirs.add(str(value))
        if (el.get("strippath") or "").strip() == "true":
            model.strippath = True

    def parse_time_files(self, model: Model, chain: tuple[str, ...]) -> None:
        for el in model.root.iter("model", "flexcomp"):
            if el.tag == "model" and el.get("file") is not None:
                self.submodel(el, model, chain)
            elif el.tag == "flexcomp" and el.get("file") is not None:
                self.flexcomp_file(el, model)

    def submodel(self, el: Any, model: Model, chain: tuple[str, ...]) -> None:
        """``<model file>``: MuJoCo looks for the file as named from the current folder,
        else in the including file's folder, and reads it in the model's folder."""
        here = origin(el, model)
        value = self.name(el, "file", here)
        kind = (el.get("content_type") or "").strip()
        if kind not in _MODEL_TYPES or (not kind and not value.lower().endswith(".xml")):
            raise self.fail("a <model> asset must be an MJCF file (.xml, text/xml)", here, el)
        filename = value
        if not paths.is_absolute(value) and not exists(value):
            outer = _include_folder(el)
            if outer is not None:
                filename = paths.join(outer, value)
        path = paths.join(model.folder, filename)
        if not exists(path):
            raise self.fail(f"model file not found: {untrusted.excerpt(value)}", here, el)
        if path in chain:
            raise self.fail(f"'{untrusted.excerpt(value)}' is a <model> of itself", here, el)
        name = el.get("name") or paths.base_name(filename).rsplit(".", 1)[0]
        model.submodels[str(name)] = self.model(path, what="model asset", chain=chain)

    def flexcomp_file(self, el: Any, model: Model) -> None:
        """``<flexcomp file>``: read while MuJoCo parses, in the mesh folder in force
        there, from the file as named or from the including file's folder."""
        here = origin(el, model)
        value = self.name(el, "file", here)
        outer = _include_folder(el)
        names = [value] + ([paths.join(outer, value)] if outer is not None else [])
        found = checked_files(names, [model], "mesh", self.error, here, label(el))
        for path in found:
            if path not in self.points:
                self.points[path] = _points_in_file(path)
        el.set(POINTS, str(max(self.points[p] for p in found)))


def check_asset_files(spec: Any, model: Model, error: type[ForgeError]) -> list[tuple[str, str]]:
    """Every file MuJoCo opens compiling ``spec`` (its parse of ``model``) checked in
    every folder it may look in: the file name as its parse recorded it (an include's
    folder already prepended where it fell back to one), under the compiler's
    ``meshdir`` (meshes, skins, height fields) or ``texturedir`` (textures), in the
    folder of the model or of a ``<model>`` asset it attached. ``(path, tag)`` of each
    file found; ``error`` naming the asset for one that is not a regular file within
    its size limit, or that is in none of those folders."""
    models = list(model.models())
    found: list[tuple[str, str]] = []
    for tag, items, kind in (
        ("mesh", spec.meshes, "mesh"),
        ("skin", spec.skins, "mesh"),
        ("hfield", spec.hfields, "texture"),
        ("texture", spec.textures, "texture"),
    ):
        for obj in items:
            names = [obj.file] + (list(obj.cubefiles) if tag == "texture" else [])
            folder = "texturedir" if tag == "texture" else "meshdir"
            dirs = {str(getattr(obj.compiler, folder)), str(getattr(spec.compiler, folder))}
            element = _asset_label(tag, obj)
            for name in filter(None, (str(n) for n in names)):
                if ":" in name or any(":" in d for d in dirs):
                    raise error(
                        f"'{untrusted.excerpt(name)}': a name with ':' (a URI or a drive) is "
                        "refused",
                        file=model.path,
                        element=element,
                    )
                for path in checked_files([name], models, kind, error, model.path, element, dirs):
                    found.append((path, tag))
    return found


def _asset_label(tag: str, obj: Any) -> str:
    name = getattr(obj, "name", "")
    shown = f' name="{untrusted.excerpt(name, 40)}"' if name else ""
    info = str(getattr(obj, "info", "") or "")  # "line N"; 0 in an included file
    return f"<{tag}{shown}>" + (f" ({info})" if info and info != "line 0" else "")


def check_name(value: str, attr: str, el: Any, file: str, error: type[ForgeError]) -> None:
    """A file or folder name MuJoCo will take as we do: no ``:`` (MuJoCo reads
    ``scheme:`` as a resource provider and ``x:/`` as absolute)."""
    if ":" in value:
        raise error(
            f"{attr}='{untrusted.excerpt(value)}': a name with ':' (a URI or a drive) is refused",
            file=file,
            element=label(el),
        )


def candidates(names: list[str], models: list[Model], dirs: set[str] | None = None) -> list[str]:
    """Every path MuJoCo may open for a file named one of ``names``: in each model's
    folder, under each folder its compilers set (and none), with the folders dropped
    too when a compiler says ``strippath``."""
    variants = list(names)
    if any(m.strippath for m in models):
        variants += [paths.base_name(n) for n in names]
    folders = {""} | (dirs if dirs is not None else {d for m in models for d in m.dirs})
    out: dict[str, None] = {}
    for base in dict.fromkeys(m.folder for m in models):
        for sub in sorted(folders):
            for name in variants:
                out[paths.join(base, paths.join(sub, name))] = None
    return list(out)


def checked_files(
    names: list[str],
    models: list[Model],
    kind: str,
    error: type[ForgeError],
    file: str,
    element: str,
    dirs: set[str] | None = None,
) -> list[str]:
    """The paths (:func:`candidates`) that exist, each checked a regular file within
    ``kind``'s size limit; ``error`` when one is not, or when none exists (we do not
    know where MuJoCo would look then)."""
    found = [p for p in candidates(names, models, dirs) if exists(p)]
    if not found:
        raise error(f"file not found: {untrusted.excerpt(names[0])}", file=file, element=element)
    for path in found:
        try:
            size = untrusted.check_regular(path, kind, error=error)
        except ForgeError as exc:  # named by the file and element that name it
            raise error(exc.detail, file=file, element=element) from None
        refuse_kernel_file(path, error, file, element)
        if size == 0:
            raise error(f"file {path} is empty (refused)", file=file, element=element)
    return found


_KERNEL = ("/proc", "/sys", "/dev")


def refuse_kernel_file(path: str, error: type[ForgeError], file: str, element: str | None) -> None:
    """``error`` when ``path`` leads into ``/proc``, ``/sys`` or ``/dev``: some of their
    regular files block a reader (``/proc/kmsg``, a trace pipe), and MuJoCo reads
    assets itself, waiting."""
    real = os.path.realpath(path)
    if real.startswith("/dev/shm/"):  # a memory file system of plain files
        return
    if any(real == top or real.startswith(top + "/") for top in _KERNEL):
        raise error(
            f"file {path} is a kernel file ({real}), not a model's file; refused",
            file=file,
            element=element,
        )


def parse_document(data: bytes, path: str, error: type[ForgeError]) -> Any:
    """``data`` as an element tree, refused unless MuJoCo's XML reader (tinyxml2) and
    ours read the same elements and file names from it."""
    for match in _RAW_NAME.finditer(data):
        if re.search(rb"[\t\r\n]", match.group(2)):
            raise error(
                f"{match.group(1).decode(errors='replace')}: a file name holding a raw tab or "
                "line break is refused (XML readers disagree on it)",
                file=path,
            )
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=True
    )
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        first = re.sub(
            r" \(<string>, line \d+\)$", "", (str(exc).strip() or "empty").splitlines()[0]
        )
        raise error(f"not well-formed XML: {untrusted.excerpt(first, 200)}", file=path) from None
    info = root.getroottree().docinfo
    if info.doctype or info.internalDTD is not None or info.externalDTD is not None:
        raise error("a DOCTYPE is refused in MJCF (MuJoCo ignores it)", file=path)
    if (info.encoding or "UTF-8").upper() not in ("UTF-8", "UTF8", "ASCII", "US-ASCII"):
        raise error(f"encoding {info.encoding} is refused: MuJoCo reads UTF-8", file=path)
    for _ in root.iter(etree.Entity):
        raise error("an entity reference is refused in MJCF (MuJoCo does not expand it)", file=path)
    return root


def _elements(el: Any) -> list[Any]:
    return [c for c in el if isinstance(c.tag, str)]


def _include_folder(el: Any) -> str | None:
    """The folder of the file holding ``el`` when that is an included file (MuJoCo's
    ``dir`` of the nearest ``<include>`` around it), else None."""
    for up in el.iterancestors():
        if up.get(_DIR) is not None:
            return str(up.get(_DIR))
    return None


def _points_in_file(path: str) -> int:
    """An upper bound on the vertices of a flexcomp's mesh or gmsh file, whatever its
    format: one per line of text, or three per 50-byte triangle of a binary STL."""
    try:
        size = os.stat(path).st_size
        lines = 1
        with open(path, "rb", opener=_nonblocking) as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                return 0
            for chunk in iter(lambda: f.read(1 << 22), b""):
                lines += chunk.count(b"\n")
    except OSError:
        return 0
    return max(lines, 3 * max(0, (size - 84) // 50))


def _nonblocking(path: str, flags: int) -> int:
    return os.open(path, flags | getattr(os, "O_NONBLOCK", 0))
