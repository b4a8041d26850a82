"""The early-information estimate (``simlidar.bench.bound``) on toy datasets whose answer is
known.

Attack list:
* the view by hand: ties at the k-th spike's time arrive together, a pixel that never spikes
  never arrives, a k beyond a sample's spike count shows everything, the authors' count leaves
  out spikes at t = 0;
* a class written entirely in the earliest spike's position: the estimate must reach ~100 % at
  k = 1..4 (a learner too weak, or a view that hides what has arrived, fails here);
* a class written only in the last spikes: the estimate must stay at chance until they arrive
  (a view that leaked a later spike, its time or its mask, would beat chance) and reach ~100 %
  once every spike has arrived; the Bayes accuracy of both toys is known (100 % and 25 %), a
  bound no learner can beat there, and the estimate must reach it without passing it;
* the encoding's direction reverses the two toys: far first, the late toy is decided at k = 1.
"""

import math

import numpy as np
import pytest

from simlidar.bench.bound import (
    BoundConfig,
    arrived,
    bound,
    rounded_up_accuracy,
    spike_times,
    train_learner,
    with_families,
)

SMALL = BoundConfig(hidden=(64, 64), max_epochs=60, patience=10)
FAST = BoundConfig(hidden=(64, 64), max_epochs=30, patience=5)
CLASSES = 4


def _toy(n: int, seed: int, late: bool):
    """(delays (n, 8, 8), labels (n,)): 60 pixels U(0.2, 0.8) that say nothing; 4 pixels carry
    the class: early toy, pixels 0-3 come first and the class's pixel first of all; late toy,
    pixels 60-63 come last and the class's pixel last of all."""
    rng = np.random.default_rng(seed)
    y = rng.integers(0, CLASSES, n)
    d = rng.uniform(0.2, 0.8, (n, 64))
    rows = np.arange(n)
    if late:
        d[:, 60:] = rng.uniform(0.90, 0.92, (n, 4))
        d[rows, 60 + y] = rng.uniform(0.98, 1.0, n)
    else:
        d[:, :4] = rng.uniform(0.08, 0.10, (n, 4))
        d[rows, y] = rng.uniform(0.0, 0.02, n)
    return d.reshape(n, 8, 8).astype(np.float32), y


def test_the_view_by_hand():
    times = np.array([[0.3, 0.1, np.inf, 0.1], [0.0, 0.5, 0.2, np.inf]])
    view, got = arrived(times, 1)
    # row 0: the first spike's time 0.1 is shared by two pixels: both arrive
    assert view[0, 1].tolist() == [0, 1, 0, 1] and view[0, 0].tolist() == pytest.approx([0.1] * 4)
    assert view[1, 1].tolist() == [1, 0, 0, 0] and view[1, 0].tolist() == [0.0] * 4
    assert got.tolist() == [2, 1]
    view, got = arrived(times, None)  # each sample's own count: every spike, never the silent
    assert view[0, 1].tolist() == [1, 1, 0, 1] and view[1, 1].tolist() == [1, 1, 1, 0]
    assert view[0, 0].tolist() == pytest.approx([0.3, 0.1, 0.3, 0.1])
    assert got.tolist() == [3, 3]
    assert np.array_equal(arrived(times, 10)[0], arrived(times, None)[0])
    assert np.isfinite(view).all()
    # far first: a delay of 1.0 as the farthest value spikes at t = 0
    t = spike_times(np.array([[0.25, 1.0]]), 1.0, "far_first", "farthest")
    assert t[0].tolist() == pytest.approx([0.75, 0.0])
    assert spike_times(np.array([[0.25, 1.0]]), 1.0)[0, 1] == math.inf
    # a missing return's channel of its own is not a view: the view has an arrived channel
    with pytest.raises(ValueError, match="missing='own_channel': expected one pixel a spike"):
        spike_times(np.array([[0.25, 1.0]]), 1.0, "near_first", "own_channel")


def test_a_class_in_the_earliest_spike_is_known_at_once():
    result = bound(
        _toy(600, 0, late=False), _toy(200, 1, late=False), CLASSES, math.inf,
        ks=(1, 2, 4), seeds=(0,), config=SMALL,
    )  # fmt: skip
    for row in result["rows"]:
        assert row["accuracy_mean"] >= 0.95, row["k"]
    assert [row["input_spikes_median"] for row in result["rows"]] == [1, 2, 4, 64]
    assert result["rows"][0]["input_spikes_authors_mean"] == 1.0  # no spike at t = 0 here


def test_the_learner_standardises_pixel_by_pixel_unless_told_per_channel():
    """The estimate's standardisation (``pixel``) is the default, bit for bit; ``channel`` (one
    mean and deviation a channel: benchmark/ablation/cnn_learner_inputs.py) learns the early
    toy too, from another scaling; any other value is refused by name."""
    (d, y), (d_test, y_test) = _toy(400, 0, late=False), _toy(100, 1, late=False)
    x, x_test = (arrived(spike_times(a, math.inf), 1)[0] for a in (d, d_test))
    found = {}
    for form in (None, "pixel", "channel"):
        options = {} if form is None else {"standardise": form}
        scores, _ = train_learner(x, y, CLASSES, 0, FAST, **options)
        found[form] = scores(x_test)
    assert np.array_equal(found[None], found["pixel"])
    assert not np.array_equal(found["pixel"], found["channel"])
    assert (found["channel"].argmax(1) == y_test).mean() >= 0.95
    with pytest.raises(ValueError, match="standardise='pixels': expected 'pixel' or 'channel'"):
        train_learner(x, y, CLASSES, 0, FAST, standardise="pixels")


def test_a_class_in_the_last_spikes_is_at_chance_until_they_arrive():
    train, test = _toy(600, 0, late=True), _toy(200, 1, late=True)
    result = bound(train, test, CLASSES, math.inf, ks=(4, 32, 60), seeds=(0,), config=SMALL)
    *early, everything = result["rows"]
    for row in early:  # chance is 25 %; 200 test samples: a std of about 3 points
        assert row["accuracy_mean"] <= 0.40, row["k"]
    assert everything["k"] is None and everything["accuracy_mean"] >= 0.95
    # the other direction makes the last spikes the first ones
    far = bound(train, test, CLASSES, math.inf, "far_first", ks=(1,), seeds=(0,), config=SMALL)
    assert far["rows"][0]["accuracy_mean"] >= 0.95


def test_the_sensor_clock_by_hand():
    times = np.array([[0.3, 0.1, np.inf, 0.1]])
    emission = np.array([[0.25, 0.05, 0.0, 0.1]])
    view, got = arrived(times, 1, emission, scale=10.0)  # T = 0.1: pixels 1 and 3 arrive
    assert view[0, 1].tolist() == [0, 1, 0, 1] and got.tolist() == [2]
    # arrived: its time of flight; not yet: T minus its emission, at least 0 (pixel 0 has not
    # fired by T; pixel 2 never spikes but fired at 0: its range exceeds T)
    assert view[0, 0].tolist() == pytest.approx([0.0, 0.5, 1.0, 0.0])
    zeros = arrived(times, 1, np.zeros_like(times))[0]
    assert np.array_equal(zeros, arrived(times, 1)[0])  # flash: every emission is 0


def _scan_toy(n: int, seed: int):
    """A class written only in the time of flight of pixels 8-11 (1 of 4 farther), under an
    emission clock that grows with the column and jitters by sample, 1,000 times larger."""
    rng = np.random.default_rng(seed)
    y = rng.integers(0, CLASSES, n)
    tof = rng.uniform(0.2, 0.3, (n, 64))
    tof[np.arange(n), 8 + y] = rng.uniform(0.6, 0.7, n)
    emission = (np.arange(64) // 8) * 0.1 + rng.uniform(0, 0.05, (n, 1))
    return (emission + tof * 1e-3).astype(np.float32), y, emission


def test_the_sensor_clock_finds_a_class_written_in_the_time_of_flight():
    (*train, e_train), (*test, e_test) = _scan_toy(600, 0), _scan_toy(200, 1)
    result = bound(
        train, test, CLASSES, math.inf, ks=(), seeds=(0,), config=SMALL,
        emission=(e_train, e_test), scale=1e3,
    )  # fmt: skip
    assert result["rows"][0]["accuracy_mean"] >= 0.95
    with pytest.raises(ValueError, match="far_first"):
        bound(train, test, CLASSES, math.inf, "far_first", emission=(e_train, e_test))


def test_several_learners_give_the_best_of_their_seeds_and_ensembles():
    """Issue 42: a row's estimate is the best of every family's seed mean and seed ensemble."""
    learners = {"mlp": FAST, "wide": BoundConfig(hidden=(128, 128), max_epochs=30, patience=5)}
    train, test = _toy(400, 0, late=False), _toy(100, 1, late=False)
    result = bound(train, test, CLASSES, math.inf, ks=(1,), seeds=(0, 1), learners=learners)
    assert set(result["learner"]) == {"mlp", "wide"}
    for row in result["rows"]:
        found = row["learners"]
        candidates = {
            **{name: f["accuracy_mean"] for name, f in found.items()},
            **{f"{name}/ensemble": f["ensemble"] for name, f in found.items()},
        }
        assert row["accuracy_mean"] == max(candidates.values()) >= 0.95
        assert candidates[row["best"]] == row["accuracy_mean"]
        assert all(len(f["accuracy"]) == 2 and "scores" not in f["runs"][0] for f in found.values())
    first, every = result["rows"]
    best = [max(f["ensemble"] for f in row["learners"].values()) for row in (first, every)]
    assert rounded_up_accuracy(result, np.ones(100)) == best[0]  # k = 1 is measured
    assert rounded_up_accuracy(result, np.full(100, 2)) == best[1]  # beyond: every spike


def test_the_per_sample_form_knows_each_sample_at_its_own_count():
    """Early toy: the class is in each sample's first spike, so the learner trained at any k
    knows it once a few spikes have come; the late toy's class is in the last spike: at k = 4
    it is at chance. A network that decided each sample at its own count is compared with the
    matrix read there."""
    from simlidar.bench.bound import pack, per_sample, per_sample_accuracy, unpack

    early = per_sample(
        _toy(400, 0, False), _toy(100, 1, False), CLASSES, math.inf, seeds=(0,), config=FAST
    )
    late = per_sample(
        _toy(400, 0, True), _toy(100, 1, True), CLASSES, math.inf, seeds=(0,), config=FAST
    )
    assert early["k_max"] == 64 and early["samples"] == 100
    assert set(early["correct"]) == {"0", "ensemble"}
    for k in (4, 8):  # one learner for every k is weaker at the ends (k = 1: 59 %, 64: 84 %)
        assert per_sample_accuracy(early, np.full(100, k)) >= 0.95
    assert per_sample_accuracy(late, np.full(100, 4)) <= 0.45  # chance: 25 %, 100 samples
    mixed = np.where(np.arange(100) % 2 == 0, 64, 4)
    correct = unpack(late["correct"]["ensemble"], (64, 100))
    expected = (correct[63, ::2].sum() + correct[3, 1::2].sum()) / 100
    assert per_sample_accuracy(late, mixed) == pytest.approx(expected)
    assert per_sample_accuracy(late, np.zeros(100)) == per_sample_accuracy(late, np.ones(100))
    matrix = np.random.default_rng(0).random((5, 7)) > 0.5
    assert np.array_equal(unpack(pack(matrix), (5, 7)), matrix)


def _sweep_toy(n: int, seed: int):
    """A class written only in the time of flight of column 5 (of 8; the farther of its first
    four rows), under an emission clock that grows with the column (the last axis)."""
    rng = np.random.default_rng(seed)
    y = rng.integers(0, CLASSES, n)
    tof = rng.uniform(0.2, 0.3, (n, 8, 8))
    tof[np.arange(n), y, 5] = rng.uniform(0.6, 0.7, n)
    emission = np.arange(8) * 0.1 + rng.uniform(0, 0.05, (n, 1, 1)) + np.zeros((n, 8, 8))
    return (emission + tof * 1e-3).astype(np.float32), y, emission


def test_the_estimate_by_the_sweeps_first_columns_knows_what_they_hold():
    """The rows by columns (the sensor time a column-gated network decides at): at 5 columns
    the class has not been fired at (chance), at 6 it has come back; the k rows are as before."""
    (*train, e_train), (*test, e_test) = _sweep_toy(600, 0), _sweep_toy(200, 1)
    options = {"ks": (), "seeds": (0,), "config": SMALL, "emission": (e_train, e_test)}
    result = bound(train, test, CLASSES, math.inf, scale=1e3, columns=(5, 6), **options)
    five, six = result["column_rows"]
    assert (five["columns"], six["columns"]) == (5, 6)
    assert five["accuracy_mean"] < 0.5 and six["accuracy_mean"] >= 0.95
    assert five["input_spikes_median"] == 40 and six["input_spikes_median"] == 48
    # the moment: the last pulse of the first c columns, plus its listening window (1 / scale)
    ends = e_test[..., :6].max(axis=(1, 2)) + 1e-3
    assert six["until_median"] == pytest.approx(np.median(ends))
    assert [r["k"] for r in result["rows"]] == [None]
    assert "column_rows" not in bound(train, test, CLASSES, math.inf, scale=1e3, **options)
    with pytest.raises(ValueError, match="columns: expected scan-timed data"):
        bound(train, test, CLASSES, math.inf, ks=(), seeds=(0,), config=SMALL, columns=(5,))


CNN = BoundConfig(hidden=(64,), max_epochs=30, patience=5, model="cnn")


def test_a_family_added_later_gives_the_estimate_of_both_at_once():
    """The CNN family (the view as (2, H, W) images) learns the early toy; added to a run of
    the MLP (``with_families``, as ``benchmark/early_bound.py --learners mlp,wide,cnn`` adds
    it to a committed run), every row is the one a run of both families at once gives."""
    train, test = _toy(400, 0, late=False), _toy(100, 1, late=False)
    common = {"ks": (2,), "seeds": (0, 1)}
    alone = bound(train, test, CLASSES, math.inf, learners={"mlp": FAST}, **common)
    cnn = bound(train, test, CLASSES, math.inf, learners={"cnn": CNN}, **common)
    both = bound(train, test, CLASSES, math.inf, learners={"mlp": FAST, "cnn": CNN}, **common)
    merged = with_families(alone, cnn)
    assert merged == both
    assert set(merged["learner"]) == {"mlp", "cnn"} and merged["learner"]["cnn"]["model"] == "cnn"
    assert all(row["learners"]["cnn"]["accuracy_mean"] >= 0.9 for row in merged["rows"])
    with pytest.raises(ValueError, match="same seeds"):
        with_families(alone, bound(train, test, CLASSES, math.inf, learners={"cnn": CNN},
                                   ks=(2,), seeds=(0,)))  # fmt: skip
