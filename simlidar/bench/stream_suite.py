"""Stream suites: ``simlidar bench --suite stream`` (docs/streams.md, "Running them").

A stream suite is a suite file (``benchmark/<name>.toml`` or any path) with ``task =
"stream"``::

    name = "stream"
    task = "stream"
    description = "..."
    models = ["cnn", "mlp", "gru_rotations", "lif_stream"]   # window models and stream networks
    event_models = ["snn_simlidar_tuned"]    # spiking window models, run event-driven
    window_models = ["cnn"]                  # window models answering at their window's end
    estimate = ["mlp-latest", "cnn-latest"]  # the estimate's learner families ([] none)
    seeds = [0, 1, 2, 3, 4]
    estimate_seeds = [0, 1, 2]
    validation = 0.1                         # the training streams held out, whole

    [generate]                               # the stream dataset: generate_streams' arguments
    train_size = 1500
    test_size = 600

    [budget]                                 # epochs of every model (default: its recipe's) ...
    [budget.cnn]                             # ... and of one
    epochs = 30

The dataset is made in ``<out>/data`` (kept when it is already the one asked for: the same
configuration, scenes and version, and ``simlidar verify`` passes), or given (``--dataset``);
the cells, the estimate and the report are written in ``<out>`` as
:mod:`simlidar.bench.stream_bench` writes them, and a run started again skips what is done.
"""

import json
from dataclasses import dataclass, field
from pathlib import Path

from simlidar.bench.stream_estimate import family_parts
from simlidar.bench.suite import SEED, SUITE_NAME
from simlidar.content import check_keys, key_error, read_toml, shipped_or_path
from simlidar.errors import ConfigError, DatasetError

TASK = "stream"
KEYS = (
    "name",
    "task",
    "description",
    "models",
    "event_models",
    "window_models",
    "estimate",
    "seeds",
    "estimate_seeds",
    "validation",
    "generate",
    "budget",
)
GENERATE = (
    "classes",
    "train_size",
    "test_size",
    "seed",
    "width",
    "fov_deg",
    "rotations",
    "min_object_hits",
    "max_attempts",
    "variation",
    "sensor",
    "profile",
    "fog_visibility_m",
    "rain_rate_mm_h",
)
MAX_SUITE_BYTES = 1024 * 1024


@dataclass(frozen=True)
class StreamSuite:
    name: str
    path: Path
    description: str
    models: tuple[str, ...]
    event_models: tuple[str, ...]
    window_models: tuple[str, ...]
    estimate: tuple[str, ...]
    seeds: tuple[int, ...]
    estimate_seeds: tuple[int, ...]
    validation: float
    generate: dict = field(default_factory=dict)
    epochs: dict = field(default_factory=dict)  # model ("*": every one) -> epochs

    def epochs_of(self, model: str) -> int | None:
        return self.epochs.get(model, self.epochs.get("*"))


def _data(name_or_path) -> tuple[Path, dict]:
    path = shipped_or_path(name_or_path, "benchmark", "suite")
    return path, read_toml(path, MAX_SUITE_BYTES, ConfigError, f"suite {path}")


def is_stream_suite(name_or_path) -> bool:
    """Whether a suite file says ``task = "stream"`` (False for one that does not read: the
    window suites' loader names what is wrong with it)."""
    try:
        _, data = _data(name_or_path)
    except ConfigError:
        return False
    return data.get("task") == TASK


def _names(where: str, data: dict, key: str, default, kind: str, check=None) -> tuple:
    values = data.get(key, default)
    if not isinstance(values, list) or not all(isinstance(v, kind) for v in values):
        raise key_error(where, key, f"a list of {kind.__name__}s", values)
    if isinstance(kind, type) and kind is int and any(isinstance(v, bool) for v in values):
        raise key_error(where, key, "a list of integers", values)
    if len(set(values)) != len(values):
        raise key_error(where, key, "distinct values", values)
    for value in values:
        if check is not None:
            check(value)
    return tuple(values)


def _seed(where: str, key: str):
    def check(value):
        if not SEED.accepts(value):
            raise key_error(where, key, "integers in [0, 2**63)", value)

    return check


def load_stream_suite(name_or_path) -> StreamSuite:
    """A stream suite by name or path, every key checked (recipes and families by name)."""
    from simlidar.models.registry import load_recipe

    path, data = _data(name_or_path)
    where = f"suite {path}"
    check_keys(where, data, KEYS, optional=set(KEYS) - {"task", "models", "generate"})
    if data["task"] != TASK:
        raise key_error(where, "task", repr(TASK), data["task"])
    name = data.get("name", path.stem)
    if not (isinstance(name, str) and SUITE_NAME.match(name)):
        raise key_error(where, "name", "letters, digits, '_', '-' or '.'", name)
    models = _names(where, data, "models", None, str, load_recipe)
    event_models = _names(where, data, "event_models", [], str, load_recipe)
    window_models = _names(where, data, "window_models", [], str, load_recipe)
    if not models and not event_models and not window_models:
        raise key_error(where, "models", "at least one model", models)
    estimate = _names(where, data, "estimate", [], str, family_parts)
    seeds = _names(where, data, "seeds", [0], int, _seed(where, "seeds"))
    estimate_seeds = _names(where, data, "estimate_seeds", [0], int, _seed(where, "estimate_seeds"))
    if not seeds:
        raise key_error(where, "seeds", "at least one seed", seeds)
    validation = data.get("validation", 0.1)
    if (
        isinstance(validation, bool)
        or not isinstance(validation, int | float)
        or not (0 <= validation <= 0.5)
    ):
        raise key_error(where, "validation", "a fraction in [0, 0.5]", validation)
    generate = data["generate"]
    if not isinstance(generate, dict):
        raise key_error(where, "generate", "a table ([generate])", generate)
    for key in generate:
        if key not in GENERATE:
            raise key_error(where, f"generate.{key}", f"one of {list(GENERATE)}", generate[key])
    from simlidar.generator.stream_config import StreamConfig

    try:
        _config(generate, StreamConfig)
    except ConfigError as exc:
        raise ConfigError(f"{where}: [generate] {exc}") from None
    return StreamSuite(
        name=name,
        path=path,
        description=str(data.get("description", "")),
        models=models,
        event_models=event_models,
        window_models=window_models,
        estimate=estimate,
        seeds=seeds,
        estimate_seeds=estimate_seeds,
        validation=float(validation),
        generate=dict(generate),
        epochs=_epochs(where, data.get("budget", {}), {*models, *event_models, *window_models}),
    )


def _config(generate: dict, config_class):
    from simlidar.sensor import load_sensor

    sensor = load_sensor(generate.get("sensor", "vlp16"))
    return config_class(**(generate | {"sensor": sensor}))


def _epochs(where: str, budget, models: set) -> dict:
    """[budget]: ``epochs`` for every model, [budget.<model>] ``epochs`` for one."""
    if not isinstance(budget, dict):
        raise key_error(where, "budget", "a table ([budget])", budget)
    epochs = {}

    def count(key: str, value) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 10_000:
            raise key_error(where, key, "a number of epochs in [1, 10000]", value)
        return value

    for key, value in budget.items():
        if isinstance(value, dict):
            if key not in models:
                raise key_error(
                    where, f"budget.{key}", f"a model of the suite {sorted(models)}", key
                )
            for inner in value:
                if inner != "epochs":
                    raise key_error(where, f"budget.{key}.{inner}", "epochs", value[inner])
            if "epochs" in value:
                epochs[key] = count(f"budget.{key}.epochs", value["epochs"])
        elif key == "epochs":
            epochs["*"] = count("budget.epochs", value)
        else:
            raise key_error(where, f"budget.{key}", "epochs or a model's table", value)
    return epochs


def stream_dataset(suite: StreamSuite, out: Path, progress: bool = True, note=print) -> Path:
    """The suite's dataset in ``out/data``: made, or kept where it is already the one asked for
    (a DatasetError naming why not, where it is not)."""
    from simlidar.generator.stream_config import StreamConfig
    from simlidar.generator.stream_files import generate_streams, scenes_digest, stream_name
    from simlidar.scene.recipe import load_catalog

    config = _config(suite.generate, StreamConfig)
    path = out / "data" / stream_name(config)
    if not path.exists():
        return generate_streams(out / "data", progress=progress, **suite.generate)
    from simlidar.dataset.loaders import split_info
    from simlidar.release.verify import verify

    catalog = load_catalog().for_sensor(config.sensor.name)
    why = None
    try:
        for split in ("train", "test"):
            attrs = split_info(path, split).attrs
            stored = attrs["config"]  # decoded by split_info
            if (json.loads(stored) if isinstance(stored, str) else stored) != json.loads(
                config.to_json()
            ):
                why = "was made with another configuration"
            elif attrs.get("input_sha256") != scenes_digest(catalog):
                why = "was made from other scenes or scenarios"
    except (DatasetError, OSError, KeyError, ValueError) as exc:
        why = f"is not a stream dataset simlidar reads ({exc})"
    problems = [] if why else verify(path)
    if problems:
        why = f"does not verify ({problems[0]})"
    if why:
        raise DatasetError(f"{path} already exists and {why}: remove it, or give another --out")
    note(f"kept {path}")
    return path


def run_stream_suite(
    suite: StreamSuite,
    out: Path,
    command: str,
    dataset: Path | None = None,
    models: list[str] | None = None,
    epochs: int | None = None,
    progress: bool = True,
    note=print,
) -> dict:
    """Make (or keep) the suite's dataset, run its cells and estimate, write the report; the
    report's summary.

    out : the output folder (the dataset in ``out/data`` unless ``dataset`` is given)
    command : what made the cells, recorded in each
    models : in place of the suite's ``models`` (its event and window models kept)
    epochs : every model's, over the suite's
    progress, note : a progress bar while the dataset is made; called with a line as each
        cell finishes
    """
    from simlidar.bench import stream_bench, stream_report

    planned = stream_bench.plans(
        models if models is not None else suite.models, suite.event_models, suite.window_models
    )
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: expected a folder")
    if dataset is None:
        dataset = stream_dataset(suite, out, progress, note)
    cells = stream_bench.run_cells(
        dataset,
        out,
        planned,
        suite.seeds,
        command,
        epochs=lambda name: epochs if epochs is not None else suite.epochs_of(name),
        validation=suite.validation,
        note=note,
    )
    if suite.estimate:
        stream_bench.run_estimate(dataset, out, suite.estimate, suite.estimate_seeds, command, note)
    stream_report.write_report(out, cells)
    return stream_report.summary(cells)
