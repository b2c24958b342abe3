"""Gymnasium environments of our facilities (see docs/envs.md).

``import urdf2mjcf.envs`` registers:

* ``IMetro-v0``: the iMETRO facility (``urdf2mjcf.envs.imetro``);
* ``Mira3D-v0``: the MIRA3D rover on the institute floor (``urdf2mjcf.envs.mira3d``).

Each builds its facility once (make-facility's Python API, into the shared cache
folder) and randomizes the loaded model on reset. Gymnasium is the optional extra
``gym``: ``pip install 'mjcf-forge[gym]'``.
"""

from __future__ import annotations

from .. import headless

headless.configure()  # before mujoco is first imported: its GL backend is fixed then

try:
    import gymnasium
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        "urdf2mjcf.envs needs gymnasium: pip install 'mjcf-forge[gym]'"
    ) from exc

MAX_EPISODE_STEPS = 500
"""Truncation: 500 control steps, 20 s at the default 25 Hz."""

ENVIRONMENTS = {
    "IMetro-v0": "urdf2mjcf.envs.imetro:IMetroEnv",
    "Mira3D-v0": "urdf2mjcf.envs.mira3d:Mira3DEnv",
}

for _id, _entry in ENVIRONMENTS.items():
    if _id not in gymnasium.registry:  # importing twice (reload) must not warn
        gymnasium.register(id=_id, entry_point=_entry, max_episode_steps=MAX_EPISODE_STEPS)

__all__ = ["ENVIRONMENTS", "MAX_EPISODE_STEPS"]
