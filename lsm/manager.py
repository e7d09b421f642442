"""The Landing Site Manager (DESIGN.md section 4, thesis section 3.2.2).

Detectors submit :class:`~lsm.records.SiteObservation` records from any thread. The manager
keeps at most ``capacity`` :class:`~lsm.records.LandingSite` records, held in a max-heap on
the loss of eq. 3.1 so that the worst site is swapped out in O(log n) when a better one
arrives. Site properties live in a structure of arrays (one slot per site), so ranking and
re-keying are vectorised over all sites.

The loss depends on the drone position and on the largest retained size, so heap keys are
recomputed (an O(n) re-heapify) when the drone has moved more than ``rekey_distance`` or the
largest size changed. :meth:`LandingSiteManager.ranked` always computes exact losses at the
given drone position.

Longer than 500 lines because the heap, the structure of arrays and the spatial hash are one
data structure kept consistent under one lock; the loss and the records live beside it.
"""

from __future__ import annotations

import heapq
import math
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from operator import attrgetter
from typing import overload

import numpy as np
from scipy.spatial import cKDTree

from lsm.area import OperatingArea
from lsm.loss import site_loss, site_loss_scalar
from lsm.records import LandingSite, SiteObservation
from lsm.settings import LossWeights, LsmSettings

# Why an observation was rejected; each has its own counter ``rejected_<reason>``.
REJECT_REASONS = (
    "malformed",  # not a SiteObservation, or fields that are not numbers
    "non_finite",  # NaN or inf in any numeric field
    "position_out_of_range",  # x, y or z farther than 10,000 km from home
    "roughness_out_of_range",  # roughness outside [0, 1]
    "uncertainty_out_of_range",  # uncertainty outside [0, 1]
    "negative_size",
    "negative_observation_altitude",
    "banned_zone",  # inside the zone of a banned site
    "beyond_max_distance",  # farther than max_distance from the drone
    "worse_than_worst",  # manager full and the new site is not better than its worst
)
OUTSIDE_GEOFENCE = "outside_geofence"
"""Rejection reason of sites outside the operating area (or within its margin of the edge);
counted (``rejected_outside_geofence``) only when the manager has an area."""

_OBS_FIELDS = attrgetter(
    "x", "y", "z", "roughness", "uncertainty", "size", "obstacle_altitude",
    "observation_altitude", "timestamp",
)
_BATCH = 1024  # observations processed per lock acquisition by the worker
_MAX_COORDINATE = 1e7  # m: farther from home than any mission's local frame reaches
_KEY_STRIDE = 1 << 32  # spatial-hash key = ix * stride + iy (|iy| < 2**31 cells)
_SMALL_BATCH = 32  # rows below which per-row Python beats numpy's per-call cost
# Bounds of the (n, 9) observation values that pass every range check of _validate: a row
# is finite and in range iff every value lies within them (unbounded fields end at the
# largest double, so inf and NaN fail too).
_BIG = float(np.finfo(np.float64).max)
_LOWEST = np.array([-_MAX_COORDINATE] * 3 + [0.0, 0.0, 0.0, -_BIG, 0.0, -_BIG])
_HIGHEST = np.array([_MAX_COORDINATE] * 3 + [1.0, 1.0, _BIG, _BIG, _BIG, _BIG])
_TREE_K = 2  # nearest snapshot entries examined per observation
_FEW_SITES = 8  # snapshots this small are examined whole instead of queried (see below)
# Snapshots of at most this many sites are searched by one numpy distance matrix per batch
# (the k-d tree only for the rows its answer could differ on; see _snapshot_candidates).
_BRUTE_SITES = 256
# Relative gap under which the 2nd and 3rd nearest snapshot entries count as tied (far above
# the rounding of a k-d tree's distances, far below any real difference).
_TIE_GAP = 1e-9
_SNAPSHOT_MIN = 64  # changed sites tolerated in the hash before the k-d tree is rebuilt


@dataclass(frozen=True, slots=True)
class Decision:
    """One decision of the manager, for the flight's event log.

    ``kind`` is one of inserted, merged, updated, replaced, rejected, dropped, banned;
    ``reason`` says why for rejected/dropped/replaced records.
    """

    kind: str
    site_id: int | None
    reason: str
    timestamp: float


def _site_at(c: dict[str, np.ndarray], i: int, source: str, loss: float) -> LandingSite:
    """The :class:`LandingSite` of row ``i`` of the columns ``c`` (see
    ``LandingSiteManager._columns``)."""
    p = c["position"][i]
    return LandingSite(
        id=int(c["id"][i]), x=float(p[0]), y=float(p[1]), z=float(p[2]),
        roughness=float(c["roughness"][i]), uncertainty=float(c["uncertainty"][i]),
        size=float(c["size"][i]), obstacle_altitude=float(c["obstacle_altitude"][i]),
        verification_altitude=float(c["verification_altitude"][i]),
        first_seen=float(c["first_seen"][i]), last_seen=float(c["last_seen"][i]),
        detection_count=int(c["detection_count"][i]), source=source, loss=loss,
    )


class RankedSites(Sequence[LandingSite]):
    """Retained sites in ascending loss: a sorted copy taken under the manager's lock.

    Indexing builds :class:`LandingSite` records on demand, so ranking 10,000 sites costs
    array work only. ``ids``, ``losses`` and ``verification_altitudes`` are the sorted
    arrays.
    """

    def __init__(self, columns: dict[str, np.ndarray], sources: list[str]) -> None:
        self._c = columns
        self._sources = sources
        self.ids: np.ndarray = columns["id"]
        self.losses: np.ndarray = columns["loss"]
        self.verification_altitudes: np.ndarray = columns["verification_altitude"]

    def __len__(self) -> int:
        return len(self.ids)

    def _site(self, i: int) -> LandingSite:
        return _site_at(self._c, i, self._sources[i], float(self._c["loss"][i]))

    @overload
    def __getitem__(self, index: int) -> LandingSite: ...

    @overload
    def __getitem__(self, index: slice) -> list[LandingSite]: ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._site(i) for i in range(len(self))[index]]
        n = len(self)
        if index < 0:
            index += n
        if not 0 <= index < n:
            raise IndexError("ranked site index out of range")
        return self._site(index)

    def __iter__(self) -> Iterator[LandingSite]:
        return (self._site(i) for i in range(len(self)))


@dataclass(frozen=True)
class LsmSnapshot:
    """A consistent copy of the manager's state at one instant."""

    sites: RankedSites
    counters: dict[str, int]
    ban_zones: list[tuple[float, float, float]]
    drone_position: tuple[float, float, float] | None


class LandingSiteManager:
    """Bounded, ranked store of landing sites fed by detectors from any thread.

    Args:
        settings: capacity, match/ban radii, max distance, verification altitude.
        weights: loss weights and the distance normaliser D.
        on_decision: called (under the manager's lock) with every :class:`Decision`;
            keep it cheap. None costs nothing.
    """

    def __init__(
        self,
        settings: LsmSettings | None = None,
        weights: LossWeights | None = None,
        on_decision: Callable[[Decision], None] | None = None,
    ) -> None:
        self.settings = settings or LsmSettings()
        self.weights = weights or LossWeights()
        self._on_decision = on_decision
        cap = self.settings.capacity
        self._pos = np.zeros((cap, 3))
        self._rough = np.zeros(cap)
        self._unc = np.zeros(cap)
        self._size = np.zeros(cap)
        self._obst = np.zeros(cap)
        self._veralt = np.zeros(cap)
        self._first = np.zeros(cap)
        self._last = np.zeros(cap)
        self._count = np.zeros(cap, dtype=np.int64)
        self._ids = np.full(cap, -1, dtype=np.int64)
        self._sources = np.full(cap, "", dtype=object)
        self._xy: list[tuple[float, float]] = [(0.0, 0.0)] * cap  # fast scalar access
        self._version: list[int] = [0] * cap  # heap entries of older versions are stale
        self._free: list[int] = list(range(cap - 1, -1, -1))
        self._slot_of: dict[int, int] = {}
        # Redetection lookup: a snapshot of site positions (and a k-d tree over it, built
        # when first queried), searched for a whole batch at once, plus a spatial hash of the
        # sites inserted or moved since that snapshot (their snapshot entries are stale: the
        # slot version changed). Hash cells are 2 match radii wide, so a match circle
        # overlaps at most 2 x 2 cells.
        self._tree: cKDTree | None = None
        self._snap_xy = np.zeros((0, 2))
        self._snap_slots = np.zeros(0, dtype=np.int64)
        self._snap_versions = np.zeros(0, dtype=np.int64)
        self._snap_lists: tuple[list[int], list[int]] | None = None  # the two, as lists
        self._cells: dict[int, list[int]] = {}
        self._dirty_key: list[int | None] = [None] * cap
        self._dirty_count = 0
        self._cell_size = 2.0 * self.settings.match_radius
        # Redetections that only bump last_seen/count are applied in bulk (np.add.at).
        self._pending_slots: list[int] = []
        self._pending_times: list[float] = []
        self._pending_set: set[int] = set()
        # Max-heap as a min-heap of (-loss, -id, version, slot): ties evict the newest site.
        self._heap: list[tuple[float, int, int, int]] = []
        self._next_id = 1
        self._size_max = 0.0
        self._drone: tuple[float, float, float] | None = None
        self._keyed_at: tuple[float, float] | None = None  # drone xy when keys were computed
        self._checked_at: tuple[float, float] | None = None  # drone xy of the last far check
        self._keyed_size_max = 0.0
        self._bans = np.zeros((0, 3))  # rows of (x, y, radius)
        self._queue: deque = deque()
        self._wake = threading.Event()
        self._lock = threading.Lock()
        self._worker: threading.Thread | None = None
        self._stopping = False
        self._counts = dict.fromkeys(
            ("received", "inserted", "merged", "updated", "replaced", "dropped", "banned",
             "banned_rejected"), 0)
        self._rejected = dict.fromkeys(REJECT_REASONS, 0)
        self._area: OperatingArea | None = None

    def set_area(self, area: OperatingArea | None) -> None:
        """Reject later observations outside ``area`` (an inclusion geofence, with its
        margin); set it before the first observation arrives. None: no area."""
        with self._lock:
            self._area = area
            if area is not None:
                self._rejected.setdefault(OUTSIDE_GEOFENCE, 0)

    @property
    def area(self) -> OperatingArea | None:
        """The operating area observations must lie in, or None."""
        return self._area

    # ------------------------------------------------------------------ producers
    def submit(self, observation: SiteObservation) -> None:
        """Queue one observation. Safe from any thread; never raises, never blocks long."""
        self._queue.append(observation)
        if not self._wake.is_set():
            self._wake.set()

    def submit_many(self, observations: Iterable[SiteObservation]) -> None:
        """Queue several observations at once (one wake-up for the worker)."""
        self._queue.extend(observations)
        if not self._wake.is_set():
            self._wake.set()

    def process_pending(self) -> int:
        """Drain the queue in the calling thread; returns how many observations were handled.

        The lockstep runner calls this after each perception update, so the outcome of a
        simulated flight does not depend on thread scheduling.
        """
        done = 0
        while True:
            batch = self._take_batch()
            if not batch:
                return done
            with self._lock:
                self._process_batch(batch)
            done += len(batch)

    @property
    def queued(self) -> int:
        """Observations submitted but not yet processed."""
        return len(self._queue)

    # ------------------------------------------------------------------ worker thread
    def start(self) -> LandingSiteManager:
        """Start the worker thread that drains the queue (live mode)."""
        if self._worker is None or not self._worker.is_alive():
            self._stopping = False
            self._worker = threading.Thread(target=self._run, name="lsm-worker", daemon=True)
            self._worker.start()
        return self

    def stop(self, drain: bool = True) -> None:
        """Stop the worker; with ``drain`` the queue is processed first, so nothing is lost."""
        self._stopping = True
        self._wake.set()
        if self._worker is not None:
            self._worker.join()
            self._worker = None
        if drain:
            self.process_pending()

    def __enter__(self) -> LandingSiteManager:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _run(self) -> None:
        while not self._stopping:
            batch = self._take_batch()
            if batch:
                with self._lock:
                    self._process_batch(batch)
                continue
            self._wake.clear()
            if not self._queue:
                # An event wait, not a clock: the worker sleeps until submit() wakes it.
                self._wake.wait(0.05)

    def _take_batch(self) -> list:
        q = self._queue
        n = min(len(q), _BATCH)
        pop = q.popleft
        return [pop() for _ in range(n)]

    # ------------------------------------------------------------------ drone position
    def set_drone_position(self, position: Sequence[float]) -> None:
        """Tell the manager where the drone is (ENU m). Sites beyond max_distance fall off."""
        x, y, z = float(position[0]), float(position[1]), float(position[2])
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return
        p = (x, y, z)
        with self._lock:
            self._drone = p
            self._maybe_rekey()

    @property
    def drone_position(self) -> tuple[float, float, float] | None:
        return self._drone

    # ------------------------------------------------------------------ reads
    def __len__(self) -> int:
        return len(self._slot_of)

    def ranked(self, drone_position: Sequence[float] | None = None) -> RankedSites:
        """All retained sites in ascending loss at ``drone_position`` (a sorted copy).

        Given a position, it first becomes the drone position (sites beyond max_distance
        fall off, as in :meth:`set_drone_position`).
        """
        if drone_position is not None:
            self.set_drone_position(drone_position)
        with self._lock:
            return self._ranked_locked()

    def best(self, drone_position: Sequence[float] | None = None) -> LandingSite | None:
        """The lowest-loss site, or None when no site is retained."""
        ranking = self.ranked(drone_position)
        return ranking[0] if len(ranking) else None

    def best_verified(self, drone_position: Sequence[float] | None = None) -> LandingSite | None:
        """The lowest-loss verified site (:meth:`is_verified`), or None when no retained
        site has been (re-)detected from the verification altitude."""
        ranking = self.ranked(drone_position)
        verified = np.flatnonzero(ranking.verification_altitudes <= self._verified_below)
        return ranking[int(verified[0])] if len(verified) else None

    def get(self, site_id: int) -> LandingSite | None:
        """The retained site with this id (its loss at the current drone position), or None."""
        with self._lock:
            slot = self._slot_of.get(int(site_id))
            if slot is None:
                return None
            # The loss as a ranking computes it (the scalar form makes the same doubles);
            # the rest read at the slot of the whole columns (no eleven one-element copies).
            loss = self._loss_of_slot(slot)
            return _site_at(self._columns(slice(None), None), slot, self._sources[slot], loss)

    def is_verified(self, site: LandingSite) -> bool:
        """True when the site was (re-)detected at or below the verification altitude
        (plus the tolerance)."""
        return site.verification_altitude <= self._verified_below

    @property
    def _verified_below(self) -> float:
        """The highest verification altitude (m) that counts as verified."""
        return self.settings.verification_altitude + self.settings.verification_tolerance

    def counters(self) -> dict[str, int]:
        """Counts of what happened to observations and sites.

        ``received == inserted + merged + rejected`` once the queue is drained;
        ``rejected_<reason>`` break the rejections down (``banned_rejected`` equals
        ``rejected_banned_zone``).
        """
        with self._lock:
            return self._counters_locked()

    def ban_zones(self) -> list[tuple[float, float, float]]:
        """Ban zones as (x, y, radius) in ENU metres."""
        with self._lock:
            return [tuple(float(v) for v in row) for row in self._bans]

    def snapshot(self) -> LsmSnapshot:
        """Ranked sites, counters and ban zones taken together under one lock."""
        with self._lock:
            return LsmSnapshot(
                sites=self._ranked_locked(),
                counters=self._counters_locked(),
                ban_zones=[tuple(float(v) for v in row) for row in self._bans],
                drone_position=self._drone,
            )

    # ------------------------------------------------------------------ bans
    def ban(self, site_id: int) -> bool:
        """Remove a site and reject later observations within ``ban_radius`` of it.

        Returns False when no site has this id.
        """
        with self._lock:
            slot = self._slot_of.get(int(site_id))
            if slot is None:
                return False
            x, y = self._xy[slot]
            self._bans = np.vstack([self._bans, [x, y, self.settings.ban_radius]])
            t = float(self._last[slot])
            self._remove(slot)
            self._counts["banned"] += 1
            self._decide("banned", int(site_id), "verification failed or operator ban", t)
            return True

    # ------------------------------------------------------------------ internals
    def _decide(self, kind: str, site_id: int | None, reason: str, t: float) -> None:
        if self._on_decision is not None:
            self._on_decision(Decision(kind, site_id, reason, t))

    def _reject(self, reason: str, t: float) -> None:
        self._rejected[reason] += 1
        if reason == "banned_zone":
            self._counts["banned_rejected"] += 1
        self._decide("rejected", None, reason, t)

    def _counters_locked(self) -> dict[str, int]:
        out = dict(self._counts)
        out["rejected"] = sum(self._rejected.values())
        out.update({f"rejected_{k}": v for k, v in self._rejected.items()})
        out["retained"] = len(self._slot_of)
        out["queued"] = len(self._queue)
        return out

    def _active_slots(self) -> np.ndarray:
        return np.flatnonzero(self._ids >= 0)

    def _flush_redetections(self) -> None:
        """Apply the queued last_seen/count bumps of plain redetections, vectorised."""
        if self._pending_slots:
            if len(self._pending_slots) < _SMALL_BATCH:
                # A few: row by row (ufunc.at's set-up costs more than these additions and
                # comparisons; the times are finite, so max is numpy's maximum).
                count, last = self._count, self._last
                for slot, t in zip(self._pending_slots, self._pending_times, strict=True):
                    count[slot] += 1
                    if t > last[slot]:
                        last[slot] = t
            else:
                slots = np.array(self._pending_slots, dtype=np.int64)
                np.add.at(self._count, slots, 1)
                np.maximum.at(self._last, slots, np.array(self._pending_times))
            self._pending_slots.clear()
            self._pending_times.clear()
            self._pending_set.clear()

    def _losses(self, slots: np.ndarray) -> np.ndarray:
        if self._drone is None:
            dist = np.zeros(len(slots))
        else:
            d = self._pos[slots, :2] - np.asarray(self._drone[:2])
            dist = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
        return site_loss(dist, self._rough[slots], self._unc[slots], self._size[slots],
                         self._veralt[slots], self._size_max, self.weights)

    def _columns(self, slots: np.ndarray, loss: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "id": self._ids[slots], "position": self._pos[slots],
            "roughness": self._rough[slots], "uncertainty": self._unc[slots],
            "size": self._size[slots], "obstacle_altitude": self._obst[slots],
            "verification_altitude": self._veralt[slots], "first_seen": self._first[slots],
            "last_seen": self._last[slots], "detection_count": self._count[slots],
            "loss": loss,
        }

    def _ranked_locked(self) -> RankedSites:
        slots = self._active_slots()
        loss = self._losses(slots)
        # Ties broken by id so rankings are reproducible.
        order = np.lexsort((self._ids[slots], loss))
        slots = slots[order]
        return RankedSites(self._columns(slots, loss[order]), self._sources[slots].tolist())

    def _cell_key(self, x: float, y: float) -> int:
        c = self._cell_size
        return math.floor(x / c) * _KEY_STRIDE + math.floor(y / c)

    def _match_keys(self, xy: np.ndarray) -> list[int]:
        """Key of the lower-left of the 2 x 2 cells each match circle can overlap, for a
        large batch at once (the same floor of the same quotient as the per-row form in
        _nearest_within_match)."""
        r, c = self.settings.match_radius, self._cell_size
        with np.errstate(invalid="ignore"):  # rows with NaN are rejected anyway
            ix = np.floor((xy[:, 0] - r) / c).astype(np.int64)
            iy = np.floor((xy[:, 1] - r) / c).astype(np.int64)
        return (ix * _KEY_STRIDE + iy).tolist()

    def _snapshot(self) -> None:
        """Snapshot every site's position (its k-d tree is built when first queried) and
        empty the hash of changed sites."""
        slots = self._active_slots()
        self._snap_xy = self._pos[slots, :2]
        self._tree = None
        self._snap_slots = slots
        self._snap_versions = np.array(self._version, dtype=np.int64)[slots]
        self._snap_lists = None
        self._cells.clear()
        self._dirty_key = [None] * self.settings.capacity
        self._dirty_count = 0

    def _snapshot_candidates(self, vals: np.ndarray, accepted: list[int]
                             ) -> tuple[list[int], list[int], list[int], list[int], list[bool]]:
        """The snapshot entries each row of the batch examines in
        :meth:`_nearest_within_match`: flat lists of slots and snapshot versions, and per
        row the range [lo, hi) of its entries and whether they are the k-d tree's _TREE_K
        nearest (slot -1 past the last).

        The lookup's rule (kept since it was a k-d tree query per row): examine the
        _TREE_K nearest snapshot entries within the match radius, all of them if the
        snapshot holds at most _FEW_SITES; all examined stale -> search every site. That
        equals the nearest site within the radius (ties to the smaller id) among the
        snapshot's unchanged entries and the hash, unless the _TREE_K-th and the next
        nearest entry are tied, where the tree's pick among the tied decides. So small
        snapshots compute every row's distances at once (the same doubles as the per-row
        test) and examine the entries within a padded radius; rows with such a tie, and
        large snapshots, take the tree's _TREE_K entries. (Flat lists: per-row lists of a
        1,024-row batch would wake the garbage collector.)"""
        n_rows = len(vals)
        n = len(self._snap_slots)
        if not n or not accepted:
            return [], [], [0] * n_rows, [0] * n_rows, [False] * n_rows
        if n > _BRUTE_SITES and n > _FEW_SITES:
            lo = self._rows_at(accepted, n_rows, np.arange(0, len(accepted) * _TREE_K, _TREE_K))
            slots, versions = self._tree_candidates(vals, accepted)
            return slots, versions, lo, [i + _TREE_K for i in lo], [True] * n_rows
        obs = vals[accepted] if len(accepted) < n_rows else vals
        snap = self._snap_xy
        dx = snap[None, :, 0] - obs[:, None, 0]
        dy = snap[None, :, 1] - obs[:, None, 1]
        d2 = dx * dx + dy * dy
        # Padded well beyond the tree's bound: every entry the tree could return is in.
        reach = self.settings.match_radius * (1 + 1e-6) + 1e-9
        rows, cols = np.nonzero(d2 <= reach * reach)
        counts = np.bincount(rows, minlength=len(accepted))
        stops = np.cumsum(counts)
        lo = self._rows_at(accepted, n_rows, stops - counts)
        hi = self._rows_at(accepted, n_rows, stops)
        queried = [False] * n_rows
        slots = self._snap_slots[cols].tolist()
        versions = self._snap_versions[cols].tolist()
        if n > _FEW_SITES:
            crowded = np.flatnonzero(counts > _TREE_K).tolist()
            if crowded:
                tied = []
                for row in crowded:
                    i = accepted[row]
                    ranked = sorted(d2[row, cols[lo[i]:hi[i]]].tolist())
                    if ranked[_TREE_K] - ranked[_TREE_K - 1] <= (
                            _TIE_GAP * ranked[_TREE_K] + 1e-12):
                        tied.append(i)
                if tied:
                    tree_slots, tree_versions = self._tree_candidates(vals, tied)
                    for j, i in enumerate(tied):
                        lo[i] = len(slots) + j * _TREE_K
                        hi[i] = lo[i] + _TREE_K
                        queried[i] = True
                    slots += tree_slots
                    versions += tree_versions
        return slots, versions, lo, hi, queried

    @staticmethod
    def _rows_at(accepted: list[int], n_rows: int, values: np.ndarray) -> list[int]:
        """``values`` of the accepted rows, as a list over every row of the batch (0 at
        rejected rows, which are never looked up)."""
        if len(accepted) == n_rows:
            return values.tolist()
        out = np.zeros(n_rows, dtype=np.int64)
        out[accepted] = values
        return out.tolist()

    def _tree_candidates(self, vals: np.ndarray, rows: list[int]
                         ) -> tuple[list[int], list[int]]:
        """The _TREE_K nearest snapshot entries within the match radius of these rows from
        the k-d tree, _TREE_K per row (slot -1 where there are fewer): flat slots, versions."""
        if self._tree is None:
            self._tree = cKDTree(self._snap_xy)
        n = len(self._snap_slots)
        # The bound is strict and the tree's distances are rounded: pad it; the exact
        # d2 <= r2 test in _nearest_within_match decides.
        bound = self.settings.match_radius * (1 + 1e-9) + 1e-12
        _, idx = self._tree.query(vals[rows, :2], k=_TREE_K, distance_upper_bound=bound)
        found = idx < n
        idx = np.minimum(idx, n - 1)
        slots = np.where(found, self._snap_slots[idx], -1)
        versions = np.where(found, self._snap_versions[idx], -1)
        return slots.ravel().tolist(), versions.ravel().tolist()

    def _nearest_within_match(self, x: float, y: float, slots: list[int],
                              versions: list[int], lo: int, hi: int, queried: bool,
                              key: int | None = None) -> int | None:
        """The retained site within match_radius nearest to (x, y); ties go to the older
        (smaller id) site. None when there is none. The row's snapshot entries are
        ``slots[lo:hi]`` (:meth:`_snapshot_candidates`); the sites changed since the
        snapshot are in the hash, around ``key`` (:meth:`_match_keys`; None: computed
        here)."""
        r = self.settings.match_radius
        best, best_d2 = None, r * r
        xy = self._xy
        ids = self._ids
        if lo < hi:
            version = self._version
            any_valid = False
            for j in range(lo, hi):
                slot = slots[j]
                if slot < 0:
                    break
                if version[slot] != versions[j]:
                    continue  # changed since the snapshot: in the hash if still retained
                any_valid = True
                sx, sy = xy[slot]
                d2 = (sx - x) * (sx - x) + (sy - y) * (sy - y)
                if d2 < best_d2 or (d2 == best_d2 and (best is None or ids[slot] < ids[best])):
                    best, best_d2 = slot, d2
            else:
                if queried and not any_valid:
                    # Every near snapshot entry is stale and more may lie beyond: examine
                    # every one within the radius (with the hash below, every site there).
                    best, best_d2 = self._nearest_in_ball(x, y)
        cells = self._cells
        if not cells:
            return best
        if key is None:
            c = self._cell_size
            key = math.floor((x - r) / c) * _KEY_STRIDE + math.floor((y - r) / c)
        for k in (key, key + 1, key + _KEY_STRIDE, key + _KEY_STRIDE + 1):
            members = cells.get(k)
            if not members:
                continue
            for slot in members:
                sx, sy = xy[slot]
                d2 = (sx - x) * (sx - x) + (sy - y) * (sy - y)
                if d2 < best_d2 or (d2 == best_d2 and (best is None or ids[slot] < ids[best])):
                    best, best_d2 = slot, d2
        return best

    def _nearest_in_ball(self, x: float, y: float) -> tuple[int | None, float]:
        """The unchanged snapshot site within match_radius nearest to (x, y), ties to the
        smaller id, and its squared distance (None and r**2 when there is none): every
        snapshot entry within the radius from the k-d tree, by the per-row test."""
        r = self.settings.match_radius
        best, best_d2 = None, r * r
        xy, ids, version = self._xy, self._ids, self._version
        slots, versions = self._snap_slots, self._snap_versions
        for j in self._tree.query_ball_point((x, y), r * (1 + 1e-9) + 1e-12):
            slot = int(slots[j])
            if version[slot] != versions[j]:
                continue
            sx, sy = xy[slot]
            d2 = (sx - x) * (sx - x) + (sy - y) * (sy - y)
            if d2 < best_d2 or (d2 == best_d2 and (best is None or ids[slot] < ids[best])):
                best, best_d2 = slot, d2
        return best, best_d2

    def _hash_add(self, slot: int) -> None:
        """Record a site inserted or moved since the snapshot."""
        x, y = self._xy[slot]
        key = self._cell_key(x, y)
        self._cells.setdefault(key, []).append(slot)
        self._dirty_key[slot] = key
        self._dirty_count += 1

    def _hash_remove(self, slot: int) -> None:
        key = self._dirty_key[slot]
        if key is None:
            return
        members = self._cells[key]
        members.remove(slot)
        if not members:
            del self._cells[key]
        self._dirty_key[slot] = None

    def _distance(self, x: float, y: float) -> float:
        """Horizontal distance to the drone, computed exactly as :meth:`_losses` does."""
        if self._drone is None:
            return 0.0
        dx, dy = x - self._drone[0], y - self._drone[1]
        return math.sqrt(dx * dx + dy * dy)

    def _loss_of_slot(self, slot: int) -> float:
        x, y = self._xy[slot]
        return site_loss_scalar(self._distance(x, y), float(self._rough[slot]),
                                float(self._unc[slot]), float(self._size[slot]),
                                float(self._veralt[slot]), self._size_max, self.weights)

    def _push(self, slot: int) -> None:
        self._version[slot] += 1
        if self._size_max != self._keyed_size_max:
            # This key is made under another size_max than the rest of the heap: the heap is
            # no longer one ordering, so the next eviction must re-key it all.
            self._keyed_size_max = math.nan
        entry = (-self._loss_of_slot(slot), -int(self._ids[slot]), self._version[slot], slot)
        heapq.heappush(self._heap, entry)
        if len(self._heap) > 2 * len(self._slot_of) + 64:
            self._rekey()  # too many stale entries: rebuild

    def _worst_slot(self) -> tuple[int, float] | None:
        """The valid heap top: (slot, loss). Stale entries are discarded on the way."""
        heap, version = self._heap, self._version
        while heap:
            neg_loss, _, ver, slot = heap[0]
            if version[slot] == ver and self._ids[slot] >= 0:
                return slot, -neg_loss
            heapq.heappop(heap)
        return None

    def _remove(self, slot: int) -> None:
        if slot in self._pending_set:
            self._flush_redetections()  # the slot may be reused: settle its counts first
        site_id = int(self._ids[slot])
        self._hash_remove(slot)
        del self._slot_of[site_id]
        self._ids[slot] = -1
        self._version[slot] += 1
        self._free.append(slot)
        if self._size[slot] >= self._size_max:
            self._refresh_size_max()

    def _refresh_size_max(self) -> None:
        slots = self._active_slots()
        self._size_max = float(self._size[slots].max()) if len(slots) else 0.0

    def _moved_since(self, xy: tuple[float, float] | None) -> bool:
        if self._drone is None:
            return False
        if xy is None:
            return True
        return math.hypot(self._drone[0] - xy[0],
                          self._drone[1] - xy[1]) > self.settings.rekey_distance

    def _maybe_rekey(self) -> None:
        """After the drone moved more than rekey_distance: drop sites beyond max_distance.

        Heap keys are recomputed lazily, only when an eviction needs them (:meth:`_rekey`).
        """
        if self._moved_since(self._checked_at):
            self._checked_at = self._drone[:2]
            slots = self._active_slots()
            d = self._pos[slots, :2] - np.asarray(self._drone[:2])
            far = slots[np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
                        > self.settings.max_distance]
            for slot in far.tolist():
                site_id = int(self._ids[slot])
                t = float(self._last[slot])
                self._remove(slot)
                self._counts["dropped"] += 1
                self._decide("dropped", site_id, "beyond max distance", t)

    def _keys_current(self) -> bool:
        return not self._moved_since(self._keyed_at) and self._size_max == self._keyed_size_max

    def _rekey(self) -> None:
        """Recompute every heap key at the current drone position and re-heapify (O(n))."""
        slots = self._active_slots()
        loss = self._losses(slots)
        version = np.array(self._version, dtype=np.int64)[slots]
        self._heap = list(zip((-loss).tolist(), (-self._ids[slots]).tolist(), version.tolist(),
                              slots.tolist(), strict=True))
        heapq.heapify(self._heap)
        self._keyed_at = None if self._drone is None else self._drone[:2]
        self._keyed_size_max = self._size_max

    def _validate(self, batch: list) -> tuple[np.ndarray | None, list[str | None]]:
        """Vectorised checks of a batch. Returns the (n, 9) value array (None if no row
        could be read) and, per observation, the rejection reason or None."""
        n = len(batch)
        reasons: list[str | None] = [None] * n
        rows = []
        for i, obs in enumerate(batch):
            try:
                if not isinstance(obs, SiteObservation):
                    raise TypeError
                rows.append(_OBS_FIELDS(obs))
            except Exception:
                reasons[i] = "malformed"
                rows.append((0.0,) * 9)
        try:
            vals = np.array(rows, dtype=np.float64).reshape(n, 9)
        except (TypeError, ValueError):
            # Some field is not a number: fall back to row by row.
            vals = np.zeros((n, 9))
            for i, row in enumerate(rows):
                try:
                    vals[i] = np.array(row, dtype=np.float64)
                except (TypeError, ValueError):
                    reasons[i] = "malformed"
        if ((vals >= _LOWEST) & (vals <= _HIGHEST)).all():
            return vals, self._zone_reasons(vals, reasons, np.zeros(n, dtype=bool))
        finite = np.isfinite(vals).all(axis=1)
        checks = (
            ("non_finite", ~finite),
            ("position_out_of_range", (np.abs(vals[:, :3]) > _MAX_COORDINATE).any(axis=1)),
            ("roughness_out_of_range", (vals[:, 3] < 0) | (vals[:, 3] > 1)),
            ("uncertainty_out_of_range", (vals[:, 4] < 0) | (vals[:, 4] > 1)),
            ("negative_size", vals[:, 5] < 0),
            ("negative_observation_altitude", vals[:, 7] < 0),
        )
        bad = np.zeros(n, dtype=bool)
        for reason, mask in checks:
            if not mask.any():
                continue  # nothing to name, nothing to add to bad
            hit = mask & ~bad
            for i in np.flatnonzero(hit).tolist():
                if reasons[i] is None:
                    reasons[i] = reason
            bad |= mask
        return vals, self._zone_reasons(vals, reasons, bad)

    def _zone_reasons(self, vals: np.ndarray, reasons: list[str | None], bad: np.ndarray
                      ) -> list[str | None]:
        """:meth:`_validate`'s last checks, on the rows not rejected yet: outside the
        operating area, inside a ban zone, beyond max_distance from the drone."""
        if self._area is not None:
            outside = ~bad  # a new array: the rows not rejected yet
            outside[outside] = ~self._area.contains(vals[outside, :2])
            for i in np.flatnonzero(outside).tolist():
                if reasons[i] is None:
                    reasons[i] = OUTSIDE_GEOFENCE
            bad |= outside
        if len(self._bans):
            dx = vals[:, None, 0] - self._bans[None, :, 0]
            dy = vals[:, None, 1] - self._bans[None, :, 1]
            inside = ((dx * dx + dy * dy) <= self._bans[None, :, 2] ** 2).any(axis=1)
            for i in np.flatnonzero(inside & ~bad).tolist():
                if reasons[i] is None:
                    reasons[i] = "banned_zone"
            bad |= inside
        if self._drone is not None:
            dx, dy = vals[:, 0] - self._drone[0], vals[:, 1] - self._drone[1]
            far = np.sqrt(dx * dx + dy * dy) > self.settings.max_distance
            if far.any():
                for i in np.flatnonzero(far & ~bad).tolist():
                    if reasons[i] is None:
                        reasons[i] = "beyond_max_distance"
        return reasons

    def _process_batch(self, batch: list) -> None:
        vals, reasons = self._validate(batch)
        self._counts["received"] += len(batch)
        rows = vals.tolist()
        if self._dirty_count > max(_SNAPSHOT_MIN, len(self._slot_of) // 8):
            self._snapshot()
        accepted = [i for i, reason in enumerate(reasons) if reason is None]
        slots, versions, lo, hi, queried = self._snapshot_candidates(vals, accepted)
        # A large batch keys its rows at once; a small one row by row, where the hash has
        # entries (numpy's per-call cost is most of keying a few rows).
        keys = self._match_keys(vals) if len(batch) > _SMALL_BATCH else [None] * len(batch)
        nearest = self._nearest_within_match
        for i, reason in enumerate(reasons):
            row = rows[i]
            if reason is not None:
                self._reject(reason, row[8] if reason != "malformed" else 0.0)
                continue
            slot = nearest(row[0], row[1], slots, versions, lo[i], hi[i], queried[i], keys[i])
            if slot is None:
                self._insert(row, batch[i].source)
            elif row[7] < self._veralt[slot]:
                self._update(slot, row, batch[i].source)
            else:
                self._counts["merged"] += 1
                self._pending_slots.append(slot)
                self._pending_times.append(row[8])
                self._pending_set.add(slot)
                if self._on_decision is not None:
                    self._decide("merged", int(self._ids[slot]), "", row[8])
        self._flush_redetections()
        # No far-site check here: the drone moves only in set_drone_position, which makes
        # it under this lock.

    def _insert(self, row: list[float], source: str) -> None:
        x, y, z, rough, unc, size, obst, obs_alt, t = row
        if not self._free:
            # Full: the new site must beat the worst retained one to get in.
            retained_size_max = self._size_max
            # Compare under the size_max that would hold with the newcomer in, with keys of
            # the current drone position (within rekey_distance).
            self._size_max = max(self._size_max, size)
            if not self._keys_current():
                self._rekey()
            loss = site_loss_scalar(self._distance(x, y), rough, unc, size, obs_alt,
                                    self._size_max, self.weights)
            worst = self._worst_slot()
            if worst is None or loss >= worst[1]:
                self._size_max = retained_size_max  # keys re-made lazily if this changed it
                self._reject("worse_than_worst", t)
                return
            worst_slot = worst[0]
            worst_id = int(self._ids[worst_slot])
            heapq.heappop(self._heap)
            self._remove(worst_slot)
            self._counts["replaced"] += 1
            self._decide("replaced", worst_id, "evicted as the worst site at capacity", t)
        slot = self._free.pop()
        site_id = self._next_id
        self._next_id += 1
        self._ids[slot] = site_id
        self._slot_of[site_id] = slot
        self._store(slot, row, source)
        self._first[slot] = t
        self._count[slot] = 1
        self._hash_add(slot)
        if size > self._size_max:
            self._size_max = size
        self._push(slot)
        self._counts["inserted"] += 1
        self._decide("inserted", site_id, "", t)

    def _store(self, slot: int, row: list[float], source: str) -> None:
        x, y, z, rough, unc, size, obst, obs_alt, t = row
        self._pos[slot] = (x, y, z)
        self._xy[slot] = (x, y)
        self._rough[slot] = rough
        self._unc[slot] = unc
        self._size[slot] = size
        self._obst[slot] = obst
        self._veralt[slot] = obs_alt
        self._last[slot] = t
        self._sources[slot] = source

    def _update(self, slot: int, row: list[float], source: str) -> None:
        """Redetected from lower down: trust the new properties (thesis 3.1.5)."""
        t = row[8]
        site_id = int(self._ids[slot])
        self._counts["merged"] += 1
        self._counts["updated"] += 1
        self._pending_slots.append(slot)  # counts the detection; last_seen set by _store
        self._pending_times.append(t)
        self._pending_set.add(slot)
        old_size = float(self._size[slot])
        self._hash_remove(slot)
        self._store(slot, row, source)
        self._hash_add(slot)
        new_size = row[5]
        if new_size > self._size_max:
            self._size_max = new_size
        elif old_size >= self._size_max and new_size < old_size:
            self._refresh_size_max()
        self._push(slot)
        self._decide("updated", site_id, "redetected lower", t)
