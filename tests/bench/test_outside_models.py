"""Outside models through the benchmark: builders named by a recipe or on the command line,
the shipped examples (snnTorch, Norse) trained and scored through ``simlidar bench`` at a tiny
size, their figures checked against NeuroBench, threads and devices.

Bad input covered (each a one-line error, exit 2, nothing written): a builder module that does
not import, a file that is not there, a module that raises while importing, a name that is not a
function, a builder that raises, one that returns no module, a module whose output has the wrong
shape or kind, a forward that raises, ``--device cuda`` on a machine without a GPU.
"""

import json
from pathlib import Path

import pytest
import torch
from outside_builders import PLAIN_MODEL

from simlidar.errors import ConfigError
from simlidar.models.registry import build_model, builder, load_recipe

EXAMPLES = Path(__file__).parents[2] / "examples"
SUITE = """
name = "outside"
description = "outside models"
models = ["cnn"]
seeds = [0]
datasets = [{paths}]

[budget]
epochs = {epochs}
"""
TRAINING = '[training]\noptimizer = "adam"\nlr = 1e-2\nbatch_size = 32\nepochs = {epochs}\n'
PLAIN = (
    "\nimport torch\nfrom torch import nn\n"
    + PLAIN_MODEL
    + """

def wrong_shape(input_shape, classes, generator=None):
    return Plain(input_shape[1] * input_shape[2], classes + 1)


def raises(input_shape, classes, generator=None):
    raise ValueError("no weights file at /nowhere.pt")


def not_a_module(input_shape, classes, generator=None):
    return "a model"


class Breaks(Plain):
    def forward(self, x):
        raise RuntimeError("mat1 and mat2 shapes cannot be multiplied")


def breaks(input_shape, classes, generator=None):
    return Breaks(4, classes)


class Fitted(Plain):  # trains itself, as a model trained elsewhere would load its weights
    def simlidar_fit(self, x_train, y_train, x_val, y_val, generator):
        with torch.no_grad():  # the class means as weights: a nearest-mean classifier
            for c in range(self.fc.out_features):
                rows = x_train[y_train == c].flatten(1)
                self.fc.weight[c] = rows.mean(0) if len(rows) else 0
                self.fc.bias[c] = -0.5 * (self.fc.weight[c] ** 2).sum()
        self.fitted = True


def fitted(input_shape, classes, generator=None):
    return Fitted(input_shape[1] * input_shape[2], classes)


class Nan(Plain):
    def forward(self, x):
        return super().forward(x) * float("nan")


def nan(input_shape, classes, generator=None):
    return Nan(input_shape[1] * input_shape[2], classes)


class TurnsNan(Plain):  # finite for the probe and the first training steps, NaN from then on
    calls = 0

    def forward(self, x):
        self.calls += 1
        out = super().forward(x)
        return out * float("nan") if self.calls > 3 else out


def turns_nan(input_shape, classes, generator=None):
    return TurnsNan(input_shape[1] * input_shape[2], classes)


class Integer(Plain):
    def forward(self, x):
        return super().forward(x).round().long()


def integer(input_shape, classes, generator=None):
    return Integer(input_shape[1] * input_shape[2], classes)


class Empty(nn.Module):  # nothing to train
    def __init__(self, classes):
        super().__init__()
        self.classes = classes

    def forward(self, x):
        return torch.zeros(len(x), self.classes)


def empty(input_shape, classes, generator=None):
    return Empty(classes)


def exits(input_shape, classes, generator=None):
    raise SystemExit(0)


def sleeps(input_shape, classes, generator=None):
    import time

    time.sleep(120)


def chatty(input_shape, classes, generator=None):
    print("x" * 1_000_000)
    return build(input_shape, classes)
"""
)


@pytest.fixture
def plain_module(tmp_path, monkeypatch):
    """A module ``outside_plain`` importable by name, and the same code as a file."""
    folder = tmp_path / "code"
    folder.mkdir()
    (folder / "outside_plain.py").write_text(PLAIN)
    monkeypatch.syspath_prepend(str(folder))
    return folder / "outside_plain.py"


def _suite(tmp_path, datasets, epochs=1):
    path = tmp_path / "outside.toml"
    paths = ", ".join(f'"{p}"' for p in [datasets[0.1]])
    path.write_text(SUITE.format(paths=paths, epochs=epochs))
    return path


def _bench_json(cli, suite, models, out):
    """``simlidar bench --json`` of ``models`` (comma-separated) on a suite, into ``out``."""
    return cli("bench", "--suite", suite, "--models", models, "--out", out, "--json")


def test_a_plain_torch_module_by_name_and_by_file(plain_module, tmp_path, datasets, cli):
    recipe = load_recipe("outside_plain:build")
    assert recipe["name"] == "outside_plain.build" and recipe["training"]["epochs"] == 30
    model = build_model(recipe, (1, 16, 16), 32)
    assert isinstance(model, torch.nn.Module)
    (tmp_path / "r").mkdir()
    file_recipe = tmp_path / "r" / "mine.toml"
    file_recipe.write_text(
        f'model = "../code/{plain_module.name}:build"\n[architecture]\n' + TRAINING.format(epochs=2)
    )
    out = tmp_path / "b"
    result = _bench_json(cli, _suite(tmp_path, datasets), f"outside_plain:build,{file_recipe}", out)
    assert result.exit_code == 0, result.output
    cells = {c["model"]: c for c in json.loads(result.stdout)["cells"]}
    assert set(cells) == {"outside_plain.build", "mine"}
    for cell in cells.values():
        assert cell["kind"] == "conventional" and cell["spec"]["output"] == "logits"
        assert cell["threads"] == 1 and cell["device"] == "cpu"
        assert cell["machine"]["torch_threads"] == 1  # it recorded the process's 2
        assert cell["macs"] == 256 * 32  # one linear layer, counted like the baselines'


def test_a_model_with_its_own_fit_is_scored_only(plain_module, tmp_path, datasets, cli):
    out = tmp_path / "b"
    result = _bench_json(cli, _suite(tmp_path, datasets), "outside_plain:fitted", out)
    assert result.exit_code == 0, result.output
    (cell,) = json.loads(result.stdout)["cells"]
    assert cell["stopped"] == "own-fit" and cell["epochs_run"] == 1
    assert cell["validation_size"] > 0 and cell["validation_curve"][0] is not None
    assert cell["accuracy"] > 3 / 32  # nearest class mean: well above chance at noise 0.1


@pytest.mark.parametrize(
    "model, words",
    [
        ("no_such_module_xyz:build", "builder module 'no_such_module_xyz': cannot import it"),
        ("missing/file.py:build", "builder file '.*missing/file.py': not found"),
        ("outside_plain:nothing", "has no function 'nothing'"),
        ("outside_plain:raises", "builder 'outside_plain:raises' raised ValueError: no weights"),
        ("outside_plain:not_a_module", "returned str; expected a torch.nn.Module"),
        ("outside_plain:wrong_shape", r"output for a batch of 2 is \(2, 33\); expected logits"),
        ("outside_plain:breaks", "forward on a batch of 2 delays inputs raised RuntimeError"),
        ("outside_plain:nan", "before training: the model's output holds nan"),
        ("outside_plain:integer", "output is torch.int64; expected a floating-point logits"),
        ("outside_plain:empty", "the model has no trainable parameters"),
        ("outside_plain:exits", "builder 'outside_plain:exits' raised SystemExit: 0"),
    ],
)
def test_bad_builders_are_one_line(plain_module, tmp_path, datasets, model, words, cli):
    """Refused before anything is written: not even suite.json (a refused model used to leave
    it and cells/, and the folder was then refused for the next suite)."""
    out = tmp_path / "b"
    result = cli("bench", "--suite", _suite(tmp_path, datasets), "--models", model, "--out", out)
    assert result.exit_code in (1, 2), result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.stderr.splitlines() if not line.startswith("note: ")]
    assert len(lines) == 1 and __import__("re").search(words, lines[0]), result.output
    assert not out.exists()


def test_a_model_that_turns_nan_stops_its_cell_naming_the_epoch(
    plain_module, tmp_path, datasets, cli
):
    """It used to train to NaN weights, score every sample as class 0 and be published."""
    out = tmp_path / "b"
    suite = _suite(tmp_path, datasets, epochs=3)
    result = cli("bench", "--suite", suite, "--models", "outside_plain:turns_nan", "--out", out)
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    line = result.stderr.splitlines()[-1]  # after the note and the progress bar
    assert line.startswith("Error: recipe outside_plain.turns_nan: epoch 0's validation: the ")
    assert "output holds nan" in line
    assert not list((out / "cells").glob("*.json")) and not list(out.glob("checkpoints/*.pt"))
    runs = tmp_path / "runs"
    trained = cli("train", "--model", "outside_plain:turns_nan", "--dataset", datasets[0.1],
                  "--out", runs, "--epochs", 2)  # fmt: skip
    assert trained.exit_code == 1 and "epoch 0" in trained.stderr and "nan" in trained.stderr
    assert not list(runs.glob("*.pt"))


def test_two_builders_of_one_package_keep_their_own_cells(tmp_path, datasets, cli, monkeypatch):
    """``mynets.a:build`` and ``mynets.b:build`` were both named ``mynets.build``: the second
    cell overwrote the first, and the run said "1 cells"."""
    package = tmp_path / "code" / "mynets"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    for name in ("a", "b"):
        (package / f"{name}.py").write_text(PLAIN)
    monkeypatch.syspath_prepend(str(tmp_path / "code"))
    out = tmp_path / "b"
    result = _bench_json(cli, _suite(tmp_path, datasets), "mynets.a:build,mynets.b:build", out)
    assert result.exit_code == 0, result.output
    names = sorted(c["model"] for c in json.loads(result.stdout)["cells"])
    assert names == ["mynets.a.build", "mynets.b.build"]


def test_two_recipes_of_one_name_from_different_folders_are_refused(
    plain_module, tmp_path, datasets, cli
):
    recipes = []
    for folder in ("x", "y"):
        (tmp_path / folder).mkdir()
        recipe = tmp_path / folder / "mine.toml"  # no [architecture]: the builder takes none
        recipe.write_text(f'model = "{plain_module}:build"\n' + TRAINING.format(epochs=1))
        recipes.append(str(recipe))
    out = tmp_path / "b"
    result = _bench_json(cli, _suite(tmp_path, datasets), ",".join(recipes), out)
    assert result.exit_code == 2, result.output
    assert "would both be cells of model 'mine'" in result.stderr and not out.exists()
    one = _bench_json(cli, _suite(tmp_path, datasets), f"{recipes[0]},{recipes[0]}", out)
    assert one.exit_code == 0, one.output  # one recipe named twice is one model
    (cell,) = json.loads(one.stdout)["cells"]
    assert cell["model"] == "mine"


def test_a_builder_that_prints_leaves_train_json_on_stdout(plain_module, tmp_path, datasets, cli):
    result = cli("train", "--model", "outside_plain:chatty", "--dataset", datasets[0.1],
                 "--out", tmp_path / "runs", "--epochs", 1, "--json")  # fmt: skip
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["model"] == "outside_plain.chatty"
    assert "x" * 1_000_000 in result.stderr


def test_a_builder_that_hangs_is_stopped_by_the_time_cap(
    plain_module, tmp_path, datasets, cli, monkeypatch
):
    import simlidar.bench.checks

    monkeypatch.setattr(simlidar.bench.checks, "PROBE_FLOOR_S", 0.3)
    result = cli("train", "--model", "outside_plain:sleeps", "--dataset", datasets[0.1],
                 "--out", tmp_path / "runs", "--max-seconds", 0.1)  # fmt: skip
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    (line,) = result.stderr.splitlines()
    assert "building the model and its first forward: still running after the time cap" in line


def test_bench_says_which_recipe_values_the_suites_budget_replaced(
    plain_module, tmp_path, datasets, cli
):
    out = tmp_path / "b"
    result = _bench_json(cli, _suite(tmp_path, datasets), "outside_plain:build", out)
    assert result.exit_code == 0, result.output
    note = "note: outside_plain.build: epochs 1 (its recipe: 30), by suite outside's budget"
    assert note in result.stderr.splitlines()
    (cell,) = json.loads(result.stdout)["cells"]
    assert cell["epochs_run"] == 1


def test_a_module_that_fails_to_import_is_named(tmp_path, datasets, cli):
    (tmp_path / "broken.py").write_text("import torch\nraise ImportError('needs a GPU build')\n")
    recipe = tmp_path / "broken.toml"
    recipe.write_text(
        'model = "broken.py:build"\n[architecture]\n[training]\nlr = 1\n'
        "batch_size = 1\nepochs = 1\n"
    )
    result = cli(
        "bench", "--suite", _suite(tmp_path, datasets), "--models", recipe, "--out", tmp_path / "b"
    )
    assert result.exit_code == 2 and "importing 'broken.py' raised ImportError: needs a GPU" in (
        result.output
    )


def test_a_device_this_machine_lacks_is_refused(tmp_path, datasets, cli):
    if torch.cuda.is_available():
        pytest.skip("this machine has a GPU")
    result = cli(
        "bench", "--suite", _suite(tmp_path, datasets), "--device", "cuda", "--out", tmp_path / "b"
    )
    assert result.exit_code == 2 and "--device cuda: torch sees no CUDA device" in result.output
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("example", ["snntorch_lif", "norse_lif", "spikingjelly_conv"])
def test_the_examples_train_and_score_through_bench(tmp_path, datasets, example, cli):
    pytest.importorskip(example.split("_")[0])  # the extras simlidar[snntorch], [norse]
    out = tmp_path / "b"
    recipe = EXAMPLES / f"{example}.toml"
    result = cli(
        "bench",
        "--suite",
        _suite(tmp_path, datasets, epochs=2),
        "--models",
        recipe,
        "--out",
        out,
        "--json",
    )
    assert result.exit_code == 0, result.output
    (cell,) = json.loads(result.stdout)["cells"]
    assert cell["kind"] == "spiking" and cell["spec"]["encoding"] == "latency"
    stepped = cell["stepped"]
    assert stepped["steps"] == 25 and stepped["samples"] == 64
    assert stepped["accuracy"] == cell["accuracy"]  # the same readout as the test score
    assert 0 < stepped["input_spikes_mean"] <= stepped["input_spikes_total_mean"] <= 256
    assert stepped["neuron_spikes_by_step"]
    if stepped["readout"] == "spike_count":  # reads the whole window
        assert stepped["decision_step_mean"] in (25.0, None)
        assert stepped["input_spikes_mean"] == stepped["input_spikes_total_mean"]
    ops = cell["synaptic_operations"]
    assert ops["effective_macs"] == 0 and ops["effective_acs"] > 0  # binary inputs: accumulates
    assert cell["energy_pj_ops"] == pytest.approx(ops["effective_acs"] * 0.9)
    assert 0 < cell["activation_sparsity"] < 1
    assert cell["footprint"] < 2 * 4 * cell["params"]  # no batch of membrane state in it
    report = (out / "report.md").read_text()
    assert cell["model"] in report


@pytest.mark.parametrize("example", ["snntorch_lif", "norse_lif", "spikingjelly_conv"])
def test_the_examples_figures_are_neurobenchs(datasets, example):
    """NeuroBench's own Benchmark on the same network and inputs. Its activation hooks know
    snnTorch's neurons (SNNTorchModel) and any module class it is given (SpikingJelly's
    BaseNode, whose multi-step output (T, B, ...) it counts element by element), but not Norse's
    cells, whose (spikes, state) output it cannot count: for the Norse example it checks every
    figure but activation sparsity. SpikingJelly's multi-step layers take the whole (T, B, ...)
    train in one call, which NeuroBench's synaptic-operation hook hands to a binary copy of the
    layer as it is."""
    pytest.importorskip(example.split("_")[0])
    from neurobench.benchmarks import Benchmark
    from neurobench.metrics.static import Footprint, ParameterCount
    from neurobench.metrics.workload import ActivationSparsity, SynapticOperations
    from neurobench.models import SNNTorchModel, TorchModel
    from torch.utils.data import DataLoader, TensorDataset

    from simlidar.bench import metrics
    from simlidar.data import load_split
    from simlidar.models.protocol import encode

    def built():
        recipe = load_recipe(EXAMPLES / f"{example}.toml")
        return build_model(recipe, (1, 16, 16), 32, torch.Generator().manual_seed(0))

    model = built()
    x = torch.from_numpy(load_split(datasets[0.1], "test")[0][:40])[:, None]
    spec = model.simlidar_spec

    def enc(batch):
        return encode(batch, spec, float("inf"))

    class TimeMajor(torch.nn.Module):  # NeuroBench hands (B, T, ...) and wants (T, B, ...) back
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, data):
            return self.net(data.transpose(0, 1))[0]

    ours = {**metrics.footprint(model), **metrics.workload(model, x, batch_size=16, encode=enc)}
    model(enc(x[:16]))  # a batch's neuron state may now sit in the model's buffers ...
    assert metrics.footprint(model)["footprint"] == ours["footprint"]  # ... and is left out
    loader = DataLoader(TensorDataset(enc(x).transpose(0, 1), torch.zeros(len(x))), batch_size=16)
    snntorch, norse = example == "snntorch_lif", example == "norse_lif"
    if snntorch:
        wrapped = SNNTorchModel(TimeMajor(built()), custom_forward=True)
    else:
        wrapped = TorchModel(TimeMajor(built()))
    if example == "spikingjelly_conv":
        from spikingjelly.activation_based.neuron import BaseNode

        wrapped.add_activation_module(BaseNode)
    workload = [SynapticOperations] if norse else [ActivationSparsity, SynapticOperations]
    theirs = Benchmark(wrapped, loader, [], [], [[Footprint, ParameterCount], workload]).run(
        quiet=True
    )
    assert ours["params"] == theirs["ParameterCount"]
    assert ours["footprint"] == theirs["Footprint"]
    if not norse:
        assert ours["activation_sparsity"] == pytest.approx(theirs["ActivationSparsity"], rel=1e-12)
    assert 0 < ours["activation_sparsity"] < 1
    ops, nb_ops = ours["synaptic_operations"], theirs["SynapticOperations"]
    assert ops["effective_acs"] == nb_ops["Effective_ACs"] > 0
    assert ops["effective_macs"] == nb_ops["Effective_MACs"] == 0
    assert ops["dense"] == nb_ops["Dense"]


def test_the_python_api_writes_the_cells_bench_writes(tmp_path, datasets, cli):
    from simlidar.bench.api import bench_model

    def tiny_mlp(input_shape, classes, generator=None):
        model = torch.nn.Sequential(torch.nn.Flatten(), torch.nn.Linear(256, classes))
        torch.nn.init.normal_(model[1].weight, std=0.01, generator=generator)
        return model

    out = tmp_path / "api"
    cells = bench_model(tiny_mlp, datasets[0.1], out=out, budget={"epochs": 2}, seeds=(0, 1))
    assert [c["model"] for c in cells] == ["python.tiny_mlp"] * 2
    assert [c["seed"] for c in cells] == [0, 1]
    assert sorted(p.name for p in (out / "cells").iterdir()) == [
        f"{datasets[0.1].name}__python.tiny_mlp__seed{s}.json" for s in (0, 1)
    ]
    assert (out / "report.md").is_file() and (out / "results.json").is_file()
    # the same keys as a cell the command line writes for a shipped model
    result = cli("bench", "--suite", _suite(tmp_path, datasets), "--out", tmp_path / "b", "--json")
    (cli_cell,) = json.loads(result.stdout)["cells"]
    assert set(cells[0]) == set(cli_cell)
    again = bench_model(tiny_mlp, datasets[0.1], out=out, budget={"epochs": 2}, seeds=(0, 1))
    assert again == cells  # a rerun reuses the finished cells
    module = tiny_mlp((1, 16, 16), 32, torch.Generator().manual_seed(3))
    (cell,) = [
        c
        for c in bench_model(module, datasets[0.1], out=tmp_path / "m", budget={"epochs": 1})
        if c["model"] == "python.Sequential"
    ]
    assert cell["params"] == 256 * 32 + 32
    with pytest.raises(ConfigError, match="budget key 'lr': expected one of"):
        bench_model(tiny_mlp, datasets[0.1], out=tmp_path / "x", budget={"lr": 1.0})


STEPPED = """
import torch
from torch import nn


class Spike(torch.autograd.Function):  # a spike above 1, a fast-sigmoid surrogate gradient
    @staticmethod
    def forward(ctx, v):
        ctx.save_for_backward(v)
        return (v > 1).float()

    @staticmethod
    def backward(ctx, grad):
        (v,) = ctx.saved_tensors
        return grad / (1 + (v - 1).abs()) ** 2


class Fire(nn.Module):
    spiking_neuron = True  # counted as a neuron module

    def forward(self, v):
        return Spike.apply(v)


class Net(nn.Module):  # reads latency spike trains or the same spikes as events
    def __init__(self, shape, classes, generator, steps):
        super().__init__()
        self.shape, self.steps = shape, steps
        self.fc = nn.Linear(shape[0] * shape[1], classes)
        nn.init.normal_(self.fc.weight, 0, 0.5, generator=generator)
        nn.init.zeros_(self.fc.bias)
        self.fire = Fire()

    def frames(self, events):  # (B, E, 4) events -> (T, B, H * W) spikes
        steps = self.steps
        real = events[..., 3] >= 0
        batch = torch.arange(len(events))[:, None].expand(real.shape)[real]
        pixel = (events[..., 1] * self.shape[1] + events[..., 0])[real].long()
        out = torch.zeros(steps, len(events), self.shape[0] * self.shape[1])
        out[events[..., 2][real].long(), batch, pixel] = 1.0
        return out

    def forward(self, x):
        x = self.frames(x) if x.dim() == 3 else x.flatten(2)
        v, spikes = 0.0, []
        for step in x:
            v = 0.8 * v + self.fc(step)
            spikes.append(self.fire(v))
            v = v * (1 - spikes[-1])
        return torch.stack(spikes)


def build(input_shape, classes, generator=None, steps=1):
    return Net(input_shape[1:], classes, generator, steps)
"""


def test_an_events_model_decides_as_its_latency_twin(tmp_path, datasets, cli):
    """One network declared on the "events" encoding and on "latency": the same spikes, so the
    same weights, test predictions and decision figures."""
    (tmp_path / "stepped.py").write_text(STEPPED)
    recipes = []
    for encoding in ("latency", "events"):
        recipe = tmp_path / f"{encoding}.toml"
        recipe.write_text(
            'model = "stepped.py:build"\n[architecture]\nsteps = 6\n'
            '[spec]\noutput = "stepped_spikes"\n'
            f'encoding = "{encoding}"\nsteps = 6\nreadout = "first_spike"\n'
            + TRAINING.format(epochs=2)
        )
        recipes.append(str(recipe))
    out = tmp_path / "b"
    result = _bench_json(cli, _suite(tmp_path, datasets), ",".join(recipes), out)
    assert result.exit_code == 0, result.output
    cells = {c["spec"]["encoding"]: c for c in json.loads(result.stdout)["cells"]}
    latency, events = cells["latency"], cells["events"]
    assert latency["kind"] == events["kind"] == "spiking"
    files = {
        c["spec"]["encoding"]: c
        for c in map(json.loads, map(Path.read_text, sorted((out / "cells").glob("*.json"))))
    }
    assert files["events"]["per_sample"] == files["latency"]["per_sample"]
    assert events["stepped"] == latency["stepped"]
    assert latency["stepped"]["samples"] == 64 and latency["stepped"]["decision_step_mean"]
    assert events["accuracy"] == latency["accuracy"]
    # the events model's layer is given frames it made itself: binary, accumulates
    assert events["synaptic_operations"] == latency["synaptic_operations"]
    assert events["synaptic_operations"]["effective_macs"] == 0


@pytest.mark.parametrize(
    "spec, words",
    [
        ('encoding = "events"\nsteps = 5', r"is \(6, 2, 32\); expected output spikes \(5 steps, 2"),
        ('encoding = "delays"', "encoding='delays' with output 'stepped_spikes': expected"),
    ],
)
def test_a_stepped_model_that_disagrees_with_its_spec_is_one_line(
    tmp_path, datasets, spec, words, cli
):
    (tmp_path / "stepped.py").write_text(STEPPED)
    recipe = tmp_path / "wrong.toml"
    recipe.write_text(
        'model = "stepped.py:build"\n[architecture]\nsteps = 6\n'
        f'[spec]\noutput = "stepped_spikes"\n{spec}\n' + TRAINING.format(epochs=1)
    )
    out = tmp_path / "b"
    result = cli("bench", "--suite", _suite(tmp_path, datasets), "--models", recipe, "--out", out)
    assert result.exit_code == 2 and "Traceback" not in result.output
    (line,) = [line for line in result.output.splitlines() if "rror" in line]
    assert "wrong" in line and __import__("re").search(words, line), result.output
    assert not (out / "cells").exists() or not list((out / "cells").iterdir())


def test_neuron_spikes_of_unknown_timing_are_counted_per_sample_over_the_window():
    """A neuron module called a number of times other than T (here twice in a 4-step run):
    its spikes go to the last step, per sample, and the summary says the timing is unknown."""
    from simlidar.bench.stepped import _NeuronSpikes

    class Neuron(torch.nn.Module):
        spiking_neuron = True

        def forward(self, x):
            return x

    class Net(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.lif = Neuron()

        def forward(self, x):
            return self.lif(x), self.lif(2 * x)

    net = Net()
    hooks = _NeuronSpikes(net, steps=4)
    net(torch.tensor([[1.0, 0.0], [0.0, 0.0], [1.0, 1.0]]))  # 3 samples, 2 neurons
    counts, stepwise = hooks.by_step(batch=3)
    hooks.remove()
    assert not stepwise
    assert counts[:3].abs().sum() == 0 and counts[3].tolist() == [3.0, 0.0, 6.0]


def test_train_prints_a_model_that_trained_itself(plain_module, datasets, tmp_path, cli):
    result = cli(
        "train",
        "--model",
        "outside_plain:fitted",
        "--dataset",
        datasets[0.1],
        "--out",
        tmp_path / "runs",
    )
    assert result.exit_code == 0, result.output
    assert "outside_plain.fitted: test accuracy" in result.output
    assert "trained by its own simlidar_fit" in result.output


def test_spikingjelly_neurons_start_every_forward_call_at_rest():
    """SpikingJelly's neurons keep their membrane potential between calls (their reset is the
    user's, functional.reset_net): a model built by simlidar has it reset before each forward
    call, so that a batch does not start from the last one's state, the batch size may change,
    and training does not backpropagate into the last batch's graph."""
    pytest.importorskip("spikingjelly")
    recipe = load_recipe(EXAMPLES / "spikingjelly_conv.toml")
    x = (torch.rand(25, 4, 1, 16, 16) > 0.9).float()
    make = builder(recipe["model"], Path(recipe["base"]))
    raw = make((1, 16, 16), 32, torch.Generator().manual_seed(0), **recipe["architecture"])
    model = build_model(recipe, (1, 16, 16), 32, torch.Generator().manual_seed(0))
    first = model(x)[1]
    assert model(x[:, :3])[1].shape == (25, 3, 32)  # a smaller batch
    assert torch.equal(model(x)[1], first)  # from rest again
    for _ in range(2):  # a second backward would reach the first batch's freed graph
        model(x)[1].sum().backward()
    # the builder's module as it is: the second call starts from the first's state
    assert torch.equal(raw(x)[1], first)
    assert not torch.equal(raw(x)[1], first)
    raw(x)[1].sum().backward()
    with pytest.raises(RuntimeError, match="backward through the graph a second time"):
        raw(x)[1].sum().backward()


def test_a_stepped_model_without_known_neurons_is_warned_about(datasets):
    """Its neurons' spikes cannot be counted: a warning says so, rather than a silent 0."""
    from simlidar.bench.stepped import stepped_decisions
    from simlidar.data import load_split
    from simlidar.models.protocol import ModelSpec

    class Threshold(torch.nn.Module):  # spikes made by a function, in no neuron module
        def forward(self, x):
            return (x.flatten(2)[..., :32] > 0).float()

    spec = ModelSpec(output="stepped_spikes", encoding="latency", steps=4, readout="spike_count")
    x, y = load_split(datasets[0.1], "test")
    with pytest.warns(UserWarning, match="Threshold: no spiking neuron module recognised"):
        summary = stepped_decisions(Threshold(), torch.from_numpy(x[:8])[:, None], y[:8], spec, 1.0)
    assert summary["neuron_spikes_mean"] == 0


def test_bench_help_names_every_way_to_give_a_model(cli):
    """It named only package.module:function."""
    text = " ".join(cli("bench", "--help").output.split())
    for words in (
        "path/to/file.py:function",
        "a .toml recipe file (its [spec] table",
        "docs/benchmark.md",
        "The suite's [budget] sets every model's epochs",
    ):
        assert words in text, words
