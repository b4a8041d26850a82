"""The stream splits' loaders (simlidar.dataset.stream_loaders): each sample's events are its
rows of the file, in time order, with its label; the time each object first returns is that
of its first event on the object's surface; ticks round by hand; a split whose offsets do not
tile its events, or whose events leave the window, is refused in one line, by the loaders and
by ``simlidar verify`` alike."""

import pickle
import shutil
from functools import partial

import h5py
import numpy as np
import pytest
import tonic.transforms as T
import torch.utils.data

from simlidar.data import StreamEventDataset, load_stream
from simlidar.dataset.stream_checks import event_problems
from simlidar.dataset.stream_loaders import EXTRA_FIELDS, stream_events
from simlidar.dataset.version import GENERATOR
from simlidar.errors import ConfigError, DatasetError
from simlidar.generator.stream_files import generate_streams

EVENTS = ("x", "y", "t_us", "p", "range_m", "surface")


@pytest.fixture(scope="module")
def stream(tmp_path_factory):
    """A stream dataset of 8 training and 4 test streams of 4 classes (two of each)."""
    out = tmp_path_factory.mktemp("streams")
    return generate_streams(out, classes=4, train_size=8, test_size=4, progress=False,
                            preview=False)  # fmt: skip


def _file(path, split="train") -> dict[str, np.ndarray]:
    """Every dataset of a split file, read whole by h5py, and its attributes (key "attrs")."""
    with h5py.File(path / f"{split}.h5", "r") as f:
        return {name: f[name][:] for name in f} | {"attrs": dict(f.attrs)}


def _rows(stored, index) -> dict[str, np.ndarray]:
    """Sample ``index``'s rows of the stored per-event datasets, by name without the prefix."""
    first = int(stored["event_start"][index])
    rows = slice(first, first + int(stored["event_count"][index]))
    return {name: stored[f"event_{name}"][rows] for name in EVENTS}


@pytest.mark.parametrize("split", ["train", "test"])
def test_load_stream_returns_the_files_arrays(stream, split):
    stored = _file(stream, split)
    loaded = load_stream(stream, split)
    assert len(loaded) == len(stored["labels"])
    assert loaded.classes == ["none", "car", "pedestrian", "truck"]
    assert loaded.files == (stream / f"{split}.h5",)
    per_sample = {n for n in stored if n not in ("attrs", "delays") and not n.startswith("event_")}
    assert set(loaded.samples) == per_sample and "t_visible_us" in per_sample
    for name, values in loaded.samples.items():
        assert values.dtype == stored[name].dtype
        np.testing.assert_array_equal(values, stored[name])
    for name in ("start", "count", *EVENTS):
        np.testing.assert_array_equal(getattr(loaded.events, name), stored[f"event_{name}"])
    for index in range(len(loaded)):
        rows = loaded.events.rows(index)
        np.testing.assert_array_equal(loaded.events.t_us[rows], _rows(stored, index)["t_us"])


@pytest.mark.parametrize("tick_us, budget", [(1.0, None), (250.0, 0)])
def test_each_sample_is_its_rows_of_the_file_in_time_order(stream, tick_us, budget):
    """Read from the events held whole (the default) or, past ``memory_budget``, from the file."""
    stored = _file(stream, "test")
    fields = ("surface", "t_us", "range_m")
    dataset = StreamEventDataset(stream, "test", tick_us=tick_us, fields=fields)
    if budget is not None:
        dataset.memory_budget = budget
    assert len(dataset) == 4 and dataset.sensor_size == (32, 16, 1)
    assert dataset.ordering == ("x", "y", "t", "p", *fields) == dataset.dtype.names
    assert dataset.classes == ["none", "car", "pedestrian", "truck"]
    np.testing.assert_array_equal(dataset.t_reference_us, stored["t_reference_us"])
    assert dataset.span_us == 1e6 == stored["attrs"]["span_us"]
    for index in range(len(dataset)):
        events, label = dataset[index]
        rows = _rows(stored, index)
        order = np.argsort(rows["t_us"], kind="stable")
        assert events.dtype == dataset.dtype and label == stored["labels"][index]
        assert len(events) == stored["event_count"][index] > 0
        assert (np.diff(events["t"]) >= 0).all() and (np.diff(events["t_us"]) >= 0).all()
        for name in ("x", "y", "p", *fields):
            np.testing.assert_array_equal(events[name], rows[name][order])
        np.testing.assert_array_equal(events["t"], np.round(rows["t_us"][order] / tick_us))
    assert dataset[-1][0].tobytes() == dataset[3][0].tobytes()
    assert dataset._whole == (budget is None)
    with pytest.raises(IndexError):
        dataset[4]


@pytest.mark.parametrize("split", ["train", "test"])
def test_t_visible_is_the_first_event_on_the_objects_surface(stream, split):
    loaded = load_stream(stream, split)
    objects = list(loaded.attrs["object_names"])
    surfaces = list(loaded.attrs["surface_names"])
    events, samples = loaded.events, loaded.samples
    seen = {"with": 0, "without": 0}
    for index, obj in enumerate(samples["object"]):
        t_visible = samples["t_visible_us"][index]
        if obj == 0:  # "none"
            assert np.isnan(t_visible)
            seen["without"] += 1
            continue
        rows = events.rows(index)
        on_object = events.surface[rows] == surfaces.index(objects[obj])
        assert t_visible == events.t_us[rows][on_object].min()
        assert on_object.sum() == samples["object_events"][index]
        seen["with"] += 1
    assert seen["with"] >= 3 and seen["without"] >= 1


def test_ticks_round_by_hand():
    events = {
        "x": np.array([5, 6, 7], np.uint16),
        "y": np.array([1, 2, 3], np.uint8),
        "t_us": np.array([1234.6, 3.0, 1234.4]),
        "p": np.zeros(3, np.uint8),
        "surface": np.array([9, 1, 2], np.uint8),
    }
    out = stream_events(events, tick_us=1.0, fields=("surface",))
    assert out["t"].tolist() == [3, 1234, 1235]  # 1234.6 us: tick 1235, sorted by time
    assert out["x"].tolist() == [6, 7, 5] and out["y"].tolist() == [2, 3, 1]
    assert out["surface"].tolist() == [1, 2, 9] and out.dtype["surface"] == np.uint8
    assert out.dtype["t"] == np.int64 and out.dtype.names == ("x", "y", "t", "p", "surface")
    assert stream_events(events, tick_us=10.0)["t"].tolist() == [0, 123, 123]
    assert stream_events(events, tick_us=0.5)["t"].tolist() == [6, 2469, 2469]


def test_a_tonic_transform_and_a_target_transform_are_applied(stream):
    plain = StreamEventDataset(stream, "train")
    to_frame = T.ToFrame(sensor_size=plain.sensor_size, time_window=100_000, start_time=0,
                         end_time=plain.span_us, include_incomplete=True)  # fmt: skip
    framed = StreamEventDataset(stream, "train", transform=to_frame,
                                target_transform=lambda label: f"class {label}")  # fmt: skip
    for index in (0, 5):
        events, label = plain[index]
        frames, named = framed[index]
        assert frames.shape == (10, 1, 16, 32)  # ten rotations of 100 ms
        assert frames.sum() == len(events) and named == f"class {label}"
        counted = np.bincount(events["t"] // 100_000, minlength=10)
        np.testing.assert_array_equal(frames.sum(axis=(1, 2, 3)), counted)


def test_a_dataset_pickles_without_its_open_files(stream):
    dataset = StreamEventDataset(stream, "train", fields=("range_m",))
    before = dataset[2][0]
    again = pickle.loads(pickle.dumps(dataset))  # as to a DataLoader worker
    assert again._h5 is None and again._arrays == {} and dataset._arrays
    assert again[2][0].tobytes() == before.tobytes()


def test_dataloader_workers_open_their_own_files(stream):
    """Workers forked after the parent read a sample: each reads through its own handles."""
    to_frame = T.ToFrame(sensor_size=(32, 16, 1), time_window=100_000, start_time=0,
                         end_time=1e6, include_incomplete=True)  # fmt: skip
    framed = StreamEventDataset(stream, "train", transform=to_frame)
    expected = np.stack([framed[i][0] for i in range(len(framed))])  # the parent's handles open
    order = [5, 0, 7, 2, 1, 6, 3, 4]
    loader = torch.utils.data.DataLoader(framed, batch_size=3, sampler=order, num_workers=2)
    batches = list(loader)
    assert torch.cat([b for b, _ in batches]).numpy().tobytes() == expected[order].tobytes()
    assert torch.cat([b for _, b in batches]).tolist() == framed.labels[order].tolist()


@pytest.fixture
def tampered(stream, tmp_path, agreeing):
    """``tampered(change)``: a copy of the stream dataset whose train.h5 ``change(f)`` altered
    (f: the file open for writing), its card and sums agreeing."""

    def make(change):
        copy = tmp_path / "copy"
        shutil.copytree(stream, copy)
        with h5py.File(copy / "train.h5", "a") as f:
            change(f)
        agreeing(copy)
        return copy

    return make


def _at(name, index, value):
    def change(f):
        values = f[name][:]
        values[index] = value
        f[name][:] = values

    return change


def _plus(name, index, more):
    def change(f):
        values = f[name][:]
        values[index] += more
        f[name][:] = values

    return change


def _refused(load, message):
    with pytest.raises(DatasetError) as caught:
        load()
    assert message in str(caught.value) and "\n" not in str(caught.value), str(caught.value)


@pytest.mark.parametrize(
    "change, sample",
    [(_plus("event_start", 2, 1), 2), (_plus("event_count", 7, 10), 7),
     (_at("event_count", 3, 2**62), 3)],
    ids=["a start shifted", "a count past the last event", "a count beyond any file"],
)  # fmt: skip
def test_offsets_that_do_not_tile_the_events_are_refused(tampered, cli, change, sample):
    copy = tampered(change)
    with h5py.File(copy / "train.h5", "r") as f:
        first, count = int(f["event_start"][sample]), int(f["event_count"][sample])
        total = f["event_t_us"].shape[0]
    message = (
        f"train.h5: 'event_start' and 'event_count' do not tile the {total} events in order "
        f"(sample {sample}: rows {first} .. {first + count})"
    )
    for load in (lambda: load_stream(copy), lambda: StreamEventDataset(copy, "train")):
        _refused(load, message)
    verified = cli("verify", copy)
    assert verified.exit_code == 1 and message in verified.output, verified.output
    assert "Traceback" not in verified.output


def test_event_problems_by_hand():
    assert event_problems("f", [0, 3, 3], [3, 0, 2], 5) == []
    assert event_problems("f", [], [], 0) == []
    assert "(no samples)" in event_problems("f", [], [], 4)[0]
    assert "(sample 1: rows 2 .. 2)" in event_problems("f", [0, 2, 3], [3, 0, 2], 5)[0]
    assert "(sample 2: rows 3 .. 4)" in event_problems("f", [0, 3, 3], [3, 0, 1], 5)[0]
    assert "(sample 0: rows 0 .. -1)" in event_problems("f", [0, -1], [-1, 6], 5)[0]
    # counts whose int64 sum wraps around to the total once tiled the events in verify's check
    big = 2**63 - 1
    wrapped = event_problems("f", [0, big, -2], [big, big, 7], 5)
    assert "(sample 0: rows 0 .. 9223372036854775807)" in wrapped[0]


def _event(name, sample, event, value):
    """Set event ``event`` of sample ``sample``'s dataset ``event_<name>`` to ``value``."""

    def change(f):
        _at(f"event_{name}", int(f["event_start"][sample]) + event, value)(f)

    return change


@pytest.mark.parametrize(
    "name, sample, event, value, message",
    [
        ("x", 0, 5, 40, "event_x 40; expected a column of the window, 0 .. 31"),
        ("y", 1, 20, 16, "event_y 16; expected a row, 0 .. 15"),
        ("t_us", 3, 7, np.nan, "event_t_us nan; expected an arrival within span_us"),
        ("t_us", 3, 8, -1.0, "event_t_us -1.0; expected an arrival within span_us"),
        ("p", 6, 9, 1, "event_p 1; expected the one polarity, 0 .. 0"),
    ],
    ids=["a column outside the window", "a row past the sensor", "a NaN time",
         "a time before the first firing", "a second polarity"],
)  # fmt: skip
def test_events_outside_the_window_are_refused_naming_the_sample(
    tampered, cli, name, sample, event, value, message
):
    copy = tampered(_event(name, sample, event, value))
    where = f"train.h5 (sample {sample}, its event {event}): {message}"
    _refused(lambda: load_stream(copy), where)
    verified = cli("verify", copy)  # verify names it as the loaders do
    assert verified.exit_code == 1 and where in verified.output, verified.output
    for budget in (2**30, 0):  # the events held whole, or read from the file
        dataset = StreamEventDataset(copy, "train")
        dataset.memory_budget = budget
        dataset[2]  # a sound sample reads as before
        _refused(partial(dataset.__getitem__, sample), where)


def test_a_surface_outside_the_names_is_refused_where_it_is_read(tampered):
    copy = tampered(_event("surface", 4, 2, 12))
    message = "(sample 4, its event 2): event_surface 12; expected an index into surface_names"
    _refused(lambda: load_stream(copy), message)
    assert len(StreamEventDataset(copy, "train")[4][0]) > 2  # not a field it returns
    _refused(lambda: StreamEventDataset(copy, "train", fields=("surface",))[4], message)


def test_a_split_that_is_not_a_stream_split_is_refused(datasets):
    path = datasets[0.1]
    message = f"{path / 'train.h5'}: source {GENERATOR!r}; expected a stream split (source "
    _refused(lambda: load_stream(path), message)
    _refused(lambda: StreamEventDataset(path), message)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"tick_us": 0}, "tick_us=0: expected microseconds in (0, 1000000]"),
        ({"tick_us": 2e6}, "tick_us=2000000.0: expected microseconds in (0, 1000000]"),
        ({"tick_us": 1e-12}, "tick_us=1e-12: the 1000000 us stream would span 1e+18 ticks"),
        ({"tick_us": "1"}, "tick_us='1': expected microseconds"),
        ({"fields": "surface"}, "fields='surface': expected a tuple of distinct names from"),
        ({"fields": ("x",)}, "fields=('x',): expected a tuple of distinct names from"),
        ({"fields": ("surface", "surface")}, "fields=('surface', 'surface'): expected"),
    ],
)
def test_bad_options_are_refused_in_one_line(stream, options, message):
    with pytest.raises(ConfigError) as caught:
        StreamEventDataset(stream, "train", **options)
    assert message in str(caught.value) and "\n" not in str(caught.value)
    assert str(list(EXTRA_FIELDS)) in str(caught.value) or "tick_us" in options


def _shards(source, out, sizes):
    """``out``: the stream dataset ``source`` with its train split cut into shard files of
    ``sizes`` samples (each file's events its own, their offsets from its first), its test
    split as it is."""
    out.mkdir()
    shutil.copy(source / "test.h5", out / "test.h5")
    stored = _file(source)
    first = 0
    for index, size in enumerate(sizes):
        samples = slice(first, first + size)
        begin = int(stored["event_start"][first])
        end = begin + int(stored["event_count"][samples].sum())
        shard = out / f"train-{index:05d}-of-{len(sizes):05d}.h5"
        shutil.copy(source / "train.h5", shard)  # its attributes as they are
        with h5py.File(shard, "a") as f:
            f.attrs["shard"], f.attrs["shards"] = index, len(sizes)
            for name, values in stored.items():
                if name == "attrs":
                    continue
                del f[name]
                if name == "event_start":
                    f[name] = values[samples] - begin
                elif name[6:] in EVENTS:  # a per-event dataset
                    f[name] = values[begin:end]
                else:
                    f[name] = values[samples]
        first += size
    return out


def test_a_sharded_split_reads_as_one(stream, tmp_path):
    sharded = _shards(stream, tmp_path / "sharded", (3, 5))
    whole, parts = load_stream(stream), load_stream(sharded)
    assert len(parts.files) == 2
    for name, values in whole.samples.items():
        np.testing.assert_array_equal(parts.samples[name], values)
    for name in ("start", "count", *EVENTS):
        np.testing.assert_array_equal(getattr(parts.events, name), getattr(whole.events, name))
    one, two = StreamEventDataset(stream), StreamEventDataset(sharded)
    np.testing.assert_array_equal(two.t_reference_us, one.t_reference_us)
    for index in range(8):
        assert two[index][0].tobytes() == one[index][0].tobytes()
        assert two[index][1] == one[index][1]
