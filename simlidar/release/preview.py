"""The preview picture: one example per class, delays as grey levels."""

from pathlib import Path

import numpy as np

from simlidar.atomic import write_file
from simlidar.dataset.reader import SplitInfo, dataset_splits
from simlidar.dataset.version import GENERATOR


def first_of_each_class(labels: np.ndarray, classes: int) -> np.ndarray:
    """Row index of the first sample of every class (-1 where a class has none)."""
    rows = np.full(classes, -1)
    for c in range(classes):
        hit = np.nonzero(labels == c)[0]
        if len(hit):
            rows[c] = hit[0]
    return rows


def write_preview(
    dataset: str | Path, out: str | Path, split: str = "test", title: str | None = None
) -> Path:
    """Draw the first ``split`` sample of every class of the dataset directory ``dataset``
    (checked whole, every split) into the PNG file ``out``."""
    return draw_preview(dataset_splits(dataset)[split], split, out, title or Path(dataset).name)


def draw_preview(info: SplitInfo, split: str, out: str | Path, title: str) -> Path:
    """Draw the first sample of every class of ``info``, the split named ``split``, into the
    PNG file ``out``; the generator draws its test split while it writes the train split."""
    from matplotlib.figure import Figure

    names = info.attrs["class_names"]
    labels = info.read(("labels",))["labels"]
    rows = first_of_each_class(labels, len(names))
    present = np.unique(rows[rows >= 0])  # read these rows only: memory stays flat
    delays = dict(zip(present, info.read(("delays",), present)["delays"]))
    n_cols = 4 if len(names) % 4 == 0 else min(len(names), 6)
    n_rows = -(-len(names) // n_cols)
    fig = Figure(figsize=(2.2 * n_cols, 2.0 * n_rows + 0.6), layout="constrained")
    axes = fig.subplots(n_rows, n_cols, squeeze=False)
    for ax in axes.flat[len(names) :]:
        ax.set_axis_off()
    for c, (ax, name) in enumerate(zip(axes.flat, names)):
        ax.set_xticks([])
        ax.set_yticks([])
        if rows[c] >= 0:
            ax.imshow(delays[rows[c]], cmap="gray", vmin=0.0, vmax=1.0, interpolation="nearest")
        else:  # not white: that would read as "no return"
            ax.set_facecolor("#f2d0d0")
            ax.text(
                0.5,
                0.5,
                f"no {split} sample",
                ha="center",
                va="center",
                fontsize=7,
                transform=ax.transAxes,
            )
        ax.set_title(name.replace("_", " "), fontsize=8)
    missing = info.attrs.get("no_return_delay", 1.0)
    if info.source != GENERATOR:
        what = "delays (black = 0, white = 1 = nothing in the window)"
    elif missing == 1.0:
        what = f"noisy delays (black = 0, white = 1 = no return), noise {info.attrs['noise']}"
    else:
        what = (
            f"noisy delays (black = 0, white = 1), a missing return written as "
            f"{missing:g} plus noise, noise {info.attrs['noise']}"
        )
    fig.suptitle(f"{title}: {split} split, {what}", fontsize=9)
    return write_file(
        out, lambda tmp: fig.savefig(tmp, format="png", dpi=80, metadata={"Software": None})
    )
