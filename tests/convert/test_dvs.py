"""DVS barrel -> first-spike times, on tiny MATLAB files written here with scipy.io.savemat in
the published layout (a struct array ROI of x, y, polarity, timestamps in us)."""

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy.io import savemat
from source_examples import RECORDINGS, write_mat

from simlidar.any_card import render_card
from simlidar.convert import convert_dvs_barrel
from simlidar.dataset.loaders import load_split
from simlidar.errors import ConfigError, DatasetError
from simlidar.release.checksums import read_sums, write_sums
from simlidar.release.verify import verify


def records(path):
    out = {}
    for split in ("train", "test"):
        with h5py.File(path / f"{split}.h5", "r") as f:
            out[split] = {name: f[name][:] for name in f} | {"attrs": dict(f.attrs)}
    return out


@pytest.fixture(scope="module")
def dvs_dataset(tmp_path_factory):
    """RECORDINGS converted with the defaults (read only: copy it to change it)."""
    folder = tmp_path_factory.mktemp("dvs")
    return convert_dvs_barrel(write_mat(folder / "tiny.mat"), folder / "out", progress=False)


def test_first_spike_times_by_hand(dvs_dataset):
    both = records(dvs_dataset)
    window = both["train"]["attrs"]["time_window_us"]
    assert window == 401.0  # the longest recording spans 450 - 50 = 400 us, plus 1 us
    delays = {int(r): d for s in both.values() for r, d in zip(s["recording"], s["delays"])}
    # recording 0 starts at 50 us: pixel (y 1, x 1) fires at 50 and again at 100 (first: 0),
    # (y 2, x 32) at 300 -> 250 / 401, (y 32, x 3) at 450 -> 400 / 401; the rest stay silent
    expected = np.ones((32, 32), dtype=np.float32)
    expected[0, 0], expected[1, 31], expected[31, 2] = 0.0, 250 / 401, 400 / 401
    np.testing.assert_array_equal(delays[0], expected)
    assert delays[1][5, 4] == 0.0 and (delays[1] < 1).sum() == 1
    assert delays[2][2, 2] == np.float32(400 / 401) and (delays[2] < 1).sum() == 2
    assert (delays[3] == 1.0).all()


def test_raw_events_are_kept_alongside(dvs_dataset):
    for split in records(dvs_dataset).values():
        for k, recording in enumerate(split["recording"]):
            start, count = split["event_start"][k], split["event_count"][k]
            x, y, p, t, _ = RECORDINGS[recording]
            rows = slice(start, start + count)
            assert split["event_x"][rows].tolist() == [v - 1 for v in x]  # 0-based
            assert split["event_y"][rows].tolist() == [v - 1 for v in y]
            assert split["event_p"][rows].tolist() == p
            assert split["event_t_us"][rows].tolist() == t


def test_event_dataset_gives_first_spikes_in_microseconds(dvs_dataset):
    """EventDataset on a DVS split: time_window_us is the unit, the default tick a microsecond;
    each pixel's first event after the recording's first, one polarity (p = 0)."""
    from simlidar.data import EventDataset

    checked = set()
    for split in ("train", "test"):
        ds = EventDataset(dvs_dataset, split)
        assert ds.sensor_size == (32, 32, 1) and ds.unit_ns == 401_000.0
        assert ds.window_ticks == 402
        for k, recording in enumerate(records(dvs_dataset)[split]["recording"]):
            events, _ = ds[k]
            if recording == 0:  # (x, y, t us, p): see test_first_spike_times_by_hand
                assert events.tolist() == [(0, 0, 0, 0), (31, 1, 250, 0), (2, 31, 400, 0)]
            if recording == 3:  # no events at all
                assert len(events) == 0 and events.dtype == ds.dtype
            checked.add(int(recording))
    assert {0, 3} <= checked


def test_recordings_split_per_class_and_the_dataset_verifies(dvs_dataset):
    both = records(dvs_dataset)
    names = list(both["train"]["attrs"]["class_names"])
    assert len(names) == 36 and names[:3] == ["0", "1", "2"] and names[10] == "A"
    assert sorted(both["test"]["labels"].tolist()) == [10, 11]  # one A and one B
    assert sorted(both["train"]["labels"].tolist()) == [7, 10, 11]  # the single 7 trains
    assert not set(both["train"]["recording"]) & set(both["test"]["recording"])
    assert verify(dvs_dataset) == []
    x, y = load_split(dvs_dataset, "train")
    assert x.shape == (3, 32, 32) and y.dtype == np.int64
    card = (dvs_dataset / "README.md").read_text()
    assert render_card(dvs_dataset) == card and "401 us: the delay 1.0" in card
    assert "@article{orchard2015hfirst" in card and "convert_dvs_barrel('FILE.mat'" in card


def test_same_file_and_seed_give_the_same_bytes(dvs_dataset, tmp_path):
    again = convert_dvs_barrel(dvs_dataset.parents[1] / "tiny.mat", tmp_path, progress=False)
    for name in read_sums(dvs_dataset):
        assert (again / name).read_bytes() == (dvs_dataset / name).read_bytes(), name


def test_a_cell_array_of_structs_reads_the_same(dvs_dataset, tmp_path):
    mat = write_mat(tmp_path / "cells.mat", cells=True)
    again = convert_dvs_barrel(mat, tmp_path / "cells", progress=False, preview=False)
    for split in ("train", "test"):
        assert (records(again)[split]["delays"] == records(dvs_dataset)[split]["delays"]).all()


def test_an_explicit_window_and_labels(tmp_path):
    mat = write_mat(tmp_path / "plain.mat", fields=("x", "y", "pol", "timestamp"))
    with pytest.raises(ConfigError, match=r"5 recordings, no 'label' field in ROI; expected one"):
        convert_dvs_barrel(mat, tmp_path / "out", progress=False)
    with pytest.raises(ConfigError, match=r"5 recordings, 2 labels given"):
        convert_dvs_barrel(mat, tmp_path / "out", labels=("A", "B"), progress=False)
    path = convert_dvs_barrel(
        mat, tmp_path / "out", labels=tuple("CCDDE"), window_us=200, progress=False, preview=False
    )
    both = records(path)
    delays = {int(r): d for s in both.values() for r, d in zip(s["recording"], s["delays"])}
    assert both["test"]["attrs"]["time_window_us"] == 200.0
    assert delays[0][0, 0] == 0.0 and delays[0][1, 31] == 1.0  # 250 us is past the window
    labels = np.concatenate([both[s]["labels"] for s in both])
    assert sorted(labels.tolist()) == [12, 12, 13, 13, 14]  # C C D D E


@pytest.mark.parametrize(
    "recordings, fields, words",
    [
        (
            [([1, 33], [1, 1], [1, 1], [0, 1], "A")] * 2,
            ("x", "y", "p", "ts", "label"),
            r"ROI\(1\).x has 33; expected integers in \[1, 32\]",
        ),
        (
            [([1], [1], [2], [0], "A")] * 2,
            ("x", "y", "p", "ts", "label"),
            r"ROI\(1\).p has 2; expected integers in \[-1, 1\]",
        ),
        (
            [([1, 2], [1], [1, 1], [0, 1], "A")] * 2,
            ("x", "y", "p", "ts", "label"),
            r"ROI\(1\) has 2 x, 1 y, 2 polarity and 2 time values; expected one per event",
        ),
        (
            [([1], [1], [1], [0], "AB")] * 2,
            ("x", "y", "p", "ts", "label"),
            r"ROI\(1\).label is array\(\['AB'\].*expected one character 0-9 or A-Z",
        ),
        (
            [([1], [1], [1], [0])] * 2,
            ("x", "y", "p"),
            r"ROI\(1\) has fields x, y, p; expected x, y, p \(or pol, polarity\), ts",
        ),
        (
            [([1], [1], [1], [0], "A")],
            ("x", "y", "p", "ts", "label"),
            r"1 recording\(s\), no class with two: expected at least two recordings of a class",
        ),
    ],
)
def test_bad_recordings_are_named_and_nothing_is_written(tmp_path, recordings, fields, words):
    mat = write_mat(tmp_path / "bad.mat", recordings, fields=fields)
    with pytest.raises(DatasetError, match=words):
        convert_dvs_barrel(mat, tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_recordings_without_events(tmp_path):
    silent = [([], [], [], [], "A"), ([], [], [], [], "A")]
    path = convert_dvs_barrel(
        write_mat(tmp_path / "silent.mat", silent), tmp_path / "out", progress=False, preview=False
    )
    assert verify(path) == []
    x, _ = load_split(path, "test")
    assert (x == 1.0).all() and records(path)["test"]["event_t_us"].shape == (0,)


def test_files_that_are_not_the_layout(tmp_path):
    savemat(tmp_path / "other.mat", {"events": np.zeros((1, 3))})
    with pytest.raises(DatasetError, match=r"other.mat: no variable 'ROI' \(found events\)"):
        convert_dvs_barrel(tmp_path / "other.mat", tmp_path / "out")
    (tmp_path / "text.mat").write_text("not a MATLAB file")
    with pytest.raises(DatasetError, match=r"text.mat: cannot read as a MATLAB file"):
        convert_dvs_barrel(tmp_path / "text.mat", tmp_path / "out")
    with pytest.raises(DatasetError, match=r"missing.mat: no such file"):
        convert_dvs_barrel(tmp_path / "missing.mat", tmp_path / "out")


def test_verify_checks_that_events_tile_the_samples(dvs_dataset, tmp_path):
    copy = Path(shutil.copytree(dvs_dataset, tmp_path / dvs_dataset.name))
    with h5py.File(copy / "test.h5", "r+") as f:
        f["event_count"][0] += 1
    write_sums(copy)
    problems = "\n".join(verify(copy))
    assert "test.h5: 'event_start' and 'event_count' do not tile the" in problems


def test_cli_converts_and_the_dense_snn_benches_on_it(tmp_path, cli):
    """`simlidar convert dvs-barrel` then `simlidar bench --dataset` with the paper's DVS
    network (hidden layer narrowed): the path runs; accuracy is not the point."""

    mat = write_mat(tmp_path / "tiny.mat", fields=("x", "y", "p", "ts"))
    args = ["convert", "dvs-barrel", str(mat), "--out", str(tmp_path / "data"), "--json"]
    missing = cli(*args)
    assert missing.exit_code == 2 and "expected one character" in missing.output
    done = cli(*args, "--labels", "AABB7")
    assert done.exit_code == 0, done.output
    path = json.loads(done.output)["path"]
    snn = tmp_path / "snn_small.toml"
    snn.write_text(
        'model = "snn"\n[architecture]\nhidden = [20]\n[training]\n'
        'optimizer = "adam"\nlr = 1e-3\nbatch_size = 2\nepochs = 1\n'
    )
    bench = cli(
        "bench",
        "--models",
        str(snn),
        "--dataset",
        path,
        "--out",
        str(tmp_path / "b"),
        "--validation",
        "0",
        "--json",
    )
    assert bench.exit_code == 0, bench.output
    (cell,) = json.loads(bench.stdout)["cells"]
    assert cell["source"] == "dvs-barrel" and cell["input_shape"] == [1, 32, 32]
    assert cell["early"]["accuracy"] == pytest.approx(cell["accuracy"])  # event-driven runs
    assert cell["early"]["decision_time_ns_mean"] is None  # not a time-of-flight dataset
