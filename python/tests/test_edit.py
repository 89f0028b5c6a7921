"""matedit.edit: the object of a photo made of another material (docs/edit.md), with the
built-in nets; and matedit.nets.load() without a path."""

import numpy as np
import pytest

import matedit


def photo():
    """A gold sphere (48 px) under the built-in sky on a dim noisy background, and its mask."""
    img = (np.random.default_rng(0).random((64, 64, 3)) * 0.2).astype(np.float32)
    normals = matedit.sphere(48)
    on = np.abs(normals).sum(-1) > 0
    img[8:56, 8:56][on] = matedit.render(normals, matedit.sky(16, 32), matedit.preset("gold"))[on]
    mask = np.zeros((64, 64), bool)
    mask[8:56, 8:56] = on
    return img, mask


def test_edit_a_photo():
    img, mask = photo()
    r = matedit.edit(img, "pvc", mask=mask, steps=20)
    assert r["edit"].shape == (64, 64, 3) and r["edit"].dtype == np.float32
    assert np.array_equal(r["mask"], mask)
    # the background is the photo's, the object changed
    off = ~mask
    off[1:-1, 1:-1] &= ~(mask[:-2, 1:-1] | mask[2:, 1:-1] | mask[1:-1, :-2] | mask[1:-1, 2:])
    assert np.array_equal(r["edit"][off & (r["alpha"] == 0)], img[off & (r["alpha"] == 0)])
    assert np.abs(r["edit"][mask] - img[mask]).mean() > 0.01
    assert r["psnr_refined"] >= r["psnr_predicted"] and len(r["losses"]) >= 1
    assert r["material"].shape == (108,) and r["env"].shape == (16, 32, 3)
    # an 8-bit sRGB photo and --like
    r2 = matedit.edit((np.clip(img, 0, 1) * 255).astype(np.uint8), like=img, mask=mask, like_mask=mask, steps=3)
    assert r2["edit"].dtype == np.float32
    # the nets run mirrored unless told not to: the predictions differ, both valid
    plain = matedit.edit(img, "pvc", mask=mask, steps=0, mirror=False)
    mirrored = matedit.edit(img, "pvc", mask=mask, steps=0)
    assert np.isfinite(plain["predicted_material"]).all() and np.isfinite(mirrored["predicted_material"]).all()
    assert not np.allclose(plain["predicted_material"], mirrored["predicted_material"])
    assert np.array_equal(mirrored["predicted_material"], r["predicted_material"])


def test_known_normals_and_light_take_the_nets_place():
    img, mask = photo()
    normals = np.zeros((64, 64, 3), np.float32)
    normals[8:56, 8:56] = matedit.sphere(48)
    sky = matedit.sky(32, 64)
    # both known: 100 refinement steps unless told otherwise, where one alone keeps 20
    r = matedit.edit(img, "pvc", mask=mask, normals=normals, env=sky)
    assert len(r["losses"]) == 100
    assert len(matedit.edit(img, "pvc", mask=mask, normals=normals)["losses"]) == 20
    # the known light as given, brought to the nets' 16 x 32 (2 x 2 texels by solid angle), not blurred
    w = np.sin((np.arange(32) + 0.5) / 32 * np.pi).reshape(16, 2, 1, 1, 1)
    small = (sky.reshape(16, 2, 32, 2, 3) * w).sum((1, 3)) / (2 * w.sum(1).reshape(16, 1, 1))
    assert np.allclose(r["env"], small, rtol=1e-4, atol=1e-6)
    crop_x0, crop_y0, size = r["crop"]
    ys, xs = np.nonzero(mask)
    assert np.allclose(r["normals"][ys - crop_y0, xs - crop_x0], normals[ys, xs])
    guessed = matedit.edit(img, "pvc", mask=mask, steps=100)
    assert r["psnr_refined"] > guessed["psnr_refined"] + 3, (r["psnr_refined"], guessed["psnr_refined"])
    # the like photo's light: another read of the same photo's material
    a = matedit.edit(img, like=img, mask=mask, like_mask=mask, steps=5)["edit"]
    b = matedit.edit(img, like=img, mask=mask, like_mask=mask, steps=5, like_env=sky)["edit"]
    assert np.isfinite(b).all() and not np.allclose(a, b)
    # like_steps: the like photo's read takes its own steps, the photo's `steps`
    read = matedit.edit(img, "pvc", mask=mask, steps=0)["material"]
    c = matedit.edit(img, like=img, mask=mask, like_mask=mask, steps=5, like_steps=0)["edit"]
    assert np.array_equal(c, matedit.edit(img, read, mask=mask, steps=5)["edit"])
    assert not np.allclose(a, c)
    with pytest.raises(ValueError, match=r"normals: shape \(32, 64, 3\), the photo \(64, 64, 3\)"):
        matedit.edit(img, "pvc", mask=mask, normals=normals[:32])
    with pytest.raises(ValueError, match=r"env \(the known light\): cannot make a 16x32 map from this 15x30 map"):
        matedit.edit(img, "pvc", mask=mask, env=matedit.sky(15, 30))


def test_bad_inputs_raise_value_error():
    img, mask = photo()
    with pytest.raises(ValueError, match="unknown preset 'nope'"):
        matedit.edit(img, "nope", mask=mask)
    with pytest.raises(ValueError, match="too small to hold an object"):
        matedit.edit(img[:8, :8], "pvc")
    with pytest.raises(ValueError, match=r"mask: shape \[32, 32\], expected \(64, 64\)"):
        matedit.edit(img, "pvc", mask=mask[:32, :32])
    with pytest.raises(ValueError, match="no background"):
        matedit.edit(img, "pvc", mask=np.ones((64, 64), bool))
    bad = img.copy()
    bad[3, 3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite"):
        matedit.edit(bad, "pvc", mask=mask)
    with pytest.raises(ValueError, match="give material or like"):
        matedit.edit(img)


def test_builtin_nets_load():
    import matedit.nets

    nets = matedit.nets.load()
    assert len(nets.cfg.basis) == 60 and nets.material.presets.shape == (60, 108)


def test_builtin_nets_give_the_cards_metrics():
    """The built-in nets on the committed held-out set (16 samples of test.json's sources,
    python/examples/nets/paper/card.json) give docs/nets_card.md's figures: every metric
    within 0.05 (dB, degrees, %) or 0.002 (IoU, RMSE) of expected.json."""
    import json
    import pathlib

    import matedit.nets
    from matedit.nets.evaluate import evaluate

    folder = pathlib.Path(__file__).parent / "data" / "nets_card"
    want = json.loads((folder / "expected.json").read_text())
    got = evaluate(matedit.nets.load(), folder)
    assert got["samples"] == want["samples"] == 16
    for kind in ("nets", "baselines"):
        for name, value in want[kind].items():
            tol = 0.002 if name in ("mask_iou", "light_si_log_rmse") else 0.05
            assert abs(got[kind][name] - value) <= tol, (kind, name, got[kind][name], value)
