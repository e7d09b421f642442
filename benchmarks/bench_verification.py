"""Verification recall and precision of the elevation-map detector at the 2.5 m hover.

Over random spots of several Mars worlds the camera descends from 20 m to 2.5 m above the
ground in 12 frames and hovers there for the mission's verification duration at its
perception rate (``perception.low_altitude_rate`` below ``perception.low_altitude``; 40 frames
for missions/mars_science.yaml), as the landing phase does, with the mission's camera, map and
detector settings. A spot counts as verified when the detector reports a site
within the match radius of it from no higher than the verification altitude plus tolerance.
Recall: verified ground-truth-safe spots over all safe spots. Precision: verifying
observations whose own position the ground truth calls safe.

    .venv/bin/python benchmarks/bench_verification.py [--worlds 6] [--spots 10]
        [--set max_step=0.07 ...]   # detector settings (perception.detection) to try
        [--why]                     # why each safe spot that failed did not verify
"""

from __future__ import annotations

import os

import _checkout  # noqa: F401  (this checkout's packages first)

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
from collections import Counter  # noqa: E402

import numpy as np  # noqa: E402
from pydantic import ValidationError  # noqa: E402

from autonomy.config import load_mission  # noqa: E402
from autonomy.perception.elevation import ElevationMapSource  # noqa: E402
from behaviors.ports import VehicleState  # noqa: E402
from lsd.elevation.detector import ElevationDetector  # noqa: E402
from lsd.site_selection import step_hazards  # noqa: E402
from sitl.terrain import is_safe, make_terrain  # noqa: E402

DESCENT = (20, 16, 13, 11, 9, 7.5, 6, 5, 4.2, 3.5, 3.0, 2.7)


def why_not_verified(detector: ElevationDetector, x: float, y: float, hover_sites: list,
                     ceiling: float) -> str:
    """Why no site near (x, y) verified at the end of the hover: the last hover frame's
    sites within the match radius (``hover_sites``) were all seen from too high, or doubtful,
    or there was none, and then which test failed most among the cells within the footprint
    radius of the spot."""
    s = detector.settings
    if hover_sites:
        if all(o.observation_altitude >= s.doubtful_altitude for o in hover_sites):
            return "site doubtful: a step beyond max_step forgiven by the noise tolerance nearby"
        return f"site seen from above {ceiling:g} m: its ring not all in the close view"
    analysis = detector.last_analysis
    if analysis is None:
        return "nothing observed"
    fit, r = analysis.fit, analysis.resolution
    xs = (analysis.origin_index[0] + np.arange(fit.height.shape[0]) + 0.5) * r
    ys = (analysis.origin_index[1] + np.arange(fit.height.shape[1]) + 0.5) * r
    disk = np.hypot(xs[:, None] - x, ys[None, :] - y) <= s.footprint_radius
    hazard, _ = step_hazards(fit, s, r)
    k = s.noise_tolerance
    with np.errstate(invalid="ignore"):
        failing = {
            "step hazard: a step beyond max_step + the noise tolerance nearby": hazard,
            "slope beyond max_slope": fit.slope - k * fit.slope_error > s.max_slope_rad,
            "roughness beyond max_roughness":
                fit.roughness**2 - k * fit.roughness_error > s.max_roughness**2,
            "too few cells observed": fit.observed_fraction < s.min_observed_fraction,
            "uncertainty beyond max_uncertainty": fit.sigma > s.max_uncertainty,
        }
    share = {reason: float(np.mean(mask[disk])) for reason, mask in failing.items()}
    worst = max(share, key=share.get)
    return worst if share[worst] > 0 else "no site: the safe area around the spot too small"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", default="missions/mars_science.yaml")
    parser.add_argument("--worlds", type=int, default=6, help="Mars worlds (seeds 0..N-1)")
    parser.add_argument("--spots", type=int, default=10, help="random spots per world")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="detector setting to override (repeatable)")
    parser.add_argument("--why", action="store_true",
                        help="tally why the safe spots that did not verify failed")
    args = parser.parse_args()
    mission = load_mission(args.mission)
    p = mission.perception
    if any("=" not in kv for kv in args.set):
        parser.error("--set: need KEY=VALUE")
    changes = dict(kv.split("=", 1) for kv in args.set)
    try:  # validated like the mission file: an unknown or bad setting names its field
        detector = type(p.detection).model_validate({**p.detection.model_dump(), **changes})
    except ValidationError as exc:
        first = exc.errors()[0]
        parser.error(f"--set {'.'.join(map(str, first['loc']))}: {first['msg']}")
    changes = {key: getattr(detector, key) for key in changes}
    ceiling = mission.landing.verification_altitude + mission.lsm.verification_tolerance
    hover_altitude = mission.landing.verification_altitude
    low = hover_altitude < p.low_altitude and p.low_altitude_rate is not None
    rate = p.low_altitude_rate if low else p.rate
    hover_frames = max(1, round(mission.landing.verification_duration * rate))
    heights = (*DESCENT, *(hover_altitude,) * hover_frames)
    times = (*range(len(DESCENT)), *(len(DESCENT) + np.arange(hover_frames) / rate))  # s
    radius = mission.lsm.match_radius

    outcomes: list[tuple[bool, bool]] = []  # (spot safe, spot verified)
    verifying_safe: list[bool] = []
    why: Counter[str] = Counter()
    for seed in range(args.worlds):
        terrain = make_terrain(mission.world.model_copy(update={"size": (200.0, 200.0)}), seed)
        spots = np.random.default_rng(seed).uniform(-80, 80, size=(args.spots, 2))
        for (x, y), safe in zip(spots, is_safe(terrain, spots[:, 0], spots[:, 1]), strict=True):
            source = ElevationMapSource.from_settings(
                terrain, rng=np.random.default_rng(1), camera=p.camera,
                elevation_map=p.elevation_map, detector=detector,
            )
            ground = float(terrain.height(x, y))
            verifying: list[tuple[float, float]] = []
            hover_sites: list = []  # the last hover frame's sites near the spot
            for t, agl in zip(times, heights, strict=True):
                state = VehicleState(position=(x, y, ground + agl), yaw=0.0,
                                     rangefinder_agl=agl, link_lost=False)
                observations = source.update(state, float(t))
                if agl > hover_altitude:
                    continue
                hover_sites = [o for o in observations if np.hypot(o.x - x, o.y - y) <= radius]
                verifying += [(o.x, o.y) for o in hover_sites if o.observation_altitude <= ceiling]
            outcomes.append((bool(safe), bool(verifying)))
            if args.why and safe and not verifying:
                why[why_not_verified(source.detector, x, y, hover_sites, ceiling)] += 1
            if verifying:
                xy = np.array(verifying)
                verifying_safe += list(is_safe(terrain, xy[:, 0], xy[:, 1]))

    safe_spots = [v for s, v in outcomes if s]
    unsafe_spots = [v for s, v in outcomes if not s]
    print(f"{args.mission}: {args.worlds} Mars worlds x {args.spots} spots; detector "
          f"{changes or 'as in the mission'}; verified = a site within {radius:g} m seen "
          f"from <= {ceiling:g} m during the {hover_altitude:g} m hover ({hover_frames} frames)")
    print(f"  recall:    {sum(safe_spots)} of {len(safe_spots)} ground-truth-safe spots verified")
    print(f"  unsafe:    {sum(unsafe_spots)} of {len(unsafe_spots)} unsafe spots verified")
    share = 100 * np.mean(verifying_safe) if verifying_safe else float("nan")
    print(f"  precision: {sum(verifying_safe)} of {len(verifying_safe)} verifying "
          f"observations on safe ground ({share:.1f}%)")
    if args.why:
        print("  safe spots not verified, by reason (the last hover frame):")
        for reason, count in why.most_common():
            print(f"    {count:3d}  {reason}")


if __name__ == "__main__":
    main()
