"""Model selection: a stratified, seeded validation split carved out of train; the best
validation epoch restored; early stopping on a plateau; the test split read once, at the end."""

import numpy as np
import pytest
import torch

from simlidar.bench import train as training_module
from simlidar.bench.scoring import evaluate
from simlidar.bench.selection import validation_split
from simlidar.bench.train import train
from simlidar.dataset.loaders import load_split
from simlidar.errors import ConfigError
from simlidar.models.registry import load_recipe
from simlidar.models.training_config import TrainingConfig

NAMES = [f"class{i}" for i in range(4)]


def _recipe(**training):
    recipe = load_recipe("mlp")
    recipe["architecture"]["dense"] = [128]
    recipe["training"].update(batch_size=16, lr=3e-3, **training)
    return recipe


def _config(recipe):
    return TrainingConfig.from_table(recipe["training"])


def test_the_validation_split_is_stratified_seeded_and_disjoint():
    labels = np.repeat(np.arange(4), [30, 20, 10, 3])
    rows, held = validation_split(labels, 0.1, seed=5, class_names=NAMES)
    assert np.bincount(labels[held], minlength=4).tolist() == [3, 2, 1, 1]  # max(1, round)
    assert np.intersect1d(rows, held).size == 0
    assert np.array_equal(np.sort(np.concatenate([rows, held])), np.arange(len(labels)))
    again = validation_split(labels, 0.1, seed=5, class_names=NAMES)
    assert np.array_equal(again[1], held) and np.array_equal(again[0], rows)
    other = validation_split(labels, 0.1, seed=6, class_names=NAMES)[1]
    assert not np.array_equal(other, held)  # drawn from the seed
    assert np.bincount(labels[other], minlength=4).tolist() == [3, 2, 1, 1]
    rows, held = validation_split(labels, 0.0, seed=5, class_names=NAMES)
    assert held.size == 0 and np.array_equal(rows, np.arange(len(labels)))


@pytest.mark.parametrize(
    ("counts", "fraction", "name"), [([5, 1, 5, 5], 0.1, "class1"), ([4, 4, 4, 2], 0.8, "class3")]
)
def test_a_fraction_that_leaves_a_class_nothing_to_train_on_is_refused(counts, fraction, name):
    labels = np.repeat(np.arange(4), counts)
    with pytest.raises(ConfigError, match=rf"validation fraction {fraction} leaves class '{name}'"):
        validation_split(labels, fraction, 0, NAMES)


def test_validation_rows_are_not_test_samples(datasets):
    x, y = load_split(datasets[0.5], "train")
    x_test, _ = load_split(datasets[0.5], "test")
    _, held = validation_split(y, 0.1, 0, [str(i) for i in range(32)])
    assert len(held) == 32 and len(np.unique(y[held])) == 32  # one of each class
    test_rows = {row.tobytes() for row in x_test}
    assert not any(row.tobytes() in test_rows for row in x[held])


def test_the_best_validation_epoch_is_restored_and_the_test_split_read_once(datasets, monkeypatch):
    reads = []
    real = training_module.load_split

    def counted(path, split="train", **kw):
        reads.append(split)
        return real(path, split, **kw)

    monkeypatch.setattr(training_module, "load_split", counted)
    recipe = _recipe(validation=0.34, patience=50)
    result = train(recipe, datasets[0.1], seed=1, epochs=12, progress=False)
    assert reads.count("test") == 1 and reads[-1] == "test"
    curve = [h["val_accuracy"] for h in result.history]
    losses = [h["val_loss"] for h in result.history]
    best = max(curve)
    first_best = [e for e, a in enumerate(curve) if a == best]
    expected = min(first_best, key=lambda e: (losses[e], e))  # ties: the lower loss
    assert result.best_epoch == expected and result.epochs == 12 and result.stopped == "epochs"
    assert curve[-1] < best  # with 32 validation samples the score jumps: restoring matters
    assert result.validation_size == 32  # round(0.34 * 3) = 1 of each class's 3
    x, y = (torch.from_numpy(a) for a in real(datasets[0.1], "train"))
    _, held = validation_split(y.numpy(), 0.34, 1, [str(i) for i in range(32)])
    accuracy, _ = evaluate(result.model, x[held][:, None], y[held], _config(recipe))
    assert accuracy == pytest.approx(best)  # the returned weights are the best epoch's
    assert result.selection()["validation_curve"] == curve


def test_training_stops_on_a_validation_plateau(datasets):
    recipe = _recipe(validation=0.34, patience=2)
    result = train(recipe, datasets[0.1], seed=0, epochs=60, progress=False)
    assert result.stopped == "plateau"
    assert result.epochs == result.best_epoch + 2 + 1 < 60  # 2 epochs without improvement
    curve = [h["val_accuracy"] for h in result.history]
    assert max(curve[result.best_epoch + 1 :]) <= curve[result.best_epoch]


def test_a_time_cap_is_recorded_as_the_reason(datasets):
    result = train(_recipe(), datasets[0.1], seed=0, epochs=5, max_seconds=0, progress=False)
    assert result.stopped == "time" and result.epochs == 1


def test_an_annealed_schedule_keeps_its_last_epoch_and_runs_every_epoch(datasets):
    from simlidar.bench.selection import ANNEALED, SELECTION, selection_rule

    recipe = _recipe(validation=0.34, patience=1, lr_schedule="cosine")
    result = train(recipe, datasets[0.1], seed=1, epochs=8, progress=False)
    assert result.stopped == "epochs" and result.epochs == 8  # patience 1 does not stop it
    assert result.best_epoch == 7  # the schedule's end, whatever the validation curve says
    curve = [h["val_accuracy"] for h in result.history]
    assert all(a is not None for a in curve)  # validation still reports every epoch
    assert any(curve[e] <= max(curve[:e]) for e in range(1, 7))  # best-epoch rules would stop
    x, y = (torch.from_numpy(a) for a in load_split(datasets[0.1], "train"))
    _, held = validation_split(y.numpy(), 0.34, 1, [str(i) for i in range(32)])
    accuracy, _ = evaluate(result.model, x[held][:, None], y[held], _config(recipe))
    assert accuracy == pytest.approx(curve[-1])  # the returned weights are the last epoch's
    assert selection_rule(_config(recipe)) == ANNEALED
    assert selection_rule(_config(_recipe())) == SELECTION


def test_the_selection_object_keeps_the_best_epoch_and_knows_its_patience():
    """The best validation accuracy is kept (ties: the lower loss, a loss of None never wins a
    tie), its weights copied when it becomes the best and put back by ``restore``; ``plateau``
    once ``patience`` epochs brought nothing better; an annealed rule and a run without
    validation keep the last epoch and never stop early."""
    from simlidar.bench.selection import ANNEALED, SELECTION, Selection

    model = torch.nn.Linear(2, 2)
    selection = Selection(SELECTION, patience=2, validating=True)
    scores = [(0.5, 1.0), (0.6, 0.9), (0.6, 0.8), (0.6, None), (0.55, 0.1), (0.6, 0.8)]
    kept = None
    for epoch, score in enumerate(scores):
        with torch.no_grad():
            model.weight.fill_(epoch)
        selection.update(epoch, score, model)
        if epoch == 2:
            kept = model.weight.clone()
    assert selection.best_epoch == 2 and selection.best == (0.6, 0.8)
    assert not selection.plateau(3) and selection.plateau(4)
    selection.restore(model)
    assert torch.equal(model.weight, kept)
    for rule, validating, score in ((ANNEALED, True, (0.9, 0.1)), (SELECTION, False, None)):
        last = Selection(rule, patience=1, validating=validating)
        for epoch in range(5):
            last.update(epoch, score if epoch == 0 else (0.1, 9.0) if validating else None, model)
            assert last.best_epoch == epoch and not last.plateau(epoch)
        assert last.state is None
