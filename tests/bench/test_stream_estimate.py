"""The early-information estimate in the stream (issue 60, item 4): what the sensor knows at a
time, by hand, the training times drawn independently of the class, and the script end to
end (resumable, its summary)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from simlidar.bench.stream_estimate import OFFSETS_MS, any_time, family_parts, known, view_at
from simlidar.dataset.stream_loaders import load_stream
from simlidar.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def dataset(small_streams):
    return small_streams


def test_the_view_is_what_has_arrived(dataset):
    """At T = reference + d a pulse of the latest windows shows its time of flight once its
    emission plus flight is at or before T, and has fired once its emission is; an object's
    first return has arrived at its reference (d = 0); the two views hold every window begun."""
    data = known(dataset, "test")
    stream = load_stream(dataset, "test")
    view = view_at(data, 0.0, 10).reshape(len(data.labels), 2, 16, -1)
    for i in range(len(data.labels)):
        t = stream.events.t_us[stream.events.rows(i)]
        begun = int((data.emission_us[i].reshape(16, 10, 32) <= data.reference_us[i]).any(
            axis=(0, 2)).sum())  # fmt: skip
        windows = view[i][:, :, (10 - begun) * 32 :]  # the begun ones, in order
        assert (windows[0] < 1.0).sum() == (t <= data.reference_us[i]).sum() >= 1
        fired = windows[1].astype(bool)
        emitted = data.emission_us[i][:, : begun * 32]
        assert (emitted[fired] <= data.reference_us[i]).all()
        assert (emitted[~fired] > data.reference_us[i]).all()
    early, later = view_at(data, 0.0, 1), view_at(data, 5.0, 1)
    assert (later[:, 0] <= early[:, 0]).all() and (later[:, 1] >= early[:, 1]).all()


def test_the_latest_windows_view(dataset):
    """A -lastK view holds the K latest windows begun by T, the current one last, a window
    before the first being nothing (no return, not fired): each window by hand from the
    pulses' times."""
    data = known(dataset, "test")
    n = len(data.labels)
    for delay in (-95.0, 0.0, 5.0, 60.0):
        last = view_at(data, delay, 2).reshape(n, 2, 16, 2, 32)
        for i in range(n):
            at = data.reference_us[i] + delay * 1000.0
            emitted = data.emission_us[i].reshape(16, 10, 32) <= at
            tof = np.where(data.arrival_us[i] <= at, data.delays[i], 1.0).reshape(16, 10, 32)
            begun = int(emitted.any(axis=(0, 2)).sum())
            for k, window in ((1, begun - 1), (0, begun - 2)):
                if window >= 0:
                    assert (last[i, 0, :, k] == tof[:, window]).all()
                    assert (last[i, 1, :, k] == emitted[:, window]).all()
                else:
                    assert (last[i, 0, :, k] == 1.0).all() and (last[i, 1, :, k] == 0).all()
    assert family_parts("cnn-last2") == ("cnn", 2)
    assert family_parts("mlp-latest") == ("mlp", "latest")
    with pytest.raises(ConfigError, match="expected mlp-latest, cnn-latest, mlp-lastK or cnn"):
        family_parts("mlp")  # every window so far tells the time since the stream began


def test_the_latest_complete_window_has_one_place(dataset):
    """A -latest view holds the latest complete window (every pulse fired) first and the one
    firing, if any, second (nothing where none): by hand from the pulses' emissions."""
    data = known(dataset, "test")
    n = len(data.labels)
    for delay in (-95.0, 0.0, 5.0, 60.0, 100.0):
        got = view_at(data, delay, "latest").reshape(n, 2, 16, 2, 32)
        for i in range(n):
            at = data.reference_us[i] + delay * 1000.0
            emitted = data.emission_us[i].reshape(16, 10, 32) <= at
            tof = np.where(data.arrival_us[i] <= at, data.delays[i], 1.0).reshape(16, 10, 32)
            complete = [w for w in range(10) if emitted[:, w].all()]
            firing = [w for w in range(10) if emitted[:, w].any() and not emitted[:, w].all()]
            assert len(firing) <= 1 and complete == list(range(len(complete)))
            for k, chosen in ((0, complete[-1:]), (1, firing)):
                if chosen:
                    assert (got[i, 0, :, k] == tof[:, chosen[0]]).all()
                    assert (got[i, 1, :, k] == emitted[:, chosen[0]]).all()
                else:
                    assert (got[i, 0, :, k] == 1.0).all() and (got[i, 1, :, k] == 0).all()
    with pytest.raises(ConfigError, match="view='last': expected a number of windows"):
        view_at(data, 0.0, "last")


def test_training_times_do_not_depend_on_the_class(dataset):
    """Each epoch's view sees every stream at its reference plus an offset uniform in
    OFFSETS_MS, drawn alike for every class (one generator, one draw a stream)."""
    data = known(dataset, "train")
    draw = any_time(data, np.random.default_rng(0), 2)
    rng = np.random.default_rng(0)
    offsets = rng.uniform(*OFFSETS_MS, size=len(data.labels))
    assert (draw() == view_at(data, offsets, 2)).all()
    assert OFFSETS_MS[0] <= -100.0 and OFFSETS_MS[1] >= 100.0


def test_the_script_end_to_end(dataset, tmp_path):
    out = tmp_path / "est"
    command = [sys.executable, str(ROOT / "benchmark/stream_estimate.py"), str(dataset),
               "--out", str(out), "--families", "mlp-last2", "--seeds", "0"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (fit,) = [json.loads(line) for line in (out / "estimate-fits.jsonl").read_text().splitlines()]
    assert fit["family"] == "mlp-last2" and len(fit["accuracy"]) == 8
    summary = json.loads((out / "estimate.json").read_text())
    assert summary["delays"]["10"]["estimate"] == fit["accuracy"][4]
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "seed 0:" not in again.stdout
    bad = subprocess.run(command[:-4] + ["--families", "svm"], capture_output=True, text=True)
    assert bad.returncode == 2 and "'svm': expected" in bad.stderr
