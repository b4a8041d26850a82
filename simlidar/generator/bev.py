"""A sweep's pictures from above, points coloured by surface: ``bev.png``, a few of its frames
(:func:`draw_bev`), and for a sweep in motion ``motion.png``, one frame raw and deskewed side by
side, and ``sequence.gif``, a sequence in the frame of its first reference pose
(:func:`draw_motion`). The sensor's frame is drawn with x forward up the picture and y left to
the left."""

import json
from pathlib import Path

import numpy as np

from simlidar.atomic import write_files
from simlidar.generator.frames import check_frame, deskewed_xyz, frame_points
from simlidar.motion.poses import Poses

MOTION_PICTURE = "motion.png"
SEQUENCE_ANIMATION = "sequence.gif"
# motion.png's window, metres either way of the sensor. A frame's skew is the ego's travel over
# a rotation (1 m at 10 m/s and 600 RPM), largest between the points scanned first and last,
# behind and beside the sensor, where the catalog's scenes end 0-10 m back: this window draws
# a metre in 11 pixels at 120 dpi, draw_bev's 80 m wide one in 3.6
PAIR_REACH_M = 15.0
# sequence.gif's window, metres across and from behind to ahead of the first frame's reference
# pose: the catalog's scenes reach about 80 m ahead, and 2 s at 20 m/s leave the sensor at 40 m
ANIMATION_ACROSS_M = (-25.0, 25.0)
ANIMATION_AHEAD_M = (-15.0, 85.0)
# A short animation, the figure a user looks at first: 2 s of a VLP-16 at 600 RPM
ANIMATION_FRAMES = 20
# 380 x 560 pixels, 4.6 a metre. Every point drawn: a GIF's size follows the dots' scatter more
# than their count. 20 frames measured at 179 KB (`simlidar sweep --frames 40
# --sequence-frames 20 --ego-speed 10 --moving-objects`: a tunnel; every other point 144 KB)
# to 501 KB (the HDL-64E, 4.6 times the points, on an open road turning at 15 deg/s: the
# ground's rings fill the view): small enough for a docs page and beside every sweep in motion
ANIMATION_DPI = 100
# the points' areas in the animation (points^2), one a surface for the whole sequence (a count
# crossing draw_bev's threshold would make a surface flicker): the objects' few points larger
ANIMATION_SIZE = 1.0
ANIMATION_OBJECT_SIZE = 4.0


def draw_bev(
    path: str | Path, out: str | Path, frames: list[int] | None = None, reach_m: float = 40.0
) -> Path:
    """Bird's-eye views of frames ``frames`` of a sweep file, points coloured by surface,
    written as a PNG. Default: up to four frames of different layouts, with objects, as
    varied as the file has (:func:`_varied_frames`)."""
    import h5py
    from matplotlib.figure import Figure

    with h5py.File(path, "r") as f:
        names = json.loads(f.attrs["surface_names"])
        classes = json.loads(f.attrs["class_names"])
        labels = f["labels"][:]
        layout, obj = f["layout"][:], f["object"][:]
    frames = _varied_frames(layout, obj) if frames is None else frames
    fig = Figure(figsize=(3.0 * len(frames), 4.0))
    for k, frame in enumerate(frames):
        points = frame_points(path, frame)
        ax = fig.add_subplot(1, len(frames), k + 1)
        _scatter(ax, -points["y"], points["x"], points["surface"], names)
        extent = (-reach_m, reach_m), (-reach_m / 2, reach_m * 2)
        _axes(ax, f"frame {frame}: {classes[labels[frame]]}", *extent)
    _label(fig)
    fig.savefig(out, dpi=120)
    return Path(out)


def draw_motion(frames_file: Path, out_dir: Path) -> list[Path]:
    """For a sweep in motion (its frames store ``ego_pose``), write into ``out_dir``, both or
    neither (:func:`simlidar.atomic.write_files`):

    * ``motion.png``: the frame with the most object points, raw (each point where its own
      pulse's pose put it) beside deskewed (moved to the frame's reference pose,
      :func:`~simlidar.generator.frames.deskewed_xyz`);
    * ``sequence.gif``: up to :data:`ANIMATION_FRAMES` frames of that frame's sequence (the
      first sequence where no frame sees an object), each deskewed and placed in the frame of
      the sequence's first reference pose, so the static world stands still while the ego
      (a black arrow) and the object move; one frame a rotation, in real time.

    A sweep not in motion: nothing written, []."""
    import h5py

    with h5py.File(frames_file, "r") as f:
        sensor = check_frame(f, frames_file, 0)
        if "ego_pose" not in f:
            return []
        sweep = {key: f[key][:] for key in ("sequence", "start_ns", "object_points")}
        sweep |= {key: f[key][:] for key in ("labels", "object", "object_motion")}
        sweep |= {key: json.loads(f.attrs[key]) for key in ("config", "class_names")}
        sweep |= {key: json.loads(f.attrs[key]) for key in ("surface_names", "object_names")}
    frame, shown = shown_frames(sweep["sequence"], sweep["object_points"])

    def write(temporaries: list[Path]) -> None:
        _draw_pair(frames_file, frame, sweep, temporaries[0])
        _animate(frames_file, shown, sweep, sensor, temporaries[1])

    paths = [Path(out_dir) / MOTION_PICTURE, Path(out_dir) / SEQUENCE_ANIMATION]
    return write_files(paths, write, what="the motion pictures")


def shown_frames(sequence: np.ndarray, object_points: np.ndarray) -> tuple[int, np.ndarray]:
    """The frame :func:`draw_motion` shows raw and deskewed, the first with the most object
    points, and the frames it animates, up to :data:`ANIMATION_FRAMES` of that frame's
    sequence. A sweep's first sequence is its class 0, which has no object (tunnel/none, or
    none), so its first sequence would show the ego alone.

    sequence, object_points : (N,) int, each frame's sequence and its object's returns
    returns : the frame, and (F,) int the frames animated, in order
    """
    frame = int(np.argmax(object_points))
    return frame, np.flatnonzero(sequence == sequence[frame])[:ANIMATION_FRAMES]


def first_pose_xyz(
    path: Path, frame: int, first: int, points: np.ndarray
) -> tuple[np.ndarray, Poses]:
    """The points ``points`` of frame ``frame`` (:func:`frame_points`) deskewed
    (:func:`deskewed_xyz`) and moved into the sensor's frame at frame ``first``'s reference
    pose, where the static world of a sequence stays put.

    returns : (P, 3) float64 metres, and the frame's reference pose of the rig (the sensor's
        frame on the road) in the first's (:class:`Poses`)
    """
    import h5py

    with h5py.File(path, "r") as f:
        sensor = check_frame(f, path, frame)
        pose, first_pose = _poses(f["ego_pose"][frame]), _poses(f["ego_pose"][first])
    mount = np.array([0.0, 0.0, sensor.mount_height_m])  # the poses' frame stands on the road
    ego = pose.relative_to(first_pose)
    return ego.to_scene(deskewed_xyz(path, frame, points) + mount) - mount, ego


def _draw_pair(path: Path, frame: int, sweep: dict, out: Path) -> None:
    """``motion.png``: frame ``frame`` raw and deskewed side by side."""
    from matplotlib.figure import Figure

    points = frame_points(path, frame)
    deskewed = deskewed_xyz(path, frame, points)
    fig = Figure(figsize=(7.0, 4.0))
    names = sweep["surface_names"]
    views = {
        "raw: each point from its pulse's pose": (-points["y"], points["x"]),
        "deskewed to the frame's reference pose": (-deskewed[:, 1], deskewed[:, 0]),
    }
    for k, (title, (across, ahead)) in enumerate(views.items()):
        ax = fig.add_subplot(1, 2, k + 1)
        _scatter(ax, across, ahead, points["surface"], names)
        window = (-PAIR_REACH_M, PAIR_REACH_M)
        _axes(ax, title, window, window, marker=12.0)
    fig.suptitle(f"{_ego(sweep)}; frame {frame}: {_scene(sweep, frame)}", fontsize=8)
    _label(fig)
    fig.savefig(out, dpi=120)


def _animate(path: Path, shown: np.ndarray, sweep: dict, sensor, out: Path) -> None:
    """``sequence.gif``: frames ``shown`` (one sequence's, in order) deskewed and placed in the
    frame of the first one's reference pose."""
    from matplotlib.animation import PillowWriter
    from matplotlib.figure import Figure

    names = sweep["surface_names"]
    moving = [names.index(n) for n in sweep["object_names"][1:] if n in names]  # 0: none
    frames = []
    for frame in shown:
        points = frame_points(path, frame)
        xyz, ego = first_pose_xyz(path, frame, shown[0], points)
        frames.append((frame, xyz, points["surface"], ego))
    # one legend for the whole sequence: a surface that leaves the view keeps its entry
    surfaces = sorted(set(np.concatenate([surface for _, _, surface, _ in frames]).tolist()))
    # one size a surface too, as a count that crosses draw_bev's threshold would flicker
    sizes = {s: ANIMATION_OBJECT_SIZE if s in moving else ANIMATION_SIZE for s in surfaces}
    fig = Figure(figsize=(3.8, 5.6))
    ax = fig.add_subplot()
    # the artists made once, their points moved from frame to frame: the axes, their ticks and
    # the layout stay the same in every frame, and are not laid out again for each
    nothing = np.empty(0)
    dots = _scatter(ax, nothing, nothing, nothing, names, surfaces, sizes)
    arrow = ax.arrow(0.0, 0.0, 0.0, 1.0, width=0.8, length_includes_head=True, color="k")
    _axes(ax, "\n", ANIMATION_ACROSS_M, ANIMATION_AHEAD_M, marker=12.0)  # two lines of title
    fig.supxlabel("right (m)", fontsize=7)
    fig.supylabel("ahead of the first frame's reference pose (m)", fontsize=7)
    fig.tight_layout()
    writer = PillowWriter(fps=sensor.rpm / 60.0)  # a frame a rotation: real time
    # not writer.saving(): on an error it would still write the file, and hide the error
    # behind its own where no frame was grabbed yet
    writer.setup(fig, out, dpi=ANIMATION_DPI)
    for frame, xyz, surface, ego in frames:
        for s, collection in zip(surfaces, dots):
            collection.set_offsets(np.stack([-xyz[surface == s, 1], xyz[surface == s, 0]], 1))
        (x, y), (dx, dy) = ego.translation_m[:2], 5.0 * ego.rotation[:2, 0]  # 5 m along its x
        arrow.set_data(x=-y, y=x, dx=-dy, dy=dx)
        seconds = (sweep["start_ns"][frame] - sweep["start_ns"][shown[0]]) * 1e-9
        scene = _scene(sweep, frame)
        ax.set_title(f"{_ego(sweep)}\n{seconds:.1f} s, frame {frame}: {scene}", fontsize=8)
        writer.grab_frame()
    writer.finish()


def _poses(pose: np.ndarray) -> Poses:
    """A stored pose, (3, 4) [R | p], as :class:`Poses`."""
    return Poses(pose[:, :3], pose[:, 3])


def _ego(sweep: dict) -> str:
    """How the ego moves, from the sweep's configuration."""
    config = sweep["config"]
    if config.get("ego_trajectory"):
        return f"ego on a trajectory file ({config['ego_trajectory']['rows']} poses)"
    speed, yaw_rate = config.get("ego_speed_mps", 0.0), config.get("ego_yaw_rate_deg_s", 0.0)
    return f"ego {speed:g} m/s, yaw rate {yaw_rate:g} deg/s"


def _scene(sweep: dict, frame: int) -> str:
    """Frame ``frame``'s class and its object's drawn motion."""
    text = sweep["class_names"][sweep["labels"][frame]]
    speed, heading, _ = sweep["object_motion"][frame]
    if speed:
        text += f", {sweep['object_names'][sweep['object'][frame]]} {speed:.1f} m/s"
        text += f" at {heading:g} deg"
    return text


def _scatter(ax, across_m, ahead_m, surface, names, surfaces=None, sizes=None) -> list:
    """Points (P,) seen from above, ``across_m`` to the right and ``ahead_m`` ahead, each
    coloured by its surface (indices into ``names``), one legend entry a surface of
    ``surfaces`` (default: those present), of area ``sizes[surface]`` (points^2; default: small
    where a surface has many points). The scatters made, one a surface, in that order."""
    from matplotlib import colormaps

    palette = colormaps["tab20"]
    made = []
    for s in sorted(set(surface.tolist())) if surfaces is None else surfaces:
        mine = surface == s
        if sizes is None:
            size = 0.4 if mine.sum() > 1000 else 3.0  # small things (objects, lamps) larger
        else:
            size = sizes[s]
        made.append(
            ax.scatter(
                across_m[mine],
                ahead_m[mine],
                s=size,
                color=palette(s % 20),
                label=names[s],
                linewidths=0,
            )
        )
    return made


def _axes(ax, title: str, across_m: tuple, ahead_m: tuple, marker: float | None = None) -> None:
    """A bird's-eye axes' extent (``across_m``: its left and right edges, metres to the right
    of the sensor; ``ahead_m``: its bottom and top, metres ahead), title and legend, whose
    markers all have the area ``marker`` (points^2; by default :data:`LEGEND_MARKER`), whatever
    the points' sizes, so that no marker covers a label."""
    ax.set_xlim(*across_m)
    ax.set_ylim(*ahead_m)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=8)
    ax.tick_params(labelsize=6)
    legend = ax.legend(fontsize=5, loc="lower left")
    for handle in legend.legend_handles:
        handle.set_sizes([LEGEND_MARKER if marker is None else marker])


# a legend marker's area in points^2: about the height of its 5-point label (markers scaled
# from the points' own sizes grew to 30 points across for an object's and covered the labels)
LEGEND_MARKER = 12.0


def _label(fig) -> None:
    """A figure of bird's-eye axes: its axis labels, laid out."""
    fig.supxlabel("right of the sensor (m)", fontsize=8)
    fig.supylabel("ahead of the sensor (m)", fontsize=8)
    fig.tight_layout()


def _varied_frames(layout: np.ndarray, obj: np.ndarray, most: int = 4) -> list[int]:
    """Up to ``most`` frames of different layouts: first those that also bring a new object,
    then any with a new layout and an object, then any frame, in frame order."""
    chosen: list[int] = []
    rules = [
        lambda f: obj[f] and obj[f] not in obj[chosen],
        lambda f: bool(obj[f]),
        lambda f: True,
    ]
    for rule in rules:
        for f in range(len(layout)):
            if len(chosen) < most and layout[f] not in layout[chosen] and rule(f):
                chosen.append(f)
    return sorted(chosen)
