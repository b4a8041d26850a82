"""KITTI -> front-view pulse crops, checked against what can be derived without the converter:
the label files, the calibration and the raw scans, read and transformed here independently
(forward, Velodyne -> camera, where the converter goes backwards). The format checks run on a
KITTI folder built from a simulated sweep in every clone (``built_kitti``), and again on the
real sample where it is found; the real frames' own numbers are checked on it alone.

Attack list: malformed label and calibration files (too few columns, an unknown type, a word
where a number goes, a calibration key without its numbers or missing), a scan whose size is
not a multiple of 16 bytes, and (issue 35, item 10) numbers that parse but mean nothing: a box
of 1e308 m or 1e308 m away, a truncation of 1e308, an infinite size; each is one line naming
the file and line, with no numpy overflow warning and nothing written."""

import json
import math

import h5py
import numpy as np
import pytest

from simlidar.convert import convert_kitti
from simlidar.convert.kitti import crop_ranges, front_view
from simlidar.dataset.loaders import load_split
from simlidar.errors import ConfigError, DatasetError
from simlidar.release.checksums import read_sums
from simlidar.release.info import dataset_info, format_info
from simlidar.release.verify import verify

C_M_PER_S = 299_792_458.0
COLUMNS = 2000  # 360 deg / 0.18 deg
CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc")
SPLITS = ("train", "test")


def calibration(path):
    """(4, 4) Velodyne -> rectified camera: R0_rect @ Tr_velo_to_cam."""
    values = {}
    for line in path.read_text().splitlines():
        key, _, rest = line.partition(":")
        values[key] = np.array(rest.split(), dtype=float)
    r0, tr = np.eye(4), np.eye(4)
    r0[:3, :3] = values["R0_rect"].reshape(3, 3)
    tr[:3, :] = values["Tr_velo_to_cam"].reshape(3, 4)
    return r0 @ tr


def objects(path):
    """(type, h, w, l, x, y, z, ry) of every label but DontCare, in file order."""
    rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
    return [(r[0], *map(float, r[8:15])) for r in rows if r[0] != "DontCare"]


def points_in_box(points, velo_to_cam, h, w, length, x, y, z, ry):
    """(n,) bool: the points (n, 3) inside the box, tested in the box's own camera frame."""
    cam = (np.c_[points, np.ones(len(points))] @ velo_to_cam.T)[:, :3] - (x, y, z)
    c, s = math.cos(ry), math.sin(ry)
    along, across = c * cam[:, 0] - s * cam[:, 2], s * cam[:, 0] + c * cam[:, 2]
    return (
        (abs(along) <= length / 2) & (cam[:, 1] <= 0) & (cam[:, 1] >= -h) & (abs(across) <= w / 2)
    )


def cells(points, res_h=0.18, res_v=0.4):
    """The paper's front-view equations, written out again: (rows, columns) of each point."""
    rows = [
        math.floor(-math.degrees(math.atan2(p[2], math.hypot(p[0], p[1]))) / res_v) for p in points
    ]
    cols = [math.floor(math.degrees(math.atan2(-p[1], p[0])) / res_h) for p in points]
    return np.array(rows), np.array(cols)


def samples(path):
    """Every sample of both splits: a list of dicts of its records and the split's attrs."""
    out = []
    for split in ("train", "test"):
        with h5py.File(path / f"{split}.h5", "r") as f:
            for k in range(len(f["labels"])):
                out.append({n: f[n][k] for n in f} | {"split": split, "attrs": dict(f.attrs)})
    return out


def test_projection_by_hand():
    points = np.array([[10.0, -1.0, 0.0], [10.0, 1.0, -1.0], [-10.0, 1.0, 0.0], [3.0, 0.0, 4.0]])
    rows, cols = front_view(points, 0.18, 0.4)
    # atan(1/10) = 5.7106 deg -> 31.73 columns of 0.18 deg; to the left it is -31.73 -> -32.
    # elevation atan(-1 / sqrt(101)) = -5.6825 deg -> row floor(14.21) = 14.
    # behind on the left: atan2(-1, -10) = -174.2894 deg -> floor(-968.27) = -969.
    # atan2(4, 3) = 53.1301 deg up -> floor(-132.83) = -133.
    assert cols.tolist() == [31, -32, -969, 0]
    assert rows.tolist() == [0, 14, 0, -133]


def test_a_crop_keeps_the_nearest_point_and_wraps_around():
    rows = np.array([0, 0, 0, 1, 1, 1])
    cols = np.array([9, 9, 0, 1, 2, 5])  # of a 10-column view; the crop starts at column 8
    ranges = np.array([7.0, 5.0, 3.0, 4.0, 6.0, 8.0])
    crop = crop_ranges(rows, cols, ranges, (0, 8), (2, 4), 10)
    expected = np.full((2, 4), np.nan)
    expected[0, 1], expected[0, 2], expected[1, 3] = 5.0, 3.0, 4.0  # columns 8, 9, 0, 1
    np.testing.assert_array_equal(crop, expected)


def split_sizes(path):
    """{split: crops} of a converted dataset, read from its files."""
    return {s: len(h5py.File(path / f"{s}.h5", "r")["labels"]) for s in ("train", "test")}


def test_the_real_sample_gives_its_six_crops(real_kitti_dataset):
    found = samples(real_kitti_dataset)
    assert len(found) == 6  # 1 + 3 + 2 labelled objects, DontCare skipped
    frames = {split: sorted({s["frame"] for s in found if s["split"] == split}) for split in SPLITS}
    assert frames == {"train": [0, 1], "test": [2]}  # seed 0
    assert split_sizes(real_kitti_dataset) == {"train": 4, "test": 2}


def test_the_truck_of_frame_1_is_63_to_69_m_ahead(real_kitti_dataset, kitti_sample):
    truck = next(s for s in samples(real_kitti_dataset) if s["frame"] == 1 and s["labels"] == 2)
    base = kitti_sample / "training"
    _, h, w, length, x, y, z, ry = objects(base / "label_2" / "000001.txt")[0]
    points = np.fromfile(base / "velodyne" / "000001.bin", "<f4").reshape(-1, 4)[:, :3]
    inside = points_in_box(
        points.astype(float), calibration(base / "calib" / "000001.txt"), h, w, length, x, y, z, ry
    )
    rows, cols = cells(points[inside])
    i, j = rows - truck["crop_origin"][0], (cols - truck["crop_origin"][1]) % COLUMNS
    tof_ns = truck["delays"][i, j].astype(float) * truck["attrs"]["tof_max_ns"]
    range_m = tof_ns * 1e-9 * C_M_PER_S / 2
    # The label: centre 69.44 m ahead of the camera, 12.34 m long, seen from behind
    # (rotation_y ~ -pi/2), so its rear is 69.44 - 6.17 = 63.27 m ahead, and the Velodyne
    # sits 0.27 m behind the camera (Tr_velo_to_cam's translation): 63.5 m from the sensor.
    assert abs(ry + math.pi / 2) < 0.02 and z == pytest.approx(69.44)
    assert 63.3 < np.median(range_m) < 63.8
    assert np.median(range_m) + length / 2 == pytest.approx(69.71, abs=0.3)


def test_velodyne_points_inside_each_box_fall_inside_its_crop(kitti_dataset, kitti_root):
    base = kitti_root / "training"
    found = samples(kitti_dataset)
    frames = sorted(int(p.stem) for p in (base / "label_2").glob("*.txt"))
    labelled = {frame: objects(base / "label_2" / f"{frame:06d}.txt") for frame in frames}
    assert len(found) == sum(map(len, labelled.values())) > 0  # DontCare skipped
    for frame, labels in labelled.items():
        crops = [s for s in found if s["frame"] == frame]
        assert [s["labels"] for s in crops] == [CLASSES.index(o[0]) for o in labels]
        points = np.fromfile(base / "velodyne" / f"{frame:06d}.bin", "<f4").reshape(-1, 4)[:, :3]
        velo_to_cam = calibration(base / "calib" / f"{frame:06d}.txt")
        for sample, (_, *box) in zip(crops, labels):
            inside = points_in_box(points.astype(float), velo_to_cam, *box)
            assert sample["box_points"] == inside.sum() > 0
            rows, cols = cells(points[inside])
            i, j = rows - sample["crop_origin"][0], (cols - sample["crop_origin"][1]) % COLUMNS
            assert ((i >= 0) & (i < 50) & (j < 118)).all()
            own = np.linalg.norm(points[inside].astype(float), axis=1) / 100.0
            assert (sample["delays"][i, j] <= own + 1e-6).all()  # the cell's nearest return


def test_frames_split_apart_and_the_dataset_verifies(kitti_dataset):
    found = samples(kitti_dataset)
    frames = {
        split: {s["frame"] for s in found if s["split"] == split} for split in ("train", "test")
    }
    assert frames["train"] and frames["test"] and not frames["train"] & frames["test"]
    assert verify(kitti_dataset) == []
    x, y = load_split(kitti_dataset, "test")
    assert x.shape == (len(y), 50, 118) and x.dtype == np.float32
    assert ((x >= 0) & (x <= 1)).all() and (x < 1).any()
    text = format_info(dataset_info(kitti_dataset))
    assert "(kitti)" in text and "8 classes (object)" in text and "50 x 118 pulses" in text
    assert sorted(read_sums(kitti_dataset)) == [
        "README.md",
        "croissant.json",
        "preview.png",
        "test.h5",
        "train.h5",
    ]


def test_the_cards_call_gives_the_same_bytes(kitti_dataset, kitti_root, tmp_path):
    text = (kitti_dataset / "README.md").read_text()
    call = text.split("## Regenerate")[1].split("```python\n")[1].split("```")[0]
    call = call.replace("'ROOT', 'data'", f"{str(kitti_root)!r}, {str(tmp_path)!r}")
    exec(call.replace("seed=0,", "seed=0, progress=False,"), {})
    again = tmp_path / kitti_dataset.name
    for name in read_sums(kitti_dataset):
        assert (again / name).read_bytes() == (kitti_dataset / name).read_bytes(), name


def test_an_object_behind_the_sensor_wraps_around_the_seam(synthetic_kitti, tmp_path):
    path = convert_kitti(synthetic_kitti, tmp_path / "out", progress=False, preview=False)
    car = next(s for s in samples(path) if s["frame"] == 0)
    assert -COLUMNS // 2 <= car["crop_origin"][1] < COLUMNS // 2
    scan = synthetic_kitti / "training" / "velodyne" / "000000.bin"
    points = np.fromfile(scan, "<f4").reshape(-1, 4)[:, :3].astype(float)  # x = -9.5 m
    rows, cols = cells(points)
    assert cols.min() < -990 and cols.max() > 990  # both sides of the 180 deg seam
    i, j = rows - car["crop_origin"][0], (cols - car["crop_origin"][1]) % COLUMNS
    assert ((i >= 0) & (i < 50) & (j < 118)).all()
    np.testing.assert_allclose(car["delays"][i, j], np.linalg.norm(points, axis=1) / 100, rtol=1e-6)
    assert car["box_points"] == (points[:, 2] <= 0.5).sum()  # the box's top is 0.5 m up
    assert (car["delays"] < 1).sum() == len(points)  # nothing else in the scene


def test_a_frame_without_objects_joins_neither_split(synthetic_kitti, tmp_path):
    path = convert_kitti(synthetic_kitti, tmp_path / "out", progress=False, preview=False)
    found = samples(path)
    assert sorted(s["frame"] for s in found) == [0, 1]
    assert {s["split"] for s in found} == {"train", "test"}
    for s in found:
        assert s["attrs"]["frames_without_objects"].tolist() == [2]
    assert verify(path) == []


def test_more_frames_without_objects_than_an_object_header_holds(synthetic_kitti, tmp_path):
    """8,183 numbers (64 KB) do not fit the earliest HDF5 format's object header; a 40,000-frame
    sweep's 10,000 stopped its conversion at the very end. The file is then written in the
    1.8 format, with the same crops; where the numbers fit, the earliest format stays (and
    with it the bytes datasets always had)."""
    small = convert_kitti(synthetic_kitti, tmp_path / "small", progress=False, preview=False)
    base = synthetic_kitti / "training"
    calib = (base / "calib" / "000002.txt").read_text()
    for k in range(3, 8185):  # with 000002, 8,183 frames without objects: empty labels, scans
        (base / "velodyne" / f"{k:06d}.bin").write_bytes(b"")
        (base / "label_2" / f"{k:06d}.txt").write_text("")
        (base / "calib" / f"{k:06d}.txt").write_text(calib)
    path = convert_kitti(synthetic_kitti, tmp_path / "large", progress=False, preview=False)
    for split in ("train", "test"):
        with h5py.File(small / f"{split}.h5") as a, h5py.File(path / f"{split}.h5") as b:
            assert a.attrs["frames_without_objects"].tolist() == [2]
            assert b.attrs["frames_without_objects"].tolist() == list(range(2, 8185))
            assert a.id.get_create_plist().get_version()[0] == 0  # the earliest superblock
            assert b.id.get_create_plist().get_version()[0] > 0
            for name in a:
                np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
    assert verify(path) == []
    assert "(8183 without objects, in neither)" in (path / "README.md").read_text()


@pytest.mark.parametrize(
    "folder, stem, damage, words",
    [
        (
            "label_2",
            "000001",
            lambda t: "Pedestrian 0.5 1 0 0 0 10 10\n" + t,
            "000001.txt line 1: 8 columns, expected 15 (type truncated",
        ),
        (
            "label_2",
            "000001",
            lambda t: t + "Bus 0 0 0 0 0 1 1 1 1 1 0 0 5 0\n",
            "000001.txt line 2: type 'Bus', expected one of Car",
        ),
        (
            "label_2",
            "000000",
            lambda t: t.replace("1.60", "x"),
            "000000.txt line 1: 'x' is not a number",
        ),
        (
            "label_2",
            "000000",
            lambda t: t.replace("1.50 1.60 4.00", "1e308 1e308 1e308"),
            "000000.txt line 1: box size h w l = 1e308 1e308 1e308, expected positive metres",
        ),
        (
            "label_2",
            "000000",
            lambda t: t.replace("1.60 4.00 0.00", "1.60 4.00 1e308"),
            "000000.txt line 1: box location x y z = 1e308 1.00 -10.00, expected metres within",
        ),
        (
            "label_2",
            "000000",
            lambda t: t.replace("Car 0.00", "Car 1e308"),
            "000000.txt line 1: truncated '1e308', expected 0..1",
        ),
        (
            "label_2",
            "000000",
            lambda t: t.replace("1.60", "inf"),
            "000000.txt line 1: 'inf': expected a finite number",
        ),
        (
            "calib",
            "000001",
            lambda t: t.replace("0 -1 0 0 0 0 -1 0 1 0 0 0", "0 -1 0"),
            "000001.txt line 3: Tr_velo_to_cam has 3 numbers, expected 12",
        ),
        (
            "calib",
            "000000",
            lambda t: t.replace("R0_rect:", "R0_rect"),
            "000000.txt line 2: 'R0_rect 1 0 0 0 1 0 0 0 1', expected 'KEY: numbers'",
        ),
        (
            "calib",
            "000000",
            lambda t: t.replace("R0_rect", "R1_rect"),
            "000000.txt: no R0_rect line",
        ),
    ],
)
@pytest.mark.filterwarnings("error")  # numpy's overflow warnings: the input got through
def test_malformed_files_are_named_and_nothing_is_written(
    synthetic_kitti, tmp_path, folder, stem, damage, words
):
    file = synthetic_kitti / "training" / folder / f"{stem}.txt"
    file.write_text(damage(file.read_text()))
    with pytest.raises(DatasetError, match=words.replace("(", r"\(")):
        convert_kitti(synthetic_kitti, tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_a_bad_scan_midway_leaves_no_half_dataset(synthetic_kitti, tmp_path):
    (synthetic_kitti / "training" / "velodyne" / "000001.bin").write_bytes(b"\0" * 20)
    (tmp_path / "out").mkdir()
    with pytest.raises(DatasetError, match=r"000001.bin: 20 bytes, expected a multiple of 16"):
        convert_kitti(synthetic_kitti, tmp_path / "out", progress=False)
    assert list((tmp_path / "out").iterdir()) == []


def test_one_frame_with_objects_is_refused(synthetic_kitti, tmp_path):
    (synthetic_kitti / "training" / "label_2" / "000001.txt").write_text("")
    with pytest.raises(DatasetError, match=r"1 frame\(s\) with labelled objects: expected at "):
        convert_kitti(synthetic_kitti, tmp_path / "out", progress=False)


def test_options_are_checked_and_an_existing_dataset_kept(synthetic_kitti, tmp_path):
    with pytest.raises(ConfigError, match=r"res_h_deg=0.17: expected degrees in \(0, 10\] "):
        convert_kitti(synthetic_kitti, tmp_path, res_h_deg=0.17)
    with pytest.raises(ConfigError, match=r"test_fraction=1.0: expected a fraction in \(0, 1\)"):
        convert_kitti(synthetic_kitti, tmp_path, test_fraction=1.0)
    with pytest.raises(ConfigError, match=r"crop=\(0, 10\): expected \(rows, columns\)"):
        convert_kitti(synthetic_kitti, tmp_path, crop=(0, 10))
    path = convert_kitti(synthetic_kitti, tmp_path, crop=(8, 16), progress=False, preview=False)
    assert path.name == "kitti-front-8x16-v1.0.0" and load_split(path)[0].shape[1:] == (8, 16)
    with pytest.raises(DatasetError, match="already exists: pass --force"):
        convert_kitti(synthetic_kitti, tmp_path, crop=(8, 16), progress=False)
    before = (path / "train.h5").stat().st_mtime_ns
    convert_kitti(
        synthetic_kitti, tmp_path, crop=(8, 16), force=True, progress=False, preview=False
    )
    assert (path / "train.h5").stat().st_mtime_ns != before and verify(path) == []
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_the_card_and_croissant_are_made_from_the_files(kitti_dataset, caplog):
    import mlcroissant as mlc
    from huggingface_hub import DatasetCard

    from simlidar.any_card import render_card

    text = (kitti_dataset / "README.md").read_text()
    assert render_card(kitti_dataset) == text  # the shared entry point (simlidar card)
    card = DatasetCard.load(kitti_dataset / "README.md")
    assert card.data.license == "cc-by-nc-sa-3.0"
    splits = {s["name"]: s["num_examples"] for s in card.data.to_dict()["dataset_info"]["splits"]}
    assert splits == split_sizes(kitti_dataset)
    found = samples(kitti_dataset)
    frames = {split: len({s["frame"] for s in found if s["split"] == split}) for split in SPLITS}
    empty = len(found[0]["attrs"]["frames_without_objects"])
    for words in (
        "@inproceedings{geiger2012kitti",
        "@article{wang2020temporal",
        "convert_kitti('ROOT', 'data', crop=(50, 118)",
        "667.128 ns: the delay 1.0",
        f"frames | train {frames['train']}, test {frames['test']} ({empty} without objects, "
        "in neither)",
    ):
        assert words in text, words
    dataset = mlc.Dataset(jsonld=kitti_dataset / "croissant.json")
    assert dataset.metadata.name == kitti_dataset.name
    assert not any("not standard" in r.getMessage() for r in caplog.records)


def test_simlidar_verify_and_info_take_a_converted_dataset(kitti_dataset, cli):

    sizes = split_sizes(kitti_dataset)
    done = cli("verify", str(kitti_dataset))
    assert done.exit_code == 0, done.output
    assert f"OK (dataset version 1.0.0, train {sizes['train']}, test {sizes['test']}" in done.output
    done = cli("info", str(kitti_dataset))
    assert done.exit_code == 0 and "Truck" in done.output


def test_cli_converts_the_sample_and_benches_it_end_to_end(
    kitti_root, kitti_dataset, tmp_path, cli
):
    """`simlidar convert kitti` then `simlidar bench --dataset`: the paper's KITTI pair (the
    spiking CNN, here narrowed, and the CNN) trains and scores on the real crops."""

    done = cli("convert", "kitti", str(kitti_root), "--out", str(tmp_path / "data"), "--json")
    assert done.exit_code == 0, done.output
    record = json.loads(done.output)
    assert record["splits"] == split_sizes(kitti_dataset)
    scnn = tmp_path / "scnn_small.toml"
    scnn.write_text(
        'model = "scnn"\n[architecture]\nconv = [[4, 5, 2], [4, 5, 2]]\n'
        'dense = [16]\n[training]\noptimizer = "adam"\nlr = 1e-3\nbatch_size = 2\n'
        "epochs = 1\n"
    )
    suite = tmp_path / "kitti.toml"
    suite.write_text(
        f'models = ["cnn", "{scnn}"]\ndatasets = ["{record["path"]}"]\n[budget]\nepochs = 1\n'
    )
    args = ["bench", "--suite", str(suite), "--out", str(tmp_path / "b"), "--json"]
    few = cli(*args)  # a few crops: nothing to hold out for model selection
    assert few.exit_code == 2 and not (tmp_path / "b").exists()
    assert few.output.count("\n") == 1 and "recipe cnn: key 'training.validation': " in few.output
    assert "--validation 0" in few.output
    bench = cli(*args, "--validation", "0")
    assert bench.exit_code == 0, bench.output
    cells = json.loads(bench.stdout)["cells"]
    assert {c["model"] for c in cells} == {"cnn", "scnn_small"}
    for c in cells:
        assert c["source"] == "kitti" and c["input_shape"] == [1, 50, 118]
        assert c["classes"] == 8 and c["test_size"] == record["splits"]["test"]
        assert sum(map(sum, c["confusion"])) == c["test_size"]
    report = (tmp_path / "b" / "report.md").read_text()
    assert "The paper on KITTI" in report and "scnn 96.62 %" in report

    bad = cli("convert", "kitti", str(tmp_path / "nowhere"))
    assert bad.exit_code == 1 and "expected the KITTI object benchmark" in bad.output
