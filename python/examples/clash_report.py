"""An IFC model in mktree: a clash test, a box query, a chart.

Loads an IFC model (or makes the plant of ``ifc_plant.py``) into an mktree
file with ``mktree.ifc``, finds every pair of elements that touch, counts
them by the pair of IFC classes, lists what a box around the first room
holds, and draws the counts with matplotlib.

    python examples/clash_report.py [MODEL.ifc] [-o clashes.png]
"""

from __future__ import annotations

import argparse
import collections
import os
import tempfile
from typing import Counter, Dict, Optional, Sequence, Tuple

import matplotlib

matplotlib.use("Agg")  # a file, no window
import matplotlib.pyplot as plt

import mktree
import mktree.ifc


def ifc_class(r: mktree.ReadTransaction, key: mktree.Key, cache: Dict[mktree.Key, str]) -> str:
    """The IFC class the loader stored in the element's payload."""
    if key not in cache:
        payload = r[key].json()
        cache[key] = payload["class"] if isinstance(payload, dict) else "?"
    return cache[key]


def report(model: str, out_png: str, work: str) -> Tuple[int, int]:
    """Runs the example; returns the clashing pairs between services
    (pipes, ducts) and walls, and the elements in the first room's box."""
    mkt = os.path.join(work, "model.mkt")
    if os.path.exists(mkt):
        os.remove(mkt)
    n = mktree.ifc.load(model, mkt)
    print(f"{n} elements indexed from {model}")
    with mktree.open(mkt, read_only=True) as db, db.read() as r:
        clashes = r.clash()
        classes: Dict[mktree.Key, str] = {}
        by_pair: Counter[str] = collections.Counter()
        for a, b in clashes:
            pair = " / ".join(sorted((ifc_class(r, a, classes), ifc_class(r, b, classes))))
            by_pair[pair] += 1
        print(f"clash test: {len(clashes)} touching pairs, {clashes.stats.block_reads} block reads "
              f"of the file's {clashes.file_blocks} blocks")
        for pair, count in by_pair.most_common():
            print(f"  {count:6d}  {pair}")
        room = r.box((0, 0, 0), (6000, 6000, 3000))
        kinds = collections.Counter(ifc_class(r, k, classes) for k in room)
        print(f"box query (the first room): {len(room)} elements, {dict(kinds)}, "
              f"{room.stats.block_reads} block reads")

    fig, ax = plt.subplots(figsize=(8, 4))
    labels = [p for p, _ in by_pair.most_common()]
    ax.barh(labels, [by_pair[p] for p in labels], color="#4477aa")
    ax.set_xlabel("touching pairs")
    ax.set_title(f"Clashes by IFC class ({os.path.basename(model)}, {n} elements)")
    ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(out_png, dpi=100)
    print(f"chart: {out_png}")
    services = sum(c for p, c in by_pair.items() if "IfcWall" in p and ("Pipe" in p or "Duct" in p))
    return services, len(room)


def main(argv: Optional[Sequence[str]] = None) -> None:
    ap = argparse.ArgumentParser(description="An IFC model in mktree: a clash test, a box query, a chart.")
    ap.add_argument("model", nargs="?", help="an IFC file (default: the plant of ifc_plant.py, 4 x 4 rooms)")
    ap.add_argument("-o", "--out", default="clashes.png", help="the chart (PNG)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as work:
        model = args.model
        if model is None:
            from ifc_plant import make_plant

            model = os.path.join(work, "plant.ifc")
            make_plant(4).write(model)
        report(model, args.out, work)


if __name__ == "__main__":
    main()
