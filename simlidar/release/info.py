"""A dataset's summary: versions, classes, counts per split and class, noise, config."""

import json
from pathlib import Path

import numpy as np

from simlidar.dataset.reader import SplitInfo, dataset_splits
from simlidar.dataset.version import GENERATOR, SOURCES
from simlidar.errors import DatasetError


def dataset_info(path: str | Path) -> dict:
    """Summarise the dataset directory ``path`` (raises DatasetError if it is not one, or if a
    split holds labels that are not class indices)."""
    splits = dataset_splits(path)
    first = splits["train"].attrs
    source = splits["train"].source
    notes = SOURCES.get(source, ("", {}, {}))[2]
    names = first["class_names"]
    counts = {}
    for split, info in splits.items():
        labels = _checked_labels(info, len(names))
        counts[split] = dict(zip(names, np.bincount(labels, minlength=len(names)).tolist()))
    summary = {
        "path": str(Path(path)),
        "dataset_version": first["dataset_version"],
        "release_notes": notes.get(first["dataset_version"], "unknown to this build"),
        "simlidar_version": first["simlidar_version"],
        "classes": len(names),
        "class_mode": first["class_mode"],
        "noise": first["noise"],
        "seed": first["seed"],
        "source": source,
        "height": splits["train"].height,
        "width": splits["train"].width,
        "splits": {s: info.size for s, info in splits.items()},
        "counts": counts,
        "config": first["config"],
    }
    if source == GENERATOR:
        from simlidar.sensor.model import Sensor

        sensor = Sensor.from_dict(first["sensor"])
        summary["sensor"] = {
            "name": sensor.name,
            "model": sensor.model,
            "beams": sensor.beams,
            "rpm": sensor.rpm,
        }
        summary["timing"] = first.get("timing", "flash")
    return summary


def _checked_labels(info: SplitInfo, classes: int) -> np.ndarray:
    """A split's labels; DatasetError naming the (first) file and the values unless every one
    is a class index in 0 .. classes - 1."""
    path = info.path
    labels = info.read(("labels",))["labels"]
    if labels.dtype.kind not in "iu":
        raise DatasetError(f"{path}: labels are {labels.dtype}, expected integer class indices")
    bad = np.unique(labels[(labels < 0) | (labels >= classes)])
    if bad.size:
        shown = ", ".join(str(v) for v in bad[:5].tolist()) + (", ..." if bad.size > 5 else "")
        raise DatasetError(
            f"{path}: labels {shown} outside 0..{classes - 1}; expected class indices "
            "(simlidar verify lists every problem)"
        )
    return labels


def format_info(summary: dict) -> str:
    """The text form of :func:`dataset_info` (what ``simlidar info`` prints)."""
    source = summary.get("source", GENERATOR)
    lines = [
        summary["path"] + ("" if source == GENERATOR else f" ({source})"),
        f"  dataset version {summary['dataset_version']}, simlidar {summary['simlidar_version']}",
        f"  release notes: {summary['release_notes']}",
        f"  {summary['classes']} classes ({summary['class_mode']}), noise {summary['noise']:g}, "
        f"seed {summary['seed']}, {summary['height']} x {summary['width']} pulses",
    ]
    if "sensor" in summary:
        sensor = summary["sensor"]
        lines.append(
            f"  sensor {sensor['name']} ({sensor['model']}), {sensor['beams']} beams, "
            f"{sensor['rpm']:g} RPM, {summary['timing']} timing"
        )
    for split, size in summary["splits"].items():
        counts = summary["counts"][split].values()
        lines.append(f"  {split}: {size} samples, {min(counts)}..{max(counts)} per class")
    width = max(len(n) for n in summary["counts"]["train"])
    for name in summary["counts"]["train"]:
        per = "  ".join(f"{s} {summary['counts'][s][name]:5d}" for s in summary["counts"])
        lines.append(f"    {name:<{width}}  {per}")
    lines.append(f"  config: {json.dumps(summary['config'], sort_keys=True)}")
    return "\n".join(lines)
