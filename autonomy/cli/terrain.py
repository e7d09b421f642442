"""``lander terrain``: build a simulated world, judge its ground-truth landing safety and
optionally render what the depth camera sees from a point above it.

    lander terrain --kind mars [--seed N] [--set rock_density=0.3 ...] [--out DIR]
                   [--depth-at X,Y,AGL[,YAW]]
    lander terrain --kind file --set path=dem.asc
    lander terrain --kind urban --set "moving_obstacles={count: 20}"

Prints the world's size, relief and safe fraction (and its moving obstacles); writes
``terrain.png`` (heights with unsafe ground shaded, moving obstacles' paths drawn) and, with
``--depth-at``, ``depth.npy`` / ``depth.png`` plus the ``lander detect`` command line that
runs a detector on that image.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import yaml
from pydantic import ValidationError

from autonomy.cli import args as types
from autonomy.config import read_yaml_value
from autonomy.errors import UserError

KINDS = ("flat", "mars", "urban", "rubble", "file")
# Largest image side drawn: bigger grids are subsampled for the picture only.
MAX_PLOT_CELLS = 1000


def parse_assignments(items: list[str]) -> dict:
    """``key=value`` strings (values read as YAML scalars/lists) -> dict."""
    values = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set {item}: expected key=value")
        try:
            values[key.strip()] = read_yaml_value(text)
        except (yaml.YAMLError, RecursionError):
            raise UserError(f"--set {item}: the value is not valid YAML") from None
    return values


def parse_depth_at(text: str) -> tuple[float, float, float, float]:
    """``X,Y,AGL[,YAW]`` (m, m, m, degrees ENU) -> floats."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (3, 4) or not all(math.isfinite(v) for v in values):
        raise UserError(f"--depth-at {text}: expected X,Y,AGL[,YAW] numbers")
    if values[2] <= 0:
        raise UserError(f"--depth-at {text}: AGL must be positive")
    return (*values[:3], values[3] if len(values) == 4 else 90.0)


def build(kind: str, assignments: dict, seed: int):
    from autonomy.config import describe_error
    from sitl.terrain import TerrainSettings, make_terrain, parse_terrain_settings

    data = {"kind": kind, **assignments}
    try:
        settings = parse_terrain_settings(data)
    except ValidationError as exc:
        field, reason = describe_error(exc.errors()[0], data, TerrainSettings)
        raise UserError(f"--set {field}: {reason}") from None
    if settings.kind == "file":  # the model in metres: were its units taken right?
        from sitl.terrain.files import describe_elevation

        for line in describe_elevation(settings):  # the model, its window, notes
            print(line)
    cells = settings_cells(settings)
    if cells is not None and cells > 4_000_000:
        print(f"building the {kind} world ({cells / 1e6:.0f} million cells) and its safety map",
              flush=True)
    try:
        return make_terrain(settings, seed=seed)
    except (OSError, ValueError) as exc:
        raise UserError(f"world: {exc}") from None


def settings_cells(settings) -> float | None:
    """Grid cells a procedural world will have (None for a file world)."""
    size = getattr(settings, "size", None)
    if size is None:
        return None
    return (size[0] / settings.cell_size + 1) * (size[1] / settings.cell_size + 1)


def plot_terrain(terrain, mask: np.ndarray, path: Path, title: str) -> None:
    import matplotlib

    from autonomy.report.plot import plot_moving

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    step = max(1, int(math.ceil(max(terrain.shape) / MAX_PLOT_CELLS)))
    xmin, xmax, ymin, ymax = terrain.extent
    half = terrain.cell_size / 2
    extent = (xmin - half, xmax + half, ymin - half, ymax + half)
    fig, ax = plt.subplots(figsize=(8, 7))
    image = ax.imshow(
        terrain.grid[::step, ::step], origin="lower", extent=extent, cmap="gist_earth"
    )
    unsafe = np.ma.masked_where(mask[::step, ::step], np.ones(mask[::step, ::step].shape))
    ax.imshow(unsafe, origin="lower", extent=extent, cmap="Reds", alpha=0.35, vmin=0, vmax=1)
    ax.plot([0], [0], marker="*", color="k", markersize=10, label="home")
    plot_moving(ax, terrain.moving)
    fig.colorbar(image, ax=ax, label="height (m)")
    ax.set(title=title, xlabel="east (m)", ylabel="north (m)")
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def describe_moving(moving) -> str | None:
    """One line about a world's moving obstacles, or None without any."""
    if moving is None:
        return None
    kinds = [o["kind"] for o in moving.describe()]
    people, vehicles = kinds.count("person"), kinds.count("vehicle")
    return (f"moving obstacles: {people} people, {vehicles} vehicles, speeds "
            f"{moving.speed.min():.1f}..{moving.speed.max():.1f} m/s, paths "
            f"{moving.length.min():.0f}..{moving.length.max():.0f} m")


def plot_depth(depth: np.ndarray, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 5))
    image = ax.imshow(depth, cmap="viridis")
    fig.colorbar(image, ax=ax, label="depth (m)")
    ax.set(title=title, xlabel="u (px)", ylabel="v (px)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def render_depth(terrain, x: float, y: float, agl: float, yaw_deg: float, seed: int):
    """One noisy frame from AGL metres above (x, y); above the stereo range the vehicle is
    taken to have flown 15 m along its heading in the last second (SfM baseline)."""
    from sitl.sensors import DepthCamera

    camera = DepthCamera(terrain, rng=np.random.default_rng(seed))
    yaw = math.radians(yaw_deg)
    position = np.array([x, y, float(terrain.height(x, y)) + agl])
    back = position - 15.0 * np.array([math.cos(yaw), math.sin(yaw), 0.0])
    camera.observe_pose(back, yaw, 0.0)
    return camera.render(position, yaw, 1.0), camera


def run(args: argparse.Namespace) -> int:
    from sitl.terrain import safety_map

    assignments = parse_assignments(args.set or [])
    depth_at = parse_depth_at(args.depth_at) if args.depth_at else None
    start = time.perf_counter()
    terrain = build(args.kind, assignments, args.seed)
    elapsed = time.perf_counter() - start
    mask, slope, _ = safety_map(terrain)
    xmin, xmax, ymin, ymax = terrain.extent
    print(
        f"world {terrain.kind} seed {args.seed}: {terrain.shape[1]} x {terrain.shape[0]} cells "
        f"of {terrain.cell_size:g} m, x {xmin:.1f}..{xmax:.1f} m, y {ymin:.1f}..{ymax:.1f} m, "
        f"built in {elapsed:.2f} s"
    )
    print(
        f"heights {float(terrain.grid.min()):.2f}..{float(terrain.grid.max()):.2f} m, median "
        f"slope {math.degrees(float(np.median(slope))):.1f} deg, safe ground "
        f"{100 * float(mask.mean()):.1f} % (footprint 1 m, 15 deg, 0.1 m, margin 0.5 m)"
    )
    if (line := describe_moving(terrain.moving)) is not None:
        print(line)
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"--out {out}: {exc.strerror}") from None
    plot_terrain(terrain, mask, out / "terrain.png", f"{terrain.kind}, seed {args.seed}")
    written = [out / "terrain.png"]
    if args.save_grid:
        np.save(out / "terrain.npy", terrain.grid)
        written.append(out / "terrain.npy")
    if depth_at is not None:
        x, y, agl, yaw_deg = depth_at
        if not terrain.contains(x, y):
            raise UserError(f"--depth-at: ({x:g}, {y:g}) is outside the world")
        frame, camera = render_depth(terrain, x, y, agl, yaw_deg, args.seed)
        if frame is None:
            reasons = ", ".join(camera.skipped)
            raise UserError(f"--depth-at: the camera gives no depth there ({reasons})")
        np.save(out / "depth.npy", frame.depth)
        plot_depth(frame.depth, out / "depth.png", f"{frame.source} depth from {agl:g} m AGL")
        written += [out / "depth.npy", out / "depth.png"]
        valid = np.isfinite(frame.depth)
        print(
            f"depth ({frame.source}, baseline {frame.baseline:g} m): {int(valid.sum())} "
            f"pixels, median sigma {float(np.nanmedian(frame.sigma)):.3f} m"
        )
        px, py, pz = frame.position
        print(
            f"detect it: lander detect --depth {out / 'depth.npy'} --fx {frame.fx:g} "
            f"--fy {frame.fy:g} --cx {frame.cx:g} --cy {frame.cy:g} "
            f"--pose {px:.2f},{py:.2f},{pz:.2f},{yaw_deg - 90.0:g}"
        )
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "terrain",
        help="build a simulated world and show its ground-truth landing safety",
        description="Build a terrain world (as a mission's 'world' section would), print its "
        "size, relief and safe fraction and write terrain.png; optionally render the depth "
        "camera's view from a point above it.",
    )
    parser.add_argument("--kind", choices=KINDS, default="mars", help="world kind")
    parser.add_argument("--seed", type=types.seed, default=0, help="world seed (0 .. 2**32-1)")
    parser.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="world setting, e.g. rock_density=0.3 or size=[200,200]",
    )
    parser.add_argument(
        "--out",
        default="lander-terrain",
        metavar="DIR",
        help="output directory (default: %(default)s)",
    )
    parser.add_argument("--save-grid", action="store_true", help="also write terrain.npy")
    parser.add_argument(
        "--depth-at",
        metavar="X,Y,AGL[,YAW]",
        help="render a depth image from AGL m above (X, Y), heading YAW deg",
    )
    parser.set_defaults(func=run)
