"""Seeded training of any registered model on a dataset in the simlidar schema."""

import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from simlidar.data import load_split, spike_threshold, split_path
from simlidar.dataset.h5 import read_split_info
from simlidar.errors import ConfigError, DatasetError
from simlidar.models import ttfs
from simlidar.models.registry import build_model, check_training
from simlidar.pulses import noisy_delays


@dataclass
class TrainResult:
    model: torch.nn.Module
    recipe: dict
    test_accuracy: float
    seconds: float
    epochs: int
    history: list[dict] = field(default_factory=list)  # per epoch: loss, lr, accuracy, seconds


def _optimizer(params, training: dict):
    kind = training.get("optimizer", "sgd")
    if kind == "sgd":
        return torch.optim.SGD(params, lr=training["lr"], momentum=training.get("momentum", 0))
    if kind == "adam":
        return torch.optim.Adam(params, lr=training["lr"])
    raise ConfigError(f"[training] optimizer={kind!r}: expected 'sgd' or 'adam'")


def is_spiking(model: torch.nn.Module) -> bool:
    """Spiking models output first-spike times (z domain); conventional ones output logits."""
    return getattr(model, "spiking", False)


def logits(model: torch.nn.Module, out: torch.Tensor, kind: str = "z",
           scale: float = 1.0) -> torch.Tensor:  # fmt: skip
    """Logits for the cross-entropy loss: a spiking model's -z (``kind`` "z", the paper's) or
    -ln z = -t (``kind`` "time"; output times are not scaled by exp), times ``scale`` (an
    inverse softmax temperature), or ``out`` itself."""
    if not is_spiking(model):
        return out
    return scale * ttfs.output_logits(out if kind == "z" else torch.log(out))


def _loss(model: torch.nn.Module, x: torch.Tensor, y: torch.Tensor, training: dict):
    """(cross-entropy, cross-entropy plus the recipe's penalties) on one batch."""
    kind, scale = training.get("logits", "z"), training.get("logit_scale", 1.0)
    if is_spiking(model):
        spikes = model.spikes(x)
        loss = F.cross_entropy(logits(model, spikes[-1], kind, scale), y)
        total = loss + training.get("weight_sum_penalty", 0.0) * model.penalty()
        if training.get("fire_penalty", 0.0):
            last = model.layers[-1].weight
            fire = ttfs.target_fire_penalty(spikes[-2].flatten(1), last, y,
                                            training.get("fire_margin", 0.1))  # fmt: skip
            total = total + training["fire_penalty"] * fire
        if training.get("early_penalty", 0.0):
            total = total + training["early_penalty"] * ttfs.target_time(spikes[-1], y)
    else:
        loss = total = F.cross_entropy(model(x), y)
    total = total + training.get("l2", 0.0) * sum((p**2).sum() for p in model.parameters())
    return loss, total


def _fresh_noise(dataset, attrs: dict, seed: int):
    """``noise_augment``: a function drawing the train split's noise anew (same level, same
    profile rule, from ``clean_delays``) for each epoch: the paper's "adding noise randomly"
    as augmentation rather than one fixed draw per sample. Seeded by the training seed."""
    if "source" in attrs or "noise" not in attrs:
        raise ConfigError(
            f"{dataset}: training option noise_augment: expected a generated dataset "
            "(clean_delays and a noise level), got converted data"
        )
    clean, _ = load_split(dataset, "train", field="clean_delays")
    level = float(attrs["noise"])
    missing = float(attrs.get("no_return_delay", 1.0))
    noise_on = attrs.get("noise_on", "returns")
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(7,))))

    def draw() -> torch.Tensor:
        u = rng.random(clean.shape, dtype=np.float32)
        return torch.from_numpy(noisy_delays(clean, level, u, missing, noise_on))[:, None]

    return draw


def predictions(model: torch.nn.Module, x: torch.Tensor, batch: int = 500) -> torch.Tensor:
    """Predicted classes of any registered model, in batches (-1: no output spike)."""
    model.eval()
    with torch.no_grad():
        outs = [model(x[i : i + batch]) for i in range(0, len(x), batch)]
    if is_spiking(model):
        return torch.cat([ttfs.predict(o) for o in outs])
    return torch.cat([o.argmax(1) for o in outs])


def train(recipe: dict, dataset: str | Path, seed: int = 0, epochs: int | None = None,
          max_seconds: float | None = None, progress: bool = True) -> TrainResult:  # fmt: skip
    """Train the recipe's model on ``dataset``'s train split; score it on the test split.

    Deterministic for a given seed, recipe, dataset and thread count (one torch.Generator
    drives the initial weights and the batch order).
    """
    from tqdm import tqdm

    training = check_training(recipe)
    x_train, y_train = (torch.from_numpy(a) for a in load_split(dataset, "train"))
    x_test, y_test = (torch.from_numpy(a) for a in load_split(dataset, "test"))
    x_train, x_test = x_train[:, None], x_test[:, None]  # (N, 1, H, W)
    attrs = read_split_info(split_path(dataset, "train")).attrs
    classes = len(attrs["class_names"])
    generator = torch.Generator().manual_seed(seed)
    model = build_model(recipe, tuple(x_train.shape[1:]), classes, generator)
    if is_spiking(model):
        model.silent_from = spike_threshold(attrs)  # the encoding follows the data's profile
    fresh_noise = _fresh_noise(dataset, attrs, seed) if training.get("noise_augment") else None
    optimizer = _optimizer(model.parameters(), training)
    epochs = epochs if epochs is not None else training.get("epochs", 100)
    budget = max_seconds if max_seconds is not None else training.get("max_seconds", np.inf)
    batch = training["batch_size"]
    schedule = None
    if training.get("lr_schedule", "constant") == "cosine":
        schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, max(epochs, 1))
    start = time.perf_counter()
    history = []
    bar = tqdm(range(epochs), desc=f"train {recipe.get('name', '')}", disable=not progress)
    for epoch in bar:
        model.train()
        if fresh_noise is not None:
            x_train = fresh_noise()
        order = torch.randperm(len(y_train), generator=generator)
        losses = []
        for i in range(0, len(order), batch):
            rows = order[i : i + batch]
            loss, total = _loss(model, x_train[rows], y_train[rows], training)
            optimizer.zero_grad()
            total.backward()
            if training.get("clip_grad_norm"):
                torch.nn.utils.clip_grad_norm_(model.parameters(), training["clip_grad_norm"])
            optimizer.step()
            losses.append(loss.item())
        lr = optimizer.param_groups[0]["lr"]  # the rate this epoch trained with
        if schedule is not None:
            schedule.step()
        accuracy = (predictions(model, x_test) == y_test).float().mean().item()
        seconds = time.perf_counter() - start
        history.append({"epoch": epoch, "loss": float(np.mean(losses)), "lr": lr,
                        "test_accuracy": accuracy, "seconds": seconds})  # fmt: skip
        bar.set_postfix(loss=f"{np.mean(losses):.3f}", test=f"{accuracy:.3f}")
        if seconds > budget:
            break
    return TrainResult(model, recipe, history[-1]["test_accuracy"], history[-1]["seconds"],
                       len(history), history)  # fmt: skip


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


def save_checkpoint(result: TrainResult, path: str | Path) -> Path:
    """State dict plus the recipe and the run's figures; loads with ``weights_only=True``."""
    path = Path(path)
    check_writable(path.parent)
    data = {
        "state_dict": result.model.state_dict(),
        "recipe": result.recipe,
        "history": result.history,
        "silent_from": getattr(result.model, "silent_from", 1.0),
    }
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.partial-", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(data, f)
        os.replace(tmp, path)
    except (OSError, RuntimeError) as exc:  # torch reports a full disk as a RuntimeError
        Path(tmp).unlink(missing_ok=True)
        cause = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
        raise DatasetError(f"{path}: cannot write the checkpoint ({cause})") from None
    return path


def load_checkpoint(path: str | Path, input_shape, classes):
    """Rebuild a model from a checkpoint written by :func:`save_checkpoint`."""
    data = torch.load(path, weights_only=True)
    model = build_model(data["recipe"], input_shape, classes)
    model.load_state_dict(data["state_dict"])
    if is_spiking(model):
        model.silent_from = float(data.get("silent_from", 1.0))  # older checkpoints: 1.0
    return model, data
