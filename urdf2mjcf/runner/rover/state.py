"""What tasks and reports read of a running simulation (:class:`SimState`).

``RoverSim`` is one: it steps the physics, runs the tasks and takes the reports, so
``sim`` imports ``tasks`` and ``report`` and neither of them imports ``sim``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import mujoco
    import numpy as np

    from .odometry import Odometry
    from .roles import Rover


class SimState(Protocol):
    """A facility with rovers, as it stands after a step."""

    @property
    def m(self) -> mujoco.MjModel: ...

    @property
    def d(self) -> mujoco.MjData: ...

    @property
    def odometry(self) -> Mapping[str, Odometry]:
        """Each rover's dead reckoning, integrated after every step."""
        ...

    @property
    def arm_targets(self) -> Mapping[str, np.ndarray]:
        """Each rover's commanded arm joint positions (rad)."""
        ...

    def wheel_speed(self, rover: Rover) -> float:
        """Largest wheel speed of ``rover`` (rad/s)."""
        ...
