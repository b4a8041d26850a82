"""Accuracy against weights on the physical profile: the CNN and ResNet-18 families.

    simlidar bench --suite benchmark/ablation/physical-ablation.toml \\
        --out benchmark/results/physical-ablation          # the variants (resumable cells)
    python benchmark/ablation/width.py                     # this table and picture

Reads the committed cells of the physical suite (``cnn``, ``resnet18``) and of the ablation
(``benchmark/ablation/*.toml``), prints test accuracy (mean ± sample std over seeds) by model
and noise level beside each model's number of weights, and draws ``width.png`` into the
ablation's folder: accuracy against weights (log scale), one panel per noise level.
Writes ``width.md`` beside it with the same table.
"""

import argparse
import json
import sys
from pathlib import Path

from simlidar.bench.tables import group_by, mean_std, percent

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmark/results"
# series -> (models in order of weights, matplotlib format); model names as the cells give them
SERIES = {
    "ResNet-18, widths 7 / 16 / 32 / 64 (cosine, 15 epochs)": (
        ["resnet18_w7", "resnet18_w16", "resnet18_w32", "resnet18"],
        "-o",
    ),
    "ResNet-18 width 7, cosine over 60 epochs": (["resnet18_w7_e60"], "^"),
    "CNN on a cosine schedule (cnn_cosine, cnn_wide)": (["cnn_cosine", "cnn_wide"], "--s"),
    "CNN at a constant rate (cnn, the baseline)": (["cnn"], "D"),
}
NOISE = (0.1, 0.2, 0.33, 0.5)


def cells(folders: list[Path], models: set[str]) -> list[dict]:
    found = []
    for folder in folders:
        for path in sorted((folder / "cells").glob("*.json")):
            cell = json.loads(path.read_text())
            if cell["model"] in models:
                found.append(cell)
    return found


def table(found: list[dict]) -> list[str]:
    by = group_by(found, "model", "noise")
    lines = [
        "| model | weights | " + " | ".join(f"noise {n:g}" for n in NOISE) + " |",
        "|---" * (2 + len(NOISE)) + "|",
    ]
    for models, _ in SERIES.values():
        for model in models:
            runs = [c for c in found if c["model"] == model]
            if not runs:
                continue
            row = [
                f"{percent([c['accuracy'] for c in by[(model, n)]])} ({len(by[(model, n)])})"
                if by.get((model, n))
                else "–"
                for n in NOISE
            ]
            lines.append(f"| {model} | {runs[0]['params']:,} | " + " | ".join(row) + " |")
    return lines


def plot(found: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by = group_by(found, "model", "noise")
    params = {c["model"]: c["params"] for c in found}
    fig, axes = plt.subplots(2, 2, figsize=(8, 6), dpi=100, sharex=True)
    for ax, n in zip(axes.flat, NOISE, strict=True):
        for i, (label, (models, fmt)) in enumerate(SERIES.items()):
            points = [m for m in models if by.get((m, n))]
            if not points:
                continue
            stats = [mean_std([100 * c["accuracy"] for c in by[(m, n)]]) for m in points]
            ax.errorbar(
                [params[m] for m in points],
                [s[0] for s in stats],
                yerr=[s[1] for s in stats],
                fmt=fmt,
                color=f"C{i}",
                capsize=3,
                label=label,
            )
        ax.set_xscale("log")
        ax.set_title(f"noise {n:g}", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("weights")
    for ax in axes[:, 0]:
        ax.set_ylabel("test accuracy (%)")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=7)
    fig.suptitle("Physical profile: accuracy against weights (mean ± std over seeds)", fontsize=10)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--physical", type=Path, default=RESULTS / "physical")
    parser.add_argument("--ablation", type=Path, default=RESULTS / "physical-ablation")
    args = parser.parse_args(argv)
    models = {m for series, _ in SERIES.values() for m in series}
    found = cells([args.physical, args.ablation], models)
    if not found:
        print(f"error: no cells of {sorted(models)} under {args.physical} or {args.ablation}")
        return 2
    lines = table(found)
    print("\n".join(lines))
    (args.ablation / "width.md").write_text(
        "Test accuracy (%) on the physical profile, mean ± sample std over seeds (seeds in "
        "brackets), written by `python benchmark/ablation/width.py`.\n\n" + "\n".join(lines) + "\n"
    )
    plot(found, args.ablation / "width.png")
    print(f"wrote {args.ablation / 'width.md'} and width.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
