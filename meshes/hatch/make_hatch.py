"""Generate the visual meshes of the pressurized hatch mockup (hatch 4060 / 4040).

    python meshes/hatch/make_hatch.py [--out DIR]     (default: this folder)

Constructive solid geometry with manifold3d from the dimensions below, which
are those of facility/mockups/hatch/urdf/hatch.xacro (tests/facility/test_hatch.py
checks that the meshes and the collision primitives agree). Every mesh is in
the frame of the link that shows it:

* hatch_frame.stl  - hatch frame: origin on the floor at the back of the stand,
                     z up, the door side of the bulkhead faces +x
* hatch_door.stl   - door frame: on the hinge axis, at the door's mid-height
* crank_wheel.stl  - crank (pressurization) wheel frame: on the door surface,
                     z along the wheel axis, pointing away from the door

Output is deterministic: binary STL, zeroed header, manifold3d's own vertex
and triangle order (urdf2mjcf.assets.stl_bytes).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from manifold3d import Manifold, OpType

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # meshes/csg.py
from csg import box, cylinder_x, cylinder_y, cylinder_z, write_meshes  # noqa: E402

# --- hatch frame (hatch frame coordinates, metres) -------------------------
WALL_X = (0.61, 0.66)  # bulkhead slab; its front face (x = 0.66) faces the door
WALL_Y = (-1.113, 0.197)  # 1.31 wide
WALL_Z = (0.0, 2.11)  # 2.11 tall
OPEN_Y = (-0.908, -0.008)  # door opening, 0.90 wide
OPEN_Z = (0.216, 1.216)  # 1.00 tall, sill 0.216 above the floor
FOOT_X = (0.0, 0.68)  # the stand's two feet: 0.68 deep
FOOT_W = 0.08
FOOT_H = 0.06
BRACE = 0.04  # square section of the diagonal braces
BRACE_FROM = (0.06, FOOT_H)  # (x, z) on the foot
BRACE_TO = (WALL_X[0], 0.95)  # (x, z) on the back of the bulkhead
HINGE = (0.678, 0.057, 0.716)  # door hinge axis (vertical) in the hatch frame
KNUCKLE_R = 0.014
FRAME_KNUCKLES = ((0.555, 0.62), (-0.62, -0.555))  # z about the hinge, above and below the door
KEEPER_Z = (0.680, 0.752)  # latch keeper on the bulkhead's front face
KEEPER_STOP = ((WALL_X[1], 0.747), (-1.010, -1.000))  # (x, y) ranges
KEEPER_LIP = ((0.737, 0.747), (-1.010, -0.961))

# --- door (door frame: on the hinge axis, z up, the door extends along -y) --
DOOR_X = (0.006, 0.036)  # 30 mm plate, in front of the hinge axis
DOOR_Y = (-1.012, -0.012)  # 1.00 wide
DOOR_Z = (-0.55, 0.55)  # 1.10 tall
DOOR_KNUCKLES = ((0.40, 0.55), (-0.55, -0.40))
WINDOW = (-0.512, 0.33, 0.08, 0.095)  # (y, z, pane radius, ring radius)
WINDOW_RECESS = 0.010  # the pane sits 10 mm below the outer face
WINDOW_RING = 0.010  # the ring stands 10 mm proud of the outer face

# --- crank wheel (wheel frame: z along the axle, away from the door) -------
WHEEL_R = (0.09, 0.11)  # rim inner and outer radius
WHEEL_Z = (0.03, 0.05)  # rim, spokes and hub
HUB_R = 0.025
SPOKE_W = 0.015
AXLE_R = 0.012  # axle from the door surface (z = 0) to the hub
HANDLE_PIVOT = (0.085, 0.0, 0.062)  # the fold-out handle's pivot (axis along y)


def brace(y_centre: float) -> Manifold:
    (x0, z0), (x1, z1) = BRACE_FROM, BRACE_TO
    length = math.hypot(x1 - x0, z1 - z0)
    pitch = -math.degrees(math.atan2(z1 - z0, x1 - x0))  # about y: x axis onto the brace
    bar = Manifold.cube((length, BRACE, BRACE), center=True).rotate((0.0, pitch, 0.0))
    return bar.translate(((x0 + x1) / 2, y_centre, (z0 + z1) / 2))


def hatch_frame() -> Manifold:
    wall = box(WALL_X, WALL_Y, WALL_Z) - box((WALL_X[0] - 0.01, WALL_X[1] + 0.01), OPEN_Y, OPEN_Z)
    feet_y = ((WALL_Y[0], WALL_Y[0] + FOOT_W), (WALL_Y[1] - FOOT_W, WALL_Y[1]))
    parts = [wall]
    for fy in feet_y:
        parts.append(box(FOOT_X, fy, (0.0, FOOT_H)))
        parts.append(brace((fy[0] + fy[1]) / 2))
    hx, hy, hz = HINGE
    for z0, z1 in FRAME_KNUCKLES:
        z = (hz + z0, hz + z1)
        parts.append(cylinder_z(KNUCKLE_R, z, (hx, hy)))
        parts.append(box((WALL_X[1] - 0.001, hx), (hy, hy + 0.06), z))  # leaf onto the bulkhead
    parts.append(box(KEEPER_STOP[0], KEEPER_STOP[1], KEEPER_Z))
    parts.append(box(KEEPER_LIP[0], KEEPER_LIP[1], KEEPER_Z))
    return Manifold.batch_boolean(parts, OpType.Add)


def hatch_door() -> Manifold:
    wy, wz, pane_r, ring_r = WINDOW
    plate = box(DOOR_X, DOOR_Y, DOOR_Z)
    recess = cylinder_x(pane_r, (DOOR_X[1] - WINDOW_RECESS, DOOR_X[1] + 0.01), (wy, wz))
    ring = cylinder_x(ring_r, (DOOR_X[1] - 0.001, DOOR_X[1] + WINDOW_RING), (wy, wz)) - cylinder_x(
        pane_r, (DOOR_X[1] - 0.002, DOOR_X[1] + WINDOW_RING + 0.01), (wy, wz)
    )
    parts = [plate - recess, ring]
    for z in DOOR_KNUCKLES:
        parts.append(cylinder_z(KNUCKLE_R, z))
    return Manifold.batch_boolean(parts, OpType.Add)


def crank_wheel() -> Manifold:
    rim = cylinder_z(WHEEL_R[1], WHEEL_Z) - cylinder_z(
        WHEEL_R[0], (WHEEL_Z[0] - 0.01, WHEEL_Z[1] + 0.01)
    )
    reach = (WHEEL_R[0] + WHEEL_R[1]) / 2
    spokes = [
        box((-reach, reach), (-SPOKE_W / 2, SPOKE_W / 2), WHEEL_Z),
        box((-SPOKE_W / 2, SPOKE_W / 2), (-reach, reach), WHEEL_Z),
    ]
    hub = cylinder_z(HUB_R, WHEEL_Z)
    axle = cylinder_z(AXLE_R, (0.0, WHEEL_Z[0] + 0.001))
    px, _, pz = HANDLE_PIVOT
    boss = cylinder_y(0.006, (-0.014, 0.014), (px, pz)) + box(
        (px - 0.006, px + 0.006), (-0.014, 0.014), (WHEEL_Z[1] - 0.001, pz)
    )
    return Manifold.batch_boolean([rim, *spokes, hub, axle, boss], OpType.Add)


MESHES = {
    "hatch_frame.stl": hatch_frame,
    "hatch_door.stl": hatch_door,
    "crank_wheel.stl": crank_wheel,
}


def main(argv: list[str] | None = None) -> None:
    write_meshes(MESHES, Path(__file__).resolve().parent, argv, __doc__)


if __name__ == "__main__":
    main()
