"""The event-driven evaluator agrees with the batched closed form, sample by sample."""

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
    assert d == Decision(-1, np.inf, 2, 2, 0, 4)  # two input spikes, two synapses each


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
