"""report.md and pictures from a benchmark's results, beside the paper's reported numbers: the
tables (:mod:`simlidar.bench.tables`) and pictures (:mod:`simlidar.bench.plots`) put together
with the notes on how each figure is measured."""

import json
import tomllib
from pathlib import Path

from simlidar.atomic import write_file
from simlidar.bench.metrics import MAC_PJ
from simlidar.bench.plots import plot_accuracy, plot_confusions, plot_decisions
from simlidar.bench.tables import accuracy_by_noise, by_model, training_table
from simlidar.content import content_dir
from simlidar.models.decisions import ALPHAS_PJ
from simlidar.models.training_config import TrainingConfig
from simlidar.settings import default_of

PAPER_FILE = "reported/wang2020.toml"


def paper_numbers() -> dict:
    """What Wang et al. (2020) reported (``baselines/reported/wang2020.toml``)."""
    return tomllib.loads((content_dir("baselines") / PAPER_FILE).read_text())


def _machine(m: dict) -> str:
    return f"{m['cpu']} ({m['cores']} cores, torch {m['torch']}, {m['torch_threads']} threads)"


def write_report(results: dict, out: Path, sampled: list[dict] | None = None) -> Path:
    """Write ``<out>/report.md`` and its pictures from results.json's content; ``sampled``:
    the cells with their per-sample arrays, which results.json leaves out (default: those of
    ``<out>/cells/``)."""
    if sampled is None:
        sampled = [json.loads(f.read_text()) for f in sorted((out / "cells").glob("*.json"))]
    paper = paper_numbers()
    cells = results["cells"]
    m = results["machine"]
    seen = {json.dumps(c["machine"], sort_keys=True) for c in cells if "machine" in c}
    unrecorded = sum("machine" not in c for c in cells)
    where = "; ".join(_machine(json.loads(k)) for k in sorted(seen))
    if unrecorded:
        where += ("; " if where else "") + (
            f"{_machine(m)}, the machine that wrote results.json ({unrecorded} cells do not "
            "record their own)"
        )
    lines = [
        f"# Benchmark report: suite {results['suite']['name']}",
        "",
        results["suite"]["description"],
        "",
        f"simlidar {results['simlidar_version']}; {len(cells)} cells; "
        f"{results['seconds'] / 60:.1f} min of training and measuring on {where}.",
        "",
        "All models were trained from scratch here: no pretrained weights exist for these "
        "inputs. Training budgets are in each cell of `results.json`. The paper's numbers come "
        f"from `baselines/{PAPER_FILE}` ({paper['citation']}).",
        "",
    ]
    lines += accuracy_by_noise(cells, paper)
    pictures = [
        (
            "accuracy_vs_noise.png",
            plot_accuracy(cells, paper, out / "accuracy_vs_noise.png"),
            "accuracy vs noise",
        ),
        (
            "decisions.png",
            plot_decisions(sampled, out / "decisions.png"),
            "decision times and input spikes consumed",
        ),
        ("confusion.png", plot_confusions(cells, out / "confusion.png"), "confusion matrices"),
    ]
    lines += [f"![{alt}]({name})\n" for name, made, alt in pictures if made]
    lines += training_table(cells)
    lines += by_model(cells, paper)
    lines += [
        "## How the figures are measured",
        "",
        "* accuracy: test split, scored once with the weights of the epoch that did best on "
        "a validation part held out of the train split (stratified, "
        f"{100 * default_of(TrainingConfig, 'validation'):g} % by default) under a "
        "constant learning rate, of the last epoch under a cosine schedule or without a "
        "validation part (`validation = 0`: the whole train split, a fixed number of epochs, "
        "as the paper trained); a spiking network whose outputs never fire counts as wrong; "
        "a spiking network that the event-driven evaluator runs is scored on the float64 spike "
        "times its event-driven figures are read from.",
        "* decision ns, input spikes used, R_data, hidden spikes: the event-driven evaluator "
        "(dense spiking networks), means over test samples; R_data = input spikes consumed "
        "before the decision / all input spikes of the sample. Time-stepped networks "
        "(snnTorch, Norse, ...; simlidar.models.protocol): the decision step of T by the "
        "network's declared readout (first output spike, or spike count / membrane at the last "
        "step), the input spikes delivered up to it, and its neurons' spikes (hidden and "
        "output) in the hidden spikes column; their operations are accumulates (binary "
        "inputs) in `results.json` (`synaptic_operations`, `energy_pj_ops`).",
        "* energy: spiking networks, spikes (input consumed + hidden + output) x alpha at "
        f"{' and '.join(f'{a:g}' for a in ALPHAS_PJ)} pJ per spike, as the paper estimates it; "
        f"conventional networks, multiply-accumulates x {MAC_PJ:g} pJ (32-bit float at 45 nm, "
        "Horowitz 2014). The paper's own estimate for conventional networks, board power x "
        "latency, needs the suite's `board_power_w`"
        + (
            " (set)."
            if any(c.get("energy_pj_board") for c in cells)
            else ": not set, as this machine's power draw is not known (column left out)."
        ),
        "* latency: batch 1, median of up to 30 runs after 3 warm-up runs on this CPU; "
        "samples/s: one batch of up to 512. Indicative only: both depend on what else the "
        "machine was doing (a benchmark script, not a training suite, measures speed).",
        "* params, footprint (bytes of parameters and buffers), connection and activation "
        "sparsity, synaptic operations: NeuroBench 2.3.0's definitions, checked against the "
        "library in the tests (docs/benchmark.md, NeuroBench metrics), in `results.json`.",
        "",
    ]
    path = out / "report.md"
    write_file(path, lambda tmp: tmp.write_text("\n".join(lines)))
    return path
