"""Every blackboard key of the landing mission, declared once.

Keys are absolute py_trees blackboard names. Behaviours register them with the access they
need (see each behaviour's constructor); the runner reads them through a
:class:`py_trees.blackboard.Client` with READ access, e.g.::

    client = py_trees.blackboard.Client(name="runner")
    client.register_key(key=PHASE, access=py_trees.common.Access.READ)
    client.get(PHASE)

:func:`build_mission_tree <behaviors.tree.build_mission_tree>` writes the initial value of
every key (see :data:`DEFAULTS`), so readers never meet a missing key.
"""

from __future__ import annotations

import types

import py_trees

PHASE = "/mission/phase"
"""str: what the mission is doing now; one of :data:`PHASES`."""

PHASES = (
    "preflight",
    "takeoff",
    "mission",
    "landing_phase",
    "search",
    "navigate_to_site",
    "descend",
    "verification",
    "centre",
    "land",
    "land_in_place",
    "failsafe",
    "done",
)
"""The values :data:`PHASE` takes ("done": landed and disarmed)."""

LANDING_SITE = "/landing/site"
"""lsm.LandingSite | None: the chosen landing site (the latest record the LSM gave for it)."""

CLEAR_ALTITUDE = "/landing/clear_altitude"
"""float | None: clear altitude for reaching the chosen site, ENU z in m (thesis eq. 3.4-3.5)."""

OUTCOME_HINT = "/mission/outcome_hint"
"""str | None: why the mission ended the way it did when not at a verified site:
"no_site" (no landing try left, by count or by battery: landed in place on purpose),
"battery_critical" (the failsafe landed where the vehicle was on the critical battery
level), "gps_lost" (the failsafe landed where the vehicle was after losing the 3D GPS fix),
"battery_reserve" (waypoints skipped on the reserve level; the landing phase still ran).
A failsafe's hint replaces any earlier one: the failsafe is what happened."""

FAILURE_REASON = "/mission/failure_reason"
"""str | None: why the last behaviour that failed did so (a denied command carries the
autopilot's reason), "<behaviour name>: <reason>". Meaningful when the tree's root FAILED;
cleared when the vehicle lands and disarms (failures recovered from on the way, e.g. a
failed verification, are counted in their own keys)."""

FAILSAFE = "/mission/failsafe"
"""str | None: the failsafe that took over the mission ("battery_critical", "gps_lost"),
latched: the mission branch never resumes once it is set."""

FAILSAFE_KINDS: tuple[str, ...] = ("battery_critical", "gps_lost")
"""The values FAILSAFE takes; the failsafe writes the same value to OUTCOME_HINT, so a
flight whose OUTCOME_HINT is one of these ended with a failsafe landing."""

VERIFICATION_ATTEMPTS = "/landing/verification_attempts"
"""int: landing-site verifications started."""

SEARCH_PATTERNS = "/landing/search_patterns"
"""int: search patterns flown (begun; a search that finds a site already known on entry,
or is refused at the battery reserve, flies none)."""

PATTERN_CENTER = "/landing/pattern_center"
"""tuple[float, float] | None: ENU x, y (m) of the centre of the next search pattern; None
means "where the vehicle is when the search starts"."""

BANNED_SITES = "/landing/banned_sites"
"""int: sites banned after a failed verification or a retreat of the descent watch."""

LANDING_TRY_COST = "/landing/try_cost"
"""float: battery (% points) the next landing try is expected to cost, written by the
landing phase's RetryWhileBattery for the last resort's BatteryAllows. A tree entry (set by
the tree that uses it), not one of the mission keys below."""

DEFAULTS: types.MappingProxyType[str, object] = types.MappingProxyType(
    {
        PHASE: "preflight",
        LANDING_SITE: None,
        CLEAR_ALTITUDE: None,
        OUTCOME_HINT: None,
        FAILURE_REASON: None,
        FAILSAFE: None,
        VERIFICATION_ATTEMPTS: 0,
        SEARCH_PATTERNS: 0,
        PATTERN_CENTER: None,
        BANNED_SITES: 0,
    }
)
"""Every mission key with its value at the start of a mission."""

KEYS: tuple[str, ...] = tuple(DEFAULTS)
"""Every mission key."""


def reset() -> None:
    """Remove every mission key's value from the blackboard.

    Tests and campaigns build many trees in one process; py_trees' blackboard storage is
    global, so a new mission must not see the previous one's values.
    """
    for key in KEYS:
        py_trees.blackboard.Blackboard.unset(key)


def initialise() -> None:
    """Write every mission key's start value (:data:`DEFAULTS`), replacing old values."""
    for key, value in DEFAULTS.items():
        py_trees.blackboard.Blackboard.set(key, value)


def read_all() -> dict[str, object]:
    """The current value of every mission key (None for a key not written), for reports."""
    storage = py_trees.blackboard.Blackboard.storage
    return {key: storage.get(key) for key in KEYS}
