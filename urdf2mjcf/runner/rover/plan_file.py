"""A rover task plan (``rover-drive BUNDLE --plan FILE``), checked before anything moves.

A plan is a YAML mapping::

    rovers: [collector]            # optional: the rovers that run it; default every rover
    tasks:                         # one after the other, every rover at once
      - {kind: straight, distance: 1.0, speed: 0.4}
      - {kind: turn, angle_deg: 90}
      - {kind: hold, duration: 0.5}
    arm: {kind: arm_wave, joint: 0, amplitude: 0.3}   # optional: during every task

:func:`read_plan` checks the file's shape (known keys and kinds, types, ranges,
required keys, at most ``TASKS_MAX`` tasks; the kinds' schemas are
:data:`.tasks.TASKS`); :func:`check_plan` checks it against the bundle's rovers (the
names, each arm joint index). Each error names the file and the element
(``tasks[2].distance``); a plan from a stranger can ask for no value out of range.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import FacilityError
from ...schema import Source, load
from ..checks import Waypoints, check_mapping, name
from .roles import Rover
from .tasks import DRIVES, TASKS

TASKS_MAX = 1_000
"""Most tasks a plan may hold."""
ROVERS_MAX = 100
"""Most rovers a plan may name."""
PLAN_SECONDS_MAX = 600.0
"""s simulated: the longest a plan may run, all its tasks together (each task also
ends within ``sim.TASK_TIMEOUT``). A plan whose tasks take longer at the least (each
drive at its top speed, each turn at its top rate, each hold) is refused before
anything moves; one that runs past it is stopped with an error."""


@dataclass(frozen=True)
class Plan:
    """A checked task plan: its rovers (None: every rover), its tasks, its arm motion."""

    rovers: tuple[str, ...] | None
    tasks: tuple[dict, ...]
    arm: dict | None
    where: Waypoints
    """Where its errors point (the file)."""


def _rovers(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, list) or not value:
        raise w.fail(where, "needs a non-empty list of rover names")
    if len(value) > ROVERS_MAX:
        raise w.fail(where, f"has {len(value)} rovers; at most {ROVERS_MAX}")
    for i, rover in enumerate(value):
        name(rover, f"{where}[{i}]", w)
        if rover in value[:i]:
            raise w.fail(f"{where}[{i}]", f"'{rover}' is named twice")


def check_task(spec: Any, at: str, w: Waypoints, *, arm: bool = False) -> dict:
    """One task of a plan (``arm``: its arm motion) checked for its kind, keys, types and
    ranges."""
    if not isinstance(spec, Mapping):
        raise w.fail(at, "a task is a mapping with its kind and keys")
    if "kind" not in spec:
        raise w.fail(f"{at}.kind", "is required")
    kind = spec["kind"]
    name(kind, f"{at}.kind", w)
    valid = [k for k, t in TASKS.items() if t.arm == arm]
    if kind not in valid:
        known = TASKS.get(kind)
        if known is not None and known.arm:
            message = f"'{kind}' is an arm motion: give it as the plan's arm"
        elif known is not None:
            message = f"'{kind}' is a drive task: give it in the plan's tasks"
        else:
            message = f"unknown kind '{kind}'"
        raise w.fail(f"{at}.kind", f"{message}; valid: {', '.join(valid)}")
    task = TASKS[kind]
    check_mapping(spec, at, w, {"kind": name, **task.checks}, task.required)
    return dict(spec)


def check_shape(data: Any, path: Path | None, source: Source | None = None) -> Plan:
    """``data`` (a plan file's) checked for keys, kinds, types and ranges; ``source``: the
    file's key lines, for errors that name them."""
    w = Waypoints(path, source)
    if not isinstance(data, Mapping):
        raise w.fail("plan", "a task plan is a mapping with tasks (and rovers, arm)")
    top = {"rovers": _rovers, "tasks": lambda v, where, w: None, "arm": lambda v, where, w: None}
    check_mapping(data, "", w, top, ("tasks",))  # tasks and arm: checked one by one below
    tasks = data["tasks"]
    if not isinstance(tasks, list) or not tasks:
        raise w.fail("tasks", "needs a non-empty list of tasks")
    if len(tasks) > TASKS_MAX:
        raise w.fail("tasks", f"has {len(tasks)} tasks; at most {TASKS_MAX}")
    checked = tuple(check_task(t, f"tasks[{i}]", w) for i, t in enumerate(tasks))
    _check_total(checked, w)
    arm = check_task(data["arm"], "arm", w, arm=True) if "arm" in data else None
    rovers = tuple(data["rovers"]) if "rovers" in data else None
    return Plan(rovers, checked, arm, w)


def _check_total(tasks: Sequence[Mapping], w: Waypoints) -> None:
    """The tasks' least time together within :data:`PLAN_SECONDS_MAX`; else an error
    naming the task where the sum passes it."""
    total = 0.0
    for i, spec in enumerate(tasks):
        total += DRIVES[spec["kind"]].least_seconds(spec)
        if total > PLAN_SECONDS_MAX:
            raise w.fail(
                f"tasks[{i}]",
                f"brings the plan's time to at least {total:g} s; a plan may run at most "
                f"{PLAN_SECONDS_MAX:g} s simulated",
            )


def run_seconds(elapsed: float, task_timeout: float) -> float:
    """Simulated seconds a task may run ``elapsed`` seconds into a plan: its own bound,
    ``task_timeout``, or what is left of :data:`PLAN_SECONDS_MAX`."""
    return max(0.0, min(task_timeout, PLAN_SECONDS_MAX - elapsed))


def past_bound(plan: Plan, i: int) -> FacilityError:
    """The error of a plan stopped at task ``i`` by :data:`PLAN_SECONDS_MAX`."""
    return plan.where.fail(
        f"tasks[{i}]",
        f"not done when the plan reached its bound of {PLAN_SECONDS_MAX:g} s simulated",
    )


def read_plan(path: str | Path) -> Plan:
    """A task plan file (a regular file of bounded size, read by the safe YAML reader),
    its shape checked (:func:`check_shape`)."""
    data, source = load(Path(path), "task plan")
    source.error = FacilityError
    return check_shape(data, Path(path), source)


def options_plan(tasks: Sequence[Mapping], arm: Mapping | None, label: str) -> Plan:
    """A plan made of tasks given another way (``rover-drive --distance ...``), checked as
    a file's are; ``label`` names them in errors."""
    w = Waypoints(None, Source(label, error=FacilityError))
    checked = tuple(check_task(t, f"tasks[{i}]", w) for i, t in enumerate(tasks))
    return Plan(None, checked, check_task(arm, "arm", w, arm=True) if arm else None, w)


def check_plan(plan: Plan, rovers: Mapping[str, Rover], names: Sequence[str] = ()) -> list[str]:
    """The rovers that run ``plan`` (its own, else ``names``, else every rover of the
    bundle), every task checked against each of them; a FacilityError naming the plan's
    element otherwise. ``names`` must be rovers of ``rovers``."""
    w = plan.where
    if plan.rovers is not None:
        for i, rover in enumerate(plan.rovers):
            if rover not in rovers:
                message = f"no rover '{rover}' in the bundle; rovers: {', '.join(rovers)}"
                raise w.fail(f"rovers[{i}]", message)
    chosen = list(plan.rovers or names or rovers)
    for n in chosen:
        for i, spec in enumerate(plan.tasks):
            TASKS[spec["kind"]].check(spec, f"tasks[{i}]", rovers[n], w)
        if plan.arm is not None:
            TASKS[plan.arm["kind"]].check(plan.arm, "arm", rovers[n], w)
    return chosen
