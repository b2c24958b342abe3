"""Primitive fits against analytic shapes built with trimesh.creation."""

from __future__ import annotations

import math
from dataclasses import astuple

import numpy as np
import pytest
import trimesh
from trimesh.transformations import quaternion_matrix, random_rotation_matrix

from urdf2mjcf.passes.collision import primitives as P
from urdf2mjcf.passes.collision.primitives import Fit

TOL = P.TOLERANCE_MM / 1000.0


def _placed(mesh: trimesh.Trimesh, seed: int) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The mesh under a random rotation and offset, and that 4x4 transform."""
    rng = np.random.default_rng(seed)
    transform = random_rotation_matrix(rng.uniform(size=3))
    transform[:3, 3] = rng.uniform(-0.5, 0.5, size=3)
    return mesh.copy().apply_transform(transform), transform


def _rot(fit: Fit) -> np.ndarray:
    return np.asarray(quaternion_matrix(fit.quat))[:3, :3]


def _single(cands: list[P.Candidate], kind: str) -> P.Candidate:
    return next(c for c in cands if len(c.fits) == 1 and c.fits[0].type == kind)


def _inside(fit: Fit, points: np.ndarray) -> np.ndarray:
    """Signed excess of each point over the primitive, computed here from scratch."""
    p = (points - np.asarray(fit.pos)) @ _rot(fit)
    s = fit.size
    if fit.type == "sphere":
        return np.linalg.norm(p, axis=1) - s[0]
    if fit.type == "capsule":
        z = np.clip(p[:, 2], -s[1], s[1])
        return np.linalg.norm(p - np.column_stack([0 * z, 0 * z, z]), axis=1) - s[0]
    if fit.type == "cylinder":
        return np.maximum(np.linalg.norm(p[:, :2], axis=1) - s[0], np.abs(p[:, 2]) - s[1])
    return (np.abs(p) - np.asarray(s)).max(axis=1)


def _fit_mesh(fit: Fit) -> trimesh.Trimesh:
    """A fine tessellation of the fit, placed, for an independent reference."""
    s = fit.size
    if fit.type == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=5, radius=s[0])
    elif fit.type == "capsule":
        mesh = trimesh.creation.capsule(height=2 * s[1], radius=s[0], count=[128, 128])
    elif fit.type == "cylinder":
        mesh = trimesh.creation.cylinder(radius=s[0], height=2 * s[1], sections=256)
    else:
        mesh = trimesh.creation.box(extents=2 * np.asarray(s))
    transform = np.eye(4)
    transform[:3, :3] = _rot(fit)
    transform[:3, 3] = fit.pos
    return mesh.apply_transform(transform)


def test_capsule_is_fitted_by_a_capsule_and_chosen() -> None:
    r, half = 0.04, 0.12
    mesh, transform = _placed(
        trimesh.creation.capsule(height=2 * half, radius=r, count=[48, 48]), 1
    )
    cands = P.candidates(mesh.vertices, mesh.faces)
    cap = _single(cands, "capsule")
    fit = cap.fits[0]
    assert fit.size[0] == pytest.approx(r, rel=0.01)
    assert fit.size[1] == pytest.approx(half, rel=0.02)
    axis = _rot(fit)[:, 2]
    angle = math.degrees(math.acos(min(1.0, abs(float(axis @ transform[:3, 2])))))
    assert angle < 1.0
    assert np.allclose(fit.pos, transform[:3, 3], atol=1e-3 * r)
    # tessellation error: the polygon's sagitta, r (1 - cos(pi / 48)), a few tenths of a mm
    assert cap.deviation.hausdorff_m < 2 * r * (1 - math.cos(math.pi / 48)) + 1e-6
    assert cap.deviation.uncovered_m == 0.0
    sphere = _single(cands, "sphere")
    assert sphere.deviation.hausdorff_m > 10 * TOL  # the cheaper fit is far off
    chosen = P.choose(cands, TOL, P.MAX_VOLUME_RATIO)
    assert chosen is cap
    # any distance allowed, but not the sphere's volume (6x): still the capsule
    assert P.choose(cands, 1.0, P.MAX_VOLUME_RATIO) is cap
    assert P.choose(cands, 1.0, 100.0) is sphere
    assert P.best(cands) is cap


def test_box_is_fitted_by_the_box() -> None:
    extents = np.array([0.06, 0.1, 0.24])
    mesh, transform = _placed(trimesh.creation.box(extents=extents), 2)
    cands = P.candidates(mesh.vertices, mesh.faces)
    box = _single(cands, "box")
    fit = box.fits[0]
    # each fitted axis is one of the true axes; its half size that axis's half extent
    align = np.abs(_rot(fit).T @ transform[:3, :3])
    match = np.argmax(align, axis=1)
    assert sorted(match) == [0, 1, 2]
    assert np.allclose(align.max(axis=1), 1.0, atol=1e-9)
    assert np.allclose(fit.size, extents[match] / 2, rtol=1e-9)
    assert np.allclose(fit.pos, transform[:3, 3], atol=1e-9)
    assert box.deviation.hausdorff_m < 1e-9
    assert box.deviation.volume_ratio == pytest.approx(1.0, abs=1e-9)
    assert P.choose(cands, TOL, P.MAX_VOLUME_RATIO) is box


def test_sphere_and_cylinder() -> None:
    ball, _ = _placed(trimesh.creation.icosphere(subdivisions=3, radius=0.07), 3)
    chosen = P.choose(P.candidates(ball.vertices, ball.faces), TOL, P.MAX_VOLUME_RATIO)
    assert chosen is not None and [f.type for f in chosen.fits] == ["sphere"]
    assert chosen.fits[0].size[0] == pytest.approx(0.07, rel=1e-6)

    can, transform = _placed(trimesh.creation.cylinder(radius=0.05, height=0.08, sections=64), 4)
    cands = P.candidates(can.vertices, can.faces)
    chosen = P.choose(cands, TOL, P.MAX_VOLUME_RATIO)
    assert chosen is not None and [f.type for f in chosen.fits] == ["cylinder"]
    fit = chosen.fits[0]
    assert fit.size == pytest.approx((0.05, 0.04), rel=1e-6)
    assert abs(float(_rot(fit)[:, 2] @ transform[:3, 2])) == pytest.approx(1.0, abs=1e-6)
    assert _single(cands, "box").deviation.hausdorff_m > TOL  # the box's corners stick out


def _l_shape() -> trimesh.Trimesh:
    a = trimesh.creation.box(extents=[0.3, 0.05, 0.05])
    a.apply_translation([0.125, 0.0, 0.0])
    b = trimesh.creation.box(extents=[0.05, 0.3, 0.05])
    b.apply_translation([0.0, 0.125, 0.0])
    return trimesh.boolean.union([a, b])


def test_l_shape_is_not_one_box() -> None:
    mesh = _l_shape()
    assert mesh.is_watertight
    cands = P.candidates(mesh.vertices, mesh.faces)
    box = _single(cands, "box")
    assert box.deviation.volume_ratio > 3.0  # independent: (0.3 x 0.3) over its L area
    chosen = P.choose(cands, TOL, P.MAX_VOLUME_RATIO)
    assert chosen is None or len(chosen.fits) > 1


def _bent_bar() -> trimesh.Trimesh:
    """Two 0.3 m bars of 30 mm square section, the second turned 40 degrees."""
    first = trimesh.creation.box(extents=[0.3, 0.03, 0.03])
    first.apply_translation([-0.15, 0.0, 0.0])
    second = trimesh.creation.box(extents=[0.3, 0.03, 0.03])
    second.apply_translation([0.15, 0.0, 0.0])
    second.apply_transform(trimesh.transformations.rotation_matrix(math.radians(40), [0, 0, 1]))
    return trimesh.boolean.union([first, second])


def test_bent_bar_gets_a_set() -> None:
    mesh = _bent_bar()
    cands = P.candidates(mesh.vertices, mesh.faces)
    singles = [c for c in cands if len(c.fits) == 1]
    assert min(c.deviation.hausdorff_m for c in singles) > 2 * TOL
    chosen = P.best(cands)
    assert len(chosen.fits) in (2, 3)
    assert chosen.deviation.hausdorff_m <= 0.5 * min(c.deviation.hausdorff_m for c in singles)
    assert chosen.deviation.uncovered_m == 0.0
    # without sets, best gives a single fit
    assert len(P.best(P.candidates(mesh.vertices, mesh.faces, sets=False)).fits) == 1


def test_fits_enclose_the_mesh() -> None:
    rng = np.random.default_rng(5)
    points = rng.normal(size=(300, 3)) * [0.1, 0.03, 0.02]
    mesh = trimesh.convex.convex_hull(points)
    for cand in P.candidates(mesh.vertices, mesh.faces):
        excess = np.min([_inside(f, mesh.vertices) for f in cand.fits], axis=0)
        assert excess.max() <= 1e-9 * np.linalg.norm(np.ptp(mesh.vertices, axis=0))
        assert cand.deviation.uncovered_m == 0.0


def test_deviation_agrees_with_an_independent_measure() -> None:
    can, _ = _placed(trimesh.creation.cylinder(radius=0.05, height=0.2, sections=64), 6)
    cands = P.candidates(can.vertices, can.faces)
    for kind in ("box", "capsule", "sphere"):
        cand = _single(cands, kind)
        ref_surface = _fit_mesh(cand.fits[0])
        pts, _ = trimesh.sample.sample_surface(ref_surface, 6000, seed=7)
        if kind == "box":
            pts = np.vstack([pts, ref_surface.vertices])  # its corners
        _, dist, _ = trimesh.proximity.closest_point(can, pts)
        # ours samples fewer points, but on a grid that holds the corners and rims
        assert cand.deviation.hausdorff_m == pytest.approx(float(dist.max()), rel=0.03, abs=5e-4)
        # volume ratio: the fine tessellation's volume over the mesh's
        assert cand.deviation.volume_ratio == pytest.approx(
            ref_surface.volume / can.volume, rel=0.01
        )
    # a fit shrunk by 20% leaves the mesh uncovered by about that much
    cyl = _single(cands, "cylinder").fits[0]
    small = Fit("cylinder", cyl.pos, cyl.quat, (cyl.size[0] * 0.8, cyl.size[1]))
    dev = P.deviation([small], can.vertices, can.faces)
    assert dev.uncovered_m == pytest.approx(0.2 * cyl.size[0], rel=1e-6)


def test_set_volume_counts_overlap_once() -> None:
    # two unit-radius spheres 1 apart: union = 2 * (4/3 pi) - lens (5/12 pi)
    a = Fit("sphere", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (1.0,))
    b = Fit("sphere", (1.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (1.0,))
    box = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    dev = P.deviation([a, b], box.vertices, box.faces)
    union = 8.0 / 3.0 * math.pi - 5.0 / 12.0 * math.pi
    assert dev.volume_ratio == pytest.approx(union, rel=0.01)


def test_deterministic_and_degenerate() -> None:
    mesh = _bent_bar()
    first = P.candidates(mesh.vertices, mesh.faces)
    assert first and first == P.candidates(mesh.vertices.copy(), mesh.faces.copy())
    assert [c.cost for c in first] == sorted(c.cost for c in first)

    flat = trimesh.creation.box(extents=[0.1, 0.1, 0.0])
    assert P.candidates(flat.vertices, flat.faces) == []
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert P.candidates(tri, np.array([[0, 1, 2]])) == []
    box = trimesh.creation.box()
    bad = box.vertices.copy()
    bad[0, 0] = np.nan
    assert P.candidates(bad, box.faces) == []
    assert P.candidates(np.zeros((8, 3)), box.faces) == []
    assert P.candidates(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)) == []
    assert P.choose([], TOL, P.MAX_VOLUME_RATIO) is None
    fit = P.candidates(box.vertices, box.faces)[0].fits
    assert all(math.isnan(x) for x in astuple(P.deviation(fit, flat.vertices, flat.faces)))
