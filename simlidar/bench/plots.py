"""The report's pictures from a benchmark's cells: accuracy against noise beside the paper's
SNN, when the spiking networks decide, confusion matrices; each written atomically as a PNG
without a Software tag (:mod:`simlidar.bench.report` puts them in report.md)."""

from collections import defaultdict
from pathlib import Path

import numpy as np

from simlidar.atomic import write_file
from simlidar.bench.tables import group_by, mean_std, paper_sized
from simlidar.dataset.version import GENERATOR


def plot_accuracy(cells: list[dict], paper: dict, path: Path) -> bool:
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    sim = [c for c in cells if c["source"] == GENERATOR]
    if not sim:
        return False
    fig = Figure(figsize=(6, 4), dpi=100)
    ax = fig.subplots()
    for (model,), runs in sorted(group_by(sim, "model").items()):
        by = group_by(runs, "noise")
        levels = sorted(k[0] for k in by)
        stats = [mean_std([100 * c["accuracy"] for c in by[(v,)]]) for v in levels]
        ax.errorbar(
            levels,
            [s[0] for s in stats],
            yerr=[s[1] for s in stats],
            marker="o",
            capsize=3,
            label=model,
        )
    sizes = f"{paper['simlidar']['train_size']} / {paper['simlidar']['test_size']}"
    ax.plot(
        paper["simlidar"]["noise"],
        paper["simlidar"]["snn_accuracy"],
        "k--",
        marker="x",
        label="paper: SNN" if paper_sized(sim, paper) else f"paper: SNN ({sizes} samples)",
    )
    chance = 100 / sim[0]["classes"]
    ax.axhline(chance, color="grey", lw=0.8, ls=":", label=f"chance ({chance:.1f} %)")
    ax.set_xlabel("noise level a (U(0, a) added to every delay)")
    ax.set_ylabel("test accuracy (%)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize=7)
    ax.set_title("Sim LiDAR: accuracy vs noise (mean ± std over seeds)", fontsize=9)
    fig.tight_layout()
    write_file(path, lambda tmp: fig.savefig(tmp, format="png", metadata={"Software": None}))
    return True


def plot_decisions(cells: list[dict], path: Path) -> bool:
    """Histograms of decision times and input spikes consumed (dense spiking networks), from
    the cells that carry ``per_sample``."""
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    runs = defaultdict(lambda: {"decision_time_ns": [], "input_spikes": []})
    for cell in cells:
        if "per_sample" in cell and "early" in cell:  # event-driven runs: times in ns
            key = f"{cell['model']} @ {cell['dataset']}"
            for name in runs[key]:
                runs[key][name] += [v for v in cell["per_sample"][name] if v is not None]
    if not runs:
        return False
    fig = Figure(figsize=(9, 3.5), dpi=100)
    axes = fig.subplots(1, 2)
    for key, values in sorted(runs.items()):
        if values["decision_time_ns"]:
            axes[0].hist(values["decision_time_ns"], bins=40, histtype="step", label=key)
        axes[1].hist(values["input_spikes"], bins=40, histtype="step", label=key)
    axes[0].set_xlabel("decision time after the first pulse left (ns)")
    axes[1].set_xlabel("input spikes consumed before the decision")
    for ax in axes:
        ax.set_ylabel("test samples")
    axes[1].legend(fontsize=6)
    fig.suptitle("When the spiking network decides (event-driven, all seeds)", fontsize=9)
    fig.tight_layout()
    write_file(path, lambda tmp: fig.savefig(tmp, format="png", metadata={"Software": None}))
    return True


def plot_confusions(cells: list[dict], path: Path) -> bool:
    """Row-normalised confusion matrices, one per model, at each model's first dataset."""
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    if not cells:
        return False
    first = sorted({c["dataset"] for c in cells})[0]
    group = group_by([c for c in cells if c["dataset"] == first], "model")
    fig = Figure(figsize=(3 * len(group), 3.2), dpi=100)
    axes = fig.subplots(1, len(group), squeeze=False)
    for ax, ((model,), runs) in zip(axes[0], sorted(group.items())):
        matrix = np.sum([np.array(c["confusion"]) for c in runs], axis=0).astype(float)
        matrix /= np.maximum(matrix.sum(axis=1, keepdims=True), 1)
        ax.imshow(matrix, cmap="viridis", vmin=0, vmax=1)
        ax.set_title(model, fontsize=8)
        ax.set_xlabel("predicted (last column: none)", fontsize=6)
        ax.set_ylabel("true", fontsize=6)
        ax.tick_params(labelsize=5)
    fig.suptitle(f"Confusion matrices on {first} (rows normalised, all seeds)", fontsize=9)
    fig.tight_layout()
    write_file(  # bbox "tight" keeps the axis labels
        path,
        lambda tmp: fig.savefig(
            tmp, format="png", metadata={"Software": None}, bbox_inches="tight"
        ),
    )
    return True
