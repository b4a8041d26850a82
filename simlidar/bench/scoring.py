"""A trained model's predictions and its validation score, in batches, in eval mode."""

import numpy as np
import torch
import torch.nn.functional as F

from simlidar.bench.checks import check_finite
from simlidar.models.protocol import ModelSpec, class_scores, encode, readout, spec_of
from simlidar.models.training_config import TrainingConfig


def _batches(
    model,
    x: torch.Tensor,
    spec: ModelSpec,
    silent_from: float,
    batch: int,
    exact: bool = False,
    when: str = "scoring",
):
    """Each batch of ``x`` (N, 1, H, W) encoded for the model on its device, and its output
    (:func:`check_finite`: a TrainingError naming ``when`` for NaN, or an infinity that is no
    "no spike").

    exact : a model that the event-driven evaluator runs (``event_driven``) is run on float64
        input spikes: the exact spike times of its float32 weights, which that evaluator reads
        too (:func:`simlidar.models.decisions.decide_all`), so that a cell's ``accuracy`` and
        ``early.accuracy`` agree by construction (in float32, two output spikes less than a
        rounding step apart can swap places; training and validation stay in float32)
    """
    device = next(iter(model.parameters()), torch.empty(0)).device
    model.eval()
    if exact and getattr(model, "event_driven", False):
        x = x.double()
    with torch.no_grad():
        for i in range(0, len(x), batch):
            out = model(encode(x[i : i + batch].to(device), spec, silent_from))
            check_finite(out, spec, when)
            yield i, out


def predictions(
    model: torch.nn.Module,
    x: torch.Tensor,
    batch: int = 500,
    spec: ModelSpec | None = None,
    silent_from: float | None = None,
) -> torch.Tensor:
    """Predicted classes of any model, in batches, on the CPU (-1: no decision); simlidar's
    event-driven networks in float64 (:func:`_batches`, ``exact``).

    x : (N, 1, H, W) delays, encoded as the model wants (``spec``; default: what it declares)
    batch : samples run at a time
    silent_from : the data's no-return threshold (default: the model's, else 1.0)
    """
    spec = spec or spec_of(model)
    silent_from = getattr(model, "silent_from", 1.0) if silent_from is None else silent_from
    runs = _batches(model, x, spec, silent_from, batch, exact=True, when="scoring the test split")
    outs = [readout(out, spec)[0].cpu() for _, out in runs]
    return torch.cat(outs) if outs else torch.zeros(0, dtype=torch.long)


def evaluate(
    model: torch.nn.Module,
    x: torch.Tensor,
    y: torch.Tensor,
    training: TrainingConfig,
    batch: int = 500,
    spec: ModelSpec | None = None,
    silent_from: float = 1.0,
    when: str = "validation",
) -> tuple[float, float | None]:
    """(accuracy, mean cross-entropy with the recipe's logits) on ``x``, in eval mode; the loss
    is None where it is not finite (a spiking network whose correct output never fired).
    ``when``: what a TrainingError for a NaN output names (:func:`check_finite`).

    model : the model, scored on the device of its parameters
    x, y : (N, 1, H, W) delays, encoded as the model wants (``spec``), and (N,) labels
    training : the recipe's training rules: their ``logits`` and ``logit_scale`` make a spiking
        network's logits (:func:`simlidar.models.protocol.class_scores`)
    batch : samples run at a time
    spec : what the model declares (default: :func:`~simlidar.models.protocol.spec_of` the
        model)
    silent_from : the data's no-return threshold: delays at or above it are no input spike
        (:func:`simlidar.dataset.loaders.spike_threshold`; 1.0: the physical profile's)
    """
    spec = spec or spec_of(model)
    correct, loss = 0, 0.0
    for i, out in _batches(model, x, spec, silent_from, batch, when=when):
        target = y[i : i + batch].to(_first_tensor(out).device)
        correct += int((readout(out, spec)[0] == target).sum())
        scores = class_scores(out, spec, training.logits, training.logit_scale)
        loss += F.cross_entropy(scores, target, reduction="sum").item()
    loss /= len(x)
    return correct / len(x), (loss if np.isfinite(loss) else None)


def _first_tensor(out) -> torch.Tensor:
    return out[0] if isinstance(out, tuple | list) else out
