"""Stream networks (issue 60, item 3): the inputs by hand, answers never before the events they
were made from, crops that keep the reference's place from the class, determinism, the
recipes' [stream] table, and the benchmark script with the shipped and an outside (snnTorch)
stream network."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from simlidar.bench import stream_sequences as ss
from simlidar.bench.stream_task import stream_views
from simlidar.dataset.loaders import load_split
from simlidar.dataset.stream_loaders import load_stream
from simlidar.errors import ConfigError
from simlidar.models.registry import build_model, load_recipe
from simlidar.models.stream_nets import scores_of
from simlidar.models.stream_spec import StreamSpec, stream_spec_of

ROOT = Path(__file__).resolve().parents[2]
BINS = StreamSpec("bins", 1.0)


@pytest.fixture(scope="module")
def dataset(small_streams):
    return small_streams


@pytest.fixture(scope="module")
def bins(dataset):
    return ss.sequences(dataset, "test", BINS)


def test_bins_by_hand(dataset, bins):
    """Every event in the bin of its arrival, at its pixel, counted once, with its nearness
    1 - its stored delay; nothing else in the input."""
    stream = load_stream(dataset, "test")
    delays, _ = load_split(dataset, "test")
    config_width = delays.shape[2] // 10
    n = len(bins.labels)
    x = ss.Sequences.batch(bins, np.arange(n), np.zeros(n, np.int64), bins.steps).numpy()
    assert x.shape == (bins.steps, n, 2, 16, config_width)
    assert x[:, :, 0].sum() == len(stream.events.t_us)
    for i in (0, n - 1):
        rows = stream.events.rows(i)
        t = stream.events.t_us[rows]
        step = np.floor(t / 1000.0).astype(int)
        y, col = stream.events.y[rows], stream.events.x[rows]
        assert (x[step, i, 0, y, col] == 1.0).all()
        rotation = np.round(t / 100_000.0).astype(int)
        near = 1.0 - delays[i, y, rotation * config_width + col]
        assert np.array_equal(x[step, i, 1, y, col], near)
        assert (bins.step_end_us[i, step] >= t).all()  # answered at or after its arrival
        assert (bins.step_end_us[i, step] - 1000.0 <= t).all()  # in the bin of its arrival
    assert bins.steps == int(np.ceil((bins.span_us + 0.667) / 1000.0))


def test_rotations_are_the_windows_with_the_frame_clock(dataset):
    views = stream_views(dataset, "test")
    rotations = ss.sequences(dataset, "test", StreamSpec("rotations"))
    n = len(views.labels)
    x = rotations.batch(np.arange(n), np.zeros(n, np.int64), 10).numpy()[:, :, 0]
    assert np.array_equal(x.transpose(1, 0, 2, 3), views.windows)
    assert np.array_equal(rotations.step_end_us, views.frame_end_us)
    assert np.array_equal(rotations.reference_step, views.first_rotation)
    late = rotations.batch(np.arange(2), np.array([8, 9]), 3).numpy()
    assert (late[2] == 1.0).all() and (late[1, 1] == 1.0).all()  # past the end: no return


@pytest.mark.parametrize("name", ["lif_stream", "gru_rotations"])
def test_an_answer_depends_on_nothing_after_it(dataset, name):
    """Causality: changing the input from step k on leaves every score before k as it was, so
    a step's answer, made at its end, is made from the events arrived by then."""
    recipe = load_recipe(name)
    spec = ss.check_recipe(recipe)
    data = ss.sequences(dataset, "test", spec)
    model = build_model(recipe, (spec.channels, 16, 32), 4, torch.Generator().manual_seed(0))
    steps = 60 if spec.input == "bins" else 10
    x = data.batch(np.arange(3), np.zeros(3, np.int64), steps)
    k = steps // 2
    changed = x.clone()
    changed[k:] = torch.rand_like(changed[k:])
    with torch.no_grad():
        before, after = scores_of(model(x)), scores_of(model(changed))
    assert torch.equal(before[:k], after[:k])
    assert not torch.equal(before[k:], after[k:])


def test_crops_put_the_reference_at_the_same_places_for_every_class(dataset):
    train = ss.sequences(dataset, "train", BINS)
    rng = np.random.default_rng(0)
    streams = np.arange(len(train.labels))
    first, length, mask = ss.crops(train, np.repeat(streams, 50), rng)
    u = train.reference_step[np.repeat(streams, 50)] - first
    before = min(100, train.reference_step.min())
    assert u.min() == 0 and u.max() == before and length == before + 150
    for label in np.unique(train.labels):  # the reference's place does not tell the class
        mine = u[np.repeat(train.labels, 50) == label]
        assert mine.min() <= 10 and mine.max() >= before - 10
    mask = mask.numpy()
    assert np.array_equal(mask.argmax(axis=0), u)  # the loss from the reference's step on


def test_fit_is_deterministic_and_answers_follow_the_scores(dataset, bins):
    recipe = load_recipe("gru_rotations")
    train = ss.sequences(dataset, "train", StreamSpec("rotations"))
    one = ss.fit(recipe, train, seed=3, epochs=2, validation=0.25)
    two = ss.fit(recipe, train, seed=3, epochs=2, validation=0.25)
    for a, b in zip(one.model.state_dict().values(), two.model.state_dict().values()):
        assert torch.equal(a, b)
    assert one.epochs == 2 and len(one.validation) == 2 and len(one.trained) == 12
    test = ss.sequences(dataset, "test", StreamSpec("rotations"))
    answers = ss.sequence_answers(one.model, test)
    with torch.no_grad():
        scores = scores_of(one.model(test.batch(np.arange(8), np.zeros(8, np.int64), 10)))
    expected = scores.argmax(-1).numpy().T
    assert np.array_equal(answers.classes, expected)
    assert np.array_equal(answers.times_us, test.step_end_us)


def test_stream_tables_are_checked(tmp_path):
    assert stream_spec_of({"name": "x"}) is None
    for table, words in (
        ({"input": "frames"}, "[stream] input='frames': expected one of ['rotations', 'bins']"),
        ({"bin_ms": 0.0}, "[stream] bin_ms=0.0: expected a number in [0.05, 10.0]"),
        ({"bin_ms": True}, "bin_ms=True"),
        ({"bins": 1}, "recipe x: unknown key 'stream.bins'"),
    ):
        with pytest.raises(ConfigError, match=re.escape(words)):
            stream_spec_of({"name": "x", "stream": table})
    bad = tmp_path / "bad.toml"
    bad.write_text(
        'model = "lif_stream"\n[stream]\ninput = "bins"\nbin_ms = 50\n'
        "[training]\nlr = 0.01\nbatch_size = 4\nepochs = 1\n"
    )
    with pytest.raises(ConfigError, match=r"bad.toml: \[stream\] bin_ms=50"):
        load_recipe(bad)
    with pytest.raises(ConfigError, match="no \\[stream\\] table; expected a stream network"):
        ss.check_recipe(load_recipe("cnn"))
    with pytest.raises(ConfigError, match="gain=0: expected a number in"):
        build_model(dict(load_recipe("lif_stream"), architecture={"gain": 0}), (2, 16, 32), 4)


def _bench(dataset, out, *models, extra=()):
    command = [
        sys.executable,
        str(ROOT / "benchmark/stream_bench.py"),
        str(dataset),
        "--out",
        str(out),
        "--models",
        ",".join(models),
        "--seeds",
        "0",
        "--epochs",
        "1",
        "--validation",
        "0.25",
        *extra,
    ]
    return subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=ROOT)


def test_the_benchmark_script_with_stream_networks(dataset, tmp_path):
    """The shipped GRU and LIF networks and snnTorch's through the same script and cells."""
    done = _bench(
        dataset, tmp_path / "b", "gru_rotations", "lif_stream", "examples/snntorch_stream.toml"
    )
    assert done.returncode == 0, done.stderr
    cells = [json.loads(line) for line in (tmp_path / "b/cells.jsonl").read_text().splitlines()]
    assert [c["model"] for c in cells] == ["gru_rotations", "lif_stream", "snntorch_stream"]
    assert [c["coding"] for c in cells] == ["rotations", "bins", "bins"]
    for c in cells:
        assert c["mode"] == "sequence" and len(c["accuracy_after"]["accuracy"]) == 8
        assert c["streams_trained"] == 12 and c["streams_validated"] == 4
    # a rotation network answers at its frame ends, a bins network at its bins' ends
    assert cells[0]["first_answer_after_reference_ms"]["median"] > 40.0
    assert cells[1]["first_answer_after_reference_ms"]["max"] <= 1.0
    report = (tmp_path / "b/report.md").read_text()
    assert "| lif_stream | 1 |" in report and "| snntorch_stream | 1 |" in report


def test_a_stream_network_is_not_an_event_model(dataset, tmp_path):
    done = _bench(dataset, tmp_path / "b", "", extra=("--event-models", "lif_stream"))
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert "--event-models lif_stream: a stream network's recipe; expected a window model" in (
        done.stderr
    )
