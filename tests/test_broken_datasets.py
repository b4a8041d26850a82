"""`train` and `bench --dataset` refuse a dataset that `verify` rejects, in one line, before
any training: broken values, shapes, labels, swapped files, checksums and cards.

Attack list of the attribute fuzz (`test_every_parsed_attribute_...`): every attribute a reader
parses (`ATTRIBUTES` in simlidar/dataset/schema.py, listed again here by hand so that a rule
dropped there is caught), set in train.h5 to a value of the wrong type, a 2-D array, a string
that is not JSON, a huge float, the largest uint64, a negative number, NaN, an HDF5 empty
(null) value and opaque bytes that are not UTF-8, and every attribute a split must carry
deleted; SHA256SUMS is rewritten so that the attribute is the only problem. Each of `verify`,
`info`, `card`, `preview`, `train` (and `bench --dataset`, once an attribute) must exit non-zero
with one line naming the attribute, never a traceback, and write nothing.
"""

import shutil

import h5py
import numpy as np
import pytest

from simlidar.dataset.schema import ATTRIBUTES, REQUIRED_ATTRS, SOURCE_ATTRS
from simlidar.release.checksums import write_sums


def _replace(path, name, values):
    with h5py.File(path, "a") as f:
        del f[name]
        f.create_dataset(name, data=values)


def _nan_delays(d):
    with h5py.File(d / "train.h5", "a") as f:
        x = f["delays"][:]
        x[0, 0, 0] = np.nan
        f["delays"][:] = x


def _short_labels(d):
    with h5py.File(d / "train.h5", "a") as f:
        labels = f["labels"][:10]
    _replace(d / "train.h5", "labels", labels)


def _swapped(d):
    (d / "train.h5").rename(d / "tmp.h5")
    (d / "test.h5").rename(d / "train.h5")
    (d / "tmp.h5").rename(d / "test.h5")


def _label(value):
    def corrupt(d):
        with h5py.File(d / "train.h5", "a") as f:
            labels = f["labels"][:]
            labels[3] = value
            f["labels"][:] = labels

    return corrupt


def _short_class_names(d):
    with h5py.File(d / "train.h5", "a") as f:
        f.attrs["class_names"] = np.array(
            list(f.attrs["class_names"])[:30], dtype=h5py.string_dtype()
        )


def _float64_delays(d):
    with h5py.File(d / "train.h5", "a") as f:
        x = f["delays"][:].astype(np.float64)
    _replace(d / "train.h5", "delays", x)


def _card_edited(d):
    card = d / "README.md"
    card.write_text(card.read_text().replace("tunnel", "tunnnel", 1))


CASES = {
    "nan": (_nan_delays, "values outside [0, 1] or NaN"),
    "short labels": (_short_labels, "has shape (96, 16, 16), expected (10, 16, 16)"),
    "swapped": (_swapped, "holds the 'test' split, expected 'train'"),
    "label 99": (_label(99), "labels outside 0..31"),
    "label -1": (_label(-1), "labels outside 0..31"),
    "class names": (_short_class_names, "30 class_names for 32 classes"),
    "float64": (_float64_delays, "'delays' is float64, expected float32"),
    "card": (_card_edited, "README.md"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_train_and_bench_refuse_a_broken_dataset_before_training(case, datasets, tmp_path, cli):
    corrupt, message = CASES[case]
    broken = tmp_path / "broken"
    shutil.copytree(datasets[0.1], broken)
    corrupt(broken)
    result = cli(
        "train", "--model", "mlp", "--dataset", str(broken), "--out", str(tmp_path / "runs")
    )
    assert result.exit_code == 1, result.output
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "expected a dataset that simlidar verify accepts" in result.stderr
    assert not (tmp_path / "runs").exists()  # refused before anything was trained or written
    bench = cli(
        "bench",
        "--suite",
        "quick",
        "--models",
        "mlp",
        "--dataset",
        str(broken),
        "--out",
        str(tmp_path / "bench"),
    )
    assert bench.exit_code == 1 and message in bench.stderr
    assert not (tmp_path / "bench").exists()


def test_a_failed_bench_claim_is_undone(tmp_path, monkeypatch, datasets):
    import errno

    from simlidar.bench import outdir
    from simlidar.bench.suite import load_suite

    calls = {"n": 0}
    original = outdir.write_json

    def full(path, data, indent=1):
        calls["n"] += 1
        if calls["n"] == 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return original(path, data, indent)

    monkeypatch.setattr(outdir, "write_json", full)
    suite = load_suite("quick")
    out = tmp_path / "bench"
    with pytest.raises(OSError):
        outdir.claim(out, suite)
    assert not out.exists()  # undone
    out.mkdir()
    (out / "cells").mkdir()  # what an older simlidar left behind
    (out / ".suite.json.partial").write_text("")  # and its fixed-name temporary
    # a claim killed while writing suite.json: its temporary folder and lock (not held)
    (out / ".suite.json.partial-k1ll3d").mkdir()
    (out / ".suite.json.partial-k1ll3d" / "suite.json").write_text("{")
    (out / ".suite.json.partial-k1ll3d.lock").write_text("")
    outdir.claim(out, suite)  # the rerun claims it
    assert sorted(p.name for p in out.iterdir()) == ["cells", "suite.json"]


# Every attribute a reader parses, by hand (the test of the rules' table, not a copy of it);
# TEXT: those a string is right for, whatever it holds
PARSED = {
    "dataset_version", "simlidar_version", "source", "split", "config", "seed", "noise",
    "classes", "class_mode", "class_names", "layout_names", "object_names", "surface_names",
    "sensor", "catalog", "catalog_sha256", "row_laser_ids", "row_elevation_deg",
    "column_azimuth_deg", "tof_max_ns", "delay_unit_ns", "time_window_us", "no_return_delay",
    "min_object_hits", "profile", "noise_on", "input_spikes", "timing", "shard", "shards",
    "input_sha256", "simulated_from", "frames_without_objects", "receiver", "receiver_sha256",
    "materials", "materials_sha256", "return_mode", "beam_samples", "waveform_bin_ns",
    "waveform_bins", "motion", "motion_sha256", "rotations", "rotation_us", "span_us",
    "scenario_names", "scenarios",
}  # fmt: skip
TEXT = {"simlidar_version", "class_mode", "catalog_sha256", "profile", "input_sha256",
        "receiver_sha256", "materials_sha256", "motion_sha256"}  # fmt: skip
NUMBERS = {"seed", "noise", "classes", "tof_max_ns", "delay_unit_ns", "time_window_us",
           "no_return_delay", "min_object_hits", "shard", "shards", "beam_samples",
           "waveform_bin_ns", "waveform_bins", "rotations", "rotation_us", "span_us"}  # fmt: skip
HOSTILE = {
    "wrong type": lambda name: "seven" if name in NUMBERS else 7,
    "2-D": lambda name: np.zeros((2, 3)),
    "not JSON": lambda name: "{not json",
    "huge": lambda name: np.float64(1e308),
    "huge integer": lambda name: np.uint64(2**64 - 1),
    "negative": lambda name: np.int64(-1),
    "NaN": lambda name: np.float64("nan"),
    "empty": lambda name: h5py.Empty("f8"),
    "not UTF-8": lambda name: np.void(b"\xff\xfe"),
}


def test_the_fuzz_covers_every_rule():
    assert set(ATTRIBUTES) == PARSED


def _one_line(result, name):
    assert "Traceback" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(
        result.exception
    )
    assert result.exit_code == 1, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and f"'{name}'" in lines[0], lines


@pytest.mark.parametrize("name", sorted(PARSED))
def test_every_parsed_attribute_refused_in_one_line_by_every_reading_command(
    name, datasets, tmp_path, cli
):
    copy = tmp_path / "d"
    shutil.copytree(datasets[0.1], copy)
    cases = {k: v for k, v in HOSTILE.items() if not (k == "not JSON" and name in TEXT)}
    if name in REQUIRED_ATTRS or name in SOURCE_ATTRS["simlidar-generator"]:
        cases["missing"] = None
    before = sorted(p.name for p in copy.iterdir())
    for number, (case, make) in enumerate(cases.items()):
        with h5py.File(copy / "train.h5", "a") as f:
            if name in f.attrs:
                del f.attrs[name]
            if make is not None:
                f.attrs[name] = make(name)
        write_sums(copy, ["train.h5"])  # the attribute is the only problem
        result = cli("verify", str(copy))
        assert "Traceback" not in result.output and result.exit_code == 1, (case, result.output)
        assert isinstance(result.exception, SystemExit), (case, repr(result.exception))
        failed = [line for line in result.stderr.splitlines() if line.startswith("FAILED")]
        assert any(f"'{name}'" in line for line in failed), (case, result.output)
        for command in (
            ["info", str(copy)],
            ["card", str(copy)],
            ["preview", str(copy), "--out", str(tmp_path / "p.png")],
            ["train", "--model", "mlp", "--dataset", str(copy), "--out", str(tmp_path / "r")],
            ["bench", "--models", "mlp", "--dataset", str(copy), "--out", str(tmp_path / "b")],
        )[: 4 + (number == 0)]:
            _one_line(cli(*command), name)
        assert sorted(p.name for p in copy.iterdir()) == before, case
        assert not any((tmp_path / n).exists() for n in ("p.png", "r", "b")), case
