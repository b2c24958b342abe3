"""What a path serves: a model file with its IMUs and force-torque sensors, or a
facility bundle, with its rovers if it has any (each rover's IMU on its own topic)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import ForgeError
from .scans import Scans
from .sensors import Sensors
from .server import Extension, ServeConfig, Server


def build(path: Path, config: ServeConfig, error: type[ForgeError]) -> Server:
    """The server of ``path``: a model file (robot.xml, scene.xml), or a facility bundle
    (its folder, or its scene.xml beside facility.json) with its rovers, if any. Read as
    a stranger's files; ``error`` (a ConversionError) names what is refused."""
    from ..mjcf_input import load_model

    if not (path.is_dir() or (path.parent / "facility.json").is_file()):
        m = load_model(path, error=error, what="model")
        return Server(m, config, extensions=(Sensors(m), Scans(m), *_cameras(m, config)))
    from ..runner.load import open_facility
    from ..runner.rover.roles import find_rovers

    _, _, manifest, m, d = open_facility(path)
    if not find_rovers(m, manifest):
        return Server(m, config, d, extensions=(Sensors(m), Scans(m), *_cameras(m, config)))
    from ..runner.rover.sim import RoverSim
    from .rovers import Rovers

    sim = RoverSim(path)
    return Server(
        sim.m,
        config,
        sim.d,
        step=lambda: sim.step(1),
        extensions=(Rovers(sim), *_cameras(sim.m, config)),
    )


def _cameras(m: Any, config: ServeConfig) -> tuple[Extension, ...]:
    if config.camera_rate <= 0 or m.ncam == 0:
        return ()
    from .cameras import Cameras

    return (Cameras(m, config.camera_rate),)
