"""The ``simlidar`` command line. The only module that imports click.

User mistakes end in one line on stderr: exit code 2 for a bad option value (usage, including a
bad model recipe given to --model), 1 for anything else (a bad scene recipe, a path that is not
a dataset, an existing dataset, ...). ``--debug`` shows the traceback instead.
"""

import json
import sys
import time
import warnings
from pathlib import Path

import click

from simlidar import __version__
from simlidar.errors import ConfigError, SimlidarError

_NO_ARGS = getattr(click.exceptions, "NoArgsIsHelpError", ())  # click >= 8.2


class _Group(click.Group):
    """Turns library errors into one-line messages with the right exit code."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except ConfigError as exc:
            if ctx.meta.get("debug"):
                raise
            raise click.UsageError(str(exc)) from None  # exit 2, one line
        except (SimlidarError, OSError) as exc:  # OSError: permissions, full disk, ...
            if ctx.meta.get("debug"):
                raise
            click.echo(f"Error: {exc}", err=True)
            ctx.exit(1)

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """As click's, but a usage error is the one line "Error: ..." (exit 2), without
        click's usage and "Try --help" lines: the message already names the option."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, **extra)
        except _NO_ARGS as exc:  # `simlidar` alone: the help, as click shows it
            exc.show()
            sys.exit(exc.exit_code)
        except click.UsageError as exc:
            click.echo(f"Error: {exc.format_message()}", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except click.Abort:
            click.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


class NoiseLevels(click.ParamType):
    """A comma-separated list of noise levels in [0, 1], e.g. ``0.1,0.2,0.33,0.5``."""

    name = "LEVELS"

    def convert(self, value, param, ctx):
        if isinstance(value, list):
            return value
        levels = []
        for part in str(value).split(","):
            try:
                level = float(part)
            except ValueError:
                self.fail(f"{part!r} is not a number; expected levels like 0.1,0.2", param, ctx)
            if not 0.0 <= level <= 1.0:
                self.fail(
                    f"{level:g} is outside [0, 1]; expected noise levels in [0, 1]", param, ctx
                )
            levels.append(level)
        if len(set(levels)) != len(levels):
            self.fail(f"{value!r} repeats a level; expected distinct levels", param, ctx)
        return levels


class FiniteRange(click.FloatRange):
    """A FloatRange that also refuses nan (which compares False with both bounds)."""

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if number != number:
            high = "" if self.max is None else f"<={self.max:g}"
            self.fail(f"{value!r} is not a number in the range {self.min:g}<=x{high}.", param, ctx)
        return number


class OutFolder(click.Path):
    """An --out folder: not an empty string, which would silently mean the current folder."""

    def __init__(self):
        super().__init__(file_okay=False, path_type=Path)

    def convert(self, value, param, ctx):
        if value == "":
            self.fail("'' is empty; expected a folder name ('.': the current one)", param, ctx)
        return super().convert(value, param, ctx)


_scenes_option = click.option(
    "--scenes",
    type=click.Path(path_type=Path),
    default=None,
    help="Scene catalog folder (default: the one shipped with simlidar).",
)


def _load_catalog(scenes):
    from simlidar.scene.recipe import load_catalog

    return load_catalog(scenes)


@click.group(cls=_Group)
@click.version_option(__version__, prog_name="simlidar")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """simlidar: synthetic VLP-16 temporal-pulse datasets (Sim LiDAR) and benchmarks."""
    ctx.meta["debug"] = debug
    if not debug:  # warnings as one line each, without the source line
        warnings.showwarning = lambda message, *args, **kwargs: click.echo(
            f"Warning: {message}", err=True
        )


@main.command()
@click.option(
    "--classes",
    type=int,
    default=32,
    show_default=True,
    help="32: layout x object, 8: layout alone, 4: object alone.",
)
@click.option(
    "--noise",
    "noise",
    type=NoiseLevels(),
    default="0.2",
    show_default=True,
    help="Noise level(s) a of U(0, a); a comma-separated list writes one dataset "
    "per level, with the same scenes.",
)
@click.option("--train-size", type=int, default=3000, show_default=True)
@click.option("--test-size", type=int, default=600, show_default=True)
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@click.option(
    "--profile",
    default=None,
    help="Dataset profile: a name in profiles/ (paper, physical) or a .toml file; see "
    "`simlidar profiles`. [default: paper]",
)
@click.option(
    "--shift",
    type=click.FloatRange(0.0, 1.0, max_open=True),
    default=None,
    help="Delay-shift augmentation: every return of a sample moves by U(-s, s). Overrides the "
    "profile's value (named in the dataset's name).",
)
@click.option(
    "--variation",
    type=click.FloatRange(0.0, 1.0, min_open=True),
    default=None,
    help="Scene variation: every parameter range of the scene catalog shrunk around its "
    "centre by this factor (1: the recipes as written). Overrides the profile's value "
    "(named in the dataset's name).",
)
@click.option(
    "--out",
    type=OutFolder(),
    default=Path("data"),
    show_default=True,
    help="Folder that receives the dataset directories.",
)
@click.option(
    "--width",
    type=click.IntRange(1, 1024),
    default=16,
    show_default=True,
    help="Azimuth columns per sample.",
)
@_scenes_option
@click.option(
    "--batch-size",
    type=click.IntRange(1, 4096),
    default=1024,
    show_default=True,
    help="Samples ray-cast together (does not change the data).",
)
@click.option("--force", is_flag=True, help="Overwrite existing datasets.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def generate(
    classes,
    noise,
    train_size,
    test_size,
    seed,
    profile,
    shift,
    variation,
    out,
    width,
    scenes,
    batch_size,
    force,
    as_json,
):
    """Generate Sim LiDAR datasets: per noise level, train/test splits (HDF5), a preview
    picture, the dataset card, Croissant metadata and checksums.

    The profile (default: paper) decides the scene variation, the delay shift, what a missing
    return is written as and which pixels get the noise. --variation and --shift override its
    values; the dataset's name then says so (docs/profiles.md)."""
    from simlidar.dataset.config import GeneratorConfig
    from simlidar.dataset.generate import generate as run
    from simlidar.profiles import DEFAULT_PROFILE, load_profile
    from simlidar.simulate import class_plan

    try:
        chosen = load_profile(profile if profile is not None else DEFAULT_PROFILE)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--profile'") from None
    for option, value, own in (
        ("--variation", variation, chosen.variation),
        ("--shift", shift, chosen.shift),
    ):
        if value is not None and value != own:
            click.echo(
                f"Note: {option} {value!r} overrides profile {chosen.name}'s {own!r}", err=True
            )
    catalog = _load_catalog(scenes)
    try:
        class_plan(catalog, classes)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--classes'") from None
    config = GeneratorConfig.from_profile(
        chosen,
        variation=variation,
        shift_max=shift,
        classes=classes,
        noise=noise[0],
        train_size=train_size,
        test_size=test_size,
        seed=seed,
        width=width,
    )
    start = time.perf_counter()
    written = run(config, noise, catalog, out, batch_size=batch_size, force=force)
    seconds = time.perf_counter() - start
    if as_json:
        record = {
            "datasets": [
                {"path": str(w.path), "noise": w.noise, "classes": w.classes, "splits": w.splits}
                for w in written
            ],
            "seconds": round(seconds, 3),
        }
        click.echo(json.dumps(record))
    else:
        for w in written:
            click.echo(
                f"wrote {w.path} (train {w.splits['train']}, test {w.splits['test']}, "
                f"noise {w.noise:g}) and its preview.png"
            )
        click.echo(f"done in {seconds:.1f} s")


@main.command()
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def profiles(as_json):
    """List the shipped dataset profiles and their values (docs/profiles.md)."""
    from simlidar.profiles import DEFAULT_PROFILE, load_profile, profile_names

    shipped = [load_profile(name).to_dict() for name in profile_names()]
    if as_json:
        click.echo(json.dumps({"default": DEFAULT_PROFILE, "profiles": shipped}))
        return
    for p in shipped:
        default = " (default)" if p["name"] == DEFAULT_PROFILE else ""
        click.echo(f"{p['name']}{default}: {p['description']}")
        click.echo(
            f"  variation {p['variation']!r}, shift {p['shift']!r}, missing return "
            f"{p['missing_delay']!r}, noise on {p['noise_on']}, input spikes: "
            f"{p['spikes']}"
        )


@main.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def info(path, as_json):
    """Show a dataset's versions, classes, counts per split and class, noise and config."""
    from simlidar.dataset.info import dataset_info, format_info

    summary = dataset_info(path)
    if as_json:
        click.echo(json.dumps(summary))
        return
    click.echo(format_info(summary))


@main.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="PNG file to write.",
)
@click.option("--split", type=click.Choice(["train", "test"]), default="test", show_default=True)
def preview(path, out, split):
    """Draw one example per class (delays as grey levels) into a PNG file."""
    from simlidar.dataset.preview import write_preview
    from simlidar.errors import DatasetError

    if out.suffix.lower() != ".png":
        raise click.BadParameter(
            f"{out}: expected a file name ending in .png", param_hint="'--out'"
        )
    if not out.parent.is_dir():
        raise DatasetError(f"--out {out}: folder {out.parent} does not exist")
    click.echo(f"wrote {write_preview(path, out, split)}")


@main.command()
@click.argument("path", type=click.Path(path_type=Path))
def card(path):
    """Rewrite a dataset's card (README.md) from its files, and its line in SHA256SUMS."""
    from simlidar.dataset.card import CARD, write_card
    from simlidar.dataset.checksums import SUMS, write_sums
    from simlidar.dataset.h5 import dataset_splits

    dataset_splits(path)  # a dataset, or a one-line error
    written = write_card(path)
    if (path / SUMS).exists():
        write_sums(path, [CARD])
    click.echo(f"wrote {written}")


@main.command()
@click.argument("path", type=click.Path(path_type=Path))
def verify(path):
    """Check a dataset: checksums, HDF5 schema, value ranges, split sizes against the card."""
    from simlidar.dataset.h5 import dataset_splits
    from simlidar.dataset.verify import verify as run

    problems = run(path)
    if problems:
        for problem in problems:
            click.echo(f"FAILED {problem}", err=True)
        click.echo(f"{path}: {len(problems)} problem(s)", err=True)
        sys.exit(1)
    splits = dataset_splits(path)
    sizes = ", ".join(f"{s} {info.size}" for s, info in splits.items())
    version = splits["train"].attrs["dataset_version"]
    click.echo(
        f"{path}: OK (dataset version {version}, {sizes}; checksums, schema, value "
        "ranges and card agree)"
    )


@main.command()
@click.argument("path", type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=OutFolder(),
    default=None,
    help="Folder for the archive (default: beside the dataset).",
)
def pack(path, out):
    """Verify a dataset and write <name>.tar.gz and its .sha256, ready to upload."""
    from simlidar.dataset.archive import pack as run

    archive, checksum = run(path, out)
    click.echo(f"wrote {archive} and {checksum.name}")


def _hex_sha256(ctx, param, value):
    """--sha256 must be 64 hexadecimal digits (usage error otherwise)."""
    from simlidar.dataset.checksums import is_sha256

    if value is not None and not is_sha256(value):
        raise click.BadParameter(f"{value!r}: expected 64 hexadecimal digits")
    return value


@main.command()
@click.argument("url")
@click.option(
    "--sha256",
    default=None,
    metavar="HEX",
    callback=_hex_sha256,
    help="Expected sha256 of the archive (default: read from URL.sha256).",
)
@click.option("--out", type=OutFolder(), default=Path("data"), show_default=True)
@click.option(
    "--timeout",
    type=FiniteRange(0.1, 86_400),  # archive.MAX_TIMEOUT_S (not imported: cli stays light)
    default=30.0,
    show_default=True,
    help="Seconds to wait for the server (at most a day).",
)
@click.option("--force", is_flag=True, help="Replace an existing dataset of the same name.")
def fetch(url, sha256, out, timeout, force):
    """Download a dataset archive, check it, extract it safely, verify it, install it."""
    from simlidar.dataset.archive import fetch as run

    click.echo(f"installed {run(url, sha256, out, timeout=timeout, force=force)}")


MAX_EPOCHS = 10**6


def _need_torch(command: str) -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise SimlidarError(
            f"simlidar {command} needs PyTorch: pip install 'simlidar[torch]' (or torch itself)"
        ) from None


_selection_options = [
    click.option(
        "--validation",
        type=click.FloatRange(0, 1, max_open=True),
        default=None,
        help="Override the fraction of each class held out for model selection (0: none).",
    ),
    click.option(
        "--patience",
        type=click.IntRange(1, MAX_EPOCHS),
        default=None,
        help="Override the epochs without a better validation score before training stops.",
    ),
]


def _selection(command):
    for option in reversed(_selection_options):
        command = option(command)
    return command


@main.command()
@click.option(
    "--model",
    "model",
    required=True,
    help="Model recipe: a name in baselines/ (snn_simlidar, ...) or a .toml file.",
)
@click.option(
    "--dataset",
    type=click.Path(path_type=Path),
    required=True,
    help="Dataset directory in the simlidar schema.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("runs"),
    show_default=True,
    help="Folder for the checkpoint.",
)
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
@click.option(
    "--epochs",
    type=click.IntRange(1, MAX_EPOCHS),
    default=None,
    help="Override the recipe's epochs.",
)
@click.option(
    "--max-seconds",
    type=FiniteRange(min=0),
    default=None,
    help="Override the recipe's time budget (inf: none).",
)
@_selection
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def train(model, dataset, out, seed, epochs, max_seconds, validation, patience, as_json):
    """Train a model on a dataset's train split, keep the epoch with the best accuracy on a
    held-out validation part of it, score that once on the test split, save a checkpoint."""
    _need_torch("train")
    from simlidar.bench.train import check_writable, save_checkpoint
    from simlidar.bench.train import train as run
    from simlidar.dataset.verify import check_trainable
    from simlidar.models.registry import load_recipe

    recipe = load_recipe(model)
    given = {"validation": validation, "patience": patience}
    recipe["training"].update({k: v for k, v in given.items() if v is not None})
    check_trainable(dataset)  # a sound dataset, or a one-line error
    check_writable(out)  # before training, not after
    result = run(recipe, dataset, seed=seed, epochs=epochs, max_seconds=max_seconds)
    path = save_checkpoint(result, out / f"{recipe['name']}-seed{seed}.pt")
    record = {
        "model": recipe["name"],
        "dataset": str(dataset),
        "seed": seed,
        "test_accuracy": round(result.test_accuracy, 4),
        "epochs": result.epochs,
        **result.selection(),
        "seconds": round(result.seconds, 1),
        "checkpoint": str(path),
    }
    if recipe["model"] == "snn":  # dense spiking network: how early it decides
        from simlidar.bench.early import early_decisions

        record["early"] = early_decisions(result.model, dataset)
    if as_json:
        click.echo(json.dumps(record))
        return
    chosen = (
        f"epoch {result.best_epoch + 1} of {result.epochs} kept (best validation "
        f"accuracy of {result.validation_size} held-out samples)"
        if result.validation_size
        else f"{result.epochs} epochs, no validation"
    )
    why = {
        "plateau": "stopped on a validation plateau",
        "epochs": "ran every epoch",
        "time": "stopped by the time cap",
    }[result.stopped]
    click.echo(
        f"{recipe['name']}: test accuracy {result.test_accuracy:.4f}, {chosen}, {why}, "
        f"{result.seconds:.0f} s; wrote {path}"
    )
    if "early" in record:
        from simlidar.bench.early import format_early

        click.echo(format_early(record["early"]))


@main.command()
@click.option(
    "--suite",
    default="quick",
    show_default=True,
    help="Suite: a name in benchmark/ (quick, paper) or a .toml file.",
)
@click.option(
    "--models",
    default=None,
    help="Comma-separated model recipes to run instead of the suite's (e.g. snn_simlidar,cnn).",
)
@click.option(
    "--dataset",
    type=click.Path(path_type=Path),
    default=None,
    help="Run the suite's models on this dataset directory instead of the suite's datasets.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Output directory (default: bench/<suite name>).",
)
@click.option(
    "--epochs",
    type=click.IntRange(1, MAX_EPOCHS),
    default=None,
    help="Override every model's epochs (the suite's and the recipes').",
)
@click.option(
    "--max-seconds",
    type=FiniteRange(min=0),
    default=None,
    help="Override every cell's time cap (inf: none).",
)
@_selection
@click.option(
    "--remeasure",
    is_flag=True,
    help="Measure the finished cells of --out again from their checkpoints (no training).",
)
@click.option("--json", "as_json", is_flag=True, help="Print results.json's content on stdout.")
def bench(
    suite, models, dataset, out, epochs, max_seconds, validation, patience, remeasure, as_json
):
    """Train and score the suite's models on its datasets: accuracy, how early spiking networks
    decide, energy, latency, size. Writes results.json, report.md and pictures; a rerun into
    the same directory skips the cells already finished."""
    _need_torch("bench")
    from simlidar.bench.run import run_suite
    from simlidar.bench.suite import load_suite

    try:
        chosen = load_suite(suite)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--suite'") from None
    names = None
    if models is not None:
        from simlidar.models.registry import load_recipe

        names = [m.strip() for m in models.split(",") if m.strip()]
        try:
            for name in names or [models]:
                load_recipe(name)
        except ConfigError as exc:
            raise click.BadParameter(str(exc), param_hint="'--models'") from None
    chosen = chosen.with_budget(
        epochs=epochs, max_seconds=max_seconds, validation=validation, patience=patience
    )
    out = out if out is not None else Path("bench") / chosen.name
    if remeasure:
        given = {
            "--models": models,
            "--dataset": dataset,
            "--epochs": epochs,
            "--max-seconds": max_seconds,
            "--validation": validation,
            "--patience": patience,
        }
        extra = [name for name, value in given.items() if value is not None]
        if extra:
            raise click.UsageError(
                f"--remeasure re-measures the finished cells of --out as they "
                f"were trained; expected no {extra[0]}"
            )
        from simlidar.bench.run import remeasure as run_remeasure

        results = run_remeasure(out, chosen, progress=not as_json)
    else:
        results = run_suite(chosen, out, models=names, dataset=dataset, progress=not as_json)
    if as_json:
        click.echo(json.dumps(results))
        return
    click.echo(f"{len(results['cells'])} cells in {out}: results.json, report.md")
    width = max((len(cell["model"]) for cell in results["cells"]), default=0)
    for cell in results["cells"]:
        click.echo(
            f"  {cell['dataset']}  {cell['model']:<{width}}  seed {cell['seed']}  accuracy "
            f"{cell['accuracy']:.4f}  latency {cell['latency_ms']:.2f} ms"
        )


@main.group()
def convert():
    """Convert real data into the simlidar schema (KITTI front view, DVS barrel events)."""


def _converted(path: Path, as_json: bool) -> None:
    from simlidar.dataset.h5 import dataset_splits

    splits = dataset_splits(path)
    sizes = {name: info.size for name, info in splits.items()}
    if as_json:
        click.echo(json.dumps({"path": str(path), "splits": sizes}))
    else:
        click.echo(f"wrote {path} (train {sizes['train']}, test {sizes['test']})")


_convert_options = [
    click.option(
        "--out",
        type=click.Path(file_okay=False, path_type=Path),
        default=Path("data"),
        show_default=True,
        help="Folder for the dataset directory.",
    ),
    click.option(
        "--seed",
        type=click.IntRange(0, 2**63 - 1),
        default=0,
        show_default=True,
        help="Seed of the train/test split.",
    ),
    click.option("--force", is_flag=True, help="Replace an existing dataset of the same name."),
    click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout."),
]


def _with_convert_options(command):
    for option in reversed(_convert_options):
        command = option(command)
    return command


@convert.command("kitti")
@click.argument("root", type=click.Path(path_type=Path))
@click.option(
    "--crop",
    type=(click.IntRange(1), click.IntRange(1)),
    default=(50, 118),
    show_default=True,
    help="Crop size: rows columns (front-view cells).",
)
@click.option(
    "--res-h",
    type=FiniteRange(0.01, 10),  # kitti.RES_DEG (not imported: cli stays light)
    default=0.18,
    show_default=True,
    help="Horizontal front-view resolution, degrees.",
)
@click.option(
    "--res-v",
    type=FiniteRange(0.01, 10),  # kitti.RES_DEG (not imported: cli stays light)
    default=0.4,
    show_default=True,
    help="Vertical front-view resolution, degrees.",
)
@click.option(
    "--max-range",
    type=FiniteRange(1, 1000),  # kitti.MAX_RANGE_M
    default=100.0,
    show_default=True,
    help="Range (m) whose time of flight is delay 1.",
)
@click.option(
    "--test-fraction",
    type=click.FloatRange(0, 1, min_open=True, max_open=True),
    default=0.2,
    show_default=True,
    help="Fraction of frames in the test split.",
)
@_with_convert_options
def convert_kitti(root, crop, res_h, res_v, max_range, test_fraction, out, seed, force, as_json):
    """KITTI 3D object benchmark (ROOT: training/ with velodyne/, label_2/, calib/, or its
    parent) -> front-view pulse crops around every labelled object, 8 classes, split by frame.
    See docs/converters.md."""
    from simlidar.convert import convert_kitti as run

    path = run(
        root,
        out,
        crop=crop,
        res_h_deg=res_h,
        res_v_deg=res_v,
        max_range_m=max_range,
        test_fraction=test_fraction,
        seed=seed,
        force=force,
        progress=not as_json,
    )
    _converted(path, as_json)


@convert.command("dvs-barrel")
@click.argument("mat_file", type=click.Path(path_type=Path))
@click.option(
    "--labels",
    default=None,
    help="One class character (0-9, A-Z) per recording, e.g. 0123...; default: the "
    "ROI struct's 'label' field.",
)
@click.option(
    "--window-us",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    help="Time window (us) whose end is delay 1 (default: longest recording + 1).",
)
@click.option(
    "--address-base",
    type=click.Choice(["0", "1"]),
    default="1",
    show_default=True,
    help="Whether x and y addresses count from 0 or from 1 (MATLAB).",
)
@click.option(
    "--test-fraction",
    type=click.FloatRange(0, 1, min_open=True, max_open=True),
    default=0.5,
    show_default=True,
    help="Fraction of each class's recordings in test.",
)
@_with_convert_options
def convert_dvs(
    mat_file, labels, window_us, address_base, test_fraction, out, seed, force, as_json
):
    """DVS barrel MATLAB file (struct array ROI: x, y, polarity, timestamps in us; 32 x 32
    pixels, 36 characters) -> first-spike times per pixel, raw events kept alongside. See
    docs/converters.md."""
    from simlidar.convert import convert_dvs_barrel as run

    path = run(
        mat_file,
        out,
        labels=tuple(labels) if labels else None,
        window_us=window_us,
        address_base=int(address_base),
        test_fraction=test_fraction,
        seed=seed,
        force=force,
        progress=not as_json,
    )
    _converted(path, as_json)


@main.command()
@_scenes_option
@click.option(
    "--export",
    "export_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Write one sampled scene per layout x object into this folder.",
)
@click.option(
    "--format", "fmt", type=click.Choice(["glb", "ply"]), default="glb", show_default=True
)
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True)
def scenes(scenes, export_dir, fmt, seed):
    """List the scene catalog, or export sampled scenes as mesh files."""
    catalog = _load_catalog(scenes)
    click.echo(f"scene catalog {catalog.root} (sha256 {catalog.fingerprint()[:12]})")
    click.echo(f"layouts ({len(catalog.layouts)}):")
    for k, r in enumerate(catalog.layouts):
        click.echo(f"  {k}  {r.name:<18} {len(r.params):2d} params  {r.description}")
    click.echo(f"objects ({len(catalog.objects)}):")
    for k, r in enumerate(catalog.objects):
        click.echo(f"  {k}  {r.name:<18} {len(r.params):2d} params  {r.description}")
    click.echo(f"surfaces: {', '.join(catalog.surfaces)}")
    if export_dir is not None:
        from simlidar.scene.export import export_scenes

        paths = export_scenes(catalog, export_dir, seed=seed, fmt=fmt)
        click.echo(f"wrote {len(paths)} scenes to {export_dir}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
