"""Datasets of sensors other than the VLP-16 (`generate --sensor`): rows = beams, the sensor
stored in every split, shown by info and the card; bad sensors refused before anything is
written."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.content import content_dir
from simlidar.data import load_split
from simlidar.dataset.reader import read_split_info
from simlidar.sensor import default_sensor, firing_azimuths_deg, load_sensor, row_order

SMALL = ["--train-size", "32", "--test-size", "32"]


@pytest.fixture(scope="module")
def hdl32e(tmp_path_factory, cli):
    out = tmp_path_factory.mktemp("hdl32e")
    result = cli("generate", "--sensor", "hdl32e", *SMALL, "--out", out, "--json")
    assert result.exit_code == 0, result.output
    return Path(json.loads(result.stdout)["datasets"][0]["path"])


def test_a_32_beam_dataset_has_32_rows_and_says_so(hdl32e, cli):
    assert hdl32e.name == "simlidar-32c-noise0.2-paper-hdl32e-v2.0.0"
    x, y = load_split(hdl32e, "train")
    assert x.shape == (32, 32, 16) and y.shape == (32,)
    attrs = read_split_info(hdl32e / "train.h5").attrs
    sensor = load_sensor("hdl32e")
    assert attrs["sensor"]["name"] == "hdl32e"
    assert list(attrs["row_laser_ids"]) == row_order(sensor)
    assert list(attrs["row_elevation_deg"]) == sorted(sensor.elevations_deg, reverse=True)
    # a pulse that came back lies within the sensor's own range limits
    with np.errstate(invalid="ignore"):
        import h5py

        with h5py.File(hdl32e / "train.h5") as f:
            tof = f["tof_ns"][:]
    returned = tof[np.isfinite(tof)]
    assert returned.size and returned.max() < sensor.tof_max_ns

    info = cli("info", hdl32e)
    assert info.exit_code == 0
    assert "sensor hdl32e (Velodyne HDL-32E), 32 beams, 600 RPM" in info.stdout
    assert "32 x 16 pulses" in info.stdout
    assert cli("verify", hdl32e).exit_code == 0
    card = (hdl32e / "README.md").read_text()
    assert "32 x W array" in card and "simulated Velodyne HDL-32E" in card
    assert "| sample | 32 x 16 float32 delays" in card
    assert "--sensor hdl32e" in card and "velodyne-hdl-32e" in card


def test_the_same_sensor_gives_the_same_bytes(hdl32e, tmp_path, cli):
    again = cli("generate", "--sensor", "hdl32e", *SMALL, "--out", tmp_path, "--json")
    path = Path(json.loads(again.stdout)["datasets"][0]["path"])
    for name in ("train.h5", "test.h5"):
        assert (path / name).read_bytes() == (hdl32e / name).read_bytes()


def test_a_sensor_file_by_path(tmp_path, cli):
    """A copy of a shipped file under another name: a new name in the dataset name."""
    mine = tmp_path / "my-32.toml"
    shutil.copy(content_dir("sensors") / "hdl32e.toml", mine)
    result = cli("generate", "--sensor", mine, *SMALL, "--out", tmp_path / "out", "--json")
    assert result.exit_code == 0, result.output
    path = Path(json.loads(result.stdout)["datasets"][0]["path"])
    assert "-paper-my-32-v" in path.name
    assert "GeneratorConfig.from_dict" in (path / "README.md").read_text()  # not shipped


@pytest.mark.parametrize("profile", ["paper", "physical"])
def test_the_hdl64e_sees_every_class_of_the_shipped_catalog(tmp_path, profile, cli):
    """KITTI's sensor looks at most 2 deg up: the catalog's hdl64e variant puts the lower
    bridge's deck and the tunnel's arch where it sees them (scenes/sensors/hdl64e.toml)."""
    result = cli(
        "generate", "--sensor", "hdl64e", "--profile", profile, "--train-size", "64",
        "--test-size", "32", "--out", tmp_path, "--json",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    path = Path(json.loads(result.stdout)["datasets"][0]["path"])
    with h5py.File(path / "train.h5") as f:
        labels, surface = f["labels"][:], f["surface"][:]
        names = [str(n) for n in f.attrs["surface_names"]]
        stored = json.loads(f.attrs["catalog"])
    assert sorted(set(labels)) == list(range(32))
    for label, seen in ((8, "bridge"), (11, "bridge"), (3, "ceiling")):  # truck ahead: 3, 11
        hits = (surface[labels == label] == names.index(seen)).sum(axis=(1, 2))
        assert hits.min() >= 3, (label, seen, hits)  # the layouts' `visible` rules
    # what a dataset stores is the recipes it was made with
    deck = stored["layouts"]["lower_bridge"]["params"]
    assert deck["bridge_m"] == [85.0, 105.0] and deck["clearance_m"] == [4.2, 5.0]
    card = (path / "README.md").read_text()
    assert f"simlidar generate --profile {profile} --classes 32" in card
    assert "--sensor hdl64e" in card and "--scenes CATALOG" not in card  # the shipped catalog


def test_the_hdl64e_on_the_recipes_as_written_says_why_it_cannot(tmp_path, cli):
    """Without the variant, the deck of the lower bridge (4.5-6.5 m high, 15-60 m ahead) is
    above the HDL-64E's view, and the error names the sample, the class and the sensor."""
    scenes = tmp_path / "scenes"
    shutil.copytree(content_dir("scenes"), scenes)
    shutil.rmtree(scenes / "sensors")
    result = cli(
        "generate", "--sensor", "hdl64e", "--profile", "physical", *SMALL, "--scenes", scenes,
        "--out", tmp_path / "out",
    )  # fmt: skip
    assert result.exit_code == 1
    line = result.stderr.strip().splitlines()[-1]  # after the progress bar
    # the test split is simulated first (its preview is drawn while train is written)
    assert line.startswith("Error: test sample 8 (lower_bridge/none): no draw in 200")
    assert "sensor hdl64e (-24.711 to +2.021 deg)" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "value, words",
    [
        ("vlp17", "sensor 'vlp17': expected one of ['hdl32e', 'hdl64e', 'vlp16']"),
        ("missing.toml", "missing.toml: file not found"),
    ],
)
def test_a_bad_sensor_is_one_line_and_writes_nothing(tmp_path, value, words, cli):
    result = cli("generate", "--sensor", tmp_path / value if "." in value else value, *SMALL,
                 "--out", tmp_path / "out")  # fmt: skip
    assert result.exit_code == 2
    assert words in result.stderr and "--sensor" in result.stderr
    assert not (tmp_path / "out").exists()


def test_a_bad_sensor_file_names_the_key(tmp_path, cli):
    bad = tmp_path / "slow.toml"
    text = (content_dir("sensors") / "vlp16.toml").read_text()
    bad.write_text(text.replace("rpm = 600.0", "rpm = 100.0"))
    result = cli("generate", "--sensor", bad, *SMALL, "--out", tmp_path / "out")
    assert result.exit_code == 2
    assert f"sensor {bad}: rpm=100.0: expected 300 to 1200 in steps of 60" in result.stderr
    assert not (tmp_path / "out").exists()


def test_sensors_lists_the_shipped_models(cli):
    text = cli("sensors")
    assert text.exit_code == 0
    assert "vlp16 (default): Velodyne VLP-16, 16 beams (-15 to +15 deg)" in text.stdout
    assert "hdl64e: Velodyne HDL-64E S2, 64 beams" in text.stdout
    listing = json.loads(cli("sensors", "--json").stdout)
    assert listing["default"] == "vlp16"
    assert [s["beams"] for s in listing["sensors"]] == [32, 64, 16]


def test_paired_lasers_fire_together_turned_by_their_corrections():
    sensor = load_sensor("hdl64e")
    az = firing_azimuths_deg(sensor, 4, 36.0, np.array([0.3]))[0]  # (64, 4), rows
    row = {laser: r for r, laser in enumerate(row_order(sensor))}
    rot = sensor.rot_corrections_deg
    for laser in (0, 5, 31):
        mate = laser + 32
        np.testing.assert_allclose(
            az[row[laser]] + rot[laser], az[row[mate]] + rot[mate], atol=1e-12
        )
    # beam azimuth = head azimuth - correction (the Velodyne drivers' convention)
    plain = default_sensor()
    turned = replace(plain, rot_corrections_deg=(1.0,) * 16)
    np.testing.assert_allclose(
        firing_azimuths_deg(turned, 4, 36.0, np.array([0.3])),
        firing_azimuths_deg(plain, 4, 36.0, np.array([0.3])) - 1.0,
        atol=1e-12,
    )
