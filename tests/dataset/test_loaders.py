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
