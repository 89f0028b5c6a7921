"""The PyTorch operator: opcheck, gradients against finite differences through the f64
reference device, batches, torch.compile, and invalid input."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import matedit  # noqa: E402
import matedit.torch as mt  # noqa: E402


def inputs(n=8, grad=True, seed=0):
    rng = np.random.default_rng(seed)
    normals = torch.from_numpy(matedit.sphere(n))
    env = torch.from_numpy((rng.random((4, 8, 3)) + 0.2).astype(np.float32))
    ctrl = torch.from_numpy(matedit.preset("red-specular-plastic")).float()
    if grad:
        for t in (normals, env, ctrl):
            t.requires_grad_()
    return normals, env, ctrl


def test_opcheck():
    n, e, c = inputs()
    torch.library.opcheck(torch.ops.matedit.render.default, (n, e, c, 0.0, "equirect", "cpu"))
    up = torch.ones(8, 8, 3)
    torch.library.opcheck(
        torch.ops.matedit.render_backward.default,
        (n.detach(), e.detach(), c.detach(), up, 0.0, "equirect", "cpu"),
    )


def test_matches_numpy():
    n, e, c = inputs(grad=False)
    img = mt.render(n, e, c)
    np.testing.assert_array_equal(img.numpy(), matedit.render(n.numpy(), e.numpy(), c.numpy()))


def test_gradients_match_finite_differences_on_the_reference():
    """The layer runs in f64 on the reference device (f32 in and out): central differences
    with steps of 1e-2 relative agree with the analytic gradient to 2% on a loss summed
    over the image, for every input."""
    n, e, c = inputs(6)
    w = torch.from_numpy(np.random.default_rng(3).random((6, 6, 3)).astype(np.float32))

    def loss(n_, e_, c_):
        return (mt.render(n_, e_, c_, device="reference").double() * w).sum()

    loss(n, e, c).backward()
    checks = [
        (e, 1, 0.05),      # env texel (row 0, col 1), channel 0
        (c, 2, 0.01),      # a scale control point
        (c, 6 + 2, 0.5),   # an exponent control point of the same lobe
        (c, 36 + 12 + 3, 0.01),
    ]
    for t, i, step in checks:
        flat = t.detach().clone().reshape(-1)
        args = []
        for sign in (1, -1):
            f = flat.clone()
            f[i] += sign * step * max(1.0, abs(float(flat[i])))
            args.append(f.reshape(t.shape))
        h = float(args[0].reshape(-1)[i] - args[1].reshape(-1)[i])
        with torch.no_grad():
            if t is e:
                fd = (loss(n, args[0], c) - loss(n, args[1], c)) / h
            else:
                fd = (loss(n, e, args[0]) - loss(n, e, args[1])) / h
        an = float(t.grad.reshape(-1)[i])
        assert abs(float(fd) - an) <= 0.02 * max(abs(an), 1e-3), (i, float(fd), an)
    # normals: the pixel at the centre, along x (off every kink of max(0, n.w)); steps of
    # 1e-5 keep |n| within the 1 + 1e-5 the layer accepts, so the loss is that pixel's
    # alone, to keep its f32 rounding small against the difference
    w1 = torch.zeros_like(w)
    w1[3, 3] = w[3, 3]

    def pixel(n_):
        return (mt.render(n_, e, c, device="reference").double() * w1).sum()

    n.grad = None
    pixel(n).backward()
    with torch.no_grad():
        plus, minus = n.detach().clone(), n.detach().clone()
        plus[3, 3, 0] += 1e-5
        minus[3, 3, 0] -= 1e-5
        fd = (pixel(plus) - pixel(minus)) / (float(plus[3, 3, 0]) - float(minus[3, 3, 0]))
    an = float(n.grad[3, 3, 0])
    assert abs(float(fd) - an) <= 0.02 * max(abs(an), 1e-3), (float(fd), an)


def test_only_requested_gradients():
    n, e, c = inputs()
    n.requires_grad_(False)
    e.requires_grad_(False)
    mt.render(n, e, c).sum().backward()
    assert n.grad is None and e.grad is None and c.grad is not None
    # the same d_ctrl as when all three are computed
    n2, e2, c2 = (t.detach().clone().requires_grad_() for t in (n, e, c))
    mt.render(n2, e2, c2).sum().backward()
    torch.testing.assert_close(c.grad, c2.grad, rtol=1e-5, atol=1e-5 * c2.grad.abs().max().item())


def test_batched_and_shared_inputs():
    n, e, c = inputs(grad=False)
    nb = torch.stack([n, n.flip(1).contiguous()]).requires_grad_()
    eb = e.clone().requires_grad_()  # shared by the batch
    cb = c.clone().requires_grad_()
    img = mt.render(nb, eb, cb)
    assert img.shape == (2, 8, 8, 3)
    img.sum().backward()
    assert eb.grad.shape == e.shape and cb.grad.shape == c.shape
    # the shared inputs' gradients are the sums of the one-by-one gradients
    total = torch.zeros_like(e)
    for i in range(2):
        ei = e.clone().requires_grad_()
        mt.render(nb[i].detach(), ei, c).sum().backward()
        total += ei.grad
    torch.testing.assert_close(eb.grad, total, rtol=1e-5, atol=1e-6)


def test_compiles():
    n, e, c = inputs()

    @torch.compile(backend="aot_eager", fullgraph=True)
    def step(n, e, c):
        return mt.render(n, e, c).square().mean()

    step(n, e, c).backward()
    assert c.grad is not None and torch.isfinite(c.grad).all()


def test_invalid_inputs():
    n, e, c = inputs(grad=False)
    with pytest.raises(ValueError, match="normals: dtype"):
        mt.render(n.double(), e, c)
    with pytest.raises(ValueError, match="ctrl: dtype"):
        mt.render(n, e, c.int())
    with pytest.raises(ValueError, match="exponents must be >= 0"):
        bad = c.clone()
        bad[6] = -1
        mt.render(n, e, bad)
    with pytest.raises(ValueError, match="torch.Tensor"):
        mt.render(n.numpy(), e, c)


def test_inputs_on_different_devices_are_refused():
    n, e, c = inputs(grad=False)
    with pytest.raises(ValueError, match="different devices"):
        mt.render(n.to("meta"), e, c)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_tensors_give_the_cpu_answers_on_their_device():
    n, e, c = inputs()
    img = mt.render(n, e, c, device="cpu")
    (img * img).sum().backward()
    want = [t.grad.clone() for t in (n, e, c)]
    cuda = [t.detach().cuda().requires_grad_() for t in (n, e, c)]
    with pytest.warns(UserWarning, match="copied to host memory"):
        img_cuda = mt.render(*cuda, device="cpu")
    assert img_cuda.device.type == "cuda"
    (img_cuda * img_cuda).sum().backward()
    torch.testing.assert_close(img_cuda.cpu(), img.detach(), rtol=0, atol=0)
    for t, w in zip(cuda, want):
        assert t.grad.device.type == "cuda"
        torch.testing.assert_close(t.grad.cpu(), w, rtol=0, atol=0)
