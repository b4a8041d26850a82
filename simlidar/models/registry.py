"""One registry for every model (spiking and conventional), built from a recipe.

A recipe is a TOML file in ``baselines/`` (or any path): ``model`` names a registered
builder, ``[architecture]`` its arguments and ``[training]`` the hyper-parameters. Input shape
and class count come from the dataset, never from the recipe.
"""

import math
import tomllib
from collections.abc import Callable
from pathlib import Path

from simlidar.content import content_dir
from simlidar.errors import ConfigError

MODELS: dict[str, Callable] = {}

TRAINING_KEYS = {  # every key a recipe's [training] table may hold (docs/snn.md, Training)
    "optimizer",
    "lr",
    "momentum",
    "batch_size",
    "l2",
    "clip_grad_norm",
    "epochs",
    "max_seconds",
    "weight_sum_penalty",
    "logits",
    "logit_scale",
    "fire_penalty",
    "fire_margin",
    "lr_schedule",
    "early_penalty",
    "noise_augment",
    "validation",
    "patience",
}
LOGITS = ("z", "time")  # a spiking model's logits: -z (the paper's) or -t = -ln z
SCHEDULES = ("constant", "cosine")  # cosine: from lr down to 0 over the run's epochs


def register_model(name: str):
    """Decorator: make ``builder(input_shape, classes, generator, **architecture)`` buildable."""

    def add(builder: Callable) -> Callable:
        MODELS[name] = builder
        return builder

    return add


def load_recipe(name_or_path: str | Path) -> dict:
    """A recipe by name (``baselines/<name>.toml``) or path, checked for its required keys."""
    path = Path(name_or_path)
    if not path.suffix:
        path = content_dir("baselines") / f"{name_or_path}.toml"
    if not path.is_file():
        names = sorted(p.stem for p in content_dir("baselines").glob("*.toml"))
        raise ConfigError(
            f"model recipe {str(name_or_path)!r}: expected one of {names} or a .toml file"
        )
    try:
        recipe = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    for key in ("model", "architecture", "training"):
        if key not in recipe:
            raise ConfigError(f"{path}: key '{key}' is missing")
    if recipe["model"] not in MODELS:
        raise ConfigError(
            f"{path}: key 'model': expected one of {sorted(MODELS)}, got {recipe['model']!r}"
        )
    recipe["name"] = path.stem
    check_training(recipe, str(path))
    return recipe


def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def check_training(recipe: dict, where: str | None = None) -> dict:
    """The recipe's [training] table, every key checked; a ConfigError names the first bad one."""
    training = recipe["training"]
    where = where or f"recipe {recipe.get('name', '?')}"
    if not isinstance(training, dict):
        raise ConfigError(f"{where}: key 'training': expected a table, got {training!r}")
    unknown = sorted(set(training) - TRAINING_KEYS)
    if unknown:
        raise ConfigError(
            f"{where}: unknown key 'training.{unknown[0]}': expected one of {sorted(TRAINING_KEYS)}"
        )
    for key, low in (("lr", 0.0), ("batch_size", 1), ("epochs", 1)):
        value = training.get(key)
        if not _number(value) or not (value > low if key == "lr" else value >= low):
            raise ConfigError(
                f"{where}: key 'training.{key}': expected a number "
                f"{'>' if key == 'lr' else '>='} {low}, got {value!r}"
            )
    for key, choices, default in (
        ("optimizer", ("sgd", "adam"), "sgd"),
        ("logits", LOGITS, "z"),
        ("lr_schedule", SCHEDULES, "constant"),
    ):
        if training.get(key, default) not in choices:
            raise ConfigError(
                f"{where}: key 'training.{key}': expected one of "
                f"{list(choices)}, got {training[key]!r}"
            )
    if not isinstance(training.get("noise_augment", False), bool):
        raise ConfigError(
            f"{where}: key 'training.noise_augment': expected true or false, got "
            f"{training['noise_augment']!r}"
        )
    check_selection(training, where, "training.")
    for key in (
        "logit_scale",
        "fire_penalty",
        "fire_margin",
        "weight_sum_penalty",
        "l2",
        "early_penalty",
    ):
        value = training.get(key, 1.0 if key == "logit_scale" else 0.0)
        positive = key == "logit_scale"
        if not _number(value) or value < 0 or (positive and value == 0):
            raise ConfigError(
                f"{where}: key 'training.{key}': expected a finite number "
                f"{'>' if positive else '>='} 0, got {value!r}"
            )
    return training


def check_selection(table: dict, where: str, prefix: str) -> None:
    """``validation`` (a fraction in [0, 1)) and ``patience`` (an integer >= 1) of a recipe's
    [training] or a suite's [budget], if present; a ConfigError names the bad one."""
    value = table.get("validation", 0.0)
    if not _number(value) or not 0 <= value < 1:
        raise ConfigError(
            f"{where}: key '{prefix}validation': expected a fraction >= 0 and < 1 "
            f"of the train split (0: no validation), got {value!r}"
        )
    value = table.get("patience", 1)
    if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
        raise ConfigError(
            f"{where}: key '{prefix}patience': expected an integer >= 1 (epochs "
            f"without a better validation score), got {value!r}"
        )


def build_model(recipe: dict, input_shape: tuple[int, ...], classes: int, generator=None):
    """Instantiate the recipe's model for inputs of ``input_shape`` (C, H, W) and ``classes``."""
    try:
        return MODELS[recipe["model"]](input_shape, classes, generator, **recipe["architecture"])
    except TypeError as exc:
        raise ConfigError(f"recipe {recipe.get('name', '?')}: [architecture] {exc}") from None
