"""Seeded training of any registered model on a dataset in the simlidar schema, in parts:
:func:`train` prepares a run (the rows, the model, the optimizer) and loops over
:func:`train_one_epoch` and the validation score (:func:`simlidar.bench.scoring.evaluate`),
which a :class:`~simlidar.bench.selection.Selection` reads to keep an epoch and to stop; the
test split is read once, at the end. The validation rows and the selection rules are in
:mod:`simlidar.bench.selection`, the noise drawn anew each epoch in
:mod:`simlidar.bench.augment`, what a model must show before it trains in
:mod:`simlidar.bench.checks`, scoring in :mod:`simlidar.bench.scoring`, the weights on disk in
:mod:`simlidar.bench.checkpoints` (docs/benchmark.md, "Training and model selection").
"""

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from simlidar.bench.augment import fresh_noise
from simlidar.bench.checks import check_weights, prepared_model, time_limit
from simlidar.bench.scoring import evaluate, predictions
from simlidar.bench.selection import (
    OWN_FIT,
    SELECTION,
    Selection,
    selection_rule,
    validation_split,
)
from simlidar.dataset.loaders import load_split, spike_threshold, split_info
from simlidar.errors import ConfigError, TrainingError
from simlidar.models.protocol import ModelSpec, class_scores, encode, spec_of
from simlidar.models.training_config import TrainingConfig

STOPS = ("plateau", "epochs", "time", "own-fit")  # why training stopped (TrainResult.stopped)


@dataclass(kw_only=True)
class TrainResult:
    model: torch.nn.Module  # with the weights of ``best_epoch``
    recipe: dict
    test_accuracy: float
    seconds: float
    epochs: int  # epochs run
    history: list[dict] = field(default_factory=list)  # per epoch: loss, lr, val_*, seconds
    best_epoch: int = 0  # 0-based epoch whose weights were kept (the last without validation)
    stopped: str = "epochs"  # one of STOPS
    validation_size: int = 0
    test_predictions: np.ndarray | None = None  # predicted class of every test sample (-1: none)
    rule: str = SELECTION  # the selection rule (selection_rule) that picked ``best_epoch``
    epoch_cap: int = 0  # the epochs it was given (``epochs`` is how many it ran)
    spec: ModelSpec = field(default_factory=ModelSpec)  # what the model declared (protocol)
    silent_from: float = 1.0  # the data's no-return threshold its inputs were encoded with
    device: str = "cpu"  # where it trained

    def selection(self) -> dict:
        """What a benchmark cell records about the selection (docs/benchmark.md)."""
        return {
            "best_epoch": self.best_epoch,
            "epochs_run": self.epochs,
            "stopped": self.stopped,
            "validation_size": self.validation_size,
            "validation_curve": [h.get("val_accuracy") for h in self.history],
        }


def make_optimizer(params, training: TrainingConfig):
    if training.optimizer == "adam":
        return torch.optim.Adam(params, lr=training.lr)
    return torch.optim.SGD(params, lr=training.lr, momentum=training.momentum)


def is_spiking(model: torch.nn.Module) -> bool:
    """Whether a model's outputs are spikes (first-spike times or spikes over time steps)
    rather than logits: what it declares (:func:`simlidar.models.protocol.spec_of`)."""
    return spec_of(model).spiking


def batch_loss(
    model: torch.nn.Module,
    x: torch.Tensor,
    y: torch.Tensor,
    training: TrainingConfig,
    spec: ModelSpec | None = None,
):
    """(cross-entropy, cross-entropy plus the recipe's penalties) on one encoded batch: the
    model's own ``simlidar_loss`` where it has one (simlidar's spiking networks add their
    penalties there), else the cross-entropy of its class scores.

    x, y : one batch, its input encoded as the model wants (``spec``) on the model's device,
        and its (B,) labels
    training : the training rules: the logits of a spiking network's class scores, the
        penalties (``l2`` here, the others read by ``simlidar_loss``)
    spec : what the model declares (default: :func:`~simlidar.models.protocol.spec_of` the
        model)
    """
    spec = spec or spec_of(model)
    own = getattr(model, "simlidar_loss", None)
    if own is not None:
        loss, total = own(x, y, training)
    else:
        scores = class_scores(model(x), spec, training.logits, training.logit_scale)
        loss = total = F.cross_entropy(scores, y)
    total = total + training.l2 * sum((p**2).sum() for p in model.parameters())
    return loss, total


@dataclass(frozen=True)
class Run:
    """What the parts of one training run share: the model and what it declared, the
    training configuration, the seeded generator of the batch order, the device, the data's
    no-return threshold its inputs are encoded with, and its name for messages."""

    model: torch.nn.Module
    spec: ModelSpec
    training: TrainingConfig
    generator: torch.Generator
    device: torch.device
    silent_from: float
    where: str


@dataclass(frozen=True)
class Rows:
    """A run's training and validation rows of the train split, (N, 1, H, W) delays and labels."""

    x_train: torch.Tensor
    y_train: torch.Tensor
    x_val: torch.Tensor
    y_val: torch.Tensor
    trained: np.ndarray  # the train split's row of each training row


def train_one_epoch(
    run: Run, optimizer, x_train: torch.Tensor, y_train: torch.Tensor, epoch: int
) -> float:
    """One epoch over the training rows in a seeded order; the mean cross-entropy. A scheduled
    early-decision term is off before its epoch; a loss that is not finite stops the run.

    run : what the run's parts share (:class:`Run`): the model, what it declares and the
        no-return threshold (which encode each batch), the training rules, the seeded
        generator of the batch order, the device
    optimizer : the torch optimizer of the model's parameters (:func:`make_optimizer`)
    x_train, y_train : the training rows, (N, 1, H, W) delays (encoded a batch at a time, on
        ``run.device``) and (N,) labels
    epoch : the 0-based epoch, which the schedule of the early-decision term reads
        (``early_start``) and a TrainingError names
    """
    training = run.training
    run.model.train()
    order = torch.randperm(len(y_train), generator=run.generator)
    active = training if epoch >= training.early_start else replace(training, early_penalty=0.0)
    losses = []
    for i in range(0, len(order), training.batch_size):
        batch = order[i : i + training.batch_size]
        x = encode(x_train[batch].to(run.device), run.spec, run.silent_from)
        loss, total = batch_loss(run.model, x, y_train[batch].to(run.device), active, run.spec)
        if not torch.isfinite(total):
            raise TrainingError(
                f"{run.where}: epoch {epoch}: the training loss is {total.item()}; expected a "
                "finite loss (a model whose output is NaN or infinite, or a recipe's "
                "setting that overflows): nothing is kept"
            )
        optimizer.zero_grad()
        total.backward()
        if training.clip_grad_norm:
            torch.nn.utils.clip_grad_norm_(run.model.parameters(), training.clip_grad_norm)
        optimizer.step()
        losses.append(loss.item())
    return float(np.mean(losses))


def training_rows(dataset, attrs: dict, seed: int, validation: float, where: str) -> Rows:
    """The train split less its validation rows (:func:`validation_split`, seeded by the
    training seed), and those rows.

    dataset : a dataset directory
    attrs : its train split's attributes (its ``class_names``)
    seed : the training seed
    validation : the fraction of each class held out for validation (0: none)
    where : what a ConfigError for a class left without a training row starts with
    returns : :class:`Rows`
    """
    x_all, y_all = (torch.from_numpy(a) for a in load_split(dataset, "train"))
    try:
        rows, held = validation_split(
            y_all.numpy(), validation, seed, [str(n) for n in attrs["class_names"]]
        )
    except ConfigError as exc:
        raise ConfigError(f"{where}: key 'training.validation': {exc}") from None
    x_all = x_all[:, None]  # (N, 1, H, W)
    return Rows(x_all[rows], y_all[rows], x_all[held], y_all[held], rows)


def train(
    recipe: dict,
    dataset: str | Path,
    seed: int = 0,
    epochs: int | None = None,
    max_seconds: float | None = None,
    progress: bool = True,
    device: torch.device | str = "cpu",
    rows: "Rows | None" = None,
    test: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> TrainResult:
    """Train the recipe's model on ``dataset``'s train split (less the validation rows), keep
    the epoch the selection rule picks, and score it once on the test split.

    The model is fed the encoding it declares (:mod:`simlidar.models.protocol`) on ``device``;
    one with its own ``simlidar_fit`` trains itself and is then scored the same way.
    Deterministic for a given seed, recipe, dataset, device and thread count (one
    torch.Generator drives the initial weights and the batch order; the validation rows are
    drawn from the seed too).

    recipe : a loaded recipe (:func:`simlidar.models.registry.load_recipe`)
    dataset : a dataset directory of any source
    seed : the run's seed
    epochs, max_seconds : over the recipe's ``[training]`` values (None: the recipe's)
    progress : a progress bar on stderr
    device : where the model trains
    rows, test : the training and validation rows and the test rows ((N, 1, H, W) delays and
        labels) in place of the splits' samples: a stream split's rotation windows
        (:mod:`simlidar.bench.stream_task`); None: the splits' own
    """
    from tqdm import tqdm

    where = f"recipe {recipe.get('name', '?')}"
    training = TrainingConfig.from_table(recipe["training"], where).over(
        epochs=epochs, max_seconds=max_seconds
    )
    attrs = split_info(dataset, "train").attrs
    data = rows or training_rows(dataset, attrs, seed, training.validation, where)
    if rows is not None and training.noise_augment:
        raise ConfigError(
            f"{where}: key 'training.noise_augment': true; expected false for rows given "
            "apart from the split's samples (the noise is drawn for those)"
        )
    generator = torch.Generator().manual_seed(seed)
    silent_from = spike_threshold(attrs)  # the encoding follows the data's profile
    device = torch.device(device)
    classes = len(attrs["class_names"])
    with time_limit(training.max_seconds, f"{where}: building the model and its first forward"):
        model, spec = prepared_model(recipe, data.x_train, classes, generator, device, silent_from)
    run = Run(model, spec, training, generator, device, silent_from, where)
    if hasattr(model, "simlidar_fit"):
        return _own_fit(run, data, recipe, dataset, test)
    draw = fresh_noise(dataset, attrs, seed, data.trained) if training.noise_augment else None
    optimizer = make_optimizer(model.parameters(), training)
    epochs, validating = training.epochs, len(data.y_val) > 0
    schedule = None
    if training.lr_schedule == "cosine":
        schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, max(epochs, 1))
    selection = Selection(selection_rule(training), training.patience, validating)
    start, history, stopped, x_train = time.perf_counter(), [], "epochs", data.x_train
    bar = tqdm(range(epochs), desc=f"train {recipe.get('name', '')}", disable=not progress)
    for epoch in bar:
        if draw is not None:
            x_train = torch.from_numpy(draw())[:, None]
        loss = train_one_epoch(run, optimizer, x_train, data.y_train, epoch)
        lr = optimizer.param_groups[0]["lr"]  # the rate this epoch trained with
        if schedule is not None:
            schedule.step()
        record = {"epoch": epoch, "loss": loss, "lr": lr}
        check_weights(model, f"{where}: epoch {epoch}")
        score = None
        if validating:
            score = evaluate(
                model, data.x_val, data.y_val, training, spec=spec, silent_from=silent_from,
                when=f"{where}: epoch {epoch}'s validation",
            )  # fmt: skip
            record.update(val_accuracy=score[0], val_loss=score[1])
            bar.set_postfix(loss=f"{loss:.3f}", val=f"{score[0]:.3f}")
        else:
            bar.set_postfix(loss=f"{loss:.3f}")
        selection.update(epoch, score, model)
        record["seconds"] = time.perf_counter() - start
        history.append(record)
        if epoch == epochs - 1:
            break
        if selection.plateau(epoch):
            stopped = "plateau"
            break
        if record["seconds"] > training.max_seconds:
            stopped = "time"
            break
    selection.restore(model)
    return _result(run, recipe, dataset, history, selection.best_epoch, stopped, len(data.y_val),
                   test=test)  # fmt: skip


def _result(
    run: Run, recipe, dataset, history, best_epoch, stopped, validation_size, rule=None, test=None
):
    """The TrainResult of a finished run, its kept weights scored once on the test split (or
    on the ``test`` rows given, (N, 1, H, W) and labels)."""
    if test is None:
        x_test, y_test = (torch.from_numpy(a) for a in load_split(dataset, "test"))
        x_test = x_test[:, None]
    else:
        x_test, y_test = test
    predicted = predictions(run.model, x_test, spec=run.spec, silent_from=run.silent_from)
    return TrainResult(
        model=run.model,
        recipe=recipe,
        test_accuracy=(predicted == y_test).float().mean().item(),
        seconds=history[-1]["seconds"],
        epochs=len(history),
        history=history,
        best_epoch=best_epoch,
        stopped=stopped,
        validation_size=validation_size,
        test_predictions=predicted.numpy(),
        rule=rule or selection_rule(run.training),
        epoch_cap=1 if rule == OWN_FIT else run.training.epochs,
        spec=run.spec,
        silent_from=run.silent_from,
        device=str(run.device),
    )


def _own_fit(run: Run, data: Rows, recipe: dict, dataset, test=None) -> TrainResult:
    """A model with its own ``simlidar_fit``: it trains itself on the encoded train rows (and
    may watch the validation rows); simlidar scores the validation rows (recorded) and reads
    the test split once."""
    model, spec, silent_from, device = run.model, run.spec, run.silent_from, run.device
    start = time.perf_counter()
    model.train()
    model.simlidar_fit(
        encode(data.x_train.to(device), spec, silent_from),
        data.y_train.to(device),
        encode(data.x_val.to(device), spec, silent_from),
        data.y_val.to(device),
        run.generator,
    )
    record = {"epoch": 0, "loss": None, "lr": None}
    check_weights(model, f"{run.where}: after simlidar_fit")
    if len(data.y_val):
        score = evaluate(
            model, data.x_val, data.y_val, run.training, spec=spec, silent_from=silent_from
        )
        record.update(val_accuracy=score[0], val_loss=score[1])
    record["seconds"] = time.perf_counter() - start
    return _result(run, recipe, dataset, [record], 0, "own-fit", len(data.y_val), OWN_FIT, test)
