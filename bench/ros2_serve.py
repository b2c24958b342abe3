"""Benchmark: ``urdf2mjcf serve --ros2``'s loop on one core (issue 32).

    taskset -c 0 python bench/ros2_serve.py MODEL.xml [--rate 500] [--seconds 10]

Serves MODEL on a Zenoh session listening on a free loopback port, paced at real
time, for ``--seconds`` of wall time, then unpaced (as fast as it steps), and prints
physics steps per second, the /joint_states rate, the real-time factor and the CPU
time it took. The physics timestep is the model's (1 kHz: ``<option
timestep="0.001"/>``).
"""

from __future__ import annotations

import argparse
import threading
import time

from urdf2mjcf.mjcf_input import load_model
from urdf2mjcf.ros2.server import ServeConfig, Server
from urdf2mjcf.ros2.session import Endpoints, Node


def run(path: str, rate: float, pace: float, seconds: float) -> str:
    m = load_model(path)
    server = Server(m, ServeConfig(Endpoints(listen=("tcp/127.0.0.1:0",)), rate=rate, pace=pace))
    node = Node(server.config.endpoints, 0, "bench")
    try:
        server.open(node)
        threading.Timer(seconds, server.stop.set).start()
        wall, cpu = time.perf_counter(), time.process_time()
        server.run()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    finally:
        node.close()
    return (
        f"pace {pace:g}: {server.steps / wall:.0f} steps/s (timestep {m.opt.timestep * 1e3:g} ms), "
        f"/joint_states {server.published / wall:.0f} Hz, real-time factor "
        f"{server.d.time / wall:.3f}, CPU {100 * cpu / wall:.0f}% of a core"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--rate", type=float, default=500.0)
    p.add_argument("--seconds", type=float, default=10.0)
    a = p.parse_args()
    print(run(a.model, a.rate, 1.0, a.seconds))
    print(run(a.model, a.rate, 1e6, a.seconds / 2))


if __name__ == "__main__":
    main()
