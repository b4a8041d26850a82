"""docs/img/streams-example.png: one stream of each class of a stream dataset, its events over
the sensor's time (column of the window against arrival time), the object's in colour, the
time it first returns marked; through a receiver, the weather's and the noise's echoes (surface
0) in their own colour, and an object the receiver never detected marked where it came into
view.

    python benchmark/stream_figure.py DATASET [--split test] [--out docs/img/streams-example.png]

DATASET: a directory written by ``simlidar stream`` (the docs' figures: ``simlidar stream
--train-size 4 --test-size 8 --out /tmp/streams``, with ``--profile sensor --fog 100`` for
docs/img/streams-fog-example.png).
"""

import argparse
from pathlib import Path

import numpy as np

from simlidar.dataset.loaders import split_info
from simlidar.dataset.reader import load_arrays
from simlidar.script_args import in_folder, run


def draw(dataset: Path, split: str, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    info = split_info(dataset, split)
    names = ("labels", "t_visible_us", "event_start", "event_count", "scenario")
    received = "receiver" in info.attrs
    rows = load_arrays(info.files[0], names + (("t_in_view_us",) if received else ()))
    events = load_arrays(info.files[0], ("event_x", "event_t_us", "event_surface"))
    classes = info.attrs["class_names"]
    scenarios = info.attrs["scenario_names"]
    surfaces = list(info.attrs["surface_names"])
    objects = [surfaces.index(n) for n in ("car", "pedestrian", "truck") if n in surfaces]
    fig, axes = plt.subplots(len(classes), 1, figsize=(9, 2.0 * len(classes)), sharex=True)
    for label, ax in enumerate(np.atleast_1d(axes)):
        i = int(np.nonzero(rows["labels"] == label)[0][0])
        first = rows["event_start"][i]
        part = slice(first, first + rows["event_count"][i])
        t_ms = events["event_t_us"][part] / 1e3
        x, surface = events["event_x"][part], events["event_surface"][part]
        on = np.isin(surface, objects)
        echo = surface == 0  # the weather's and the noise's (through a receiver)
        scene = ~on & ~echo
        ax.scatter(t_ms[scene], x[scene], s=1, c="0.6", label="scene")
        if received:
            ax.scatter(t_ms[echo], x[echo], s=1, c="tab:blue", label="fog, drops, noise")
        ax.scatter(t_ms[on], x[on], s=4, c="tab:red", label="object")
        visible = rows["t_visible_us"][i]
        title = f"{classes[label]} ({scenarios[rows['scenario'][i]]})"
        if np.isfinite(visible):
            ax.axvline(visible / 1e3, color="tab:red", lw=0.8, ls="--")
            title += f": first object return at {visible / 1e3:.1f} ms"
        elif received and np.isfinite(rows["t_in_view_us"][i]):
            in_view = rows["t_in_view_us"][i] / 1e3
            ax.axvline(in_view, color="tab:red", lw=0.8, ls=":")
            title += f": in view from {in_view:.1f} ms, never detected"
        ax.set_title(title, fontsize=9, loc="left")
        ax.set_ylabel("column")
    np.atleast_1d(axes)[-1].set_xlabel("arrival time, ms from the stream's first firing")
    np.atleast_1d(axes)[0].legend(loc="upper right", fontsize=8, markerscale=4)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--split", choices=("train", "test"), default="test")
    parser.add_argument("--out", type=in_folder, default=Path("docs/img/streams-example.png"))
    args = parser.parse_args(argv)
    draw(args.dataset, args.split, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
