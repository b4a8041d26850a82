"""`train` and `bench --dataset` refuse a dataset that `verify` rejects, in one line, before
any training: broken values, shapes, labels, swapped files, checksums and cards."""

import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from simlidar.cli import main


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
def test_train_and_bench_refuse_a_broken_dataset_before_training(case, datasets, tmp_path):
    corrupt, message = CASES[case]
    broken = tmp_path / "broken"
    shutil.copytree(datasets[0.1], broken)
    corrupt(broken)
    runner = CliRunner()
    result = runner.invoke(
        main, ["train", "--model", "mlp", "--dataset", str(broken), "--out", str(tmp_path / "runs")]
    )
    assert result.exit_code == 1, result.output
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "expected a dataset that simlidar verify accepts" in result.stderr
    assert not (tmp_path / "runs").exists()  # refused before anything was trained or written
    bench = runner.invoke(
        main,
        [
            "bench",
            "--suite",
            "quick",
            "--models",
            "mlp",
            "--dataset",
            str(broken),
            "--out",
            str(tmp_path / "bench"),
        ],
    )
    assert bench.exit_code == 1 and message in bench.stderr
    assert not (tmp_path / "bench").exists()


def test_a_failed_bench_claim_is_undone(tmp_path, monkeypatch, datasets):
    import errno

    from simlidar.bench import run
    from simlidar.bench.suite import load_suite

    calls = {"n": 0}
    original = run._write_json

    def full(path, data, indent=1):
        calls["n"] += 1
        if calls["n"] == 1:
            (path.parent / f".{path.name}.partial").write_text("")
            raise OSError(errno.ENOSPC, "No space left on device")
        return original(path, data, indent)

    monkeypatch.setattr(run, "_write_json", full)
    suite = load_suite("quick")
    out = tmp_path / "bench"
    with pytest.raises(OSError):
        run.claim(out, suite)
    assert not out.exists()  # undone
    out.mkdir()
    (out / "cells").mkdir()  # what an older simlidar left behind
    run.claim(out, suite)  # the rerun claims it
    assert (out / "suite.json").is_file()
