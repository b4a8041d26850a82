"""A run's kept weights on disk: written atomically with its recipe and figures, read back with
``weights_only=True``."""

import io
import os
import tempfile
from pathlib import Path

import torch

from simlidar.atomic import write_file
from simlidar.bench.train import TrainResult, is_spiking
from simlidar.dataset.reader import dataset_splits
from simlidar.errors import DatasetError
from simlidar.models.registry import build_model


def check_writable(folder: str | Path) -> None:
    """Create ``folder`` if needed and prove a file can be written there; a DatasetError
    naming the folder otherwise (``train`` calls it before the first epoch)."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-check-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise DatasetError(f"--out {folder}: cannot write there ({exc.strerror})") from None


def checkpoint_path(out: str | Path, model: str, dataset: str | Path, seed: int) -> Path:
    """Where ``simlidar train`` keeps a run's weights: ``<out>/<model>-<dataset>-seed<seed>.pt``,
    the dataset by its directory's name (``.`` by the folder it names), so that runs of one
    model on two datasets never share a file."""
    name = Path(dataset).absolute().resolve().name or "dataset"
    return Path(out) / f"{model}-{name}-seed{seed}.pt"


def save_checkpoint(result: TrainResult, path: str | Path, dataset: Path | None = None) -> Path:
    """State dict plus the recipe and the run's figures, and with ``dataset`` (the dataset
    directory it was trained on) what the model depends on in it (``trained_on``,
    :func:`data_record`: ``simlidar evaluate`` holds another dataset to it); loads with
    ``weights_only=True``."""
    path = Path(path)
    check_writable(path.parent)
    data = {
        "state_dict": result.model.state_dict(),
        "recipe": result.recipe,
        "history": result.history,
        "silent_from": result.silent_from,
    }
    if dataset is not None:
        data["trained_on"] = data_record(dataset)
    buffer = io.BytesIO()  # torch's own writer reports a full disk as "file write failed"
    torch.save(data, buffer)
    return write_file(path, lambda tmp: tmp.write_bytes(buffer.getbuffer()), what="the checkpoint")


def data_record(dataset: Path) -> dict:
    """What a model depends on in a dataset besides its samples: the input shape (C, H, W),
    the class names (label i is class_names[i]), the timing (``flash``: times of flight;
    ``scan``: arrival times in the sweep) and the dataset profile (None: the physical rule).
    What :func:`simlidar.bench.evaluate.check_fit` compares with a checkpoint's ``trained_on``."""
    info = dataset_splits(dataset)["test"]
    return {
        "input_shape": [1, info.height, info.width],
        "class_names": [str(n) for n in info.attrs["class_names"]],
        "timing": str(info.attrs.get("timing", "flash")),
        "profile": None if "profile" not in info.attrs else str(info.attrs["profile"]),
    }


def load_checkpoint(path: str | Path, input_shape, classes):
    """Rebuild a model from a checkpoint written by :func:`save_checkpoint` (on the CPU)."""
    data = torch.load(path, weights_only=True, map_location="cpu")
    model = build_model(data["recipe"], input_shape, classes)
    model.load_state_dict(data["state_dict"])
    if hasattr(model, "silent_from") or is_spiking(model):
        model.silent_from = float(data.get("silent_from", 1.0))  # older checkpoints: 1.0
    return model, data
