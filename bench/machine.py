"""The machine a benchmark ran on, as every benchmark reports it: CPU, cores, load,
Python and MuJoCo (a shared 2-core machine is noisy: the load says how much)."""

from __future__ import annotations

import os
import platform
import re
from pathlib import Path


def describe() -> dict[str, str]:
    import mujoco

    cpu = platform.processor() or platform.machine()
    try:
        names = re.findall(r"model name\s*:\s*(.+)", Path("/proc/cpuinfo").read_text())
        cpu = names[0].strip() if names else cpu
    except OSError:
        pass
    return {
        "platform": platform.platform(),
        "cpu": cpu,
        "cores": str(os.cpu_count()),
        "load": f"{os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else "-",
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
    }


def line(m: dict[str, str] | None = None) -> str:
    """One line for a table: ``AMD EPYC, 2 CPUs, load 0.9, Python 3.11.7, MuJoCo 4.0.0``."""
    m = m or describe()
    return (
        f"{m['cpu']}, {m['cores']} CPUs, load {m['load']}, Python {m['python']}, "
        f"MuJoCo {m['mujoco']}"
    )
