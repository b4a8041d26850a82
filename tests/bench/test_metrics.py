"""Benchmark metrics against numbers derived by hand, and against NeuroBench itself.

Figures reported under NeuroBench's names must be NeuroBench's: the library (the `test` extra
pins the version whose definitions docs/benchmark.md describes) measures the same models on the
same inputs, and any difference fails here.
"""

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader, TensorDataset

from simlidar.bench import metrics
from simlidar.bench.early import early_decisions
from simlidar.dataset.loaders import load_split
from simlidar.models.registry import build_model, load_recipe

RESNET = {"plan": "resnet18", "width": 4}  # as tests/bench/test_bench.py's small ResNet
RECIPES = {
    "cnn": load_recipe("cnn")["architecture"],
    "mlp": load_recipe("mlp")["architecture"],
    "resnet18": RESNET,
    "resnet50": {"plan": "resnet50", "width": 4},
}
BATCH = 16


def _model(name: str) -> torch.nn.Module:
    family = "resnet" if name.startswith("resnet") else "cnn"
    recipe = {"name": name, "model": family, "architecture": RECIPES[name]}
    return build_model(recipe, (1, 16, 16), 32, torch.Generator().manual_seed(0))


def _prune(model: torch.nn.Module, fraction: float = 0.2) -> torch.nn.Module:
    """Zero the smallest ``fraction`` of each connection layer's weights (so that connection
    sparsity and the non-zero-weight rule of the effective counts are exercised)."""
    with torch.no_grad():
        for m in model.modules():
            if isinstance(m, metrics.CONNECTION_LAYERS):
                m.weight[m.weight.abs() <= m.weight.abs().quantile(fraction)] = 0.0
    return model


def _neurobench(model: torch.nn.Module, x: torch.Tensor) -> dict:
    """NeuroBench's own figures of ``model`` over the inputs x (N, C, H, W)."""
    from neurobench.benchmarks import Benchmark
    from neurobench.metrics.static import ConnectionSparsity, Footprint, ParameterCount
    from neurobench.metrics.workload import ActivationSparsity, SynapticOperations
    from neurobench.models import TorchModel

    labels = torch.zeros(len(x), dtype=torch.long)
    loader = DataLoader(TensorDataset(x, labels), batch_size=BATCH)
    static = [Footprint, ParameterCount, ConnectionSparsity]
    bench = Benchmark(
        TorchModel(model), loader, [], [], [static, [ActivationSparsity, SynapticOperations]]
    )
    return bench.run(quiet=True)


@pytest.fixture(scope="module")
def pulses(datasets):
    """The test split of a generated dataset (64 samples; missing returns are 0.0, so the first
    layer has zero inputs too): (N, 1, 16, 16)."""
    x, _ = load_split(datasets[0.5], "test")
    return torch.from_numpy(x)[:, None]


@pytest.mark.parametrize(
    "name, spikes",
    [("cnn", False), ("mlp", False), ("mlp", True), ("resnet18", False), ("resnet50", True)],
)
def test_figures_under_neurobench_names_are_neurobenchs(pulses, name, spikes):
    # spikes: binary inputs, which NeuroBench counts as accumulates in the first layer
    x = (pulses[:40] > 0.5).float() if spikes else pulses[:40]  # batches of 16, 16 and 8
    model = _prune(_model(name))
    ours = {**metrics.footprint(model), **metrics.workload(model, x, batch_size=BATCH)}
    theirs = _neurobench(model, x)
    assert ours["params"] == theirs["ParameterCount"]
    assert ours["footprint"] == theirs["Footprint"]
    assert 0.19 < ours["connection_sparsity"] < 0.21
    assert round(ours["connection_sparsity"], 4) == theirs["ConnectionSparsity"]  # NB rounds
    assert ours["activation_sparsity"] == pytest.approx(theirs["ActivationSparsity"], rel=1e-12)
    ops, nb_ops = ours["synaptic_operations"], theirs["SynapticOperations"]
    assert ops == {
        "effective_macs": nb_ops["Effective_MACs"],
        "effective_acs": nb_ops["Effective_ACs"],
        "dense": nb_ops["Dense"],
    }
    assert (ops["effective_acs"] > 0) == spikes
    assert 0 < ops["effective_macs"] + ops["effective_acs"] < ops["dense"]


def test_the_issue_figures_of_the_unpruned_cnn(pulses):
    # the cnn recipe untrained, seed 0: what NeuroBench 2.3.0 reported when the issue was filed
    model = _model("cnn")
    ours = {**metrics.footprint(model), **metrics.workload(model, pulses)}
    assert (ours["params"], ours["footprint"], ours["connection_sparsity"]) == (
        136_856,
        547_424,
        0.0,
    )
    assert (
        ours["synaptic_operations"]["dense"]
        == _neurobench(model, pulses)["SynapticOperations"]["Dense"]
        == 505_136
    )


def test_neurobenchs_dense_count_leaves_out_the_padding():
    """Why NeuroBench's dense count of the CNN (505,136) is below the hand count (644,096).

    Both count the same layers (the two convolutions and the two linear layers) and neither
    counts the bias. The hand count multiplies every output by its full kernel; NeuroBench runs
    each layer with all weights and inputs set to 1 and sums the outputs, so a kernel position
    that falls on the zero padding adds nothing. A 5 x 5 kernel at stride 2 with padding 2 over
    16 rows sees, output row by output row, 3, 5, 5, 5, 5, 5, 5, 4 input rows: 37 of 8 x 5;
    over 8 rows (second convolution) 3, 5, 5, 4: 17 of 4 x 5.
    """
    model = _model("cnn")
    hand = metrics.macs(model, torch.rand(1, 16, 16))
    conv1 = 48 * 8 * 8 * (1 * 5 * 5)  # 16 x 16 -> 8 x 8 (5x5, stride 2, pad 2)
    conv2 = 24 * 4 * 4 * (48 * 5 * 5)  # 8 x 8 -> 4 x 4
    dense = 24 * 4 * 4 * 256 + 256 * 32
    assert hand == conv1 + conv2 + dense == 644_096
    assert sum(min(2 * i + 2, 15) - max(2 * i - 2, 0) + 1 for i in range(8)) == 37
    assert sum(min(2 * i + 2, 7) - max(2 * i - 2, 0) + 1 for i in range(4)) == 17
    conv1_in, conv2_in = 48 * 37 * 37 * 1, 24 * 17 * 17 * 48
    ones = torch.ones(1, 1, 16, 16)
    counted = metrics.workload(model, ones)["synaptic_operations"]
    assert counted["dense"] == conv1_in + conv2_in + dense == 505_136
    assert hand - counted["dense"] == (conv1 - conv1_in) + (conv2 - conv2_in) == 138_960
    # an input of ones makes every product effective, padding aside, until a ReLU outputs 0
    first = metrics.layer_operations(model.net[0], ones)
    assert first == (conv1_in, conv1_in)


def test_activation_sparsity_is_over_the_whole_split(pulses):
    model = _model("cnn")
    x = pulses[:20]
    whole = metrics.workload(model, x)["activation_sparsity"]
    one_by_one = [metrics.workload(model, s[None])["activation_sparsity"] for s in x]
    # every sample has as many activations, so the split's fraction is the mean of the samples'
    assert whole == pytest.approx(np.mean(one_by_one), rel=1e-12)
    assert whole != pytest.approx(one_by_one[0], rel=1e-3)  # not the first sample's
    assert metrics.workload(model, x, batch_size=3) == metrics.workload(model, x)


def test_footprint_and_connection_sparsity():
    model = torch.nn.Sequential(torch.nn.Linear(4, 3), torch.nn.BatchNorm1d(3))
    with torch.no_grad():
        model[0].weight[:2] = 0.0  # 8 of 12 weights
    figures = metrics.footprint(model)
    assert figures["params"] == 4 * 3 + 3 + 3 + 3
    # float32 parameters and buffers (running mean and var), plus int64 num_batches_tracked
    assert figures["footprint"] == 4 * (12 + 3 + 3 + 3 + 3 + 3) + 8
    assert figures["connection_sparsity"] == 8 / 12  # the batch norm's weight is no connection


def test_spiking_figures_of_a_deeper_network_from_the_event_driven_run(datasets):
    recipe = {"name": "snn2", "model": "snn", "architecture": {"hidden": [40, 20]}}
    model = build_model(recipe, (1, 16, 16), 32, torch.Generator().manual_seed(0))
    with torch.no_grad():
        model.layers[1].weight[:5] = 0.0  # the first 5 neurons of layer 1 reach nothing
    early = early_decisions(model, datasets[0.5])
    x, _ = load_split(datasets[0.5], "test")
    figures = metrics.spiking_figures(model, torch.from_numpy(x)[:, None], early)
    ops = figures["synaptic_operations"]
    assert ops["effective_macs"] == 0 and ops["effective_acs"] == early["accumulates_mean"]
    assert ops["dense"] == 256 * 40 + 40 * 20 + 20 * 32
    # at most every input spike to all 40, every hidden spike to its 20 or 32 successors
    assert early["hidden_spikes_mean"] > 0
    assert early["input_spikes_mean"] * 40 < ops["effective_acs"]
    assert (
        ops["effective_acs"] <= early["input_spikes_mean"] * 40 + early["hidden_spikes_mean"] * 32
    )
    fired = early["hidden_spikes_mean"] + 1 - early["no_decision"] / early["samples"]
    assert figures["activation_sparsity"] == pytest.approx(1 - fired / (40 + 20 + 32))


def test_spiking_figures_count_a_missing_returns_channel_of_its_own(datasets):
    """With ``missing = "own_channel"`` the first convolution reads twice the channels: the
    dense synapses count them (from the delays' shape alone the layers did not fit)."""
    x, _ = load_split(datasets[0.5], "test")
    found = {}
    for missing in ("as_value", "own_channel"):
        architecture = {"conv": [[4, 3, 2]], "dense": [8], "missing": missing}
        recipe = {"name": "scnn", "model": "scnn", "architecture": architecture}
        model = build_model(recipe, (1, 16, 16), 32, torch.Generator().manual_seed(0))
        early = early_decisions(model, datasets[0.5])
        figures = metrics.spiking_figures(model, torch.from_numpy(x)[:, None], early)
        found[missing] = figures["synaptic_operations"]["dense"]
    after = 4 * 8 * 8 * 8 + 8 * 32  # the dense layers': the same in both
    assert found["own_channel"] - after == 2 * (found["as_value"] - after) > 0


def test_confusion_matrix_counts_undecided_samples_apart():
    labels = np.array([0, 0, 1, 2, 2])
    predicted = np.array([0, 1, 1, -1, 2])
    matrix = metrics.confusion_matrix(labels, predicted, 3)
    assert matrix.tolist() == [[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1]]


def test_latency_and_board_energy():
    model = build_model(load_recipe("cnn"), (1, 16, 16), 4)
    x = torch.rand(40, 1, 16, 16)
    figures = metrics.conventional_figures(model, x, board_power_w=10.0)
    assert figures["latency_ms"] > 0 and figures["throughput_per_s"] > 0
    assert figures["throughput_batch"] == 40
    # power x latency: 10 W = 1e13 pJ/s, times t ms = t 1e-3 s
    assert np.isclose(figures["energy_pj_board"], 10.0 * figures["latency_ms"] * 1e9)
    assert figures["energy_pj_mac"] == figures["macs"] * metrics.MAC_PJ
    assert figures["synaptic_operations"]["dense"] < figures["macs"]  # no padding products


def test_the_spiking_cnn_has_the_synapses_neurobench_counts_for_its_cnn(pulses):
    """A spiking CNN's synapses (each neuron spikes at most once: NeuroBench's dense count of an
    event-driven run) are the products NeuroBench's Dense counts for the ReLU CNN of the same
    layers: padding connects nothing in both."""
    from simlidar.models.decisions import network_size
    from simlidar.models.registry import build_model, load_recipe

    scnn = build_model(load_recipe("scnn_kitti"), (1, 16, 16), 32)
    cnn = _model("cnn")
    dense = _neurobench(cnn, pulses)["SynapticOperations"]["Dense"]
    neurons, synapses = network_size(scnn, (1, 16, 16))
    assert synapses == dense == 505_136
    assert neurons == 48 * 8 * 8 + 24 * 4 * 4 + 256 + 32


def test_spikingjelly_multi_step_layers_count_every_step():
    """SpikingJelly's layers in step_mode "m" take the whole (T, B, ...) train in one call: each
    step's inputs are counted as NeuroBench's count of one sample each, T x B in all, the same
    through a layer.Conv2d (an nn.Conv2d subclass), an nn.Conv2d wrapped in a
    SeqToANNContainer (called on (T x B, ...)) and a layer.Linear; its neurons (BaseNode) are
    spiking neuron modules."""
    pytest.importorskip("spikingjelly")
    from spikingjelly.activation_based import layer, neuron

    torch.manual_seed(0)
    conv = layer.Conv2d(2, 3, 3, stride=2, padding=1, step_mode="m")
    wrapped = layer.SeqToANNContainer(torch.nn.Conv2d(2, 3, 3, stride=2, padding=1))
    wrapped[0].load_state_dict(conv.state_dict())
    linear = layer.Linear(12, 5, step_mode="m")
    with torch.no_grad():
        conv.weight[0] = 0.0  # a channel of zero weights: 18 of 54
    x = (torch.rand(4, 6, 2, 5, 5) > 0.6).float()  # (T, B, C, H, W) spikes
    single = torch.nn.Conv2d(2, 3, 3, stride=2, padding=1)
    single.load_state_dict(conv.state_dict())
    per_step = [metrics.layer_operations(single, step) for step in x]
    summed = tuple(sum(c[i] for c in per_step) for i in (0, 1))
    assert metrics.layer_operations(conv, x) == summed
    # dense, by hand, per T x B: 3 output channels x 2 input channels x the kernel's products
    # inside the 5 x 5 image: its 3 rows at the 3 output rows see 2, 3 and 2 image rows (7),
    # and as many columns
    assert summed[1] == 4 * 6 * 3 * 2 * 7 * 7
    assert summed[0] < summed[1] * 2 / 3
    seen = []
    hook = wrapped[0].register_forward_pre_hook(lambda m, i: seen.append(i[0].shape))
    assert wrapped(x).shape == (4, 6, 3, 3, 3) and seen == [(24, 2, 5, 5)]
    hook.remove()
    spikes = (torch.rand(4, 6, 12) > 0.5).float()
    effective, dense = metrics.layer_operations(linear, spikes)
    assert dense == 4 * 6 * 12 * 5
    assert effective == int((spikes != 0).sum()) * 5  # no zero weights
    assert metrics.is_spiking_neuron(neuron.LIFNode(step_mode="m"))
    assert metrics.is_spiking_neuron(neuron.IFNode())
    assert not metrics.is_spiking_neuron(linear)


def test_norse_recurrent_synapses_count_by_hand():
    """Norse's LIFRecurrentCell and LIFRecurrent hold their synapses themselves (input_weights
    (hidden, in), recurrent_weights (hidden, hidden)); NeuroBench counts neither, simlidar both.

    2 neurons, 3 inputs; input weights [[8, 0, 8], [0, 0, 8]], recurrent [[0, 5], [5, 0]] (no
    autapses); Norse's defaults: per step the current jumps by the weighted inputs, then
    v += 0.1 (i - v), a spike above 1 resets v to 0, and i decays by a fifth. Sample 1 gets
    inputs [1, 0, 1], [0, 1, 0], [0, 0, 0] over 3 steps; sample 2 nothing. Step 0: the input
    reaches 3 non-zero weights (input 0 -> neuron 0, input 2 -> both); no spikes before it;
    i = (16, 8), v = (1.6, 0.8): neuron 0 fires. Step 1: input 1 has only zero weights; neuron
    0's spike reaches neuron 1 (1 recurrent synapse): i = (12.8, 6.4 + 5), v = (1.28, 1.86):
    both fire. Step 2: no input; the two spikes reach the 2 non-zero recurrent weights; i =
    (10.24 + 5, 9.12 + 5), both fire again. Effective 3 + 1 + 2 = 6 accumulates (binary inputs
    and spikes), 3 a sample; dense 3 x (6 + 4) = 30 a sample (every weight each step).
    """
    norse = pytest.importorskip("norse.torch")

    def cell(kind):
        made = kind(3, 2)
        with torch.no_grad():
            made.input_weights.copy_(torch.tensor([[8.0, 0, 8], [0, 0, 8]]))
            made.recurrent_weights.copy_(torch.tensor([[0.0, 5], [5, 0]]))
        return made

    class Stepped(torch.nn.Module):  # (B, T, 3) -> spikes (T, B, 2), the cell once a step
        def __init__(self):
            super().__init__()
            self.cell = cell(norse.LIFRecurrentCell)

        def forward(self, x):
            state, spikes = None, []
            for step in x.transpose(0, 1):
                z, state = self.cell(step, state)
                spikes.append(z)
            return torch.stack(spikes)

    class Layer(torch.nn.Module):  # the same as a layer over all steps
        def __init__(self):
            super().__init__()
            self.layer = cell(norse.LIFRecurrent)

        def forward(self, x):
            return self.layer(x.transpose(0, 1))[0]

    x = torch.zeros(2, 3, 3)
    x[0, 0] = torch.tensor([1.0, 0, 1])
    x[0, 1] = torch.tensor([0.0, 1, 0])
    for model in (Stepped(), Layer()):
        assert model(x).tolist() == [[[1, 0], [0, 0]], [[1, 1], [0, 0]], [[1, 1], [0, 0]]]
        figures = metrics.workload(model, x)
        assert figures["synaptic_operations"] == {
            "effective_macs": 0.0,
            "effective_acs": 3.0,
            "dense": 30.0,
        }
        assert figures["activation_sparsity"] == pytest.approx(1 - 5 / 12)  # 5 spikes of 12
        assert metrics.footprint(model)["connection_sparsity"] == 5 / 10  # 3 + 2 zeros
    # NeuroBench sees no connection layer in it: no synapses, no operations
    from neurobench.benchmarks import Benchmark
    from neurobench.metrics.static import ConnectionSparsity
    from neurobench.metrics.workload import SynapticOperations
    from neurobench.models import TorchModel

    loader = DataLoader(TensorDataset(x, torch.zeros(2)), batch_size=2)
    workload = [[ConnectionSparsity], [SynapticOperations]]
    theirs = Benchmark(TorchModel(Layer()), loader, [], [], workload).run(quiet=True)
    assert theirs["ConnectionSparsity"] is None
    assert theirs["SynapticOperations"] == {"Effective_MACs": 0, "Effective_ACs": 0, "Dense": 0}
    # the cell's state given as a keyword, spikes in it: their recurrent synapses count
    c = cell(norse.LIFRecurrentCell)
    _, state = c(torch.zeros(1, 3))
    state = state._replace(z=torch.tensor([[1.0, 0.0]]))
    (_, (effective, dense, _)) = metrics.recurrent_operations(
        c, (torch.zeros(1, 3),), {"state": state}, None
    )
    assert (effective, dense) == (1, 4)
