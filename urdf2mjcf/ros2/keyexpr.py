"""rmw_zenoh's names: data key expressions and the compact QoS of liveliness tokens.

Data of a topic or a service travels on ``<domain>/<fully qualified name>/<DDS type
name>/<type hash>`` (ros2/rmw_zenoh ``docs/design.md``), e.g.
``0/chatter/std_msgs::msg::dds_::String_/RIHS01_df66...``: two peers meet only
when their domain, name, type and type definition all agree.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .type_hash import type_hash

# rmw's enums (rmw/types.h)
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2

_NAME = re.compile(r"^/[A-Za-z0-9_~{}]+(?:/[A-Za-z0-9_{}]+)*$")


@dataclass(frozen=True)
class QoS:
    """The QoS policies an endpoint announces (deadline, lifespan and liveliness are
    rmw_zenoh's defaults: infinite, automatic)."""

    depth: int = 10
    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST

    def keyexpr(self) -> str:
        """rmw_zenoh's ``qos_to_keyexpr``: each policy written only where it differs
        from rmw_zenoh's default (reliable, volatile, keep last, depth 42)."""

        def differ(value: int, default: int) -> str:
            return "" if value == default else str(value)

        return (
            f"{differ(self.reliability, RELIABLE)}:{differ(self.durability, VOLATILE)}:"
            f"{differ(self.history, KEEP_LAST)},{differ(self.depth, 42)}:,:,:,,"
        )


DEFAULT = QoS()
"""rclcpp's default for publishers, subscriptions and services: reliable, volatile, 10."""
LATCHED = QoS(depth=1, durability=TRANSIENT_LOCAL)
"""``/tf_static``'s and a latched topic's: transient local, depth 1."""
CLOCK = QoS(depth=1, reliability=BEST_EFFORT)
"""rclcpp's ClockQoS."""
TF = QoS(depth=100)
"""tf2_ros's DynamicBroadcasterQoS."""


def dds_type_name(type_name: str) -> str:
    """``std_msgs/msg/String`` -> ``std_msgs::msg::dds_::String_`` (the name a CDR
    type has in DDS, which rmw_zenoh keeps)."""
    pkg, kind, name = type_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def check_name(name: str) -> str:
    """A fully qualified topic or service name (``/a/b``), else ValueError."""
    if not _NAME.match(name) or "//" in name:
        raise ValueError(f"'{name}' is not a fully qualified ROS name (like /a/b_c)")
    return name


def data_keyexpr(domain: int, name: str, type_name: str) -> str:
    """Where ``name``'s samples (or a service's queries) travel in ``domain``."""
    check_name(name)
    return f"{domain}/{name[1:]}/{dds_type_name(type_name)}/{type_hash(type_name)}"


def mangle(name: str) -> str:
    """A name as a single key-expression chunk: every ``/`` becomes ``%``."""
    return name.replace("/", "%")
