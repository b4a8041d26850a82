"""The model protocol (simlidar.models.protocol): encodings and readouts on hand-made spike
trains, declarations and a recipe's [spec] over them, bad declarations refused in one line."""

import pytest
import torch

from simlidar.errors import ConfigError
from simlidar.models.protocol import ModelSpec, class_scores, encode, readout, spec_of

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
