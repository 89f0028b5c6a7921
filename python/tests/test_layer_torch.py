"""matedit.nets.layer (the layer's forward in torch ops) against the Rust layer: images of
presets and MERL mixes on the probe sphere under the three probe lights within 1e-4 of the
image max (float32; float64 within 1e-6 of the f64 reference, which returns float32), gradients in ctrl, env
and normals within 1e-3 of matedit.torch.render's, batched and shared inputs, normals that
face away (x = 0 pairs), the paper convention, model.spheres' torch backend, and CUDA
where there is one."""

import importlib.util
import pathlib
import sys

import numpy as np
import pytest
import torch

import matedit
import matedit.nets
import matedit.torch

REPO_NETS = pathlib.Path(__file__).resolve().parents[1] / "matedit" / "nets"
if REPO_NETS.is_dir():
    matedit.nets.__path__.insert(0, str(REPO_NETS))  # the repository's layer.py, not an installed copy

from matedit.nets import layer, model  # noqa: E402

PROBE = model.probe_scene(32)
MERL = model.merl_presets(matedit.presets()[: model.N_MERL])


def _model():
    """The repository's model.py (model where there is none)."""
    if not (REPO_NETS / "model.py").exists():
        return model
    name = "matedit.nets._repo_model"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, REPO_NETS / "model.py")
        sys.modules[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[name])
    return sys.modules[name]


def mixes(b: int, seed: int, sharpness: float = 3.0) -> torch.Tensor:
    """b random convex mixes of the MERL presets (B, 108)."""
    g = torch.Generator().manual_seed(seed)
    return torch.softmax(torch.randn(b, model.N_MERL, generator=g) * sharpness, -1) @ MERL


def rust_spheres(ctrl: torch.Tensor, device: str = "cpu") -> torch.Tensor:
    """(B, P, 32, 32, 3) by matedit.render, one render per material and light."""
    n, envs = (t.numpy() for t in PROBE)
    c = ctrl.double().numpy()
    return torch.from_numpy(
        np.stack([np.stack([matedit.render(n, e, m, device=device) for e in envs]) for m in c])
    )


def rel(a: torch.Tensor, b: torch.Tensor) -> float:
    """max |a - b| / max |b|."""
    return ((a.double() - b.double()).abs().max() / b.double().abs().max()).item()


MATERIALS = {
    "gold": lambda: torch.from_numpy(matedit.preset("gold")).float()[None],
    "matte-white": lambda: torch.from_numpy(matedit.preset("matte-white")).float()[None],
    "chrome-ish": lambda: torch.from_numpy(matedit.preset("chrome-ish")).float()[None],
    "merl-mix": lambda: mixes(1, 0, sharpness=1.0),
    "random-mixes": lambda: mixes(4, 1),
}


@pytest.mark.parametrize("name", MATERIALS)
@pytest.mark.parametrize("device", ["cpu", "reference"])
def test_images_match_the_rust_layer(name, device):
    ctrl = MATERIALS[name]()
    ours = layer.Scene(*PROBE).render_all(ctrl)
    ref = rust_spheres(ctrl, device)
    assert ours.shape == ref.shape and ours.dtype == torch.float32
    for b in range(len(ctrl)):
        assert rel(ours[b], ref[b]) < 1e-4, (name, b)


@pytest.mark.parametrize("name", ["gold", "chrome-ish", "random-mixes"])
def test_float64_matches_the_f64_reference(name):
    ctrl = MATERIALS[name]().double()
    ours = layer.Scene(*PROBE).render_all(ctrl)
    assert ours.dtype == torch.float64
    assert rel(ours, rust_spheres(ctrl, "reference")) < 1e-6  # the reference returns float32


def test_ctrl_gradient_matches_the_rust_backward():
    ctrl = mixes(4, 2)
    up = torch.randn(4, 3, 32, 32, 3, generator=torch.Generator().manual_seed(0))
    grads = []
    for backend in ["rust", "torch"]:
        c = ctrl.clone().requires_grad_()
        (_model().spheres(c, PROBE, backend=backend) * up).sum().backward()
        grads.append(c.grad)
    assert rel(grads[1], grads[0]) < 1e-3


def test_env_and_normals_gradients_match_the_rust_backward():
    n, envs = PROBE
    ctrl = mixes(3, 3)
    up = torch.randn(3, 32, 32, 3, generator=torch.Generator().manual_seed(1))
    grads = []
    for fn in [matedit.torch.render, layer.render]:
        ins = [t.clone().requires_grad_() for t in (n, envs, ctrl)]
        (fn(*ins) * up).sum().backward()
        grads.append([t.grad for t in ins])
    for name, ours, ref in zip(["normals", "env", "ctrl"], grads[1], grads[0]):
        assert rel(ours, ref) < 1e-3, name


def bumpy_normals(seed: int) -> torch.Tensor:
    """The probe sphere's normals tilted at random, some facing away (n.z < 0)."""
    g = torch.Generator().manual_seed(seed)
    n = PROBE[0]
    fg = n.norm(dim=-1, keepdim=True) > 0
    t = torch.nn.functional.normalize(n + 0.8 * torch.randn(n.shape, generator=g), dim=-1)
    return torch.where(fg, t, 0.0)


def test_batched_and_shared_inputs():
    normals = torch.stack([PROBE[0], bumpy_normals(0)])
    envs, ctrl = PROBE[1][:2], mixes(2, 4)
    assert (normals[1][..., 2] < 0).any()
    cases = [
        (normals, envs, ctrl),
        (normals, envs[0], ctrl),
        (normals[1], envs, ctrl),
        (normals, envs, ctrl[0]),
        (normals[1], envs[0], ctrl),
        (normals[1], envs[0], ctrl[0]),
    ]
    for ins in cases:
        ref = matedit.torch.render(*ins)
        ours = layer.render(*ins)
        assert ours.shape == ref.shape, [tuple(t.shape) for t in ins]
        assert rel(ours, ref) < 1e-4, [tuple(t.shape) for t in ins]


def test_render_all_is_every_material_under_every_light():
    ctrl = mixes(3, 5)
    scene = layer.Scene(*PROBE)
    every = scene.render_all(ctrl)
    for p in range(3):
        zipped = layer.Scene(PROBE[0], PROBE[1][p]).render(ctrl)
        assert torch.allclose(every[:, p], zipped, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="shared"):
        layer.Scene(torch.stack([PROBE[0]] * 2), PROBE[1]).render_all(ctrl)
    with pytest.raises(ValueError, match="batch sizes"):
        layer.render(PROBE[0], PROBE[1], mixes(2, 6))


def test_paper_convention():
    n, env, ctrl = PROBE[0], PROBE[1][0], mixes(1, 7)[0]
    ref = matedit.render(n.numpy(), env.numpy(), ctrl.double().numpy(), convention="paper")
    assert rel(layer.render(n, env, ctrl, convention="paper"), torch.from_numpy(ref)) < 1e-4


def test_spheres_torch_backend():
    m = _model()
    ctrl = mixes(2, 8)
    rust = m.spheres(ctrl, PROBE)
    assert rel(m.spheres(ctrl, PROBE, backend="torch"), rust) < 1e-4
    assert rel(m.spheres(ctrl, layer.Scene(*PROBE), backend="torch"), rust) < 1e-4
    with pytest.raises(ValueError, match="backend"):
        m.spheres(ctrl, PROBE, backend="jax")


def test_small_chunks_give_the_same_images(monkeypatch):
    ctrl = mixes(3, 9)
    whole = layer.Scene(*PROBE).render_all(ctrl)
    monkeypatch.setattr(layer, "CHUNK", 1)
    assert rel(layer.Scene(*PROBE).render_all(ctrl), whole) < 1e-6  # matmul rounds by its shapes


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_matches_the_cpu():
    ctrl = mixes(4, 10)
    up = torch.randn(4, 3, 32, 32, 3, generator=torch.Generator().manual_seed(2))
    out = {}
    for dev in ["cpu", "cuda"]:
        c = ctrl.to(dev).requires_grad_()
        img = layer.Scene(*(t.to(dev) for t in PROBE)).render_all(c)
        assert img.device.type == dev
        (img * up.to(dev)).sum().backward()
        out[dev] = (img.cpu(), c.grad.cpu())
    assert rel(out["cuda"][0], rust_spheres(ctrl)) < 1e-4
    assert rel(out["cuda"][1], out["cpu"][1]) < 1e-3
