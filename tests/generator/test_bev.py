"""A sweep's pictures (simlidar/generator/bev.py): for a sweep in motion, one frame raw and
deskewed (motion.png) and its sequence as an animation (sequence.gif), placed so that the static
world stands still; both written or neither, the same bytes each time."""

import json
import os

import h5py
import numpy as np
import pytest
from matplotlib.animation import PillowWriter
from PIL import Image

from simlidar.errors import ConfigError, DatasetError
from simlidar.generator.bev import draw_motion, first_pose_xyz, shown_frames
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.frames import frame_points
from simlidar.generator.sweep import SweepConfig, sweep


@pytest.fixture(scope="module")
def moving(tmp_path_factory, catalog):
    """frames.h5 of `simlidar sweep --frames 4 --sequence-frames 4 --ego-speed 10
    --moving-objects`: one sequence of class 0 (tunnel, no object)."""
    config = GeneratorConfig(ego_speed_mps=10.0, moving_objects=True)
    out = tmp_path_factory.mktemp("moving")
    path = sweep(config, SweepConfig(frames=4, sequence_frames=4), catalog, out, progress=False)
    return path / "frames.h5"


def test_a_sweep_in_motion_gets_both_pictures_the_same_bytes_each_time(moving, tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    written = draw_motion(moving, tmp_path / "a")
    assert written == [tmp_path / "a" / "motion.png", tmp_path / "a" / "sequence.gif"]
    assert sorted(os.listdir(tmp_path / "a")) == ["motion.png", "sequence.gif"]  # no temporary
    with Image.open(written[0]) as png:
        assert png.format == "PNG" and png.size == (840, 480)  # 7 x 4 inches at 120 dpi
    with Image.open(written[1]) as gif:
        # the sequence's 4 frames, one a rotation of the VLP-16 at 600 RPM: real time
        assert gif.format == "GIF" and gif.n_frames == 4 and gif.size == (380, 560)
        assert gif.info["duration"] == 100 and gif.info["loop"] == 0
        gif.seek(3)
        assert gif.convert("L").getextrema()[0] < 128  # drawn on, not a blank frame
    again = draw_motion(moving, tmp_path / "b")
    for one, other in zip(written, again):
        assert one.read_bytes() == other.read_bytes()


def test_a_sweep_not_in_motion_gets_none(catalog, tmp_path):
    path = sweep(GeneratorConfig(), SweepConfig(frames=1), catalog, tmp_path, progress=False)
    (tmp_path / "out").mkdir()
    assert draw_motion(path / "frames.h5", tmp_path / "out") == []
    assert not any((tmp_path / "out").iterdir())


def test_the_frame_shown_has_the_most_object_points_and_its_sequence_is_animated():
    """A sweep's first sequence is class 0, which has no object: the frame the pictures show is
    the first with the most object points, and the animation up to 20 of its sequence's."""
    sequence = np.repeat([0, 1], [3, 25])
    object_points = np.zeros(28, dtype=np.int32)
    object_points[3:8] = [5, 9, 9, 2, 0]
    frame, shown = shown_frames(sequence, object_points)
    assert frame == 4
    np.testing.assert_array_equal(shown, np.arange(3, 23))
    frame, shown = shown_frames(sequence, np.zeros(28, dtype=np.int32))  # no object anywhere
    assert frame == 0
    np.testing.assert_array_equal(shown, [0, 1, 2])


def test_the_static_world_stands_still_in_the_first_frames_pose(wall_catalog, tmp_path):
    """A car at 10 m/s before a wall whose face is at x = 20 m; a VLP-16 at 600 RPM. Frame 0's
    reference time is its middle cycle, 904 x 55.296 us = 49.988 ms, the car 0.49988 m on:
    there the wall stands 19.50012 m ahead, and every frame's wall, deskewed and placed in
    that pose, stands there too (within the range's 2 mm quantisation), while the ego moves
    on a rotation (1808 or 1809 cycles, 99.98 or 100.04 ms, about 1 m) a frame."""
    config = GeneratorConfig(ego_speed_mps=10.0)
    chosen = SweepConfig(frames=3, sequence_frames=3)
    path = sweep(config, chosen, wall_catalog, tmp_path, progress=False)
    path = path / "frames.h5"
    with h5py.File(path) as f:
        wall = json.loads(f.attrs["surface_names"]).index("wall")
    reference_m = 10.0 * 904 * 55.296e-6
    for frame in range(3):
        points = frame_points(path, frame)
        xyz, ego = first_pose_xyz(path, frame, 0, points)
        on_wall = points["surface"] == wall
        assert on_wall.sum() > 5000
        np.testing.assert_allclose(xyz[on_wall, 0], 20.0 - reference_m, atol=0.002)
        travel_m = ego.translation_m[0]
        assert travel_m == pytest.approx(frame * 1.0, abs=0.001)
        np.testing.assert_allclose(ego.translation_m[1:], 0.0, atol=1e-12)


def test_a_failure_while_drawing_leaves_neither_picture(moving, tmp_path, monkeypatch):
    """motion.png is drawn first; the animation then fails: neither file, nor a temporary."""

    def fail(self, **options):
        raise RuntimeError("the animation's frame cannot be grabbed")

    monkeypatch.setattr(PillowWriter, "grab_frame", fail)
    with pytest.raises(RuntimeError, match="cannot be grabbed"):
        draw_motion(moving, tmp_path)
    assert not any(tmp_path.iterdir())


def test_a_missing_folder_is_one_line_and_nothing_written(moving, tmp_path):
    with pytest.raises(DatasetError, match=r"motion\.png: cannot write the motion pictures \("):
        draw_motion(moving, tmp_path / "missing")
    assert not (tmp_path / "missing").exists()


def test_a_file_that_is_not_a_sweep_is_refused(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.attrs["format"] = "something else"
    (tmp_path / "out").mkdir()
    with pytest.raises(ConfigError, match=r"other\.h5: expected a simlidar sweep file"):
        draw_motion(tmp_path / "other.h5", tmp_path / "out")
    assert not any((tmp_path / "out").iterdir())


def test_every_legend_marker_has_one_size_so_none_covers_a_label():
    """A bird's-eye legend's markers all have LEGEND_MARKER's area, however large the points
    of their surface are drawn (an object's markers were scaled to 30 points across and
    covered the labels below them)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from simlidar.generator.bev import LEGEND_MARKER, _axes, _scatter

    fig, ax = plt.subplots()
    many = np.zeros(2000)
    _scatter(ax, np.r_[many, 1.0], np.r_[many, 2.0], np.r_[many.astype(int), 1], ["road", "car"])
    _axes(ax, "two surfaces", (-40, 40), (-20, 80))
    sizes = [float(h.get_sizes()[0]) for h in ax.get_legend().legend_handles]
    plt.close(fig)
    assert sizes == [LEGEND_MARKER, LEGEND_MARKER]
