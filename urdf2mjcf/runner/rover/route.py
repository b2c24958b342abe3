"""A route around obstacles (A* on a grid of the plane, circles inflated by the rover's
half width) and a pure-pursuit task that follows it."""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np

from .odometry import true_pose
from .roles import Rover
from .state import SimState
from .tasks import Task, speed_profile

CELL = 0.1
"""m: the grid's cell."""
MARGIN = 2.0
"""m of grid around the start and the goal."""
TURN_RATE = 1.2
"""rad/s commanded when turning in place (the tyres scrub: the rover turns slower)."""
CLEARANCE = 0.75
"""m added to every obstacle's radius: the rover's half diagonal (0.55 m) and a margin."""


def plan(
    start: Sequence[float] | np.ndarray,
    goal: Sequence[float] | np.ndarray,
    obstacles: Sequence[tuple[float, float, float]],
) -> list[tuple[float, float]]:
    """The shortest 8-connected grid path from ``start`` to ``goal`` (x, y in m) that keeps
    ``CLEARANCE`` from every obstacle (x, y, radius), thinned to its corners; a
    ``ValueError`` if there is none."""
    lo = np.minimum(start, goal) - MARGIN
    hi = np.maximum(start, goal) + MARGIN
    n = np.ceil((hi - lo) / CELL).astype(int) + 1
    xs = lo[0] + CELL * np.arange(n[0])
    ys = lo[1] + CELL * np.arange(n[1])
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    free = np.ones(n, bool)
    for ox, oy, r in obstacles:
        free &= (gx - ox) ** 2 + (gy - oy) ** 2 > (r + CLEARANCE) ** 2

    def cell(p: Sequence[float] | np.ndarray) -> tuple[int, int]:
        return (
            int(np.clip(round((p[0] - lo[0]) / CELL), 0, n[0] - 1)),
            int(np.clip(round((p[1] - lo[1]) / CELL), 0, n[1] - 1)),
        )

    a, b = cell(start), cell(goal)
    if not free[a] or not free[b]:
        raise ValueError("the start or the goal is too close to an obstacle")
    came: dict[tuple[int, int], tuple[int, int]] = {}
    cost = {a: 0.0}
    todo = [(0.0, a)]
    steps = [(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1) if i or j]
    while todo:
        _, c = heapq.heappop(todo)
        if c == b:
            break
        for i, j in steps:
            nb = (c[0] + i, c[1] + j)
            if not (0 <= nb[0] < n[0] and 0 <= nb[1] < n[1]) or not free[nb]:
                continue
            new = cost[c] + math.hypot(i, j)
            if new < cost.get(nb, math.inf):
                cost[nb], came[nb] = new, c
                heapq.heappush(todo, (new + math.hypot(nb[0] - b[0], nb[1] - b[1]), nb))
    if b not in cost:
        raise ValueError("no way around the obstacles")
    cells = [b]
    while cells[-1] != a:
        cells.append(came[cells[-1]])
    cells.reverse()
    # keep the corners: where the step direction changes
    keep = [cells[0]]
    for prev, c, nxt in zip(cells[:-2], cells[1:-1], cells[2:], strict=True):
        if (c[0] - prev[0], c[1] - prev[1]) != (nxt[0] - c[0], nxt[1] - c[1]):
            keep.append(c)
    keep.append(cells[-1])
    out = [(float(xs[i]), float(ys[j])) for i, j in keep]
    out[0], out[-1] = (float(start[0]), float(start[1])), (float(goal[0]), float(goal[1]))
    return out


def length(path: Sequence[Sequence[float]] | np.ndarray) -> float:
    p = np.asarray(path, float)
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


class Pursue(Task):
    """Follow ``path`` (x, y) by pure pursuit on the base's pose (a localised rover: the
    odometry's drift through wheel slip is what ``drift`` measures): steer towards
    the point ``lookahead`` m ahead on the path, turn in place where it lies more than
    60 deg off, slow down to stop within ``tolerance`` of the last point."""

    def __init__(
        self,
        path: Sequence[tuple[float, float]],
        speed: float = 0.5,
        lookahead: float = 0.6,
        tolerance: float = 0.05,
    ):
        self.path = np.asarray(path, float)
        self.speed, self.lookahead, self.tolerance = speed, lookahead, tolerance
        self.done = False

    def start(self, sim: SimState, rover: Rover) -> None:
        self.done, self._stopping, self._t0 = False, False, float(sim.d.time)
        self._seg = 0

    def _target(self, p: np.ndarray) -> tuple[np.ndarray, float]:
        """The lookahead point and the path left from the rover's projection."""
        path = self.path
        best, best_d, best_s = self._seg, math.inf, 0.0
        for i in range(self._seg, min(self._seg + 3, len(path) - 1)):
            a, b = path[i], path[i + 1]
            ab = b - a
            s = float(np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-12), 0.0, 1.0))
            dist = float(np.linalg.norm(a + s * ab - p))
            if dist < best_d:
                best, best_d, best_s = i, dist, s
        self._seg = best
        left = self.lookahead
        a, b = path[best], path[best + 1]
        point = a + best_s * (b - a)
        remaining = float(np.linalg.norm(b - point)) + length(path[best + 1 :])
        for i in range(best, len(path) - 1):
            seg_end = path[i + 1]
            step = float(np.linalg.norm(seg_end - point))
            if step >= left:
                return point + (seg_end - point) * (left / step), remaining
            left -= step
            point = seg_end
        return path[-1].copy(), remaining

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        pose = true_pose(sim.m, sim.d, rover)
        p = np.array([pose.x, pose.y])
        to_goal = float(np.linalg.norm(self.path[-1] - p))
        target, remaining = self._target(p)
        d = target - p
        alpha = math.atan2(d[1], d[0]) - pose.yaw
        alpha = (alpha + math.pi) % (2 * math.pi) - math.pi
        # there, or close and past it (never turn round for the last centimetres)
        past = to_goal <= 3 * self.tolerance and abs(alpha) > math.pi / 2
        if to_goal <= self.tolerance or past or self._stopping:
            self._stopping = True
            self.done = sim.wheel_speed(rover) < 0.01
            return None, 0.0
        remaining = max(remaining, to_goal)
        if abs(alpha) > math.radians(60):  # turn in place towards the path first
            return 0.0, math.copysign(TURN_RATE, alpha)
        v = speed_profile(remaining, float(sim.d.time) - self._t0, self.speed, 0.4)
        v = max(v, 0.03)
        dist = max(float(np.linalg.norm(d)), 1e-6)
        return v, 2 * v * math.sin(alpha) / dist
