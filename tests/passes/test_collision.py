"""Collision pass: primitives, hulls, CoACD decompositions, cache, determinism."""

from __future__ import annotations

import dataclasses
import hashlib
import io
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from urdf2mjcf.assets import stl_bytes
from urdf2mjcf.errors import MeshError
from urdf2mjcf.ir import (
    Box,
    Capsule,
    Collision,
    Cylinder,
    Link,
    LoadedMesh,
    MeshData,
    MeshPart,
    MeshRef,
    Model,
    Pose,
    Robot,
    Sphere,
    Visual,
)
from urdf2mjcf.mesh_distance import VOLUME_RATIO
from urdf2mjcf.passes import collision
from urdf2mjcf.passes.collision import CollisionConfig
from urdf2mjcf.passes.collision.convexity import hull_fit
from urdf2mjcf.passes.collision.decompositions import (
    DecompositionCache,
    array_digest,
    cache_key,
    default_cache_dir,
)

# ---------------------------------------------------------------------------
# Test meshes (generated, metres)
# ---------------------------------------------------------------------------


def _md(mesh: trimesh.Trimesh) -> MeshData:
    return MeshData(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64))


def u_shape() -> trimesh.Trimesh:
    """A 0.3 x 0.1 x 0.2 block with a 0.2 wide channel cut 0.15 deep from the top."""
    outer = trimesh.creation.box((0.3, 0.1, 0.2))
    cut = trimesh.creation.box((0.2, 0.2, 0.2))
    cut.apply_translation((0.0, 0.0, 0.05))
    return trimesh.boolean.difference([outer, cut], engine="manifold")


def dented_box() -> trimesh.Trimesh:
    """A box with a shallow pocket: convex apart from 3 mm."""
    outer = trimesh.creation.box((0.2, 0.2, 0.2))
    pocket = trimesh.creation.box((0.05, 0.05, 0.01))
    pocket.apply_translation((0.0, 0.0, 0.1))
    return trimesh.boolean.difference([outer, pocket], engine="manifold")


def drop_faces(mesh: trimesh.Trimesh, faces) -> trimesh.Trimesh:
    keep = np.ones(len(mesh.faces), bool)
    keep[list(faces)] = False
    return trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)


def cracked_sphere() -> trimesh.Trimesh:
    """An icosphere with a few triangles missing: not watertight, still convex."""
    return drop_faces(trimesh.creation.icosphere(subdivisions=3, radius=0.05), range(0, 40, 7))


def open_box() -> trimesh.Trimesh:
    """A box with its top face missing."""
    box = trimesh.creation.box((0.1, 0.1, 0.1))
    top = np.flatnonzero(box.face_normals[:, 2] > 0.9)
    return drop_faces(box, top)


def cracked_box() -> trimesh.Trimesh:
    """A box with one triangle of its top face missing: a crack, not an opening."""
    box = trimesh.creation.box((0.1, 0.1, 0.1))
    top = np.flatnonzero(box.face_normals[:, 2] > 0.9)
    return drop_faces(box, top[:1])


def open_u_shape() -> trimesh.Trimesh:
    """The U shape with one end wall missing: not watertight, clearly concave."""
    u = u_shape()
    end = np.flatnonzero(u.face_normals[:, 1] > 0.9)
    return drop_faces(u, end)


# ---------------------------------------------------------------------------
# Building models
# ---------------------------------------------------------------------------


class Builder:
    """Links with collision/visual elements and the loaded meshes they use."""

    def __init__(self, root: Path):
        self.root = root
        self.meshes: dict = {}

    def mesh(self, name: str, mesh: trimesh.Trimesh, scale=(1.0, 1.0, 1.0)) -> MeshRef:
        path = self.root / name
        md = _md(mesh)
        path.write_bytes(stl_bytes(md))
        digest = hashlib.sha256(stl_bytes(md) + repr(scale).encode()).hexdigest()
        self.meshes[(path, scale)] = LoadedMesh(
            path=path, scale=scale, parts=(MeshPart(md, None),), merged=md, sha256=digest
        )
        return MeshRef(filename=f"meshes/{name}", path=path, scale=scale)

    def model(self, *links: Link) -> Model:
        robot = Robot(name="robot", source=self.root / "robot.urdf", links=links, joints=())
        return Model(robot=robot, meshes=dict(self.meshes))


def col(geometry, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> Collision:
    return Collision(origin=Pose(xyz, rpy), geometry=geometry)


@pytest.fixture
def build(tmp_path) -> Builder:
    return Builder(tmp_path)


@pytest.fixture
def cfg(tmp_path) -> CollisionConfig:
    return CollisionConfig(cache_dir=tmp_path / "cache", workers=1)


def kinds(model: Model) -> list[str]:
    return [n.kind for n in model.notes]


def asset_data(model: Model, name: str) -> trimesh.Trimesh:
    asset = next(a for a in model.mesh_assets if a.name == name)
    return trimesh.load(io.BytesIO(asset.data), file_type="stl", process=True)


def part_meshes(model: Model, link: str) -> list[trimesh.Trimesh]:
    return [asset_data(model, g.mesh) for g in model.collision_geoms[link] if g.type == "mesh"]


def snapshot(model: Model):
    """Everything the pass produced, as comparable plain data."""
    geoms = {k: tuple(dataclasses.astuple(g) for g in v) for k, v in model.collision_geoms.items()}
    assets = tuple((a.name, a.file, a.data) for a in model.mesh_assets)
    return geoms, assets, tuple(model.notes)


# ---------------------------------------------------------------------------
# Convexity measure
# ---------------------------------------------------------------------------


def test_hull_gap_is_small_for_convex_and_large_for_u_shape():
    assert hull_fit(trimesh.creation.box((0.3, 0.1, 0.2))).gap < 0.005
    assert hull_fit(trimesh.creation.icosphere(radius=0.05)).gap < 0.005
    assert hull_fit(cracked_sphere()).gap < 0.005
    assert hull_fit(u_shape()).gap > 0.035
    assert hull_fit(open_u_shape()).gap > 0.035


def test_hull_gap_is_deterministic_and_independent_of_scale():
    u = u_shape()
    big = u.copy()
    big.apply_scale(10.0)
    assert hull_fit(u).gap == hull_fit(u_shape()).gap
    assert hull_fit(big).gap == pytest.approx(hull_fit(u).gap, rel=1e-6)


# ---------------------------------------------------------------------------
# Primitives, hulls, decompositions
# ---------------------------------------------------------------------------


def test_primitives_stay_primitives_with_mujoco_half_sizes(build, cfg):
    link = Link(
        "base",
        collisions=(
            col(Box((0.2, 0.4, 0.6)), xyz=(1.0, 2.0, 3.0)),
            col(Cylinder(radius=0.1, length=0.5), rpy=(0.0, np.pi / 2, 0.0)),
            col(Sphere(radius=0.3)),
            col(Capsule(radius=0.05, length=0.2)),
        ),
    )
    out = collision.run(build.model(link), cfg)
    geoms = out.collision_geoms["base"]
    assert [g.type for g in geoms] == ["box", "cylinder", "sphere", "capsule"]
    assert geoms[0].size == pytest.approx((0.1, 0.2, 0.3))
    assert geoms[0].pos == (1.0, 2.0, 3.0)
    assert geoms[1].size == pytest.approx((0.1, 0.25))
    assert geoms[1].quat == pytest.approx((np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0))
    assert geoms[2].size == pytest.approx((0.3,))
    assert geoms[3].size == pytest.approx((0.05, 0.1))
    assert all(g.role == "collision" for g in geoms)
    assert out.mesh_assets == ()


def test_near_convex_mesh_becomes_one_geom_holding_its_convex_hull(build, cfg):
    mesh = dented_box()
    ref = build.mesh("dented.stl", mesh)
    out = collision.run(build.model(Link("arm", collisions=(col(ref, xyz=(0.0, 0.0, 0.5)),))), cfg)
    (geom,) = out.collision_geoms["arm"]
    assert geom.type == "mesh" and geom.pos == (0.0, 0.0, 0.5)
    assert "hull" in geom.mesh
    hull = asset_data(out, geom.mesh)
    expected = mesh.vertices[ConvexHull(mesh.vertices).vertices]
    got = np.unique(np.round(hull.vertices, 6), axis=0)
    assert np.array_equal(got, np.unique(np.round(expected, 6), axis=0))
    assert hull.is_watertight and hull.volume == pytest.approx(0.2**3, rel=1e-5)
    assert "hull" in kinds(out) and "decomposed" not in kinds(out)


def test_u_shape_is_decomposed_into_convex_parts_that_cover_it(build, cfg):
    mesh = u_shape()
    ref = build.mesh("u_shape.stl", mesh)
    out = collision.run(build.model(Link("bracket", collisions=(col(ref),))), cfg)
    parts = part_meshes(out, "bracket")
    assert len(parts) >= 2
    assert len(parts) == len(out.collision_geoms["bracket"])
    for part in parts:  # each part is its own convex hull
        assert part.is_watertight
        assert part.volume == pytest.approx(part.convex_hull.volume, rel=1e-6)
    total = sum(p.volume for p in parts)
    assert 0.9 * mesh.volume <= total <= 1.25 * mesh.volume  # hull of the U: 2x the volume
    # Points inside the U lie inside some part.
    rng = np.random.default_rng(0)
    pts = rng.uniform(mesh.bounds[0], mesh.bounds[1], size=(4000, 3))
    inside = pts[_inside_u(pts)]
    covered = np.zeros(len(inside), bool)
    for part in parts:
        eq = ConvexHull(part.vertices).equations
        covered |= np.all(inside @ eq[:, :3].T + eq[:, 3] <= 1e-4, axis=1)
    assert covered.mean() > 0.97
    (note,) = [n for n in out.notes if n.kind == "decomposed"]
    assert note.element == "mesh 'meshes/u_shape.stl'"
    assert note.message.startswith(f"{len(parts)} convex parts")


def _inside_u(p: np.ndarray) -> np.ndarray:
    in_block = np.all(np.abs(p) <= (0.15, 0.05, 0.1), axis=1)
    in_channel = (np.abs(p[:, 0]) < 0.1) & (p[:, 2] > -0.05)
    return in_block & ~in_channel


def test_parts_are_placed_at_the_element_origin_in_the_mesh_frame(build, cfg):
    ref = build.mesh("u_shape.stl", u_shape())
    link = Link("bracket", collisions=(col(ref, xyz=(0.1, 0.2, 0.3), rpy=(0.0, 0.0, 1.0)),))
    out = collision.run(build.model(link), cfg)
    geoms = out.collision_geoms["bracket"]
    assert {g.pos for g in geoms} == {(0.1, 0.2, 0.3)}
    for g in geoms:
        assert g.quat == pytest.approx((np.cos(0.5), 0.0, 0.0, np.sin(0.5)))
    lo = np.min([p.bounds[0] for p in part_meshes(out, "bracket")], axis=0)
    hi = np.max([p.bounds[1] for p in part_meshes(out, "bracket")], axis=0)
    assert lo == pytest.approx((-0.15, -0.05, -0.1), abs=0.01)
    assert hi == pytest.approx((0.15, 0.05, 0.1), abs=0.01)


def test_non_watertight_near_convex_meshes_become_hulls(build, cfg):
    sphere, box = cracked_sphere(), cracked_box()
    assert not sphere.is_watertight and not box.is_watertight
    link = Link(
        "head",
        collisions=(col(build.mesh("sphere.stl", sphere)), col(build.mesh("open.stl", box))),
    )
    out = collision.run(build.model(link), cfg)
    geoms = out.collision_geoms["head"]
    assert len(geoms) == 2 and all("hull" in g.mesh for g in geoms)
    assert "decomposed" not in kinds(out)
    assert asset_data(out, geoms[1].mesh).volume == pytest.approx(1e-3, rel=1e-5)


def test_open_topped_box_is_decomposed_as_the_certificate_would_fail_its_hull(build, cfg):
    """A cup passes the hull gap (0.016), but its hull's lid lies 47 mm from any of its
    faces, past the certificate's distance tolerance (a quarter of its 173 mm
    diagonal): the certificate's own figures send it to CoACD."""
    cup = open_box()
    diagonal = float(np.linalg.norm(cup.extents))
    lid_centre = np.array([[0.0, 0.0, 0.05]])
    # the reference: the lid's centre against every face of the cup, exactly
    _, to_cup, _ = trimesh.proximity.closest_point(cup, lid_centre)
    assert to_cup[0] > 0.25 * diagonal
    assert hull_fit(cup).gap <= collision.CollisionConfig.max_hull_gap
    out = collision.run(
        build.model(Link("cup", collisions=(col(build.mesh("cup.stl", cup)),))), cfg
    )
    assert kinds(out).count("decomposed") == 1
    (note,) = [n for n in out.notes if n.kind == "decomposed"]
    assert "hull sticks out" in note.message and "tolerance 43.3 mm" in note.message
    assert len(out.collision_geoms["cup"]) > 1


def tube(outer: float, inner: float, length: float) -> trimesh.Trimesh:
    return trimesh.creation.annulus(r_min=inner, r_max=outer, height=length, sections=48)


def test_thin_tube_is_decomposed_not_hulled_by_the_certificates_volume_rule(build, cfg):
    """A tube's hull passes the gap (its surface lies on the tube) but is the solid
    cylinder, 5.26 x the tube's volume by the analytic formula: past the
    certificate's 5, so it is cut, finely (the default remesh would fill the wall),
    into parts that leave the bore open and enclose less than 5 x the tube."""
    ro, ri, length = 0.03, 0.027, 0.2
    pipe = tube(ro, ri, length)
    assert hull_fit(pipe).gap <= collision.CollisionConfig.max_hull_gap
    analytic = ro**2 / (ro**2 - ri**2)
    assert analytic > VOLUME_RATIO[1]
    out = collision.run(
        build.model(Link("tube", collisions=(col(build.mesh("t.stl", pipe)),))), cfg
    )
    (note,) = [n for n in out.notes if n.kind == "decomposed"]
    assert f"hull volume {analytic:.3g} x the mesh's: a hollow part" in note.message
    parts = part_meshes(out, "tube")
    assert len(parts) > 4
    union = trimesh.boolean.union(parts, engine="manifold").volume
    assert union / (np.pi * (ro**2 - ri**2) * length) < VOLUME_RATIO[1]
    # the bore stays open: no part's surface comes within 0.8 of the inner radius of the
    # axis (the hull fills it; the parts' chords between the wall's vertices cut in a little)
    for part in parts:
        points, _ = trimesh.sample.sample_surface(part, 2000, seed=0)
        assert np.linalg.norm(points[:, :2], axis=1).min() > 0.8 * ri


def test_non_watertight_concave_mesh_is_decomposed(build, cfg):
    mesh = open_u_shape()
    assert not mesh.is_watertight
    out = collision.run(
        build.model(Link("fork", collisions=(col(build.mesh("f.stl", mesh)),))), cfg
    )
    assert "decomposed" in kinds(out)
    parts = part_meshes(out, "fork")
    assert len(parts) >= 2
    assert sum(p.volume for p in parts) < 0.8 * mesh.convex_hull.volume


def test_flat_mesh_becomes_a_thin_box(build, cfg):
    plate = trimesh.Trimesh(
        [[0, 0, 0], [0.2, 0, 0], [0, 0.1, 0], [0.2, 0.1, 0]], [[0, 1, 2], [1, 3, 2]]
    )
    out = collision.run(
        build.model(Link("plate", collisions=(col(build.mesh("p.stl", plate)),))), cfg
    )
    (geom,) = out.collision_geoms["plate"]
    assert geom.type == "box"
    assert sorted(geom.size) == pytest.approx(sorted((0.1, 0.05, 0.0005)))
    assert geom.pos == pytest.approx((0.1, 0.05, 0.0))
    assert "warning" in kinds(out)


def test_tilted_flat_mesh_gets_the_tightest_box_around_it(build, cfg):
    from urdf2mjcf.transforms import rpy_to_matrix, transform

    rot = rpy_to_matrix((0.4, -0.3, 0.5))
    corners = np.array([[x, y, 0.0] for x in (-0.1, 0.1) for y in (-0.05, 0.05)])
    plate = trimesh.Trimesh(corners @ rot.T + (0.3, 0.0, 0.1), [[0, 1, 3], [0, 3, 2]])
    out = collision.run(
        build.model(Link("plate", collisions=(col(build.mesh("p.stl", plate)),))), cfg
    )
    (geom,) = out.collision_geoms["plate"]
    assert sorted(geom.size) == pytest.approx(sorted((0.1, 0.05, 0.0005)), abs=1e-9)
    local = (np.c_[plate.vertices, np.ones(4)] @ np.linalg.inv(transform(geom.pos, geom.quat)).T)[
        :, :3
    ]
    assert np.all(np.abs(local) <= np.array(geom.size) + 1e-9)


def test_the_same_mesh_on_two_links_is_processed_and_stored_once(build, cfg):
    ref = build.mesh("u_shape.stl", u_shape())
    link_a, link_b = Link("a", collisions=(col(ref),)), Link("b", collisions=(col(ref),))
    out = collision.run(build.model(link_a, link_b), cfg)
    assert kinds(out).count("decomposed") == 1
    names_a = [g.mesh for g in out.collision_geoms["a"]]
    assert names_a == [g.mesh for g in out.collision_geoms["b"]]
    assert len(out.mesh_assets) == len(names_a)


# ---------------------------------------------------------------------------
# Names and sources
# ---------------------------------------------------------------------------


def test_geom_names_follow_the_link_rule(build, cfg):
    ref = build.mesh("u_shape.stl", u_shape())
    links = (
        Link("single", collisions=(col(Box((1.0, 1.0, 1.0))),)),
        Link("pair", collisions=(col(Sphere(0.1)), col(Sphere(0.2)))),
        Link("decomposed", collisions=(col(ref),)),
        Link("mixed", collisions=(col(Sphere(0.1)), col(ref))),
        Link("empty"),
    )
    out = collision.run(build.model(*links), cfg)
    names = {k: [g.name for g in v] for k, v in out.collision_geoms.items()}
    n_parts = len(names["decomposed"])
    assert n_parts >= 2
    assert names["single"] == ["single_collision"]
    assert names["pair"] == ["pair_collision_0", "pair_collision_1"]
    assert names["decomposed"] == [f"decomposed_collision_{k}" for k in range(n_parts)]
    assert names["mixed"] == [f"mixed_collision_{k}" for k in range(n_parts + 1)]
    assert names["empty"] == []
    assert list(out.collision_geoms) == ["single", "pair", "decomposed", "mixed", "empty"]


def test_visual_source_takes_geometry_from_visual_elements(build, cfg):
    ref = build.mesh("dented.stl", dented_box())
    missing = MeshRef("meshes/missing.stl", build.root / "missing.stl")
    link = Link(
        "base",
        visuals=(Visual(Pose(), Sphere(0.3)), Visual(Pose(), ref), Visual(Pose(), missing)),
        collisions=(col(Box((1.0, 1.0, 1.0))),),
    )
    out = collision.run(build.model(link), dataclasses.replace(cfg, source="visual"))
    geoms = out.collision_geoms["base"]
    assert [g.type for g in geoms] == ["sphere", "mesh"]  # the missing mesh is skipped
    assert all(g.role == "collision" for g in geoms)


def test_none_source_gives_no_collision_geoms(build, cfg):
    ref = build.mesh("u_shape.stl", u_shape())
    link = Link("base", collisions=(col(ref), col(Box((1.0, 1.0, 1.0)))))
    out = collision.run(build.model(link), dataclasses.replace(cfg, source="none"))
    assert out.collision_geoms == {"base": ()}
    assert out.mesh_assets == () and out.notes == ()


def test_unloaded_collision_mesh_is_an_error(build, cfg):
    missing = MeshRef("meshes/missing.stl", build.root / "missing.stl")
    with pytest.raises(MeshError, match="missing.stl"):
        collision.run(build.model(Link("base", collisions=(col(missing),))), cfg)


# ---------------------------------------------------------------------------
# Cache, parallelism, determinism
# ---------------------------------------------------------------------------


def test_second_run_takes_decompositions_from_the_cache(build, cfg, monkeypatch):
    model = build.model(Link("bracket", collisions=(col(build.mesh("u.stl", u_shape())),)))
    first = collision.run(model, cfg)
    assert kinds(first).count("decomposed") == 1

    import coacd

    def boom(*args, **kwargs):
        raise AssertionError("CoACD must not run on a warm cache")

    monkeypatch.setattr(coacd, "run_coacd", boom)
    second = collision.run(model, cfg)
    assert "decomposed" not in kinds(second)
    assert kinds(second).count("cached") == 1
    assert snapshot(second)[:2] == snapshot(first)[:2]


def test_second_run_takes_the_convexity_test_from_the_cache_too(build, cfg, monkeypatch):
    model = build.model(
        Link("bracket", collisions=(col(build.mesh("u.stl", u_shape())),)),
        Link(
            "block", collisions=(col(build.mesh("b.stl", trimesh.creation.box((0.1, 0.1, 0.1)))),)
        ),
    )
    first = collision.run(model, cfg)

    def boom(mesh):
        raise AssertionError("the hull gap must come from the cache")

    monkeypatch.setattr(collision, "hull_fit", boom)
    second = collision.run(model, cfg)
    assert snapshot(second)[:2] == snapshot(first)[:2], "same geoms and assets"


def test_second_run_takes_the_convex_hull_from_the_cache(build, cfg, monkeypatch):
    """A near-convex mesh on a warm cache: the stored hull, bit for bit, without
    building a trimesh or running qhull; a corrupt hull entry is computed again."""
    dented = build.mesh("d.stl", dented_box())
    model = build.model(Link("block", collisions=(col(dented),)))
    first = collision.run(model, cfg)
    assert kinds(first).count("hull") == 1
    (entry,) = (cfg.cache_dir / "hulls").glob("*.npz")
    good = entry.read_bytes()

    def boom(*args, **kwargs):
        raise AssertionError("a stored hull needs neither trimesh nor qhull")

    with monkeypatch.context() as patched:
        patched.setattr(collision, "as_trimesh", boom)
        patched.setattr(collision, "convex_hull", boom)
        second = collision.run(model, cfg)
    assert snapshot(second)[:2] == snapshot(first)[:2], "same geoms and asset bytes"
    for garbage in (b"not a zip file", good[: len(good) // 2]):
        entry.write_bytes(garbage)
        again = collision.run(model, cfg)
        assert snapshot(again)[:2] == snapshot(first)[:2]
        assert entry.read_bytes() == good


def test_corrupt_cache_entry_is_ignored_and_rewritten(build, cfg):
    model = build.model(Link("bracket", collisions=(col(build.mesh("u.stl", u_shape())),)))
    first = collision.run(model, cfg)
    (entry,) = (cfg.cache_dir / "coacd").glob("*.npz")
    good = entry.read_bytes()
    for garbage in (b"not a zip file", good[: len(good) // 2]):
        entry.write_bytes(garbage)
        again = collision.run(model, cfg)
        assert kinds(again).count("decomposed") == 1 and "cached" not in kinds(again)
        assert snapshot(again)[:2] == snapshot(first)[:2]
        assert entry.read_bytes() == good
    assert not list((cfg.cache_dir / "coacd").glob("*.tmp"))


def test_unwritable_cache_does_not_stop_the_conversion(build, cfg, tmp_path):
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("")
    model = build.model(Link("bracket", collisions=(col(build.mesh("u.stl", u_shape())),)))
    out = collision.run(model, dataclasses.replace(cfg, cache_dir=blocker))
    assert kinds(out).count("decomposed") == 1
    assert len(out.collision_geoms["bracket"]) >= 2


def test_cache_can_be_disabled(build, cfg):
    model = build.model(Link("bracket", collisions=(col(build.mesh("u.stl", u_shape())),)))
    off = dataclasses.replace(cfg, use_cache=False)
    collision.run(model, off)
    assert kinds(collision.run(model, off)).count("decomposed") == 1
    assert not (cfg.cache_dir / "coacd").exists()


def test_cache_key_depends_on_mesh_and_params():
    v, f = np.zeros((3, 3)), np.array([[0, 1, 2]])
    base = cache_key("a" * 64, array_digest(v, f), {"threshold": 0.1})
    assert base == cache_key("a" * 64, array_digest(v, f), {"threshold": 0.1})
    assert base != cache_key("b" * 64, array_digest(v, f), {"threshold": 0.1})
    assert base != cache_key("a" * 64, array_digest(v + 1, f), {"threshold": 0.1})
    assert base != cache_key("a" * 64, array_digest(v, f), {"threshold": 0.2})


def test_cache_entry_under_another_key_is_a_miss(tmp_path):
    cache = DecompositionCache(tmp_path)
    part = MeshData(np.eye(4)[:, :3].copy(), np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]]))
    cache.store("k1", [part])
    assert cache.load("k1")[0].vertices.tolist() == part.vertices.tolist()
    cache.path("k1").rename(cache.path("k2"))
    assert cache.load("k2") is None


def test_default_cache_dir_follows_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("URDF2MJCF_CACHE", str(tmp_path / "explicit"))
    assert default_cache_dir() == tmp_path / "explicit"
    monkeypatch.delenv("URDF2MJCF_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "urdf2mjcf"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert default_cache_dir() == Path.home() / ".cache" / "urdf2mjcf"


def _three_concave_links(build: Builder) -> Model:
    u = u_shape()
    tall = u.copy()
    tall.apply_scale((1.0, 1.0, 2.0))
    return build.model(
        Link("a", collisions=(col(build.mesh("u.stl", u)),)),
        Link("b", collisions=(col(build.mesh("fork.stl", open_u_shape())), col(Sphere(0.1)))),
        Link("c", collisions=(col(build.mesh("tall.stl", tall)),)),
    )


def test_output_is_identical_across_runs_and_worker_counts(build, tmp_path):
    model = _three_concave_links(build)
    calls = []
    serial = CollisionConfig(use_cache=False, workers=1)
    pooled = CollisionConfig(use_cache=False, workers=2, progress=lambda *a: calls.append(a))
    first = collision.run(model, serial)
    assert kinds(first).count("decomposed") == 3
    assert snapshot(collision.run(model, serial)) == snapshot(first)
    assert snapshot(collision.run(model, pooled)) == snapshot(first)
    assert sorted(c[0] for c in calls) == [1, 2, 3] and {c[1] for c in calls} == {3}
    assert {c[2] for c in calls} == {"u.stl", "fork.stl", "tall.stl"}


def test_progress_reports_each_decomposition(build, cfg):
    calls = []
    model = _three_concave_links(build)
    collision.run(model, dataclasses.replace(cfg, progress=lambda *a: calls.append(a)))
    assert [c[:2] for c in calls] == [(1, 3), (2, 3), (3, 3)]
    calls.clear()
    collision.run(model, dataclasses.replace(cfg, progress=lambda *a: calls.append(a)))
    assert calls == []  # everything cached


# ---------------------------------------------------------------------------
# MuJoCo accepts the result
# ---------------------------------------------------------------------------


def test_hull_and_part_meshes_compile_in_mujoco(build, cfg, tmp_path):
    links = (
        Link("bracket", collisions=(col(build.mesh("u.stl", u_shape()), xyz=(0.0, 0.0, 0.3)),)),
        Link(
            "ball",
            collisions=(col(build.mesh("s.stl", cracked_sphere())), col(Box((0.1, 0.1, 0.1)))),
        ),
    )
    out = collision.run(build.model(*links), cfg)
    assets = tmp_path / "assets"
    assets.mkdir()
    for a in out.mesh_assets:
        (assets / a.file).write_bytes(a.data)
    mesh_xml = "".join(f'<mesh name="{a.name}" file="{a.file}"/>' for a in out.mesh_assets)
    bodies = ""
    for link, geoms in out.collision_geoms.items():
        parts = []
        for g in geoms:
            attrs = f'name="{g.name}" type="{g.type}" pos="{" ".join(map(repr, g.pos))}" '
            attrs += f'quat="{" ".join(map(repr, g.quat))}"'
            attrs += f' mesh="{g.mesh}"' if g.mesh else f' size="{" ".join(map(repr, g.size))}"'
            parts.append(f"<geom {attrs}/>")
        bodies += f'<body name="{link}"><freejoint/>{"".join(parts)}</body>'
    xml = (
        f'<mujoco><compiler meshdir="{assets}"/><asset>{mesh_xml}</asset>'
        f"<worldbody>{bodies}</worldbody></mujoco>"
    )
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d)
    assert m.nmesh == len(out.mesh_assets)
    assert m.ngeom == sum(len(v) for v in out.collision_geoms.values())
    total = sum(m.mesh_vertnum)
    assert total > 0 and np.all(np.isfinite(d.qpos))


def test_collision_elements_keep_their_urdf_names_when_unique(tmp_path):
    from urdf2mjcf.passes import parse, xacro

    urdf = tmp_path / "named.urdf"
    urdf.write_text(
        """<robot name="named">
  <link name="a">
    <collision name="bumper"><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
    <collision name="collision"><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>
  <link name="b"><collision name="collision"><geometry><sphere radius="0.05"/></geometry></collision></link>
</robot>"""
    )
    model = parse.run(xacro.run(urdf, xacro.XacroConfig(use_environment=False)))
    out = collision.run(model, CollisionConfig(use_cache=False))
    assert [g.name for g in out.collision_geoms["a"]] == ["bumper", "a_collision_1"]
    assert [g.name for g in out.collision_geoms["b"]] == ["b_collision"], (
        "a name used twice is not a geom name"
    )
