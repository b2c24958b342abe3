"""``facility-demo SCENE``: replay the logistics demo in a built facility and judge it.

Exit 0 only when the demo succeeds (every trial, with ``--trials``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click


def _table(steps: list[dict]) -> str:
    lines = [f"{'step':<22} {'ok':<5} {'time':>7}  contacts"]
    for s in steps:
        lines.append(
            f"{s['name']:<22} {'ok' if s['ok'] else 'FAIL':<5} {s['duration']:6.2f}s  "
            f"{', '.join(s['contacts']) or '-'}"
        )
        if s["message"]:
            lines.append(f"{'':<22} {s['message']}")
    return "\n".join(lines)


@click.command("facility-demo")
@click.argument("scene", type=click.Path(exists=True, path_type=Path))
@click.option(
    "--waypoints",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="demo file (default: recipes/demo/imetro.yaml of the facility root)",
)
@click.option(
    "--trials",
    type=int,
    default=0,
    help="N trials, each on the facility rebuilt with seeded pose jitter (parallel)",
)
@click.option("--seed", type=int, default=0, help="first seed of the trials (seeds S..S+N-1)")
@click.option(
    "--recipe",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="recipe rebuilt per trial (default: the one in facility.json)",
)
@click.option(
    "--report",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write the JSON report here",
)
@click.option(
    "--frames",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="save PNGs of key moments (scene camera, wrist camera red mask)",
)
@click.option("--workers", type=int, default=None, help="parallel processes for --trials")
def facility_demo_command(scene, waypoints, trials, seed, recipe, report, frames, workers):
    """Replay the iMETRO logistics demo in SCENE (a built facility folder or its scene.xml)."""
    from .. import headless

    headless.configure()
    from ..facility.root import find_root

    folder = scene.parent if scene.suffix == ".xml" else scene
    manifest_path = folder / "facility.json"
    if not manifest_path.is_file():
        click.echo(f"error: {manifest_path}: no facility.json (build with make-facility)", err=True)
        sys.exit(2)
    root = find_root()  # a checkout here or above, else the installed data
    waypoints = waypoints or root / "recipes" / "demo" / "imetro.yaml"
    if trials and trials > 0:
        from .trials import run_trials

        manifest = json.loads(manifest_path.read_text())
        recipe = recipe or root / (manifest.get("recipe_file") or "recipes/imetro.yaml")
        seeds = list(range(seed, seed + trials))
        results = run_trials(recipe, root, waypoints, seeds, workers=workers, frames=frames)
        ok = sum(r["ok"] for r in results)
        for r in results:
            where = "" if r["ok"] else f" at '{r['failed_step']}'"
            click.echo(
                f"seed {r['seed']:>4}: {'success' if r['ok'] else 'FAIL'}{where}: {r['message']}"
                f"  ({r['wall_time']:.1f} s wall, {r['sim_time']:.1f} s simulated)"
            )
        click.echo(f"success rate: {ok}/{len(results)} ({100 * ok / len(results):.0f} %)")
        out = {"trials": results, "successes": ok, "success_rate": ok / len(results)}
        success = ok == len(results)
    else:
        from .demo import run_demo

        res = run_demo(folder, waypoints, frames=frames, log=lambda *_: None)
        out = res.to_json()
        click.echo(_table(out["steps"]))
        click.echo(
            f"{'SUCCESS' if res.ok else 'FAILED'}: {res.message}"
            f"  ({res.sim_time:.1f} s simulated in {res.wall_time:.1f} s wall, "
            f"real-time factor {res.sim_time / max(res.wall_time, 1e-9):.1f})"
        )
        success = res.ok
    if report:
        report.parent.mkdir(parents=True, exist_ok=True)
        report.write_text(json.dumps(out, indent=2, default=float) + "\n")
    sys.exit(0 if success else 1)


def main() -> None:  # pragma: no cover
    facility_demo_command()


if __name__ == "__main__":  # pragma: no cover
    main()
