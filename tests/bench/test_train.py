"""Training runs for real (a tiny budget): it learns, it is seeded, checkpoints reload.

Attack list (issue 35, item 10): ``simlidar train`` on a full disk (a real file-size limit,
``RLIMIT_FSIZE``, on a real process): torch's internal message and no test accuracy at all;
now the accuracy is printed first, then one line with the system's cause, no file left.
"""

import copy
import json
import math
from dataclasses import replace
from pathlib import Path

import pytest
import torch

from simlidar.bench.checkpoints import load_checkpoint, save_checkpoint
from simlidar.bench.scoring import predictions
from simlidar.bench.train import train
from simlidar.dataset.loaders import load_split
from simlidar.errors import ConfigError
from simlidar.models.registry import load_recipe
from simlidar.models.training_config import TrainingConfig


def _small_recipe():
    recipe = load_recipe("snn_simlidar")
    recipe["architecture"]["hidden"] = [64]
    # 3 samples a class here: these tests train on all of them (selection is tested below)
    recipe["training"].update(optimizer="adam", lr=3e-3, batch_size=32, validation=0)
    return recipe


def test_training_learns_and_is_seeded(datasets, tmp_path):
    a = train(_small_recipe(), datasets[0.1], seed=0, epochs=8, progress=False)
    b = train(_small_recipe(), datasets[0.1], seed=0, epochs=8, progress=False)
    assert a.history == [
        dict(h, seconds=a.history[i]["seconds"]) for i, h in enumerate(b.history)
    ]  # same losses and accuracies
    assert a.history[-1]["loss"] < a.history[0]["loss"]
    assert a.test_accuracy > 2.0 / 32  # above chance on 32 classes

    path = save_checkpoint(a, tmp_path / "snn.pt")
    model, data = load_checkpoint(path, (1, 16, 16), 32)  # weights_only=True inside
    assert data["recipe"]["name"] == "snn_simlidar"
    x, _ = load_split(datasets[0.1], "test")
    x = torch.from_numpy(x)[:, None]
    assert torch.equal(predictions(model, x), predictions(a.model, x))

    from simlidar.bench.early import early_decisions

    early = early_decisions(a.model, datasets[0.1])
    # event-driven = batched, the same count: predictions reads the float64 spikes of a
    # float32 model as the evaluator does (float32 against float64 may flip a near-tie)
    _, y = load_split(datasets[0.1], "test")
    assert early["accuracy"] == (predictions(a.model, x).numpy() == y).mean()
    double = copy.deepcopy(a.model).double()
    assert torch.equal(predictions(double, x.double()), predictions(a.model, x))
    assert 0 < early["input_spikes_mean"] <= early["input_spikes_total_mean"]
    assert early["energy_pj_mean"]["45.0"] > early["energy_pj_mean"]["0.37"] > 0


def test_the_train_command(datasets, tmp_path, cli):
    one_epoch = ["train", "--model", "snn_simlidar", "--dataset", datasets[0.1], "--out", tmp_path]
    result = cli(*one_epoch, "--epochs", "1", "--json")
    assert result.exit_code == 0, result.output
    record = json.loads(result.stdout)
    assert record["epochs"] == 1 and record["early"]["samples"] == 64
    # the accuracy printed is the saved model's on the test split, recomputed here
    x, y = load_split(datasets[0.1], "test")
    saved = tmp_path / f"snn_simlidar-{Path(datasets[0.1]).name}-seed0.pt"
    assert record["checkpoint"] == str(saved)
    model, _ = load_checkpoint(saved, (1, 16, 16), 32)
    predicted = predictions(model, torch.from_numpy(x)[:, None])
    accuracy = float((predicted.numpy() == y).mean())
    assert record["test_accuracy"] == round(accuracy, 4)  # as train prints it
    before = saved.read_bytes()
    again = cli(*one_epoch, "--epochs", "1")  # refused before training: nothing replaced
    assert again.exit_code == 1 and "Traceback" not in again.output
    assert again.output.strip().splitlines() == [
        f"Error: {saved} already exists: pass --force to replace it"
    ]
    assert saved.read_bytes() == before
    text = cli(*one_epoch, "--epochs", "1", "--force")
    assert text.exit_code == 0 and "snn_simlidar: test accuracy" in text.stdout
    assert "event-driven: accuracy" in text.stdout and "pJ at 45 pJ/spike" in text.stdout
    assert "epoch 1 of 1 kept (best validation accuracy of 32 held-out samples)" in text.stdout
    assert saved.is_file()
    base = ["train", "--model", "mlp", "--dataset", str(datasets[0.1]), "--out", str(tmp_path)]
    base += ["--force"]
    whole = cli(*base, "--epochs", "3", "--validation", "0", "--json")
    assert whole.exit_code == 0, whole.output
    record = json.loads(whole.stdout)
    assert record["validation_size"] == 0 and record["best_epoch"] == 2
    for option, value in (("--validation", "1"), ("--validation", "-0.5"), ("--patience", "0")):
        bad = cli(*base, option, value)
        assert bad.exit_code == 2 and f"Invalid value for '{option}'" in bad.stderr


def test_time_logits_are_minus_ln_z_and_the_choice_is_checked(datasets):
    from simlidar.errors import ConfigError
    from simlidar.models.protocol import class_scores
    from simlidar.models.registry import build_model

    spec = build_model(_small_recipe(), (1, 16, 16), 32).simlidar_spec
    z = torch.tensor([[1.0, torch.e, torch.inf], [torch.e**2, 1.0, 4.0]])
    assert torch.allclose(class_scores(z, spec, "time")[1], -torch.log(z[1]))
    assert torch.allclose(class_scores(z, spec, "z")[1], -z[1])
    silent = class_scores(z, spec, "time")[0]
    assert silent[2] < silent[:2].min()  # the silent output ranks below every firing one
    recipe = _small_recipe()
    recipe["training"]["logits"] = "exp"
    with pytest.raises(ConfigError, match=r"training.logits': expected one of \['z', 'time'\]"):
        train(recipe, datasets[0.1], epochs=1, progress=False)


def test_logit_scale_fire_penalty_and_cosine_schedule_train(datasets):
    from simlidar.models.protocol import class_scores
    from simlidar.models.registry import build_model

    spec = build_model(_small_recipe(), (1, 16, 16), 32).simlidar_spec
    z = torch.tensor([[1.0, torch.e, torch.inf]])
    assert torch.allclose(class_scores(z, spec, "time", 10.0)[0, :2], torch.tensor([0.0, -10.0]))
    recipe = _small_recipe()
    recipe["training"].update(
        logits="time",
        logit_scale=10.0,
        fire_penalty=10.0,
        fire_margin=0.1,
        lr_schedule="cosine",
        lr=1e-3,
        early_penalty=1.0,
    )
    result = train(recipe, datasets[0.1], seed=0, epochs=6, progress=False)
    assert result.history[-1]["loss"] < result.history[0]["loss"]
    assert result.test_accuracy > 2.0 / 32
    rates = [h["lr"] for h in result.history]  # cosine from 1e-3 towards 0 over the 6 epochs
    assert rates[0] == 1e-3 and all(a > b > 0 for a, b in zip(rates, rates[1:]))
    assert rates[-1] == pytest.approx(1e-3 * (1 + math.cos(math.pi * 5 / 6)) / 2)


def test_the_penalties_enter_the_loss_as_the_recipe_weighs_them():
    from simlidar.bench.train import batch_loss
    from simlidar.models import ttfs
    from simlidar.models.registry import build_model

    recipe = _small_recipe()
    model = build_model(recipe, (1, 16, 16), 32, torch.Generator().manual_seed(0))
    x = torch.rand(8, 1, 16, 16, generator=torch.Generator().manual_seed(1))
    y = torch.arange(8)
    training = TrainingConfig(lr=1e-3, batch_size=8, epochs=1)  # no penalty, no l2
    base, total = batch_loss(model, x, y, training)
    assert total == base
    spikes = model.spikes(x)
    fire = ttfs.target_fire_penalty(spikes[-2].flatten(1), model.layers[-1].weight, y, 5.0)
    early = ttfs.target_time(spikes[-1], y)
    assert fire > 0 and early > 0
    _, total = batch_loss(model, x, y, replace(training, fire_penalty=2.0, fire_margin=5.0))
    assert total.item() == pytest.approx((base + 2.0 * fire).item())
    _, total = batch_loss(model, x, y, replace(training, early_penalty=3.0))
    assert total.item() == pytest.approx((base + 3.0 * early).item())


def test_a_training_config_checks_itself():
    """Made by hand or changed by over(), not only when read from a recipe."""
    for bad, words in [
        (dict(lr=-1, batch_size=60, epochs=3), r"lr=-1: expected a number > 0"),
        (dict(lr=1e-3, batch_size=0, epochs=3), r"batch_size=0: expected an integer >= 1"),
        (
            dict(lr=1e-3, batch_size=60, epochs=0),
            r"epochs=0: expected an integer in \[1, 1000000\]",
        ),
        (dict(lr=1e-3, batch_size=60, epochs=3, optimizer="nope"), r"optimizer='nope': expected"),
    ]:
        with pytest.raises(ConfigError, match=words):
            TrainingConfig(**bad)
    good = TrainingConfig(lr=1e-3, batch_size=60, epochs=3)
    with pytest.raises(ConfigError, match=r"patience=-5: expected an integer in \[1, 1000000\]"):
        good.over(patience=-5)
    assert good.over(patience=None, epochs=10**6).epochs == 10**6


def test_a_scheduled_early_term_is_off_before_its_epoch(datasets):
    """early_start past the last epoch trains exactly as no term; from epoch 1 it changes the
    second epoch, not the first."""
    recipe = _small_recipe()
    recipe["training"].update(early_penalty=3.0, early_form="exp", early_beta=2.0)
    runs = {}
    for name, extra in [
        ("off", {"early_penalty": 0.0}),
        ("late", {"early_start": 5}),
        ("from1", {"early_start": 1}),
    ]:
        r = {**recipe, "training": {**recipe["training"], **extra}}
        runs[name] = train(r, datasets[0.1], seed=0, epochs=2, progress=False)
    weights = {k: r.model.state_dict() for k, r in runs.items()}
    assert all(torch.equal(weights["off"][k], weights["late"][k]) for k in weights["off"])
    assert runs["from1"].history[0] == {
        **runs["off"].history[0],
        "seconds": runs["from1"].history[0]["seconds"],
    }
    assert runs["from1"].history[1]["loss"] != runs["off"].history[1]["loss"]


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("early_form", "quadratic", r"training.early_form': expected one of \['linear', 'exp'"),
        ("early_beta", 0, r"training.early_beta': expected a finite number in \[0.05, 100\]"),
        # extreme values that trained to NaN weights (issue 40): refused by the ranges
        ("early_beta", 1e-300, r"training.early_beta': expected a finite number in \[0.05"),
        ("early_penalty", 1e308, r"training.early_penalty': expected a finite number in \[0, "),
        ("early_margin", 1e308, r"training.early_margin': expected a finite number in \[0, 100"),
        ("early_start", -1, r"training.early_start': expected an integer >= 0, got -1"),
        ("lr_schdule", "cosine", r"unknown key 'training.lr_schdule': expected one of \['batch"),
        ("lr_schedule", "step", r"training.lr_schedule': expected one of \['constant', 'cosine'\]"),
        ("fire_penalty", -1.0, r"training.fire_penalty': expected a finite number in \[0, 1"),
        ("fire_penalty", float("inf"), r"training.fire_penalty': expected a finite number in"),
        ("logit_scale", "10", r"training.logit_scale': expected a finite number > 0, got '10'"),
        ("logit_scale", 0, r"training.logit_scale': expected a finite number > 0, got 0"),
        ("logit_scale", float("nan"), r"training.logit_scale': expected a finite number > 0"),
        ("optimizer", "rmsprop", r"training.optimizer': expected one of \['sgd', 'adam'\]"),
        ("noise_augment", 1, r"training.noise_augment': expected true or false, got 1"),
        (
            "validation",
            1.0,
            r"training.validation': expected a fraction of the train split in \[0, 1\) "
            r"\(0: no validation\), got 1.0",
        ),
        (
            "validation",
            -0.1,
            r"training.validation': expected a fraction of the train split in \[0, 1\)",
        ),
        ("validation", "10%", r"training.validation': expected a fraction .*got '10%'"),
        ("patience", 0, r"training.patience': expected an integer in \[1, 1000000\] .*got 0"),
        ("patience", 2.5, r"training.patience': expected an integer in \[1, 1000000\] .*got 2.5"),
        (
            "patience",
            True,
            r"training.patience': expected an integer in \[1, 1000000\] .*got True",
        ),
    ],
)
def test_training_keys_are_checked(datasets, key, value, message):
    from simlidar.errors import ConfigError

    recipe = _small_recipe()
    recipe["training"][key] = value
    with pytest.raises(ConfigError, match=message):
        train(recipe, datasets[0.1], epochs=1, progress=False)


def test_train_errors_are_one_line(tmp_path, cli):
    bad = cli("train", "--model", "nope", "--dataset", tmp_path)
    assert bad.exit_code == 2 and "model recipe 'nope'" in bad.stderr
    missing = cli("train", "--model", "snn_simlidar", "--dataset", tmp_path / "x")
    assert missing.exit_code == 1 and "expected a dataset directory" in missing.stderr


def test_a_stream_network_is_refused_on_windows(datasets, tmp_path, cli):
    done = cli("train", "--model", "lif_stream", "--dataset", datasets[0.1], "--out", tmp_path)
    assert done.exit_code == 2 and "Traceback" not in done.output
    assert "recipe lif_stream: a stream network (its [stream] table); expected a window" in (
        done.stderr
    )
    assert not list(tmp_path.iterdir())  # nothing written


def test_noise_augment_draws_the_noise_anew_each_epoch(datasets):
    """Fresh U(0, a) on the clean delays under the split's rule, seeded, different per epoch."""
    import numpy as np

    from simlidar.bench.augment import fresh_noise
    from simlidar.dataset.reader import read_split_info

    path = datasets[0.5]
    attrs = read_split_info(path / "train.h5").attrs
    clean, _ = load_split(path, "train", field="clean_delays")
    stored, _ = load_split(path, "train")
    draw = fresh_noise(path, attrs, seed=3, rows=np.arange(len(clean)))
    first, second = draw(), draw()
    assert first.shape == clean.shape and not np.array_equal(first, second)
    assert not np.array_equal(first, stored)  # not the file's draw
    for x in (first, second):  # the physical rule: returns delayed by at most 0.5, clipped
        assert (x >= clean).all() and (x - clean <= 0.5 + 1e-6).all() and x.max() <= 1.0
        assert (x[clean == 1.0] == 1.0).all()  # a missing return stays missing
    again = fresh_noise(path, attrs, seed=3, rows=np.arange(len(clean)))()
    assert np.array_equal(again, first)  # seeded
    recipe = _small_recipe()
    recipe["training"]["noise_augment"] = True
    a = train(recipe, path, seed=0, epochs=2, progress=False)
    b = train(recipe, path, seed=0, epochs=2, progress=False)
    assert [h["loss"] for h in a.history] == [h["loss"] for h in b.history]


def test_the_train_command_says_what_a_cosine_schedule_kept(datasets, tmp_path, cli):
    recipe = tmp_path / "mlp_cosine.toml"
    text = (Path(__file__).parents[2] / "baselines" / "mlp.toml").read_text()
    recipe.write_text(text.replace("[training]", '[training]\nlr_schedule = "cosine"'))
    base = ["train", "--model", str(recipe), "--dataset", str(datasets[0.1])]
    base += ["--out", str(tmp_path / "runs"), "--validation", "0.34", "--force"]
    whole = cli(*base, "--epochs", "3")
    assert whole.exit_code == 0, whole.output
    assert "epoch 3 of 3 kept (the last of its cosine schedule; validation accuracy" in whole.stdout
    assert "ran every epoch" in whole.stdout and "warning" not in whole.stderr
    cut = cli(*base, "--epochs", "5", "--max-seconds", "0")
    assert cut.exit_code == 0, cut.output
    assert "epoch 1 of 1 kept (the last of its cosine schedule" in cut.stdout
    assert "stopped by the time cap" in cut.stdout
    assert cut.stderr.splitlines()[-1].startswith(
        "warning: the time cap stopped the cosine schedule after epoch 1 of 5, before it "
        "annealed (learning rate 0.001 in that epoch)"
    )
    plain = ["train", "--model", "mlp", "--dataset", str(datasets[0.1]), "--out", str(tmp_path)]
    plain += ["--force"]
    capped = cli(*plain, "--epochs", "5", "--max-seconds", "0")
    assert capped.exit_code == 0 and "warning" not in capped.stderr  # constant rate: no schedule


def _limit_file_size(size: int):
    """A child's pre-exec hook: writes past ``size`` bytes fail (EFBIG; Python ignores
    SIGXFSZ)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, resource.RLIM_INFINITY))

    return limit


def test_train_on_a_full_disk_prints_the_result_then_one_line(datasets, tmp_path):
    import subprocess
    import sys

    runs = tmp_path / "runs"
    for as_json in (False, True):
        args = [sys.executable, "-m", "simlidar.cli", "train", "--model", "mlp", "--epochs", "1"]
        args += ["--dataset", str(datasets[0.1]), "--out", str(runs)] + ["--json"] * as_json
        done = subprocess.run(
            args,
            capture_output=True,
            text=True,
            timeout=600,
            preexec_fn=_limit_file_size(64 * 1024),  # the MLP's checkpoint takes about 450 KB
        )
        assert done.returncode == 1, done.stderr
        checkpoint = runs / f"mlp-{Path(datasets[0.1]).name}-seed0.pt"
        assert done.stderr.strip().splitlines()[-1] == (
            f"Error: {checkpoint}: cannot write the checkpoint (File too large)"
        )
        assert "Traceback" not in done.stderr
        if as_json:
            record = json.loads(done.stdout)
            assert record["checkpoint"] is None and 0 <= record["test_accuracy"] <= 1
        else:
            assert done.stdout.startswith("mlp: test accuracy 0.")
        assert list(runs.iterdir()) == []
