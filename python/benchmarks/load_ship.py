"""Bulk load through the package against the CLI's build, same objects.

The CLI generates ship N as OBJ and builds it (``mktree build --json``,
whose ``seconds`` exclude reading the OBJ). The package reads the same OBJ
into numpy arrays with ``mktree.read_scene`` (not timed: that is import)
and times ``with db.write() as w: w.bulk_load(objects)`` from the arrays
to the commit: checking and converting the arrays, building the tree,
writing and committing. Runs alternate, and the medians are compared.

    python benchmarks/load_ship.py --cli target/release/mktree --objects 100000 --repeats 3
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

import mktree


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cli", required=True, help="the mktree binary")
    ap.add_argument("--objects", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", default=None, help="scratch folder (default: a temporary one)")
    args = ap.parse_args()
    work = args.dir or tempfile.mkdtemp(prefix="mktree-load-")
    obj = os.path.join(work, f"ship{args.objects}.obj")
    if not os.path.exists(obj):
        subprocess.run([args.cli, "gen", "ship", "--objects", str(args.objects), "-o", obj], check=True)

    started = time.perf_counter()
    objects = mktree.read_scene(obj)
    read_seconds = time.perf_counter() - started
    print(f"read_scene: {len(objects)} objects as numpy arrays in {read_seconds:.2f} s (not counted)")

    cli, cli_wall, py = [], [], []
    for i in range(args.repeats):
        out = os.path.join(work, f"cli{i}.mkt")
        started = time.perf_counter()
        run = subprocess.run([args.cli, "build", obj, "-o", out, "--json"], check=True, capture_output=True, text=True)
        cli_wall.append(time.perf_counter() - started)
        cli.append(json.loads(run.stdout)["seconds"])
        os.remove(out)

        path = os.path.join(work, f"py{i}.mkt")
        started = time.perf_counter()
        db = mktree.Database.create(path)
        with db.write() as w:
            w.bulk_load(objects)
        py.append(time.perf_counter() - started)
        db.close()
        os.remove(path)
        print(f"run {i + 1}: CLI build {cli[-1]:.2f} s (wall with its OBJ read {cli_wall[-1]:.2f} s), package {py[-1]:.2f} s")

    c, p = statistics.median(cli), statistics.median(py)
    print(f"median of {args.repeats}: CLI {c:.2f} s, package {p:.2f} s: {p / c:.2f}x the CLI's build "
          f"({p + read_seconds:.2f} s with read_scene against the CLI's {statistics.median(cli_wall):.2f} s wall)")


if __name__ == "__main__":
    main()
