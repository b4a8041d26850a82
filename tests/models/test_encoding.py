"""The input encoding as a named choice: the spike-time direction and what a missing return
becomes (``ttfs.encode``, a spiking network's ``[architecture]`` keys ``direction`` and
``missing``).

Attack list:
* each direction and each treatment of a missing return, on delays whose spike times are
  worked out by hand (a return at the window's start and end, a missing return under both
  profiles' rules);
* today's encoding unchanged: the default equals an explicit ``near_first`` / ``as_value`` bit
  for bit on real delays, and a network trained with the defaults has the same weights as one
  trained with the explicit keys (a changed default would change today's datasets' cells);
* a value outside the choices, in a recipe: one line naming the key, no traceback;
* the choice reaches the cell (the recipe records it), survives a checkpoint, and the
  evaluator reads it (far-first spikes carry no sensor time);
* the authors' setting (far first, a missing return as the farthest value) spikes missing
  returns at exactly t = 0, which the authors' counting rule leaves out;
* an input budget (``input_budget``): the gate keeps each sample's first spikes, ties at the
  budget's time included, by hand; a network behind it never consumes more, in training and
  in the event-driven evaluation; a budget that is not a whole number >= 1 is one line.
"""

import math

import numpy as np
import pytest
import torch

from simlidar.bench.checkpoints import load_checkpoint, save_checkpoint
from simlidar.bench.train import train
from simlidar.dataset.loaders import load_split
from simlidar.errors import ConfigError
from simlidar.models import ttfs
from simlidar.models.decisions import decide_all
from simlidar.models.networks import dense_snn
from simlidar.models.registry import build_model, load_recipe

E = math.e
# a return at the window's start, one a quarter in, a missing return written as 1.0
DELAYS = torch.tensor([0.0, 0.25, 1.0], dtype=torch.float64)


@pytest.mark.parametrize(
    "direction, missing, no_return, times",
    [
        # t = 2 d; the data's rule (physical: 1.0 and above is no spike) decides the missing
        ("near_first", "as_value", 1.0, [0.0, 0.5, None]),
        # t = 2 (1 - d): the larger value first
        ("far_first", "as_value", 1.0, [2.0, 1.5, None]),
        # the missing return as the farthest value: last near-first, at t = 0 far-first
        ("near_first", "farthest", 1.0, [0.0, 0.5, 2.0]),
        ("far_first", "farthest", 1.0, [2.0, 1.5, 0.0]),
        # every pixel a spike by the data's rule (paper), but 1.0 is the end of the window
        ("near_first", "as_value", math.inf, [0.0, 0.5, 2.0]),
        ("near_first", "no_spike", math.inf, [0.0, 0.5, None]),
        ("far_first", "no_spike", 1.0, [2.0, 1.5, None]),
    ],
)
def test_spike_times_by_hand(direction, missing, no_return, times):
    z = ttfs.encode(DELAYS, 2.0, no_return, direction, missing)
    expected = [math.inf if t is None else math.exp(t) for t in times]
    assert z.tolist() == pytest.approx(expected)


@pytest.mark.parametrize(
    "direction, no_return, times, told",
    [
        # the returns as "no_spike"; the missing return told by a second channel at the
        # window's end: t = 2 near-first, t = 0 far-first
        ("near_first", 1.0, [0.0, 0.5, None], [None, None, 2.0]),
        ("far_first", 1.0, [2.0, 1.5, None], [None, None, 0.0]),
        # under paper's rule only the window's end (1.0) is missing
        ("near_first", math.inf, [0.0, 0.5, None], [None, None, 2.0]),
    ],
)
def test_a_missing_return_in_a_channel_of_its_own_by_hand(direction, no_return, times, told):
    z = ttfs.encode(DELAYS, 2.0, no_return, direction, "own_channel")
    expected = [math.inf if t is None else math.exp(t) for t in times + told]
    assert z.tolist() == pytest.approx(expected)
    images = DELAYS.reshape(1, 1, 1, 3).repeat(1, 2, 2, 1)  # (B, C, H, W) = (1, 2, 2, 3)
    z = ttfs.encode(images, 2.0, no_return, direction, "own_channel")
    assert z.shape == (1, 4, 2, 3)  # the returns' two channels, then the missing returns'
    assert torch.equal(z[:, :2], ttfs.encode(images, 2.0, no_return, direction, "no_spike"))
    assert z[0, 2:].isfinite().sum() == 4 and torch.isfinite(z[0, 2:, :, 2]).all()


def test_networks_read_twice_the_channels_where_a_missing_return_has_its_own():
    g = torch.Generator().manual_seed(0)
    assert ttfs.input_channels("own_channel") == 2 and ttfs.input_channels("no_spike") == 1
    dense = dense_snn((1, 16, 16), 32, g, missing="own_channel", input_budget=64)
    assert dense.layers[0].weight.shape[0] == 512
    assert dense.arriving_fraction((1, 16, 16)) == 64 / 512
    # each pixel spikes in one of its two channels: the first layers start for half the inputs
    g = torch.Generator().manual_seed(0)
    assert (
        dense_snn((1, 16, 16), 32, g, missing="own_channel").arriving_fraction((1, 16, 16)) == 0.5
    )
    conv = build_model(load_recipe("scnn_simlidar_tuned"), (1, 16, 16), 32, g)
    assert conv.layers[0].weight.shape[1] == 1
    recipe = load_recipe("scnn_simlidar_tuned")
    recipe["architecture"]["missing"] = "own_channel"
    conv = build_model(recipe, (1, 16, 16), 32, g)
    assert conv.layers[0].weight.shape[1] == 2
    first = conv.layers[0].weight.double()  # N((1 + excess) / (fan_in / 2), ...): 18 inputs
    assert first.sum(dim=(1, 2, 3)).mean().item() == pytest.approx(2 * 3.0, rel=0.1)
    x = torch.rand(3, 1, 16, 16, generator=g)
    x[x > 0.7] = 1.0
    assert conv(x).shape == (3, 32) and dense(x).shape == (3, 32)


def test_a_bad_choice_is_refused():
    with pytest.raises(ValueError, match="direction='sideways'"):
        ttfs.encode(DELAYS, 2.0, direction="sideways")


def test_the_default_is_todays_encoding_bit_for_bit(datasets):
    x, _ = load_split(datasets[0.1], "test")
    delays = torch.from_numpy(x)[:, None]
    for no_return in (1.0, math.inf):
        today = ttfs.encode(delays, 3.0, no_return)
        assert torch.equal(today, ttfs.encode(delays, 3.0, no_return, "near_first", "as_value"))
        # the expression before the choice existed
        spike = delays < no_return
        before = torch.where(spike, torch.exp(3.0 * torch.where(spike, delays, 0.0)), torch.inf)
        assert torch.equal(today, before)
    model = dense_snn((1, 16, 16), 32)
    assert (model.direction, model.missing) == ("near_first", "as_value")


def _tiny(**encoding):
    recipe = load_recipe("snn_simlidar")
    recipe["architecture"].update(hidden=[16], **encoding)
    recipe["training"].update(optimizer="adam", lr=3e-3, batch_size=32, validation=0)
    return recipe


def test_training_with_the_default_equals_an_explicit_near_first(datasets):
    default = train(_tiny(), datasets[0.1], seed=0, epochs=2, progress=False)
    explicit = train(
        _tiny(direction="near_first", missing="as_value"),
        datasets[0.1],
        seed=0,
        epochs=2,
        progress=False,
    )
    far = train(_tiny(direction="far_first"), datasets[0.1], seed=0, epochs=2, progress=False)
    for a, b, c in zip(
        default.model.parameters(), explicit.model.parameters(), far.model.parameters()
    ):
        assert torch.equal(a, b)
        assert not torch.equal(a, c)  # the choice is used: other inputs, other weights


# one train() call a setting, written out: each test's own (alike in form)
def test_the_choice_is_recorded_and_survives_a_checkpoint(datasets, tmp_path):
    from simlidar.bench.early import early_decisions

    result = train(
        _tiny(direction="far_first", missing="farthest"),
        datasets[0.1],
        seed=0,
        epochs=1,
        progress=False,
    )
    assert result.recipe["architecture"]["direction"] == "far_first"
    model, _ = load_checkpoint(save_checkpoint(result, tmp_path / "far.pt"), (1, 16, 16), 32)
    assert (model.direction, model.missing) == ("far_first", "farthest")
    x, _ = load_split(datasets[0.1], "test")
    delays = torch.from_numpy(x)[:, None]
    assert torch.equal(model.input_spikes(delays), result.model.input_spikes(delays))
    early = early_decisions(model, datasets[0.1])
    # far-first spikes are not in sensor time: no nanoseconds, network time only
    assert early["decision_time_ns_mean"] is None and early["last_input_ns_mean"] is None
    assert early["decision_time_mean"] is not None or early["no_decision"] == early["samples"]


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("direction", "sideways", "expected one of"),
        ("missing", "zero", "expected one of"),
        ("input_budget", 0, "expected a whole number >= 1"),
        ("input_budget", 2.5, "expected a whole number >= 1"),
    ],
)
def test_a_bad_recipe_value_is_one_line(key, value, expected):
    recipe = _tiny(**{key: value})
    with pytest.raises(ConfigError) as caught:
        build_model(recipe, (1, 16, 16), 32)
    message = str(caught.value)
    assert f"{key}={value!r}" in message and expected in message
    assert "\n" not in message


def test_the_authors_setting_spikes_missing_returns_at_zero_and_leaves_them_uncounted():
    # physical-style data: returns below 1.0, missing returns written as 1.0. Far first with
    # the farthest value puts the missing returns at t = 0 (z = 1): our count includes them,
    # the authors' does not.
    generator = torch.Generator().manual_seed(0)
    model = dense_snn((1, 4, 4), 3, generator, hidden=(8,), direction="far_first")
    model.missing = "farthest"
    model.double()
    delays = torch.full((1, 1, 4, 4), 1.0, dtype=torch.float64)
    delays[0, 0, 0, :3] = torch.tensor([0.2, 0.3, 0.4], dtype=torch.float64)
    z = model.input_spikes(delays)
    assert int((z == 1.0).sum()) == 13 and int(torch.isfinite(z).sum()) == 16
    for layer in model.layers:  # strong positive weights: the network decides at once
        layer.weight.data.fill_(0.5)
    (d,) = decide_all(model, z)
    assert d.label >= 0 and d.input_total == 16
    assert d.input_spikes - d.input_spikes_authors == 13  # every missing return, at t = 0
    zeros = (z.flatten() == 1.0).numpy()
    assert np.all(zeros[3:]) and not np.any(zeros[:3])


def test_the_input_budget_keeps_the_first_spikes_by_hand():
    inf = math.inf
    z = torch.tensor([[[3.0, 1.0, inf, 1.0, 2.0]], [[inf, 5.0, inf, inf, inf]]])
    kept = ttfs.first_spikes(z, 1)
    # row 0: the first spike's time is shared by two pixels, both pass; row 1 has one spike
    assert kept.tolist() == [[[inf, 1.0, inf, 1.0, inf]], [[inf, 5.0, inf, inf, inf]]]
    assert ttfs.first_spikes(z, 3).tolist() == [[[inf, 1.0, inf, 1.0, 2.0]], z[1].tolist()]
    assert torch.equal(ttfs.first_spikes(z, 99), z)  # a budget beyond the spikes: all pass


def test_a_network_behind_the_budget_never_consumes_more(datasets):
    from simlidar.bench.early import early_decisions

    result = train(_tiny(input_budget=20), datasets[0.1], seed=0, epochs=1, progress=False)
    assert result.recipe["architecture"]["input_budget"] == 20
    x, _ = load_split(datasets[0.1], "test")
    z = result.model.input_spikes(torch.from_numpy(x)[:, None])
    arrived = torch.isfinite(z).flatten(1).sum(1)
    assert (arrived >= 20).all() and (arrived <= 40).all()  # ties at the 20th may add a few
    early = early_decisions(result.model, datasets[0.1], per_sample=True)
    assert max(early["per_sample"]["input_spikes"]) <= arrived.max()
    assert early["input_spikes_total_mean"] == pytest.approx(arrived.double().mean().item())
    # what had arrived by each decision, let through or not: at least what was consumed, and
    # by decide_all's rule (every spike at or before the output spike) on the ungated spikes
    delays = torch.from_numpy(x.astype(np.float64))[:, None]  # as the evaluator reads them
    sent = result.model.arriving_spikes(delays)
    got = early["per_sample"]["input_spikes_arrived"]
    assert all(a >= c for a, c in zip(got, early["per_sample"]["input_spikes"]))
    assert early["input_spikes_arrived_mean"] == pytest.approx(np.mean(got))
    runs = decide_all(result.model, result.model.input_spikes(delays[:5]))
    assert got[:5] == [int((s <= d.z).sum()) for s, d in zip(sent.flatten(1)[:5], runs[:5])]
    ungated = train(_tiny(), datasets[0.1], seed=0, epochs=1, progress=False)
    assert "input_spikes_arrived_mean" not in early_decisions(ungated.model, datasets[0.1])


def test_behind_a_small_budget_the_first_dense_layer_can_fire():
    # 16 of 256 inputs arrive: weights started for all 256 would sum to about 3 * 16 / 256 and
    # never fire; started for the 16 that arrive, most first-layer neurons fire
    delays = torch.rand((64, 1, 16, 16), generator=torch.Generator().manual_seed(1)).double()
    for budget, firing in ((None, 0.9), (16, 0.5)):
        model = dense_snn((1, 16, 16), 4, torch.Generator().manual_seed(0), input_budget=budget)
        model.double()
        z = model.input_spikes(delays)
        assert budget is None or (torch.isfinite(z).flatten(1).sum(1) == budget).all()
        first = model.layers[0](z)
        assert torch.isfinite(first).double().mean() > firing, budget


def test_behind_a_budget_a_convolution_keeps_its_weights():
    # a patch arrives together (near returns first: the object and the road close by), so a
    # convolution starts as without a gate, and a neuron over the arrived patch fires
    from simlidar.models.networks import spiking_cnn

    def make(budget):
        return spiking_cnn((1, 16, 16), 4, torch.Generator().manual_seed(0), input_budget=budget)

    gated, free = make(25), make(None)
    for a, b in zip(gated.layers[:2], free.layers[:2]):
        assert torch.equal(a.weight, b.weight)
    delays = 0.5 + 0.5 * torch.rand((64, 1, 16, 16), generator=torch.Generator().manual_seed(1))
    delays[:, :, :5, :5] *= 0.1  # the 25 nearest returns: one 5 x 5 patch
    gated.double()
    z = gated.input_spikes(delays.double())
    assert (torch.isfinite(z[:, :, :5, :5]).flatten(1).sum(1) == 25).all()
    first = gated.layers[0](z)  # kernel 5, stride 2, padding 2: output (1, 1) sees rows 0-4
    assert torch.isfinite(first[:, :, 1, 1]).double().mean() > 0.5


def test_a_column_gate_lets_only_the_sweeps_first_firings_through():
    """``input_columns``: the spikes of the first columns (the sweep's first firings) and no
    other, in training's forward pass and the event-driven evaluation alike; the first dense
    layer starts for the inputs that arrive, and the gate is checked like the budget."""
    from simlidar.errors import ConfigError
    from simlidar.models.decisions import decide_all

    delays = torch.rand((8, 1, 16, 16), generator=torch.Generator().manual_seed(1)).double()
    model = dense_snn((1, 16, 16), 4, torch.Generator().manual_seed(0), input_columns=5)
    free = dense_snn((1, 16, 16), 4, torch.Generator().manual_seed(0))
    model.double(), free.double()
    z = model.input_spikes(delays)
    assert torch.isfinite(z[..., :5]).all() and torch.isinf(z[..., 5:]).all()
    assert torch.equal(z[..., :5], free.input_spikes(delays)[..., :5])
    assert torch.equal(model.arriving_spikes(delays), z)  # later columns come after a decision
    assert model.arriving_fraction((1, 16, 16)) == 5 / 16
    assert torch.isfinite(model.layers[0](z)).double().mean() > 0.5  # started for 80 inputs
    # the later columns cannot change the decision: the output is that of the first 5 alone
    changed = delays.clone()
    changed[..., 5:] = torch.rand((8, 1, 16, 11), generator=torch.Generator().manual_seed(2))
    assert torch.equal(model(delays), model(changed))
    runs = decide_all(model, model.input_spikes(delays))
    assert [d.input_total for d in runs] == [80] * 8
    both = dense_snn((1, 16, 16), 4, input_budget=16, input_columns=4)
    assert both.arriving_fraction((1, 16, 16)) == 16 / 256
    for bad in (0, 2.5, True, "3"):
        with pytest.raises(ConfigError, match=r"input_columns=.*: expected a whole number >= 1"):
            dense_snn((1, 16, 16), 4, input_columns=bad)
