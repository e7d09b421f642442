"""What report.html shows, gathered into one JSON-able dict.

Everything the page draws comes from here: the trace (decimated to at most
:data:`MAX_SAMPLES` samples), phases, every retained candidate site with the inputs of its
loss (thesis eq. 3.1, so the page can split it into its five terms for the drone position
the slider picks), banned and verified sites, the tree's timeline (from tree.btlog when the
flight wrote one), the detector's and the LSM's events, the map's terrain as a PNG, and the
world's moving obstacles (their paths, where they are along the flight and at touchdown).
"""

from __future__ import annotations

import base64
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from autonomy.report import timeline
from autonomy.report.data import FlightData, zone_record
from autonomy.report.events import _clean
from autonomy.report.plot import map_window, shaded_terrain
from behaviors.btlog import read_btlog

MAX_SAMPLES = 4000  # trace samples kept: enough for a smooth slider, small enough to load
MAX_EVENTS = 4000  # detector/LSM events kept (the rare kinds first)
MAP_PIXELS = 512  # terrain image side at most
BTLOG = "tree.btlog"

# LSM decisions in the events lane, rarest (most telling) first when some must be dropped.
_DECISION_RANK = {"banned": 0, "inserted": 1, "replaced": 2, "dropped": 3, "rejected": 4,
                  "updated": 5, "merged": 6}


def loss_terms(sites: np.ndarray, drone_xy: Sequence[float], weights: Any) -> np.ndarray:
    """(N, 5) terms of eq. 3.1 per site: w_dist d/D, w_rough roughness, w_var uncertainty,
    -w_size size/size_max, w_verAlt verAlt/D; ``sites`` columns x, y, roughness,
    uncertainty, size, verification altitude. Their row sums are the LSM's losses."""
    sites = np.asarray(sites, dtype=np.float64).reshape(-1, 6)
    d = np.hypot(sites[:, 0] - drone_xy[0], sites[:, 1] - drone_xy[1])
    size_max = sites[:, 4].max() if len(sites) else 0.0
    norm = weights.normaliser
    size_term = sites[:, 4] / size_max if size_max > 0 else np.zeros(len(sites))
    return np.column_stack([
        weights.dist * d / norm, weights.rough * sites[:, 2], weights.var * sites[:, 3],
        -weights.size * size_term, weights.ver_alt * sites[:, 5] / norm,
    ])


def _decimate(n: int, limit: int) -> np.ndarray:
    """Indices of at most ``limit`` of ``n`` samples, evenly, first and last kept."""
    if n <= limit:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, limit).round().astype(np.int64))


def _map_image(data: FlightData, window) -> dict[str, Any] | None:
    raster = shaded_terrain(data.terrain, window, MAP_PIXELS)
    if raster is None:
        return None
    rgba, extent, grid = raster
    bgr = (np.clip(rgba[::-1, :, 2::-1], 0, 1) * 255).astype(np.uint8)  # north up, BGR
    ok, png = cv2.imencode(".png", bgr)
    if not ok:
        return None
    return {"href": "data:image/png;base64," + base64.b64encode(png.tobytes()).decode(),
            "extent": extent, "low": float(grid.min()), "high": float(grid.max())}


MOVING_SAMPLES = 300  # instants the moving obstacles are placed at for the slider


def _moving(data: FlightData, end: float) -> dict[str, Any] | None:
    """The world's moving obstacles (sitl.terrain.moving): each one's kind, footprint and
    path (a closed one back to its first point), where each is at :data:`MOVING_SAMPLES`
    instants over the flight (the slider's), and at touchdown; None when nothing moves."""
    moving = getattr(data.terrain, "moving", None)
    if moving is None or len(moving) == 0:
        return None
    described = moving.describe()
    times = np.linspace(0.0, max(end, 0.0), MOVING_SAMPLES)
    snaps = [moving.at(float(t)) for t in times]
    page: dict[str, Any] = {
        "kind": [d["kind"] for d in described],
        "path": [d["path"] + (d["path"][:1] if d["closed"] else []) for d in described],
        "half_length": moving.half_length, "half_width": moving.half_width,
        "t": times,
        "x": np.round([s.x for s in snaps], 2), "y": np.round([s.y for s in snaps], 2),
        "heading": np.round([s.heading for s in snaps], 3),
        "touchdown": None,
    }
    if data.touchdown_time is not None:
        at = moving.at(float(data.touchdown_time))
        page["touchdown"] = {"t": data.touchdown_time, "x": at.x, "y": at.y,
                             "heading": at.heading}
    return page


def _events_lane(events: Sequence[dict[str, Any]]) -> list[list[Any]]:
    """``[t, kind, what, text]`` of the detector's and the LSM's events and flight notes."""
    rows = []
    for e in events:
        kind = e.get("kind")
        if kind == "lsm":
            what = e.get("decision", "")
            text = f"site {e.get('site')}" if e.get("site") is not None else ""
            if e.get("reason"):
                text += f" ({e['reason']})"
        elif kind == "perception":
            what = e.get("event", "")
            text = ", ".join(f"{k} {v}" for k, v in e.items() if k not in ("t", "kind", "event"))
        elif kind in ("flight", "link") and e.get("event") not in ("start", "end"):
            what = e.get("event", "")
            text = e.get("text") or e.get("reason") or ""
        else:
            continue
        rows.append([e["t"], kind, what, str(text)[:160]])
    if len(rows) > MAX_EVENTS:
        rank = np.array([_DECISION_RANK.get(r[2], -1) for r in rows])
        keep = np.sort(np.argsort(rank, kind="stable")[:MAX_EVENTS])
        rows = [rows[i] for i in keep]
    return rows


def tree_timeline(events: Sequence[dict[str, Any]], end: float,
                  out_dir: Path | None) -> tuple[dict[str, Any], str | None]:
    """The tree's timeline from ``out_dir/tree.btlog`` if there is one, else from the
    events; and a note when the log could not be used (the events' timeline is shown)."""
    path = out_dir / BTLOG if out_dir is not None else None
    if path is not None and path.is_file():
        try:
            log = read_btlog(path)
        except (OSError, ValueError, ET.ParseError) as exc:  # BtlogError is a ValueError
            note = f"{BTLOG} unreadable ({exc}); the timeline is from events.jsonl"
            return timeline.from_events(events, end).as_dict(), note
        last = log.transitions[-1].time + log.first_timestamp if log.transitions else end
        return timeline.from_btlog(log, max(end, last)).as_dict(), None
    return timeline.from_events(events, end).as_dict(), None


def build_page(data: FlightData, summary: dict[str, Any], events: Sequence[dict[str, Any]],
               out_dir: Path | None = None) -> dict[str, Any]:
    """The dict report.html embeds (see the module docstring)."""
    t, xyz, battery = data.trace.arrays()
    keep = _decimate(len(t), MAX_SAMPLES)
    t, xyz, battery = t[keep], xyz[keep], battery[keep]
    ground = (data.terrain.height(xyz[:, 0], xyz[:, 1]) if data.terrain is not None
              else np.zeros(len(t)))
    end = max(float(data.end_time), float(t[-1]) if len(t) else 0.0)
    window = map_window(data, xyz)
    sites = data.sites
    verified = set(data.verified_ids or ())
    props = np.array([[s.x, s.y, s.roughness, s.uncertainty, s.size, s.verification_altitude]
                      for s in sites]).reshape(-1, 6)
    weights = data.weights
    tree, tree_note = tree_timeline(events, end, out_dir)
    bans = [e for e in events if e.get("kind") == "lsm" and e.get("decision") == "banned"]
    page = {
        "summary": summary,
        "end": end,
        "trace": {"t": t, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "battery": battery,
                  "ground": ground},
        "phases": [[p_t, p] for p_t, p in data.trace.phases],
        "sites": [
            {"id": s.id, "x": s.x, "y": s.y, "z": s.z, "roughness": s.roughness,
             "uncertainty": s.uncertainty, "size": s.size,
             "verification_altitude": s.verification_altitude, "first_seen": s.first_seen,
             "last_seen": s.last_seen, "detections": s.detection_count, "source": s.source,
             "loss": s.loss, "verified": s.id in verified}
            for s in sites
        ],
        "weights": None if weights is None else {
            "dist": weights.dist, "rough": weights.rough, "var": weights.var,
            "size": weights.size, "ver_alt": weights.ver_alt, "normaliser": weights.normaliser,
        },
        "size_max": float(props[:, 4].max()) if len(props) else 0.0,
        "drone_end": [float(xyz[-1, 0]), float(xyz[-1, 1])] if len(xyz) else [0.0, 0.0],
        "bans": [{"x": x, "y": y, "r": r, "t": bans[i]["t"] if i < len(bans) else None,
                  "site": bans[i].get("site") if i < len(bans) else None}
                 for i, (x, y, r) in enumerate(data.ban_zones)],
        "geofence": None if data.geofence is None else [list(v) for v in data.geofence],
        "chosen": None if data.chosen_site is None else data.chosen_site.id,
        "touchdown": None if data.touchdown is None else {
            "x": data.touchdown[0], "y": data.touchdown[1], "z": data.touchdown[2],
            "t": data.touchdown_time, "safe": data.touchdown_safe},
        "window": window,
        "map": _map_image(data, window),
        "tree": tree,
        "tree_note": tree_note,
        "events": _events_lane(events),
        "moving": _moving(data, end),
    }
    if data.geofence_exclude:  # only then: pages of flights without no-fly zones unchanged
        page["geofence_exclude"] = [zone_record(zone) for zone in data.geofence_exclude]
    return _clean(page)
