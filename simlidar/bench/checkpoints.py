"""A run's kept weights on disk: written atomically with its recipe and figures, read back with
``weights_only=True``."""

import io
import os
import tempfile
from pathlib import Path

import torch

from simlidar.atomic import write_file
from simlidar.bench.train import TrainResult, is_spiking
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


def save_checkpoint(result: TrainResult, path: str | Path) -> Path:
    """State dict plus the recipe and the run's figures; loads with ``weights_only=True``."""
    path = Path(path)
    check_writable(path.parent)
    data = {
        "state_dict": result.model.state_dict(),
        "recipe": result.recipe,
        "history": result.history,
        "silent_from": result.silent_from,
    }
    buffer = io.BytesIO()  # torch's own writer reports a full disk as "file write failed"
    torch.save(data, buffer)
    return write_file(path, lambda tmp: tmp.write_bytes(buffer.getbuffer()), what="the checkpoint")


def load_checkpoint(path: str | Path, input_shape, classes):
    """Rebuild a model from a checkpoint written by :func:`save_checkpoint` (on the CPU)."""
    data = torch.load(path, weights_only=True, map_location="cpu")
    model = build_model(data["recipe"], input_shape, classes)
    model.load_state_dict(data["state_dict"])
    if hasattr(model, "silent_from") or is_spiking(model):
        model.silent_from = float(data.get("silent_from", 1.0))  # older checkpoints: 1.0
    return model, data
