"""Which rows a run validates on and which epoch it keeps (docs/benchmark.md, "Training and
model selection").

A stratified validation split is carved out of the train split (:func:`validation_split`,
seeded by the training seed); :class:`Selection` keeps the weights of the epoch with the best
validation accuracy (ties: the lower validation loss, :func:`better_score`) and says when
``patience`` epochs brought no improvement. A learning rate schedule that anneals to 0
(``cosine``) defines its own end: such a run keeps its last epoch and the validation split only
reports (:func:`selection_rule`).
"""

import copy

import numpy as np
import torch

from simlidar.errors import ConfigError
from simlidar.models.training_config import TrainingConfig

SELECTION = "best-validation-accuracy-then-loss/v1"  # the rule's name, recorded by every cell
ANNEALED = "last-epoch-of-annealed-schedule/v1"  # the rule of a schedule that anneals to 0
OWN_FIT = "own-fit/v1"  # the selection rule of a model that trains itself (simlidar_fit)


def selection_rule(training: TrainingConfig) -> str:
    """The name of the rule that picks a run's kept epoch: the best validation epoch, or the
    last one where the learning rate schedule anneals to 0 (``cosine``)."""
    return ANNEALED if training.lr_schedule == "cosine" else SELECTION


def better_score(
    score: tuple[float, float | None], best: tuple[float, float | None] | None
) -> bool:
    """A higher validation accuracy, or the same with a lower (finite) validation loss."""
    if best is None or score[0] != best[0]:
        return best is None or score[0] > best[0]
    return score[1] is not None and (best[1] is None or score[1] < best[1])


def validation_count(n: int, fraction: float, name: str) -> int:
    """The rows :func:`validation_split` holds out of a class ``name`` of ``n`` training
    samples, ``max(1, round(fraction * n))``; a ConfigError when none would be left to train
    on. Needs the counts only: a suite's generated datasets are checked from their sizes."""
    take = max(1, int(np.floor(fraction * n + 0.5)))
    if take >= n:
        raise ConfigError(
            f"validation fraction {fraction} leaves class {name!r} ({n} training "
            "sample(s)) with no sample to train on; expected a fraction that keeps at least "
            "one sample of every class for training and one for validation, or 0 (no "
            "validation; on the command line --validation 0)"
        )
    return take


def validation_split(
    labels: np.ndarray, fraction: float, seed: int, class_names
) -> tuple[np.ndarray, np.ndarray]:
    """(training rows, validation rows) of a train split, stratified by class.

    From each class with n training samples, ``max(1, round(fraction * n))`` rows are drawn
    without replacement for validation (a generator seeded by ``seed``: the same rows for the
    same seed); ``fraction`` 0 keeps every row for training. A ConfigError names a class that
    would be left without a training sample.
    """
    rows = np.arange(len(labels))
    if fraction == 0:
        return rows, rows[:0]
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(11,))))
    held = []
    for label, name in enumerate(class_names):
        mine = rows[labels == label]
        if len(mine) == 0:
            continue
        held.append(rng.permutation(mine)[: validation_count(len(mine), fraction, name)])
    validation = np.sort(np.concatenate(held)) if held else rows[:0]
    return np.setdiff1d(rows, validation), validation


class Selection:
    """The epoch a run keeps under ``rule`` (:func:`selection_rule`): after each epoch,
    :meth:`update` with its validation score (None: no validation rows, the last epoch is
    kept); :meth:`plateau` once ``patience`` epochs brought no better score; :meth:`restore`
    puts the kept epoch's weights back (a copy is taken when an epoch becomes the best)."""

    def __init__(self, rule: str, patience: int, validating: bool):
        self.rule, self.patience, self.validating = rule, patience, validating
        self.best: tuple[float, float | None] | None = None
        self.best_epoch = 0
        self.state: dict | None = None

    def update(self, epoch: int, score: tuple[float, float | None] | None, model) -> None:
        if score is None or self.rule == ANNEALED:
            self.best_epoch = epoch  # the last epoch, or the schedule's end decides
        elif better_score(score, self.best):
            self.best, self.best_epoch = score, epoch
            self.state = copy.deepcopy(model.state_dict())

    def plateau(self, epoch: int) -> bool:
        return self.validating and epoch - self.best_epoch >= self.patience

    def restore(self, model: torch.nn.Module) -> None:
        if self.state is not None:
            model.load_state_dict(self.state)
