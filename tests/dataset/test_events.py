"""Spike events in Tonic's convention (issue 32, item 6): ``to_events``, ``EventDataset`` and
``PulseDataset``'s ``target_transform``, checked against real tonic transforms on events of a
real generated dataset, with every expected value worked out from the HDF5 file's delays.

Attack list (the hostile input or the mismatch each test covers):
* tonic's ``ToFrame`` on one-polarity events writes ``p = 0`` into the array it is given: the
  events must already be p = 0, or the caller's array changes under it (frames test);
* ``ToTimesurface`` indexes its (P, H, W) memory by ``p``: p = 1 with one polarity was an
  IndexError (time-surface test);
* times in picoseconds where Tonic's parameters (``time_window``, ``dt``, ``tau``,
  ``filter_time``) are microseconds: events are in ticks of ``tick_ns`` (1 us by default) and
  every expected bin below is computed from the delays in those ticks;
* frames of a fixed (absolute) time span must be the same shape for every sample so that a
  DataLoader can stack them, and lose no event (frames test); ``n_time_bins`` is relative to
  each sample's first and last event, and tonic leaves the last event out (its test);
* ``Denoise``'s neighbourhood rule, including the start of its memory (denoise test);
* a tick coarser than the whole window (the default microsecond on a 667 ns flash window), a
  zero, negative, NaN, string or boolean tick, a bad unit: one-line ``ConfigError`` naming the
  value and what was expected, before any event is made;
* a split with no time unit among its attributes: a ``DatasetError`` naming the file;
* sharded splits read through ``EventDataset`` give the same events as one file;
* ``target_transform`` is applied to the label, in ``EventDataset`` and ``PulseDataset``.
"""

import shutil

import h5py
import numpy as np
import pytest
import tonic.transforms as T  # the test extra's tonic (pinned: the slicing below is its own)

from simlidar.data import EVENT_DTYPE, EventDataset, sensor_size, to_events, window_ticks
from simlidar.errors import ConfigError, DatasetError

NS = 1.0  # a tick of one nanosecond: a flash window of 667 ns spans 668 ticks


def raw(path, split="test"):
    """Delays, labels and the time of flight of a delay of 1.0, straight from the file."""
    with h5py.File(path / f"{split}.h5", "r") as f:
        return f["delays"][:], f["labels"][:], float(f.attrs["tof_max_ns"])


def ticks(delays, unit_ns, tick_ns=NS):
    """(H, W) arrival ticks of a sample's pulses, -1 where there is none (a delay of 1.0)."""
    t = np.round(delays.astype(np.float64) * unit_ns / tick_ns).astype(np.int64)
    return np.where(delays < 1.0, t, -1)


def test_events_by_hand():
    delays = np.ones((16, 4), np.float32)
    delays[2, 1] = 0.5  # row 2, column 1, half the window
    delays[0, 3] = 0.1
    events = to_events(delays, unit_ns=6000.0)  # a window of 6 us, in microseconds
    assert events.dtype == EVENT_DTYPE and EVENT_DTYPE.names == ("x", "y", "t", "p")
    assert events.tolist() == [(3, 0, 1, 0), (1, 2, 3, 0)]  # 0.6 us rounds to 1; p = 0
    assert to_events(delays, 6000.0, tick_ns=1.0).tolist() == [(3, 0, 600, 0), (1, 2, 3000, 0)]
    assert to_events(delays, 6000.0, tick_ns=0.001)["t"].tolist() == [600_000, 3_000_000]  # ps
    assert to_events(delays, 6000.0, no_return=0.3).tolist() == [(3, 0, 1, 0)]
    assert len(to_events(np.ones((16, 4), np.float32), 6000.0)) == 0  # no return, no event
    # a delay of 1.0 is the last tick: every time lies below window_ticks
    assert window_ticks(6000.0) == 7 and window_ticks(667.13, 1.0) == 668
    assert to_events(np.zeros((1, 1)) + 1.0, 667.13, np.inf, 1.0)["t"].tolist() == [667]
    assert sensor_size(4, 16) == (4, 16, 1) and sensor_size(118, 50) == (118, 50, 1)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(tick_ns=1000.0), "tick_ns=1000.0: expected nanoseconds in (0, 667.13] (a delay"),
        (dict(tick_ns=0), "tick_ns=0: expected nanoseconds in (0, 667.13]"),
        (dict(tick_ns=-1.0), "tick_ns=-1.0: expected"),
        (dict(tick_ns=float("nan")), "tick_ns=nan: expected"),
        (dict(tick_ns="1"), "tick_ns='1': expected"),
        (dict(tick_ns=True), "tick_ns=True: expected"),
        (dict(unit_ns=0.0), "unit_ns=0.0: expected nanoseconds > 0"),
        (dict(unit_ns=float("inf")), "unit_ns=inf: expected nanoseconds > 0"),
        (dict(unit_ns=None), "unit_ns=None: expected nanoseconds > 0"),
    ],
)
def test_a_bad_tick_or_unit_is_one_line(kwargs, words):
    delays = np.full((16, 16), 0.5, np.float32)
    args = dict(unit_ns=667.13) | kwargs
    with pytest.raises(ConfigError) as err:
        to_events(delays, **args)
    assert words in str(err.value) and "\n" not in str(err.value)
    if "tick_ns" in kwargs:
        with pytest.raises(ConfigError, match="tick_ns="):
            window_ticks(667.13, kwargs["tick_ns"])


def test_the_event_dataset_has_tonics_attributes_and_the_files_events(datasets):
    path = datasets[0.1]
    delays, labels, tof_max_ns = raw(path)
    ds = EventDataset(path, "test", tick_ns=NS, target_transform=lambda y: y + 100)
    assert ds.sensor_size == (16, 16, 1) and len(ds) == 64 == len(labels)
    assert ds.dtype == EVENT_DTYPE and ds.ordering == ("x", "y", "t", "p")
    assert EventDataset.ordering == ("x", "y", "t", "p") and EventDataset.dtype == EVENT_DTYPE
    assert len(ds.classes) == 32 and ds.unit_ns == tof_max_ns == pytest.approx(667.128, abs=1e-3)
    assert ds.window_ticks == 668 and ds.tick_ns == NS
    for i in (0, 5, 63, -1):
        events, label = ds[i]
        assert label == labels[i] + 100
        want = ticks(delays[i], tof_max_ns)
        assert len(events) == int((want >= 0).sum()) > 0
        assert (events["p"] == 0).all() and (np.diff(events["t"]) >= 0).all()
        assert (events["t"] == want[events["y"], events["x"]]).all()  # each pixel's own time
        assert ((0 <= events["t"]) & (events["t"] < ds.window_ticks)).all()
    with pytest.raises(IndexError, match="index 64 out of range for 64 samples"):
        ds[64]


def test_the_default_tick_is_a_nanosecond_on_a_flash_window(datasets):
    """A microsecond is longer than the 667 ns flash window, and the documented first call
    (no tick) refused the flash data it was shown with; the default now fits the window."""
    events = EventDataset(datasets[0.1], "test")
    assert events.tick_ns == 1.0 and events.window_ticks == round(events.unit_ns) + 1
    with pytest.raises(ConfigError, match=r"^tick_ns=1000.0: expected nanoseconds in \(0, 667"):
        EventDataset(datasets[0.1], "test", tick_ns=1000.0)  # asked for, it is refused


def test_a_tick_too_short_for_an_int64_time_is_refused(datasets):
    """tick_ns = 1e-300 turned every event's t into INT64_MIN."""
    with pytest.raises(ConfigError, match=r"^tick_ns=1e-300: the 667.128 ns window would span"):
        EventDataset(datasets[0.1], "test", tick_ns=1e-300)


@pytest.mark.parametrize("field", ["labels", "surface", 3])
def test_a_field_that_is_not_a_sample_is_refused(datasets, field):
    with pytest.raises(
        ConfigError, match=r"^field=.*: expected one of \['delays', 'clean_delays'\]"
    ):
        EventDataset(datasets[0.1], "test", field=field)


def test_a_split_without_a_time_unit_is_refused(datasets, tmp_path):
    copy = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], copy)
    with h5py.File(copy / "test.h5", "a") as f:
        del f.attrs["tof_max_ns"]
    with pytest.raises(DatasetError, match=r"test.h5: no time unit of the delays \(attribute"):
        EventDataset(copy, "test", tick_ns=NS)


def test_tonic_frames_of_absolute_bins_count_every_event_once(datasets):
    """time_window bins from 0 to window_ticks: the same 7 frames of 100 ns for every sample,
    each pulse in the bin of its arrival tick, and the caller's array left as it was."""
    import torch

    path = datasets[0.5]
    delays, labels, tof_max_ns = raw(path)
    ds = EventDataset(path, "test", tick_ns=NS)
    to_frame = T.ToFrame(
        sensor_size=ds.sensor_size,
        time_window=100,
        start_time=0,
        end_time=ds.window_ticks,
        include_incomplete=True,
    )
    for i in range(len(ds)):
        events, _ = ds[i]
        before = events.copy()
        frames = to_frame(events)
        np.testing.assert_array_equal(events, before)  # ToFrame wrote p = 0: it already was
        assert frames.shape == (7, 1, 16, 16)  # ceil(668 / 100) frames, one polarity
        assert frames.sum() == len(events) == int((delays[i] < 1).sum())
        want = ticks(delays[i], tof_max_ns)
        np.testing.assert_array_equal(frames.sum(axis=(0, 1)), want >= 0)  # one pulse a pixel
        for k in range(7):
            np.testing.assert_array_equal(frames[k, 0], (want >= 0) & (want // 100 == k))
    # the same shape for every sample: a DataLoader stacks them (workers open their own files)
    framed = EventDataset(path, "test", tick_ns=NS, transform=to_frame)
    batches = list(torch.utils.data.DataLoader(framed, batch_size=32, num_workers=2))
    assert [tuple(x.shape) for x, _ in batches] == [(32, 7, 1, 16, 16)] * 2
    assert sum(int(x.sum()) for x, _ in batches) == int((delays < 1).sum())
    assert torch.cat([y for _, y in batches]).tolist() == labels.tolist()


def test_tonic_frames_of_n_time_bins_are_relative_to_each_sample(datasets):
    """n_time_bins slices each sample from its first event in bins of (last - first) // n
    ticks, end excluded (tonic 1.7.0): the last event falls outside; time_window above keeps
    every event."""
    path = datasets[0.1]
    delays, _, tof_max_ns = raw(path)
    ds = EventDataset(path, "test", tick_ns=NS)
    events, _ = ds[3]
    frames = T.ToFrame(sensor_size=ds.sensor_size, n_time_bins=4)(events)
    want = ticks(delays[3], tof_max_ns)
    first, last = int(want[want >= 0].min()), int(want.max())
    width = (last - first) // 4
    assert frames.shape == (4, 1, 16, 16) and width > 0
    for k in range(4):
        lo = first + k * width
        np.testing.assert_array_equal(frames[k, 0], (want >= lo) & (want < lo + width))
    inside = int(((want >= 0) & (want < first + 4 * width)).sum())
    assert frames.sum() == inside < len(events)


def test_tonic_time_surfaces(datasets):
    """ToTimesurface over one polarity (an IndexError with p = 1): surface i at a pixel is
    exp(-((i + 1) dt + t_first - t) / tau) once the pixel's pulse has come (t before the end of
    slice i), 0 before."""
    path = datasets[0.1]
    delays, _, tof_max_ns = raw(path)
    ds = EventDataset(path, "test", tick_ns=NS)
    dt, tau = 50, 30.0
    for i in (0, 17):
        events, _ = ds[i]
        surfaces = T.ToTimesurface(sensor_size=ds.sensor_size, dt=dt, tau=tau)(events)
        want = ticks(delays[i], tof_max_ns)
        first, last = int(want[want >= 0].min()), int(want.max())
        n = (last - first - dt) // dt + 1  # whole slices of dt from the first event
        assert surfaces.shape == (n, 1, 16, 16) and n >= 2
        for k in range(n):
            end = first + (k + 1) * dt
            seen = (want >= 0) & (want < end)
            expected = np.where(seen, np.exp(-(end - want) / tau), 0.0)
            np.testing.assert_allclose(surfaces[k, 0], expected, rtol=1e-12)
        # the first surface has seen some pulses, not all: times, not only pixels, count
        assert 0 < int((surfaces[0, 0] > 0).sum()) < int((want >= 0).sum())


def test_tonic_denoise(datasets):
    """Denoise keeps an event when a 4-neighbour pixel's pulse came at most filter_time ticks
    before it in the stream; a neighbour not yet seen counts until t reaches filter_time
    (tonic's memory starts there)."""
    path = datasets[0.5]
    ds = EventDataset(path, "test", tick_ns=NS)
    filter_time = 60
    kept_all = dropped_all = 0
    for i in range(0, len(ds), 8):
        events, _ = ds[i]
        before = events.copy()
        kept = T.Denoise(filter_time=filter_time)(events)
        np.testing.assert_array_equal(events, before)
        width, height = int(events["x"].max()) + 1, int(events["y"].max()) + 1
        seen: dict[tuple[int, int], int] = {}
        want = []
        for x, y, t, p in events.tolist():
            seen[(x, y)] = t
            close = False
            for nx, ny in ((x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)):
                if 0 <= nx < width and 0 <= ny < height:
                    last = seen.get((nx, ny))  # None: no pulse yet, tonic's memory start
                    close |= t < filter_time if last is None else t - last < filter_time
            if close:
                want.append((x, y, t, p))
        assert kept.dtype == EVENT_DTYPE and kept.tolist() == want
        kept_all, dropped_all = kept_all + len(kept), dropped_all + len(events) - len(kept)
    assert kept_all > 0 and dropped_all > 0  # the rule bites both ways on these samples


def test_shards_give_the_same_events(sharded, datasets):
    whole = EventDataset(datasets[0.1], "train", tick_ns=NS)
    shards = EventDataset(sharded, "train", tick_ns=NS)
    assert len(shards) == len(whole) == 96
    for i in (0, 39, 40, 95):
        (a, ya), (b, yb) = whole[i], shards[i]
        np.testing.assert_array_equal(a, b)
        assert ya == yb


def test_pulse_dataset_target_transform(datasets):
    import torch

    from simlidar.data import PulseDataset

    _, labels, _ = raw(datasets[0.1])
    one_hot = PulseDataset(
        datasets[0.1],
        "test",
        target_transform=lambda y: torch.nn.functional.one_hot(torch.tensor(y), 32),
    )
    x, target = one_hot[5]
    assert x.shape == (16, 16) and target.shape == (32,) and int(target.argmax()) == labels[5]
    batch = next(iter(torch.utils.data.DataLoader(one_hot, batch_size=64)))[1]
    assert batch.shape == (64, 32) and batch.argmax(1).tolist() == labels.tolist()
