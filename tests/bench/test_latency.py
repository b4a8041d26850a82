"""The stream task's latency metrics against numbers derived by hand.

The clock of every example: a VLP-16 at 600 RPM, 100 ms rotations, times on the sensor's clock
in microseconds from the stream's first firing; delays in milliseconds after the reference.
"""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simlidar.bench.latency import (
    DELAYS_MS,
    Answers,
    accuracy_after,
    area_under_curve,
    decision_latency,
    frame_ends_us,
    mean_interval,
)
from simlidar.errors import ConfigError

MS = 1000.0  # us


def _padded(rows: list[list[tuple[float, int]]]) -> Answers:
    """Answers from each sample's (time_us, class) list, padded with NaN and -1."""
    k = max((len(r) for r in rows), default=0)
    times = np.full((len(rows), k), np.nan)
    classes = np.full((len(rows), k), -1)
    for i, row in enumerate(rows):
        for j, (t, c) in enumerate(row):
            times[i, j], classes[i, j] = t, c
    return Answers(times, classes)


@pytest.fixture
def frames() -> tuple[Answers, np.ndarray, np.ndarray]:
    """A frame network answering at 100, 200 and 300 ms. Sample 0 (class 2) is visible at 150 ms:
    a background guess (class 0) at 100 ms, right from 200 ms. Sample 1 (class 1) is visible at
    20 ms and right from the first frame's end, 100 ms."""
    ends = frame_ends_us(3, 100 * MS, 99_999.0, 1.0)  # 100, 200, 300 ms
    answers = Answers.from_frames(ends, [[0, 2, 2], [1, 1, 1]], n_classes=3)
    return answers, np.array([2, 1]), np.array([150 * MS, 20 * MS])


def test_a_frame_answer_is_in_force_from_its_own_time(frames):
    answers, labels, ref = frames
    # sample 0: its 200 ms answer comes 50 ms after its reference; at 49.5 ms the 100 ms guess
    # is in force; sample 1: nothing before 100 ms (no answer: wrong), right at 80 ms exactly
    result = accuracy_after(answers, labels, ref, delays_ms=(10, 49.5, 50, 80))
    assert result.accuracy == (0.0, 0.0, 0.5, 1.0)
    assert result.counts == (2, 2, 2, 2)
    assert math.isnan(result.end_accuracy)
    np.testing.assert_array_equal(answers.at(ref + 10 * MS), [0, -1])
    np.testing.assert_array_equal(answers.at(np.array([200 * MS, 99_999.999])), [2, -1])


def test_the_first_answer_latency_counts_guesses_before_the_reference(frames):
    answers, labels, ref = frames
    result = decision_latency(answers, labels, ref)
    np.testing.assert_array_equal(result.latency_ms, [-50.0, 80.0])  # 100 - 150, 100 - 20
    assert (result.answered, result.before_reference, result.first_accuracy) == (2, 1, 0.5)
    # numpy's linear quantiles of (-50, 80): -50 + q * 130
    assert result.median_ms == pytest.approx(15.0)
    assert (result.q05_ms, result.q95_ms) == pytest.approx((-43.5, 73.5))
    shares = result.to_dict()
    assert (shares["share_before"], shares["share_at_or_after"], shares["share_never"]) == (
        0.5,
        0.5,
        0.0,
    )


def test_the_area_of_the_frame_network_by_hand(frames):
    answers, labels, ref = frames
    # sample 0: right over [200, 250] of [150, 250] ms: 0.5; sample 1: [100, 120] of [20, 120]: 0.2
    result = area_under_curve(answers, labels, ref, horizon_ms=100.0)
    assert result.area == pytest.approx(0.35)
    assert (result.counted, result.samples) == (2, 2)


def test_from_frames_answers_on_the_frame_clock():
    ends = frame_ends_us(10, 100 * MS, 99_954.432, 0.667128)
    classes = np.random.default_rng(0).integers(0, 4, (5, 10))
    answers = Answers.from_frames(ends, classes)
    np.testing.assert_array_equal(answers.times_us, np.broadcast_to(ends, (5, 10)))
    ref = np.zeros(5)
    latency = decision_latency(answers, classes[:, 0], ref).latency_ms
    np.testing.assert_array_equal(latency, np.full(5, ends[0] / MS))
    # per-sample frame ends (a crop whose window ends later for sample 1)
    per_sample = np.stack([ends, ends + 500.0])
    answers = Answers.from_frames(per_sample, classes[:2])
    np.testing.assert_array_equal(answers.times_us, per_sample)


def test_a_frame_without_answer_leaves_the_one_before_in_force():
    answers = Answers.from_frames([100 * MS, 200 * MS, 300 * MS], [[-1, 3, -1], [2, -1, 1]])
    expected = [[200 * MS, np.nan, np.nan], [100 * MS, 300 * MS, np.nan]]
    np.testing.assert_array_equal(answers.times_us, expected)
    np.testing.assert_array_equal(answers.at(np.full(2, 250 * MS)), [3, 2])
    np.testing.assert_array_equal(answers.at(np.full(2, 150 * MS)), [-1, 2])


def test_frame_ends_of_a_vlp16_at_600_rpm():
    # 1808 firing cycles of 55.296 us fit in 100 ms: the last begins at 1807 x 55.296 =
    # 99,919.872 us and its 16th laser fires 15 x 2.304 us later, at 99,954.432 us; a return
    # from 100 m takes 2 x 100 m / c = 0.667128 us
    ends = frame_ends_us(10, 100_000.0, 1807 * 55.296 + 15 * 2.304, 200 / 299_792_458 * 1e6)
    assert ends.shape == (10,) and ends.dtype == np.float64
    assert ends[0] == pytest.approx(99_955.099128, abs=1e-6)
    assert ends[9] == pytest.approx(999_955.099128, abs=1e-6)


def test_area_by_hand_for_one_decision():
    # right from 20 ms of a 100 ms horizon: 0.8; wrong from 20 ms: 0; never: 0
    answers = Answers.from_decisions([20 * MS, 20 * MS, np.nan], [1, 0, -1])
    result = area_under_curve(answers, [1, 1, 1], np.zeros(3), horizon_ms=100.0)
    assert result.area == pytest.approx(0.8 / 3)
    single = Answers.from_decisions([520 * MS], [4])
    assert area_under_curve(single, [4], [500 * MS]).area == pytest.approx(0.8)


def test_area_of_an_answer_that_changes_its_mind():
    # right over [10, 30] ms, then wrong: 20 of 100 ms; answered before the reference: counts
    # only from the reference on (right over [0, 10] of a sample answering at -5 ms)
    answers = _padded([[(10 * MS, 1), (30 * MS, 0)], [(-5 * MS, 1), (10 * MS, 2)]])
    result = area_under_curve(answers, [1, 1], [0.0, 0.0], horizon_ms=100.0)
    assert result.area == pytest.approx((0.2 + 0.1) / 2)


def test_delays_past_the_span_are_left_out_and_counted():
    # a 1 s stream; sample A (ref 950 ms) is right from 955 ms; sample B never answers.
    # A's 100 ms delay lands at 1050 ms: left out, not scored with its answer at the end
    answers = Answers.from_decisions([955 * MS, np.inf], [1, -1])
    labels, ref, span = [1, 0], [950 * MS, 100 * MS], 1000 * MS
    result = accuracy_after(answers, labels, ref, delays_ms=(10, 50, 100), span_us=span)
    assert result.counts == (2, 2, 1)  # 950 + 50 = 1000 ms is at the span's end: counted
    assert result.accuracy == (0.5, 0.5, 0.0)
    assert result.end_accuracy == 0.5
    area = area_under_curve(answers, labels, ref, horizon_ms=100.0, span_us=span)
    assert (area.area, area.counted, area.samples) == (0.0, 1, 2)
    area = area_under_curve(answers, labels, ref, horizon_ms=50.0, span_us=span)
    assert area.area == pytest.approx((45 / 50 + 0.0) / 2) and area.counted == 2
    nothing = accuracy_after(answers, labels, ref, delays_ms=(2000,), span_us=span)
    assert nothing.counts == (0,) and math.isnan(nothing.accuracy[0])
    assert json.loads(json.dumps(nothing.to_dict(), allow_nan=False))["accuracy"] == [None]


def test_results_go_to_json():
    answers = Answers.from_decisions([1 * MS, 3 * MS], [0, 1])
    after = accuracy_after(answers, [0, 0], [0.0, 0.0], span_us=200 * MS).to_dict()
    assert after["delays_ms"] == list(map(float, DELAYS_MS))
    assert after["accuracy"] == [0.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
    assert after["counts"] == [2] * 8 and after["end_accuracy"] == 0.5
    latency = decision_latency(answers, [0, 0], [0.0, 0.0]).to_dict()
    assert "latency_ms" not in latency and latency["median_ms"] == 2.0
    area = area_under_curve(answers, [0, 0], [0.0, 0.0]).to_dict()
    # sample 0 right over [1, 100] ms of [0, 100]: 0.99; sample 1 wrong throughout
    assert area == {"horizon_ms": 100.0, "area": pytest.approx(0.495), "counted": 2, "samples": 2}
    for d in (after, latency, area):
        json.dumps(d, allow_nan=False)


def test_decisions_never_made():
    answers = Answers.from_decisions([np.nan, np.inf, 5 * MS, 7 * MS], [0, 1, -1, 1])
    np.testing.assert_array_equal(answers.classes[:, 0], [-1, -1, -1, 1])
    result = decision_latency(answers, [0, 1, 1, 1], np.zeros(4))
    assert (result.answered, result.first_accuracy, result.median_ms) == (1, 0.25, 7.0)
    none = decision_latency(Answers(np.zeros((2, 0)), np.zeros((2, 0), int)), [0, 0], [0, 0])
    assert none.answered == 0 and math.isnan(none.median_ms) and none.first_accuracy == 0.0
    assert none.to_dict()["median_ms"] is None


def test_the_later_of_two_answers_at_one_time_is_in_force():
    answers = _padded([[(10.0, 1), (10.0, 2)]])
    np.testing.assert_array_equal(answers.at([10.0]), [2])
    np.testing.assert_array_equal(answers.at(9.0), [-1])


@pytest.mark.parametrize(
    ("times", "classes", "n_classes", "message"),
    [
        ([[1.0, 3.0, 2.0]], [[0, 0, 0]], None, "sample 0: times_us not in time order: 2.0 in"),
        ([[1.0, 2.0]], [[0, 0, 0]], None, "times_us of shape (1, 2), classes of shape (1, 3)"),
        ([1.0, 2.0], [0, 0], None, "expected two arrays of one shape (N, K)"),
        ([[1.0, 2.0]], [[0, 5]], 5, "sample 0: class 5 in slot 1: expected -1 or [0, 5)"),
        ([[1.0, 2.0]], [[0, -2]], None, "class -2 in slot 1: expected -1 or [0, n_classes)"),
        ([[1.0, 2.0]], [[0, -1]], None, "slot 1 has time 2.0 and class -1"),
        ([[1.0, np.nan]], [[0, 1]], None, "slot 1 has time nan and class 1"),
        ([[np.nan, 2.0]], [[-1, 1]], None, "an answer in slot 1 after an unused slot"),
        ([[1.0]], [[0.5]], None, "classes: expected integers"),
        ([[1.0]], [[0]], 0, "n_classes: 0: expected an integer >= 1"),
    ],
)
def test_answers_refuse_in_one_line(times, classes, n_classes, message):
    with pytest.raises(ConfigError) as caught:
        Answers(np.array(times), np.array(classes), n_classes)
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_answers_keep_their_own_read_only_copy():
    times, classes = np.array([[1.0, np.inf]]), np.array([[0, -1]])
    answers = Answers(times, classes)
    times[0, 0] = 99.0
    assert answers.times_us[0, 0] == 1.0 and np.isnan(answers.times_us[0, 1])
    with pytest.raises(ValueError):
        answers.classes[0, 0] = 1


def test_bad_arguments_are_refused_in_one_line():
    answers = Answers.from_decisions([1.0, 2.0], [0, 1], n_classes=2)
    cases = [
        (lambda: answers.at([1.0]), "t_us: expected shape (2,), got (1,)"),
        (lambda: answers.at([np.nan, 1.0]), "t_us: expected times, got NaN"),
        (lambda: accuracy_after(answers, [0, 2], [0, 0]), "labels: 2: expected classes in [0, 2)"),
        (lambda: accuracy_after(answers, [0, 1], [0, np.nan]), "t_reference_us: expected finite"),
        (lambda: accuracy_after(answers, [0, 1], [0, 0], (-1,)), "delays_ms: (-1,): expected"),
        (lambda: accuracy_after(answers, [0, 1], [0, 0], span_us=[1.0]), "span_us: expected shape"),
        (lambda: area_under_curve(answers, [0, 1], [0, 0], 0.0), "horizon_ms: 0: expected"),
        (lambda: area_under_curve(answers, [0, 1], [0, 0], math.inf), "horizon_ms: inf: expected"),
        (lambda: Answers.from_decisions([-np.inf], [0]), "decision_us: expected times"),
        (lambda: Answers.from_frames([2.0, 1.0], [[0, 0]]), "frame_end_us: 1.0 after 2.0"),
        (lambda: Answers.from_frames([1.0, 2.0], [[0, 0, 0]]), "frame_end_us: expected shape"),
        (lambda: frame_ends_us(0, 100.0, 50.0), "rotations: 0: expected an integer >= 1"),
        (lambda: frame_ends_us(2, 100.0, 100.0), "window_last_firing_us 100.0 in rotation_us"),
        (lambda: frame_ends_us(2, 100.0, 5.0, -1.0), "max_tof_us: -1.0: expected a finite"),
        (lambda: frame_ends_us(2, True, 5.0), "rotation_us: True: expected a number"),
        (lambda: mean_interval([0.9]), "values: [0.9]: expected 2 values or more"),
        (lambda: mean_interval([0.9, 0.8], 1.0), "confidence: 1.0: expected a level in (0, 1)"),
    ]
    for call, message in cases:
        with pytest.raises(ConfigError) as caught:
            call()
        assert message in str(caught.value) and "\n" not in str(caught.value), message


def test_mean_interval_from_the_t_table():
    # t(0.975, 1) = 12.706 (two seeds, s = sqrt(2): half-width = 12.706 x sqrt(2) / sqrt(2));
    # t(0.975, 4) = 2.776 with s = sqrt(2.5) over 5 seeds: 2.776 x sqrt(0.5) = 1.963
    assert mean_interval([0.0, 2.0]) == pytest.approx((1.0, 12.7062), abs=1e-4)
    assert mean_interval([1, 2, 3, 4, 5]) == pytest.approx((3.0, 1.9632), abs=1e-4)
    assert mean_interval([0.5, 0.5, 0.5]) == (0.5, 0.0)
    # t(0.95, 4) = 2.132: a 90 % interval
    assert mean_interval([1, 2, 3, 4, 5], 0.90)[1] == pytest.approx(2.1318 * 0.70711, abs=1e-4)


ANSWER = st.tuples(st.integers(-50_000, 300_000), st.integers(0, 2))


@settings(max_examples=60, deadline=None)
@given(
    rows=st.lists(st.lists(ANSWER, max_size=4), min_size=1, max_size=5),
    labels=st.lists(st.integers(0, 2), min_size=5, max_size=5),
    refs=st.lists(st.integers(0, 200_000), min_size=5, max_size=5),
)
def test_the_exact_area_is_the_mean_of_a_fine_grid(rows, labels, refs):
    """A grid of G midpoints misses at most one cell (1/G of the horizon) per change of the
    prediction in force, and a sample's prediction changes at most K times (K answers)."""
    rows = [sorted(r) for r in rows]
    answers = _padded(rows)
    n, k, grid = len(rows), max(len(r) for r in rows), 1000
    labels, refs = np.array(labels[:n]), np.array(refs[:n], dtype=float)
    delays_ms = (np.arange(grid) + 0.5) * 100.0 / grid
    curve = accuracy_after(answers, labels, refs, delays_ms=delays_ms).accuracy
    area = area_under_curve(answers, labels, refs, horizon_ms=100.0).area
    assert abs(area - np.mean(curve)) <= max(k, 1) / grid + 1e-12
