"""The event-driven evaluator agrees with the batched closed form, sample by sample.

Attack list (inputs that could make the two disagree):

* random dense networks, pruned synapses, and a spiking CNN written out as dense layers, on
  generated pulses: the same class, spike time, input and hidden spikes and accumulates;
* a near-tie built by hand: two output spikes one float32 rounding step apart, equal in the
  float32 forward and ordered in float64 (how a published cell's ``accuracy``, 0.7400, and
  ``early.accuracy``, 0.7383, came one sample apart): the accuracy's prediction and the
  event-driven decision read the same float64 spikes, so they pick the same class;
* an exact tie of two outputs: the lower class index, in the batched prediction, in
  ``decide_all`` and in the event-driven run.

Attack list of the two counting rules (hand-made spike trains where they differ):

* inputs at exactly t = 0 (z = 1) before the decision: ours counts them, the authors'
  ``0 < t < t_out`` does not;
* an input after the decision: counted by neither;
* an input at the very instant of the output spike (a tie at t_out): ours counts it (it is
  delivered first), the authors' does not;
* no decision at all: ours counts every input delivered, the authors' every input after t = 0;
* the batched evaluator (``decide_all``) gives the same two counts as the event-driven run.
"""

import numpy as np
import pytest
import torch

from simlidar.dataset.loaders import load_split
from simlidar.models import ttfs
from simlidar.models.decisions import ALPHAS_PJ, Decision, decide


def _random_net(seed, sizes=(256, 60, 32)):
    rng = np.random.default_rng(seed)
    return [rng.normal(3.0 / a, 1.0 / np.sqrt(a), (a, b)) for a, b in zip(sizes, sizes[1:])]


@pytest.mark.parametrize("seed", [0, 1])
def test_event_driven_equals_closed_form_on_every_test_sample(datasets, seed):
    x, _ = load_split(datasets[0.5], "test")
    weights = _random_net(seed)
    z = ttfs.encode(torch.from_numpy(x.astype(np.float64)).flatten(1), 3.0)
    out = z
    for w in weights:
        out = ttfs.dense(out, torch.from_numpy(w))
    expected = ttfs.predict(out).numpy()
    first = out.min(dim=1).values.numpy()
    for i in range(len(x)):
        d = decide(weights, z[i].numpy())
        assert d.label == expected[i], i
        if d.label >= 0:
            assert d.z == pytest.approx(first[i], rel=1e-9), i
            assert d.input_spikes <= d.input_total == int(torch.isfinite(z[i]).sum())


def test_a_decision_before_all_inputs_by_hand():
    # one input neuron pair feeding one output: input 0 at z=1 (w=2) makes the output fire at
    # z=2, before input 1 arrives at z=e^3: one of two input spikes consumed
    weights = [np.array([[2.0], [0.5]])]
    d = decide(weights, np.array([1.0, np.exp(3.0)]))
    assert (d.label, d.z, d.input_spikes, d.input_total, d.hidden_spikes) == (0, 2.0, 1, 2, 0)
    assert d.accumulates == 1  # input 0 reached its one synapse; the output spike reaches none
    assert d.data_ratio == 0.5 and d.time == pytest.approx(np.log(2.0))
    # network time ln 2 with scale 3 is the delay ln 2 / 3 of a 667.13 ns window
    assert d.time_ns(3.0, 667.128) == pytest.approx(np.log(2.0) / 3 * 667.128)
    assert d.spikes == 2 and d.energy_pj(ALPHAS_PJ[0]) == pytest.approx(0.74)


def test_a_silent_network_decides_nothing():
    d = decide([np.full((3, 2), 0.1)], np.array([1.0, 2.0, np.inf]))
    # two input spikes, two synapses each; the authors' rule leaves out the one at t = 0
    assert d == Decision(-1, np.inf, 2, 2, 0, 4, 1)


def test_accumulates_count_non_zero_synapses_by_hand():
    # input 0 (z=1) reaches hidden 0 (w=2) and, through a zero weight, nothing else; hidden 0
    # fires at z = 2 * 1 / (2 - 1) = 2 and reaches both outputs; output 1 (w=3) fires at
    # z = 3 * 2 / (3 - 1) = 3, before input 1 arrives at z = e^3 = 20.1: 1 + 2 accumulates
    weights = [np.array([[2.0, 0.0], [0.1, 0.1]]), np.array([[0.5, 3.0], [1.0, 1.0]])]
    d = decide(weights, np.array([1.0, np.exp(3.0)]))
    assert (d.label, d.z, d.input_spikes, d.hidden_spikes) == (1, 3.0, 1, 1)
    assert d.accumulates == 1 + 2


def test_accumulates_of_a_deeper_network_follow_the_closed_form(datasets):
    # 256-60-40-32 with a fifth of the weights zeroed: every input spike up to the decision and
    # every hidden spike before it (the batched closed form's spike times) reaches the non-zero
    # weights of its row
    x, _ = load_split(datasets[0.5], "test")
    rng = np.random.default_rng(3)
    weights = [w * (rng.random(w.shape) > 0.2) for w in _random_net(2, (256, 60, 40, 32))]
    z = ttfs.encode(torch.from_numpy(x.astype(np.float64)).flatten(1), 3.0)
    spikes = [z]  # (N, width) spike times of the inputs and of each layer
    for w in weights:
        spikes.append(ttfs.dense(spikes[-1], torch.from_numpy(w)))
    fan_out = [np.count_nonzero(w, axis=1) for w in weights]
    deep = 0
    for i in range(len(x)):
        d = decide(weights, z[i].numpy())
        before = [(s[i].numpy() <= d.z) & np.isfinite(s[i].numpy()) for s in spikes[:-1]]
        assert d.accumulates == sum(int(f[b].sum()) for f, b in zip(fan_out, before)), i
        assert (d.input_spikes, d.hidden_spikes) == (
            before[0].sum(),
            before[1].sum() + before[2].sum(),
        ), i
        deep += int(before[2].sum() > 0)
    assert deep > len(x) // 2  # the second hidden layer took part


def _dense_net(weights):
    """A SpikingNet of dense layers with these (N_in, N_out) weights."""
    from simlidar.models.layers import DenseTTFS
    from simlidar.models.networks import SpikingNet

    layers = []
    for w in weights:
        layer = DenseTTFS(*w.shape)
        layer.weight.data = torch.from_numpy(w)
        layers.append(layer)
    return SpikingNet(layers, 3.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_batched_decisions_equal_the_event_driven_run(datasets, seed):
    from simlidar.models.decisions import decide_all

    x, _ = load_split(datasets[0.5], "test")
    weights = _random_net(seed)
    weights[0][np.random.default_rng(seed).random(weights[0].shape) < 0.2] = 0.0  # pruned
    z = ttfs.encode(torch.from_numpy(x.astype(np.float64)).flatten(1), 3.0)
    batched = decide_all(_dense_net(weights), z)
    for i in range(len(x)):
        one = decide(weights, z[i].numpy())
        assert batched[i].label == one.label, i
        assert batched[i].z == pytest.approx(one.z, rel=1e-9) or one.z == batched[i].z == np.inf
        got = (batched[i].input_spikes, batched[i].hidden_spikes, batched[i].accumulates)
        assert got == (one.input_spikes, one.hidden_spikes, one.accumulates), i
    assert 0 < np.mean([d.data_ratio for d in batched]) <= 1


def _conv_as_dense(w, shape, stride, padding):
    """A convolution's weights written out as a dense (C H W, C_out H_out W_out) matrix: zero
    where an input is not in an output's receptive field (padding: no input at all)."""
    c_out, c_in, k, _ = w.shape
    _, h, wd = shape
    h_out, w_out = (h + 2 * padding - k) // stride + 1, (wd + 2 * padding - k) // stride + 1
    dense = np.zeros((c_in, h, wd, c_out, h_out, w_out))
    for fy in range(h_out):
        for fx in range(w_out):
            for ky in range(k):
                for kx in range(k):
                    y, x = fy * stride - padding + ky, fx * stride - padding + kx
                    if 0 <= y < h and 0 <= x < wd:
                        dense[:, y, x, :, fy, fx] = w[:, :, ky, kx].T
    return dense.reshape(c_in * h * wd, c_out * h_out * w_out), (c_out, h_out, w_out)


def test_a_convolutional_network_decides_as_its_dense_equivalent():
    """decide_all on a spiking CNN equals the event-driven run of the same network with each
    convolution written out as a dense layer (same spikes, same synapses)."""
    from simlidar.models.decisions import decide_all
    from simlidar.models.networks import spiking_cnn

    generator = torch.Generator().manual_seed(3)
    model = spiking_cnn(
        (1, 9, 13), 4, generator, conv=((3, 3, 2), (2, 3, 1)), dense=(12,), excess=8.0
    )
    for layer in model.layers:
        layer.weight.data = layer.weight.data.double()
    model.layers[0].weight.data[0, 0, 1, 1] = 0.0  # a pruned synapse
    x = torch.rand(12, 1, 9, 13, generator=generator, dtype=torch.float64)
    z = ttfs.encode(x, 3.0, 0.9)  # delays above 0.9: no spike
    batched = decide_all(model, z)
    weights, shape = [], (1, 9, 13)
    for layer in model.layers:
        w = layer.weight.detach().numpy()
        if w.ndim == 4:
            dense, shape = _conv_as_dense(w, shape, layer.stride, layer.padding)
            weights.append(dense)
        else:
            weights.append(w)
    for i in range(len(x)):
        one = decide(weights, z[i].flatten().numpy())
        assert (batched[i].label, batched[i].input_spikes) == (one.label, one.input_spikes), i
        assert (batched[i].hidden_spikes, batched[i].accumulates) == (
            one.hidden_spikes,
            one.accumulates,
        ), i
        assert batched[i].z == pytest.approx(one.z, rel=1e-9) or one.z == batched[i].z
    assert any(d.label >= 0 for d in batched) and any(d.data_ratio < 1 for d in batched)


def _near_tie():
    """Two float32 delays one rounding step apart (d_late > d_early) that the float32 encoding
    maps to the same input spike, and a network in which output 0 fires at 2 z(d_late) and
    output 1 at 2 z(d_early): tied in float32, output 1 first in float64."""
    delays = torch.linspace(0.7, 0.99, 4096, dtype=torch.float32)
    earlier = torch.nextafter(delays, torch.zeros_like(delays))
    same = ttfs.encode(delays, 3.0) == ttfs.encode(earlier, 3.0)
    i = int(torch.nonzero(same)[0])  # rounding of 3 * d makes many such pairs
    x = torch.stack([delays[i], earlier[i]]).reshape(1, 1, 1, 2)  # (B, C, H, W)
    model = _dense_net([np.array([[2.0, 0.0], [0.0, 2.0]], dtype=np.float32)])
    return model, x


def test_a_near_tie_goes_the_same_way_in_the_accuracy_and_the_event_driven_run():
    from simlidar.bench.scoring import predictions
    from simlidar.models.decisions import decide_all

    model, x = _near_tie()
    single = model(x)  # float32, as trained: the two outputs tie
    assert single[0, 0] == single[0, 1] and ttfs.predict(single).tolist() == [0]
    exact = model(x.double())  # float64: output 1 fires first, by a rounding step
    assert exact[0, 1] < exact[0, 0] and exact[0, 0] / exact[0, 1] - 1 < 1e-6
    z = ttfs.encode(x.double().flatten(1), 3.0)
    assert [d.label for d in decide_all(model, z)] == [1]
    weights = [layer.weight.detach().double().numpy() for layer in model.layers]
    assert decide(weights, z[0].numpy()).label == 1
    assert predictions(model, x).tolist() == [1]  # the cell's accuracy: the same rule


def test_an_exact_tie_goes_to_the_lower_class_everywhere():
    from simlidar.bench.scoring import predictions
    from simlidar.models.decisions import decide_all

    model, x = _near_tie()
    x[..., 1] = x[..., 0]  # the same delay: the two outputs fire at the same instant
    z = ttfs.encode(x.double().flatten(1), 3.0)
    weights = [layer.weight.detach().double().numpy() for layer in model.layers]
    assert predictions(model, x).tolist() == [0]
    assert [d.label for d in decide_all(model, z)] == [0]
    assert decide(weights, z[0].numpy()).label == 0


def _both_counts(weights, z_in):
    """(ours, authors') from the event-driven run and from the batched one, checked equal."""
    from simlidar.models.decisions import decide_all

    one = decide(weights, z_in)
    (batched,) = decide_all(_dense_net(weights), torch.from_numpy(z_in)[None])
    assert (batched.label, batched.input_spikes, batched.input_spikes_authors) == (
        one.label,
        one.input_spikes,
        one.input_spikes_authors,
    )
    return one


def test_inputs_at_time_zero_count_for_us_not_for_the_authors():
    # inputs 0 and 1 at t = 0 (z = 1, w = 1 + 0.5) and input 2 at t = 0.5 (w = 1): the output
    # fires at z = (1 + 0.5 + 1.6487) / (2.5 - 1) = 2.10, before input 3 at z = e^3
    z_in = np.array([1.0, 1.0, np.exp(0.5), np.exp(3.0)])
    d = _both_counts([np.array([[1.0], [0.5], [1.0], [0.5]])], z_in)
    assert d.label == 0 and d.z == pytest.approx((1.5 + np.exp(0.5)) / 1.5)
    assert (d.input_spikes, d.input_spikes_authors, d.input_total) == (3, 1, 4)


def test_a_tie_at_the_decision_counts_for_us_not_for_the_authors():
    # input 0 at z = 1.5 (w = 2) makes the output fire at z = 2 * 1.5 / (2 - 1) = 3.0; input 1
    # arrives at exactly z = 3.0 (delivered first: it does not move the spike, since
    # (3 + 0.5 * 3) / (2.5 - 1) = 3); input 2 at z = 5 comes after the decision
    z_in = np.array([1.5, 3.0, 5.0])
    d = _both_counts([np.array([[2.0], [0.5], [0.5]])], z_in)
    assert (d.label, d.z) == (0, 3.0)
    assert (d.input_spikes, d.input_spikes_authors) == (2, 1)


def test_without_a_decision_the_authors_count_every_input_after_time_zero():
    d = _both_counts([np.full((4, 2), 0.1)], np.array([1.0, 1.0, 2.0, np.inf]))
    assert (d.label, d.input_spikes, d.input_spikes_authors, d.input_total) == (-1, 3, 1, 3)


def test_the_counts_agree_when_no_input_is_at_zero_or_at_the_decision(datasets):
    # noisy delays: no input at exactly t = 0 and (almost surely) none at t_out, so the two
    # rules give the same count on every sample
    from simlidar.models.decisions import authors_count, decide_all

    x, _ = load_split(datasets[0.5], "test")
    z = ttfs.encode(torch.from_numpy(x.astype(np.float64)).flatten(1), 3.0)
    assert (z > 1.0).all()
    runs = decide_all(_dense_net(_random_net(0)), z)
    assert [d.input_spikes_authors for d in runs] == [d.input_spikes for d in runs]
    assert authors_count(np.array([1.0, 2.0, np.inf]), 2.0) == 0
