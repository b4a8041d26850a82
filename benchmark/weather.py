"""Weather as a benchmark axis: networks trained in clear air or on mixed weather, tested in
fog and rain (issue 41, item 6).

    python benchmark/weather.py --data /tmp/weather                   # the published run
    python benchmark/weather.py --data /tmp/weather --seeds 0 --visibilities 50 --rains 50 \\
        --models cnn                                                   # a quick look

Generates the ``sensor`` profile's datasets (noise ``--noise``, 3000 / 600 samples, seed 0) in
clear air, at every visibility of ``--visibilities`` (``simlidar generate --profile sensor --fog
V``) and at every rain rate of ``--rains`` (``--rain R``): the same seed, so the same scenes,
materials, phases and noise draws, only the weather differs. The *mixed* train split holds
sample i of weather i mod K (clear air, then the fogs, then the rains: K weathers in turn, the
same 3000 scenes), with the clear test split. Each model of ``--models`` trains by the paper's
protocol (all of it, the recipe's epochs, the last kept; the recipe's time cap lifted so that
load cannot change a figure) for every seed of ``--seeds``, once on the clear train split and
once on the mixed one, and is scored on the test split of every weather. Beside each test split
the early-information estimate with every spike (``benchmark/early_bound.py --ks 256``: the
learner families of ``--learners``, by default the flash and scan estimates' two MLPs and the
paper's CNN, trained with fresh noise on that weather's own train split, near first; a run that
lacks a family is given it, so ``--learners mlp,wide`` first and the default later spreads the
CNN's hours over runs): what the learners tried reach when trained in that weather, so the
distance between a network trained in clear air and its weather's estimate is the price of
having trained in clear air plus the network's own gap there. It is an estimate, not a bound:
a stronger learner can beat it. The committed scores above it are listed, each with its lead in
test samples over the estimate's best seed ensemble and what that lead can mean on 600 test
samples (``early_bound.above_the_bound``).

Each (model, training, seed) is a JSON file under ``--out``/cells (a rerun skips it, or trains
it again where it lacks a weather, and then stops if a score it had changed); the estimate's
runs are under ``--out``/bound (the older name). Writes weather.md, weather.json and
weather.png (accuracy against visibility and rain rate, mean and 95 % interval over seeds,
beside the estimate); ``--no-train`` writes them again from the cells and runs there are,
making no dataset (``--data`` is not read), and ``--doc FILE`` also puts the fog and rain
tables into FILE, between its lines ``<!-- weather-tables:start -->`` and ``<!--
weather-tables:end -->``, and the scores above the estimate, between ``<!--
weather-above-the-estimate:start -->`` and ``<!-- weather-above-the-estimate:end -->``
(docs/weather.md).
"""

import argparse
import json
import math
import os
import shutil
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import reproduction_table
from paper_table import JOBS, SEEDS, check_recipes
from weather_estimate import above_the_estimate, bounds, estimate, estimate_runs
from weather_report import (
    DOC_END,
    DOC_START,
    TABLES_END,
    TABLES_START,
    summarise,
    write,
    write_doc,
)

from simlidar.errors import ResultsError
from simlidar.script_args import command_line, integers, run

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("snn_simlidar_tuned", "cnn")
VISIBILITIES = (200.0, 100.0, 50.0, 30.0)
RATES = (10.0, 50.0, 100.0, 200.0)
TRAININGS = ("clear", "mixed")


def visibilities(text: str) -> list[float]:
    """``--visibilities``: comma-separated metres, each > 0 and finite."""
    values = []
    for item in text.split(","):
        try:
            value = float(item)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"{item!r}: expected a visibility in metres > 0")
        values.append(value)
    return values


def rain_rates(text: str) -> list[float]:
    """``--rains``: comma-separated mm/h, each in (0, 500]; empty: none."""
    from simlidar.sensor.weather import MAX_RAIN_MM_H

    values = []
    for item in filter(None, text.split(",")):
        try:
            value = float(item)
        except ValueError:
            value = math.nan
        if not 0 < value <= MAX_RAIN_MM_H:
            raise argparse.ArgumentTypeError(
                f"{item!r}: expected a rain rate in mm/h in (0, {MAX_RAIN_MM_H:g}]"
            )
        values.append(value)
    return values


def configs(noise: float, fogs: list[float], rains: list[float], sizes: dict) -> dict:
    """The generator's configuration of the clear-air dataset, of one per visibility and of one
    per rain rate ("clear", "50", ..., "rain10", ...)."""
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.profiles import load_profile

    weathers = [("clear", {})]
    weathers += [(f"{fog:g}", {"fog_visibility_m": fog}) for fog in fogs]
    weathers += [(f"rain{rate:g}", {"rain_rate_mm_h": rate}) for rate in rains]
    profile = load_profile("sensor")
    return {
        key: GeneratorConfig.from_profile(profile, noise=noise, seed=0, **weather, **sizes)
        for key, weather in weathers
    }


def datasets(
    root: Path, noise: float, fogs: list[float], rains: list[float], sizes: dict
) -> dict[str, Path]:
    """The datasets of :func:`configs` under ``root``, made where missing."""
    from simlidar.generator.generate import generate, generated_name
    from simlidar.scene.recipe import load_catalog

    found = {}
    for key, config in configs(noise, fogs, rains, sizes).items():
        path = root / generated_name(config)
        if not path.is_dir():
            generate(config, [noise], load_catalog(), root, progress=False)
        found[key] = path
    return found


def mixed_name(names: dict[str, str]) -> str:
    """The mixed dataset's name, of the weathers' dataset names (:func:`mixed_dataset`)."""
    return f"{names['clear']}-mixed-{'-'.join(list(names)[1:])}"


def _alive(pid: str) -> bool:
    """Whether the process ``pid`` (a partial folder's suffix) still runs."""
    try:
        os.kill(int(pid), 0)
    except (ValueError, ProcessLookupError):
        return False
    except PermissionError:  # another user's
        return True
    return True


def mixed_dataset(sets: dict[str, Path], root: Path) -> Path:
    """The mixed train split beside the clear test split: a copy of the clear dataset whose
    train rows i are weather i mod K's (every per-pixel dataset the two share), made where
    missing, atomically; its card and checksums are dropped (they would describe clear air)
    and ``mixed.json`` says what it holds."""
    import h5py

    names = list(sets)
    path = root / mixed_name({w: p.name for w, p in sets.items()})
    if path.is_dir():
        return path
    for stale in root.glob(f".{path.name}.partial-*"):  # of a run that died building it
        if not _alive(stale.name.rsplit("-", 1)[1]):
            shutil.rmtree(stale, ignore_errors=True)
    building = root / f".{path.name}.partial-{os.getpid()}"
    building.mkdir(parents=True)
    for split in ("train.h5", "test.h5"):
        shutil.copyfile(sets["clear"] / split, building / split)
    with h5py.File(building / "train.h5", "r+") as mine:
        n = len(mine["labels"])
        for k, name in enumerate(names[1:], start=1):
            rows = np.arange(k, n, len(names))
            with h5py.File(sets[name] / "train.h5", "r") as theirs:
                if not np.array_equal(theirs["labels"][:], mine["labels"][:]):
                    shutil.rmtree(building)
                    raise SystemExit(
                        f"{sets[name]}: its train labels differ from {sets['clear']}'s; "
                        "expected the same seed and sizes (the same scenes)"
                    )
                for field, data in mine.items():
                    if field in theirs and theirs[field].shape == data.shape and len(data) == n:
                        values = data[:]
                        values[rows] = theirs[field][:][rows]
                        data[:] = values
    (building / "mixed.json").write_text(
        json.dumps(
            {
                "rule": "train row i from weather i mod K; test: clear air's",
                "weathers": {w: p.name for w, p in sets.items()},
            },
            indent=1,
        )  # fmt: skip
        + "\n"
    )
    try:
        os.replace(building, path)
    except OSError:  # another run made it meanwhile: theirs is the same
        if not path.is_dir():
            raise
        shutil.rmtree(building)
    return path


def cell(
    recipe_name: str,
    seed: int,
    trained_on: str,
    sets: dict[str, str],
    path: str,
    had: dict | None = None,
) -> str:
    """Train ``recipe_name`` on the train split of the dataset ``trained_on`` (the clear one,
    or the mixed one, whose test split is the clear one), score it on every test split of
    ``sets``; write the JSON atomically. ``had``: the scores an earlier run of the same cell
    gave (trained on the same data): a RuntimeError, and nothing written, if one changed."""
    import torch

    torch.set_num_threads(1)
    from simlidar.bench.scoring import predictions
    from simlidar.bench.train import train
    from simlidar.dataset.loaders import load_split
    from simlidar.models.registry import load_recipe

    recipe = load_recipe(recipe_name)
    recipe["training"]["validation"] = 0  # the paper's protocol: all 3000, the last epoch
    result = train(recipe, trained_on, seed=seed, max_seconds=float("inf"), progress=False)
    accuracy = {}
    for weather, dataset in sets.items():
        x, y = load_split(dataset, "test")
        predicted = predictions(
            result.model, torch.from_numpy(x)[:, None], spec=result.spec,
            silent_from=result.silent_from,
        ).numpy()  # fmt: skip
        if weather == "clear":  # the training run's own test predictions, read again
            assert np.array_equal(predicted, result.test_predictions)
        accuracy[weather] = float((predicted == y).mean())
    changed = {w: (v, accuracy[w]) for w, v in (had or {}).items() if accuracy.get(w, v) != v}
    if changed:  # training is deterministic: the same data must give the same scores
        raise RuntimeError(f"{path}: trained again, its scores changed: {changed}")
    record = {
        "recipe": recipe_name,
        "seed": seed,
        "trained_on": Path(trained_on).name,
        "test_accuracy": accuracy,
        "epochs": result.epochs,
        "seconds": result.seconds,
    }
    temporary = Path(f"{path}.partial-{os.getpid()}")
    temporary.write_text(json.dumps(record, indent=1) + "\n")
    os.replace(temporary, path)
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True, help="where the datasets are made")
    parser.add_argument("--visibilities", type=visibilities, default="200,100,50,30")
    parser.add_argument("--rains", type=rain_rates, default="10,50,100,200", help="mm/h")
    parser.add_argument("--noise", type=float, default=0.1, choices=(0.1, 0.2))
    parser.add_argument("--models", default=",".join(MODELS))
    parser.add_argument("--seeds", type=SEEDS, default="0,1,2")
    parser.add_argument("--jobs", type=JOBS, default=2)
    parser.add_argument("--train-size", type=integers(32, 10**6, one=True), default=3000)
    parser.add_argument("--test-size", type=integers(32, 10**6, one=True), default=600)
    parser.add_argument(
        "--no-bound",
        action="store_true",
        help="skip the early-information estimate (a quick look; the flag keeps the older name)",
    )
    parser.add_argument(
        "--learners",
        default="mlp,wide,cnn",
        help="the estimate's learner families (early_bound.py --learners); a run that lacks "
        "some is given them",
    )
    parser.add_argument(
        "--no-train",
        action="store_true",
        help="write the reports again from the cells and the estimate's runs under --out, "
        "making no dataset and training nothing (--data is not read)",
    )
    parser.add_argument(
        "--doc",
        type=reproduction_table.markdown_file,
        metavar="FILE",
        help=f"also put the fog and rain tables into FILE, between its lines {TABLES_START} and "
        f"{TABLES_END}, and the scores above the estimate, between {DOC_START} and {DOC_END} "
        "(docs/weather.md)",
    )
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/weather")
    args = parser.parse_args(argv)
    models = [m for m in args.models.split(",") if m]
    check_recipes(models)
    if args.doc is not None:  # its markers, before anything is written
        if args.no_bound:
            parser.error("--doc with --no-bound: expected the estimate, which --doc quotes")
        for start, end in ((DOC_START, DOC_END), (TABLES_START, TABLES_END)):
            reproduction_table.split(args.doc.read_text(), args.doc, start, end)
    sizes = {"train_size": args.train_size, "test_size": args.test_size}
    if args.no_train:
        from simlidar.generator.generate import generated_name

        weathers = configs(args.noise, args.visibilities, args.rains, sizes)
        names = {w: generated_name(c) for w, c in weathers.items()}
    else:
        sets = datasets(args.data, args.noise, args.visibilities, args.rains, sizes)
        names = {w: p.name for w, p in sets.items()}
        train_on = {"clear": sets["clear"], "mixed": mixed_dataset(sets, args.data)}
    trained_on = {"clear": names["clear"], "mixed": mixed_name(names)}
    cells = args.out / "cells"

    def cell_path(model: str, training: str, seed: int) -> Path:  # a recipe file's stem
        middle = "" if training == "clear" else f"{training}__"
        return cells / f"{Path(model).stem}__{middle}seed{seed}.json"

    if not args.no_train:
        cells.mkdir(parents=True, exist_ok=True)
        todo = []
        for s in args.seeds:
            for training in TRAININGS:
                for m in models:
                    path, data = cell_path(m, training, s), train_on[training]
                    had = None
                    if path.is_file():  # kept if trained on this data and scored on every set
                        old = json.loads(path.read_text())
                        if old["trained_on"] == data.name:
                            if set(sets) <= set(old["test_accuracy"]):
                                continue
                            had = old["test_accuracy"]  # trained again: these must hold
                    sets_ = {w: str(p) for w, p in sets.items()}
                    todo.append((m, s, str(data), sets_, str(path), had))
        train_cells(todo, args.jobs)
    found = {}
    for training in TRAININGS:
        for m in models:
            paths = [cell_path(m, training, s) for s in args.seeds]
            mine = [read_cell(p, trained_on[training], names) for p in paths if p.is_file()]
            if mine:
                found[label(m, training)] = mine
    if not found:
        raise ResultsError(f"{cells}: expected cells of {models} to summarise")
    runs = {}
    if not args.no_bound:
        if args.no_train:
            import early_bound

            runs = estimate_runs(names, args.out / "bound")
            early_bound.report(args.out / "bound")
        else:
            runs = bounds(sets, args.out / "bound", args.learners)
    summary = summarise(found, list(names), estimate(runs))
    summary["above_the_estimate"] = above_the_estimate(found, names, runs)
    command = command_line("weather.py", argv)
    write(args.out, summary, command, names)
    if args.doc is not None:
        write_doc(args.doc, summary)
    return 0


def train_cells(todo: list[tuple], jobs: int) -> None:
    """Train the cells ``todo`` (:func:`cell`'s arguments), ``jobs`` at a time; a cell whose
    scores changed stops the run in one line."""
    if not todo:
        return
    from tqdm import tqdm

    try:
        if jobs == 1:  # here, in this process
            for job in tqdm(todo, desc="cells"):
                cell(*job)
        else:
            with ProcessPoolExecutor(jobs) as pool:
                futures = [pool.submit(cell, *job) for job in todo]
                for future in tqdm(as_completed(futures), total=len(futures), desc="cells"):
                    future.result()
    except RuntimeError as exc:
        raise SystemExit(str(exc)) from None


def read_cell(path: Path, trained_on: str, names: dict[str, str]) -> dict:
    """A committed cell, which must have been trained on ``trained_on`` and scored on every
    weather of ``names``; a ResultsError says which it is not."""
    cell = json.loads(path.read_text())
    if cell["trained_on"] != trained_on:
        raise ResultsError(
            f"{path}: trained on {cell['trained_on']}, expected {trained_on}: run without "
            "--no-train to train it again"
        )
    missing = [w for w in names if w not in cell["test_accuracy"]]
    if missing:
        raise ResultsError(f"{path}: no score in {missing}: run without --no-train to add them")
    return cell


def label(model: str, training: str) -> str:
    """A row's name: the recipe's stem, and "(mixed)" when trained on mixed weather."""
    return Path(model).stem + ("" if training == "clear" else f" ({training})")


if __name__ == "__main__":
    run(main)
