"""What one sync costs against how many places a commit's blocks lie in.

A copy-on-write commit writes its blocks wherever the free list has room
and then syncs once (format-spec/commit.md). This measures, on the disk
under `--dir`, the time of `--blocks` writes of `--block-size` bytes plus a
128-byte slot write near the start of the file and one `fdatasync`, with
the blocks in 1, 2, 3, 4, 6 or all-separate runs at random places of a
scratch file of `--mb` megabytes (written in full first, so that no write
allocates). It prints the median over `--reps` commits per layout.

    python benchmarks/sync_runs.py --dir /tmp --mb 1200

docs/changes.md quotes its figures for ship 10^6 (a 1.2 GB file).
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import time


def commit_ms(fd: int, offsets: list[int], block: bytes) -> float:
    """Writes `block` at each offset and a slot, syncs; milliseconds."""
    started = time.perf_counter()
    for at in offsets:
        os.pwrite(fd, block, at)
    os.pwrite(fd, block[:128], 640)
    os.fdatasync(fd)
    return (time.perf_counter() - started) * 1e3


def layout(rng: random.Random, blocks: int, runs: int, file_blocks: int, size: int) -> list[int]:
    """Byte offsets of `blocks` blocks in `runs` runs at random places."""
    offsets: list[int] = []
    per, extra = divmod(blocks, runs)
    for r in range(runs):
        n = per + (1 if r < extra else 0)
        first = rng.randrange(1, file_blocks - n)
        offsets += [(first + i) * size for i in range(n)]
    return offsets


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=".", help="where the scratch file goes (removed afterwards)")
    ap.add_argument("--mb", type=int, default=1200, help="scratch file size in MB")
    ap.add_argument("--blocks", type=int, default=12, help="blocks per commit")
    ap.add_argument("--block-size", type=int, default=16384)
    ap.add_argument("--reps", type=int, default=60, help="commits per layout")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.blocks < 1 or args.mb < 1 or args.block_size < 128 or args.reps < 1:
        ap.error("--blocks, --mb and --reps must be positive, --block-size at least 128")
    size: int = args.block_size
    file_blocks = args.mb * 1_000_000 // size
    if file_blocks < 2 * args.blocks + 2:
        ap.error("the scratch file must hold at least twice --blocks blocks")
    path = os.path.join(args.dir, f"sync-runs-{os.getpid()}.bin")
    rng = random.Random(args.seed)
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        chunk = os.urandom(1 << 20)
        for at in range(0, file_blocks * size, len(chunk)):
            os.pwrite(fd, chunk[: min(len(chunk), file_blocks * size - at)], at)
        os.fsync(fd)
        block = os.urandom(size)
        print(f"{args.blocks} blocks of {size} bytes, one sync, median of {args.reps} commits:")
        for runs in sorted({1, 2, 3, 4, 6, args.blocks}):
            if runs > args.blocks:
                continue
            times = [commit_ms(fd, layout(rng, args.blocks, runs, file_blocks, size), block) for _ in range(args.reps)]
            print(f"  {runs:3d} run(s): {statistics.median(times):.3f} ms")
    finally:
        os.close(fd)
        os.remove(path)


if __name__ == "__main__":
    main()
