"""Pulse streams of moving scenes (simlidar stream, issue 60): each pulse's time by hand, the
time an object first returns, its track, the dense view of the events, same bytes for every
batch size, the card's regenerate call, and the scenario file's and the CLI's refusals."""

import hashlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.errors import ConfigError, RecipeError
from simlidar.generator.pulse_streams import simulate_streams, stream_rays
from simlidar.generator.stream_config import StreamConfig
from simlidar.generator.stream_files import generate_streams
from simlidar.scene.recipe import load_catalog
from simlidar.scene.scenarios import load_scenarios
from simlidar.sensor.model import SPEED_OF_LIGHT_M_PER_S, row_order

CONFIG = StreamConfig(classes=4, train_size=8, test_size=4)


@pytest.fixture(scope="module")
def batch(catalog):
    return simulate_streams(CONFIG, catalog, "train", 0, 16)


@pytest.fixture(scope="module")
def written(tmp_path_factory, catalog):
    out = tmp_path_factory.mktemp("streams")
    return generate_streams(out, train_size=8, test_size=4, progress=False, preview=False,
                            scenes=catalog)  # fmt: skip


def _by_sample(batch, name):
    return np.split(getattr(batch, name), np.cumsum(batch.event_count)[:-1])


def test_pulse_times_by_hand():
    """Rotation r's column c fires in the cycle whose azimuth lies nearest the column's centre
    plus 360 r (cycle k at azimuth (k + phase) * 360 / (60e6 / rpm / cycle_us)), each laser in
    its slot: t = (k - k_00) cycle_us + slot firing_interval_us, k_00 the first column's cycle
    in rotation 0."""
    sensor = CONFIG.sensor
    phase = np.array([0.0, 0.37, 0.99])
    _, _, times_ns, rotation = stream_rays(CONFIG, phase)
    step_deg = 360.0 / (60e6 / sensor.rpm / sensor.cycle_us)  # 0.19906 deg at 600 RPM
    centre = -18.0 + (np.arange(32) + 0.5) * 36.0 / 32
    slots = np.array([sensor.slots[k] for k in row_order(sensor)])
    for b, p in enumerate(phase):
        cycles = np.round((centre[None, :] + 360.0 * np.arange(10)[:, None]) / step_deg - p)
        expected_us = (cycles.reshape(-1) - cycles[0, 0]) * 55.296
        expected_us = expected_us[None, :] + slots[:, None] * 2.304
        assert np.allclose(times_ns[b] * 1e-3, expected_us, rtol=0, atol=1e-6)
    assert (rotation == np.repeat(np.arange(10), 32)).all()


def test_visible_time_is_the_first_event_on_the_object(batch):
    """t_visible_us is the arrival of the first event on the object (every stream), after the
    window's first rotation and before the span's last 100 ms; NaN without object; the
    reference time is t_visible_us, or for none one of its returns in the same range."""
    times, on = _by_sample(batch, "event_t_us"), _by_sample(batch, "event_object")
    span_us = CONFIG.rotations * CONFIG.rotation_us
    assert (batch.object == batch.labels).all()  # 4 classes: the object alone
    for i in range(len(batch.labels)):
        assert (np.diff(times[i]) >= 0).all()
        if batch.object[i] == 0:
            assert np.isnan(batch.t_visible_us[i]) and not on[i].any()
        else:
            assert batch.t_visible_us[i] == times[i][on[i]].min()
            assert batch.object_events[i] == on[i].sum() >= CONFIG.min_object_hits
            assert batch.t_reference_us[i] == batch.t_visible_us[i]
        assert CONFIG.rotation_us <= batch.t_reference_us[i] <= span_us - 100e3
        assert batch.t_reference_us[i] in times[i]  # a return: the object's first, or drawn


def test_track_follows_the_drawn_motion(batch):
    """Without a yaw rate the object moves in a straight line: x(t) = x_0 + v cos(h) t, its
    start x_0 the track at t = 0 run back from the first rotation's middle."""
    rotation_s = CONFIG.rotation_us * 1e-6
    for i in np.nonzero(batch.object != 0)[0]:
        speed, heading, yaw_rate = batch.object_motion[i].astype(np.float64)
        assert yaw_rate == 0.0
        track = batch.object_track[i].astype(np.float64)
        step = np.diff(track[:, :2], axis=0)  # the middles are about a rotation apart
        expected = speed * rotation_s * np.array([np.cos(np.deg2rad(heading)),
                                                  np.sin(np.deg2rad(heading))])  # fmt: skip
        assert np.allclose(step, expected, atol=speed * 60e-6 + 1e-4)  # a cycle's drift
        assert (track[:, 2] == heading).all()


def test_scenarios_start_unseen(batch, catalog):
    """Oncoming vehicles start past the range limit, overtaking ones beside or behind the
    sensor, crossing pedestrians outside the window's edge."""
    names = catalog.scenarios.names
    for i in np.nonzero(batch.object != 0)[0]:
        x, y, _ = batch.object_track[i, 0]
        kind = names[batch.scenario[i]]
        if kind == "oncoming":
            assert x > 95.0 and batch.object_motion[i, 1] == 180.0
        elif kind == "overtaking":
            assert x < 2.0 and batch.object_motion[i, 0] > batch.ego_motion[i, 0]
        else:
            assert kind == "crossing" and abs(y) > abs(x) * np.tan(np.deg2rad(18.0))


def test_dense_delays_hold_the_events(written):
    """delays[row, r W + x] of each event is its range's time of flight over tof_max_ns;
    every other pulse is 1.0 (no return)."""
    with h5py.File(written / "train.h5") as f:
        delays, count = f["delays"][:], f["event_count"][:]
        x, y, t = f["event_x"][:], f["event_y"][:], f["event_t_us"][:]
        range_m, tof_max = f["event_range_m"][:], f.attrs["tof_max_ns"]
    sample = np.repeat(np.arange(len(count)), count)
    tof_ns = 2.0 * range_m.astype(np.float64) / SPEED_OF_LIGHT_M_PER_S * 1e9
    rotation = np.round(t / 100e3).astype(int)  # windows start within a cycle of r x 100 ms
    got = delays[sample, y, rotation * 32 + x]
    assert np.allclose(got, tof_ns / tof_max, rtol=1e-6)
    assert (delays < 1.0).sum() == len(t)


def test_same_bytes_for_any_batch_size(tmp_path, written, catalog):
    again = generate_streams(tmp_path, train_size=8, test_size=4, progress=False,
                             preview=False, scenes=catalog, batch_size=3)  # fmt: skip
    for name in ("train.h5", "test.h5"):
        assert (again / name).read_bytes() == (written / name).read_bytes()


def test_same_bytes_for_two_workers(tmp_path, written, catalog):
    """Worker processes simulate the batches, the calling one writes them in order."""
    again = generate_streams(tmp_path, train_size=8, test_size=4, progress=False,
                             preview=False, scenes=catalog, batch_size=2, workers=2)  # fmt: skip
    for name in ("train.h5", "test.h5"):
        assert (again / name).read_bytes() == (written / name).read_bytes()


def test_card_regenerates_the_same_bytes(tmp_path, written):
    """The card's "Regenerate" call, run as written, makes the same split files."""
    card = (written / "README.md").read_text()
    code = card.split("## Regenerate", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    code = code.replace("'data'", repr(str(tmp_path)))
    exec(compile(code.replace(")\n", ", progress=False, preview=False)\n"), "card", "exec"), {})
    again = tmp_path / written.name
    for name in ("train.h5", "test.h5"):
        digest = hashlib.sha256((again / name).read_bytes()).hexdigest()
        assert digest == hashlib.sha256((written / name).read_bytes()).hexdigest()


def test_an_existing_dataset_is_refused(written):
    with pytest.raises(Exception, match="already exists: pass --force"):
        generate_streams(written.parent, train_size=8, test_size=4, progress=False)


@pytest.mark.parametrize(
    "text, match",
    [
        (
            "[scenario.a]\ndescription='x'\nobjects=['car']\ndistance_m=1\nlateral_m=0\n"
            "speed_mps=1\n",
            "a scenario for every object",
        ),
        (
            "[scenario.none]\ndescription='x'\nobjects=['car','truck','pedestrian']\n"
            "distance_m=1\nlateral_m=0\nspeed_mps=1\n",
            "another name",
        ),
        (
            "[scenario.a]\ndescription='x'\nobjects=['car','truck','pedestrian']\ndistance_m=1\n"
            "lateral_m=0\nspeed_mps=1\nwind=3\n",
            "key 'wind'",
        ),
        (
            "[scenario.a]\ndescription='x'\nobjects=['car','truck','pedestrian']\ndistance_m=500\n"
            "lateral_m=0\nspeed_mps=1\n",
            r"values in \[-120, 120\]",
        ),
        (
            "[visibility]\ntail_ms=-1\n[scenario.a]\ndescription='x'\nobjects=['car','truck',"
            "'pedestrian']\ndistance_m=1\nlateral_m=0\nspeed_mps=1\n",
            "milliseconds",
        ),
        (
            "[scenario.a]\ndescription='x'\nobjects=['car','truck','pedestrian']\ndistance_m=1\n"
            "lateral_m=0\nspeed_mps=1\nmirrored='yes'\n",
            "true or false",
        ),
    ],
)
def test_scenario_file_mistakes_are_named(tmp_path, text, match):
    path = tmp_path / "scenarios.toml"
    path.write_text("[ego]\nspeed_mps = 0.0\n" * ("[ego]" not in text) + text)
    with pytest.raises(RecipeError, match=match) as caught:
        load_scenarios(path, ["car", "pedestrian", "truck"])
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_a_catalog_without_scenarios_is_refused(catalog_copy):
    (Path(catalog_copy) / "scenarios.toml").unlink()
    with pytest.raises(ConfigError, match="has no scenarios.toml"):
        generate_streams(catalog_copy.parent / "out", train_size=4, test_size=4,
                         scenes=load_catalog(catalog_copy), progress=False)  # fmt: skip
    assert not (catalog_copy.parent / "out").exists()


@pytest.mark.parametrize(
    "args, match",
    [
        (("--rotations", "30"), "rotations=30: 3 s at 600 RPM; expected a span of at most 2 s"),
        (("--width", "500"), "width=500: columns 0.072 deg apart"),
        (("--train-size", "2"), "train_size=2: expected an integer in [4, "),
        (("--classes", "5"), "classes=5"),
    ],
)
def test_cli_refuses_in_one_line(cli, tmp_path, args, match):
    result = cli("stream", "--out", tmp_path / "out", "--test-size", 4, *args)
    assert result.exit_code != 0
    assert match in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_cli_writes_a_dataset_verify_accepts(cli, tmp_path):
    result = cli("stream", "--out", tmp_path, "--train-size", 4, "--test-size", 4, "--json",
                 "--no-preview")  # fmt: skip
    assert result.exit_code == 0, result.output
    path = next(tmp_path.iterdir())
    assert cli("verify", path).exit_code == 0


def test_a_labelled_layout_is_seen_in_every_window(catalog):
    """With the layout in the label (32 classes), every rotation's window sees the layout's
    defining structure (its recipe's `visible` rule), as a window dataset's sample does."""
    config = StreamConfig(classes=32, train_size=32, test_size=32)
    batch = simulate_streams(config, catalog, "test", 0, 32)
    columns = -18.0 + (np.arange(32) + 0.5) * 36.0 / 32
    surfaces, x, rotation = (_by_sample(batch, name) for name in
                             ("event_surface", "event_x", "event_rotation"))  # fmt: skip
    checked = 0
    for i in range(32):
        for label, min_hits, side in catalog.layouts[batch.layout[i]].visible:
            seen = surfaces[i] == label
            if side != "any":
                seen &= (columns[x[i]] < 0) if side == "left" else (columns[x[i]] > 0)
            per_window = np.bincount(rotation[i][seen], minlength=10)
            assert (per_window >= min_hits).all(), (i, label, per_window)
            checked += 1
    assert checked > 0
