"""report.png: the flight on a map of the terrain, and its altitude over time by phase."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from autonomy.report.data import FlightData
from lsm.area import NoFlyCircle

# matplotlib is imported where a function draws: a flight or a campaign worker that writes
# no report.png does not pay for pyplot at start-up.

_MAX_PIXELS = 600  # map raster side after striding the terrain grid


@contextmanager
def quiet_missing_glyphs() -> Iterator[None]:
    """A name in a script the font lacks (CJK, emoji) is drawn as boxes: no reason to print
    matplotlib's warning about each glyph on the user's terminal (usable as a decorator)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", r"Glyph \d+ .* missing from font", UserWarning)
        yield


@functools.cache
def _ground_colours():
    """Land colours only (gist_earth without its sea blues), low to high."""
    import matplotlib
    from matplotlib.colors import ListedColormap

    return ListedColormap(matplotlib.colormaps["gist_earth"](np.linspace(0.35, 0.95, 256)))


def map_window(data: FlightData, xyz: np.ndarray) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) around the trajectory and the sites, 20 m margin."""
    pts = [xyz[:, :2]] if len(xyz) else [np.zeros((1, 2))]
    pts.append(np.array([[s.x, s.y] for s in data.sites]).reshape(-1, 2))
    pts.append(np.array([[x, y] for x, y, _ in data.ban_zones]).reshape(-1, 2))
    if data.geofence is not None:
        pts.append(np.asarray(data.geofence, dtype=np.float64).reshape(-1, 2))
    for zone in data.geofence_exclude:
        if isinstance(zone, NoFlyCircle):  # its bounding box
            pts.append(np.array([[zone.x - zone.radius, zone.y - zone.radius],
                                 [zone.x + zone.radius, zone.y + zone.radius]]))
        else:
            pts.append(np.asarray(zone, dtype=np.float64).reshape(-1, 2))
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0) - 20.0, allp.max(axis=0) + 20.0
    side = max(hi - lo)  # square window keeps the map readable
    mid = (lo + hi) / 2
    return (mid[0] - side / 2, mid[0] + side / 2, mid[1] - side / 2, mid[1] + side / 2)


def shaded_terrain(terrain, window, max_pixels: int = _MAX_PIXELS):
    """The terrain inside ``window`` (xmin, xmax, ymin, ymax) hill-shaded: ((h, w, 4) RGBA
    floats in [0, 1], row 0 south, (xmin, xmax, ymin, ymax) of the cell centres, the
    strided height grid), or None when there is no terrain there."""
    if terrain is None:
        return None
    xs, ys = terrain.coordinates()
    j0, j1 = np.searchsorted(xs, [window[0], window[1]])
    i0, i1 = np.searchsorted(ys, [window[2], window[3]])
    if j1 - j0 < 2 or i1 - i0 < 2:
        return None
    # The smallest stride that keeps both sides within max_pixels (a floor division let a
    # side reach nearly twice that, and the shading's cost with its area).
    step = max(1, -(-max(i1 - i0, j1 - j0) // max_pixels))
    grid = np.asarray(terrain.grid[i0:i1:step, j0:j1:step], dtype=np.float64)
    lo, hi = float(grid.min()), float(grid.max())
    from matplotlib.colors import LightSource

    shaded = LightSource(azdeg=315, altdeg=45).shade(
        grid, cmap=_ground_colours(), blend_mode="overlay",
        vmin=lo - 0.5, vmax=max(hi, lo + 5.0),  # a flat world is a plain colour, not black
        vert_exag=1.0, dx=terrain.cell_size * step, dy=terrain.cell_size * step,
    )
    extent = (xs[j0], xs[j0 + (grid.shape[1] - 1) * step], ys[i0],
              ys[i0 + (grid.shape[0] - 1) * step])
    return shaded, tuple(float(v) for v in extent), grid


def _draw_terrain(ax, terrain, window) -> None:
    raster = shaded_terrain(terrain, window)
    if raster is None:
        ax.set_facecolor("#d9d2c3")
        return
    shaded, extent, grid = raster
    ax.imshow(shaded, origin="lower", extent=extent, interpolation="bilinear")
    ax.contour(
        np.linspace(extent[0], extent[1], grid.shape[1]),
        np.linspace(extent[2], extent[3], grid.shape[0]),
        grid, levels=10, colors="k", linewidths=0.3, alpha=0.4,
    )


def plot_moving(ax, moving) -> None:
    """Each moving obstacle's path, and where it is at t = 0 (sitl.terrain.moving)."""
    if moving is None:
        return
    colours = {"person": "tab:orange", "vehicle": "tab:purple"}
    start = moving.at(0.0)
    labelled = set()
    for k, obstacle in enumerate(moving.describe()):
        kind = obstacle["kind"]
        path = np.asarray(obstacle["path"] + (obstacle["path"][:1] if obstacle["closed"]
                                              else []))
        label = None if kind in labelled else f"{kind} path (dot: t = 0)"
        labelled.add(kind)
        ax.plot(path[:, 0], path[:, 1], color=colours[kind], lw=1.2, label=label)
        ax.plot([start.x[k]], [start.y[k]], "o", color=colours[kind], markersize=4)


@quiet_missing_glyphs()
def write_report_png(data: FlightData, path: Path, *, outcome: str = "") -> None:
    """Draw the two-panel flight report into ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no display
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    phase_colours = plt.get_cmap("tab20").colors
    t, xyz, _ = data.trace.arrays()
    fig, (ax_map, ax_alt) = plt.subplots(
        1, 2, figsize=(15, 6.5), gridspec_kw={"width_ratios": [1, 1.3]}
    )
    window = map_window(data, xyz)
    _draw_terrain(ax_map, data.terrain, window)
    if len(xyz):
        ax_map.plot(xyz[:, 0], xyz[:, 1], "-", color="white", lw=2.2, alpha=0.8)
        ax_map.plot(xyz[:, 0], xyz[:, 1], "-", color="tab:blue", lw=1.2, label="trajectory")
        ax_map.plot(*xyz[0, :2], "o", color="tab:blue", ms=6, label="home")
    if data.geofence is not None:
        from matplotlib.patches import Polygon

        ax_map.add_patch(Polygon(data.geofence, closed=True, fill=False, ec="tab:green",
                                 lw=1.8, ls="-.", zorder=3, label="geofence"))
    for i, zone in enumerate(data.geofence_exclude):
        from matplotlib.patches import Polygon

        style = {"fill": False, "ec": "tab:red", "hatch": "///", "lw": 1.5, "zorder": 3,
                 "label": "no-fly zone" if i == 0 else None}
        ax_map.add_patch(Circle((zone.x, zone.y), zone.radius, **style)
                         if isinstance(zone, NoFlyCircle) else Polygon(zone, closed=True, **style))
    if data.sites:
        sites = np.array([(s.x, s.y, s.loss) for s in data.sites])
        sc = ax_map.scatter(
            sites[:, 0], sites[:, 1], c=sites[:, 2], cmap="plasma_r", s=40,
            edgecolors="k", linewidths=0.5, zorder=4, label="candidate sites",
        )
        fig.colorbar(sc, ax=ax_map, shrink=0.8, label="site loss (lower is better)")
    for i, (x, y, r) in enumerate(data.ban_zones):
        ax_map.add_patch(Circle((x, y), r, fill=False, ec="tab:red", ls="--", lw=1, zorder=4))
        ax_map.plot(x, y, "x", color="tab:red", ms=9, mew=2, zorder=5,
                    label="banned site" if i == 0 else None)
    if data.chosen_site is not None:
        ax_map.plot(data.chosen_site.x, data.chosen_site.y, "*", color="gold", ms=18,
                    mec="k", zorder=6, label="chosen site")
    plot_moving(ax_map, getattr(data.terrain, "moving", None))
    if data.first_collision is not None:
        x, y, _ = data.first_collision["position"]
        ax_map.plot(x, y, "X", color="red", ms=12, mec="k", zorder=8,
                    label=f"first collision ({data.first_collision['obstacle']})")
    if data.touchdown is not None:
        colour = {True: "lime", False: "red", None: "white"}[data.touchdown_safe]
        ax_map.plot(data.touchdown[0], data.touchdown[1], "v", color=colour, ms=10, mec="k",
                    zorder=7, label="touchdown")
    ax_map.set_xlim(window[0], window[1])
    ax_map.set_ylim(window[2], window[3])
    ax_map.set_aspect("equal")
    ax_map.set_xlabel("east (m)")
    ax_map.set_ylabel("north (m)")
    if ax_map.get_legend_handles_labels()[0]:  # nothing to show before the vehicle was heard
        ax_map.legend(loc="upper left", fontsize=8, framealpha=0.8)
    ax_map.set_title(f"{data.mission_name or 'mission'} - {data.world} world")

    if len(t):
        ax_alt.plot(t, xyz[:, 2], color="tab:blue", lw=1.5, label="altitude (ENU z)")
        if data.terrain is not None:
            ground = data.terrain.height(xyz[:, 0], xyz[:, 1])
            ax_alt.fill_between(t, np.minimum(ground, xyz[:, 2]).min() - 1, ground,
                                color="tan", alpha=0.6, label="ground below")
        # No phases at all when the flight never got past waiting for the vehicle.
        ends = [start for start, _ in data.trace.phases[1:]] + [float(t[-1])] * bool(
            data.trace.phases)
        names = sorted({p for _, p in data.trace.phases})
        seen: set[str] = set()
        for (start, phase), end in zip(data.trace.phases, ends, strict=True):
            colour = phase_colours[names.index(phase) % len(phase_colours)]
            ax_alt.axvspan(start, end, color=colour, alpha=0.35,
                           label=None if phase in seen else phase)
            seen.add(phase)
    ax_alt.set_xlabel("time (s)")
    ax_alt.set_ylabel("altitude above home (m)")
    if ax_alt.get_legend_handles_labels()[0]:
        ax_alt.legend(loc="upper right", fontsize=8, ncol=2, framealpha=0.8)
    ax_alt.set_title(f"outcome: {outcome}" if outcome else "altitude")
    ax_alt.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
