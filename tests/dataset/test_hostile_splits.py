"""Issue 58, findings 3 and 4: every object of a split file is checked, not only its root's
members, and the loaders check what they return as ``train`` and ``verify`` do (one checked
reader for every consumer); attributes that contradict the data are refused.

Each hostile file is a copy of a small generated dataset changed by the test, its card and
SHA256SUMS made to agree (``agreeing``), so that the change is the only problem. Each consumer
(verify, pack, load_split, PulseDataset, EventDataset, card) must refuse it in one line, and
pack must write nothing.
"""

import json
import shutil

import h5py
import numpy as np
import pytest

from simlidar.dataset.loaders import EventDataset, PulseDataset, load_split
from simlidar.dataset.storage import MAX_LINKS
from simlidar.errors import DatasetError
from simlidar.sensor.model import load_sensor


def _in_group(make):
    def change(f):
        make(f.create_group("extra"))

    return change


def _external(group):
    group.create_dataset("leak", shape=(100,), dtype="u1", external=[("/etc/hostname", 0, 100)])


def _virtual(group):
    layout = h5py.VirtualLayout(shape=(10,), dtype="f4")
    layout[:] = h5py.VirtualSource("/tmp/elsewhere.h5", "x", shape=(10,))
    group.create_virtual_dataset("mapped", layout)


def _external_link(group):
    group["elsewhere"] = h5py.ExternalLink("/etc/hostname", "/x")


def _soft_link(group):
    group["again"] = h5py.SoftLink("/delays")


def _unbacked(group):
    group.create_dataset("bomb", shape=(2**34,), dtype="u1", chunks=(2**20,), compression="gzip")


def _hard_link(f):
    del f["clean_delays"]
    f["clean_delays"] = f["delays"]  # the noisy inputs passed off as the clean ones


def _many_groups(f):
    for index in range(MAX_LINKS + 1):
        f.create_group(f"g{index}")


STRUCTURE = {
    "external storage in a group": (
        _in_group(_external),
        "'extra/leak' is stored in the external file '/etc/hostname'",
    ),
    "virtual dataset in a group": (_in_group(_virtual), "'extra/mapped' is an HDF5 virtual"),
    "external link in a group": (
        _in_group(_external_link),
        "'extra/elsewhere' is an HDF5 ExternalLink",
    ),
    "soft link in a group": (_in_group(_soft_link), "'extra/again' is an HDF5 SoftLink"),
    "unbacked dataset in a group": (
        _in_group(_unbacked),
        "'extra/bomb' declares (17179869184,) uint8 (16.0 GiB) but stores 0 B",
    ),
    "a field hard-linked to another": (
        _hard_link,
        "is one object under 2 names (an HDF5 hard link)",
    ),
    "too many links": (_many_groups, f"more than {MAX_LINKS} HDF5 links"),
}


@pytest.fixture
def hostile(datasets, tmp_path, agreeing):
    """``hostile(change)``: a copy of the noise-0.1 dataset whose train.h5 ``change(f)`` has
    altered (f: the file open for writing), its card and sums agreeing."""

    def make(change):
        copy = tmp_path / "d"
        shutil.copytree(datasets[0.1], copy)
        with h5py.File(copy / "train.h5", "a") as f:
            change(f)
        agreeing(copy)
        return copy

    return make


def _one_line(result, message):
    assert result.exit_code == 1, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert "Traceback" not in result.output


def _loaders_refuse(path, message):
    for load in (
        lambda: load_split(path, "train"),
        lambda: PulseDataset(path, "train"),
        lambda: EventDataset(path, "train"),
    ):
        with pytest.raises(DatasetError, match=None) as caught:
            load()
        assert message in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize("case", list(STRUCTURE))
def test_every_object_of_a_split_file_is_checked(case, hostile, tmp_path, cli):
    change, message = STRUCTURE[case]
    copy = hostile(change)
    verified = cli("verify", copy)
    assert verified.exit_code == 1 and message in verified.output, verified.output
    packed = cli("pack", copy, "--out", tmp_path / "packed")
    _one_line(packed, message)
    assert not (tmp_path / "packed").exists() or not any((tmp_path / "packed").iterdir())
    _loaders_refuse(copy, message)


def _label_at(row, value):
    def change(f):
        labels = f["labels"][:]
        labels[row] = value
        f["labels"][:] = labels

    return change


def _delay_at(row, value):
    def change(f):
        delays = f["delays"][:]
        delays[row, 0, 0] = value
        f["delays"][:] = delays

    return change


@pytest.mark.parametrize(
    "change, message",
    [
        (_label_at(3, 10**12), "labels outside 0..31"),
        (_label_at(3, -1), "labels outside 0..31"),
        (_delay_at(3, np.nan), "'delays' has values outside [0, 1] or NaN"),
        (_delay_at(3, 7.0), "'delays' has values outside [0, 1] or NaN"),
    ],
)
def test_the_loaders_check_the_values_they_return(change, message, hostile, cli):
    copy = hostile(change)
    assert message in cli("verify", copy).output
    with pytest.raises(DatasetError, match=r"labels|delays") as caught:
        load_split(copy, "train")
    assert message in str(caught.value)
    for dataset in (PulseDataset(copy, "train"), EventDataset(copy, "train")):
        dataset[2]  # a sound sample reads as before
        with pytest.raises(DatasetError) as caught:
            dataset[3]
        assert message in str(caught.value) and "(sample 3)" in str(caught.value)


def _replaced(name, convert):
    def change(f):
        values = convert(f[name][:])
        del f[name]
        f.create_dataset(name, data=values)

    return change


def _compound(labels):
    values = np.zeros(len(labels), dtype=[("a", "<i8"), ("b", "<i8")])
    values["a"] = labels
    return values


DTYPES = {
    "narrow clean delays": (
        _replaced("clean_delays", lambda x: x.astype(np.float16)),
        "'clean_delays' is float16, expected float32",
    ),
    "compound labels": (_replaced("labels", _compound), "'labels' is [('a', '<i8'), ('b', '<i8')]"),
    "a field of another shape": (
        _replaced("surface", lambda x: x[:, :8]),
        "'surface' has shape (96, 8, 16), expected (96, 16, 16)",
    ),
}


@pytest.mark.parametrize("case", list(DTYPES))
def test_the_loaders_refuse_a_field_that_is_not_the_schemas(case, hostile, cli):
    change, message = DTYPES[case]
    copy = hostile(change)
    assert message in cli("verify", copy).output
    _loaders_refuse(copy, message)


def _attribute(name, value):
    def change(f):
        f.attrs[name] = value

    return change


def _sensor(**changes):
    def change(f):
        sensor = json.loads(f.attrs["sensor"]) | changes
        f.attrs["sensor"] = json.dumps(sensor)

    return change


HDL64E = {k: v for k, v in load_sensor("hdl64e").to_dict().items() if k != "name"}
CONTRADICTIONS = {
    "a sensor of 64 beams over 16 rows": (
        _sensor(**HDL64E),
        "attribute 'sensor' has 64 beams, but the samples have 16 rows",
    ),
    "a row more than the rows": (
        _attribute("row_laser_ids", np.arange(17, dtype=np.int32)),
        "attribute 'row_laser_ids' holds 17 values for the samples' 16 rows",
    ),
    "a laser the sensor lacks": (
        _attribute("row_laser_ids", np.arange(1, 17, dtype=np.int32)),
        "attribute 'row_laser_ids' is [1, 2,",
    ),
    "columns fewer than the columns": (
        _attribute("column_azimuth_deg", np.zeros(5)),
        "attribute 'column_azimuth_deg' holds 5 values for the samples' 16 columns",
    ),
    "a path for a sensor name": (_sensor(name="../../etc/passwd"), "'../../etc/passwd'"),
    "a catalog without layouts": (
        _attribute("catalog", json.dumps({"objects": {}})),
        "attribute 'catalog' has layouts.'tunnel' = None",
    ),
    "a catalog of the wrong shape": (
        _attribute("catalog", json.dumps({"layouts": [1], "objects": 7})),
        "attribute 'catalog' has layouts.'tunnel' = None",
    ),
}


@pytest.mark.parametrize("case", list(CONTRADICTIONS))
def test_attributes_that_contradict_the_data_are_refused(case, hostile, cli):
    change, message = CONTRADICTIONS[case]
    copy = hostile(change)
    assert message in cli("verify", copy).output
    card = copy / "README.md"
    before = card.read_bytes()
    _one_line(cli("card", copy), message)
    assert card.read_bytes() == before  # nothing rewritten
    _loaders_refuse(copy, message)


def test_a_sound_dataset_still_reads(datasets):
    """The checks refuse none of what the generator writes, and change nothing read."""
    path = datasets[0.1]
    x, y = load_split(path, "train")
    assert x.shape == (96, 16, 16) and y.shape == (96,)
    with h5py.File(path / "train.h5", "r") as f:
        np.testing.assert_array_equal(x, f["delays"][:])
    sample, label = PulseDataset(path, "train")[5]
    assert label == int(y[5]) and np.array_equal(sample.numpy(), x[5])
