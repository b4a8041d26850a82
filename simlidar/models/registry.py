"""One registry for every model (spiking and conventional), built from a recipe.

A recipe is a TOML file in ``baselines/`` (or any path): ``model`` names a registered
builder, ``[architecture]`` its arguments and ``[training]`` the hyper-parameters. Input shape
and class count come from the dataset, never from the recipe.
"""

import tomllib
from collections.abc import Callable
from pathlib import Path

from simlidar.content import content_dir
from simlidar.errors import ConfigError

MODELS: dict[str, Callable] = {}


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
        raise ConfigError(f"model recipe {str(name_or_path)!r}: expected one of {names} or a "
                          ".toml file")  # fmt: skip
    try:
        recipe = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    for key in ("model", "architecture", "training"):
        if key not in recipe:
            raise ConfigError(f"{path}: key '{key}' is missing")
    if recipe["model"] not in MODELS:
        raise ConfigError(f"{path}: key 'model': expected one of {sorted(MODELS)}, got "
                          f"{recipe['model']!r}")  # fmt: skip
    training = recipe["training"]
    for key, low in (("lr", 0.0), ("batch_size", 1), ("epochs", 1)):
        value = training.get(key)
        if (
            not isinstance(value, int | float)
            or isinstance(value, bool)
            or not (value > low if key == "lr" else value >= low)
        ):
            raise ConfigError(f"{path}: key 'training.{key}': expected a number "
                              f"{'>' if key == 'lr' else '>='} {low}, got {value!r}")  # fmt: skip
    recipe["name"] = path.stem
    return recipe


def build_model(recipe: dict, input_shape: tuple[int, ...], classes: int, generator=None):
    """Instantiate the recipe's model for inputs of ``input_shape`` (C, H, W) and ``classes``."""
    try:
        return MODELS[recipe["model"]](input_shape, classes, generator, **recipe["architecture"])
    except TypeError as exc:
        raise ConfigError(f"recipe {recipe.get('name', '?')}: [architecture] {exc}") from None
