"""We delete only what we wrote: ``urdf2mjcf cache clear`` and the size bound's
eviction, pointed at a user's folder, at a cache whose kind sub-folder is a symlink to
a user's folder, or at files in our folders that we did not name, delete nothing of
the user's. A bad ``$URDF2MJCF_CACHE_MAX_MB`` is one error line, never an internal
error. Every probe runs the real command in a fresh process with a time and memory
limit (:mod:`.attack`)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from urdf2mjcf import cache

from . import attack

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
URDF = """<robot name="small">
  <link name="base">
    <visual><geometry><mesh filename="meshes/colored_box.dae"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/box.stl"/></geometry></collision>
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>
"""
HEX = "0123456789abcdef" * 4
"""A name exactly like ours (64 lowercase hex digits)."""
TIMEOUT = 120


def make_robot(folder: Path) -> Path:
    (folder / "meshes").mkdir(parents=True)
    for name in ("colored_box.dae", "box.stl"):
        shutil.copy(MESHES / name, folder / "meshes" / name)
    urdf = folder / "robot.urdf"
    urdf.write_text(URDF)
    return urdf


def user_folder(folder: Path) -> Path:
    """A user's files that an old `cache clear` or eviction deleted: .json/.npz/.bin,
    also inside sub-folders named like our kinds, some even named like our entries."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "settings.json").write_text('{"mine": true}')
    (folder / "weights.npz").write_bytes(b"PK\x03\x04 the user's arrays")
    (folder / "firmware.bin").write_bytes(bytes(range(256)) * 64)
    (folder / f"{HEX}.npz").write_bytes(b"named like a decomposition")
    for kind, suffix in cache.SUFFIXES.items():
        (folder / kind).mkdir(exist_ok=True)
        (folder / kind / f"results{suffix}").write_bytes(b"the user's " + kind.encode())
        (folder / kind / f"{HEX}{suffix}").write_bytes(b"named like ours, but not ours")
    return folder


def cli(*args: str, cwd: Path, env: dict[str, str] | None = None) -> attack.Result:
    return attack.run("urdf2mjcf", *args, cwd=cwd, env=env, timeout=TIMEOUT)


def convert(tmp: Path, cache_dir: Path, env: dict[str, str] | None = None) -> attack.Result:
    urdf = tmp / "robot" / "robot.urdf"
    if not urdf.exists():
        make_robot(urdf.parent)
    out = tmp / "out" / "robot.xml"
    return cli(
        str(urdf), "-o", str(out), "--overwrite", "--cache-dir", str(cache_dir), cwd=tmp, env=env
    )


def our_cache(tmp: Path) -> Path:
    """A cache a real conversion made (marked with our CACHEDIR.TAG)."""
    root = tmp / "cache"
    res = convert(tmp, root)
    assert res.returncode == 0, res.stderr
    assert cache.is_ours(root)
    assert list((root / "meshes").glob("*.bin")) and list((root / "hull_gap").glob("*.json"))
    return root


# -- cache clear ------------------------------------------------------------------------


def test_clear_refuses_a_users_folder_without_our_marker(tmp_path):
    user = user_folder(tmp_path / "Documents")
    before = attack.snapshot(user)
    res = cli("cache", "clear", "--cache-dir", str(user), cwd=tmp_path)
    attack.assert_one_error(res, str(user), "CACHEDIR.TAG", "delete the folder yourself")
    assert attack.snapshot(user) == before
    assert res.seconds < TIMEOUT


def test_clear_refuses_another_tools_cachedir_tag(tmp_path):
    user = user_folder(tmp_path / "other-tool-cache")
    (user / "CACHEDIR.TAG").write_text(f"{cache.TAG_SIGNATURE}\n# made by another tool\n")
    before = attack.snapshot(user)
    res = cli("cache", "clear", "--cache-dir", str(user), cwd=tmp_path)
    attack.assert_one_error(res, str(user), "CACHEDIR.TAG")
    assert attack.snapshot(user) == before


def test_clear_refuses_a_tag_that_is_a_symlink_to_ours(tmp_path):
    ours = our_cache(tmp_path)
    user = user_folder(tmp_path / "user")
    (user / "CACHEDIR.TAG").symlink_to(ours / "CACHEDIR.TAG")
    before = attack.snapshot(user)
    res = cli("cache", "clear", "--cache-dir", str(user), cwd=tmp_path)
    attack.assert_one_error(res, str(user), "CACHEDIR.TAG")
    assert attack.snapshot(user) == before


def test_info_on_a_folder_without_marker_reports_and_changes_nothing(tmp_path):
    user = user_folder(tmp_path / "Documents")
    before = attack.snapshot(user)
    res = cli("cache", "info", "--cache-dir", str(user), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "not a cache of ours" in res.stdout
    assert "loaded meshes (meshes/): 1 entries" in res.stdout  # read only, by our naming
    assert attack.snapshot(user) == before


def test_clear_skips_a_kind_folder_that_is_a_symlink_to_a_users_folder(tmp_path):
    root = our_cache(tmp_path)
    user = user_folder(tmp_path / "user")
    shutil.rmtree(root / "meshes")
    (root / "meshes").symlink_to(user / "meshes")
    (root / "coacd").symlink_to(user)  # a kind folder that is a link to the user's root
    before = attack.snapshot(user)
    res = cli("cache", "clear", "--cache-dir", str(root), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert attack.snapshot(user) == before
    assert (root / "meshes").is_symlink() and (root / "coacd").is_symlink()
    assert not (root / "hull_gap").exists(), "our own entries did go"
    assert "removed 0 entries" not in res.stdout


def test_clear_deletes_only_files_named_as_ours(tmp_path):
    root = our_cache(tmp_path)
    user_file = tmp_path / "precious.bin"
    user_file.write_bytes(b"the user's file")
    keep = {
        "meshes": [
            "notes.txt",
            f"{HEX.upper()}.bin",  # upper case: not ours
            f"{HEX}.bin.bak",
            f"{HEX}.npz",  # another kind's suffix
            f"{HEX[:63]}.bin",
            f".{HEX[:16]}.abc.tmp",  # not mkstemp's 8 characters
            "results.json",
        ],
        "coacd": [f"{HEX}.bin", f"{HEX}.json", "x.npz"],
        "hull_gap": [f"{HEX}.npz", "mine.json"],
    }
    for kind, names in keep.items():
        (root / kind).mkdir(exist_ok=True)
        for name in names:
            (root / kind / name).write_text(f"mine: {name}")
    link = root / "meshes" / f"{'f' * 64}.bin"  # a symlink named like an entry
    link.symlink_to(user_file)
    before = {
        p: p.read_bytes() for kind, names in keep.items() for p in (root / kind / n for n in names)
    }
    stale = root / "meshes" / f".{HEX[:16]}.abcd_123.tmp"  # our stale temporary file: goes
    stale.write_bytes(b"half an entry")
    res = cli("cache", "clear", "--cache-dir", str(root), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert {p: p.read_bytes() for p in before} == before
    assert link.is_symlink() and user_file.read_bytes() == b"the user's file"
    assert not stale.exists()
    for kind in cache.KINDS:  # every real entry of ours went
        folder = root / kind
        if folder.is_dir():
            ours = [p for p in folder.iterdir() if cache.is_entry_name(kind, p.name)]
            assert all(p.is_symlink() for p in ours), ours


# -- eviction --------------------------------------------------------------------------


def test_eviction_in_a_users_folder_without_marker_deletes_nothing(tmp_path):
    user = user_folder(tmp_path / "Documents")
    before = attack.snapshot(user)
    res = convert(tmp_path, user, env={"URDF2MJCF_CACHE_MAX_MB": "0.001"})
    assert res.returncode == 0, res.stderr
    after = attack.snapshot(user)
    assert {k: v for k, v in after.items() if k in before} == before, "the user's files stay"
    assert not cache.is_ours(user), "a folder with files we did not name is not marked"
    assert "CACHEDIR.TAG" in res.stderr  # the warning: never evicted


def test_eviction_in_our_cache_spares_what_we_did_not_name(tmp_path):
    root = our_cache(tmp_path)
    user = user_folder(tmp_path / "user")
    for kind, suffix in cache.SUFFIXES.items():
        (root / kind).mkdir(exist_ok=True)
        (root / kind / f"results{suffix}").write_bytes(b"the user's")
        (root / kind / f"{HEX.upper()}{suffix}").write_bytes(b"the user's too")
    (root / "settings.json").write_text("{}")
    shutil.rmtree(root / "hulls")
    (root / "hulls").symlink_to(user / "hulls")  # a linked kind folder: never evicted
    old = [p for p in root.rglob("*") if cache.is_entry_name(p.parent.name, p.name)]
    assert old
    mine = {
        p: p.read_bytes()
        for p in root.rglob("*")
        if p.is_file() and not p.is_symlink() and not cache.is_entry_name(p.parent.name, p.name)
    }
    before = attack.snapshot(user)
    (tmp_path / "robot" / "meshes" / "box.stl").write_bytes(
        (MESHES / "box_ascii.stl").read_bytes()
    )  # a changed mesh: new entries, so the run writes and evicts
    res = convert(tmp_path, root, env={"URDF2MJCF_CACHE_MAX_MB": "0.000001"})
    assert res.returncode == 0, res.stderr
    assert {p: p.read_bytes() for p in mine} == mine
    assert attack.snapshot(user) == before
    assert not any(p.exists() for p in old), "our entries were evicted down to the bound"


# -- the bound's environment variable ---------------------------------------------------


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e300", "-1", "lots", "1e7.5"])
def test_bad_cache_max_mb_is_one_error_line(tmp_path, value):
    env = {"URDF2MJCF_CACHE_MAX_MB": value}
    res = convert(tmp_path, tmp_path / "cache", env=env)
    attack.assert_one_error(res, "URDF2MJCF_CACHE_MAX_MB")
    assert not (tmp_path / "out").exists(), "nothing written"
    res = cli("cache", "info", "--cache-dir", str(tmp_path / "cache"), cwd=tmp_path, env=env)
    attack.assert_one_error(res, "URDF2MJCF_CACHE_MAX_MB")


def test_cache_max_mb_is_ignored_without_the_cache(tmp_path):
    urdf = make_robot(tmp_path / "robot")
    res = cli(
        str(urdf),
        "-o",
        str(tmp_path / "out" / "robot.xml"),
        "--no-cache",
        cwd=tmp_path,
        env={"URDF2MJCF_CACHE_MAX_MB": "nan"},
    )
    assert res.returncode == 0, res.stderr
