"""Full sweeps (`simlidar sweep`): every firing of whole rotations, per-point labels and
timing, the point-cloud exports read back by an independent reader."""

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.dataset.schema import POINT_DTYPE
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.exports import export_frame
from simlidar.generator.frames import frame_points, read_frame
from simlidar.generator.sweep import FRAME_BATCH, SweepConfig, sweep
from simlidar.sensor import default_sensor, load_sensor, row_order
from simlidar.sensor.rays import (
    cycles_per_rotation,
    sweep_azimuths_deg,
    sweep_emission_ns,
    sweep_rays,
)

FRAMES = 12


@pytest.fixture(scope="module")
def frames(tmp_path_factory, catalog):
    out = tmp_path_factory.mktemp("sweep")
    path = sweep(GeneratorConfig(), SweepConfig(frames=FRAMES), catalog, out, progress=False)
    return path / "frames.h5"


def test_a_rotation_fires_every_cycle_once():
    sensor = default_sensor()
    assert cycles_per_rotation(sensor) == 1808  # 100 ms / 55.296 us at 600 RPM
    assert cycles_per_rotation(load_sensor("hdl64e")) == 2083  # 100 ms / 48 us
    az = sweep_azimuths_deg(sensor, np.array([0.25]))[0]
    first = row_order(sensor).index(0)  # laser 0 fires first in its cycle
    k = np.arange(1808)
    assert np.allclose(az[first], -180.0 + (k + 0.25) * sensor.azimuth_step_deg)
    assert az.max() - az.min() < 360.0  # one rotation, no firing twice
    t = sweep_emission_ns(sensor)
    assert t.shape == (16, 1808) and np.allclose(t[first], k * 55296.0)
    assert t.max() < 100e6  # all within the 100 ms of one rotation
    origins, directions = sweep_rays(sensor, np.array([0.0, 0.5]))
    assert directions.shape == (2, 16, 1808, 3)
    assert np.allclose(np.linalg.norm(directions, axis=-1), 1.0)


def test_road_points_lie_on_the_road_with_the_incidence_of_their_laser(frames):
    sensor = default_sensor()
    points = frame_points(frames, 5)  # open_road/car (frame f shows class f mod 32)
    road = points[points["surface"] == 1]
    assert len(road) > 1000
    # the sensor frame's origin is the rotation axis' reference point, 1.8 m above the road
    assert np.abs(road["z"] + sensor.mount_height_m).max() < 0.01
    # flat road: |cos incidence| = sin(-elevation) of the laser that hit it
    elevation = np.deg2rad(np.asarray(sensor.elevations_deg)[road["laser"]])
    assert np.allclose(road["intensity"], np.sin(-elevation), atol=1e-3)
    # range limits: nothing at 100 m and beyond (ranges from the emitters, near the origin)
    r = np.sqrt(points["x"] ** 2 + points["y"] ** 2 + points["z"] ** 2)
    assert 1.0 < r.min() and r.max() < 100.1
    assert (np.diff(points["t_ns"]) >= 0).all()  # firing order


def test_objects_show_up_where_they_were_placed(frames):
    with h5py.File(frames) as f:
        obj, pose, counts = f["object"][:], f["object_pose"][:], f["object_points"][:]
        names = json.loads(f.attrs["surface_names"])
    objects = {1: "car", 2: "pedestrian", 3: "truck"}
    for frame in np.nonzero(obj)[0]:
        assert counts[frame] > 0
        points = frame_points(frames, int(frame))
        mine = points[points["surface"] == names.index(objects[int(obj[frame])])]
        assert len(mine) == counts[frame]
        xy = np.stack([mine["x"], mine["y"]], axis=1)
        # on the object: within half a truck's length of its placement, its near side seen
        assert np.linalg.norm(xy - pose[frame, :2], axis=1).max() < 7.0
        assert mine["x"].min() < pose[frame, 0]
    assert (counts[obj == 0] == 0).all()


def test_frames_do_not_depend_on_the_batch(tmp_path, catalog, frames):
    again = sweep(
        GeneratorConfig(), SweepConfig(frames=FRAMES), catalog, tmp_path, progress=False, batch=5
    )
    assert (again / "frames.h5").read_bytes() == frames.read_bytes()


def test_kitti_bin_and_labels_hold_the_points(frames, tmp_path):
    points = frame_points(frames, 2)
    written = export_frame(frames, 2, tmp_path, "kitti")
    assert [p.relative_to(tmp_path).as_posix() for p in written] == [
        "velodyne/000002.bin",
        "labels/000002.label",
        "label_2/000002.txt",
        "calib/000002.txt",
    ]
    xyzi = np.fromfile(written[0], dtype="<f4").reshape(-1, 4)  # how KITTI readers do it
    assert np.array_equal(xyzi[:, 0], points["x"]) and np.array_equal(
        xyzi[:, 3], points["intensity"]
    )
    labels = np.fromfile(written[1], dtype="<u4")
    assert np.array_equal(labels & 0xFFFF, points["surface"])


def test_ply_reads_back_with_trimesh(frames, tmp_path):
    import trimesh

    points = frame_points(frames, 3)
    (ply,) = export_frame(frames, 3, tmp_path, "ply")
    cloud = trimesh.load(ply)
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1)
    assert np.allclose(np.asarray(cloud.vertices), xyz)
    assert len(cloud.vertices) == len(points)


def test_pcd_header_and_body_agree(frames, tmp_path):
    points = frame_points(frames, 4)
    (pcd,) = export_frame(frames, 4, tmp_path, "pcd")
    raw = pcd.read_bytes()
    head, body = raw.split(b"DATA binary\n", 1)
    header = dict(line.split(" ", 1) for line in head.decode().splitlines()[1:])
    assert header["FIELDS"].split() == list(POINT_DTYPE.names)
    assert int(header["POINTS"]) == len(points)
    sizes = [int(s) for s in header["SIZE"].split()]
    assert sum(sizes) == POINT_DTYPE.itemsize and len(body) == len(points) * sum(sizes)
    assert np.array_equal(np.frombuffer(body, POINT_DTYPE), points)


def test_the_cli_writes_a_sweep_and_its_exports(tmp_path, cli):
    result = cli("sweep", "--frames", 2, "--export", "kitti,pcd", "--out", tmp_path, "--json")
    assert result.exit_code == 0, result.output
    path = Path(json.loads(result.stdout)["path"])
    assert path.name == "simlidar-sweep-32c-vlp16-2f-seed0-v1.1.0"
    names = sorted(p.relative_to(path).as_posix() for p in path.rglob("*") if p.is_file())
    assert names == [
        "bev.png",
        "calib/000000.txt",
        "calib/000001.txt",
        "frames.h5",
        "label_2/000000.txt",
        "label_2/000001.txt",
        "labels/000000.label",
        "labels/000001.label",
        "pcd/000000.pcd",
        "pcd/000001.pcd",
        "velodyne/000000.bin",
        "velodyne/000001.bin",
    ]
    with h5py.File(path / "frames.h5") as f:
        assert f["range_m"].shape == (2, 16, 1808) and f["range_m"].chunks == (1, 16, 1808)
        assert f.attrs["format"] == "simlidar-sweep"
    again = cli("sweep", "--frames", 2, "--out", tmp_path)
    assert again.exit_code == 1 and "already exists: pass --force" in again.output


@pytest.mark.parametrize(
    "args, message",
    [
        (["--frames", 0], "'--frames': 0 is not in the range 1<=x<=1000000"),
        (["--export", "kitti,las"], "'las': expected a comma-separated list of kitti, ply, pcd"),
        (["--classes", 5], "classes=5: expected one of [4, 8, 32]"),
        (["--sensor", "hdl99"], "sensor 'hdl99': expected one of"),
        (["--profile", "physical"], "'physical': expected a profile with a receiver (sensor)"),
        (["--fog", "50"], "fog_visibility_m=50.0 (--fog): expected a profile with a receiver"),
        (["--profile", "nosuch"], "profile 'nosuch': expected one of"),
    ],
)
def test_bad_sweep_options_are_one_line_and_write_nothing(tmp_path, args, message, cli):
    result = cli("sweep", *args, "--out", tmp_path / "out")
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


def test_reading_a_frame_checks_the_file_and_the_index(frames, tmp_path):
    sensor, values, emission = read_frame(frames, 0)
    assert sensor == default_sensor() and values["range_m"].shape == emission.shape
    with pytest.raises(ConfigError, match=f"frame {FRAMES}: expected 0 to {FRAMES - 1}"):
        read_frame(frames, FRAMES)
    other = tmp_path / "x.h5"
    with h5py.File(other, "w") as f:
        f["labels"] = np.zeros(1)
    with pytest.raises(ConfigError, match="expected a simlidar sweep file"):
        read_frame(other, 0)


def test_sweep_config_is_checked():
    with pytest.raises(ConfigError, match="frames=0"):
        SweepConfig(frames=0)


def test_hdl64e_sweep_crops_read_the_distance_of_the_truck(tmp_path, cli):
    """The sim half of a sim-to-real pair: an HDL-64E sweep exported in the KITTI layout and
    cropped by `simlidar convert kitti`, the very projection of the real frames. As the
    converter's test reads KITTI's truck at 63.5 m, the simulated truck's crop reads the
    distance of its rear face, known from the frame's stored box."""
    done = cli(
        "sweep", "--frames", 4, "--sensor", "hdl64e", "--export", "kitti", "--out", tmp_path,
        "--json",
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    sweep_dir = Path(json.loads(done.stdout)["path"])
    converted = cli("convert", "kitti", sweep_dir, "--out", tmp_path / "crops")
    assert converted.exit_code == 0, converted.output
    crops = tmp_path / "crops" / "kitti-front-50x118-sim-v1.0.0"
    assert cli("verify", crops).exit_code == 0
    with h5py.File(sweep_dir / "frames.h5") as f:
        length, _, _, x, y, _, yaw = f["object_box"][3]  # frame 3: tunnel/truck
        assert f["object"][3] == 3
    rows = []
    for split in ("train", "test"):
        with h5py.File(crops / f"{split}.h5") as f:
            assert json.loads(f.attrs["simulated_from"])["sweep"] == sweep_dir.name
            rows += [
                (f["delays"][k], f.attrs["tof_max_ns"], f["crop_origin"][k])
                for k in range(len(f["frame"]))
                if f["frame"][k] == 3
            ]
    ((delays, tof_max, origin),) = rows
    assert delays.shape == (50, 118)
    # the truck fills the crop's centre: its nearest points there are its rear face
    centre = delays[20:30, 54:64].astype(float) * tof_max * 1e-9 * 299_792_458 / 2
    rear = x - length / 2 * np.cos(np.deg2rad(yaw))  # the rear face, ahead of the sensor
    assert np.nanmedian(centre) == pytest.approx(np.hypot(rear, y), abs=0.1)
    labels = (sweep_dir / "label_2" / "000003.txt").read_text().split()
    assert labels[0] == "Truck" and float(labels[13]) == pytest.approx(x, abs=1e-3)


def test_a_sweep_converts_without_its_kitti_export_to_the_same_bytes(tmp_path, cli):
    """`simlidar convert kitti` reads a sweep's frames.h5 directly when the KITTI files are
    not on disk: the same crops and input hash as from the exported folder."""
    made = {}
    for kind, extra in (("exported", ["--export", "kitti"]), ("direct", [])):
        done = cli(
            "sweep", "--frames", 6, "--sensor", "hdl64e", *extra, "--out", tmp_path / kind,
            "--json",
        )  # fmt: skip
        assert done.exit_code == 0, done.output
        sweep_dir = Path(json.loads(done.stdout)["path"])
        assert (sweep_dir / "velodyne").is_dir() == (kind == "exported")
        converted = cli("convert", "kitti", sweep_dir, "--out", tmp_path / kind / "crops")
        assert converted.exit_code == 0, converted.output
        made[kind] = tmp_path / kind / "crops" / "kitti-front-50x118-sim-v1.0.0"
    for split in ("train.h5", "test.h5"):
        exported = (made["exported"] / split).read_bytes()
        assert exported == (made["direct"] / split).read_bytes()
    with h5py.File(made["direct"] / "train.h5") as f:
        assert len(f["labels"]) > 0 and json.loads(f.attrs["simulated_from"])["sweep"]
    assert cli("verify", made["direct"]).exit_code == 0


def test_a_folder_that_is_neither_kitti_nor_a_sweep_is_named(tmp_path, cli):
    (tmp_path / "frames.h5").write_bytes(b"not hdf5")
    result = cli("convert", "kitti", tmp_path, "--out", tmp_path / "out")
    assert result.exit_code != 0
    assert "expected the KITTI object benchmark's training layout" in result.output


SENSOR_FRAMES = 6


def _sensor_sweep(out, catalog, batch=FRAME_BATCH, **fields):
    from simlidar.generator.profiles import load_profile

    config = GeneratorConfig.from_profile(load_profile("sensor"), **fields)
    frames = SweepConfig(frames=SENSOR_FRAMES)
    return sweep(config, frames, catalog, out, progress=False, batch=batch)


def test_a_sweep_through_the_receiver_keeps_the_scenes_and_reports_its_bytes(tmp_path, catalog):
    """--profile sensor: the same frames (labels, phases, boxes) as the plain sweep, returns of
    surfaces a subset of its hits (and rare false alarms, surface 0), the intensity the VLP-16's
    reflectivity byte (whole numbers, 0 where nothing returns, at most 100 on the diffuse
    scenery), the receiver in the attributes, version 2.0.0; fog loses surfaces and returns
    echoes of its own near the sensor; the same bytes for any batch."""
    plain = sweep(GeneratorConfig(), SweepConfig(frames=SENSOR_FRAMES), catalog, tmp_path / "p",
                  progress=False) / "frames.h5"  # fmt: skip
    path = _sensor_sweep(tmp_path / "s", catalog)
    assert path.name == "simlidar-sweep-32c-vlp16-6f-seed0-sensor-v2.0.0"
    foggy = _sensor_sweep(tmp_path / "f", catalog, fog_visibility_m=50.0)
    assert foggy.name == "simlidar-sweep-32c-vlp16-6f-seed0-sensor-fog50.0-v2.0.0"
    with (
        h5py.File(plain) as a,
        h5py.File(path / "frames.h5") as b,
        h5py.File(foggy / "frames.h5") as c,
    ):
        for name in ("labels", "layout", "object", "phase", "object_box"):
            assert np.array_equal(a[name][:], b[name][:], equal_nan=True), name
        assert b.attrs["sweep_version"] == "2.0.0" and "receiver" in b.attrs
        assert a.attrs["sweep_version"] == "1.1.0" and "receiver" not in a.attrs
        hit, returned, fogged = (~np.isnan(f["range_m"][:]) for f in (a, b, c))
        alarm = returned & (b["surface"][:] == 0)
        assert alarm.mean() < 1e-3
        assert not (returned & ~alarm & ~hit).any() and returned.sum() < hit.sum()
        fog_surfaces = fogged & (c["surface"][:] > 0)
        fog_own = fogged & (c["surface"][:] == 0)
        assert fog_surfaces.sum() < (returned & ~alarm).sum() and fog_own.sum() > 0
        assert (c["range_m"][:][fog_own] < 12.0).all()
        intensity = b["intensity"][:]
        assert np.array_equal(intensity, np.round(intensity)) and intensity.max() <= 255
        assert (intensity[~returned] == 0).all() and (intensity[returned] > 0).mean() > 0.99
        names = json.loads(b.attrs["surface_names"])
        scenery = np.isin(b["surface"][:], [names.index(n) for n in ("road", "wall", "ground")])
        assert (intensity[scenery & returned] <= 100).all()
        assert (b["surface"][:][~returned] == 0).all()
    again = _sensor_sweep(tmp_path / "again", catalog, batch=4)
    assert (again / "frames.h5").read_bytes() == (path / "frames.h5").read_bytes()
    points = frame_points(path / "frames.h5", 0)
    assert len(points) == int(returned[0].sum())


def test_a_sweep_stores_every_reported_return_and_exports_each_with_its_number(tmp_path, catalog):
    """--beam-samples 2 --return-mode dual with rain (issue 41, item 5): version 2.0.0, the
    plain sensor sweep's frames (labels, phases, boxes, as the axes judge them), the per-pulse
    fields the first reported return; every reported return stored, and exported once each,
    numbered in order of arrival with its pulse's count (PLY and KITTI agree); the same bytes
    for any batch."""
    options = dict(beam_samples=2, return_mode="dual", rain_rate_mm_h=200.0)
    path = _sensor_sweep(tmp_path / "d", catalog, **options)
    assert path.name == "simlidar-sweep-32c-vlp16-6f-seed0-sensor-rain200.0-beam2-dual-v2.0.0"
    plain = _sensor_sweep(tmp_path / "s", catalog) / "frames.h5"
    with h5py.File(plain) as a, h5py.File(path / "frames.h5") as b:
        for name in ("labels", "layout", "object", "phase", "object_box"):
            assert np.array_equal(a[name][:], b[name][:], equal_nan=True), name
        assert b.attrs["return_mode"] == "dual" and b.attrs["beam_samples"] == 2
        assert b.attrs["sweep_version"] == "2.0.0"
        returns = b["returns_range_m"][:]
        assert returns.shape == b["range_m"].shape + (2,)
        first = np.fmin(returns[..., 0], returns[..., 1])
        np.testing.assert_array_equal(first, b["range_m"][:])
        two = ~np.isnan(returns[..., 0]) & (returns[..., 0] != returns[..., 1])
        assert two.sum() > 20  # edges and drops
        assert (b["echoes"][:][two] >= 2).all()
        drops = b["returns_surface"][:] == 0
        assert (drops & ~np.isnan(returns)).any()  # the rain's returns near the sensor
    points = frame_points(path / "frames.h5", 0)
    with h5py.File(path / "frames.h5") as b:
        r = b["returns_range_m"][0]
    distinct = (~np.isnan(r[..., 0])).sum() + (two[0]).sum()
    assert len(points) == distinct
    assert set(np.unique(points["return_number"])) == {1, 2}
    assert (points["return_number"] <= points["number_of_returns"]).all()
    assert (points["number_of_returns"] == 2).sum() == 2 * two[0].sum()
    second = points["return_number"] == 2
    first_of_pair = np.flatnonzero(second) - 1
    far = np.linalg.norm([points[k] for k in "xyz"], axis=0)
    assert (far[second] > far[first_of_pair]).all()  # in order of arrival
    files = export_frame(path / "frames.h5", 0, tmp_path / "x", "ply")
    files += export_frame(path / "frames.h5", 0, tmp_path / "x", "kitti")
    import trimesh

    cloud = trimesh.load(files[0])
    assert len(cloud.vertices) == len(points)
    scan = np.fromfile(tmp_path / "x/velodyne/000000.bin", "<f4").reshape(-1, 4)
    assert len(scan) == len(points)
    again = _sensor_sweep(tmp_path / "again", catalog, batch=4, **options)
    assert (again / "frames.h5").read_bytes() == (path / "frames.h5").read_bytes()


def test_a_sweep_refuses_waveforms_in_one_line(tmp_path, catalog):
    from simlidar.generator.profiles import load_profile

    config = GeneratorConfig.from_profile(load_profile("sensor"), waveform_bin_ns=1.0)
    with pytest.raises(ConfigError, match=r"waveform_bin_ns=1.0: a sweep stores no waveforms"):
        sweep(config, SweepConfig(frames=1), catalog, tmp_path, progress=False)
    assert not any(tmp_path.iterdir())
