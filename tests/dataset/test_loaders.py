import numpy as np
import pytest

from simlidar.dataset.loaders import load_split
from simlidar.errors import DatasetError


def test_load_split_matches_the_file(datasets):
    import h5py

    x, y = load_split(datasets[0.5], "test")
    clean, _ = load_split(datasets[0.5], "test", field="clean_delays")
    with h5py.File(datasets[0.5] / "test.h5") as f:
        np.testing.assert_array_equal(x, f["delays"][:])
        np.testing.assert_array_equal(y, f["labels"][:])
    assert (x >= clean).all()


def test_pulse_dataset_is_a_torch_dataset(datasets):
    import torch

    from simlidar.dataset.loaders import PulseDataset

    ds = PulseDataset(datasets[0.1], "test")
    assert isinstance(ds, torch.utils.data.Dataset)
    x, label = ds[5]
    assert x.dtype == torch.float32 and x.shape == (16, 16) and label == 5
    with pytest.raises(IndexError):
        ds[64]
    # workers open their own handles; every sample arrives once
    loader = torch.utils.data.DataLoader(ds, batch_size=10, num_workers=2)
    labels = torch.cat([b for _, b in loader])
    assert sorted(labels.tolist()) == sorted(load_split(datasets[0.1], "test")[1].tolist())


def test_bad_paths_and_splits(tmp_path, datasets):
    with pytest.raises(DatasetError, match="split 'val': expected 'train' or 'test'"):
        load_split(datasets[0.1], "val")
    with pytest.raises(DatasetError, match="expected a dataset directory with train.h5"):
        load_split(tmp_path, "train")


# Issue 61, item 7: PulseDataset reads a split into memory, or a chunk at a time, and returns
# what it returned when it read a row at a time: load_split's values, byte for byte.


@pytest.fixture
def small_chunks(monkeypatch):
    """The chunk-cache path forced on the small datasets: a memory budget of 0 bytes, blocks
    of 16 rows (the files' chunks are larger: any block reads the same values) and 2 of them
    kept, so that a shuffled epoch evicts."""
    from simlidar.dataset import loaders

    monkeypatch.setattr(loaders, "MEMORY_BUDGET", 0)
    monkeypatch.setattr(loaders, "CHUNK_SAMPLES", 16)
    monkeypatch.setattr(loaders, "CACHE_CHUNKS", 2)


def _same_as_load_split(ds, path, split, order, field="delays"):
    """``ds[i]`` for each i of ``order`` is load_split's sample i: float32 of the same bytes,
    and the label as an int."""
    x, y = load_split(path, split, field=field)
    for i in order:
        sample, label = ds[int(i)]
        assert sample.dtype == torch_float32() and sample.shape == x.shape[1:]
        assert sample.numpy().tobytes() == x[i].tobytes(), i
        assert type(label) is int and label == y[i], i


def torch_float32():
    import torch

    return torch.float32


def _orders(n):
    return [range(n), np.random.default_rng(0).permutation(n), range(-1, -n - 1, -1)]


@pytest.mark.parametrize("path", ["one file", "shards"])
@pytest.mark.parametrize("way", ["in memory", "chunk cache"])
def test_pulse_dataset_returns_what_load_split_does(path, way, datasets, sharded, request):
    from simlidar.dataset.loaders import PulseDataset

    if way == "chunk cache":
        request.getfixturevalue("small_chunks")
    path = datasets[0.1] if path == "one file" else sharded
    for split, field in (("train", "delays"), ("test", "delays"), ("test", "clean_delays")):
        ds = PulseDataset(path, split, field=field)
        assert not ds._blocks and ds._h5 is None  # nothing read when made
        for order in _orders(len(ds)):
            _same_as_load_split(ds, path, split, order, field)
        files = len(ds.files)
        if way == "in memory":  # each file read once, whole
            held = {part: len(arrays["labels"]) for (part, _), (arrays, _) in ds._blocks.items()}
            assert ds._whole and held == dict(enumerate(ds.info.sizes)) and len(held) == files
        else:
            assert not ds._whole and len(ds._blocks) <= 2
            assert all(len(arrays["labels"]) <= 16 for arrays, _ in ds._blocks.values())


def test_the_budget_is_the_datasets_own(datasets, monkeypatch):
    """``memory_budget`` is MEMORY_BUDGET when the dataset is made; a split over it reads
    chunks, one within it is read whole."""
    from simlidar.dataset import loaders

    ds = loaders.PulseDataset(datasets[0.1], "train")
    assert ds.memory_budget == loaders.MEMORY_BUDGET == 512 * 2**20
    split_bytes = 96 * (16 * 16 * 4 + 8)
    ds.memory_budget = split_bytes - 1
    ds[0]
    assert not ds._whole
    monkeypatch.setattr(loaders, "MEMORY_BUDGET", split_bytes)
    ds = loaders.PulseDataset(datasets[0.1], "train")
    ds[0]
    assert ds.memory_budget == split_bytes and ds._whole


@pytest.mark.parametrize("way", ["in memory", "chunk cache"])
def test_a_data_loader_gets_the_same_batches(way, sharded, request):
    """Shuffled batches of 64 through a DataLoader, with worker processes forked after the
    parent read (they take its blocks, and open their own files); the dataset pickles without
    its blocks and handles."""
    import pickle

    import torch

    from simlidar.dataset.loaders import PulseDataset

    if way == "chunk cache":
        request.getfixturevalue("small_chunks")
    x, y = load_split(sharded, "train")
    ds = PulseDataset(sharded, "train")
    ds[50]
    restored = pickle.loads(pickle.dumps(ds))
    assert not restored._blocks and restored._h5 is None and restored.classes == ds.classes
    assert len(pickle.dumps(ds)) < x.nbytes // 4
    order = np.random.default_rng(1).permutation(len(x))
    for workers in (0, 2):
        loader = torch.utils.data.DataLoader(
            ds, batch_size=64, sampler=order.tolist(), num_workers=workers
        )
        batches = list(loader)
        assert [len(b) for _, b in batches] == [64, 32]
        got = torch.cat([b for b, _ in batches]).numpy()
        assert got.tobytes() == x[order].tobytes()
        assert torch.cat([b for _, b in batches]).tolist() == y[order].tolist()


def test_a_sample_is_a_copy(datasets):
    """A transform that changes its tensor in place changes nothing the dataset holds."""
    from simlidar.dataset.loaders import PulseDataset

    ds = PulseDataset(datasets[0.1], "train", transform=lambda t: t.fill_(7.0))
    assert (ds[3][0] == 7.0).all()
    x, _ = load_split(datasets[0.1], "train")
    assert PulseDataset(datasets[0.1], "train")[3][0].numpy().tobytes() == x[3].tobytes()
    ds.transform = None
    assert ds[3][0].numpy().tobytes() == x[3].tobytes()


def test_pulse_and_event_datasets_have_the_class_names(datasets, sharded):
    """``classes``: the split's class names in label order, one spelling (the stored one)."""
    import h5py

    from simlidar.dataset.loaders import EventDataset, PulseDataset

    with h5py.File(datasets[0.1] / "train.h5") as f:
        stored = [str(name) for name in f.attrs["class_names"]]
    for path in (datasets[0.1], sharded):
        pulses, events = PulseDataset(path, "test"), EventDataset(path, "test")
        assert pulses.classes == events.classes == stored
    assert len(stored) == 32 and stored[5] == "open_road/car"  # docs/dataset-format.md
    assert all(isinstance(name, str) for name in pulses.classes)


@pytest.mark.parametrize("way", ["in memory", "chunk cache"])
@pytest.mark.parametrize(
    "row, value, message",
    [
        (70, 7.0, "'delays' has values outside [0, 1] or NaN"),
        (70, np.nan, "'delays' has values outside [0, 1] or NaN"),
        (5, None, "labels outside 0..31"),
    ],
)
def test_a_hostile_value_is_still_refused(way, row, value, message, datasets, tmp_path, request):
    """A block holding a bad value is checked sample by sample: its other samples read, the
    bad one is refused in one line naming its file and row, every time it is asked for."""
    import shutil

    import h5py

    from simlidar.dataset.loaders import PulseDataset
    from simlidar.errors import DatasetError

    if way == "chunk cache":
        request.getfixturevalue("small_chunks")
    copy = tmp_path / "d"
    shutil.copytree(datasets[0.1], copy)
    with h5py.File(copy / "train.h5", "a") as f:
        if value is None:
            labels = f["labels"][:]
            labels[row] = 32
            f["labels"][:] = labels
        else:
            delays = f["delays"][:]
            delays[row, 3, 4] = value
            f["delays"][:] = delays
    x, y = load_split(datasets[0.1], "train")
    ds = PulseDataset(copy, "train")
    for i in (row - 1, row + 1, 0, 95):
        sample, label = ds[i]
        assert sample.numpy().tobytes() == x[i].tobytes() and label == y[i]
    for _ in range(2):
        with pytest.raises(DatasetError) as caught:
            ds[row]
        text = str(caught.value)
        assert message in text and f"train.h5 (sample {row})" in text and "\n" not in text


def test_a_split_the_memory_cannot_hold_reads_by_chunks(datasets, monkeypatch):
    """Within the budget but over the memory this process has left (resources.py's
    available_memory), the split is read by chunks; where even the cache does not fit, a
    ResourceError in one line, before anything is read."""
    from simlidar import resources
    from simlidar.dataset import loaders
    from simlidar.errors import ResourceError

    x, y = load_split(datasets[0.1], "train")
    monkeypatch.setattr(loaders, "CHUNK_SAMPLES", 16)
    monkeypatch.setattr(loaders, "CACHE_CHUNKS", 2)  # 2 x 16 x 1032 = 33,024 bytes
    for module in (resources, loaders):
        monkeypatch.setattr(module, "available_memory", lambda: 50_000)  # the split: 99,072
    ds = loaders.PulseDataset(datasets[0.1], "train")
    for i in np.random.default_rng(2).permutation(96):
        sample, label = ds[i]
        assert sample.numpy().tobytes() == x[i].tobytes() and label == y[i]
    assert not ds._whole and len(ds._blocks) == 2
    for module in (resources, loaders):
        monkeypatch.setattr(module, "available_memory", lambda: 20_000)
    ds = loaders.PulseDataset(datasets[0.1], "train")
    with pytest.raises(ResourceError) as caught:
        ds[0]
    text = str(caught.value)
    assert "train.h5: 2 chunks of 16 rows of ['delays', 'labels']: 32.2 KiB to hold" in text
    assert "19.5 KiB available" in text and "\n" not in text and not ds._blocks
