"""A run published to ROS 2 while it runs (``facility-demo --ros2``, ``rover-drive
--ros2``): the recording's messages (:class:`..runner.record.Recorder` builds each once
and hands it to every sink) on their topics over rmw_zenoh, as ``--record`` writes them
and ``--foxglove`` streams them, with ``/clock`` (simulated time) beside them and,
for a rover run, each rover's wheel odometry on ``/<rover>/odom``.

The stream only reads: the run does what it does without it. It paces the run
(``pace`` simulated seconds per wall-clock second, ``--pace``) so that one watches it
as it happens. A topic's message is
encoded only while a subscriber matches it (a camera nobody watches is not rendered).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from .server import ros_time
from .session import Endpoints, Node, Publisher

CLOCK = 10_000_000
"""ns of simulated time between two /clock messages (100 Hz)."""


class Ros2Stream:
    """A ROS 2 node named ``name`` publishing a run of ``data`` (its MjData): a sink of
    the recorder; call :meth:`step` after every physics step and :meth:`close` when the
    run ends. ``extra``: called at every /clock tick with the node (the rover's
    odometry)."""

    def __init__(
        self,
        data: Any,
        endpoints: Endpoints,
        domain: int,
        name: str,
        extra: Callable[[Node], None] | None = None,
        pace: float = 1.0,
    ) -> None:
        from . import keyexpr

        self.d = data
        self.where = f"domain {domain}, rmw_zenoh; " + ", ".join(
            [*(f"listening on {e}" for e in endpoints.listen)]
            + [f"connecting to {e}" for e in endpoints.connect]
        )
        self.node = Node(endpoints, domain, name)
        self._clock = self.node.publisher("/clock", "rosgraph_msgs/msg/Clock", keyexpr.CLOCK)
        self._publishers: dict[str, Publisher] = {}
        self._extra = extra
        self._time: int | None = None
        self.pace = pace
        self._start: tuple[float, float] | None = None
        self.sent = 0

    def __call__(self, topic: str, datatype: str, msg: dict, ns: int) -> None:
        pub = self._publishers.get(topic)
        if pub is None:
            pub = self._publishers[topic] = self.node.publisher(topic, datatype)
        pub.publish(msg)
        self.sent += 1

    def wants(self, prefix: str) -> bool:
        """Whether a subscriber matches a topic under ``prefix`` (one not yet declared:
        yes, its first message declares it)."""
        under = [p for t, p in self._publishers.items() if t.startswith(prefix)]
        return not under or any(p.matched for p in under)

    def step(self) -> None:
        """After a physics step: /clock (every ``CLOCK`` of simulated time) and the
        extra; keep to the pace."""
        t = float(self.d.time)
        if self._start is None:
            self._start = (t, time.perf_counter())
        ahead = (t - self._start[0]) / self.pace - (time.perf_counter() - self._start[1])
        if ahead > 0:
            time.sleep(ahead)
        ns = int(round(t * 1e9))
        if self._time is not None and ns - self._time < CLOCK:
            return
        self._time = ns
        self._clock.publish({"clock": ros_time(t)})
        if self._extra is not None:
            self._extra(self.node)

    def close(self) -> None:
        self.node.close()
