"""Dataset synthesis on Ray: one task per shard of `matedit synth`.

    from matedit.ray import synth_ray
    summary = synth_ray("spec.json", "/data/ds", num_shards=16)

Each task runs `matedit.synth(spec, out_dir, shard=(i, num_shards))` in a Ray worker; the
driver then checks every chunk and writes the final manifest (`matedit.synth_verify`).
Sample k depends on the spec, its seed and k alone, so the chunk files are the same bytes
as one `matedit synth` run writes, whatever the number of shards or workers. On a cluster,
the spec, its inputs and `out_dir` must be on a file system every node sees under the
same path. A failed or lost task can simply be run again: chunks already complete are
skipped.
"""

from __future__ import annotations

import os
import time

import matedit


def _shard(spec: str, out_dir: str, index: int, count: int, device: str, threads: int) -> dict:
    import matedit as m

    return m.synth(spec, out_dir, shard=(index, count), device=device, threads=threads)


def synth_ray(
    spec,
    out_dir,
    num_shards: int,
    *,
    device: str = "cpu",
    ray_address: str | None = None,
    num_cpus: int = 1,
) -> dict:
    """Writes the dataset of `spec` into `out_dir` as `num_shards` Ray tasks.

    ray_address: the cluster to join (None: the running instance if `ray.init` was
    called, else a new local one). num_cpus: CPUs each task asks Ray for, and the
    threads it renders with. Returns a summary dict: samples, seconds (wall clock, tasks
    to verified manifest), samples_per_second, shards (each task's summary), and the
    verification's chunks_total, chunks_present, missing and complete. The spec is
    checked before any task starts: a bad spec raises ValueError naming the item and
    writes nothing.
    """
    import ray

    spec = os.path.abspath(os.fspath(spec))
    out_dir = os.path.abspath(os.fspath(out_dir))
    if num_shards < 1:
        raise ValueError(f"num_shards: {num_shards} must be at least 1")
    matedit.synth_check(spec, out_dir, shard=(0, num_shards), device=device)
    if not ray.is_initialized():
        ray.init(address=ray_address)
    task = ray.remote(num_cpus=num_cpus)(_shard)
    t0 = time.perf_counter()
    refs = [task.remote(spec, out_dir, i, num_shards, device, num_cpus) for i in range(num_shards)]
    shards = ray.get(refs)
    verified = matedit.synth_verify(spec, out_dir, device=device)
    seconds = time.perf_counter() - t0
    samples = sum(s["samples"] for s in shards)
    return {
        "samples": samples,
        "seconds": seconds,
        "samples_per_second": samples / seconds if seconds > 0 else 0.0,
        "shards": shards,
        **verified,
    }
