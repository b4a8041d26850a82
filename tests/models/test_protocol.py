"""The model protocol (simlidar.models.protocol): encodings and readouts on hand-made spike
trains, declarations and a recipe's [spec] over them, bad declarations refused in one line."""

import pytest
import torch

from simlidar.errors import ConfigError
from simlidar.models.protocol import (
    ModelSpec,
    arrivals,
    class_scores,
    encode,
    readout,
    spec_of,
    tonic_events,
)

STEPPED = dict(output="stepped_spikes", encoding="latency", steps=4)


def _trains(*rows):
    """Output spikes (T, B, C) from per-sample lists of (step, neuron) spikes; T = 4, C = 3."""
    spikes = torch.zeros(4, len(rows), 3)
    for b, row in enumerate(rows):
        for step, neuron in row:
            spikes[step, b, neuron] = 1.0
    return spikes


def test_latency_encoding_by_hand():
    delays = torch.tensor([0.0, 0.24, 0.25, 0.5, 0.999, 1.0]).reshape(1, 1, 1, 6)
    spec = ModelSpec(**STEPPED)
    physical = encode(delays, spec, silent_from=1.0)  # a missing return (1.0) is no spike
    assert physical.shape == (4, 1, 1, 1, 6)
    steps = [int(physical[:, 0, 0, 0, i].argmax()) for i in range(5)]
    assert steps == [0, 0, 1, 2, 3]  # floor(delay * 4), the last step for 0.999
    assert physical.sum() == 5 and physical[:, 0, 0, 0, 5].sum() == 0
    paper = encode(delays, spec, silent_from=float("inf"))  # every pixel spikes
    assert paper.sum() == 6 and paper[3, 0, 0, 0, 5] == 1  # 1.0 on the last step
    assert encode(delays, ModelSpec(), 1.0) is delays  # "delays": the file's delays as they are


def test_events_encoding_by_hand():
    """The latency spikes as Tonic-ordered events: sorted by step, then pixel (row-major);
    a pixel that does not spike is a padding row of -1 at the end."""
    delays = torch.tensor([[0.6, 1.0, 0.1], [0.0, 0.3, 0.6]]).reshape(1, 1, 2, 3)
    spec = ModelSpec(output="stepped_spikes", encoding="events", steps=4)
    events = encode(delays, spec, silent_from=1.0)
    assert events.shape == (1, 6, 4) and events.dtype == delays.dtype
    assert events[0].tolist() == [
        [2, 0, 0, 0],  # x column, y row, t step, p
        [0, 1, 0, 0],  # same step 0: pixel 2 before pixel 3
        [1, 1, 1, 0],
        [0, 0, 2, 0],
        [2, 1, 2, 0],
        [-1, -1, -1, -1],  # the missing return (1.0) is no event
    ]
    (sample,) = tonic_events(events)
    assert sample.dtype.names == ("x", "y", "t", "p") and len(sample) == 5
    assert sample["t"].tolist() == [0, 0, 1, 2, 2] and not sample["p"].any()
    assert arrivals(delays, 4, 1.0)[:, 0].tolist() == [2, 3, 5, 5]


def test_events_are_the_latency_spikes_by_tonics_frames():
    """tonic's ToFrame with one-step bins over the T steps makes, of each sample's events, its
    latency encoding; the arrivals are its running sums."""
    T = pytest.importorskip("tonic.transforms")
    gen = torch.Generator().manual_seed(0)
    delays = torch.rand(5, 1, 4, 6, generator=gen) * 1.1  # some at or past the no-return 1.0
    for steps, silent_from in [(7, 1.0), (3, float("inf")), (1, 1.0)]:
        latency = encode(delays, ModelSpec(encoding="latency", steps=steps), silent_from)
        events = encode(delays, ModelSpec(encoding="events", steps=steps), silent_from)
        to_frame = T.ToFrame(
            sensor_size=(6, 4, 1),
            time_window=1,
            start_time=0,
            end_time=steps,
            include_incomplete=True,
        )
        for b, sample in enumerate(tonic_events(events)):
            frames = to_frame(sample)  # (T, 1 polarity, H, W)
            assert frames.shape == (steps, 1, 4, 6)
            assert torch.equal(torch.from_numpy(frames).float(), latency[:, b])
        counted = latency.reshape(steps, 5, -1).sum(2).cumsum(0)
        assert torch.equal(arrivals(delays, steps, silent_from), counted.long())


def test_a_stepped_output_needs_a_stepped_encoding():
    with pytest.raises(ConfigError, match=r"encoding='delays' with output 'stepped_spikes': exp"):
        ModelSpec(output="stepped_spikes")
    with pytest.raises(ConfigError, match=r"steps=0: expected at least 1 time step for the events"):
        ModelSpec(encoding="events")


def test_first_spike_readout_ties_go_to_the_membrane_then_the_lowest_index():
    spikes = _trains(
        [(2, 1), (3, 0)],  # neuron 1 first, at step 2
        [(1, 0), (1, 2)],  # a tie at step 1: membrane decides (neuron 2)
        [(0, 1), (0, 2)],  # a tie, equal membranes: the lower index (1)
        [],  # never spikes: no decision
    )
    membrane = torch.zeros(4, 4, 3)
    membrane[1, 1] = torch.tensor([1.2, 0.0, 1.5])
    membrane[0, 2] = torch.tensor([0.0, 1.1, 1.1])
    spec = ModelSpec(**STEPPED)  # readout first_spike by default
    label, step = readout((spikes, membrane), spec)
    assert label.tolist() == [1, 2, 1, -1] and step.tolist() == [2, 1, 0, -1]
    label, _ = readout(spikes, spec)  # without membrane: the lowest index at a tie
    assert label.tolist() == [1, 0, 1, -1]


def test_count_and_membrane_readouts_decide_at_the_last_step():
    spikes = _trains([(0, 0), (1, 2), (2, 2)], [(0, 0), (3, 1)], [])
    membrane = torch.zeros(4, 3, 3)
    membrane[-1] = torch.tensor([[0.0, 0.0, 0.1], [0.2, 0.9, 0.0], [0.3, 0.1, 0.7]])
    count = ModelSpec(**STEPPED, readout="spike_count")
    label, step = readout(spikes, count)
    assert label.tolist() == [2, 0, -1] and step.tolist() == [3, 3, -1]  # tie 0/1: lower index
    label, _ = readout((spikes, membrane), count)
    assert label.tolist() == [2, 1, 2]  # ties by the last membrane; silent: the membrane reads
    label, step = readout((spikes, membrane), ModelSpec(**STEPPED, readout="membrane"))
    assert label.tolist() == [2, 1, 2] and step.tolist() == [3, 3, 3]
    with pytest.raises(ConfigError, match="readout 'membrane': expected the model to return"):
        readout(spikes, ModelSpec(**STEPPED, readout="membrane"))
    assert torch.equal(class_scores(spikes, count), spikes.sum(0))


def test_a_declaration_and_a_recipes_spec_over_it():
    class Plain(torch.nn.Module):
        pass

    assert spec_of(Plain()) == ModelSpec()  # a plain module: logits of delay images
    model = Plain()
    model.simlidar_spec = ModelSpec(**STEPPED)
    over = spec_of(model, {"readout": "spike_count", "steps": 8})
    assert (over.output, over.steps, over.readout) == ("stepped_spikes", 8, "spike_count")
    for table, words in [
        ({"readout": "rate"}, r"\[spec\] readout='rate': expected one of"),
        ({"steps": 0}, r"\[spec\] steps=0: expected at least 1 time step"),
        ({"colour": "red"}, r"unknown key 'spec.colour'"),
    ]:
        with pytest.raises(ConfigError, match=words):
            spec_of(model, table, "recipe x")
    model.simlidar_spec = "stepped"
    with pytest.raises(ConfigError, match="simlidar_spec: expected a simlidar.models.protocol"):
        spec_of(model)


def test_a_latency_encoding_that_does_not_fit_is_refused_before_it_is_allocated(monkeypatch):
    """``[spec] steps = 100000`` (the largest allowed) made a (T, B, 1, H, W) tensor of
    gigabytes without a check; now a batch that cannot be held is one line."""
    import simlidar.resources
    from simlidar.errors import ResourceError

    monkeypatch.setattr(simlidar.resources, "available_memory", lambda: 64 * 2**20)
    spec = ModelSpec(output="stepped_spikes", encoding="latency", steps=100_000)
    delays = torch.rand(60, 1, 16, 16)
    with pytest.raises(ResourceError, match=r"\[spec\] steps = 100000: the latency encoding of a"):
        encode(delays, spec, 1.0)
    assert encode(delays[:1], ModelSpec(encoding="latency", steps=25), 1.0).shape[0] == 25
