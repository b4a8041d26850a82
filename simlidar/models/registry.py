"""One registry for every model (spiking and conventional, shipped or outside), built from a
recipe.

A recipe is a TOML file in ``baselines/`` (or any path): ``model`` names a builder,
``[architecture]`` its arguments, ``[training]`` the hyper-parameters and an optional ``[spec]``
what the model outputs and which input it wants (:mod:`simlidar.models.protocol`). Input
shape and class count come from the dataset, never from the recipe.

A builder is one of :data:`BUILDERS` or an outside one: ``"package.module:function"`` (imported)
or ``"path/to/file.py:function"`` (relative to the recipe's folder), called as
``function(input_shape, classes, generator, **architecture)`` and returning a
``torch.nn.Module``. Naming an outside builder runs its code, as a pytest plugin's would.
``simlidar bench --models package.module:function`` names one without a recipe file (the
default training of :data:`OUTSIDE_TRAINING`).
"""

import hashlib
import importlib
import importlib.util
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path

from simlidar.content import read_toml, shipped_or_path
from simlidar.errors import ConfigError, raised
from simlidar.models.protocol import reset_state, spec_of, stateful_modules
from simlidar.models.training_config import TrainingConfig

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
    # stream networks (a recipe's [stream] table; simlidar.models.stream_nets)
    "gru_rotations": ("stream_nets", "rotation_gru"),
    "lif_stream": ("stream_nets", "lif_stream"),
}

MAX_MODEL_RECIPE_BYTES = 64 * 1024  # a model recipe is a few dozen lines

# builders handed over in this process (simlidar.bench.api): key -> (function, fingerprint)
_REGISTERED: dict[str, tuple[Callable, str | None]] = {}
# builder files imported, by the path as named (relative to the working directory without a
# base) and the base: a model's code that then changes the working directory changes nothing
_FILES: dict[tuple[str, Path | None], object] = {}
# the [training] of a builder named on the command line without a recipe file
OUTSIDE_TRAINING = {"optimizer": "adam", "lr": 1e-3, "batch_size": 60, "epochs": 30}
_OUTSIDE = re.compile(r"^(?P<where>[^:]+):(?P<function>[A-Za-z_][A-Za-z0-9_]*)$")


def is_outside(model: str) -> bool:
    """Whether ``model`` (a recipe's key or a ``--models`` entry) names an outside builder."""
    return _OUTSIDE.match(str(model)) is not None


def builder(name: str, base: Path | None = None) -> Callable:
    """The builder of the model ``name``: one of BUILDERS, ``package.module:function`` or
    ``path/to/file.py:function`` (relative to ``base``, the recipe's folder, or without one to
    the working directory); ConfigError naming it when it does not import or is not a
    function. A file is imported once: the same name and base find its module later, wherever
    a model's code has moved the working directory since."""
    if name in BUILDERS:
        module, function = BUILDERS[name]
        return getattr(importlib.import_module(f"simlidar.models.{module}"), function)
    if name in _REGISTERED:
        return _REGISTERED[name][0]
    match = _OUTSIDE.match(name)
    if match is None:
        raise ConfigError(
            f"model {name!r}: expected one of {sorted(BUILDERS)}, 'package.module:function' "
            "or 'path/to/file.py:function'"
        )
    where, function = match["where"], match["function"]
    try:
        module = _import_file(where, base) if where.endswith(".py") else _import(where)
    except ConfigError:
        raise
    except (Exception, SystemExit) as exc:  # the user's module failed while importing
        raise ConfigError(f"builder {name!r}: importing {where!r} raised {raised(exc)}") from None
    found = getattr(module, function, None)
    if not callable(found):
        raise ConfigError(f"builder {name!r}: {where!r} has no function {function!r}")
    return found


def register(function: Callable, name: str, fingerprint: str | None = None) -> str:
    """Make ``function`` a builder of this process under ``python:<name>`` (what recipes and
    cells then call it); ``fingerprint`` (its source's sha256, say) is what a cell records of
    its code. Returns the key."""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise ConfigError(f"builder name {name!r}: expected a Python identifier")
    key = f"python:{name}"
    _REGISTERED[key] = (function, fingerprint)
    return key


def _import(module: str):
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        cwd = os.getcwd()
        if exc.name == module.split(".")[0] and cwd not in sys.path:
            sys.path.insert(0, cwd)  # as `python -m` would: a module beside the user
            return _import(module)
        raise ConfigError(
            f"builder module {module!r}: cannot import it ({exc}); expected an installed module "
            "or a path/to/file.py"
        ) from None


def _import_file(where: str, base: Path | None):
    imported = _FILES.get((where, base))
    if imported is not None and imported.__name__ in sys.modules:
        return imported
    path = Path(where)
    if not path.is_absolute() and base is not None:
        path = base / path
    if not path.is_file():
        raise ConfigError(f"builder file {str(path)!r}: not found; expected a Python file")
    # one module per file, named after its path: two recipes naming it share it
    name = "simlidar_outside_" + hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:16]
    if name in sys.modules:
        module = sys.modules[name]
    else:  # its __file__ absolute: builder_source reads it wherever the process then is
        spec = importlib.util.spec_from_file_location(name, path.absolute())
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[name]
            raise
    _FILES[(where, base)] = module
    return module


def load_recipe(name_or_path: str | Path) -> dict:
    """A recipe by name (``baselines/<name>.toml``), path, or an outside builder named alone
    (``package.module:function``: :data:`OUTSIDE_TRAINING`), checked for its required keys."""
    if is_outside(str(name_or_path)) and not str(name_or_path).endswith(".toml"):
        name = str(name_or_path)
        builder(name)  # imports now: a bad name is refused before any work
        return {
            "model": name,
            "architecture": {},
            "training": dict(OUTSIDE_TRAINING),
            "name": model_name(name),
        }
    other = " or an outside builder 'package.module:function'"
    path = shipped_or_path(name_or_path, "baselines", "model recipe", other)
    recipe = read_toml(path, MAX_MODEL_RECIPE_BYTES)
    for key in ("model", "training"):
        if key not in recipe:
            raise ConfigError(f"{path}: key '{key}' is missing")
    recipe.setdefault("architecture", {})  # a builder may take no keywords
    if not isinstance(recipe["architecture"], dict):
        raise ConfigError(
            f"{path}: key 'architecture': expected a table, got {recipe['architecture']!r}"
        )
    model = recipe["model"]
    if not isinstance(model, str) or (model not in BUILDERS and not is_outside(model)):
        raise ConfigError(
            f"{path}: key 'model': expected one of {sorted(BUILDERS)}, 'package.module:function' "
            f"or 'path/to/file.py:function', got {model!r}"
        )
    recipe["name"] = path.stem
    if is_outside(model):
        recipe["base"] = str(path.resolve().parent)  # where a file builder's path starts
        builder(model, path.resolve().parent)  # imports now: refused before any work
    TrainingConfig.from_table(recipe["training"], str(path))  # checked; kept as written
    if "spec" in recipe:
        if not isinstance(recipe["spec"], dict):
            raise ConfigError(f"{path}: key 'spec': expected a table, got {recipe['spec']!r}")
        spec_of(None, recipe["spec"], str(path))  # checked over the defaults
    if "stream" in recipe:  # a stream network's input (checked without torch)
        from simlidar.models.stream_spec import stream_spec_of

        stream_spec_of(recipe, str(path))
    return recipe


def builder_source(recipe: dict) -> str | None:
    """sha256 of an outside builder's source file (None for a shipped builder or one whose
    source cannot be read): a cell made by other code is not reused."""
    if recipe["model"] in BUILDERS:
        return None
    if recipe["model"] in _REGISTERED:
        return _REGISTERED[recipe["model"]][1]
    function = builder(recipe["model"], Path(recipe["base"]) if "base" in recipe else None)
    try:
        source = Path(sys.modules[function.__module__].__file__).read_bytes()
    except (KeyError, AttributeError, TypeError, OSError):
        return None
    return hashlib.sha256(source).hexdigest()


def model_name(model: str) -> str:
    """The name a recipe, path or builder named alone goes by in cells and reports: the
    recipe file's stem, or a builder's whole module path (a file's stem) and function,
    file-safe: ``mynets.snt_conv:build`` is ``mynets.snt_conv.build``, never ``mynets.build``
    (two builders of one package would share a cell)."""
    if is_outside(str(model)) and not str(model).endswith(".toml"):
        where, function = str(model).rsplit(":", 1)
        module = Path(where).stem if where.endswith(".py") else where
        return re.sub(r"[^A-Za-z0-9_.-]", "_", f"{module}.{function}")
    return Path(model).stem


def check_distinct(models: list[str]) -> None:
    """Refuse models of one run that would share a cell id (:func:`model_name`): two builders
    or recipe files of one name from different places (``a/mine.toml`` and ``b/mine.toml``), whose
    cells would overwrite each other's; ConfigError naming both. One model named twice is
    one model."""
    seen: dict[str, str] = {}
    for model in models:
        name = model_name(model)
        source = str(model) if is_outside(str(model)) and not str(model).endswith(".toml") else None
        if source is None:
            try:
                source = str(shipped_or_path(model, "baselines", "model recipe").resolve())
            except ConfigError:
                source = str(model)
        if seen.setdefault(name, source) != source:
            raise ConfigError(
                f"models {seen[name]!r} and {source!r} would both be cells of model {name!r}; "
                "expected models of different names (rename one recipe file, or name its "
                "builder in a recipe of its own)"
            )


def build_model(recipe: dict, input_shape: tuple[int, ...], classes: int, generator=None):
    """Instantiate the recipe's model for inputs of ``input_shape`` (C, H, W) and ``classes``;
    ConfigError naming the recipe and the builder where it raises or returns no module."""
    import torch

    name = recipe["model"]
    where = f"recipe {recipe.get('name', '?')}"
    make = builder(name, Path(recipe["base"]) if "base" in recipe else None)
    try:
        model = make(input_shape, classes, generator, **recipe.get("architecture", {}))
    except TypeError as exc:
        if name in BUILDERS:
            raise ConfigError(f"{where}: [architecture] {exc}") from None
        raise ConfigError(f"{where}: builder {name!r} raised TypeError: {exc}") from None
    except ConfigError:
        raise
    except (Exception, SystemExit) as exc:  # SystemExit(0) is a builder failing, not success
        if name in BUILDERS and not isinstance(exc, SystemExit):
            raise
        raise ConfigError(f"{where}: builder {name!r} raised {raised(exc)}") from None
    if not isinstance(model, torch.nn.Module):
        raise ConfigError(
            f"{where}: builder {name!r} returned {type(model).__name__}; expected a torch.nn.Module"
        )
    if stateful_modules(model):  # each forward call is a new batch: its neurons start at rest
        model.register_forward_pre_hook(reset_state)
    return model
