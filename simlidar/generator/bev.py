"""A sweep's bird's-eye picture (``bev.png``): a few of its frames seen from above, points
coloured by surface."""

import json
from pathlib import Path

import numpy as np

from simlidar.generator.frames import frame_points


def draw_bev(
    path: str | Path, out: str | Path, frames: list[int] | None = None, reach_m: float = 40.0
) -> Path:
    """Bird's-eye views of frames ``frames`` of a sweep file, points coloured by surface,
    written as a PNG. Default: up to four frames of different layouts, with objects, as
    varied as the file has (:func:`_varied_frames`)."""
    import h5py
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    with h5py.File(path, "r") as f:
        names = json.loads(f.attrs["surface_names"])
        classes = json.loads(f.attrs["class_names"])
        labels = f["labels"][:]
        layout, obj = f["layout"][:], f["object"][:]
    frames = _varied_frames(layout, obj) if frames is None else frames
    fig = Figure(figsize=(3.0 * len(frames), 4.0))
    palette = colormaps["tab20"]
    for k, frame in enumerate(frames):
        points = frame_points(path, frame)
        ax = fig.add_subplot(1, len(frames), k + 1)
        for s in sorted(set(points["surface"].tolist())):
            mine = points[points["surface"] == s]
            # x forward is up the picture, y left is left
            size = 0.4 if len(mine) > 1000 else 3.0  # small things (objects, lamps) larger
            ax.scatter(
                -mine["y"], mine["x"], s=size, color=palette(s % 20), label=names[s], linewidths=0
            )
        ax.set_xlim(-reach_m, reach_m)
        ax.set_ylim(-reach_m / 2, reach_m * 2)
        ax.set_aspect("equal")
        ax.set_title(f"frame {frame}: {classes[labels[frame]]}", fontsize=8)
        ax.tick_params(labelsize=6)
        ax.legend(fontsize=5, markerscale=10, loc="lower left")
    fig.supxlabel("right of the sensor (m)", fontsize=8)
    fig.supylabel("ahead of the sensor (m)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    return Path(out)


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
