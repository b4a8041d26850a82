"""Stored waveforms (issue 41, item 3: "on request, the received waveform"): the dataset
`waveform` holds each pulse's waveform as the receiver formed it, its records leave every other
field as the dataset without it has them, the same bytes whatever the batches and workers, and
verify, the card and load_split know it."""

import h5py
import numpy as np
import pytest

from simlidar.dataset.loaders import load_split
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.profiles import load_profile
from simlidar.sensor.receiver import load_receiver
from simlidar.sensor.waveform import pulse_sigma_ns

RECEIVER = load_receiver("vlp16")


@pytest.fixture(scope="module")
def made(tmp_path_factory, sensor_dataset):
    out = tmp_path_factory.mktemp("waveforms")
    return {
        "last": sensor_dataset(out / "a", return_mode="last"),
        "last, stored": sensor_dataset(out / "b", return_mode="last", waveform_bin_ns=1.0),
        "rain, stored": sensor_dataset(out / "c", rain_rate_mm_h=200.0, waveform_bin_ns=0.5),
    }


def test_the_waveform_is_a_field_added_to_the_same_records(made, read_split):
    plain, _ = read_split(made["last"])
    stored, attrs = read_split(made["last, stored"])
    assert made["last, stored"].name == "simlidar-32c-noise0.1-sensor-last-wave1.0-v5.0.0"
    assert set(stored) - set(plain) == {"waveform"}
    for name, values in plain.items():
        np.testing.assert_array_equal(stored[name], values, err_msg=name)
    # 0 to 667 ns (100 m) every 1 ns; one sample a chunk
    assert attrs["waveform_bin_ns"] == 1.0 and attrs["waveform_bins"] == 668
    assert stored["waveform"].shape == (64, 16, 16, 668)
    with h5py.File(made["last, stored"] / "train.h5") as f:
        assert f["waveform"].chunks == (1, 16, 16, 668) and f["waveform"].dtype == np.float32


def test_the_stored_waveform_is_the_one_the_returns_come_from(made, read_split):
    """A pulse's reported return lies on a peak of its stored waveform near the threshold or
    above (sampled within half a bin of the peak: at least exp(-0.5^2 / (2 sigma^2)) of it,
    less the bin's own noise, 4 sigma); the waveform carries the detector's noise in every bin:
    a pulse that hit nothing holds that noise alone, of mean 0 and the file's sigma_0."""
    rows, attrs = read_split(made["last, stored"])
    wave, tof = rows["waveform"], rows["returns_tof_ns"][..., 0]
    assert np.isfinite(wave).all()
    returned = ~np.isnan(tof)
    assert returned.sum() > 1000
    at = np.clip(np.round(tof[returned]).astype(int), 0, 667)
    near = np.take_along_axis(wave[returned], at[:, None], axis=1)[:, 0]
    sigma = pulse_sigma_ns(RECEIVER.pulse_width_ns)
    # the range noise moves a return by a few cm (0.7 ns at the threshold), the quantisation
    # by 2 mm
    floor = RECEIVER.threshold_w * np.exp(-((0.5 + 0.7) ** 2) / (2 * sigma**2))
    assert (near >= floor - 4 * RECEIVER.noise_w).mean() > 0.99
    nothing = np.isnan(rows["reflectance"])  # no hit within the sensor's range
    quiet = wave[nothing].astype(np.float64)
    assert nothing.any() and abs(quiet.mean()) < 0.01 * RECEIVER.noise_w
    assert quiet.std() == pytest.approx(RECEIVER.noise_w, rel=0.01)


def test_rain_and_a_finer_bin(made, read_split):
    rows, attrs = read_split(made["rain, stored"])
    assert attrs["waveform_bins"] == 1335 and attrs["waveform_bin_ns"] == 0.5
    drops = (rows["surface"] == 0) & ~np.isnan(rows["tof_ns"])
    assert drops.any()
    at = np.round(rows["tof_ns"][drops] / 0.5).astype(int)
    near = np.take_along_axis(rows["waveform"][drops], at[:, None], axis=1)[:, 0]
    # the drops' echoes are in the waveform (each bin with its own noise, the return its
    # jitter)
    assert (near > 0.5 * RECEIVER.threshold_w).mean() > 0.95


def test_the_same_bytes_whatever_the_batches_and_workers(
    made, tmp_path, sensor_dataset, dataset_digest
):
    options = dict(rain_rate_mm_h=200.0, waveform_bin_ns=0.5)
    again = sensor_dataset(tmp_path / "a", batch_size=5, **options)
    pool = sensor_dataset(tmp_path / "b", workers=2, **options)
    assert dataset_digest(again) == dataset_digest(pool) == dataset_digest(made["rain, stored"])


def test_verify_the_card_and_load_split_know_the_waveform(made, tmp_path, cli, copy_dataset):
    path = made["last, stored"]
    card = (path / "README.md").read_text()
    assert "--waveform-bin 1.0" in card and "`waveform` | float32 | (N, 16, 16, 668)" in card
    assert "668 samples, one every 1 ns" in card
    assert cli("verify", path).exit_code == 0
    x, y = load_split(path, "test", field="waveform")
    assert x.shape == (32, 16, 16, 668) and len(y) == 32
    copy = copy_dataset(path, tmp_path / "d")
    with h5py.File(copy / "test.h5", "a") as f:
        del f["waveform"]
    result = cli("verify", copy)
    assert result.exit_code == 1 and "dataset 'waveform' missing" in result.output


@pytest.mark.parametrize(
    "options, expected",
    [
        (("--profile", "physical", "--waveform-bin", "1"), "expected a profile with a receiver"),
        (("--profile", "sensor", "--waveform-bin", "0.3"), "expected a multiple of 0.25 ns"),
        (("--profile", "sensor", "--waveform-bin", "8"), "not in the range 0<=x<=4"),
    ],
)
def test_a_wrong_bin_is_one_line_and_writes_nothing(tmp_path, cli, refused, options, expected):
    refused(cli("generate", *options, "--out", tmp_path / "o"), tmp_path / "o", expected)


def test_a_waveform_too_big_for_a_chunk_is_refused():
    """One sample a chunk: 64 x 200 pulses x 2,669 samples of 0.25 ns x 4 bytes = 136.7 MB,
    over the 128 MiB a reader accepts, is refused before anything is made."""
    from simlidar.errors import ConfigError
    from simlidar.sensor.model import load_sensor

    with pytest.raises(ConfigError, match=r"waveform_bin_ns=0.25 \(--waveform-bin\): a sample"):
        GeneratorConfig.from_profile(
            load_profile("sensor"), sensor=load_sensor("hdl64e"), width=200, waveform_bin_ns=0.25
        )


def test_a_waveform_attribute_alone_is_one_line_in_verify_and_card(
    made, tmp_path, cli, copy_dataset
):
    copy = copy_dataset(made["last, stored"], tmp_path / "d")
    for split in ("train", "test"):
        with h5py.File(copy / f"{split}.h5", "a") as f:
            del f.attrs["waveform_bin_ns"]
    for command in ("verify", "card"):
        result = cli(command, copy)
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert "expected 'waveform_bin_ns' and 'waveform_bins' together" in result.output


def test_load_split_refuses_a_waveform_its_attributes_contradict(made, tmp_path, copy_dataset):
    """Issue 58, finding 4: a waveform of 668 samples under ``waveform_bins = 100`` was
    returned as it was; now every loader refuses it, as verify does."""
    from simlidar.dataset.loaders import PulseDataset
    from simlidar.errors import DatasetError
    from simlidar.release.checksums import write_sums

    copy = copy_dataset(made["last, stored"], tmp_path / "d")
    with h5py.File(copy / "test.h5", "a") as f:
        f.attrs["waveform_bins"] = 100
    write_sums(copy)
    expected = "'waveform' has shape (32, 16, 16, 668), expected (32, 16, 16, 100)"
    for load in (
        lambda: load_split(copy, "test", field="waveform"),
        lambda: PulseDataset(copy, "test"),
    ):
        with pytest.raises(DatasetError) as caught:
            load()
        assert expected in str(caught.value) and "\n" not in str(caught.value)


def test_a_path_for_a_receiver_name_is_refused(made, tmp_path, cli, copy_dataset):
    """Issue 58, finding 4: a stored receiver named like a path (the card prints it as
    ``sensors/receivers/<name>.toml``) is refused by verify, the card and the loaders."""
    import json

    from simlidar.errors import DatasetError
    from simlidar.release.checksums import write_sums

    copy = copy_dataset(made["last"], tmp_path / "d")
    with h5py.File(copy / "train.h5", "a") as f:
        f.attrs["receiver"] = json.dumps(
            json.loads(f.attrs["receiver"]) | {"name": "../../etc/passwd"}
        )
    write_sums(copy)
    expected = "key 'name': expected a name of letters, digits, '_' or '-'"
    for command in ("verify", "card"):
        result = cli(command, copy)
        assert result.exit_code == 1 and expected in result.output, result.output
        assert "'../../etc/passwd'" in result.output and "Traceback" not in result.output
    with pytest.raises(DatasetError, match="etc/passwd"):
        load_split(copy, "train")
