"""What a commit would cost with a log file beside the tree (issue 33).

A copy-on-write commit today writes its blocks where the free list has room
and syncs the file once (format-spec/commit.md). The alternative measured
here is SQLite's WAL: a commit appends its blocks and a commit record to a
separate log file and syncs only the log; the blocks are written to their
places in the main file without a sync, and every `--checkpoint` commits
the main file is synced and the log restarted. Both write `--blocks` blocks
of `--block-size` bytes per commit in a scratch file of `--mb` megabytes;
today's layout puts them in `--runs` runs near each other (the free list's
low holes). Prints the median and mean milliseconds per commit, the mean
counting the checkpoints.

    python python/benchmarks/log_sync.py --dir /tmp --mb 1200

docs/changes.md quotes its figures.
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=".", help="where the scratch files go (removed afterwards)")
    ap.add_argument("--mb", type=int, default=1200)
    ap.add_argument("--blocks", type=int, default=15, help="blocks per commit")
    ap.add_argument("--block-size", type=int, default=16384)
    ap.add_argument("--runs", type=int, default=6, help="runs a copy-on-write commit's blocks lie in")
    ap.add_argument("--commits", type=int, default=400)
    ap.add_argument("--checkpoint", type=int, nargs="+", default=[50, 200], help="commits per checkpoint")
    args = ap.parse_args()
    size, n = args.block_size, args.blocks
    file_blocks = args.mb * 1_000_000 // size
    rng = random.Random(0)
    main_path = os.path.join(args.dir, "log_sync_main.bin")
    log_path = os.path.join(args.dir, "log_sync_log.bin")
    block = os.urandom(size)
    with open(main_path, "wb") as f:
        for _ in range(file_blocks // 64):
            f.write(block * 64)
    fd = os.open(main_path, os.O_RDWR)
    os.fsync(fd)

    def places(runs: int) -> list[int]:
        base = rng.randrange(1, file_blocks // 8)
        per, extra = divmod(n, runs)
        out: list[int] = []
        for r in range(runs):
            first = base + rng.randrange(0, 2000)
            out += [(first + i) * size for i in range(per + (1 if r < extra else 0))]
        return out

    def report(name: str, times: list[float]) -> None:
        print(f"{name}: median {statistics.median(times):.3f} ms, mean {statistics.mean(times):.3f} ms")

    try:
        for runs in sorted({1, args.runs, n}):
            times = []
            for _ in range(args.commits):
                at = places(runs)
                start = time.perf_counter()
                for offset in at:
                    os.pwrite(fd, block, offset)
                os.pwrite(fd, block[:128], 640)
                os.fdatasync(fd)
                times.append((time.perf_counter() - start) * 1e3)
            report(f"in place, {runs} runs, one sync", times)
        for every in args.checkpoint:
            log = os.open(log_path, os.O_RDWR | os.O_CREAT | os.O_TRUNC)
            os.pwrite(log, b"\0" * ((n * size + 4096) * every + size), 0)
            os.fsync(log)
            times, checkpoints, end = [], [], size
            for i in range(args.commits):
                at = places(args.runs)
                start = time.perf_counter()
                os.pwrite(log, block * n + block[:4096], end)
                end += n * size + 4096
                os.fdatasync(log)
                for offset in at:
                    os.pwrite(fd, block, offset)
                os.pwrite(fd, block[:128], 640)
                if (i + 1) % every == 0:
                    c = time.perf_counter()
                    os.fdatasync(fd)
                    os.pwrite(log, block[:4096], 0)
                    os.fdatasync(log)
                    end = size
                    checkpoints.append((time.perf_counter() - c) * 1e3)
                times.append((time.perf_counter() - start) * 1e3)
            os.close(log)
            report(f"log, checkpoint every {every} (checkpoint median {statistics.median(checkpoints):.1f} ms)", times)
    finally:
        os.close(fd)
        for p in (main_path, log_path):
            if os.path.exists(p):
                os.remove(p)


if __name__ == "__main__":
    main()
