"""Generate the visual meshes of the EXPRESS rack and the MERLIN freezer mockups.

    python meshes/express_rack/make_express_rack.py [--out DIR]     (default: this folder)

Constructive solid geometry with manifold3d from the dimensions below, which
are those of facility/mockups/express_rack/urdf/express_rack.xacro and
merlin_freezer.xacro (tests/facility/test_express_rack.py checks that the
meshes, the collision primitives and the masses agree). Every mesh is in the
frame of the link that shows it:

* express_rack.stl - rack frame: origin on the floor below the centre of the
                     front face, z up, +x out of the front, y across
* merlin_body.stl  - freezer frame: origin at the centre of the front face,
                     z up, +x out of the front (the door side)
* merlin_door.stl  - freezer door frame: on the hinge axis (vertical) at the
                     door's mid-height; the door extends along +y

Output is deterministic: binary STL, zeroed header, manifold3d's own vertex
and triangle order (urdf2mjcf.assets.stl_bytes).
"""

from __future__ import annotations

import sys
from pathlib import Path

from manifold3d import Manifold, OpType

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # meshes/csg.py
from csg import box, cylinder_z, write_meshes  # noqa: E402

SEGMENTS = 48

# --- EXPRESS rack (rack frame, metres) --------------------------------------
RACK_X = (-0.86, 0.0)  # 0.86 deep, the front at x = 0
RACK_Y = (-0.525, 0.525)  # 1.05 wide
RACK_Z = (0.0, 2.0)  # 2.0 tall
BAY_X = (-0.85, 0.0)  # every bay is open at the front, 10 mm back panel
LOCKER_COLUMNS = ((-0.451, -0.007), (0.007, 0.451))  # 0.444 wide: a mid-deck locker + 2 mm a side
LOCKER_ROWS = ((0.654, 0.920), (0.934, 1.200), (1.214, 1.480), (1.494, 1.760))  # 0.266 tall
DRAWER_BAY = ((-0.451, 0.451), (0.020, 0.640))  # (y, z): the lower, full-width bay
TOP_BAY = ((-0.451, 0.451), (1.774, 1.980))  # (y, z): the upper, full-width bay
POST_VOIDS = ((-0.515, -0.461), (0.461, 0.515))  # the side posts are 10 mm walled tubes
POST_VOID_X = (-0.85, -0.01)
POST_VOID_Z = (0.010, 1.990)

# --- MERLIN freezer (freezer frame) ------------------------------------------
BODY_X = (-0.52, 0.0)  # 0.52 deep
BODY_Y = (-0.22, 0.22)  # 0.44 wide
BODY_Z = (-0.13, 0.13)  # 0.26 tall
BODY_WALL = 0.005  # aluminium shell
# door (door frame: on the hinge axis at (0.010, -0.212, 0) in the freezer frame)
DOOR_X = (0.002, 0.020)
DOOR_Y = (0.004, 0.414)
DOOR_Z = (-0.115, 0.115)
DOOR_KNUCKLE_R = 0.006
DOOR_KNUCKLES = ((0.07, 0.11), (-0.11, -0.07))
DOOR_LABEL = ((0.06, 0.26), (-0.06, 0.06), 0.002)  # (y, z, depth): a recessed label panel


def express_rack() -> Manifold:
    cut_x = (BAY_X[0], BAY_X[1] + 0.01)  # through the front face
    cuts = [box(cut_x, y, z) for z in LOCKER_ROWS for y in LOCKER_COLUMNS]
    cuts.append(box(cut_x, *DRAWER_BAY))
    cuts.append(box(cut_x, *TOP_BAY))
    cuts += [box(POST_VOID_X, y, POST_VOID_Z) for y in POST_VOIDS]
    return box(RACK_X, RACK_Y, RACK_Z) - Manifold.batch_boolean(cuts, OpType.Add)


def merlin_body() -> Manifold:
    w = BODY_WALL
    inner = box(
        (BODY_X[0] + w, BODY_X[1] - w),
        (BODY_Y[0] + w, BODY_Y[1] - w),
        (BODY_Z[0] + w, BODY_Z[1] - w),
    )
    return box(BODY_X, BODY_Y, BODY_Z) - inner


def merlin_door() -> Manifold:
    (ly, lz, depth) = DOOR_LABEL
    plate = box(DOOR_X, DOOR_Y, DOOR_Z) - box((DOOR_X[1] - depth, DOOR_X[1] + 0.01), ly, lz)
    knuckles = [cylinder_z(DOOR_KNUCKLE_R, z, segments=SEGMENTS) for z in DOOR_KNUCKLES]
    return Manifold.batch_boolean([plate, *knuckles], OpType.Add)


MESHES = {
    "express_rack.stl": express_rack,
    "merlin_body.stl": merlin_body,
    "merlin_door.stl": merlin_door,
}


def main(argv: list[str] | None = None) -> None:
    write_meshes(MESHES, Path(__file__).resolve().parent, argv, __doc__)


if __name__ == "__main__":
    main()
