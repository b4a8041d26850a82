"""The paper's Sim LiDAR table, rerun: the dense SNN (256-400-32) at the four noise levels.

    python benchmark/paper_table.py                      # the whole table (about an hour, 2 cores)
    python benchmark/paper_table.py --seeds 0 --recipes snn_simlidar_tuned   # a part of it

What it does, with one command:

1. ``simlidar generate --noise 0.1,0.2,0.33,0.5`` with the default profile (``paper``) and the
   paper's sizes (3000 / 600), into ``--data`` (kept and reused when already there);
2. trains every recipe of ``--recipes`` with every seed of ``--seeds`` on every noise level,
   ``--jobs`` cells at a time (one torch thread each), each cell a JSON file under
   ``--out``/cells (a rerun skips finished cells, so a killed run resumes);
3. prints the mean and sample standard deviation over the seeds found in ``--out``/cells
   beside the paper's accuracy (``baselines/reported/wang2020.toml``), with the distribution
   of input spikes consumed before the decision (median, 10th / 90th percentile, maximum,
   over every test sample of every seed), and writes ``table.md``, ``table.json`` and
   ``input_spikes.png`` to ``--out``.

Every cell trains for its recipe's epochs, without the recipe's time cap (``max_seconds``), so
that no figure depends on how loaded the machine was, on the whole train split (``validation =
0``: no validation split, no early stopping, as the paper trained). Test accuracy is that of
the last epoch: nothing is selected, on the test split or any other.
"""

import argparse
import json
import os
import time
import tomllib
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from simlidar.bench.hardware import MAX_THREADS
from simlidar.models.training_config import MAX_EPOCHS, PENALTY
from simlidar.script_args import command_line, integers, numbers, run

ROOT = Path(__file__).resolve().parents[1]
LEVELS = (0.1, 0.2, 0.33, 0.5)
# the arguments this script shares with early_tradeoff, early_objectives and scan_timing
SEEDS = integers(0, 2**63 - 1)  # training seeds, as `simlidar train --seed`
EPOCHS = integers(1, MAX_EPOCHS, one=True)
JOBS = integers(1, MAX_THREADS, one=True)  # cells trained at a time
PENALTIES = numbers(PENALTY.low, PENALTY.high)  # the training option early_penalty
NOISE = numbers(0, 1, one=True)  # a dataset's noise level, as `simlidar generate --noise`


def interval(accuracy: np.ndarray) -> list[float] | None:
    """The 95 % confidence interval of the mean of the seeds' accuracies (Student's t, n - 1
    degrees of freedom); None for one seed."""
    if len(accuracy) < 2:
        return None
    from scipy.stats import t

    half = t.ppf(0.975, len(accuracy) - 1) * accuracy.std(ddof=1) / np.sqrt(len(accuracy))
    return [float(accuracy.mean() - half), float(accuracy.mean() + half)]


def recipe_epochs(text: str) -> dict[str, int]:
    """An argparse type: ``RECIPE=N,...``, each N an epoch count (the recipes are checked with
    :func:`check_recipes`)."""
    epochs = {}
    for part in text.split(",") if text else ():
        name, equals, count = part.partition("=")
        try:
            if not name or not equals:
                raise argparse.ArgumentTypeError(part)
            epochs[name] = EPOCHS(count)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(
                f"{part!r}: expected RECIPE=N, N an integer in [1, {MAX_EPOCHS}]"
            ) from None
    return epochs


def check_recipes(names) -> None:
    """Load every recipe of ``names`` before any work: a ConfigError names one that does not
    exist."""
    from simlidar.models.registry import load_recipe

    for name in names:
        load_recipe(name)


def _cell(
    recipe_name: str,
    dataset: str,
    seed: int,
    path: str,
    training: dict | None = None,
    epochs: int | None = None,
    architecture: dict | None = None,
) -> str:
    """Train one cell in a worker process; write its JSON atomically; return the path.

    training : [training] keys to set on top of the recipe's (benchmark/early_tradeoff.py)
    architecture : [architecture] keys to set on top of the recipe's (an encoding's
        ``direction``: benchmark/early_objectives.py); recorded when given
    """
    import torch

    torch.set_num_threads(1)
    from simlidar.bench.early import early_decisions
    from simlidar.bench.train import train
    from simlidar.models.registry import load_recipe

    recipe = load_recipe(recipe_name)
    recipe["training"]["validation"] = 0  # the paper's protocol: all 3000, the last epoch
    recipe["training"].update(training or {})
    recipe["architecture"].update(architecture or {})
    # epochs decide, never the recipe's time cap: a figure must not depend on machine load
    result = train(
        recipe, dataset, seed=seed, epochs=epochs, max_seconds=float("inf"), progress=False
    )
    early = early_decisions(result.model, dataset, per_sample=True)
    record = {
        "recipe": recipe_name,
        "dataset": Path(dataset).name,
        "seed": seed,
        "training": training or {},
        **({"architecture": architecture} if architecture else {}),
        "test_accuracy": result.test_accuracy,
        "epochs": result.epochs,
        "seconds": result.seconds,
        "history": result.history,
        "early": {k: v for k, v in early.items() if k != "per_sample"},
        "input_spikes": early["per_sample"]["input_spikes"],
        **{  # behind an input budget: what had arrived by each decision
            k: early["per_sample"][k] for k in ("input_spikes_arrived",) if k in early["per_sample"]
        },
        "decision_time_ns": early["per_sample"]["decision_time_ns"],
    }
    tmp = Path(path).with_suffix(".partial")
    tmp.write_text(json.dumps(record))
    tmp.replace(path)
    return path


def done(path: Path, recipe: str, epochs: int | None = None) -> bool:
    """Is the cell at ``path`` finished: there, and trained for all its epochs (a cell of an
    older run that stopped on a time cap is trained again)?"""
    if not path.is_file():
        return False
    from simlidar.models.registry import load_recipe

    wanted = epochs or load_recipe(recipe)["training"]["epochs"]
    return json.loads(path.read_text())["epochs"] >= wanted


def run_cells(todo: list[tuple], jobs: int) -> None:
    """Train the cells of ``todo`` (:func:`_cell` arguments), ``jobs`` at a time."""
    if not todo:
        return
    from tqdm import tqdm

    with ProcessPoolExecutor(jobs) as pool:
        futures = [pool.submit(_cell, *job) for job in todo]
        for future in tqdm(as_completed(futures), total=len(futures), desc="cells"):
            future.result()


def made(root: Path, config) -> Path:
    """The dataset of ``config`` (a GeneratorConfig of one noise level) under ``root``,
    generated there if missing."""
    from simlidar.generator.generate import generate, generated_name
    from simlidar.scene.recipe import load_catalog

    path = root / generated_name(config)
    if not path.is_dir():
        generate(config, [config.noise], load_catalog(), root)
    return path


def datasets(root: Path) -> dict[float, Path]:
    """The four datasets of the table (default profile), generated when missing."""
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.generate import generate, generated_name
    from simlidar.generator.profiles import DEFAULT_PROFILE, load_profile
    from simlidar.scene.recipe import load_catalog

    config = GeneratorConfig.from_profile(load_profile(DEFAULT_PROFILE))
    paths = {level: root / generated_name(config.with_noise(level)) for level in LEVELS}
    if not all(p.is_dir() for p in paths.values()):
        missing = [level for level, p in paths.items() if not p.is_dir()]
        generate(config, missing, load_catalog(), root)
    return paths


def summarise(cells: list[dict], paper: list[float]) -> dict:
    """Per recipe and noise level: accuracy mean / sample std over seeds, input spikes."""
    table = {}
    for recipe in sorted({c["recipe"] for c in cells}):
        rows = []
        for level, reported in zip(LEVELS, paper):
            mine = [c for c in cells if c["recipe"] == recipe and c["noise"] == level]
            if not mine:
                continue
            acc = np.array([100 * c["test_accuracy"] for c in mine])
            spikes = np.concatenate([c["input_spikes"] for c in mine])
            rows.append(
                {
                    "noise": level,
                    "paper": reported,
                    "seeds": sorted(c["seed"] for c in mine),
                    "accuracy": [round(a, 2) for a in acc],
                    "mean": round(float(acc.mean()), 2),
                    "std": round(float(acc.std(ddof=1)), 2) if len(acc) > 1 else None,
                    "ci95": [round(v, 2) for v in interval(acc)] if len(acc) > 1 else None,
                    "difference": round(float(acc.mean()) - reported, 2),
                    "epochs": [c["epochs"] for c in mine],
                    "minutes": [  # the fewest and the most: runs differ by machine and code
                        round(float(f([c["seconds"] for c in mine])) / 60, 1) for f in (min, max)
                    ],
                    "input_spikes": {
                        "p10": float(np.percentile(spikes, 10)),
                        "median": float(np.median(spikes)),
                        "p90": float(np.percentile(spikes, 90)),
                        "max": int(spikes.max()),
                        "mean": float(spikes.mean()),
                        "total": float(
                            np.mean([c["early"]["input_spikes_total_mean"] for c in mine])
                        ),
                    },
                    "no_decision": int(sum(c["early"]["no_decision"] for c in mine)),
                }
            )
        table[recipe] = rows
    return table


def markdown(table: dict, command: str) -> str:
    lines = [
        f"Made by `{command}`. Accuracy in percent on the 600 test samples, mean and sample "
        "standard deviation over training seeds (last epoch) [95 % interval of the mean, "
        "Student's t]; input spikes consumed before "
        "the decision over every test sample of every seed (the paper: as few as 13-16, "
        "never more than 180 of 256).",
        "",
    ]
    for recipe, rows in table.items():
        lines += [
            f"### `{recipe}`",
            "",
            "| noise | paper | ours | difference | seeds | input spikes: median (p10 / "
            "p90, max) of total | epochs | minutes / run |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |",
        ]
        for r in rows:
            std = f" ± {r['std']:.2f}" if r["std"] is not None else ""
            if r.get("ci95"):
                std += " [{:.2f}, {:.2f}]".format(*r["ci95"])
            s = r["input_spikes"]
            lines.append(
                f"| {r['noise']} | {r['paper']:.2f} | {r['mean']:.2f}{std} | "
                f"{r['difference']:+.2f} | {len(r['seeds'])} | {s['median']:.0f} ({s['p10']:.0f} "
                f"/ {s['p90']:.0f}, {s['max']}) of {s['total']:.0f} | "
                f"{'/'.join(map(str, sorted(set(r['epochs']))))} | {minutes(r['minutes'])} |"
            )
        lines.append("")
    return "\n".join(lines)


def minutes(span) -> str:
    """A row's minutes a run: one figure, or the fewest and the most (older tables: a mean)."""
    if not isinstance(span, list):
        return str(span)
    return str(span[0]) if span[0] == span[1] else f"{span[0]}-{span[1]}"


def plot(table: dict, cells: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recipes = list(table)
    fig, axes = plt.subplots(1, len(recipes), figsize=(5.5 * len(recipes), 3.8), squeeze=False)
    bins = np.arange(0, 258, 8)
    for ax, recipe in zip(axes[0], recipes):
        for level in LEVELS:
            spikes = [
                s
                for c in cells
                if c["recipe"] == recipe and c["noise"] == level
                for s in c["input_spikes"]
            ]
            if spikes:
                ax.hist(spikes, bins=bins, histtype="step", linewidth=1.5, label=f"noise {level}")
        ax.axvspan(13, 16, color="tab:green", alpha=0.3, label="paper: as few as 13-16")
        ax.axvline(180, color="tab:red", linestyle="--", label="paper: never more than 180")
        ax.set(
            title=recipe,
            xlabel="input spikes consumed before the decision (of 256)",
            ylabel="test samples (all seeds)",
            xlim=(0, 256),
        )
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--recipes", default="snn_simlidar,snn_simlidar_tuned")
    parser.add_argument("--seeds", type=SEEDS, default="0,1,2")
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/paper-table")
    parser.add_argument("--jobs", type=JOBS, default=min(2, os.cpu_count() or 1))
    parser.add_argument(
        "--epochs",
        type=recipe_epochs,
        default="snn_simlidar=60",  # its recipe's 200 epochs were sized for a 600 s cap
        help="RECIPE=N,...: train these recipes for N epochs, not their own",
    )
    args = parser.parse_args(argv)
    recipes = [r for r in args.recipes.split(",") if r]
    seeds = list(args.seeds)
    check_recipes([*recipes, *args.epochs])
    reported = tomllib.loads((ROOT / "baselines/reported/wang2020.toml").read_text())
    paper = reported["simlidar"]["snn_accuracy"]

    paths = datasets(args.data)
    cells_dir = args.out / "cells"
    epochs = args.epochs
    tags = {r: f"-e{epochs[r]}" if r in epochs else "" for r in recipes}
    cells_dir.mkdir(parents=True, exist_ok=True)
    todo = []
    for recipe in recipes:
        for level in LEVELS:
            for seed in seeds:
                cell = cells_dir / f"{paths[level].name}__{recipe}{tags[recipe]}__seed{seed}.json"
                if not done(cell, recipe, epochs.get(recipe)):
                    todo.append(
                        (recipe, str(paths[level]), seed, str(cell), None, epochs.get(recipe))
                    )
    start = time.perf_counter()
    run_cells(todo, args.jobs)
    cells = []  # every finished cell of these recipes, also seeds of earlier runs
    for recipe in recipes:
        for level in LEVELS:
            name = f"{recipe}{tags[recipe]}"
            for cell in sorted(cells_dir.glob(f"{paths[level].name}__{name}__seed*.json")):
                record = json.loads(cell.read_text())
                record["noise"] = level
                record["recipe"] = name
                cells.append(record)
    table = summarise(cells, paper)
    command = command_line("paper_table.py", argv)
    text = markdown(table, command)
    (args.out / "table.md").write_text(text)
    (args.out / "table.json").write_text(json.dumps(table, indent=1))
    plot(table, cells, args.out / "input_spikes.png")
    print(text)
    print(
        f"{len(todo)} cells trained in {time.perf_counter() - start:.0f} s; wrote "
        f"{args.out / 'table.md'}"
    )
    return 0


if __name__ == "__main__":
    run(main)
