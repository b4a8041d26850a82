"""The stream task with frame-based networks (issue 60, item 3): the rotation windows, the frame
clock by hand, the rows a network learns from, its answers at the frame ends, and the benchmark
script end to end."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from simlidar.bench.stream_task import (
    CUT_DEG,
    frame_answers,
    scored_windows,
    stream_views,
    training_windows,
)
from simlidar.bench.train import train
from simlidar.dataset.loaders import load_split
from simlidar.dataset.stream_loaders import load_stream
from simlidar.errors import ConfigError
from simlidar.models.registry import load_recipe

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def dataset(small_streams):
    return small_streams


@pytest.fixture(scope="module")
def views(dataset):
    return stream_views(dataset, "test")


def test_windows_are_the_rotations_side_by_side(dataset, views):
    delays, labels = load_split(dataset, "test")
    for r in range(10):
        assert (views.windows[:, r] == delays[:, :, 32 * r : 32 * (r + 1)]).all()
    assert (views.labels == labels).all() and views.classes == ("none", "car", "pedestrian",
                                                                "truck")  # fmt: skip


def test_frame_clock_by_hand(dataset, views):
    """Rotation r's frame ends when the head passes the rear: half a rotation (50 ms at 600
    RPM) after its window's middle, plus the time of flight at 100 m (0.667 us); the window's
    middle is halfway between its first firing (cycle k_r0) and its last (cycle k_r31, slot 15),
    each cycle the one nearest its column's centre (0.19906 deg apart, from the phase)."""
    phase = load_stream(dataset, "test").samples["phase"]
    step_deg = 360.0 / (60e6 / 600.0 / 55.296)
    centre = -18.0 + (np.arange(32) + 0.5) * 36.0 / 32
    assert CUT_DEG == 180.0
    for i, p in enumerate(phase):
        cycles = np.round((centre[None, :] + 360.0 * np.arange(10)[:, None]) / step_deg - p)
        first_us = (cycles[:, 0] - cycles[0, 0]) * 55.296
        last_us = (cycles[:, -1] - cycles[0, 0]) * 55.296 + 15 * 2.304
        expected = (first_us + last_us) / 2 + 50_000.0 + 2 * 100.0 / 299_792_458.0 * 1e6
        assert np.allclose(views.frame_end_us[i], expected, rtol=0, atol=1e-6)
        # the window clock: its last firing plus the time of flight at 100 m
        window_end = last_us + 2 * 100.0 / 299_792_458.0 * 1e6
        assert np.allclose(views.window_end_us[i], window_end, rtol=0, atol=1e-6)


def test_first_rotation_holds_the_reference(views):
    """Each stream's first window is the one its reference time falls in: the reference is a
    return (the object's first, or one drawn for none), an event of that window."""
    ends = views.window_start_us + views.unit_us  # a bound on every arrival of a window
    for i, r in enumerate(views.first_rotation):
        assert 1 <= r <= 9
        assert views.window_start_us[i, r] <= views.reference_us[i] < ends[i, r]


def test_training_rows_hold_out_whole_streams(views):
    classes = list(views.classes)
    rows = training_windows(views, seed=0, validation=0.25, classes=classes)
    per_stream = 10 - views.first_rotation
    held = np.setdiff1d(np.arange(len(views.labels)), rows.trained)
    assert len(rows.y_train) == per_stream[rows.trained].sum()
    assert len(rows.y_val) == per_stream[held].sum() > 0
    assert rows.x_train.shape[1:] == (1, 16, 32)
    x, y = scored_windows(views)
    assert len(y) == per_stream.sum()


class _Fixed(torch.nn.Module):
    """A window model whose class is its input's first column's count of returns, mod 4."""

    def forward(self, x):
        returns = (x[:, 0, :, 0] < 1.0).sum(dim=1)
        return torch.nn.functional.one_hot(returns % 4, 4).float()


def test_a_frame_networks_answers_come_at_its_frame_ends(views):
    """The frame-based baseline's latency is its frame clock by construction: an answer at
    each rotation's frame end, its class the network's for that rotation's window."""
    answers = frame_answers(_Fixed(), views)
    assert (answers.times_us == views.frame_end_us).all()
    expected = _Fixed()(torch.from_numpy(views.windows[3, 7][None, None])).argmax(1).item()
    assert answers.classes[3, 7] == expected
    sector = frame_answers(_Fixed(), views, clock="window")  # the same answers, sooner
    assert (sector.times_us == views.window_end_us).all()
    assert np.array_equal(sector.classes, answers.classes)
    assert (views.window_end_us < views.frame_end_us - 40_000.0).all()
    with pytest.raises(ConfigError, match="clock='rear': expected one of"):
        frame_answers(_Fixed(), views, clock="rear")


def test_train_refuses_noise_augmentation_on_given_rows(dataset, views):
    recipe = load_recipe("mlp")
    recipe["training"] |= {"noise_augment": True, "epochs": 1}
    rows = training_windows(views, 0, 0.0, list(views.classes))
    with pytest.raises(ConfigError, match="noise_augment"):
        train(recipe, dataset, rows=rows, test=scored_windows(views), progress=False)


def test_the_benchmark_script_end_to_end(dataset, tmp_path):
    """Two cells, then the same command again: nothing trained anew (resumable), the report and
    the picture written."""
    out = tmp_path / "bench"
    command = [sys.executable, str(ROOT / "benchmark/stream_bench.py"), str(dataset), "--out",
               str(out), "--models", "mlp", "--seeds", "0,1", "--epochs", "1"]  # fmt: skip
    first = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    cells = [json.loads(line) for line in (out / "cells.jsonl").read_text().splitlines()]
    assert [(c["model"], c["seed"]) for c in cells] == [("mlp", 0), ("mlp", 1)]
    for c in cells:
        after = c["accuracy_after"]
        assert len(after["accuracy"]) == 8 and 0.0 <= after["end_accuracy"] <= 1.0
        assert c["first_answer_after_reference_ms"]["min"] >= 0.0
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "seed" not in again.stdout.replace("--seeds", "")
    assert len((out / "cells.jsonl").read_text().splitlines()) == 2
    assert "| mlp | 2 |" in (out / "report.md").read_text()
    assert (out / "accuracy-latency.png").stat().st_size > 0


def test_the_benchmark_script_refuses_a_window_dataset(datasets, tmp_path):
    command = [sys.executable, str(ROOT / "benchmark/stream_bench.py"), str(datasets[0.1]),
               "--out", str(tmp_path / "b"), "--models", "mlp", "--seeds", "0"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 1
    assert "expected a stream split" in done.stderr and "Traceback" not in done.stderr


def test_arrival_coding_by_hand(dataset):
    """An arrival-coded window holds each event's arrival from its window's first firing over
    the scan window (turn of 36 x 31 / 32 deg at 600 RPM plus two cycles plus the time of
    flight at 100 m: 9,409.4 us)."""
    views = stream_views(dataset, "test", coding="arrival")
    stream = load_stream(dataset, "test")
    unit_us = 36.0 * 31 / 32 / 360.0 * 100_000.0 + 2 * 55.296 + 2 * 100.0 / 299_792_458.0 * 1e6
    assert views.unit_us == pytest.approx(unit_us, rel=1e-12)
    events, i = stream.events, 5
    rows = events.rows(i)
    t, x, y = events.t_us[rows], events.x[rows], events.y[rows]
    rotation = np.round(t / 100_000.0).astype(int)
    got = views.windows[i, rotation, y, x]
    expected = (t - views.window_start_us[i, rotation]) / unit_us
    assert np.allclose(got, expected, rtol=1e-6) and (0 < got).all() and (got < 1).all()
    assert (views.windows[i] < 1.0).sum() == len(t)
    with pytest.raises(ConfigError, match="coding='flash'"):
        stream_views(dataset, "test", coding="flash")


def test_an_event_driven_network_answers_after_what_it_consumed(dataset):
    """A spiking network's answer in a window comes at its first output spike, at or after
    every input spike delivered before it (the event-driven run's rule): each answer's time is
    at least its window's first firing plus the k-th earliest arrival of the window, k the
    input spikes it consumed."""
    from simlidar.bench.stream_task import decision_answers
    from simlidar.models.decisions import decide_all

    views = stream_views(dataset, "test", coding="arrival")
    recipe = load_recipe("snn_simlidar_tuned")
    recipe["training"] |= {"noise_augment": False, "epochs": 2, "validation": 0.0}
    rows = training_windows(stream_views(dataset, "train", coding="arrival"), 0, 0.0,
                            list(views.classes))  # fmt: skip
    model = train(recipe, dataset, rows=rows, test=scored_windows(views), progress=False).model
    answers = decision_answers(model, views)
    n = len(views.labels)
    x = torch.from_numpy(views.windows.reshape(n * 10, 1, 16, 32)).double()
    runs = decide_all(model, model.input_spikes(x))
    arrivals = np.sort(views.windows.reshape(n, 10, -1), axis=2)
    checked = 0
    for i in range(n):
        decided = [r for r in range(10) if runs[i * 10 + r].label >= 0]
        times = answers.times_us[i][: len(decided)]
        assert np.isnan(answers.times_us[i][len(decided) :]).all()
        assert (
            answers.classes[i][: len(decided)] == [runs[i * 10 + r].label for r in decided]
        ).all()
        for t, r in zip(times, decided):
            k = runs[i * 10 + r].input_spikes
            if k:
                consumed = views.window_start_us[i, r] + arrivals[i, r, k - 1] * views.unit_us
                assert t >= consumed - 1e-6
                checked += 1
            assert t >= views.window_start_us[i, r]  # no answer before its window fires
    assert checked > 0
    with pytest.raises(ConfigError, match="arrival-coded"):
        decision_answers(model, stream_views(dataset, "test"))
