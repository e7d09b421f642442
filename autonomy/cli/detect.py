"""``lander detect``: run a landing-site detector offline on recorded data.

    lander detect --lidar CLOUD.{npy,ply,las,laz} [--judge] [--roofs] [--out DIR]
    lander detect --depth DEPTH.{npy,png,tif} (--camera-info FILE | --fx F --fy F --cx C --cy C)
                  [--depth-scale M] [--pose x,y,z,yaw]

Prints a table of sites (best first) and writes ``sites.csv`` and ``overlay.png`` (points or
depth coloured by height, sites drawn with their radii) into ``--out``; a LAS/LAZ file with
a CRS also gets ``sites.geojson`` (WGS84). See docs/lidar-and-elevation-models.md.

Longer than 500 lines: two inputs (point clouds and depth images) with their tables,
CSV/GeoJSON and overlays; one module per input is the next step.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from autonomy.cli import args as types
from autonomy.errors import UserError

if TYPE_CHECKING:  # the detectors are imported when the command runs (fast `lander --help`)
    from lsd.frames import DepthFrame
    from lsm.records import SiteObservation

NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
CSV_FIELDS = (
    "rank", "x", "y", "z", "lat", "lon", "size", "roughness", "uncertainty",
    "obstacle_altitude", "score", "class",
)  # fmt: skip
MAX_PLOTTED_POINTS = 200_000
DROPPED = "with NaN/inf or beyond 1e8 m dropped"
MAX_DRAWN_SITES = 200  # the best ones; all are in sites.csv
# Clouds in memory with more points are searched a 200 m tile at a time (same sites): the
# search's neighbourhood pairs grow with the search points, about 1 GB per 2 M points.
TILE_ABOVE = 500_000


def _settings(model: type, values: dict, flag_of: dict[str, str]):
    """Build a settings model from the flags that were given; a bad value names its flag."""
    from pydantic import ValidationError

    from autonomy.config import describe_error

    given = {k: v for k, v in values.items() if v is not None}
    try:
        return model(**given)
    except ValidationError as exc:
        err = exc.errors()[0]
        field, reason = describe_error(err, given, model)
        flag = flag_of.get(field.split(".")[0]) or flag_of.get(str(err["loc"][0])
                                                              if err["loc"] else "")
        raise UserError(f"{flag or field}: {reason}") from None


def parse_pose(text: str | None) -> tuple[np.ndarray, np.ndarray]:
    """``x,y,z,yaw`` (m, m, m, degrees: heading of the image x axis, counter-clockwise from
    east, camera looking straight down) or a 4x4 camera->world ``.npy``; default: camera at
    the origin looking down. Returns (position (3,), rotation (3, 3))."""
    if text is None:
        return np.zeros(3), NADIR.copy()
    if text.lower().endswith(".npy"):
        from lsd.io import DataFileError, load_npy

        try:
            m = load_npy(Path(text))
        except DataFileError as exc:
            raise UserError(f"--pose {exc}") from None
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise UserError(f"--pose {text}: expected a finite 4x4 matrix, got shape {m.shape}")
        rot = m[:3, :3].astype(np.float64)
        if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4) or np.linalg.det(rot) < 0:
            raise UserError(f"--pose {text}: the 3x3 block is not a rotation")
        return m[:3, 3].astype(np.float64), rot
    try:
        x, y, z, yaw = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--pose: expected x,y,z,yaw or a 4x4 .npy, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, z, yaw)):
        raise UserError("--pose: values must be finite")
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.array([x, y, z]), rz @ NADIR


def _classes(raw: np.ndarray, codes: np.ndarray, obs: list[SiteObservation]) -> list[str]:
    """Majority class of the raw points within each site's radius (horizontal), with share."""
    from scipy.spatial import cKDTree

    from lsd.io import class_name

    if not obs:
        return []
    tree = cKDTree(raw[:, :2])
    centres = np.array([[o.x, o.y] for o in obs])
    radii = np.array([max(o.size, 1e-6) for o in obs])
    out = []
    for members in tree.query_ball_point(centres, radii):  # one query per site, not per point
        if not members:
            out.append("")
            continue
        counts = np.bincount(codes[members])
        top = int(np.argmax(counts))
        out.append(f"{class_name(top)} {100.0 * counts[top] / len(members):.0f}%")
    return out


def _write_outputs(
    out_dir: Path, obs: list[SiteObservation], scores: np.ndarray, classes: list[str],
    georef=None,
) -> list[dict]:
    """sites.csv: x, y, z and obstacle_altitude in the file's CRS and units (metres
    without one; x, y to 1e-8 deg, about a millimetre, in degrees), lat/lon WGS84 when the
    CRS is known, size in metres."""
    xyz = np.array([[o.x, o.y, o.z] for o in obs]).reshape(-1, 3)
    obst = np.array([[o.x, o.y, o.obstacle_altitude] for o in obs]).reshape(-1, 3)
    lonlat = None
    if georef is not None:
        lonlat = georef.to_lonlat(xyz[:, :2]) if len(xyz) else None
        xyz, obst = georef.to_file(xyz), georef.to_file(obst)
    places = _xy_places(georef)
    rows = []
    for i, (o, sc) in enumerate(zip(obs, scores, strict=True)):
        rows.append(
            {
                "rank": i + 1, "x": round(xyz[i, 0], places), "y": round(xyz[i, 1], places),
                "z": round(xyz[i, 2], 3),
                "lat": "" if lonlat is None else round(float(lonlat[i, 1]), 8),
                "lon": "" if lonlat is None else round(float(lonlat[i, 0]), 8),
                "size": round(o.size, 3), "roughness": round(o.roughness, 4),
                "uncertainty": round(o.uncertainty, 4),
                "obstacle_altitude": round(obst[i, 2], 3),
                "score": round(float(sc), 4), "class": classes[i] if classes else "",
            }
        )  # fmt: skip
    with open(out_dir / "sites.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    return rows


def _xy_places(georef) -> int:
    """Decimals of x and y in sites.csv: a millimetre in metres or feet, 1e-8 in degrees."""
    return 8 if georef is not None and georef.projection is not None else 3


def _remove_stale_geojson(out_dir: Path) -> None:
    """A sites.geojson of an earlier run into the same folder would sit beside this run's
    sites.csv as if it were its own: remove it (this run has no CRS to write one)."""
    stale = out_dir / "sites.geojson"
    if stale.is_file():
        stale.unlink()
        print(f"removed {stale}: an earlier run's (this input has no CRS for one)")


def _print_table(rows: list[dict], limit: int, degrees: bool = False) -> None:
    if not rows:
        return
    with_class = any(r["class"] for r in rows)
    w, d = (13, 7) if degrees else (10, 2)  # 1e-7 deg: about a centimetre
    head = f"{'#':>4} {'x':>{w}} {'y':>{w}} {'z':>8} {'size':>6} {'rough':>6} {'unc':>6} "
    head += f"{'obst_z':>8} {'score':>6}" + ("  class" if with_class else "")
    print(head)
    for r in rows[:limit]:
        line = (
            f"{r['rank']:>4} {r['x']:>{w}.{d}f} {r['y']:>{w}.{d}f} {r['z']:>8.2f} "
            f"{r['size']:>6.2f} "
            f"{r['roughness']:>6.3f} {r['uncertainty']:>6.3f} {r['obstacle_altitude']:>8.2f} "
            f"{r['score']:>6.3f}"
        )
        print(line + (f"  {r['class']}" if with_class else ""))
    if len(rows) > limit:
        print(f"... {len(rows) - limit} more in sites.csv")


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _overlay_cloud(path: Path, cloud: np.ndarray, obs: list[SiteObservation], seed: int,
                   georef=None) -> None:
    """Points coloured by height with the sites' discs, in metres (the file's CRS
    coordinates converted to metres, named in the axis labels)."""
    plt = _figure()
    from matplotlib.patches import Circle

    pts = cloud
    if len(pts) > MAX_PLOTTED_POINTS:
        keep = np.random.default_rng(seed).choice(len(pts), MAX_PLOTTED_POINTS, replace=False)
        pts = pts[keep]
    frame = "" if georef is None or georef.crs is None else f", {georef.label} in metres"
    if georef is not None and georef.projection is not None:
        frame = f", {georef.label} projected to a transverse Mercator (metres)"
    fig, ax = plt.subplots(figsize=(8, 8))
    if len(pts):
        # Highest point per pixel of a 600 px raster: as fast for a million points as for
        # a thousand (a scatter of each point is not).
        lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
        cell = max(float((hi - lo).max()) / 600.0, 1e-6)
        ij = ((pts[:, :2] - lo) / cell).astype(np.int64)
        shape = (int(ij[:, 1].max()) + 1, int(ij[:, 0].max()) + 1)
        top = np.full(shape[0] * shape[1], -np.inf)
        np.maximum.at(top, ij[:, 1] * shape[1] + ij[:, 0], pts[:, 2])
        top = np.where(np.isfinite(top), top, np.nan).reshape(shape)
        im = ax.imshow(top, origin="lower", cmap="terrain", interpolation="nearest",
                       extent=(lo[0], lo[0] + shape[1] * cell, lo[1], lo[1] + shape[0] * cell))
        fig.colorbar(im, ax=ax, label="z (m)", shrink=0.8)
    for i, o in enumerate(obs[:MAX_DRAWN_SITES]):
        ax.add_patch(Circle((o.x, o.y), o.size, fill=False, ec="red", lw=1.2))
        if i < 20:
            ax.annotate(str(i + 1), (o.x, o.y), color="red", fontsize=7, ha="center")
    if not len(pts) and obs:
        xy = np.array([[o.x, o.y] for o in obs])
        ax.set_xlim(xy[:, 0].min() - 5, xy[:, 0].max() + 5)
        ax.set_ylim(xy[:, 1].min() - 5, xy[:, 1].max() + 5)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x (m{frame})")
    ax.set_ylabel(f"y (m{frame})")
    ax.set_title(f"{len(obs)} landing sites (red: radius; best {MAX_DRAWN_SITES} drawn)")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def _overlay_depth(path: Path, frame: DepthFrame, obs: list[SiteObservation]) -> None:
    plt = _figure()
    from matplotlib.patches import Circle

    k = frame.intrinsics
    world_z = np.full(frame.depth.shape, np.nan)
    points, _ = frame.to_points()
    valid = np.isfinite(frame.depth) & (frame.depth > 0)
    world_z[valid] = points[:, 2]
    fig, ax = plt.subplots(figsize=(9, 7))
    im = ax.imshow(world_z, cmap="terrain")
    fig.colorbar(im, ax=ax, label="world z (m)", shrink=0.8)
    rot, pos = np.asarray(frame.rotation), np.asarray(frame.position)
    for i, o in enumerate(obs[:MAX_DRAWN_SITES]):
        cam = rot.T @ (np.array(o.position) - pos)
        if cam[2] <= 0:
            continue
        u, v = k.fx * cam[0] / cam[2] + k.cx, k.fy * cam[1] / cam[2] + k.cy
        ax.add_patch(Circle((u, v), k.fx * o.size / cam[2], fill=False, ec="red", lw=1.2))
        if i < 20:
            ax.annotate(str(i + 1), (u, v), color="red", fontsize=7, ha="center")
    ax.set_title(f"{len(obs)} landing sites (red: radius; best {MAX_DRAWN_SITES} drawn)")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def run_lidar(args: argparse.Namespace, out_dir: Path) -> int:
    from lsd.io import DataFileError, open_las, read_point_cloud
    from lsd.lidar_pca.detector import LidarPcaDetector, LidarPcaSettings, spot_grades
    from lsd.lidar_pca.sites import find_sites, finish_sites, is_classified
    from lsd.pointcloud import clean_points

    settings = _settings(
        LidarPcaSettings,
        {
            "voxel_size": args.voxel, "seeding": args.seeding or "grid",
            "n_points": args.n_points, "r_min": args.r_min, "r_max": args.r_max,
            "r_step": args.r_step, "sigma_max": args.sigma_max,
            "theta_max_deg": args.theta_max, "residual_max": args.residual_max,
            "obstacle_height": args.obstacle_height,
            "classes": {"enabled": not args.no_classes, "roofs": args.roofs},
        },
        {
            "voxel_size": "--voxel", "seeding": "--seeding", "n_points": "--n-points",
            "r_min": "--r-min", "r_max": "--r-max", "r_step": "--r-step",
            "sigma_max": "--sigma-max", "theta_max_deg": "--theta-max",
            "residual_max": "--residual-max", "obstacle_height": "--obstacle-height",
        },
    )  # fmt: skip
    if args.paper:  # the paper's Algorithm 1 only: no off-plane, off-data or obstacle cuts
        settings = settings.model_copy(update={
            "max_step": None, "max_offset": None, "min_spread": None, "max_gap": None,
            "residual_max": None,
            "obstacle_height": None, "classes": settings.classes.model_copy(
                update={"enabled": False})})
    path = Path(args.lidar)
    rng = np.random.default_rng(args.seed)
    raw = codes = None
    try:
        tiled = False
        if path.suffix.lower() in (".las", ".laz"):
            with open_las(path) as (reader, georef):
                count = int(reader.header.point_count)
            tiled = args.tile_size is not None or count > args.in_memory_points
        if tiled:
            result = _run_tiled(args, path, settings, rng)
            spots, counts, georef = result.spots, result.counts, result.georef
            print(f"{path}: {result.points} points streamed through {result.tiles} tiles")
            _print_georef(georef)
        else:
            data = read_point_cloud(path)
            georef = data.georef
            raw = np.asarray(data.points)
            cloud, dropped = clean_points(raw)
            withheld = (f", {data.withheld} of them flagged withheld (deleted)"
                        if data.withheld else "")
            print(f"{path}: {len(raw)} points ({dropped} {DROPPED}{withheld})")
            _print_georef(georef)
            if len(cloud) < settings.n_min:
                raise UserError(
                    f"{path}: only {len(cloud)} valid points ({dropped} {DROPPED}); "
                    f"need at least {settings.n_min}"
                )
            finite = (np.abs(raw) <= 1e8).all(axis=1)
            codes = None if data.classification is None else data.classification[finite]
            if settings.seeding == "grid" and (args.tile_size or len(cloud) > TILE_ABOVE):
                from lsd.lidar_pca.tiles import detect_in_tiles, stderr_progress

                spots, counts = detect_in_tiles(
                    cloud, codes, settings, rng, tile_size=args.tile_size or 200.0,
                    progress=None if args.quiet else stderr_progress(str(path)))
            else:
                spots, counts = find_sites(cloud, codes, settings, rng)
                spots = finish_sites(spots, settings, counts)
            raw = cloud
    except DataFileError as exc:
        raise UserError(str(exc)) from None
    except ValueError as exc:  # e.g. more voxels than int64 keys hold: a cloud too wide
        raise UserError(f"{path}: {exc}") from None
    classified = is_classified(codes) if raw is not None else None
    if classified is not None:
        print("classification: " + (
            "ASPRS classes used (sites on ground" + (" or roofs" if settings.classes.roofs
                                                      else "") + " only)"
            if classified and settings.classes.enabled else
            "ignored (--no-classes)" if classified else
            "none usable (no ground class): sites by geometry alone"))
    print(f"voxel {settings.voxel_size:g} m, {settings.seeding} seeding: {counts.summary()}")
    det = LidarPcaDetector(settings)
    obs = det.to_observations(spots)
    scores = spot_grades(spots, settings)
    classes = _classes(raw, codes, obs) if raw is not None and codes is not None else []
    rows = _write_outputs(out_dir, obs, scores, classes, georef)
    wrote = [out_dir / "sites.csv"]
    if georef is not None and georef.crs is not None:
        _write_geojson(out_dir / "sites.geojson", rows, georef)
        wrote.append(out_dir / "sites.geojson")
    else:
        _remove_stale_geojson(out_dir)
    _overlay_cloud(out_dir / "overlay.png", raw if raw is not None else np.empty((0, 3)), obs,
                   args.seed, georef)
    wrote.append(out_dir / "overlay.png")
    unit = "m" if georef is None or georef.crs is None else georef.unit_name
    where = "" if georef is None else f"; x, y, z in {georef.label} ({unit})"
    if georef is not None and georef.projection is not None:
        z_unit = "m" if georef.vertical_unit == 1.0 else "its vertical unit"
        where = f"; x, y in {georef.label} (lon, lat degrees), z in {z_unit}"
    if obs:
        print(f"{len(obs)} sites (score = spot grade, eq. 6{where}; size in m)")
    else:
        print(f"0 sites, because {_why_none(counts)}")
    _print_table(rows, args.limit, degrees=_xy_places(georef) == 8)
    if args.judge:
        _judge(raw, codes, spots, settings, args.seed)
    print("wrote " + ", ".join(str(w) for w in wrote))
    return 0


def _run_tiled(args, path: Path, settings, rng):
    from lsd.lidar_pca.tiles import detect_tiled, stderr_progress

    if settings.seeding != "grid":
        raise UserError("--seeding: a tiled (streamed) cloud needs grid seeding")
    if args.judge:
        raise UserError("--judge: judging needs the cloud in memory; raise "
                        "--in-memory-points above the file's point count")
    return detect_tiled(path, settings, rng, tile_size=args.tile_size or 200.0,
                        progress=None if args.quiet else stderr_progress(str(path)))


def _print_georef(georef) -> None:
    if georef is None:
        return
    if georef.crs is not None:
        name = "" if georef.label == georef.crs.name else f": {georef.crs.name}"
        if georef.projection is not None:
            lon, lat = georef.centre
            conv = (", geographic (degrees): projected to a transverse Mercator centred at "
                    f"{lat:.6f}, {lon:.6f}")
        elif georef.horizontal_unit != 1.0:
            conv = f", x and y converted from {georef.unit_name} to metres"
        else:
            conv = ""
        print(f"CRS {georef.label}{name}{conv}")
    if georef.note:
        print(georef.note)


def _why_none(counts) -> str:
    """The honest reason a run found no site, from its counts."""
    if counts.search_points == 0:
        return "the cloud holds no searchable points"
    if counts.planes == 0:
        top = ", ".join(f"{k} {v}" for k, v in counts.rejected.most_common() if v)
        return (f"no search point found a plane flat and large enough ({top}; "
                f"see --theta-max, --residual-max, --r-min)")
    if counts.dropped and sum(counts.dropped.values()) >= counts.planes:
        top = ", ".join(f"{k} {v}" for k, v in counts.dropped.most_common() if v)
        return f"the site rules dropped all {counts.planes} planes ({top})"
    return "every plane was dropped"


def _judge(points, codes, spots, settings, seed: int) -> None:
    """Score the sites against the cloud's labels and a plane fit, with random discs of
    r_min on the same cloud as the baseline."""
    from lsd.lidar_pca.judge import Judge, JudgeRules, random_discs, score

    judge = Judge(points, codes, JudgeRules.from_settings(settings))
    safe, why = judge.judge(spots.centre[:, :2], spots.radius)
    centres = random_discs(points, 500, settings.r_min, np.random.default_rng(seed + 1))
    base, base_why = judge.judge(centres, settings.r_min)
    print(f"judge: sites {score(safe, why)}" if len(safe) else "judge: no sites to judge")
    print(f"judge: random {settings.r_min:g} m discs {score(base, base_why)}")


def _write_geojson(path: Path, rows: list[dict], georef) -> None:
    """The sites as GeoJSON points (WGS84 lon/lat, RFC 7946) with their properties."""
    import json

    label = georef.label
    features = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [r["lon"], r["lat"]]},
            "properties": {k: r[k] for k in CSV_FIELDS if k not in ("lat", "lon")}
            | {"crs": label},
        }
        for r in rows
    ]
    with open(path, "w") as f:
        json.dump({"type": "FeatureCollection", "features": features}, f)


def run_depth(args: argparse.Namespace, out_dir: Path) -> int:
    from lsd.camera_info import read_camera_info
    from lsd.depth_costmap.detector import DepthCostmapDetector, DepthCostmapSettings
    from lsd.frames import DepthFrame, Intrinsics
    from lsd.io import DataFileError, read_depth_image

    info = None
    if args.camera_info is not None:
        try:
            info = read_camera_info(args.camera_info)
        except DataFileError as exc:
            raise UserError(str(exc)) from None
    intrinsics = {}
    for flag in ("fx", "fy", "cx", "cy"):  # flags given override the calibration file
        value = getattr(args, flag)
        if value is None and info is not None:
            value = getattr(info, flag)
        if value is None:
            raise UserError(f"--{flag}: required with --depth (or --camera-info FILE)")
        if not math.isfinite(value) or (flag in ("fx", "fy") and value <= 0):
            raise UserError(f"--{flag}: must be {'positive' if flag in ('fx', 'fy') else 'finite'}"
                            f", got {value}")
        intrinsics[flag] = value
    settings = _settings(
        DepthCostmapSettings,
        {
            "vehicle_radius": args.vehicle_radius, "threshold": args.threshold,
            "d_max": args.d_max, "edge_blur_px": args.edge_blur,
            "normal_window": args.normal_window,
        },
        {
            "vehicle_radius": "--vehicle-radius", "threshold": "--threshold",
            "d_max": "--d-max", "edge_blur_px": "--edge-blur",
            "normal_window": "--normal-window",
        },
    )
    try:
        depth = read_depth_image(args.depth, **(
            {} if args.depth_scale is None else {"unit": args.depth_scale}))
    except DataFileError as exc:
        raise UserError(str(exc)) from None
    h, w = depth.shape
    if info is not None and info.width is not None and info.height is not None:
        if (info.width, info.height) != (w, h):
            raise UserError(
                f"{args.camera_info}: calibrated for {info.width} x {info.height} images, "
                f"but {args.depth} is {w} x {h}"
            )
    if info is not None and info.distorted:
        print(f"note: {args.camera_info} has lens distortion coefficients; the detector takes "
              "the depth image as rectified (pinhole), as depth cameras stream it")
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(depth) & (depth > 0)
    if not usable.any():
        raise UserError(f"{args.depth}: no valid depth (every pixel is zero, negative or NaN)")
    position, rotation = parse_pose(args.pose)
    k = Intrinsics(intrinsics["fx"], intrinsics["fy"], intrinsics["cx"], intrinsics["cy"], w, h)
    frame = DepthFrame(depth, None, k, position, rotation)
    det = DepthCostmapDetector(settings)
    det.process(frame)
    if det.last_problem:
        raise UserError(f"{args.depth}: {det.last_problem}")
    obs = det.clusters()
    n = len(obs)
    score = np.bincount(det.labels, det.site_list.sites.score, minlength=n) / np.maximum(
        np.bincount(det.labels, minlength=n), 1
    )
    order = np.argsort(-score, kind="stable")
    obs = [obs[i] for i in order]
    print(
        f"{args.depth}: {w}x{h} depth image, {int((~usable).sum())} pixels without depth; "
        f"{len(det.last_sites)} dense sites, {len(det.site_list)} after de-duplication, "
        f"{n} clusters"
    )
    rows = _write_outputs(out_dir, obs, score[order], [])
    _overlay_depth(out_dir / "overlay.png", frame, obs)
    _remove_stale_geojson(out_dir)
    print(f"{n} sites (score = mean decision-map value J, eq. 7)")
    _print_table(rows, args.limit)
    print(f"wrote {out_dir / 'sites.csv'} and {out_dir / 'overlay.png'}")
    return 0


def run(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except BrokenPipeError:  # e.g. `lander detect ... | head`: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


def _run(args: argparse.Namespace) -> int:
    if (args.lidar is None) == (args.depth is None):
        raise UserError("give exactly one of --lidar FILE or --depth FILE")
    out_dir = Path(args.out)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"--out {out_dir}: cannot create ({exc.strerror})") from None
    if args.lidar is not None:
        return run_lidar(args, out_dir)
    return run_depth(args, out_dir)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "detect",
        help="find landing sites in a recorded point cloud or depth image",
        description="Run the LiDAR PCA detector on a point cloud (.npy Nx3, .ply, .las/.laz "
        "with the 'las' extra) or the depth-costmap detector on a depth image (.npy metres, "
        "16-bit .png or .tif in --depth-scale units, float .tif metres). Prints the sites and "
        "writes sites.csv and overlay.png.",
    )
    src = parser.add_argument_group("input (one of)")
    src.add_argument("--lidar", metavar="FILE", help="point cloud in the world frame")
    src.add_argument("--depth", metavar="FILE", help="depth image")
    parser.add_argument("--out", default="lander-detect", metavar="DIR",
                        help="output directory (default: %(default)s)")
    parser.add_argument("--limit", type=types.integer(0, 1_000_000), default=20,
                        help="table rows printed")
    parser.add_argument("--seed", type=types.seed, default=0, help="random seed (search points)")
    lidar = parser.add_argument_group("LiDAR PCA detector")
    lidar.add_argument("--voxel", type=float, help="voxel size (m), default 0.05")
    lidar.add_argument("--seeding", choices=("random", "grid"),
                       help="search points: grid (default here: one per r_max cell, every "
                       "patch searched) or random (--n-points, the paper's)")
    lidar.add_argument("--n-points", type=int, help="random search points, default 20")
    lidar.add_argument("--r-min", type=float, help="smallest spot radius (m), default 1.5")
    lidar.add_argument("--r-max", type=float, help="largest radius (m), default 3")
    lidar.add_argument("--r-step", type=float, help="radius step (m), default 0.5")
    lidar.add_argument("--sigma-max", type=float,
                       help="largest z std (m), default 0.2 (the paper's; flatness is "
                       "--residual-max)")
    lidar.add_argument("--theta-max", type=float, help="steepest slope (deg), default 15")
    lidar.add_argument("--residual-max", type=float,
                       help="largest RMS distance from a site's plane (m), default 0.05")
    lidar.add_argument("--obstacle-height", type=float,
                       help="highest point allowed in the 1 m clearance ring above the site's "
                       "plane (m), default 0.5")
    lidar.add_argument("--roofs", action="store_true",
                       help="classified clouds: also report sites on flat roofs (building "
                       "points only in disc and ring)")
    lidar.add_argument("--no-classes", action="store_true",
                       help="ignore the file's ASPRS classification (geometry alone)")
    lidar.add_argument("--judge", action="store_true",
                       help="score the sites against the cloud's labels and a plane fit, "
                       "beside random discs on the same cloud")
    lidar.add_argument("--tile-size", type=types.number(10, 100_000), metavar="M",
                       help="search square tiles of this edge (m), a LAS/LAZ file streamed "
                       "through them; default: 200 m tiles for clouds above 500,000 points, "
                       "LAS/LAZ files above --in-memory-points streamed")
    lidar.add_argument("--in-memory-points", type=types.integer(1, 1_000_000_000),
                       default=2_000_000, metavar="N",
                       help="LAS/LAZ files with more points are streamed through tiles "
                       "(bounded memory), default %(default)s")
    lidar.add_argument("--quiet", action="store_true", help="no progress bar")
    lidar.add_argument("--paper", action="store_true",
                       help="the paper's checks only (no off-plane, off-the-data or obstacle "
                       "cuts of the radius)")
    depth = parser.add_argument_group("depth costmap detector")
    depth.add_argument("--camera-info", metavar="FILE",
                       help="intrinsics from a ROS camera_info YAML (ost.yaml or an echoed "
                       "CameraInfo) or an OpenCV calibration file; --fx/--fy/--cx/--cy "
                       "override it")
    depth.add_argument("--depth-scale", type=types.number(0, 1e3, low_open=True),
                       metavar="M",
                       help="metres per unit of a 16-bit depth image, default 0.001 "
                       "(millimetres; TUM RGB-D and Kinect v1: 0.0002)")
    for flag in ("fx", "fy"):
        depth.add_argument(f"--{flag}", type=types.number(0, 1e6, low_open=True),
                           help="focal length (pixels)")
    for flag in ("cx", "cy"):
        depth.add_argument(f"--{flag}", type=types.number(-1e6, 1e6),
                           help="principal point (pixels)")
    depth.add_argument("--pose", help="camera pose: x,y,z,yaw (deg, looking down) or 4x4 .npy")
    depth.add_argument("--vehicle-radius", type=float, help="footprint radius (m), default 1")
    depth.add_argument("--threshold", type=float, help="decision threshold, default 0.72")
    depth.add_argument("--d-max", type=float, help="farthest valid depth (m), default 200")
    depth.add_argument("--edge-blur", type=int, metavar="PX",
                       help="Gaussian blur radius of the depth map before its gradients and "
                       "Canny (px), default 2; 0: none")
    depth.add_argument("--normal-window", type=int, metavar="PX",
                       help="window averaging depth gradients for normals (px), default 5")
    parser.set_defaults(func=run)
