import pytest
import torch

from simlidar.content import content_dir
from simlidar.errors import ConfigError, ResourceError
from simlidar.models.registry import BUILDERS, build_model, load_recipe
from simlidar.models.stream_nets import scores_of
from simlidar.models.stream_spec import stream_spec_of

SHIPPED = sorted(p.stem for p in content_dir("baselines").glob("*.toml"))
STREAM = [name for name in SHIPPED if "stream" in load_recipe(name)]  # a [stream] table
WINDOW = [name for name in SHIPPED if name not in STREAM]


def _data_of(name: str) -> tuple[tuple[int, ...], int]:
    """The input shape and classes of the data a shipped recipe is made for (by its name)."""
    if "kitti" in name:
        return (1, 50, 118), 8
    if "dvs" in name:
        return (1, 32, 32), 36
    return (1, 16, 16), 32


@pytest.mark.parametrize("name", WINDOW)
def test_every_shipped_recipe_builds_and_runs(name):
    recipe = load_recipe(name)
    shape, classes = _data_of(name)
    model = build_model(recipe, shape, classes, torch.Generator().manual_seed(0))
    out = model(torch.rand(2, *shape))
    assert out.shape == (2, classes)
    assert torch.isfinite(out).any()  # the initial weights let spiking neurons fire


@pytest.mark.parametrize("name", STREAM)
def test_every_shipped_stream_recipe_builds_and_runs(name):
    """A stream network gives scores at every step of a stream, (T, B, classes)."""
    recipe = load_recipe(name)
    spec = stream_spec_of(recipe)
    model = build_model(recipe, (spec.channels, 16, 32), 4, torch.Generator().manual_seed(0))
    out = scores_of(model(torch.rand(7, 2, spec.channels, 16, 32)))
    assert out.shape == (7, 2, 4) and torch.isfinite(out).all()


def test_the_shipped_folder_is_what_the_registry_serves():
    assert len(SHIPPED) >= 9 and {load_recipe(n)["model"] for n in SHIPPED} == set(BUILDERS)


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


@pytest.mark.parametrize(
    "model, architecture, error, words",
    [
        ("snn", "hidden = [0]", ConfigError, "a layer of 256 inputs and 0 outputs; expected whole"),
        ("snn", "hidden = [2.5]", ConfigError, "expected whole numbers >= 1"),
        ("mlp", "dense = [0]", ConfigError, "dense layer: a layer of 256 inputs and 0 outputs"),
        ("cnn", "conv = [[0, 5, 2]]", ConfigError, "convolution: a layer of 25 inputs and 0"),
        ("snn", "hidden = [100000000]", ResourceError, "a 256 x 100000000 layer's weights"),
        ("mlp", "dense = [100000000]", ResourceError, "a 256 x 100000000 layer's weights"),
    ],
)
def test_layer_sizes_are_checked_before_their_weights_are_allocated(
    tmp_path, model, architecture, error, words
):
    """``hidden = [0]`` divided by zero (a traceback) and ``hidden = [100000000]`` asked for
    400 GB without a check: one line each, before any weight is allocated."""
    path = tmp_path / "wide.toml"
    path.write_text(
        f'model = "{model}"\n[architecture]\n{architecture}\n'
        "[training]\nlr = 0.001\nbatch_size = 8\nepochs = 1\n"
    )
    with pytest.raises(error, match=words) as err:
        build_model(load_recipe(path), (1, 16, 16), 32)
    assert "\n" not in str(err.value)


def test_a_recipe_may_leave_out_its_architecture(tmp_path):
    path = tmp_path / "bare.toml"
    path.write_text('model = "mlp"\n[training]\nlr = 0.001\nbatch_size = 8\nepochs = 1\n')
    recipe = load_recipe(path)
    assert recipe["architecture"] == {}
    assert build_model(recipe, (1, 16, 16), 32)(torch.rand(2, 1, 16, 16)).shape == (2, 32)
    path.write_text(path.read_text().replace("[training]", "architecture = 3\n[training]"))
    with pytest.raises(ConfigError, match="key 'architecture': expected a table, got 3"):
        load_recipe(path)
