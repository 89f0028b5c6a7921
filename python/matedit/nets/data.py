"""Streaming `matedit synth` datasets: chunk tars read one at a time, never whole.

    ds = ChunkStream("ds", batch_size=8, seed=0)     # an infinite stream of batches
    loader = torch.utils.data.DataLoader(ds, batch_size=None, num_workers=2)
    for step, batch in zip(range(steps), loader): ...   # dict of tensors, batch first

Batch g of the stream is made by one "role": r = g mod R with R = DataLoader workers (1
without workers); on DDP rank k the role reads the chunks of shard k R + r of world R. Each
epoch the chunks are permuted with (seed, epoch) and dealt out to the shards in turn; a shard
reads its chunks in that order, one tar at a time, through a shuffle buffer seeded by
(seed, epoch, shard). So the stream is a pure function of the seed, the ranks and the
workers; `start_step` resumes it at batch `start_step` exactly (the skipped samples are not
decoded), which is all a checkpoint records of the data position.

`read_chunk(path)` yields one tar's samples; `samples(folder)` every sample once, in order.

`Resident(folder, device)` holds every sample of a folder in one device's memory instead,
for a GPU that must not wait: `batch(generator)` draws a batch by index on the device, and
`refresh()` adds the chunks that a `matedit synth` still writing there has finished since.
"""

from __future__ import annotations

import io
import json
import pathlib
import tarfile

import numpy as np
import torch

MEMBERS = ("env.npy", "image.npy", "material.json", "normals.npy")
EDIT = "edit.npy"  # the true edit, in datasets whose spec has "edit" (docs/synth.md)


def chunks(folder, allow_none: bool = False) -> list[dict]:
    """The chunk records of a synth folder ({"file", "first", "count"}), in chunk order;
    none is an error unless `allow_none`."""
    d = pathlib.Path(folder)
    if not d.is_dir():
        raise ValueError(f"{d}: not a folder (a dataset is a folder that `matedit synth` wrote)")
    recs = []
    for p in sorted(d.glob("chunk-*.json")):
        try:
            r = json.loads(p.read_text())
            recs.append({"file": str(d / r["file"]), "first": int(r["first"]), "count": int(r["count"])})
        except (ValueError, KeyError, TypeError) as e:
            raise ValueError(f"{p}: not a synth chunk record ({e})") from None
    if not recs and not allow_none:
        raise ValueError(f"{d}: no chunk-*.json records; write a dataset there with `matedit synth SPEC -o {d}`")
    return recs


def spec_digest(folder) -> str | None:
    """The SHA-256 of the spec that wrote a synth folder (its manifest's), if it has one;
    for a list of folders, their digests joined by commas (None where none has one)."""
    if isinstance(folder, list):
        digests = [spec_digest(f) for f in folder]
        return ",".join(d or "" for d in digests) if any(digests) else None
    try:
        return json.loads((pathlib.Path(folder) / "manifest.json").read_text()).get("spec_sha256")
    except (OSError, ValueError):
        return None


def decode(key: str, members: dict[str, bytes], where: str) -> dict:
    """One sample's tensors from its tar members: image, normals, env (float32, channels
    last), mask (bool; mask.npy where present, else normals != 0), ctrl (float32 (108,)),
    index (int64); edit (float32, as image) where the sample has edit.npy. Other members
    are ignored."""
    missing = [m for m in MEMBERS if m not in members]
    if missing:
        raise ValueError(f"{where}: sample {key}: missing {', '.join(missing)}")
    try:
        arr = {m.split(".")[0]: np.load(io.BytesIO(members[m])) for m in MEMBERS if m.endswith(".npy")}
        ctrl = np.asarray(json.loads(members["material.json"])["ctrl"], dtype=np.float32)
        mask = np.load(io.BytesIO(members["mask.npy"])) != 0 if "mask.npy" in members else None
        if EDIT in members:
            arr["edit"] = np.load(io.BytesIO(members[EDIT]))
    except Exception as e:
        raise ValueError(f"{where}: sample {key}: unreadable ({e})") from None
    if mask is None:
        mask = np.any(arr["normals"] != 0, axis=-1)
    shapes = {arr["image"].shape, arr["normals"].shape, arr.get("edit", arr["image"]).shape}
    if ctrl.shape != (108,) or len(shapes) != 1 or mask.shape != arr["image"].shape[:2]:
        raise ValueError(f"{where}: sample {key}: inconsistent shapes")
    out = {k: torch.from_numpy(np.ascontiguousarray(v, dtype=np.float32)) for k, v in arr.items()}
    out.update(mask=torch.from_numpy(mask), ctrl=torch.from_numpy(ctrl), index=torch.tensor(int(key)))
    return out


def read_chunk(path, keys: set[str] | None = None):
    """(key, sample) of one chunk tar in member order; with `keys`, only those decoded."""
    where = str(path)
    try:
        with tarfile.open(path) as tar:
            key, members = None, {}
            for info in tar:
                k, _, kind = info.name.partition(".")
                if k != key and key is not None:
                    if keys is None or key in keys:
                        yield key, decode(key, members, where)
                    members = {}
                key = k
                if keys is None or k in keys:
                    members[kind] = tar.extractfile(info).read()
            if key is not None and (keys is None or key in keys):
                yield key, decode(key, members, where)
    except (tarfile.TarError, OSError) as e:
        raise ValueError(f"{where}: not a readable tar ({e})") from None


def samples(folder):
    """Every sample of a dataset once, in index order, one chunk in memory at a time."""
    for rec in chunks(folder):
        for _, s in read_chunk(rec["file"]):
            yield s


def _keys(rec: dict) -> list[str]:
    return [f"{i:08d}" for i in range(rec["first"], rec["first"] + rec["count"])]


def collate(batch: list[dict]) -> dict:
    return {k: torch.stack([s[k] for s in batch]) for k in batch[0]}


class ChunkStream(torch.utils.data.IterableDataset):
    """An infinite, seeded stream of batches (dicts of tensors) from a synth folder, split by
    chunk across DataLoader workers and DDP ranks (see the module's docstring)."""

    def __init__(self, folder, batch_size: int, seed: int = 0, rank: int = 0, world: int = 1,
                 shuffle_buffer: int = 64, start_step: int = 0):
        super().__init__()
        self.recs = chunks(folder)
        self.folder = str(folder)
        self.batch_size, self.seed, self.rank, self.world = batch_size, seed, rank, world
        self.buffer, self.start_step = max(1, shuffle_buffer), start_step

    def shard_chunks(self, epoch: int, shard: int, shards: int) -> list[dict]:
        perm = np.random.default_rng([self.seed, epoch]).permutation(len(self.recs))
        return [self.recs[i] for i in perm[shard::shards]]

    def epoch_order(self, epoch: int, shard: int, shards: int) -> list[tuple[int, str]]:
        """(chunk position, key) in the order the shard yields them in `epoch`: its chunks'
        keys in turn, through a shuffle buffer."""
        rng = np.random.default_rng([self.seed, epoch, shard])
        buf, out = [], []
        for c, rec in enumerate(self.shard_chunks(epoch, shard, shards)):
            for key in _keys(rec):
                if len(buf) < self.buffer:
                    buf.append((c, key))
                else:
                    j = int(rng.integers(self.buffer))
                    out.append(buf[j])
                    buf[j] = (c, key)
        rng.shuffle(buf)
        return out + buf

    def role_samples(self, shard: int, shards: int, skip: int):
        """The shard's samples, epoch after epoch, from sample number `skip` on."""
        # synth chunks hold the same count and a shard gets as many chunks every epoch
        epoch, skip = divmod(skip, sum(r["count"] for r in self.shard_chunks(0, shard, shards)))
        while True:
            order = self.epoch_order(epoch, shard, shards)[skip:]
            recs = self.shard_chunks(epoch, shard, shards)
            pending, loaded = {}, 0
            wanted = {}
            for c, key in order:
                wanted.setdefault(c, set()).add(key)
            for c, key in order:
                while (c, key) not in pending:
                    if loaded > c:
                        raise ValueError(f"{recs[c]['file']}: sample {key} is missing (its record counts it)")
                    # read the next chunk, keeping only the samples still to come
                    if loaded in wanted:
                        for k, s in read_chunk(recs[loaded]["file"], wanted[loaded]):
                            pending[(loaded, k)] = s
                    loaded += 1
                yield pending.pop((c, key))
            epoch, skip = epoch + 1, 0

    def __iter__(self):
        info = torch.utils.data.get_worker_info()
        worker, workers = (info.id, info.num_workers) if info else (0, 1)
        shards = self.world * workers
        if len(self.recs) < shards:
            raise ValueError(
                f"{self.folder}: {len(self.recs)} chunks for {shards} readers ({self.world} ranks x "
                f"{workers} workers); every reader needs a chunk: use fewer workers or smaller chunks"
            )
        # the DataLoader takes batches from its workers in turn, starting at worker 0: worker
        # w makes the batches g >= start_step with g mod workers = role
        role = (worker + self.start_step) % workers
        first = self.start_step + worker  # the first batch this worker makes
        done = len(range(role, first, workers))  # batches of this role made before it
        stream = self.role_samples(self.rank * workers + role, shards, done * self.batch_size)
        while True:
            yield collate([next(stream) for _ in range(self.batch_size)])


class Resident:
    """Every sample of a synth folder in memory on `device` (images, normals, masks, lights
    and materials as stacked tensors), growing by `refresh()` as chunks appear; a chunk's
    record is written after its tar, so a recorded chunk is complete. The tensors grow by
    doubling their capacity, so that adding a chunk copies only the chunk."""

    def __init__(self, folder, device="cpu"):
        self.folder, self.device = str(folder), torch.device(device)
        self.loaded: set[str] = set()
        self.store: dict[str, torch.Tensor] = {}
        self.count = 0
        self.refresh()
        if not self.count:
            chunks(folder)  # raises: no chunk records

    def __len__(self) -> int:
        return self.count

    @property
    def tensors(self) -> dict[str, torch.Tensor]:
        return {k: v[: self.count] for k, v in self.store.items()}

    def refresh(self) -> int:
        """Loads the chunks recorded since the last call; returns how many samples came."""
        new = [r for r in chunks(self.folder, allow_none=True) if r["file"] not in self.loaded]
        for r in new:
            part = collate([s for _, s in read_chunk(r["file"])])
            n = len(part["index"])
            if not self.store or self.count + n > len(self.store["index"]):
                size = max(2 * len(self.store["index"]) if self.store else 0, self.count + n)
                grown = {k: v.new_empty((size, *v.shape[1:]), device=self.device) for k, v in part.items()}
                for k, v in self.store.items():
                    grown[k][: self.count] = v[: self.count]
                self.store = grown
            for k, v in part.items():
                self.store[k][self.count : self.count + n] = v.to(self.device)
            self.count += n
            self.loaded.add(r["file"])
        return sum(r["count"] for r in new)

    def batch(self, size: int, generator: torch.Generator) -> dict:
        """`size` samples drawn uniformly with replacement by `generator` (on the CPU, so
        that the draws do not depend on the device)."""
        idx = torch.randint(self.count, (size,), generator=generator).to(self.device)
        return {k: v[idx] for k, v in self.store.items()}


class Mixed:
    """Several synth folders, each a Resident on `device`, drawn in equal shares: a batch of
    `size` takes size / n samples from each of the n folders (their order in the batch),
    whatever their sizes, so that a small folder counts as much as a big one."""

    def __init__(self, folders, device="cpu"):
        self.parts = [Resident(f, device) for f in folders]

    def __len__(self) -> int:
        return sum(len(p) for p in self.parts)

    def refresh(self) -> int:
        return sum(p.refresh() for p in self.parts)

    def batch(self, size: int, generator: torch.Generator) -> dict:
        n = len(self.parts)
        if size % n:
            raise ValueError(f"batch_size {size} does not split into equal shares of {n} folders")
        shares = [p.batch(size // n, generator) for p in self.parts]
        keys = [k for k in shares[0] if all(k in s for s in shares)]  # an edit only some folders have
        return {k: torch.cat([s[k] for s in shares]) for k in keys}
