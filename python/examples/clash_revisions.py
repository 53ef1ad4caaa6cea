"""A clash test across three revisions of an IFC model, as the README's
table shows it: the model of ``ifc_clash_model.py`` indexed with
``mktree.ifc``; revision 1 records the test (services against the
structure, clearance 50 mm, touches too); an engineer approves one clash;
revision 2 moves 20 pipes clear of the walls and lifts 10 ducts into the
beams; revision 3 moves 10 of the pipes back. Prints each run's counts by
type and status (``mktree clash --test``).

    python examples/clash_revisions.py MODEL.ifc WORK_DIR --mktree target/release/mktree
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
from typing import Any, Dict, List

import mktree
import mktree.ifc

SETS = ["--a", "class:IfcPipeSegment", "--a", "class:IfcDuctSegment", "--b", "class:IfcWall", "--b", "class:IfcSlab",
        "--b", "class:IfcColumn", "--b", "class:IfcBeam"]
TEST = ["--type", "clearance", "--distance", "50", "--touch", "--tolerance", "2", "--group", "proximity:1000"]


def run(cli: str, mkt: str) -> "tuple[List[Dict[str, Any]], Dict[str, Any]]":
    out = subprocess.run([cli, "clash", mkt, "--json", "--test", "services"] + SETS + TEST,
                         capture_output=True, text=True, check=True).stdout
    lines = [json.loads(x) for x in out.splitlines()]
    return lines[:-1], lines[-1]["summary"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("model")
    ap.add_argument("work")
    ap.add_argument("--mktree", default="target/release/mktree")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    mkt = os.path.join(args.work, "revisions.mkt")
    for f in (mkt, mkt + ".clash"):
        if os.path.exists(f):
            os.remove(f)
    mktree.ifc.load(args.model, mkt)
    clashes, summary = run(args.mktree, mkt)
    print("revision 1:", summary["by_type_status"], summary["mode"])
    hard = next(c for c in clashes if c["type"] == "hard")
    subprocess.run([args.mktree, "clash-status", mkt, "--test", "services", "--a", hard["a"], "--b", hard["b"],
                    "--set", "approved", "--text"], check=True)
    with mktree.open(mkt) as db:
        with db.read() as r:
            keys = r.box((-1e9, -1e9, -1e9), (1e9, 1e9, 1e9)).keys
            classes = {k: r[k].json()["class"] for k in keys}
        pipes = sorted(k for k in keys if classes[k] == "IfcPipeSegment" and k != hard["a"])[:20]
        ducts = sorted(k for k in keys if classes[k] == "IfcDuctSegment" and k != hard["a"])[:10]
        with db.write() as w:
            for k in pipes:
                w.move_by(k, (0.0, 0.0, 5000.0))  # clear of everything
            for k in ducts:
                w.move_by(k, (0.0, 0.0, 400.0))  # into the beams above
    _, summary = run(args.mktree, mkt)
    print("revision 2:", summary["by_type_status"], summary["mode"])
    with mktree.open(mkt) as db, db.write() as w:
        for k in pipes[:10]:
            w.move_by(k, (0.0, 0.0, -5000.0))
    _, summary = run(args.mktree, mkt)
    print("revision 3:", summary["by_type_status"], summary["mode"])


if __name__ == "__main__":
    main()
