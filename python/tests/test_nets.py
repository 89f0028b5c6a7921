"""matedit.nets on a tiny dataset the tests synthesise (16 x 16 images, 8 x 16 lights):
the loss of a short run falls, a stopped and resumed run ends at the uninterrupted run's
weights bit for bit, DDP over 2 gloo processes (torchrun) trains with ranks that agree,
the data stream splits and resumes exactly, bad inputs raise ValueError naming the
problem, the balloon baseline inflates a disc into a sphere, and evaluation reports
finite metrics beside its baselines."""

import io
import json
import math
import os
import pathlib
import socket
import subprocess
import sys
import tarfile
from dataclasses import replace

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")

import matedit  # noqa: E402
from matedit.nets import NetsConfig, Nets, load, save, srgb_to_linear  # noqa: E402
from matedit.nets import data, evaluate, train  # noqa: E402
from matedit.nets.model import check_image, prepare  # noqa: E402

SPEC = {
    "count": 32,
    "image_size": 16,
    "env_size": "8x16",
    "chunk_size": 8,
    "normals": [{"shape": "blobby"}, {"sphere": 16}],
    "envs": [{"procedural": "sun-sky"}, {"procedural": "studio"}],
    "materials": [{"random": "merl"}],
}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("nets")
    for name, seed in (("train", 1), ("test", 2)):
        spec = root / f"{name}.json"
        spec.write_text(json.dumps({**SPEC, "seed": seed}))
        matedit.synth(spec, root / name, device="cpu", threads=2)
    return root


def write_config(root: pathlib.Path, name: str, **changes) -> pathlib.Path:
    settings = {
        "data": "train",
        "width": 8,
        "levels": 2,
        "env_height": 8,
        "env_width": 16,
        "steps": 30,
        "batch_size": 4,
        "lr": 3e-3,
        "warmup": 2,
        "log_every": 1000,
        "checkpoint_every": 1000,
        "seed": 5,
        # torch at 1 thread: no idle OpenMP threads spinning on the cores the layer needs,
        # whether or not torch was imported before matedit.nets (docs/nets.md, "Threads")
        "threads": 1,
    }
    settings.update(changes)
    path = root / f"{name}.py"
    path.write_text("".join(f"{k} = {v!r}\n" for k, v in settings.items()))
    return path


def test_loss_falls_and_run_files(dataset):
    cfg = train.load_config(write_config(dataset, "falls", steps=50))
    out = dataset / "runs" / "falls"
    res = train.train(cfg, out, quiet=True)
    totals = [r["total"] for r in res["history"]]
    assert res["step"] == 50 and len(totals) == 50 and all(math.isfinite(t) for t in totals)
    # seeds 5 to 8 of this config gave ratios 0.63 to 0.72
    first, last = np.mean(totals[:5]), np.mean(totals[-10:])
    assert last < 0.8 * first, (first, last)
    for f in ("ckpt.pt", "weights.safetensors", "losses.png", "run.json"):
        assert (out / f).is_file(), f
    run = json.loads((out / "run.json").read_text())
    assert run["seed"] == 5 and run["step"] == 50 and len(run["data_spec_sha256"]) == 64
    nets = load(out / "weights.safetensors")
    assert nets.cfg == NetsConfig(width=8, levels=2, env_height=8, env_width=16, image_size=16)
    assert float(nets.light_count) == 50 * 4  # the mean-light baseline saw every sample

    # evaluation on the held-out split: finite metrics beside the baselines', the CLI's JSON
    js = out / "eval.json"
    assert evaluate.main([str(out / "weights.safetensors"), str(dataset / "test"), "--json", str(js)]) == 0
    metrics = json.loads(js.read_text())
    # the training folder is refused: metrics come from a held-out split
    assert evaluate.main([str(out / "weights.safetensors"), str(dataset / "train"), "--json", str(js)]) == 2
    assert metrics["samples"] == 32
    for who in ("nets", "baselines"):
        assert {"edit_psnr_db", "edit_true_normals_psnr_db", "edit_true_light_psnr_db"} <= metrics[who].keys()
        assert all(math.isfinite(v) for v in metrics[who].values()), metrics[who]
        assert 0 <= metrics[who]["mask_iou"] <= 1
        assert 0 <= metrics[who]["normals_under_11.25_pct"] <= metrics[who]["normals_under_30_pct"] <= 100

    # at the nets' size: the same numbers where it is the data's, finite ones where the
    # nets see the images at half the data's size (and their outputs come back to it)
    plain = evaluate.evaluate(nets, dataset / "test", limit=8)["nets"]
    same = evaluate.evaluate(nets, dataset / "test", limit=8, at_nets_size=True)["nets"]
    assert same == pytest.approx(plain, rel=1e-6)
    nets.cfg = replace(nets.cfg, image_size=8)
    half = evaluate.evaluate(nets, dataset / "test", limit=8, at_nets_size=True)["nets"]
    assert all(math.isfinite(v) for v in half.values()) and half != same, half



def test_the_frame_the_nets_saw_is_kept_with_them(tmp_path):
    # "square" unless said; `matedit edit` shows "photo" nets a photo at its own shape
    nets = Nets(NetsConfig(width=8, levels=2, env_height=8, env_width=16, frame="photo"))
    save(nets, tmp_path / "photo.safetensors")
    assert load(tmp_path / "photo.safetensors").cfg.frame == "photo"
    assert load().cfg.frame == "square"
    assert load(EXAMPLES / "photo" / "weights" / "p16.safetensors").cfg.frame == "photo"
    with pytest.raises(ValueError, match="frame: 'round' is not 'square' or 'photo'"):
        Nets(replace(nets.cfg, frame="round"))

def test_resume_reaches_the_uninterrupted_weights(dataset):
    # two DataLoader workers, so that the data position is tested across workers too
    path = write_config(dataset, "resume", steps=10, workers=2, render_loss=True)
    cfg = train.load_config(path)
    whole = train.train(cfg, dataset / "runs" / "whole", quiet=True)
    stopped = train.train(cfg, dataset / "runs" / "split", stop_at=4, quiet=True)
    assert stopped["step"] == 4
    resumed = train.train(cfg, dataset / "runs" / "split", resume=True, quiet=True)
    assert resumed["step"] == 10 and resumed["history"] == whole["history"]
    a = load(dataset / "runs" / "whole" / "weights.safetensors").state_dict()
    b = load(dataset / "runs" / "split" / "weights.safetensors").state_dict()
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k
    # a changed config cannot resume the run
    other = train.load_config(write_config(dataset, "resume", steps=10, workers=2, render_loss=True, lr=1e-3))
    with pytest.raises(ValueError, match=r"config changed since the checkpoint \(lr\)"):
        train.train(other, dataset / "runs" / "split", resume=True, quiet=True)


def test_resident_mode_trains_resumes_and_follows(dataset, tmp_path):
    # the GPU mode (the data held on the device, losses read every log_every steps, bf16
    # autocast) on the CPU: the loss falls, a stopped run resumes to the same weights
    path = write_config(dataset, "resident", steps=40, resident=True, amp="bf16", log_every=5)
    cfg = train.load_config(path)
    whole = train.train(cfg, dataset / "runs" / "res_whole", quiet=True)
    totals = [r["total"] for r in whole["history"]]
    assert len(totals) == 40 and np.mean(totals[-10:]) < 0.8 * np.mean(totals[:5]), totals
    train.train(cfg, dataset / "runs" / "res_split", stop_at=15, quiet=True)
    resumed = train.train(cfg, dataset / "runs" / "res_split", resume=True, quiet=True)
    assert resumed["history"] == whole["history"]
    a = load(dataset / "runs" / "res_whole" / "weights.safetensors").state_dict()
    b = load(dataset / "runs" / "res_split" / "weights.safetensors").state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)

    # a folder that a synth is still writing: chunks recorded later are picked up
    grow = tmp_path / "grow"
    grow.mkdir()
    recs = sorted((dataset / "train").glob("chunk-*.json"))
    def add(rec):
        r = json.loads(rec.read_text())
        (grow / r["file"]).write_bytes((dataset / "train" / r["file"]).read_bytes())
        (grow / rec.name).write_text(rec.read_text())
    add(recs[0])
    held = data.Resident(grow)
    assert len(held) == 8 and held.refresh() == 0
    for rec in recs[1:]:
        add(rec)
    assert held.refresh() == 24 and len(held) == 32
    assert held.tensors["image"].shape == (32, 16, 16, 3) and held.tensors["mask"].dtype == torch.bool
    batch = held.batch(6, torch.Generator().manual_seed(0))
    assert batch["ctrl"].shape == (6, 108)
    with pytest.raises(ValueError, match="no chunk-"):
        data.Resident(tmp_path)

    # two folders in equal shares: each half of a batch comes from its own folder
    mixed = data.Mixed([grow, dataset / "test"])
    assert len(mixed) == 64
    batch = mixed.batch(8, torch.Generator().manual_seed(1))
    assert batch["image"].shape == (8, 16, 16, 3)
    images = [held.tensors["image"], mixed.parts[1].tensors["image"]]
    for half, ims in ((batch["image"][:4], images[0]), (batch["image"][4:], images[1])):
        assert all(any(torch.equal(im, x) for x in ims) for im in half)
    with pytest.raises(ValueError, match="batch_size 7 does not split into equal shares of 2"):
        mixed.batch(7, torch.Generator())
    mix = write_config(dataset, "mixed", steps=4, resident=True, data=["train", "test"])
    assert len(train.train(train.load_config(mix), dataset / "runs" / "mixed", quiet=True)["history"]) == 4
    with pytest.raises(ValueError, match="a list of folders needs resident = True"):
        train.load_config(write_config(dataset, "bad_mix", data=["train", "test"]))
    with pytest.raises(ValueError, match="follow = 5 needs resident = True"):
        train.load_config(write_config(dataset, "bad_follow", follow=5))
    with pytest.raises(ValueError, match="amp = 'fp8'"):
        train.load_config(write_config(dataset, "bad_amp", amp="fp8"))


def test_render_loss_on_either_layer_and_drawn_pixels(dataset):
    # the torch layer's rendering losses are the Rust layer's; on drawn pixels they are
    # finite, and a run with them learns
    held = data.Resident(dataset / "train")
    batch = held.batch(4, torch.Generator().manual_seed(2))
    cfgs = {layer: train.load_config(write_config(dataset, f"render_{layer}", render_loss=True, layer=layer))
            for layer in ("rust", "torch")}
    nets = Nets(NetsConfig(width=8, levels=2, env_height=8, env_width=16))
    parts = {k: train.losses(nets, batch, c, train.sphere_renderer(c, torch.device("cpu"))) for k, c in cfgs.items()}
    for k in ("render", "edit"):
        assert parts["torch"][k].item() == pytest.approx(parts["rust"][k].item(), rel=1e-4), k
    path = write_config(dataset, "render_drawn", steps=40, resident=True, render_loss=True, layer="torch", render_pixels=32)
    res = train.train(train.load_config(path), dataset / "runs" / "render_drawn", quiet=True)
    assert all(math.isfinite(r["render"]) and math.isfinite(r["edit"]) for r in res["history"])
    totals = [r["total"] for r in res["history"]]
    assert np.mean(totals[-10:]) < 0.8 * np.mean(totals[:5]), totals
    with pytest.raises(ValueError, match="render_pixels = -1"):
        train.load_config(write_config(dataset, "bad_pixels", render_pixels=-1))


def test_init_starts_from_weights(dataset):
    first = dataset / "runs" / "first"
    train.train(train.load_config(write_config(dataset, "first", steps=3)), first, quiet=True)
    # `init` is relative to the config; a run stopped at step 0 writes its starting weights
    more = train.load_config(write_config(dataset, "more", steps=5, seed=6, init="runs/first/weights.safetensors"))
    train.train(more, dataset / "runs" / "more0", stop_at=0, quiet=True)
    a = load(first / "weights.safetensors").state_dict()
    b = load(dataset / "runs" / "more0" / "weights.safetensors").state_dict()
    for k in a:
        assert torch.equal(a[k], b[k]), k
    # and training goes on from there
    train.train(more, dataset / "runs" / "more", quiet=True)
    c = load(dataset / "runs" / "more" / "weights.safetensors").state_dict()
    assert any(not torch.equal(a[k], c[k]) for k in a)
    # nets of other sizes are refused, naming the file
    wide = train.load_config(write_config(dataset, "wide", width=4, init="runs/first/weights.safetensors"))
    with pytest.raises(ValueError, match=r"first/weights.safetensors: its nets are .*width=8.*width=4"):
        train.train(wide, dataset / "runs" / "wide", quiet=True)


def test_ddp_two_processes(dataset):
    path = write_config(dataset, "ddp", steps=4)
    out = dataset / "runs" / "ddp"
    env = {**os.environ, "PYTHONPATH": str(pathlib.Path(matedit.__file__).parent.parent), "OMP_NUM_THREADS": "1"}
    with socket.socket() as s:  # a free port for the rendezvous
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_port", str(port),
           "-m", "matedit.nets.train", str(path), "--out", str(out)]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    run = json.loads((out / "run.json").read_text())
    assert run["world_size"] == 2 and run["step"] == 4 and run["ranks_agree"]
    nets = load(out / "weights.safetensors")
    assert float(nets.light_count) == 4 * 4 * 2  # both ranks' lights, all-reduced


def test_stream_splits_by_rank_and_resumes(dataset):
    folder = dataset / "train"
    epoch = []
    for rank in range(2):
        it = iter(data.ChunkStream(folder, 4, seed=3, rank=rank, world=2))
        epoch.append({int(i) for _ in range(4) for i in next(it)["index"]})
    assert not epoch[0] & epoch[1] and epoch[0] | epoch[1] == set(range(32))
    loader = torch.utils.data.DataLoader(data.ChunkStream(folder, 4, seed=3), batch_size=None, num_workers=2)
    full = [b["index"].tolist() for b, _ in zip(loader, range(12))]
    assert sorted(i for b in full[:8] for i in b) == list(range(32))  # an epoch sees every sample once
    for start in (3, 8):
        ds = data.ChunkStream(folder, 4, seed=3, start_step=start)
        loader = torch.utils.data.DataLoader(ds, batch_size=None, num_workers=2)
        assert [b["index"].tolist() for b, _ in zip(loader, range(12 - start))] == full[start:]
    b = next(iter(data.ChunkStream(folder, 4, seed=3)))
    assert b["image"].shape == (4, 16, 16, 3) and b["env"].shape == (4, 8, 16, 3) and b["ctrl"].shape == (4, 108)
    assert b["mask"].dtype == torch.bool and torch.equal(b["mask"], b["normals"].abs().sum(-1) > 0)
    with pytest.raises(ValueError, match="4 chunks for 6 readers"):
        next(iter(data.ChunkStream(folder, 4, rank=0, world=6)))


def test_bad_inputs_raise_value_error(dataset, tmp_path, capsys):
    nets = Nets(NetsConfig(width=4, levels=2, env_height=8, env_width=16))
    with pytest.raises(ValueError, match=r"image: shape \(16, 16\), expected \(H, W, 3\)"):
        nets.predict(np.zeros((16, 16), np.float32))
    bad = np.ones((16, 16, 3), np.float32)
    bad[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="image: 1 values are NaN or infinite"):
        nets.predict(bad)
    with pytest.raises(ValueError, match="image: not an image"):
        nets.predict("photo.png")
    with pytest.raises(ValueError, match="linearise it with srgb_to_linear"):
        check_image("image", np.zeros((16, 16, 3), np.uint8))
    with pytest.raises(ValueError, match="not a multiple of 2"):
        nets.predict(np.ones((15, 16, 3), np.float32))
    with pytest.raises(ValueError, match=r"mask: shape \(8, 8\)"):
        nets.predict(np.ones((16, 16, 3), np.float32), mask=np.ones((8, 8), bool))
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"not weights")
    with pytest.raises(ValueError, match="junk.safetensors: not a safetensors file"):
        load(junk)
    with pytest.raises(ValueError, match="no chunk-\\*.json records"):
        data.ChunkStream(tmp_path, 4)
    with pytest.raises(ValueError, match="unknown setting 'stepz'"):
        train.load_config(write_config(tmp_path, "typo", stepz=3))
    with pytest.raises(ValueError, match=r"lr = -1.0: expected a positive number"):
        train.load_config(write_config(tmp_path, "neg", lr=-1.0))
    with pytest.raises(ValueError, match="photo: dtype float32, expected uint8"):
        srgb_to_linear(np.zeros((2, 2, 3), np.float32))
    small_env = train.load_config(write_config(dataset, "small_env", env_height=4, steps=1))
    with pytest.raises(ValueError, match=r"train: env size 8x16, the light net's is 4x16"):
        train.train(small_env, tmp_path / "run", quiet=True)
    with pytest.raises(ValueError, match="linearise it with srgb_to_linear"):
        check_image("image", torch.zeros((16, 16, 3), dtype=torch.uint8))
    # the command lines: one line naming the file, exit code 2
    assert train.main([str(tmp_path / "missing.py")]) == 2
    assert evaluate.main([str(junk), str(dataset / "test")]) == 2
    save(nets, tmp_path / "w.safetensors")
    capsys.readouterr()
    assert evaluate.main([str(tmp_path / "w.safetensors"), str(tmp_path / "nowhere")]) == 2
    assert capsys.readouterr().err.strip().endswith("nowhere: not a folder (a dataset is a folder that `matedit synth` wrote)")


def test_predict_and_weights_round_trip(tmp_path):
    torch.manual_seed(0)
    nets = Nets(NetsConfig(width=4, levels=2, env_height=8, env_width=16))
    image = matedit.render(matedit.sphere(16), matedit.sky(8, 16), matedit.preset("gold"))
    mask = np.abs(matedit.sphere(16)).sum(-1) > 0
    out = nets.predict(image, mask)
    assert out["normals"].shape == (16, 16, 3) and out["ctrl"].shape == (108,) and out["env"].shape == (8, 16, 3)
    assert np.allclose(np.linalg.norm(out["normals"][mask], axis=-1), 1, atol=1e-5)
    assert (out["env"] > 0).all() and (out["ctrl"].reshape(3, 3, 2, 6)[:, :, 1] >= 0).all()
    save(nets, tmp_path / "w.safetensors")
    again = load(tmp_path / "w.safetensors").predict(image, mask)
    for k in out:
        assert np.array_equal(out[k], again[k]), k
    # the input convention: the masked mean of the normalised image is 1
    x = prepare(torch.from_numpy(image)[None], torch.from_numpy(mask)[None])
    lin = torch.expm1(x.abs()) * x.sign()
    assert abs(float(lin.permute(0, 2, 3, 1)[0][torch.from_numpy(mask)].mean()) - 1) < 1e-5


def test_mirrored_predictions_are_mirror_symmetric():
    from matedit.nets.model import MIRROR, mirror_env

    # the light's mirror agrees with the layer: the mirrored scene renders the mirrored image
    normals = matedit.sphere(16)
    env = (matedit.sky(8, 16) * np.linspace(0.2, 2, 16)[None, :, None]).astype(np.float32)
    gold = matedit.preset("gold")
    image = matedit.render(normals, env, gold)
    m_normals = np.ascontiguousarray(normals[:, ::-1] * np.array(MIRROR, np.float32))
    m_env = mirror_env(torch.from_numpy(env)[None])[0].numpy()
    assert np.allclose(matedit.render(m_normals, m_env, gold), image[:, ::-1], atol=1e-6)
    assert not np.allclose(matedit.render(m_normals, env, gold), image[:, ::-1], atol=1e-2)
    # averaged with its mirror, a prediction of the mirrored image is the mirrored prediction
    torch.manual_seed(0)
    nets = Nets(NetsConfig(width=4, levels=2, env_height=8, env_width=16))
    image[3:6, 2:4] *= 3  # no longer symmetric
    a, b = nets.predict(image, mirror=True), nets.predict(np.ascontiguousarray(image[:, ::-1]), mirror=True)
    assert np.array_equal(a["mask"][:, ::-1], b["mask"])
    assert np.allclose(a["normals"][:, ::-1] * np.array(MIRROR), b["normals"], atol=1e-5)
    assert np.allclose(mirror_env(torch.from_numpy(a["env"])[None])[0].numpy(), b["env"], rtol=1e-4)
    assert np.allclose(a["ctrl"], b["ctrl"], rtol=1e-4, atol=1e-4)
    plain = nets.predict(image)
    assert not np.allclose(plain["normals"], a["normals"], atol=1e-3)


def test_a_basis_of_some_presets(tmp_path):
    names = matedit.presets()[:90]
    nets = Nets(NetsConfig(width=4, levels=2, env_height=8, env_width=16, basis=[names[5], names[0]]))
    assert nets.material.presets.shape == (2, 108)
    assert np.array_equal(nets.material.presets[0].numpy(), matedit.preset(names[5]).astype(np.float32))
    save(nets, tmp_path / "w.safetensors")
    assert load(tmp_path / "w.safetensors").cfg.basis == [names[5], names[0]]
    ctrl = nets.predict(np.ones((16, 16, 3), np.float32))["ctrl"]
    lo, hi = np.minimum(*nets.material.presets.numpy()), np.maximum(*nets.material.presets.numpy())
    assert ((ctrl >= lo - 1e-4) & (ctrl <= hi + 1e-4)).all()  # a mix of the two
    with pytest.raises(ValueError, match="'gold' is not a fitted MERL preset"):
        Nets(NetsConfig(basis=["gold"]))


def test_srgb_to_linear():
    lin = srgb_to_linear(np.array([[[0, 128, 255]]], np.uint8))
    assert lin[0, 0, 0] == 0 and abs(lin[0, 0, 2] - 1) < 1e-6
    assert abs(lin[0, 0, 1] - 0.21586) < 1e-4  # ((128/255 + 0.055) / 1.055)^2.4


def test_balloon_inflates_a_disc_into_a_sphere():
    radius = 24.0
    y, x = np.mgrid[:64, :64]
    r = np.hypot(x - 31.5, y - 31.5)
    disc = r < radius
    n = evaluate.balloon(disc)
    nx, ny = (x - 31.5) / radius, -(y - 31.5) / radius  # y up: row 0 is the top
    sphere = np.stack([nx, ny, np.sqrt(np.clip(1 - nx**2 - ny**2, 0, 1))], -1)
    err = np.degrees(np.arccos(np.clip((n * sphere).sum(-1), -1, 1)))
    # the 5-point Poisson solution of a pixelated disc: within 2 degrees inside 0.8 R, 3 mean
    assert err[r < 0.8 * radius].max() < 2 and err[disc].mean() < 3
    assert (n[~disc] == 0).all() and np.allclose(np.linalg.norm(n[disc], axis=-1), 1, atol=1e-5)
    assert n[32, 10, 0] < -0.8 and n[10, 32, 1] > 0.8  # the rim faces sideways, the top up


def test_a_mask_member_is_used(dataset, tmp_path):
    """A sample's mask.npy, where present, is its mask (not the normals' support)."""
    src = dataset / "train" / "chunk-000000.tar"
    mask = np.zeros((16, 16), np.float32)  # as synth writes it
    mask[2:9, 3:7] = 1
    buf = io.BytesIO()
    np.save(buf, mask)
    with tarfile.open(src) as t, tarfile.open(tmp_path / "chunk.tar", "w") as out:
        for info in t.getmembers():
            if info.name.endswith(".mask.npy"):
                continue  # synth's own mask: replaced by the one below
            out.addfile(info, t.extractfile(info))
            if info.name.endswith(".env.npy"):
                extra = tarfile.TarInfo(info.name.replace("env.npy", "mask.npy"))
                extra.size = len(buf.getvalue())
                out.addfile(extra, io.BytesIO(buf.getvalue()))
    got = list(data.read_chunk(tmp_path / "chunk.tar"))
    assert len(got) == 8 and all(torch.equal(s["mask"], torch.from_numpy(mask != 0)) for _, s in got)
    plain = [s for _, s in data.read_chunk(src)]
    assert torch.equal(plain[0]["mask"], plain[0]["normals"].abs().sum(-1) > 0)


def test_an_edit_member_is_decoded(dataset, tmp_path):
    """A sample's edit.npy (a spec with "edit"), where present, is decoded as "edit"."""
    src = dataset / "train" / "chunk-000000.tar"
    with tarfile.open(src) as t, tarfile.open(tmp_path / "chunk.tar", "w") as out:
        for info in t.getmembers():
            data_ = t.extractfile(info).read()
            if info.name.endswith(".env.npy"):  # edit.npy sorts before env.npy, as synth writes it
                buf = io.BytesIO()
                np.save(buf, np.full((16, 16, 3), 0.25, np.float32))
                extra = tarfile.TarInfo(info.name.replace("env.npy", "edit.npy"))
                extra.size = len(buf.getvalue())
                out.addfile(extra, io.BytesIO(buf.getvalue()))
            out.addfile(info, io.BytesIO(data_))
    got = [s for _, s in data.read_chunk(tmp_path / "chunk.tar")]
    plain = [s for _, s in data.read_chunk(src)]
    assert len(got) == 8 and all(torch.equal(s["edit"], torch.full((16, 16, 3), 0.25)) for s in got)
    assert all(torch.equal(a["image"], b["image"]) and "edit" not in b for a, b in zip(got, plain))
    assert data.collate(got)["edit"].shape == (8, 16, 16, 3)


def test_a_missing_sample_is_named(dataset, tmp_path):
    (tmp_path / "chunk-000000.json").write_bytes((dataset / "train" / "chunk-000000.json").read_bytes())
    with tarfile.open(dataset / "train" / "chunk-000000.tar") as t, tarfile.open(tmp_path / "chunk-000000.tar", "w") as out:
        for info in t.getmembers():
            if not info.name.startswith("00000003."):
                out.addfile(info, t.extractfile(info))
    with pytest.raises(ValueError, match="chunk-000000.tar: sample 00000003 is missing"):
        list(zip(range(3), data.ChunkStream(tmp_path, 4, shuffle_buffer=1)))


EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples" / "nets"


def test_the_example_recipes_load_and_each_pair_differs_in_the_rendering_loss():
    """Every training recipe under python/examples/nets (a file whose header says
    `python -m matedit.nets.train NAME.py`) loads with known settings of the right types,
    and the with/without pairs of the rendering-loss experiment differ in that loss alone."""
    recipes = sorted(
        p for p in EXAMPLES.rglob("*.py") if f"matedit.nets.train {p.name} " in p.read_text()
    )
    assert {p.name for p in recipes} >= {"without_render_loss.py", "with_render_loss.py", "long.py",
                                         "tune.py", "p16.py", "q16.py", "r16.py", "small.py"}
    cfgs = {p.relative_to(EXAMPLES).as_posix(): train.load_config(p) for p in recipes}
    for without, with_, also in [("paper/without_render_loss.py", "paper/with_render_loss.py", {}),
                                 ("photo/p16.py", "photo/r16.py", {"render_pixels": 256})]:
        a, b = cfgs[without], cfgs[with_]
        assert not a["render_loss"] and b["render_loss"]
        differ = {k for k in a if a[k] != b[k]}
        assert differ == {"render_loss", *also}, (without, with_, differ)
        assert all(b[k] == v for k, v in also.items())
