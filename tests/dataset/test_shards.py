"""Sharded splits (issue "Scale out"): names, writing, reading, checking and publishing.

Attack list (issue 35, item 3): a split file named ``train-00000-of-9999999999.h5`` (a count
of ten billion shards from a file name) must not make ``verify``, ``info`` or ``card`` build a
list per claimed shard: each is run as a real process under a 2 GiB address-space limit and
must end in a few seconds with one line naming the missing shards; a count or index of more
digits than a number holds is not a shard name.
"""

import json
import shutil

import h5py
import numpy as np
import pytest

from simlidar.data import PulseDataset, load_split, split_files, split_path
from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.schema import SCHEMA
from simlidar.dataset.shards import (
    find_split_files,
    shard_bounds,
    shard_name,
    shard_of,
    split_file_names,
    split_of,
)
from simlidar.errors import DatasetError
from simlidar.generator.generate import generate
from simlidar.release.card import read_front_matter
from simlidar.release.checksums import read_sums
from simlidar.release.info import dataset_info
from simlidar.release.verify import verify

TRAIN = ["train-00000-of-00003.h5", "train-00001-of-00003.h5", "train-00002-of-00003.h5"]
TEST = ["test-00000-of-00002.h5", "test-00001-of-00002.h5"]


def test_names_and_bounds():
    assert shard_name("train", 3, 16) == "train-00003-of-00016.h5"
    assert shard_bounds(96, 40) == [(0, 40), (40, 80), (80, 96)]
    assert shard_bounds(40, 40) == [(0, 40)]  # at most one shard's worth: one file
    assert split_file_names("train", 96, 40) == TRAIN
    assert split_file_names("test", 64, 64) == ["test.h5"]
    assert shard_of("train-00002-of-00003.h5") == ("train", 2, 3)
    assert shard_of("train.h5") is None and shard_of("train-2-of-3.h5") is None
    assert [split_of(n) for n in ("train.h5", TEST[1], "README.md", "x.h5")] == [
        "train",
        "test",
        None,
        None,
    ]
    with pytest.raises(DatasetError, match="shard size 0: expected a number of samples >= 1"):
        shard_bounds(10, 0)


def test_the_shards_hold_the_one_file_datasets_rows(sharded, datasets):
    names = sorted(p.name for p in sharded.iterdir())
    assert names == sorted(
        ["README.md", "SHA256SUMS", "croissant.json", "preview.png"] + TRAIN + TEST
    )
    one = datasets[0.1]
    for split, files in (("train", TRAIN), ("test", TEST)):
        with h5py.File(one / f"{split}.h5") as whole:
            start = 0
            for index, name in enumerate(files):
                with h5py.File(sharded / name) as part:
                    assert (part.attrs["shard"], part.attrs["shards"]) == (index, len(files))
                    rows = part["labels"].shape[0]
                    for field in SCHEMA:
                        assert (
                            part[field][:].tobytes() == whole[field][start : start + rows].tobytes()
                        )
                    own = {k for k in part.attrs} - {"shard", "shards"}
                    assert own == set(whole.attrs)
                    assert all(np.array_equal(part.attrs[k], whole.attrs[k]) for k in whole.attrs)
                start += rows
            assert start == whole["labels"].shape[0]


def test_the_same_bytes_for_every_worker_count_and_batch_size(
    sharded, catalog, small_config, tmp_path
):
    (again,) = generate(
        small_config, [0.1], catalog, tmp_path, batch_size=7, progress=False, shard_samples=40
    )
    assert read_sums(again.path) == read_sums(sharded)
    for name in TRAIN + TEST + ["README.md", "croissant.json", "SHA256SUMS"]:
        assert (again.path / name).read_bytes() == (sharded / name).read_bytes(), name


def test_a_split_no_larger_than_the_shard_size_is_one_file_as_before(
    datasets, catalog, small_config, tmp_path
):
    (same,) = generate(
        small_config, [0.1], catalog, tmp_path, batch_size=40, progress=False, shard_samples=96
    )
    for name in ("train.h5", "test.h5", "README.md", "croissant.json", "SHA256SUMS"):
        assert (same.path / name).read_bytes() == (datasets[0.1] / name).read_bytes(), name


def test_loaders_read_the_shards_in_order(sharded, datasets):
    for split in ("train", "test"):
        x, y = load_split(sharded, split)
        x1, y1 = load_split(datasets[0.1], split)
        assert np.array_equal(x, x1) and np.array_equal(y, y1)
    assert [p.name for p in split_files(sharded, "train")] == TRAIN
    assert [p.name for p in split_files(datasets[0.1], "train")] == ["train.h5"]
    with pytest.raises(DatasetError, match="the train split is 3 shard files; expected one file"):
        split_path(sharded, "train")
    shards, whole = PulseDataset(sharded, "train"), PulseDataset(datasets[0.1], "train")
    assert len(shards) == len(whole) == 96
    for index in (0, 39, 40, 79, 80, 95, -1, -57):
        (a, la), (b, lb) = shards[index], whole[index]
        assert la == lb and np.array_equal(a.numpy(), b.numpy()), index
    with pytest.raises(IndexError):
        shards[96]


def test_a_data_loader_with_workers_reads_every_shard(sharded):
    import torch

    loader = torch.utils.data.DataLoader(
        PulseDataset(sharded, "test"), batch_size=25, num_workers=2
    )
    labels = torch.cat([y for _, y in loader]).numpy()
    assert np.array_equal(labels, load_split(sharded, "test")[1])


def test_info_card_croissant_and_checksums_describe_the_shards(sharded, caplog):
    import mlcroissant as mlc

    info = dataset_info(sharded)
    assert info["splits"] == {"train": 96, "test": 64}
    assert sum(info["counts"]["train"].values()) == 96
    meta = read_front_matter(sharded)
    assert meta["configs"][0]["data_files"] == [
        {"split": "train", "path": "train-*.h5"},
        {"split": "test", "path": "test-*.h5"},
    ]
    sizes = {s["name"]: s for s in meta["dataset_info"]["splits"]}
    assert sizes["train"]["num_examples"] == 96
    assert sizes["train"]["num_bytes"] == sum((sharded / n).stat().st_size for n in TRAIN)
    card = (sharded / "README.md").read_text()
    assert (
        "the train split is 3 files, `train-00000-of-00003.h5` to `train-00002-of-00003.h5`" in card
    )
    assert "--shard-size 40" in card
    croissant = json.loads((sharded / "croissant.json").read_text())
    sets = {d["@id"]: d for d in croissant["distribution"]}
    assert sets["train-*.h5"]["@type"] == "cr:FileSet"
    assert sets["train-*.h5"]["includes"] == "train-*.h5"
    field = croissant["recordSet"][0]["field"][0]
    assert field["source"]["fileSet"] == {"@id": "train-*.h5"}
    dataset = mlc.Dataset(jsonld=sharded / "croissant.json")
    assert dataset.metadata.name == sharded.name
    assert not any("not standard" in r.getMessage() for r in caplog.records)
    assert set(TRAIN + TEST) <= set(read_sums(sharded))


def test_the_cards_command_writes_the_same_shards(sharded, tmp_path, cli):

    command = (sharded / "README.md").read_text().split("## Regenerate")[1].split("```\n")[1]
    args = command.split()[1:] + ["--out", str(tmp_path), "--workers", "2"]
    result = cli(*args)
    assert result.exit_code == 0, result.output
    assert read_sums(tmp_path / sharded.name) == read_sums(sharded)


def test_hugging_face_datasets_loads_sharded_and_one_file_splits(sharded, datasets):
    import datasets as hf  # a test dependency: the card's data_files must work with it

    for path in (sharded, datasets[0.1]):
        loaded = hf.load_dataset(str(path))
        for split in ("train", "test"):
            x, y = load_split(path, split)
            assert loaded[split].num_rows == len(y)
            assert np.array_equal(np.asarray(loaded[split]["labels"]), y)
        assert np.allclose(np.asarray(loaded["test"][-1]["delays"]), x[-1])


def test_a_sound_sharded_dataset_verifies(sharded):
    assert verify(sharded) == []


def _copy(sharded, tmp_path):
    copy = tmp_path / sharded.name
    shutil.copytree(sharded, copy)
    return copy


def test_a_missing_shard_is_named(sharded, tmp_path):
    copy = _copy(sharded, tmp_path)
    (copy / TRAIN[1]).unlink()
    problems = verify(copy)
    assert any(
        "train shards incomplete (missing train-00001-of-00003.h5); expected shards 0..2" in p
        for p in problems
    ), problems
    with pytest.raises(DatasetError, match="missing train-00001-of-00003.h5"):
        load_split(copy, "train")
    with pytest.raises(DatasetError, match="missing train-00001-of-00003.h5"):
        dataset_splits(copy)


def test_swapped_shards_are_named(sharded, tmp_path):
    copy = _copy(sharded, tmp_path)
    (copy / TRAIN[0]).rename(copy / "x")
    (copy / TRAIN[1]).rename(copy / TRAIN[0])
    (copy / "x").rename(copy / TRAIN[1])
    problems = verify(copy)
    assert any(
        p.endswith(
            f"{TRAIN[0]}: shard attributes shard=1, shards=3; expected shard=0, shards=3 "
            "(shard files renamed?)"
        )
        for p in problems
    ), problems
    with pytest.raises(DatasetError, match="shard=1, shards=3; expected 0 and 3"):
        load_split(copy, "train")


def test_shards_beside_a_one_file_split_are_refused(sharded, datasets, tmp_path):
    copy = _copy(sharded, tmp_path)
    shutil.copy(datasets[0.1] / "train.h5", copy / "train.h5")
    with pytest.raises(DatasetError, match="both train.h5 and 3 train shard files"):
        find_split_files(copy, "train")
    assert any("both train.h5 and 3 train shard files" in p for p in verify(copy))


def test_shards_of_two_counts_are_refused(sharded, tmp_path):
    copy = _copy(sharded, tmp_path)
    shutil.copy(copy / TRAIN[0], copy / "train-00000-of-00004.h5")
    with pytest.raises(DatasetError, match=r"train shards of different counts \(3, 4\)"):
        find_split_files(copy, "train")


def test_a_card_count_that_disagrees_is_named(sharded, tmp_path):
    copy = _copy(sharded, tmp_path)
    card = copy / "README.md"
    card.write_text(card.read_text().replace("num_examples: 96", "num_examples: 97"))
    problems = verify(copy)
    assert f"{copy / 'train-*.h5'} (3 shards): 96 samples, the card says 97" in problems


def test_a_failed_run_leaves_no_shard_behind(catalog, small_config, tmp_path, monkeypatch):
    import simlidar.generator.shard as shard

    calls = []
    real = shard.split_rows

    def failing(*args):
        calls.append(1)
        if len(calls) == 4:  # within the second train shard
            raise RuntimeError("disk gone")
        return real(*args)

    monkeypatch.setattr(shard, "split_rows", failing)
    with pytest.raises(RuntimeError, match="disk gone"):
        generate(
            small_config, [0.1], catalog, tmp_path, batch_size=16, progress=False, shard_samples=40
        )
    assert list(tmp_path.iterdir()) == []


def test_a_bad_shard_size_is_one_line(tmp_path, cli):

    result = cli("generate", "--shard-size", "0", "--out", str(tmp_path))
    assert result.exit_code == 2
    assert "Invalid value for '--shard-size': 0 is not in the range x>=1." in result.output
    assert list(tmp_path.iterdir()) == []


def test_a_shard_count_from_a_file_name_builds_no_list(datasets, tmp_path, limited_python):

    copy = tmp_path / "d"
    shutil.copytree(datasets[0.1], copy)
    (copy / "train.h5").rename(copy / "train-00000-of-9999999999.h5")
    for command in ("verify", "info", "card"):
        result = limited_python(["-m", "simlidar.cli", command, copy], 2 * 2**30, timeout=120)
        assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
        assert (
            f"{copy}: train shards incomplete (missing train-00001-of-9999999999.h5, "
            "train-00002-of-9999999999.h5, train-00003-of-9999999999.h5, ...); expected "
            "shards 0..9999999998"
        ) in result.stderr
    assert shard_of("train-" + "9" * 19 + "-of-" + "9" * 19 + ".h5") is None
    assert shard_of("train-" + "0" * 18 + "-of-" + "9" * 18 + ".h5") == ("train", 0, 10**18 - 1)
