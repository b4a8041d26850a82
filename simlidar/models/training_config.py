"""How a model trains: a recipe's ``[training]`` table as one frozen dataclass, every key with
its default, accepted values and meaning (docs/snn.md, Training; docs/benchmark.md, Training and
model selection). ``lr``, ``batch_size`` and ``epochs`` have no default: a recipe names them.

A recipe keeps its table as written (its fingerprint is the file's content);
:meth:`TrainingConfig.from_table` reads it, with a one-line error naming the first unknown key
or bad value. A suite's ``[budget]`` overrides a few keys and is checked by the same rules
(:meth:`TrainingConfig.check_table`).
"""

import math
from dataclasses import MISSING, dataclass, fields, replace

from simlidar.errors import ConfigError
from simlidar.settings import Choice, Range, check, check_value, setting

LOGITS = ("z", "time")  # a spiking model's logits: -z (the paper's) or -t = -ln z
SCHEDULES = ("constant", "cosine")  # cosine: from lr down to 0 over the run's epochs
# the early-decision term's form (docs/snn.md, "Deciding early"): the correct output's spike
# time t, exp(t / early_beta) (Goeltz et al. 2021), or S4NN's relative targets
EARLY_FORMS = ("linear", "exp", "relative")
MAX_EPOCHS = 10**6  # the most epochs (and patience) a run may ask for
NON_NEGATIVE = Range(0, None, "a finite number", finite=True)
# A penalty's weight and a margin are bounded where a larger value only makes the loss overflow
# (early_penalty = 1e308 trained to NaN weights): the shipped recipes weigh penalties at most
# 100 (weight_sum_penalty, Mostafa 2018's K) and the published runs early terms at most 10;
# margins are in time constants, where output spikes come within a few
PENALTY = Range(0, 10_000, "a finite number")
MARGIN = Range(0, 100, "a finite number", note="(time constants)")
# exp(t / early_beta) overflows float32 beyond t / early_beta = 88: output spike times of a few
# time constants need early_beta well above 0.01 (Goeltz et al. 2021 use 1)
EARLY_BETA = Range(0.05, 100, "a finite number", note="(time constants)")


@dataclass(frozen=True)
class TrainingConfig:
    lr: float = setting(help="Learning rate.", rule=Range(0, None, "a number", low_open=True))
    batch_size: int = setting(help="Samples per step.", rule=Range(1, None, "an integer"))
    epochs: int = setting(help="Epoch cap.", rule=Range(1, MAX_EPOCHS, "an integer"))
    optimizer: str = setting("sgd", "Optimiser.", Choice(("sgd", "adam")))
    momentum: float = setting(0.0, "SGD momentum.", NON_NEGATIVE)
    l2: float = setting(0.0, "Weight of the sum of squared parameters in the loss.", PENALTY)
    clip_grad_norm: float = setting(
        0.0, "Clip the gradient's norm at this value (0: no clipping).", NON_NEGATIVE
    )
    max_seconds: float = setting(
        math.inf,
        "Time cap: training stops after the epoch that crosses it (inf: none).",
        Range(0, None, "seconds"),
    )
    weight_sum_penalty: float = setting(
        0.0, "Spiking networks: weight of Mostafa's weight-sum penalty.", PENALTY
    )
    logits: str = setting(
        "z", "Spiking networks: logits -z (the paper's) or -t = -ln z.", Choice(LOGITS)
    )
    logit_scale: float = setting(
        1.0,
        "Spiking networks: inverse softmax temperature of the logits.",
        Range(0, None, "a finite number", low_open=True, finite=True),
    )
    fire_penalty: float = setting(
        0.0, "Spiking networks: weight of the target-neuron firing penalty.", PENALTY
    )
    fire_margin: float = setting(0.1, "Spiking networks: margin of that penalty.", MARGIN)
    lr_schedule: str = setting(
        "constant",
        "constant, or cosine: from lr down to 0 over the run's epochs (the run then keeps its "
        "last epoch).",
        Choice(SCHEDULES),
    )
    early_penalty: float = setting(
        0.0, "Spiking networks: weight of the early-decision term.", PENALTY
    )
    early_form: str = setting(
        "linear",
        "Spiking networks: the early-decision term: linear (the correct output's spike time), "
        "exp (Goeltz et al. 2021: exp(t / early_beta)) or relative (S4NN's targets: the "
        "correct output at the earliest output's time, the others early_margin later).",
        Choice(EARLY_FORMS),
    )
    early_beta: float = setting(
        1.0, "Spiking networks: the exp form's time scale, in time constants.", EARLY_BETA
    )
    early_margin: float = setting(
        0.5, "Spiking networks: the relative form's margin, in time constants.", MARGIN
    )
    early_start: int = setting(
        0,
        "Spiking networks: the epoch (0-based) from which the early-decision term is on (a "
        "schedule that adds it once accuracy has converged).",
        Range(0, None, "an integer"),
    )
    noise_augment: bool = setting(
        False, "Draw fresh noise for the training rows every epoch.", Choice((True, False))
    )
    validation: float = setting(
        0.1,
        "Fraction of each class held out for model selection (0: none).",
        Range(0, 1, "a fraction of the train split", high_open=True, note="(0: no validation)"),
    )
    patience: int = setting(
        10,
        "Epochs without a better validation score before training stops.",
        Range(1, MAX_EPOCHS, "an integer", note="(epochs without a better validation score)"),
    )

    def __post_init__(self) -> None:
        check(self)

    @classmethod
    def check_table(cls, table, where: str, prefix: str = "training.") -> None:
        """Check the keys of a (possibly partial) table: unknown keys and bad values get a
        ConfigError ``<where>: key '<prefix><key>': expected ..., got ...``."""
        if not isinstance(table, dict):
            key = prefix.rstrip(".")
            raise ConfigError(f"{where}: key '{key}': expected a table, got {table!r}")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(table) - set(names))
        if unknown:
            raise ConfigError(
                f"{where}: unknown key '{prefix}{unknown[0]}': expected one of {sorted(names)}"
            )
        for name in names:
            if name in table:
                value = table[name]
                check_value(
                    cls,
                    name,
                    value,
                    lambda key, expected, v=value: (
                        f"{where}: key '{prefix}{key}': expected {expected}, got {v!r}"
                    ),
                )

    @classmethod
    def from_table(cls, table, where: str = "recipe") -> "TrainingConfig":
        """A recipe's ``[training]`` table, checked (:meth:`check_table`); a required key that is
        missing is named too."""
        cls.check_table(table, where)
        for f in fields(cls):
            if f.default is MISSING and f.name not in table:
                rule = f.metadata["rule"]
                raise ConfigError(
                    f"{where}: key 'training.{f.name}': expected {rule.expected()}, got nothing"
                )
        return cls(**table)

    def over(self, **values) -> "TrainingConfig":
        """This configuration with ``values`` (None: keep) over it."""
        return replace(self, **{k: v for k, v in values.items() if v is not None})
