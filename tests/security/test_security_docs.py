"""docs/security.md states facts the code holds: the size limits (each kind, its
default, its variable), the YAML expansion bound, the xacro expansion bounds (work,
memory, single values, macro calls, includes) and the trust switch are read from the code here, so the page cannot drift."""

from __future__ import annotations

from pathlib import Path

from urdf2mjcf import untrusted
from urdf2mjcf.passes import xacro_budget, xacro_guard, xacro_install
from urdf2mjcf.passes.validate import ValidateConfig

DOC = (Path(__file__).resolve().parents[2] / "docs" / "security.md").read_text()


def limits_table() -> str:
    rows = ["| kind | default | variable | covers |", "|---|---|---|---|"]
    for kind, (mb, what) in untrusted.LIMITS_MB.items():
        rows.append(f"| {kind} | {mb:g} MB | `{untrusted.limit_env(kind)}` | {what} |")
    return "\n".join(rows)


def test_the_limits_table_is_the_code_s():
    start = DOC.index("<!-- limits table")
    end = DOC.index("<!-- end limits table -->")
    table = DOC[start:end].split("-->", 1)[1].strip()
    assert table == limits_table(), "regenerate the table from untrusted.LIMITS_MB:\n" + (
        limits_table()
    )


def _bounds() -> dict[str, str]:
    from urdf2mjcf import limits, mjcf_bounds, mjcf_files, mjcf_input
    from urdf2mjcf.facility import scatter
    from urdf2mjcf.runner import cli as runner_cli
    from urdf2mjcf.runner import waypoints
    from urdf2mjcf.runner.rover import plan_file, sim

    return {
        "ValidateConfig.max_steps": f"{ValidateConfig.max_steps:,} steps",
        "xacro_budget.MAX_WORK": f"{xacro_budget.MAX_WORK:,} steps",
        "xacro_budget.MAX_MEMORY": f"{xacro_budget.MAX_MEMORY:,} bytes",
        "xacro_budget.MAX_TEXT": f"{xacro_budget.MAX_TEXT:,} characters",
        "xacro_budget.MAX_ITEMS": f"{xacro_budget.MAX_ITEMS:,} items",
        "xacro_budget.MAX_INT_BITS": f"{xacro_budget.MAX_INT_BITS:,} bits",
        "xacro_install.MAX_MACRO_CALLS": f"{xacro_install.MAX_MACRO_CALLS:,} macro calls",
        "xacro_install.MAX_MACRO_DEPTH": f"{xacro_install.MAX_MACRO_DEPTH:,} levels",
        "xacro_install.MAX_INCLUDES": f"{xacro_install.MAX_INCLUDES:,} includes",
        "scatter.COUNT_MAX": f"{scatter.COUNT_MAX:,} rocks",
        "scatter.TRY_MAX": f"{scatter.TRY_MAX:,} draws",
        "runner.cli.TRIALS_MAX": f"{runner_cli.TRIALS_MAX:,} trials",
        "waypoints.DURATION_MAX": f"{waypoints.DURATION_MAX:g} s",
        "waypoints.SECONDS_MAX": f"{waypoints.SECONDS_MAX:g} s",
        "waypoints.STEPS_MAX": f"{waypoints.STEPS_MAX:,} steps",
        "rover.sim.SETTLE_MAX": f"{sim.SETTLE_MAX:g} s",
        "rover.plan_file.PLAN_SECONDS_MAX": f"{plan_file.PLAN_SECONDS_MAX:g} s",
        "rover.sim.TASK_TIMEOUT": f"{sim.TASK_TIMEOUT:g} s",
        "mjcf_files.ELEMENTS_MAX": f"{mjcf_files.ELEMENTS_MAX:,} elements",
        "mjcf_files.DOCUMENTS_MAX": f"{mjcf_files.DOCUMENTS_MAX:,} files",
        "mjcf_files.DOCUMENT_BYTES_MAX": f"{mjcf_files.DOCUMENT_BYTES_MAX / 2**20:g} MB",
        "mjcf_bounds.BODIES_MAX": f"{mjcf_bounds.BODIES_MAX:,} bodies",
        "mjcf_bounds.FLEX_POINTS_MAX": f"{mjcf_bounds.FLEX_POINTS_MAX:,} points",
        "mjcf_bounds.DEPTH_MAX": f"{mjcf_bounds.DEPTH_MAX:,} levels",
        "mjcf_bounds.MESH_VERTICES_MAX": f"{mjcf_bounds.MESH_VERTICES_MAX:,} vertices",
        "mjcf_bounds.PIXELS_MAX": f"{mjcf_bounds.PIXELS_MAX:,} pixels",
        "mjcf_bounds.HFIELD_SAMPLES_MAX": f"{mjcf_bounds.HFIELD_SAMPLES_MAX:,} samples",
        "mjcf_bounds.MEMORY_MAX": f"{mjcf_bounds.MEMORY_MAX / 2**30:g} GiB",
        "mjcf_bounds.SIZE_COUNT_MAX": f"{mjcf_bounds.SIZE_COUNT_MAX:,} entries",
        "mjcf_bounds.USER_FIELDS_MAX": f"{mjcf_bounds.USER_FIELDS_MAX:,} numbers",
        "mjcf_bounds.RENDER_SIZE_MAX": f"{mjcf_bounds.RENDER_SIZE_MAX:,} pixels",
        "mjcf_bounds.ITERATIONS_MAX": f"{mjcf_bounds.ITERATIONS_MAX:,} iterations",
        "mjcf_input.COMPILE_TIMEOUT": f"{mjcf_input.COMPILE_TIMEOUT:g} s",
        "mjcf_input.COMPILE_MEMORY": f"{mjcf_input.COMPILE_MEMORY / 2**30:g} GiB",
        "limits.TIMESTEP_RANGE": "{:g} to {:g} s".format(*limits.TIMESTEP_RANGE),
    }


def test_the_bounds_table_is_the_code_s():
    start = DOC.index("<!-- bounds table")
    end = DOC.index("<!-- end bounds table -->")
    rows = [r for r in DOC[start:end].splitlines() if r.startswith("| ") and "`" in r]
    found = {}
    for row in rows:
        _, _, bound, where, _ = (c.strip() for c in row.split("|"))
        found[where.strip("`")] = bound
    assert found == _bounds()


def test_the_figures_the_page_repeats_are_the_code_s():
    for figure in (
        f"{untrusted.YAML_MAX_NODES:,} nodes",
        f"`{xacro_guard.TRUST_ENV}=1`",
        f"{xacro_budget.MAX_WORK:,} steps for one expansion",
        f"`{untrusted.limit_env('mesh')}`",
    ):
        assert figure in DOC, figure
