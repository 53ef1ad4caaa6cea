"""mktree's typed clash tests beside IfcClash on one IFC model, with the
same sets and settings (docs/clash.md, "Against IfcClash").

Set A is the services (IfcPipeSegment, IfcDuctSegment), set B the
structure (IfcWall, IfcSlab, IfcColumn, IfcBeam). Three runs each:

- hard: IfcClash ``intersection`` (tolerance 2 mm, check_all) against
  ``mktree clash --type hard --tolerance 2``;
- clearance: IfcClash ``clearance`` (50 mm, check_all) against
  ``mktree clash --type clearance --distance 50 --touch`` (every pair
  closer than 50 mm: hard, touching and apart);
- collision: IfcClash ``collision`` (allow_touching) against
  ``mktree clash --type hard --tolerance 0 --touch`` (every pair in contact).

Every pair one tool reports and the other does not is classified by
mktree's own measure of it (touching, depth at or below the tolerance,
a distance at the boundary, ...). Times: IfcClash's whole run (it
tessellates every time), mktree's import (``mktree.ifc``) and each clash
run (the CLI's wall time, and the clash step alone as the library
reports it).

    python benchmarks/ifcclash_compare.py MODEL.ifc --mktree target/release/mktree --out report.json
"""

from __future__ import annotations

import argparse
import collections
import json
import logging
import os
import subprocess
import sys
import tempfile
import time
from typing import Any, Dict, FrozenSet, List, Set, Tuple

SERVICES = ["IfcPipeSegment", "IfcDuctSegment"]
STRUCTURE = ["IfcWall", "IfcSlab", "IfcColumn", "IfcBeam"]

Pair = FrozenSet[str]


def ifcclash_run(model: str, mode: str, **settings: Any) -> Tuple[Dict[Pair, Dict[str, Any]], float, float]:
    """IfcClash's pairs (unordered GlobalIds), its whole run's seconds, and
    the seconds of its clash step alone (the run less opening the file and
    tessellating the elements into its tree)."""
    import ifcclash.ifcclash as ic

    s = ic.ClashSettings()
    s.output = os.path.join(tempfile.mkdtemp(), "out.json")
    s.logger = logging.getLogger("ifcclash")
    clasher = ic.Clasher(s)
    clash_set = {
        "name": mode,
        "a": [{"file": model, "mode": "i", "selector": ", ".join(SERVICES)}],
        "b": [{"file": model, "mode": "i", "selector": ", ".join(STRUCTURE)}],
        "mode": mode,
        **settings,
    }
    clasher.clash_sets = [clash_set]
    outside = [0.0]

    def timed(f: Any) -> Any:
        def run(*a: Any, **k: Any) -> Any:
            t = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                outside[0] += time.perf_counter() - t
        return run

    clasher.load_ifc = timed(clasher.load_ifc)
    clasher.add_collision_objects = timed(clasher.add_collision_objects)
    started = time.perf_counter()
    clasher.clash()
    seconds = time.perf_counter() - started
    pairs = {}
    for c in clash_set["clashes"].values():
        pairs[frozenset((c["a_global_id"], c["b_global_id"]))] = {
            "type": str(c["type"]), "distance_m": c["distance"], "p1": c["p1"], "p2": c["p2"]}
    return pairs, seconds, seconds - outside[0]


def mktree_run(binary: str, mkt: str, *flags: str) -> Tuple[Dict[Pair, Dict[str, Any]], Dict[str, Any], float]:
    """mktree's clashes by unordered key pair, its summary, and the CLI's wall seconds."""
    args = [binary, "clash", mkt, "--json"]
    for c in SERVICES:
        args += ["--a", f"class:{c}"]
    for c in STRUCTURE:
        args += ["--b", f"class:{c}"]
    started = time.perf_counter()
    out = subprocess.run(args + list(flags), capture_output=True, text=True, check=True).stdout
    seconds = time.perf_counter() - started
    lines = [json.loads(x) for x in out.splitlines()]
    summary = lines.pop()["summary"]
    return {frozenset((c["a"], c["b"])): c for c in lines}, summary, seconds


def explain(pair: Pair, mine: Dict[Pair, Dict[str, Any]], side: str, boundary: float) -> str:
    """Why a pair is in one answer only, by mktree's measure of it (from
    the run that reports every contact and every pair closer than 50 mm)."""
    c = mine.get(pair)
    if c is None:
        return f"{side}: apart by 50 mm or more in mktree's measure"
    if c["type"] == "touch":
        return f"{side}: touching (depth {c['depth']:.3f} mm)"
    if c["type"] == "clearance":
        if abs(c["distance"] - boundary) < 1e-6 * max(1.0, boundary):
            return f"{side}: at the boundary distance ({c['distance']:.6f} mm)"
        return f"{side}: apart, {c['distance']:.3f} mm"
    return f"{side}: {c['type']}, depth {c['depth']:.3f} mm"


def compare(name: str, theirs: Dict[Pair, Any], ours: Dict[Pair, Any], reference: Dict[Pair, Any],
            boundary: float) -> Dict[str, Any]:
    only_theirs = [p for p in theirs if p not in ours]
    only_ours = [p for p in ours if p not in theirs]
    cases: collections.Counter[str] = collections.Counter()
    for p in only_theirs:
        cases[explain(p, reference, "IfcClash only", boundary)] += 1
    for p in only_ours:
        cases[explain(p, reference, "mktree only", boundary)] += 1
    # Coarser names for the README: the measure's text without its numbers.
    kinds: collections.Counter[str] = collections.Counter()
    for text, n in cases.items():
        kinds[text.split(" (")[0].split(",")[0].split(" depth")[0]] += n
    return {"test": name, "ifcclash": len(theirs), "mktree": len(ours), "both": len(set(theirs) & set(ours)),
            "ifcclash_only": len(only_theirs), "mktree_only": len(only_ours), "cases": dict(kinds),
            "examples": dict(list(cases.most_common(12)))}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("model")
    ap.add_argument("--mktree", default="target/release/mktree")
    ap.add_argument("--work", default=None, help="folder for the .mkt file (default: a temporary one)")
    ap.add_argument("--out", default=None, help="write the report here as JSON")
    ap.add_argument("--skip-ifcclash", action="store_true")
    ap.add_argument("--lod-levels", type=int, default=4,
                    help="M of mktree's file (1: no levels of detail, a file for clash tests alone)")
    ap.add_argument("--rerun-only", action="store_true",
                    help="reuse the .mkt file of an earlier run in --work: only the re-run after 100 moves")
    args = ap.parse_args()

    import mktree.ifc

    work = args.work or tempfile.mkdtemp()
    os.makedirs(work, exist_ok=True)
    mkt = os.path.join(work, "model.mkt")
    for f in [mkt + ".clash"] + ([] if args.rerun_only else [mkt]):
        if os.path.exists(f):
            os.remove(f)
    started = time.perf_counter()
    n = 0 if args.rerun_only else mktree.ifc.load(args.model, mkt, lod_levels=args.lod_levels)
    import_s = time.perf_counter() - started
    report: Dict[str, Any] = {"model": args.model, "elements": n, "lod_levels": args.lod_levels,
                              "mktree_import_s": import_s, "runs": []}
    print(f"mktree import: {n} elements in {import_s:.2f} s", flush=True)

    everything, _, _ = ({}, None, None) if args.rerun_only else mktree_run(args.mktree, mkt, "--type", "clearance", "--distance", "50",
                                              "--touch", "--tolerance", "2")
    runs: List[Tuple[str, Tuple[str, Dict[str, Any]], Tuple[str, ...]]] = [
        ("hard", ("intersection", {"tolerance": 0.002, "check_all": True}),
         ("--type", "hard", "--tolerance", "2")),
        ("clearance 50 mm", ("clearance", {"clearance": 0.05, "check_all": True}),
         ("--type", "clearance", "--distance", "50", "--touch", "--tolerance", "2")),
        ("contact", ("collision", {"allow_touching": True}),
         ("--type", "hard", "--tolerance", "0", "--touch")),
    ]
    for name, (mode, settings), flags in ([] if args.rerun_only else runs):
        ours, summary, cli_s = mktree_run(args.mktree, mkt, *flags)
        row: Dict[str, Any] = {"test": name, "mktree_cli_s": cli_s, "mktree_stats": summary["stats"],
                               "mktree_by_type": summary["by_type_status"]}
        if not args.skip_ifcclash:
            theirs, their_s, their_step_s = ifcclash_run(args.model, mode, **settings)
            row["ifcclash_s"] = their_s
            row["ifcclash_clash_step_s"] = their_step_s
            row.update(compare(name, theirs, ours, everything, 50.0 if mode == "clearance" else 0.0))
        report["runs"].append(row)
        print(json.dumps(row, indent=1, default=str), flush=True)
    # A recorded test, 100 services moved 10 mm in one commit, the re-run
    # (incremental) and a full run of the same test on the same commit.
    hard = ("--type", "hard", "--tolerance", "2")
    _, first, first_s = mktree_run(args.mktree, mkt, "--test", "services", *hard)
    db = mktree.open(mkt)
    with db.read() as r:
        services = [k for k in r.box((-1e9, -1e9, -1e9), (1e9, 1e9, 1e9)).keys
                    if r[k].json().get("class") in SERVICES][:: 7][:100]
    with db.write() as w:
        for k in services:
            w.move_by(k, (0.0, 0.0, 10.0))
    db.close()
    again, rerun, rerun_s = mktree_run(args.mktree, mkt, "--test", "services", *hard)
    full, full_summary, full_s = mktree_run(args.mktree, mkt, "--test", "services", "--full", *hard)
    assert rerun["mode"]["mode"] == "incremental", rerun["mode"]
    assert {p: c for p, c in again.items()} == {p: c for p, c in full.items()}
    report["rerun"] = {"moved": len(services), "first_cli_s": first_s, "first_stats": first["stats"],
                       "rerun_cli_s": rerun_s, "rerun_stats": rerun["stats"], "rerun_mode": rerun["mode"],
                       "full_cli_s": full_s, "full_stats": full_summary["stats"], "equal": True}
    print(json.dumps(report["rerun"], indent=1), flush=True)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as out:
            json.dump(report, out, indent=1, default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
