"""The suite's pre-warmed decomposition cache: what a whole run decomposes, packed.

CoACD is most of what the corpus tests spend (a cold mini cheetah: 34 s, warm:
1.5 s), so the session cache (tests/conftest.py) starts from
``tests/data/warm-cache.tar.xz`` rather than empty. Entries are content-addressed
(the key hashes the mesh, CoACD's parameters and the versions of coacd, trimesh
and numpy), so the archive cannot make a result stale: with other versions
installed its entries are never hit and the suite decomposes as it would cold.
``tests/test_cold_cache.py`` converts one robot from an empty cache and checks it
against the warm conversion, byte for byte.

Refresh it after a change to the collision pass or to what the suite converts::

    pytest -n auto --basetemp=/tmp/suite
    python -m tests.warm_cache /tmp/suite/urdf2mjcf-cache

``URDF2MJCF_TEST_COLD_CACHE=1`` runs the whole suite from an empty cache instead.
"""

from __future__ import annotations

import io
import json
import os
import re
import sys
import tarfile
from pathlib import Path

ARCHIVE = Path(__file__).parent / "data" / "warm-cache.tar.xz"
KINDS = {"coacd": ".npz", "hull_gap": ".json", "primitive_fits": ".json"}
"""The kinds packed: what is slow to make and small to keep (decompositions, convexity
tests, primitive fits). Hulls (qhull: fast) would add half as much again; the mesh and
certificate entries are large."""
MANIFEST = "versions.json"
COLD_ENV = "URDF2MJCF_TEST_COLD_CACHE"
_NAME = re.compile(r"(?P<kind>[a-z_]+)/[0-9a-f]{64}(?P<suffix>\.[a-z]+)")


def versions() -> dict[str, object]:
    """What a decomposition's key depends on besides the mesh and the parameters."""
    from urdf2mjcf.passes.collision import decompositions

    return {"format": decompositions.CACHE_FORMAT, **decompositions._versions()}


def pack(cache: Path, archive: Path = ARCHIVE) -> int:
    """Write ``archive`` from the entries of ``cache`` (sorted, zero times and owners, so
    the same entries give the same bytes); the number of entries packed."""
    names = sorted(
        f"{kind}/{p.name}"
        for kind, suffix in KINDS.items()
        for p in (cache / kind).glob(f"*{suffix}")
        if p.is_file() and not p.is_symlink() and _NAME.fullmatch(f"{kind}/{p.name}")
    )
    members = [(MANIFEST, json.dumps(versions(), sort_keys=True).encode())]
    members += [(name, (cache / name).read_bytes()) for name in names]
    archive.parent.mkdir(parents=True, exist_ok=True)
    tmp = archive.with_suffix(".tmp")
    with tarfile.open(tmp, "w:xz", format=tarfile.USTAR_FORMAT, preset=9) as tar:
        for name, data in members:
            info = tarfile.TarInfo(name)
            info.size, info.mode, info.mtime = len(data), 0o644, 0
            tar.addfile(info, io.BytesIO(data))
    tmp.replace(archive)
    return len(names)


def unpack(cache: Path, archive: Path = ARCHIVE) -> int:
    """Put the archive's entries into ``cache`` (regular files named as the cache names
    them; anything else in it is skipped); the number of entries put there."""
    if not archive.is_file():
        return 0
    n = 0
    with tarfile.open(archive, "r:xz") as tar:
        for info in tar:
            m = _NAME.fullmatch(info.name)
            f = tar.extractfile(info) if info.isfile() and m is not None else None
            if f is None or m is None or KINDS.get(m["kind"]) != m["suffix"]:
                continue
            dest = cache / info.name
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_bytes(f.read())
            n += 1
    return n


def made_with(archive: Path = ARCHIVE) -> dict[str, object]:
    """The versions the archive was made with (its first member), or {} without one."""
    if not archive.is_file():
        return {}
    with tarfile.open(archive, "r:xz") as tar:
        info = tar.next()
        f = tar.extractfile(info) if info is not None and info.name == MANIFEST else None
        return json.loads(f.read()) if f is not None else {}


def hits() -> bool:
    """Whether this run's session cache holds the archive's entries, made with the
    versions installed."""
    return os.environ.get(COLD_ENV) != "1" and made_with() == versions()


def header() -> str:
    """One line for the test run's header: whether the archive's entries can be hit."""
    if os.environ.get(COLD_ENV) == "1":
        return "decomposition cache: cold (URDF2MJCF_TEST_COLD_CACHE=1)"
    made, now = made_with(), versions()
    if not made:
        return f"decomposition cache: cold ({ARCHIVE.name} is missing)"
    if made != now:
        return (
            f"decomposition cache: {ARCHIVE.name} was made with {made}, this run has {now}: "
            "its entries miss (python -m tests.warm_cache refreshes it)"
        )
    return f"decomposition cache: pre-warmed from {ARCHIVE.name} ({now})"


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    n = pack(Path(argv[0]))
    size = ARCHIVE.stat().st_size / 1e6
    print(f"{ARCHIVE}: {n} entries, {size:.1f} MB, made with {versions()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
