"""Settings declared once (simlidar.settings): the dataclass field's rule is the check, the
command line option's type and default come from the same field."""

import math

import click
import pytest

from simlidar.cli import main
from simlidar.convert.config import DvsConfig, KittiConfig
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.sweep import SweepConfig
from simlidar.models.training_config import TrainingConfig
from simlidar.settings import Choice, Range, default_of, rule_of


@pytest.mark.parametrize(
    ("rule", "good", "bad", "expected"),
    [
        (Range(2, None, "an integer"), [2, 10**400], [1, 2.5, True, "3"], "an integer >= 2"),
        (Range(0, 1, "a level"), [0, 0.5, 1], [-0.1, 1.01, math.nan, 10**400], "a level in [0, 1]"),
        (
            Range(0, 2**63, "an integer", high_open=True),
            [0, 2**63 - 1],
            [-1, 2**63],
            "an integer in [0, 2**63)",
        ),
        # an int too large for a float is no number of seconds (it used to raise OverflowError)
        (Range(0, None, "seconds"), [0, math.inf], [-1, math.nan, 10**400], "seconds >= 0"),
        (
            Range(0, None, "a finite number", finite=True),
            [0, 3.5],
            [math.inf],
            "a finite number >= 0",
        ),
        (Choice(("z", "time")), ["z", "time"], ["exp", 1], "one of ['z', 'time']"),
        (Choice((True, False)), [True, False], [1, 0, "true"], "true or false"),
    ],
)
def test_a_rule_accepts_what_its_message_says(rule, good, bad, expected):
    assert all(rule.accepts(v) for v in good)
    assert not any(rule.accepts(v) for v in bad)
    assert rule.expected() == expected


def _option(command: click.Command, flag: str) -> click.Option:
    return next(p for p in command.params if flag in getattr(p, "opts", ()))


@pytest.mark.parametrize(
    ("command", "flag", "cls", "name"),
    [
        (("generate",), "--classes", GeneratorConfig, "classes"),
        (("generate",), "--train-size", GeneratorConfig, "train_size"),
        (("generate",), "--test-size", GeneratorConfig, "test_size"),
        (("generate",), "--seed", GeneratorConfig, "seed"),
        (("generate",), "--width", GeneratorConfig, "width"),
        (("sweep",), "--frames", SweepConfig, "frames"),
        (("sweep",), "--variation", GeneratorConfig, "variation"),
        (("convert", "kitti"), "--crop", KittiConfig, "crop"),
        (("convert", "kitti"), "--res-h", KittiConfig, "res_h_deg"),
        (("convert", "kitti"), "--max-range", KittiConfig, "max_range_m"),
        (("convert", "kitti"), "--test-fraction", KittiConfig, "test_fraction"),
        (("convert", "dvs-barrel"), "--test-fraction", DvsConfig, "test_fraction"),
        (("convert", "dvs-barrel"), "--seed", DvsConfig, "seed"),
    ],
)
def test_an_option_takes_its_default_and_range_from_the_dataclass_field(command, flag, cls, name):
    group = main
    for word in command:
        group = group.commands[word]
    option = _option(group, flag)
    default = default_of(cls, name)
    assert option.default == (list(default) if isinstance(default, tuple) else default) or (
        tuple(option.default) == default
    )
    rule = rule_of(cls, name)
    if isinstance(rule, Range):  # the option refuses just outside each bound, accepts on it
        for bound, open_, step in ((rule.low, rule.low_open, -1), (rule.high, rule.high_open, 1)):
            if bound is None:
                continue
            outside = bound + step * (1 if rule.integer else 1e-9 * max(1, abs(bound)))
            with pytest.raises(click.BadParameter):
                option.type.convert(bound if open_ else outside, option, None)


def test_the_noise_option_shows_the_config_default():
    option = _option(main.commands["generate"], "--noise")
    assert option.default == str(GeneratorConfig().noise)


def test_a_training_table_is_read_with_one_line_errors():
    config = TrainingConfig.from_table({"lr": 1e-3, "batch_size": 32, "epochs": 5}, "r.toml")
    assert (config.validation, config.patience, config.max_seconds) == (0.1, 10, math.inf)
    assert config.over(epochs=None, patience=3).patience == 3
    with pytest.raises(
        ConfigError,
        match=r"r.toml: key 'training.epochs': expected an integer in \[1, 1000000\], got noth",
    ):
        TrainingConfig.from_table({"lr": 1e-3, "batch_size": 32}, "r.toml")
    with pytest.raises(ConfigError, match=r"unknown key 'training.lrate': expected one of \["):
        TrainingConfig.from_table({"lrate": 1}, "r.toml")
    with pytest.raises(
        ConfigError, match=r"key 'budget.patience': expected an integer in \[1, 1000000\] "
    ):
        TrainingConfig.check_table({"patience": 0}, "suite s", "budget.")
