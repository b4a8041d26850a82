"""One registry for every model (spiking and conventional), built from a recipe.

A recipe is a TOML file in ``baselines/`` (or any path): ``model`` names a registered
builder, ``[architecture]`` its arguments and ``[training]`` the hyper-parameters. Input shape
and class count come from the dataset, never from the recipe.
"""

import importlib
import tomllib
from collections.abc import Callable
from pathlib import Path

from simlidar.content import content_dir
from simlidar.errors import ConfigError
from simlidar.models.training import TrainingConfig

# model name (a recipe's `model`) -> (module of simlidar.models, builder function); each
# builder is ``builder(input_shape, classes, generator, **architecture)``. The modules (torch)
# load on first use, so that the training configuration imports without torch.
BUILDERS = {
    "snn": ("networks", "dense_snn"),
    "scnn": ("networks", "spiking_cnn"),
    "cnn": ("conventional", "cnn"),
    "mlp": ("conventional", "mlp"),
    "vgg": ("conventional", "vgg"),
    "resnet": ("conventional", "resnet"),
}


def builder(name: str) -> Callable:
    """The builder of the model ``name`` (one of BUILDERS)."""
    module, function = BUILDERS[name]
    return getattr(importlib.import_module(f"simlidar.models.{module}"), function)


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
    if recipe["model"] not in BUILDERS:
        raise ConfigError(
            f"{path}: key 'model': expected one of {sorted(BUILDERS)}, got {recipe['model']!r}"
        )
    recipe["name"] = path.stem
    TrainingConfig.from_table(recipe["training"], str(path))  # checked; kept as written
    return recipe


def build_model(recipe: dict, input_shape: tuple[int, ...], classes: int, generator=None):
    """Instantiate the recipe's model for inputs of ``input_shape`` (C, H, W) and ``classes``."""
    try:
        return builder(recipe["model"])(input_shape, classes, generator, **recipe["architecture"])
    except TypeError as exc:
        raise ConfigError(f"recipe {recipe.get('name', '?')}: [architecture] {exc}") from None
