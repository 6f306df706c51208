"""What verifying an artifact costs (pipelines.artifacts.verify), and why sha256.

Prints, for one artifact: hashlib's digests and zlib's CRC over 256 MB in one thread (GB/s),
then verify() of the file with its pages evicted from the page cache first (cold: read from
disk; posix_fadvise DONTNEED on this file only) and with them cached (warm), each the median
of --repeat runs, and with the block hashing in one thread against all.

Usage: .venv/bin/python benchmarks/bench_checksums.py OUT/fem.h5 [--repeat 3]
"""
from __future__ import annotations

import argparse
import hashlib
import os
import statistics
import sys
import time
import zlib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipelines import artifacts as art  # noqa: E402


def _throughput(repeat: int) -> dict:
    data = os.urandom(256 << 20)
    view = memoryview(data)
    out = {}
    for name in ("sha256", "sha1", "md5", "blake2b", "sha512"):
        times = []
        for _ in range(repeat):
            h, t0 = hashlib.new(name), time.perf_counter()
            for k in range(0, len(data), 1 << 24):
                h.update(view[k:k + (1 << 24)])
            times.append(time.perf_counter() - t0)
        out[name] = len(data) / statistics.median(times) / 1e9
    times = []
    for _ in range(repeat):
        c, t0 = 0, time.perf_counter()
        for k in range(0, len(data), 1 << 24):
            c = zlib.crc32(view[k:k + (1 << 24)], c)
        times.append(time.perf_counter() - t0)
    out["zlib.crc32"] = len(data) / statistics.median(times) / 1e9
    return out


def _evict(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)


def _verify_time(path: Path, cold: bool) -> float:
    if cold:
        _evict(path)
    t0 = time.perf_counter()
    assert art.verify(path) is None, art.verify(path)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("artifact", type=Path)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    size = args.artifact.stat().st_size
    print(f"one thread, 256 MB in memory, median of {args.repeat}:")
    for name, rate in _throughput(args.repeat).items():
        print(f"  {name:11s} {rate:5.2f} GB/s")
    print(f"verify({args.artifact}) ({size / 1e9:.2f} GB), median of {args.repeat}:")
    cores = len(os.sched_getaffinity(0))
    real = os.sched_getaffinity
    for threads in sorted({1, cores}):
        os.sched_getaffinity = (lambda pid, n=threads: set(range(n)))  # the pool's size
        try:
            for cold in (True, False):
                times = [_verify_time(args.artifact, cold) for _ in range(args.repeat)]
                t = statistics.median(times)
                print(f"  {threads} thread(s), {'cold' if cold else 'warm'}: {t:.2f} s ({size / t / 1e9:.2f} GB/s; "
                      f"runs {', '.join(f'{x:.2f}' for x in times)})")
        finally:
            os.sched_getaffinity = real
    return 0


if __name__ == "__main__":
    sys.exit(main())
