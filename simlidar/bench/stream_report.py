"""The report of a stream benchmark's run (docs/streams.md, "Running them"): ``report.md``,
``summary.json`` and ``accuracy-latency.png`` from its cells (:mod:`simlidar.bench.stream_bench`)
and estimate: per model the mean and a 95 % Student's t half-width over its seeds, the estimate
beside them; and the table alone, which ``benchmark/stream_bench.py --doc`` puts into the docs."""

import json
from pathlib import Path

import numpy as np

from simlidar.bench.latency import DELAYS_MS, mean_interval
from simlidar.bench.stream_bench import CELLS, ESTIMATE


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
            **{
                f"acc_{d:g}ms": [c["accuracy_after"]["accuracy"][k] for c in mine]
                for k, d in enumerate(DELAYS_MS)
            },
            "acc_end": [c["accuracy_after"]["end_accuracy"] for c in mine],
            "area": [c["area_under_curve"]["area"] for c in mine],
            "wait_ms": [c["first_answer_after_reference_ms"]["median"] for c in mine],
            "test_window_accuracy": [c["test_window_accuracy"] for c in mine],
        }
        out[model] = {"seeds": len(mine)} | {name: _interval(v) for name, v in figures.items()}
    return out


REPORT_TEXT = (
    "Accuracy on the sensor's clock, ms after each test stream's reference time (the object's "
    "first return; for `none`, one of its returns, drawn), mean and 95 % Student's t "
    "half-width over seeds. A frame-based network answers when a rotation's frame is complete "
    "(cut at the rear: half a rotation after the window's middle): the answer in force 10 ms "
    "after the reference is the one of the frame before, made without the object (a guess from "
    "the background); so does a network over rotations (`gru_rotations`). `-window`: the same "
    "frame-based network answering when its window is complete (its last pulse plus the longest "
    "time of flight: the forward sector published as soon as it is scanned). An event-driven "
    "network (`-event`) answers in every window at its first output spike; a network over "
    "binned events (`lif_stream`) at the end of every bin. 'Wait' is the median time from the "
    "reference to the first answer after it. 'Window accuracy': a window model's on the test "
    "windows from the reference's on, a stream network's over the steps from the reference's "
    "on. The estimate: learners trained on what the sensor knows at any time around the "
    "reference, scored at each delay (docs/streams.md, 'What the data allow'); its seed mean, "
    "the best family's."
)


def report_table(table: dict, estimate: dict | None) -> list[str]:
    """The report's table (markdown lines) of a :func:`summary` and the estimate (None: no row
    of it): per model, accuracy 10, 50 and 100 ms after the reference and at the span's end,
    the area, the wait and the window accuracy, mean ± 95 % half-width."""
    lines = [
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
    return lines


def write_report(out: Path, cells: list[dict]) -> None:
    """report.md, summary.json and accuracy-latency.png of ``out`` from its cells and, where
    there is one, the estimate (estimate.json) beside them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = summary(cells)
    estimate = None
    if (out / ESTIMATE).exists():
        estimate = json.loads((out / ESTIMATE).read_text())
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
        REPORT_TEXT,
        "",
        *report_table(table, estimate),
    ]
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
    plt.close(fig)
