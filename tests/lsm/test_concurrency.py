"""Many producer threads, a worker thread and a reader hammering one manager."""

from __future__ import annotations

import threading

import numpy as np

from lsm import LandingSiteManager, LsmSettings, SiteObservation

PRODUCERS = 4
PER_PRODUCER = 25_000
CAPACITY = 200


def produce(m: LandingSiteManager, seed: int) -> None:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-90, 90, size=(PER_PRODUCER, 2))
    props = rng.uniform(0, 1, size=(PER_PRODUCER, 3))
    bad = rng.random(PER_PRODUCER) < 0.05  # a few broken observations in the stream
    for i in range(PER_PRODUCER):
        rough = 1.7 if bad[i] else float(props[i, 0])
        m.submit(SiteObservation(float(xy[i, 0]), float(xy[i, 1]), 0.0, rough,
                                 float(props[i, 1]), 5.0 * float(props[i, 2]), 1.0,
                                 100.0 * float(props[i, 2]), float(i), f"p{seed}"))


def test_producers_worker_and_reader_agree():
    m = LandingSiteManager(LsmSettings(capacity=CAPACITY, max_distance=500.0, ban_radius=1.0))
    stop = threading.Event()
    problems: list[str] = []
    rankings = 0

    def reader():
        nonlocal rankings
        k = 0
        while not stop.is_set():
            ranking = m.ranked((k % 50, 0, 100))
            ids = ranking.ids.tolist()
            if len(ids) != len(set(ids)):
                problems.append("an id retained twice")
            if len(ids) > CAPACITY:
                problems.append(f"{len(ids)} sites retained, capacity {CAPACITY}")
            if len(ids) and k % 97 == 0:
                m.ban(ids[-1])
            rankings += 1
            k += 1

    with m:
        threads = [threading.Thread(target=produce, args=(m, s)) for s in range(PRODUCERS)]
        watcher = threading.Thread(target=reader)
        watcher.start()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        stop.set()
        watcher.join()
    c = m.counters()
    assert not problems, problems[:3]
    assert rankings > 0
    assert c["received"] == PRODUCERS * PER_PRODUCER
    assert c["received"] == c["inserted"] + c["merged"] + c["rejected"]
    assert c["rejected_roughness_out_of_range"] > 0
    assert c["rejected"] == sum(v for k, v in c.items() if k.startswith("rejected_"))
    assert c["retained"] == len(m) <= CAPACITY
    assert c["inserted"] - c["replaced"] - c["dropped"] - c["banned"] == len(m)
