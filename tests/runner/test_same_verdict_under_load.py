"""Same seed, same verdict, however busy the machine: the published demo's seeded trials,
a rover's task plan, the deliver task and both Gymnasium environments, each run once
as the suite finds the machine and once with every core kept busy by spinning
processes (twice as many as cores), give the same verdicts and bit-identical final
states. Nothing that decides a run may read a clock: the planner stops on iteration
budgets (``runner/plan.py``), everything else on simulated time."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import urdf2mjcf.envs  # noqa: F401  (registers the ids)
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.demo import Demo, load_waypoints
from urdf2mjcf.runner.load import load
from urdf2mjcf.runner.rover import RoverSim
from urdf2mjcf.runner.rover.deliver import run_deliver
from urdf2mjcf.runner.rover.plan_file import check_plan, read_plan
from urdf2mjcf.runner.rover.tasks import DRIVES

ROOT = Path(__file__).resolve().parents[2]
WAYPOINTS = ROOT / "recipes" / "demo" / "imetro.yaml"
SPIN = "import os, sys\nos.write(1, b'x')\nwhile True: pass\n"

pytestmark = pytest.mark.slow


@contextmanager
def every_core_busy() -> Iterator[int]:
    """Twice as many spinning processes as this process may run on, for the block."""
    n = 2 * len(os.sched_getaffinity(0))
    spinners = [
        subprocess.Popen([sys.executable, "-c", SPIN], stdout=subprocess.PIPE) for _ in range(n)
    ]
    try:
        for p in spinners:  # each has started spinning before the run does
            assert p.stdout is not None and p.stdout.read(1) == b"x"
        yield n
    finally:
        for p in spinners:
            p.kill()
        for p in spinners:
            p.wait()
            if p.stdout is not None:
                p.stdout.close()


def quiet_and_busy(run: Callable[[], Any]) -> tuple[Any, Any]:
    """``run()`` as the machine is, then with every core busy."""
    quiet = run()
    with every_core_busy():
        busy = run()
    return quiet, busy


def _state(m: mujoco.MjModel, d: mujoco.MjData) -> bytes:
    """The full physics state (time, qpos, qvel, act, warm start, ...) as bytes."""
    sig = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.empty(mujoco.mj_stateSize(m, sig))
    mujoco.mj_getState(m, d, out, sig)
    return out.tobytes()


def _decided(result: dict) -> dict:
    """A demo result without its wall-clock figures (the only things a load may change)."""

    def step(s: dict) -> dict:
        plan = {k: v for k, v in (s.get("plan") or {}).items() if k != "planning_time_s"}
        return {**s, "plan": plan}

    out = {k: v for k, v in result.items() if k not in ("wall_time", "real_time_factor")}
    out["steps"] = [step(s) for s in result["steps"]]
    return out


@pytest.fixture(scope="module")
def seeded_facilities(tmp_path_factory) -> dict[int, Path]:
    """The default facility built with the trials' jitter for seeds 0 and 1."""
    out = {}
    for seed in (0, 1):
        folder = tmp_path_factory.mktemp(f"seed{seed}") / "imetro"
        recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
        build_facility(recipe, folder, root=ROOT, seed=seed, components=False, workers=1)
        out[seed] = folder
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_a_demo_trial_decides_the_same_with_every_core_busy(seeded_facilities, seed):
    def run() -> tuple[dict, bytes]:
        fac = load(seeded_facilities[seed])
        demo = Demo(fac, load_waypoints(WAYPOINTS), log=lambda *_: None)
        try:
            res = demo.run()
            return _decided(res.to_json()), _state(demo.m, demo.d)
        finally:
            demo.close()

    (quiet, quiet_state), (busy, busy_state) = quiet_and_busy(run)
    assert quiet["ok"], quiet["message"]
    planned = [s["plan"] for s in quiet["steps"] if (s["plan"] or {}).get("planner") == "RRTstar"]
    assert planned and all(p["iterations"] > 0 for p in planned), "a move was planned by RRT*"
    assert busy == quiet
    assert busy_state == quiet_state


@pytest.fixture(scope="module")
def floor(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


def test_a_rover_plan_ends_in_the_same_state_with_every_core_busy(floor, tmp_path):
    path = tmp_path / "plan.yaml"
    path.write_text(
        "tasks:\n"
        "  - {kind: straight, distance: 0.6, speed: 0.5}\n"
        "  - {kind: turn, angle_deg: 30}\n"
        "  - {kind: hold, duration: 0.2}\n"
        "arm: {kind: arm_wave, joint: 0, amplitude: 0.3, period: 2.0}\n"
    )

    def run() -> bytes:
        plan = read_plan(path)
        sim = RoverSim(floor)
        chosen = check_plan(plan, sim.rovers)
        sim.settle(0.3)
        for spec in plan.tasks:
            DRIVES[spec["kind"]].run(sim, spec, chosen, plan.arm)
        return _state(sim.m, sim.d)

    quiet, busy = quiet_and_busy(run)
    assert busy == quiet


def test_the_deliver_task_decides_the_same_with_every_core_busy(shipped_bundle):
    bundle = shipped_bundle("mira3d-pair-floor")

    def run() -> tuple[dict, bytes]:
        sim = RoverSim(bundle)
        res, _ = run_deliver(sim, seed=3, log=lambda _: None)
        return res.task_json(), _state(sim.m, sim.d)

    (quiet, quiet_state), (busy, busy_state) = quiet_and_busy(run)
    assert quiet["success"] is True
    assert busy == quiet
    assert busy_state == quiet_state


@pytest.mark.parametrize("env_id", ["IMetro-v0", "Mira3D-v0"])
def test_an_environment_rollout_is_the_same_with_every_core_busy(env_id, _session_cache):
    def flat(obs: dict) -> bytes:
        return b"".join(np.asarray(obs[k]).tobytes() for k in sorted(obs))

    def run() -> list[bytes]:
        env = gym.make(env_id)
        try:
            obs, _ = env.reset(seed=7)
            env.action_space.seed(7)
            seen = [flat(obs)]
            for _ in range(100):
                obs, reward, term, trunc, _ = env.step(env.action_space.sample())
                seen.append(flat(obs) + np.float64(reward).tobytes())
                if term or trunc:
                    obs, _ = env.reset(seed=8)
                    seen.append(flat(obs))
            return seen
        finally:
            env.close()

    quiet, busy = quiet_and_busy(run)
    assert busy == quiet
