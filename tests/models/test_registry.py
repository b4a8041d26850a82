import pytest
import torch

from simlidar.errors import ConfigError
from simlidar.models.registry import BUILDERS, build_model, load_recipe

RECIPES = ["snn_simlidar", "scnn_kitti", "snn_dvs"]


@pytest.mark.parametrize("name", RECIPES)
def test_every_shipped_recipe_builds_and_runs(name):
    recipe = load_recipe(name)
    shape = {"snn_simlidar": (1, 16, 16), "scnn_kitti": (1, 50, 118), "snn_dvs": (1, 32, 32)}
    classes = {"snn_simlidar": 32, "scnn_kitti": 8, "snn_dvs": 36}[name]
    model = build_model(recipe, shape[name], classes, torch.Generator().manual_seed(0))
    out = model(torch.rand(2, *shape[name]))
    assert out.shape == (2, classes)
    assert torch.isfinite(out).any()  # the initial weights let neurons fire


def test_the_papers_layer_sizes():
    snn = build_model(load_recipe("snn_simlidar"), (1, 16, 16), 32)
    assert [tuple(m.weight.shape) for m in snn.layers] == [(256, 400), (400, 32)]
    dvs = build_model(load_recipe("snn_dvs"), (1, 32, 32), 36)
    assert [tuple(m.weight.shape) for m in dvs.layers] == [(1024, 2000), (2000, 36)]
    scnn = build_model(load_recipe("scnn_kitti"), (1, 50, 118), 8)
    shapes = [tuple(m.weight.shape) for m in scnn.layers]
    assert shapes[:2] == [(48, 1, 5, 5), (24, 48, 5, 5)] and shapes[2:] == [
        (24 * 13 * 30, 256),
        (256, 8),
    ]
    assert set(RECIPES) <= {"snn_simlidar", "scnn_kitti", "snn_dvs"} and "snn" in BUILDERS


def test_bad_recipes_are_named(tmp_path):
    with pytest.raises(ConfigError, match="model recipe 'nope': expected one of"):
        load_recipe("nope")
    bad = tmp_path / "bad.toml"
    bad.write_text('model = "perceptron"\n[architecture]\n[training]\n')
    with pytest.raises(ConfigError, match="key 'model': expected one of"):
        load_recipe(bad)
    training = "[training]\nlr = 0.01\nbatch_size = 4\nepochs = 1\n"
    bad.write_text('model = "snn"\n[architecture]\nlayers = [3]\n' + training)
    with pytest.raises(ConfigError, match=r"\[architecture\]"):
        build_model(load_recipe(bad), (1, 4, 4), 2)
    bad.write_text('model = "snn"\n[architecture]\nscale = 100.0\n' + training)
    with pytest.raises(ConfigError, match=r"scale=100.0: expected a value in \(0, 80.0\]"):
        build_model(load_recipe(bad), (1, 4, 4), 2)
    for broken, key in (
        ("lr = 0.01", "training.lr"),
        ("batch_size = 4", "training.batch_size"),
        ("epochs = 1", "training.epochs"),
    ):
        bad.write_text('model = "snn"\n[architecture]\n' + training.replace(broken, ""))
        with pytest.raises(ConfigError, match=key):
            load_recipe(bad)
