"""Frame-based networks on a stream dataset (issue 60, item 3): each model of ``--models``
trained on the rotation windows of the train split with each seed of ``--seeds``, scored on
the test split on the sensor's clock (docs/streams.md, "Frame-based networks"): accuracy 0.5 to
100 ms after each stream's reference time, the first answer's latency, the area under the
accuracy-latency curve; a report with the mean and a 95 % Student's t interval over seeds and
the accuracy-latency picture.

    python benchmark/stream_bench.py DATASET --out DIR [--models cnn,mlp] [--seeds 0,1,2,3,4]
        [--epochs N] [--validation 0.1] [--no-train]

Cells are appended to DIR/cells.jsonl as they finish, and a run started again skips the
(model, seed) pairs already there (resumable); ``--no-train`` writes the report from them. A
recipe's noise augmentation is switched off (a stream carries no noise to draw anew).
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from simlidar.bench.latency import DELAYS_MS, mean_interval
from simlidar.bench.stream_task import (
    decision_answers,
    frame_answers,
    latency_record,
    read_cells,
    scored_windows,
    stream_views,
    training_windows,
)
from simlidar.bench.train import train
from simlidar.errors import ConfigError
from simlidar.models.registry import load_recipe
from simlidar.script_args import command_line, integers, numbers, run

CELLS = "cells.jsonl"


def run_cell(dataset: Path, model: str, seed: int, epochs: int | None, validation: float,
             views, mode: str, command: str) -> dict:  # fmt: skip
    """One (model, seed) cell: ``mode`` "frame" (answers at the frame ends, time-of-flight
    windows) or "event" (a spiking network's first output spike in each arrival-coded
    window); ``views``: the train and test StreamViews of that coding."""
    recipe = load_recipe(model)
    recipe["training"]["noise_augment"] = False
    recipe["training"]["validation"] = validation
    train_views, test_views = views
    rows = training_windows(train_views, seed, validation, list(train_views.classes))
    start = time.perf_counter()
    result = train(recipe, dataset, seed=seed, epochs=epochs, progress=False, rows=rows,
                   test=scored_windows(test_views))  # fmt: skip
    seconds = time.perf_counter() - start
    if mode == "event":
        answers = decision_answers(result.model, test_views)
    else:
        answers = frame_answers(result.model, test_views, result.spec, result.silent_from)
    return {
        "model": recipe["name"] + ("-event" if mode == "event" else ""),
        "mode": mode,
        "command": command,
        "coding": test_views.coding,
        "seed": seed,
        "dataset": dataset.name,
        "streams_trained": len(rows.trained),
        "windows_trained": len(rows.y_train),
        "windows_validated": len(rows.y_val),
        "epochs": result.epochs,
        "best_epoch": result.best_epoch,
        "train_seconds": round(seconds, 1),
        "test_window_accuracy": result.test_accuracy,
        **latency_record(answers, test_views),
    }


def _interval(values: list) -> tuple[float, float]:
    """Mean and 95 % half-width of the figures that exist (None: a network that never answered
    after the reference); NaN where none does, a NaN half-width for one."""
    given = [float(v) for v in values if v is not None and np.isfinite(v)]
    if len(given) > 1:
        return mean_interval(given)
    return (given[0] if given else float("nan")), float("nan")


def summary(cells: list[dict]) -> dict:
    """Per model: each figure's mean and 95 % half-width over its seeds."""
    out = {}
    for model in sorted({c["model"] for c in cells}):
        mine = [c for c in cells if c["model"] == model]
        figures = {
            **{f"acc_{d:g}ms": [c["accuracy_after"]["accuracy"][k] for c in mine]
               for k, d in enumerate(DELAYS_MS)},
            "acc_end": [c["accuracy_after"]["end_accuracy"] for c in mine],
            "area": [c["area_under_curve"]["area"] for c in mine],
            "wait_ms": [c["first_answer_after_reference_ms"]["median"] for c in mine],
            "test_window_accuracy": [c["test_window_accuracy"] for c in mine],
        }  # fmt: skip
        out[model] = {"seeds": len(mine)} | {name: _interval(v) for name, v in figures.items()}
    return out


def write_report(out: Path, cells: list[dict]) -> None:
    """report.md, summary.json and accuracy-latency.png of ``out`` from its cells and, where
    ``benchmark/stream_estimate.py`` wrote one there, the estimate beside them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = summary(cells)
    estimate = None
    if (out / "estimate.json").exists():
        estimate = json.loads((out / "estimate.json").read_text())
    commands = list(dict.fromkeys(c["command"] for c in cells))
    if estimate is not None:
        commands.append(estimate["command"])
    lines = [
        "# Networks on pulse streams",
        "",
        f"Cells in `{CELLS}`, made by:",
        "",
        *[f"    {c}" for c in commands],
        "",
        "Accuracy on the sensor's clock, ms after each test stream's reference time (the "
        "object's first return; for `none`, one of its returns, drawn), mean and 95 % "
        "Student's t half-width over seeds. A frame-based network answers when a rotation's "
        "frame is complete (cut at the rear: half a rotation after the window's middle): the "
        "answer in force 10 ms after the reference is the one of the frame before, made "
        "without the object (a guess from the background). An event-driven network (`-event`) "
        "answers in every window at its first output spike. 'Wait' is the median time from "
        "the reference to the first answer after it. The estimate: learners trained on what the "
        "sensor knows at any time around the reference, scored at each delay "
        "(docs/streams.md, 'What the data allow'); its seed mean, the best family's.",
        "",
        "| model | seeds | 10 ms | 50 ms | 100 ms | end of span | area 0-100 ms | wait, ms | "
        "window accuracy |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]

    def cell(pair):
        mean, half = pair
        if np.isnan(mean):
            return "n/a"
        return f"{mean:.3f}" + ("" if np.isnan(half) else f" ± {half:.3f}")

    for model, row in table.items():
        lines.append(
            f"| {model} | {row['seeds']} | {cell(row['acc_10ms'])} | {cell(row['acc_50ms'])} | "
            f"{cell(row['acc_100ms'])} | {cell(row['acc_end'])} | {cell(row['area'])} | "
            f"{cell(row['wait_ms'])} | {cell(row['test_window_accuracy'])} |"
        )
    if estimate is not None:
        at = estimate["delays"]
        seeds = max(f["seeds"] for f in at["10"]["families"].values())
        lines.append(
            f"| estimate | {seeds} | {at['10']['estimate']:.3f} ({at['10']['best']}) | "
            f"{at['50']['estimate']:.3f} ({at['50']['best']}) | "
            f"{at['100']['estimate']:.3f} ({at['100']['best']}) | | | | |"
        )
    lines += ["", "![accuracy against time](accuracy-latency.png)"]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "summary.json").write_text(json.dumps(table, indent=1, default=float) + "\n")
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for model, row in table.items():
        mean = [row[f"acc_{d:g}ms"][0] for d in DELAYS_MS]
        half = np.nan_to_num([row[f"acc_{d:g}ms"][1] for d in DELAYS_MS])
        ax.plot(DELAYS_MS, mean, marker="o", label=model)
        ax.fill_between(DELAYS_MS, np.array(mean) - half, np.array(mean) + half, alpha=0.2)
    if estimate is not None:
        values = [estimate["delays"][f"{d:g}"]["estimate"] for d in DELAYS_MS]
        ax.plot(DELAYS_MS, values, "k--", label="estimate")
    ax.set_xscale("log")
    ax.set_xlabel("ms after the object's first return (sensor time)")
    ax.set_ylabel("test accuracy")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "accuracy-latency.png", dpi=110)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--models", default="cnn,mlp", help="frame-based: answers at frame ends")
    parser.add_argument("--event-models", default="", help="spiking recipes run event-driven: "
                        "arrival-coded windows, answers at the first output spike")  # fmt: skip
    parser.add_argument("--seeds", type=integers(0, 2**31), default=(0, 1, 2, 3, 4))
    parser.add_argument("--epochs", type=integers(1, 10_000, one=True), default=None)
    parser.add_argument("--validation", type=numbers(0, 0.5, one=True), default=0.1)
    parser.add_argument("--no-train", action="store_true")
    args = parser.parse_args(argv)
    cells_path = args.out / CELLS
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out}: expected a folder")
    cells = read_cells(cells_path, args.dataset.name)
    command = command_line("stream_bench.py", argv)
    plans = [(m, "frame") for m in args.models.split(",") if m]
    plans += [(m, "event") for m in args.event_models.split(",") if m]
    views = {}
    if not args.no_train:  # every split and recipe read before anything is written
        recipes = {model: load_recipe(model) for model, _ in plans}
        for _, mode in plans:
            coding = "arrival" if mode == "event" else "tof"
            if coding not in views:
                views[coding] = tuple(stream_views(args.dataset, s, coding)
                                      for s in ("train", "test"))  # fmt: skip
    elif not cells:
        raise ConfigError(f"--no-train: {cells_path}: no cells to report; expected a run's")
    args.out.mkdir(parents=True, exist_ok=True)
    done = {(c["model"], c["seed"]) for c in cells}
    for model, mode in plans if not args.no_train else []:
        coding = "arrival" if mode == "event" else "tof"
        for seed in args.seeds:
            name = recipes[model]["name"] + ("-event" if mode == "event" else "")
            if (name, seed) in done:
                continue
            record = run_cell(args.dataset, model, seed, args.epochs, args.validation,
                              views[coding], mode, command)  # fmt: skip
            with cells_path.open("a") as f:
                f.write(json.dumps(record) + "\n")
            cells.append(record)
            acc = dict(zip(DELAYS_MS, record["accuracy_after"]["accuracy"]))
            print(f"{record['model']} seed {seed}: 10 ms {acc[10]:.3f}, 50 ms {acc[50]:.3f}, "
                  f"end {record['accuracy_after']['end_accuracy']:.3f} "
                  f"({record['train_seconds']} s)", flush=True)  # fmt: skip
    write_report(args.out, cells)
    print(f"wrote {args.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    run(main)
