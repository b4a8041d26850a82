"""The conventional baselines: layer plans checked against torchvision's published sizes."""

import pytest
import torch

from simlidar.errors import ConfigError
from simlidar.models.registry import build_model, load_recipe


def _params(model) -> int:
    return sum(p.numel() for p in model.parameters())


def test_plans_match_torchvision_parameter_counts():
    # torchvision: resnet18 11,689,512 and resnet50 25,557,032 parameters (3-channel 7x7 stem,
    # 1000 classes). Ours: a 1-channel 3x3 stem and 32 classes; everything else identical.
    stem = 3 * 64 * 7 * 7 - 1 * 64 * 3 * 3
    r18 = build_model(load_recipe("resnet18"), (1, 16, 16), 32)
    assert _params(r18) == 11_689_512 - stem - (512 * 1000 + 1000) + (512 * 32 + 32)
    r50 = build_model(load_recipe("resnet50"), (1, 16, 16), 32)
    assert _params(r50) == 25_557_032 - stem - (2048 * 1000 + 1000) + (2048 * 32 + 32)
    # torchvision vgg16_bn's 13 conv layers with batch norm hold 14,723,136 parameters;
    # ours take 1 input channel and end in GAP, dense 512, dense 32
    vgg = build_model(load_recipe("vgg16"), (1, 16, 16), 32)
    features = 14_723_136 - 2 * 64 * 3 * 3
    assert _params(vgg) == features + (512 * 512 + 512) + (512 * 32 + 32)


@pytest.mark.parametrize("name", ["cnn", "vgg16", "resnet18", "resnet50", "mlp"])
@pytest.mark.parametrize("shape", [(1, 16, 16), (1, 5, 3)])  # KITTI crops: the CNN test
def test_every_baseline_takes_any_input_size(name, shape):
    model = build_model(load_recipe(name), shape, 8, torch.Generator().manual_seed(0))
    model.eval()
    out = model(torch.rand(2, *shape))
    assert out.shape == (2, 8) and torch.isfinite(out).all()


def test_cnn_has_the_papers_layers_and_a_seed_fixes_the_weights():
    recipe = load_recipe("cnn")
    a = build_model(recipe, (1, 50, 118), 8, torch.Generator().manual_seed(3))
    b = build_model(recipe, (1, 50, 118), 8, torch.Generator().manual_seed(3))
    shapes = [tuple(p.shape) for p in a.parameters() if p.dim() > 1]
    # conv 5x5/2 x48, conv 5x5/2 x24 (50 x 118 -> 25 x 59 -> 13 x 30), dense 256, dense 8
    assert shapes == [(48, 1, 5, 5), (24, 48, 5, 5), (256, 24 * 13 * 30), (8, 256)]
    assert all(torch.equal(p, q) for p, q in zip(a.parameters(), b.parameters()))


def test_the_mlp_reference_has_the_dense_snns_shape():
    mlp = build_model(load_recipe("mlp"), (1, 16, 16), 32)
    assert [tuple(p.shape) for p in mlp.parameters() if p.dim() > 1] == [(400, 256), (32, 400)]


def test_unknown_plans_are_named(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        'model = "vgg"\n[architecture]\nplan = "vgg99"\n'
        "[training]\nlr = 0.01\nbatch_size = 4\nepochs = 1\n"
    )
    with pytest.raises(ConfigError, match=r"plan='vgg99': expected one of \['vgg11', 'vgg16'\]"):
        build_model(load_recipe(bad), (1, 16, 16), 4)


def test_the_mlp_is_the_cnn_without_convolutions():
    from simlidar.models.registry import build_model, load_recipe

    mlp = load_recipe("mlp")
    as_cnn = dict(mlp, model="cnn", architecture={"conv": [], **mlp["architecture"]})
    for seed in (0, 1):
        a = build_model(mlp, (1, 16, 16), 32, torch.Generator().manual_seed(seed)).state_dict()
        b = build_model(as_cnn, (1, 16, 16), 32, torch.Generator().manual_seed(seed)).state_dict()
        assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert [tuple(v.shape) for v in a.values()] == [(400, 256), (400,), (32, 400), (32,)]
