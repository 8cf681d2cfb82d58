#!/usr/bin/env python3
"""hbv.dask against one process: closest hits of incoherent rays on the dragon, a local cluster of
2 worker processes x 1 thread against one process on 2 threads (same machine, one run).

Rays: from a sphere of radius D (the box's diagonal) about the mesh's box centre towards uniform
points of the box (python_compare.py's "random" set), generated chunk by chunk from (seed, chunk
index), float32. Every run answers the same rays with ``intersect`` and reduces the hits on the
side that computed them (hit count and sum of t), so no answer crosses a process.

1. one process: ``bvh.intersect(o, d, threads=2)`` over the chunks, in memory;
2. the cluster, structure from a shared ``.hbv`` file (``hbv.dask.open``), loaded by a warm-up:
   a. streaming: rays generated inside the graph, peak resident memory of each worker
      (``ru_maxrss``) against its idle size + the structure's + 4 chunks;
   b. throughput: the rays persisted on the workers first, then ``intersect`` timed, in rounds
      interleaved with (1) (medians of --repeat; the ratio: the median of the rounds' ratios,
      target >= 0.9x); and the rays per CPU second of each side (workers + client + scheduler
      against the one process), which a machine shared with other work disturbs less;
   c. per-task overhead: ``count`` and a sum on --tiny-chunks chunks of one ray each;
      (wall x workers) / chunks.

    /work/venv-dask/bin/python bench/dask_scaling.py [MESH.ply] [--rays 20000000] [--chunk 1000000]
"""

import argparse
import os
import pathlib
import statistics
import sys
import tempfile
import time

import numpy as np

SCENES = pathlib.Path(__file__).resolve().parent.parent.parent / "shared/scenes"


def incoherent_rays(lo, hi, n, seed, chunk_index, part):
    """Chunk ``chunk_index`` of the rays: origins (part 0) or unit directions (part 1), float32."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    rng = np.random.default_rng([seed, chunk_index])
    centre, diagonal = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    s = rng.normal(size=(n, 3))
    origins = centre + s / np.linalg.norm(s, axis=1)[:, None] * diagonal
    if part == 0:
        return origins.astype(np.float32)
    toward = lo + (hi - lo) * rng.uniform(size=(n, 3)) - origins
    return (toward / np.linalg.norm(toward, axis=1)[:, None]).astype(np.float32)


def lazy_rays(lo, hi, n, chunk, seed):
    import dask.array as da

    rows = tuple(min(chunk, n - start) for start in range(0, n, chunk))

    def make(part):
        def block(block_id=None):
            return incoherent_rays(lo, hi, rows[block_id[0]], seed, block_id[0], part)

        return da.map_blocks(block, chunks=(rows, (3,)), dtype=np.float32,
                             name=f"bench-rays-{part}-{n}-{chunk}-{seed}",
                             meta=np.empty((0, 3), np.float32))

    return make(0), make(1)


def cpu_seconds():
    """User + system CPU seconds of this process, all its threads."""
    times = os.times()
    return times.user + times.system


def worker_memory(reset_peak=False):
    """This process's resident and peak resident bytes (VmRSS, VmHWM); reset_peak: then start
    the peak again from the current size (Linux: 5 > /proc/self/clear_refs)."""
    status = dict(line.split(":", 1) for line in pathlib.Path("/proc/self/status").read_text().splitlines())
    kib = lambda field: int(status[field].split()[0]) * 1024  # noqa: E731
    memory = {"rss": kib("VmRSS"), "peak": kib("VmHWM")}
    if reset_peak:
        pathlib.Path("/proc/self/clear_refs").write_text("5")
    return memory


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mesh", nargs="?", default=str(SCENES / "dragon.ply"))
    parser.add_argument("--rays", type=int, default=20_000_000)
    parser.add_argument("--chunk", type=int, default=1_000_000)
    parser.add_argument("--tiny-chunks", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    if not os.path.exists(args.mesh):
        print(f"skipped: {args.mesh} not found (the dragon lives in /work/shared/scenes)")
        return

    import dask
    from distributed import Client, LocalCluster, wait

    import hbv
    import hbv.dask

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from machine import describe, machine

    mesh = hbv.load(args.mesh)
    bvh = hbv.BVH(mesh)
    lo, hi = mesh.bounds
    folder = tempfile.mkdtemp(prefix="hbv-dask-bench-")
    path = os.path.join(folder, "mesh.hbv")
    bvh.save(path)
    n, chunk = args.rays, args.chunk
    chunk_count = -(-n // chunk)
    print(f"# {describe(machine(('numpy', 'dask', 'distributed')))}")
    print(f"# {pathlib.Path(args.mesh).name}: {mesh.triangle_count:,} triangles, {n:,} rays in "
          f"{chunk_count} chunks of {chunk:,}; .hbv file {os.path.getsize(path) / 2**20:.0f} MiB")

    rays = [(incoherent_rays(lo, hi, min(chunk, n - i * chunk), args.seed, i, 0),
             incoherent_rays(lo, hi, min(chunk, n - i * chunk), args.seed, i, 1))
            for i in range(chunk_count)]
    bvh.intersect(*rays[0], threads=2)  # the layout is made on the first call

    def one_process():
        """1. One process on 2 threads: (seconds, CPU seconds, hits)."""
        start, cpu = time.perf_counter(), cpu_seconds()
        hits = t_sum = 0
        for o, d in rays:
            answer = bvh.intersect(o, d, threads=2)
            hits += int(answer["hit"].sum())
            t_sum += float(answer["t"].astype(np.float64)[answer["hit"]].sum())
        return time.perf_counter() - start, cpu_seconds() - cpu, hits

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0", memory_limit=0) as cluster, Client(cluster) as client:
        handle = hbv.dask.open(path)
        idle = client.run(worker_memory)
        start = time.perf_counter()
        hbv.dask.preload(handle, client, warm=("intersect",))
        load_seconds = time.perf_counter() - start
        loaded = client.run(worker_memory, reset_peak=True)

        def reduced(o, d):
            answer = hbv.dask.intersect(handle, o, d)
            return answer["hit"].sum(), answer["t"].astype(np.float64)[answer["hit"]].sum()

        # 2a. Streaming, peak memory.
        start = time.perf_counter()
        streamed = dask.compute(*reduced(*lazy_rays(lo, hi, n, chunk, args.seed)))
        streaming = time.perf_counter() - start
        peaks = client.run(worker_memory)
        chunk_bytes = chunk * (2 * 12 + 33)  # float32 origins, directions; hit, t, prim, u, v, normal
        print(f"hbv.dask.preload on both workers (read, load, first intersect): {load_seconds:.2f} s")
        print(f"streaming (rays made in the graph): {streaming:.2f} s, {n / streaming / 1e6:.2f} M rays/s")
        print("| worker | idle | structure | peak while loading | peak while streaming | "
              "streaming peak − idle | structure + 4 chunks |")
        print("|---|---|---|---|---|---|---|")
        mib = lambda b: f"{b / 2**20:.0f} MiB"  # noqa: E731
        for worker in sorted(peaks):
            base = idle[worker]["rss"]
            structure = loaded[worker]["rss"] - base
            print(f"| {worker.rsplit(':', 1)[-1]} | {mib(base)} | {mib(structure)} | "
                  f"{mib(loaded[worker]['peak'] - base)} | {mib(peaks[worker]['peak'])} | "
                  f"{mib(peaks[worker]['peak'] - base)} | {mib(structure + 4 * chunk_bytes)} |")

        # 2b. Throughput, rays persisted on the workers, rounds interleaved with (1).
        o, d = dask.persist(*lazy_rays(lo, hi, n, chunk, args.seed))
        wait([o, d])
        def cluster_cpu():
            """CPU seconds of the workers and of this process (client and scheduler)."""
            return sum(client.run(cpu_seconds).values()) + cpu_seconds()

        rounds, cpu_rounds = [], []
        for _ in range(args.repeat):
            alone, alone_cpu, hits = one_process()
            start, cpu = time.perf_counter(), cluster_cpu()
            got = dask.compute(*reduced(o, d))
            together, together_cpu = time.perf_counter() - start, cluster_cpu() - cpu
            assert int(got[0]) == hits == int(streamed[0]), (got, hits, streamed)
            rounds.append((alone, together))
            cpu_rounds.append((alone_cpu, together_cpu))
        alone = statistics.median(a for a, _ in rounds)
        together = statistics.median(t for _, t in rounds)
        ratio = statistics.median(a / t for a, t in rounds)
        cpu_ratio = statistics.median(a / t for a, t in cpu_rounds)
        print(f"one process, 2 threads: {alone:.2f} s, {n / alone / 1e6:.2f} M rays/s ({hits:,} hits)")
        print(f"cluster 2 x 1 thread:   {together:.2f} s, {n / together / 1e6:.2f} M rays/s, "
              f"{ratio:.2f}x one process (median of {args.repeat} interleaved rounds)")
        print("rounds (one process s, cluster s, ratio): " + ", ".join(
            f"({a:.2f}, {t:.2f}, {a / t:.2f}x)" for a, t in rounds))
        print(f"rays per CPU second, cluster (workers, client, scheduler) against one process: "
              f"{cpu_ratio:.2f}x; rounds (CPU s): " + ", ".join(
                  f"({a:.1f}, {t:.1f})" for a, t in cpu_rounds))
        del o, d

        # 2c. Per-task overhead: one ray per chunk, each chunk one `count` task and its share of
        # a sum (the reduction's tree: about one more task per chunk).
        k = args.tiny_chunks
        tiny = dask.persist(*lazy_rays(lo, hi, k, 1, args.seed))
        wait(list(tiny))
        times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            hbv.dask.count(handle, *tiny).sum().compute()
            times.append(time.perf_counter() - start)
        per_chunk = statistics.median(times) * 2 / k
        print(f"{k} one-ray chunks of count + sum: {statistics.median(times):.2f} s, "
              f"{per_chunk * 1e3:.2f} ms per chunk per worker")

if __name__ == "__main__":
    main()
