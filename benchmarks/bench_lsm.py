"""Landing Site Manager throughput, ranking latency and memory per site.

Run: .venv/bin/python benchmarks/bench_lsm.py

Figures:
- observations/s through the full path (producer thread submit() -> worker thread ->
  stored), at capacity 1,000 and 10,000, with a realistic redetection rate (most
  observations re-see a known site, as a detector does frame after frame);
- ranked() latency with 10,000 retained sites (median and 99th percentile);
- bytes per retained site (tracemalloc, manager filled to 10,000 sites).
"""

from __future__ import annotations

import os
import statistics
import threading
import time
import tracemalloc

import _checkout  # noqa: F401  (this checkout's packages first)
import numpy as np

from lsm import LandingSiteManager, LsmSettings, SiteObservation
from lsm.settings import MAX_DISTANCE


def observations(n: int, n_sites: int, redetect: float, seed: int) -> list[SiteObservation]:
    """n observations over n_sites ground sites; a fraction `redetect` re-sees known ones."""
    rng = np.random.default_rng(seed)
    sites = rng.uniform(-95, 95, size=(n_sites, 2))
    which = np.where(rng.random(n) < redetect, rng.integers(0, max(1, n_sites // 4), n),
                     rng.integers(0, n_sites, n))
    xy = sites[which] + rng.normal(0, 0.3, size=(n, 2))
    props = rng.uniform(0, 1, size=(n, 4))
    return [
        SiteObservation(float(x), float(y), 0.0, float(r), float(u), 6.0 * float(s), 1.0,
                        2.0 + 98.0 * float(a), float(i), "bench")
        for i, ((x, y), (r, u, s, a)) in enumerate(zip(xy.tolist(), props.tolist(),
                                                       strict=True))
    ]


def throughput(capacity: int, n: int, redetect: float) -> tuple[float, float, dict]:
    """Wall-clock and per-CPU-second rates (the CPU figure is what the LSM itself costs
    when other processes share the cores)."""
    m = LandingSiteManager(LsmSettings(capacity=capacity, max_distance=200.0))
    m.set_drone_position((0.0, 0.0, 100.0))
    data = observations(n, n_sites=capacity * 3, redetect=redetect, seed=capacity)
    # Warm the store so the run measures the steady state at capacity.
    warm = observations(capacity * 4, n_sites=capacity * 3, redetect=0.0, seed=capacity + 1)
    m.submit_many(warm)
    m.process_pending()
    base = m.counters()["received"]
    m.start()
    t0 = time.perf_counter()
    c0 = time.process_time()

    def producer():
        submit = m.submit
        for o in data:
            submit(o)

    th = threading.Thread(target=producer)
    th.start()
    th.join()
    while m.counters()["received"] - base < n:
        time.sleep(0.0005)
    elapsed = time.perf_counter() - t0
    cpu = time.process_time() - c0
    m.stop()
    return n / elapsed, n / cpu, m.counters()


def ranked_latency(n_sites: int, repeats: int = 200) -> tuple[float, float]:
    m = LandingSiteManager(LsmSettings(capacity=n_sites, max_distance=MAX_DISTANCE,
                                       match_radius=0.5))
    rng = np.random.default_rng(7)
    xy = rng.uniform(-2000, 2000, size=(n_sites, 2))
    m.submit_many(SiteObservation(float(x), float(y), 0.0, 0.2, 0.3, 2.0, 1.0, 50.0)
                  for x, y in xy.tolist())
    m.process_pending()
    assert len(m) > 0.95 * n_sites, len(m)
    times = []
    for k in range(repeats):
        t0 = time.perf_counter()
        r = m.ranked((float(k), 0.0, 100.0))
        times.append(time.perf_counter() - t0)
        assert len(r) == len(m)
    times.sort()
    return statistics.median(times) * 1e3, times[int(0.99 * (len(times) - 1))] * 1e3


def bytes_per_site(n_sites: int) -> float:
    data = [SiteObservation(float(i % 100) * 10.0, float(i // 100) * 10.0, 0.0, 0.2, 0.3, 2.0,
                            1.0, 50.0, 0.0, "sfm") for i in range(n_sites)]
    tracemalloc.start()
    m = LandingSiteManager(LsmSettings(capacity=n_sites, max_distance=MAX_DISTANCE))
    m.submit_many(data)
    data = None
    m.process_pending()
    current, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(m) == n_sites
    return current / n_sites


def main() -> None:
    print("Landing Site Manager benchmark (lsm)")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'capacity':>9} {'redetect':>9} {'observations':>13} {'obs/s wall':>11} "
          f"{'obs/CPU-s':>10} {'merged':>8} {'inserted':>9} {'rejected':>9}")
    for capacity in (1_000, 10_000):
        for redetect in (0.8,):
            n = 200_000
            rate, cpu_rate, c = throughput(capacity, n, redetect)
            print(f"{capacity:>9,} {redetect:>9.0%} {n:>13,} {rate:>11,.0f} {cpu_rate:>10,.0f} "
                  f"{c['merged']:>8,} {c['inserted']:>9,} {c['rejected']:>9,}")
    med, p99 = ranked_latency(10_000)
    print(f"ranked() with 10,000 sites: median {med:.2f} ms, p99 {p99:.2f} ms")
    print(f"memory: {bytes_per_site(10_000):.0f} bytes per retained site (10,000 sites)")


if __name__ == "__main__":
    main()
