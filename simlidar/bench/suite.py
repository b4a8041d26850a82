"""Benchmark suites: which models, on which datasets, with which seeds and training budget.

A suite is a TOML file (``benchmark/<name>.toml`` or any path)::

    name = "quick"
    description = "..."
    models = ["snn_simlidar", "cnn"]     # recipes in baselines/ (or .toml paths)
    seeds = [0]
    board_power_w = 65.0                 # optional: the paper's energy estimate, power x latency

    [generate]                           # datasets made on the fly (GeneratorConfig fields) ...
    noise = [0.1, 0.5]                   # ... one per noise level
    profile = "paper"                    # a dataset profile (the default), or a .toml path
    train_size = 640

    # datasets = ["data/my-dataset"]     # ... or dataset directories instead of [generate]

    [budget]                             # per (dataset, model, seed) cell; each key overrides
    epochs = 5                           # the recipe's [training] value of the same name
    max_seconds = 60
    patience = 10                        # epochs without a better validation score
    validation = 0.1                     # fraction of each class held out for selection
    [budget.snn_simlidar]                # per model, overriding the defaults above
    epochs = 10
"""

import hashlib
import json
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from simlidar.content import content_dir, key_error, read_toml, shipped_or_path
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.profiles import DEFAULT_PROFILE, load_profile
from simlidar.models.registry import load_recipe
from simlidar.models.training_config import TrainingConfig
from simlidar.settings import Range

SUITE_NAME = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}$")
KEYS = {"name", "description", "models", "seeds", "board_power_w", "generate", "datasets", "budget"}
KEYS |= {"task"}  # "window" (the default); a stream suite's is read by simlidar.bench.stream_suite
# A board's power, watts: 100 kW is a rack of accelerators. Beyond it (inf, 1e308) the energy
# estimate, power x latency, overflowed to a bare Infinity in results.json.
MAX_BOARD_POWER_W = 100_000
MAX_SUITE_BYTES = 1024 * 1024  # a suite lists models and datasets: far less than this
BUDGET_KEYS = ("epochs", "max_seconds", "validation", "patience")  # also a cell's rules
SEED = Range(0, 2**63, "an integer", high_open=True)  # a training seed (as train's --seed)


@dataclass(frozen=True)
class Suite:
    name: str
    path: Path
    sha256: str  # of the suite file's bytes
    data_sha256: str  # of its [generate] table or datasets list: an output directory's data
    description: str
    models: tuple[str, ...]
    seeds: tuple[int, ...]
    generate: GeneratorConfig | None  # datasets made on the fly, one per noise level ...
    noise: tuple[float, ...]
    datasets: tuple[Path, ...]  # ... or existing dataset directories
    budget: dict = field(default_factory=dict)  # model ("*": all) -> {key: value}
    board_power_w: float | None = None

    def budget_for(self, model: str) -> dict:
        return {**self.budget.get("*", {}), **self.budget.get(model, {})}

    def with_budget(self, **overrides) -> "Suite":
        """The suite with ``overrides`` (budget keys; None: not given) set for every model,
        over the suite's own values (``simlidar bench --epochs/--max-seconds``)."""
        given = {k: v for k, v in overrides.items() if v is not None}
        budget = {model: {**table, **given} for model, table in self.budget.items()}
        return replace(self, budget=budget)


def suite_names() -> list[str]:
    return sorted(p.stem for p in content_dir("benchmark").glob("*.toml"))


def _fail(path: Path, key: str, expected: str, got) -> ConfigError:
    """A suite file's bad key (:func:`simlidar.content.key_error`)."""
    return key_error(f"suite {path}", key, expected, got)


def _budget(path: Path, table: dict, key: str) -> dict:
    """A [budget] table: some of TrainingConfig's keys (BUDGET_KEYS), checked by its rules."""
    for name, value in table.items():
        if name not in BUDGET_KEYS:
            raise _fail(path, f"{key}.{name}", f"one of {sorted(BUDGET_KEYS)}", value)
    TrainingConfig.check_table(table, f"suite {path}", f"{key}.")
    return dict(table)


def load_suite(name_or_path: str | Path) -> Suite:
    """A suite by name (``benchmark/<name>.toml``) or path, every key checked."""
    path = shipped_or_path(name_or_path, "benchmark", "suite")
    data = read_toml(path, MAX_SUITE_BYTES, ConfigError, f"suite {path}")
    raw = path.read_bytes()  # its digest names the suite's settings
    if data.get("task", "window") != "window":
        raise _fail(
            path, "task", "'window' here (a stream suite runs with simlidar bench --suite)",
            data["task"],
        )  # fmt: skip
    for key in data:
        if key not in KEYS:
            raise ConfigError(f"suite {path}: unknown key '{key}': expected one of {sorted(KEYS)}")
    name = data.get("name", path.stem)
    if not (isinstance(name, str) and SUITE_NAME.match(name)):
        raise _fail(
            path,
            "name",
            "letters, digits, '_', '-' or '.', not starting with '.' (it "
            "names the output folder bench/<name>)",
            name,
        )
    models = data.get("models")
    if not isinstance(models, list) or not models or not all(isinstance(m, str) for m in models):
        raise _fail(path, "models", "a non-empty list of recipe names", models)
    for model in models:
        load_recipe(model)  # an unknown recipe is named here, before any work
    seeds = data.get("seeds", [0])
    if not isinstance(seeds, list) or not seeds or not all(map(SEED.accepts, seeds)):
        raise _fail(path, "seeds", "a non-empty list of integers in [0, 2**63)", seeds)
    for key, values in (("models", models), ("seeds", seeds)):
        if len(set(values)) != len(values):
            raise _fail(path, key, "distinct values", values)
    for key in ("generate", "budget"):
        if key in data and not isinstance(data[key], dict):
            raise _fail(path, key, "a table ([" + key + "])", data[key])
    if ("generate" in data) == ("datasets" in data):
        raise ConfigError(
            f"suite {path}: expected exactly one of 'generate' (datasets made on "
            "the fly) or 'datasets' (dataset directories)"
        )
    config, noise, datasets = None, (), ()
    if "generate" in data:
        table = dict(data["generate"])
        levels = table.pop("noise", None)
        if not isinstance(levels, list) or not levels or len(set(levels)) != len(levels):
            raise _fail(path, "generate.noise", "a non-empty list of distinct noise levels", levels)
        unknown = set(table) - set(GeneratorConfig.__dataclass_fields__) - {"noise"}
        if unknown or "sensor" in table:
            bad = sorted(unknown | ({"sensor"} & set(table)))[0]
            raise _fail(path, f"generate.{bad}", "a GeneratorConfig field", table[bad])
        try:
            chosen = table.pop("profile", DEFAULT_PROFILE)
            if not isinstance(chosen, str):
                raise _fail(path, "generate.profile", "a profile name or .toml path", chosen)
            profile = load_profile(chosen)
            config = GeneratorConfig.from_profile(profile, **table)
            for level in levels:
                config.with_noise(level)
        except ConfigError as exc:
            raise ConfigError(f"suite {path}: [generate] {exc}") from None
        noise = tuple(float(v) for v in levels)
    else:
        paths = data["datasets"]
        if not isinstance(paths, list) or not paths or not all(isinstance(p, str) for p in paths):
            raise _fail(path, "datasets", "a non-empty list of dataset directories", paths)
        datasets = tuple(Path(p) for p in paths)
    budget = {"*": {}}
    for key, value in data.get("budget", {}).items():
        if isinstance(value, dict):
            if key not in models:
                raise _fail(path, f"budget.{key}", f"a model of the suite {models}", key)
            budget[key] = _budget(path, value, f"budget.{key}")
        else:
            budget["*"].update(_budget(path, {key: value}, "budget"))
    power = data.get("board_power_w")
    watts = Range(0, MAX_BOARD_POWER_W, "watts")
    if power is not None and not watts.accepts(power):
        raise _fail(path, "board_power_w", watts.expected(), power)
    return Suite(
        name=name,
        path=path,
        sha256=hashlib.sha256(raw).hexdigest(),
        data_sha256=hashlib.sha256(
            json.dumps(data.get("generate", data.get("datasets")), sort_keys=True).encode()
        ).hexdigest(),
        description=str(data.get("description", "")),
        models=tuple(models),
        seeds=tuple(seeds),
        generate=config,
        noise=noise,
        datasets=datasets,
        budget=budget,
        board_power_w=power,
    )
