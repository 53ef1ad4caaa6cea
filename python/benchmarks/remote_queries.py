"""Requests, round trips and bytes per query of a file read over HTTP or S3.

Runs `mktree query URL --box ... --json` (a cold reader: one process per
query) for random boxes of 1%, 5% and 20% of the scene's extent, checks
each answer and its block reads against the same query on the local copy,
and prints the means per set: block reads, requests, round trips, KiB
fetched, and the open's requests and round trips.

    python python/benchmarks/remote_queries.py --mktree target/release/mktree \\
        --url http://127.0.0.1:8080/ship5.mkt --local ship5.mkt --queries 40

docs/object-storage.md quotes its figures.
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import subprocess
from typing import Any


def query(mktree: str, target: str, box: list[float]) -> dict[str, Any]:
    out = subprocess.run(
        [mktree, "query", target, "--box", ",".join(f"{v:.1f}" for v in box), "--json"],
        capture_output=True, text=True, check=True,
    ).stdout
    answer: dict[str, Any] = json.loads(out)
    return answer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mktree", default="target/release/mktree")
    ap.add_argument("--url", required=True, help="the file's URL")
    ap.add_argument("--local", required=True, help="the same file on disk")
    ap.add_argument("--queries", type=int, default=40, help="boxes per set")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    stats = json.loads(subprocess.run([args.mktree, "stats", args.local, "--json"],
                                      capture_output=True, text=True, check=True).stdout)
    box = stats["file"]["scene_box"]
    lo, ext = box[:3], [box[i + 3] - box[i] for i in range(3)]
    print("| set | block reads | requests | round trips | KiB fetched | open: requests, round trips |")
    print("| --- | --- | --- | --- | --- | --- |")
    for share in (0.01, 0.05, 0.2):
        rng = random.Random(args.seed)
        rows = []
        for _ in range(args.queries):
            size = [e * share for e in ext]
            at = [lo[i] + rng.random() * (ext[i] - size[i]) for i in range(3)]
            b = at + [at[i] + size[i] for i in range(3)]
            remote, local = query(args.mktree, args.url, b), query(args.mktree, args.local, b)
            if remote["objects"] != local["objects"] or remote["block_reads"] != local["block_reads"]:
                raise SystemExit(f"the remote answer to {b} differs from the local one")
            t = remote["transfer"]
            rows.append((remote["block_reads"]["total"], t["query"]["requests"], t["query"]["round_trips"],
                         t["query"]["bytes"] / 1024, t["open"]["requests"], t["open"]["round_trips"]))
        m = [statistics.mean(r[i] for r in rows) for i in range(6)]
        print(f"| box {share * 100:g}% | {m[0]:.2f} | {m[1]:.2f} | {m[2]:.2f} | {m[3]:.0f} | {m[4]:.1f}, {m[5]:.1f} |")


if __name__ == "__main__":
    main()
