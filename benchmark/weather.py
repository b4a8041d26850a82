"""Weather as a benchmark axis: networks trained in clear air, tested in fog (issue 41, item 6).

    python benchmark/weather.py --data /tmp/weather                   # the published run
    python benchmark/weather.py --data /tmp/weather --seeds 0 --visibilities 50 \\
        --models cnn                                                   # a quick look

Generates the ``sensor`` profile's datasets (noise ``--noise``, 3000 / 600 samples, seed 0) in
clear air and at every visibility of ``--visibilities`` (``simlidar generate --profile sensor
--fog V``): the same seed, so the same scenes, materials, phases and noise draws, only the fog
differs. Each model of ``--models`` trains on the clear train split by the paper's protocol (all
of it, the recipe's epochs, the last kept; the recipe's time cap lifted so that load cannot
change a figure) for every seed of ``--seeds``, and is scored on the test split of every
weather. Beside each test split the early-information bound with every spike
(``benchmark/early_bound.py --ks 256``: its two learner families trained with fresh noise on that
weather's own train split, near first): what a learner that trained in that weather reaches, so
the distance between a network and its weather's bound is the price of having trained in clear
air plus the network's own gap there.

Each (model, seed) is a JSON file under ``--out``/cells (a rerun skips it); the bound's runs
are under ``--out``/bound. Writes weather.md, weather.json and weather.png (accuracy against
visibility, mean and 95 % interval over seeds, beside the bound).
"""

import argparse
import json
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from early_objectives import interval
from paper_table import JOBS, SEEDS, check_recipes

from simlidar.script_args import command_line, integers, run

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("snn_simlidar_tuned", "cnn")
VISIBILITIES = (200.0, 100.0, 50.0, 30.0)


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


def datasets(root: Path, noise: float, fogs: list[float], sizes: dict) -> dict[str, Path]:
    """The clear-air dataset and one per visibility ("clear", "50", ...), made where missing."""
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.generate import generate, generated_name
    from simlidar.generator.profiles import load_profile
    from simlidar.scene.recipe import load_catalog

    found = {}
    for fog in [math.inf, *fogs]:
        config = GeneratorConfig.from_profile(
            load_profile("sensor"), noise=noise, fog_visibility_m=fog, seed=0, **sizes
        )
        path = root / generated_name(config)
        if not path.is_dir():
            generate(config, [noise], load_catalog(), root, progress=False)
        found["clear" if math.isinf(fog) else f"{fog:g}"] = path
    return found


def cell(recipe_name: str, seed: int, sets: dict[str, str], path: str) -> str:
    """Train ``recipe_name`` on the clear train split, score it on every test split of
    ``sets``; write the JSON atomically."""
    import torch

    torch.set_num_threads(1)
    from simlidar.bench.train import predictions, train
    from simlidar.dataset.loaders import load_split
    from simlidar.models.registry import load_recipe

    recipe = load_recipe(recipe_name)
    recipe["training"]["validation"] = 0  # the paper's protocol: all 3000, the last epoch
    result = train(recipe, sets["clear"], seed=seed, max_seconds=float("inf"), progress=False)
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
    record = {
        "recipe": recipe_name,
        "seed": seed,
        "trained_on": Path(sets["clear"]).name,
        "test_accuracy": accuracy,
        "epochs": result.epochs,
        "seconds": result.seconds,
    }
    temporary = Path(f"{path}.partial-{os.getpid()}")
    temporary.write_text(json.dumps(record, indent=1) + "\n")
    os.replace(temporary, path)
    return path


def bounds(sets: dict[str, Path], out: Path) -> dict[str, dict]:
    """The bound with every spike per weather (early_bound.py's runs, made where missing)."""
    import early_bound

    early_bound.main(
        [
            *map(str, sets.values()),
            "--encodings",
            "near_first/as_value",
            "--ks",
            "256",
            "--out",
            str(out),
        ]  # fmt: skip
    )
    rows = {}
    for weather, dataset in sets.items():
        run_path = out / "runs" / f"{dataset.name}__near_first-as_value.json"
        result = json.loads(run_path.read_text())
        every = [r for r in result["rows"] if r["k"] is None][0]
        rows[weather] = {"accuracy": 100 * every["accuracy_mean"], "best": every.get("best")}
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True, help="where the datasets are made")
    parser.add_argument("--visibilities", type=visibilities, default="200,100,50,30")
    parser.add_argument("--noise", type=float, default=0.1, choices=(0.1, 0.2))
    parser.add_argument("--models", default=",".join(MODELS))
    parser.add_argument("--seeds", type=SEEDS, default="0,1,2")
    parser.add_argument("--jobs", type=JOBS, default=2)
    parser.add_argument("--train-size", type=integers(32, 10**6, one=True), default=3000)
    parser.add_argument("--test-size", type=integers(32, 10**6, one=True), default=600)
    parser.add_argument("--no-bound", action="store_true", help="skip the bound (a quick look)")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/weather")
    args = parser.parse_args(argv)
    models = [m for m in args.models.split(",") if m]
    check_recipes(models)
    sizes = {"train_size": args.train_size, "test_size": args.test_size}
    sets = datasets(args.data, args.noise, args.visibilities, sizes)
    cells = args.out / "cells"
    cells.mkdir(parents=True, exist_ok=True)

    def cell_path(model: str, seed: int) -> Path:  # a recipe file's stem, a shipped name
        return cells / f"{Path(model).stem}__seed{seed}.json"

    todo = [
        (m, s, {w: str(p) for w, p in sets.items()}, str(cell_path(m, s)))
        for s in args.seeds
        for m in models
        if not cell_path(m, s).is_file()
    ]
    if todo:
        from tqdm import tqdm

        if args.jobs == 1:  # here, in this process
            for job in tqdm(todo, desc="cells"):
                cell(*job)
        else:
            with ProcessPoolExecutor(args.jobs) as pool:
                futures = [pool.submit(cell, *job) for job in todo]
                for future in tqdm(as_completed(futures), total=len(futures), desc="cells"):
                    future.result()
    found = {
        Path(m).stem: [json.loads(cell_path(m, s).read_text()) for s in args.seeds] for m in models
    }
    bound = {} if args.no_bound else bounds(sets, args.out / "bound")
    summary = summarise(found, list(sets), bound)
    command = command_line("weather.py", argv)
    write(args.out, summary, command, {w: p.name for w, p in sets.items()})
    return 0


def summarise(found: dict, weathers: list[str], bound: dict) -> dict:
    points = {}
    for model, runs in found.items():
        points[model] = []
        for weather in weathers:
            acc = np.array([100 * r["test_accuracy"][weather] for r in runs])
            points[model].append(
                {
                    "weather": weather,
                    "accuracy": float(acc.mean()),
                    "accuracy_std": float(acc.std(ddof=1)) if len(acc) > 1 else None,
                    "accuracy_ci95": interval(acc),
                    "seeds": [r["seed"] for r in runs],
                }
            )
    return {"points": points, "bound": bound}


def write(out: Path, summary: dict, command: str, names: dict) -> None:
    weathers = list(names)
    header = " | ".join("clear air" if w == "clear" else f"V = {w} m" for w in weathers)
    lines = [
        "# Weather: trained in clear air, tested in fog",
        "",
        f"Made by `{command}` (`benchmark/weather.py`; its docstring says what is compared). "
        "Test accuracy (%), mean ± sample std over seeds [95 % interval, Student's t]; the "
        "bound: the early-information bound with every spike on that weather's own data "
        "(learners trained in that weather).",
        "",
        "Datasets: " + ", ".join(f"`{n}`" for n in names.values()) + ".",
        "",
        f"| model | {header} |",
        "| --- |" + " ---: |" * len(weathers),
    ]
    for model, rows in summary["points"].items():
        cells = []
        for r in rows:
            text = f"{r['accuracy']:.2f}"
            if r["accuracy_std"] is not None:
                text += f" ± {r['accuracy_std']:.2f}"
            if r["accuracy_ci95"]:
                text += f" [{r['accuracy_ci95'][0]:.2f}, {r['accuracy_ci95'][1]:.2f}]"
            cells.append(f"{text} (n={len(r['seeds'])})")
        lines.append(f"| {model} | " + " | ".join(cells) + " |")
    if summary["bound"]:
        row = [f"{summary['bound'][w]['accuracy']:.1f}" for w in weathers]
        lines.append("| *bound, every spike* | " + " | ".join(row) + " |")
    text = "\n".join(lines) + "\n"
    out.mkdir(parents=True, exist_ok=True)
    (out / "weather.md").write_text(text)
    (out / "weather.json").write_text(
        json.dumps({"command": command, "datasets": names, **summary}, indent=1) + "\n"
    )
    plot(summary, weathers, out / "weather.png")
    print(text)


def plot(summary: dict, weathers: list[str], path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4.5))
    ax = fig.subplots()
    # clear air drawn at the right, beyond the thinnest fog
    fogs = [float(w) for w in weathers if w != "clear"]
    clear_at = 2.0 * max(fogs) if fogs else 1000.0
    x = [clear_at if w == "clear" else float(w) for w in weathers]
    for model, rows in summary["points"].items():
        mean = [r["accuracy"] for r in rows]
        low = [r["accuracy"] - (r["accuracy_ci95"] or (r["accuracy"],))[0] for r in rows]
        high = [(r["accuracy_ci95"] or (0, r["accuracy"]))[1] - r["accuracy"] for r in rows]
        ax.errorbar(x, mean, yerr=[low, high], fmt="o-", capsize=3, label=model)
    if summary["bound"]:
        ax.plot(x, [summary["bound"][w]["accuracy"] for w in weathers], "k--",
                label="bound, every spike (learners trained in that weather)")  # fmt: skip
    ax.set_xscale("log")
    ax.minorticks_off()
    ax.set_xticks(x, ["clear" if w == "clear" else w for w in weathers])
    ax.set(xlabel="visibility (m)", ylabel="test accuracy (%)", ylim=(0, 101),
           title="Trained in clear air, tested in fog (sensor profile)")  # fmt: skip
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    run(main)
