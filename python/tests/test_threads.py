"""Threads query one file in parallel: answers from a shared read
transaction equal the sequential ones, long calls release the GIL (another
Python thread runs meanwhile), and a writer in one thread neither blocks
the readers nor changes their snapshots."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import mktree
from conftest import grid, tetra


def test_threads_share_a_read_transaction(make_db) -> None:
    db = make_db(mktree.generate("tanker1"))
    r = db.read()
    info = r.info()
    assert info is not None
    lo, hi = info.scene_bounds[:3], info.scene_bounds[3:]
    boxes = [
        (tuple(a + (b - a) * f for a, b in zip(lo, hi)), tuple(a + (b - a) * (f + 0.2) for a, b in zip(lo, hi)))
        for f in [i / 40 for i in range(32)]
    ]
    expected = [r.box(a, b).keys for a, b in boxes]
    with ThreadPoolExecutor(max_workers=8) as pool:
        for _ in range(5):
            got = list(pool.map(lambda q: r.box(q[0], q[1]).keys, boxes))
            assert got == expected
        clashes = list(pool.map(lambda _: r.clash().pairs, range(4)))
    assert all(c == clashes[0] for c in clashes)


def test_a_long_call_releases_the_gil(make_db) -> None:
    db = make_db(mktree.generate("tanker2"))
    r = db.read()
    ticks = 0
    stop = threading.Event()

    def count() -> None:
        nonlocal ticks
        while not stop.is_set():
            ticks += 1
            time.sleep(0.0005)

    counter = threading.Thread(target=count)
    counter.start()
    try:
        time.sleep(0.02)
        before, calls = ticks, 0
        started = time.perf_counter()
        while time.perf_counter() - started < 0.3:
            pairs = r.clash(clearance=50.0)
            calls += 1
        took = time.perf_counter() - started
        during = ticks - before
    finally:
        stop.set()
        counter.join()
    assert len(pairs) > 0
    # Holding the GIL through each call would leave the counter a tick or
    # two between calls; released, it ticks every half millisecond or so.
    assert during >= 3 * calls + 20, f"{during} ticks in {calls} calls, {took:.2f} s"


def test_a_writer_thread_leaves_readers_their_snapshots(make_db) -> None:
    db = make_db(grid(4))
    r = db.read()
    done = threading.Event()

    def write() -> None:
        for i in range(5):
            with db.write() as w:
                m = tetra((100000 + 2000 * i, 0, 0))
                w.insert((1000 + i, m.vertices, m.triangles))
        done.set()

    writer = threading.Thread(target=write)
    writer.start()
    while not done.is_set():
        assert len(r.box((-1, -1, -1), (1e7, 1e7, 1e7))) == 64
    writer.join()
    assert len(db.read().box((-1, -1, -1), (1e7, 1e7, 1e7))) == 69 and len(r) == 64
