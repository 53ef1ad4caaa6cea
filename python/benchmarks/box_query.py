"""A small box query from Python against the same query through the Rust
API, every block cached, in one run.

Opens (or builds) a file, draws `--queries` boxes of `--extent` of the
scene's extent about random points of it (seeded), runs them once to fill
the database's block cache, then times them: through Python, `r.box(lo,
hi)` in a loop (arguments, the call, the answer's keys as a list); through
the Rust API, the same boxes by `query_region` with the same cache
(`mktree._mktree._rust_box_seconds`, no Python between queries). Every
timed Python query must read no block (all cache hits), else the run stops.

    python benchmarks/box_query.py --scene tanker2
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import tempfile
import time

import mktree
from mktree import _mktree


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--file", help="an .mkt file (default: a generated scene)")
    ap.add_argument("--scene", default="tanker2", help="the preset generated without --file")
    ap.add_argument("--queries", type=int, default=200)
    ap.add_argument("--extent", type=float, default=0.01, help="box side over the scene's extent")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=5, help="alternating rounds; medians are compared")
    args = ap.parse_args()
    path = args.file
    if path is None:
        path = os.path.join(tempfile.mkdtemp(prefix="mktree-box-"), f"{args.scene}.mkt")
        db = mktree.Database.create(path)
        with db.write() as w:
            w.bulk_load(mktree.generate(args.scene))
        db.close()
    db = mktree.Database.open(path, read_only=True)
    r = db.read()
    info = r.info()
    assert info is not None, "the file has no tree"
    lo = info.scene_bounds[:3]
    hi = info.scene_bounds[3:]
    rng = random.Random(7)
    boxes = []
    for _ in range(args.queries):
        c = [rng.uniform(a, b) for a, b in zip(lo, hi)]
        h = [(b - a) * args.extent / 2 for a, b in zip(lo, hi)]
        boxes.append((c[0] - h[0], c[1] - h[1], c[2] - h[2], c[0] + h[0], c[1] + h[1], c[2] + h[2]))
    pairs = [((b[0], b[1], b[2]), (b[3], b[4], b[5])) for b in boxes]
    found = sum(len(r.box(a, b)) for a, b in pairs)  # fills the cache
    assert all(r.box(a, b).stats.block_reads == 0 for a, b in pairs), "blocks left uncached: use fewer queries"

    def python_seconds() -> float:
        started = time.perf_counter()
        for _ in range(args.repeats):
            for a, b in pairs:
                r.box(a, b).keys
        return float((time.perf_counter() - started) / (args.repeats * len(pairs)))

    py, rust = [], []
    for _ in range(args.rounds):
        py.append(python_seconds())
        rust.append(_mktree._rust_box_seconds(r, boxes, args.repeats))
    p, q = statistics.median(py), statistics.median(rust)
    print(f"{info.objects} objects, {len(boxes)} boxes of {args.extent:g} of the extent, "
          f"{found / len(boxes):.1f} objects each, every block cached")
    print(f"per query: Rust API {q * 1e6:.1f} us, Python {p * 1e6:.1f} us: {p / q:.2f}x "
          f"(medians of {args.rounds} rounds of {args.repeats} x {len(boxes)} queries)")


if __name__ == "__main__":
    main()
