"""The report's tables (markdown lines) from a benchmark's cells, beside the paper's reported
numbers, and the figures they are made of: means over seeds, cells grouped by their settings,
the marks on a group of seeds (:mod:`simlidar.bench.report` assembles report.md)."""

from collections import defaultdict

import numpy as np

from simlidar.bench.metrics import MAC_PJ
from simlidar.dataset.version import GENERATOR
from simlidar.models.decisions import ALPHAS_PJ


def mean_std(values: list[float]) -> tuple[float, float, int]:
    """Mean, sample standard deviation (ddof 1; 0 for one value) and count."""
    std = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
    return float(np.mean(values)), std, len(values)


def percent(values: list[float]) -> str:
    """Fractions ``values`` as a report's percentage: ``mean ± std`` (the mean alone for one
    value), two decimals."""
    mean, std, n = mean_std([100 * v for v in values])
    return f"{mean:.2f} ± {std:.2f}" if n > 1 else f"{mean:.2f}"


def _num(value, fmt: str = "{:.3g}") -> str:
    return "–" if value is None else fmt.format(value)


def group_by(cells: list[dict], *keys: str) -> dict:
    """``cells`` by the values of ``keys``: {(value, ...): [cell, ...]}, in the cells' order."""
    groups = defaultdict(list)
    for c in cells:
        groups[tuple(c[k] for k in keys)].append(c)
    return groups


def _mean(cells: list[dict], get) -> float | None:
    values = [get(c) for c in cells]
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def paper_sized(cells: list[dict], paper: dict) -> bool:
    """Whether every cell's dataset has the paper's Sim LiDAR split sizes (3000 / 600): only
    then does the report set the paper's row beside the models' (on smaller splits every model
    scores lower, most at high noise)."""
    sizes = (paper["simlidar"]["train_size"], paper["simlidar"]["test_size"])
    return all((c["train_size"], c["test_size"]) == sizes for c in cells)


def _sizes(cells: list[dict]) -> str:
    return ", ".join(
        f"{a} / {b}" for a, b in sorted({(c["train_size"], c["test_size"]) for c in cells})
    )


def accuracy_by_noise(cells: list[dict], paper: dict) -> list[str]:
    """Generated datasets: accuracy (%) of each model at each noise level, and the paper's
    SNN: a row of the table where the splits have the paper's sizes, a note apart otherwise."""
    sim = [c for c in cells if c["source"] == GENERATOR]
    if not sim:
        return []
    levels = sorted({c["noise"] for c in sim})
    models = sorted({c["model"] for c in sim})
    by = group_by(sim, "model", "noise")
    classes = sorted({c["classes"] for c in sim})
    chance = " and ".join(f"{100 / k:.2f} % ({k} classes)" for k in classes)
    lines = [
        "## Sim LiDAR: accuracy (%) by noise level",
        "",
        "Mean ± sample standard deviation over seeds (number of seeds in brackets); "
        f"{_sizes(sim)} train / test samples a dataset; chance is {chance}.",
        "",
        "| model | " + " | ".join(f"noise {v:g}" for v in levels) + " |",
        "|---" * (len(levels) + 1) + "|",
    ]
    for m in models:
        row = [
            f"{percent([c['accuracy'] for c in by[m, v]])} ({len(by[m, v])}){_marks(by[m, v])}"
            if by[m, v]
            else "–"
            for v in levels
        ]
        lines.append(f"| {m} | " + " | ".join(row) + " |")
    reported = dict(zip(paper["simlidar"]["noise"], paper["simlidar"]["snn_accuracy"]))
    if paper_sized(sim, paper):
        row = [f"{reported[v]:.2f}" if v in reported else "–" for v in levels]
        lines.append("| *paper: SNN 256-400-32* | " + " | ".join(row) + " |")
    for mark, applies, note in MARKS:
        if any(applies(group) for group in by.values()):
            lines += ["", f"{mark} {note}"]
    if not paper_sized(sim, paper):
        sim_paper = paper["simlidar"]
        shown = [f"{reported[v]:.2f} % at noise {v:g}" for v in levels if v in reported]
        lines += [
            "",
            f"**Not comparable with the paper's figures.** These datasets hold {_sizes(sim)} "
            f"train / test samples, the paper's {sim_paper['train_size']} / "
            f"{sim_paper['test_size']}: with fewer training samples every model scores lower, "
            "most at high noise. Compare the rows above with each other. The paper's SNN "
            "256-400-32, on its own data: "
            + ("; ".join(shown) if shown else "no figure at these noise levels")
            + ". The paper's protocol is `simlidar bench --suite paper`.",
        ]
    return lines + [""]


def still_improving(cell: dict) -> bool:
    """Whether a cell ended on its epoch cap with its best validation epoch among the last
    ``patience``. Not for a cell without validation (never known), nor for one whose learning
    rate schedule anneals to 0 at the cap (cosine): its last epochs are the schedule's end."""
    patience = cell.get("inputs", {}).get("rules", {}).get("patience")
    if cell.get("stopped") != "epochs" or not cell.get("validation_size") or patience is None:
        return False
    if cell.get("lr_schedule") == "cosine":
        return False
    return cell["epochs_run"] - 1 - cell["best_epoch"] < patience


def _spread(cells: list[dict]) -> bool:
    """Whether a group of seeds' accuracies spread over more than SPREAD_POINTS."""
    return mean_std([100 * c["accuracy"] for c in cells])[1] > SPREAD_POINTS


CAPPED, OPEN, SPREAD = "†", "§", "‡"
SPREAD_POINTS = 2.0  # a sample standard deviation over seeds above this is marked
MARKS = (  # (mark, whether it applies to a group of cells, the note under the table)
    (
        CAPPED,
        lambda cells: any(c.get("stopped_by_time") for c in cells),
        "at least one seed stopped on the suite's time cap (`max_seconds`) before its epoch "
        "budget: a figure of the machine's speed and load, not of the model.",
    ),
    (
        OPEN,
        lambda cells: any(map(still_improving, cells)),
        "at least one seed ran to its epoch cap with its validation score (accuracy, then loss) "
        "still improving, its best epoch among the last `patience`: not converged by the suite's "
        "rule (at a validation accuracy of 100 % only the loss was still falling). A cosine "
        "schedule, which anneals the rate to 0 at the cap, is not marked: its last epochs are the "
        "schedule's end.",
    ),
    (
        SPREAD,
        _spread,
        f"the seeds disagree by more than {SPREAD_POINTS:g} points (sample standard deviation): "
        "the mean says less than its digits suggest; see the training table below (epochs, "
        "stops) for where the seeds went apart.",
    ),
)


def _marks(cells: list[dict], which: tuple = MARKS) -> str:
    """The marks of ``which`` that apply to a group of cells, each after a space."""
    return "".join(f" {mark}" for mark, applies, _ in which if applies(cells))


def training_table(cells: list[dict]) -> list[str]:
    """Per model: how training ended (model selection, docs/benchmark.md) and how long it took."""
    if not cells:
        return []
    lines = [
        "## Training: selection, stops and time per model",
        "",
        "Over every cell of the model (all datasets and seeds). Epochs are counted from 1; "
        "the kept epoch is the one with the best validation accuracy under a constant learning "
        "rate, the last under a cosine schedule or without validation samples "
        '(docs/benchmark.md, "Training and model selection").',
        "",
        "| model | cells | epoch budget | epochs run | kept epoch (median) | stopped: "
        "plateau / epoch cap / time cap | still improving at the cap | validation samples "
        "| minutes a cell (mean, max) | minutes in all |",
        "|---" * 10 + "|",
    ]
    for (model,), runs in sorted(group_by(cells, "model").items()):
        stops = [c.get("stopped", "time" if c.get("stopped_by_time") else "epochs") for c in runs]
        budget = sorted({str(c.get("budget", {}).get("epochs", "recipe")) for c in runs})
        run = [c["epochs"] for c in runs]
        kept = [c["best_epoch"] + 1 for c in runs if c.get("best_epoch") is not None]
        minutes = [c["seconds"] / 60 for c in runs]
        held = sorted({c.get("validation_size", 0) for c in runs})
        lines.append(
            f"| {model} | {len(runs)} | {', '.join(budget)} | {min(run)}–{max(run)} | "
            f"{_num(float(np.median(kept)) if kept else None, '{:.0f}')} | "
            f"{stops.count('plateau')} / {stops.count('epochs')} / {stops.count('time')} | "
            f"{sum(map(still_improving, runs))} | {', '.join(map(str, held))} | "
            f"{np.mean(minutes):.1f}, {max(minutes):.1f} | {sum(minutes):.0f} |"
        )
    return lines + [""]


def by_model(cells: list[dict], paper: dict) -> list[str]:
    """Per dataset: accuracy, decision time, data ratio, energy, latency, size by model."""
    lines = []
    kitti = paper["kitti"]["accuracy"]
    for (dataset,), group in sorted(group_by(cells, "dataset").items()):
        source = group[0]["source"]
        lines += [
            f"## {dataset}",
            "",
            f"{group[0]['train_size']} train / {group[0]['test_size']} test samples, "
            f"input {' x '.join(map(str, group[0]['input_shape']))}, "
            f"{group[0]['classes']} classes, noise {group[0]['noise']:g}.",
            "",
            "| model | accuracy % | decision ns | input spikes used | R_data | "
            f"hidden spikes | energy pJ ({' / '.join(f'{a:g}' for a in ALPHAS_PJ)} pJ/spike; "
            f"{MAC_PJ:g} pJ/MAC) | MACs | "
            "latency ms | samples/s | params | footprint MB | epochs |",
            "|---" * 13 + "|",
        ]
        for (model,), runs in sorted(group_by(group, "model").items()):
            early = [c for c in runs if c.get("early")]
            if early:

                def e(key, early=early):
                    return _mean(early, lambda cell, key=key: cell["early"][key])

                pj = [
                    _mean(early, lambda c, a=a: c["early"]["energy_pj_mean"][str(a)])
                    for a in ALPHAS_PJ
                ]
                energy = " / ".join(f"{v:.3g}" for v in pj)
                spikes = f"{e('input_spikes_mean'):.1f} of {e('input_spikes_total_mean'):.1f}"
                timing = [
                    _num(e("decision_time_ns_mean"), "{:.0f}"),
                    spikes,
                    _num(e("data_ratio_mean"), "{:.3f}"),
                    _num(e("hidden_spikes_mean"), "{:.1f}"),
                    energy,
                    "–",
                ]
            elif any(c.get("stepped") for c in runs):
                timing = _stepped_columns([c for c in runs if c.get("stepped")])
            elif runs[0]["kind"] == "conventional":
                energy = _num(_mean(runs, lambda c: c["energy_pj_mac"]), "{:.3g}")
                timing = [
                    "–",
                    "–",
                    "–",
                    "–",
                    energy,
                    _num(_mean(runs, lambda c: c["macs"]), "{:.3g}"),
                ]
            else:
                timing = ["–"] * 6  # a spiking CNN: no event-driven evaluator yet
            capped = _marks(runs, MARKS[:1])  # the epochs column: the time cap only
            lines.append(
                f"| {model} | {percent([c['accuracy'] for c in runs])} | "
                + " | ".join(timing)
                + f" | {_mean(runs, lambda c: c['latency_ms']):.3f}"
                f" | {_mean(runs, lambda c: c['throughput_per_s']):.0f}"
                f" | {runs[0]['params']:,} | {runs[0]['footprint'] / 1e6:.2f}"
                f" | {_num(_mean(runs, lambda c: c['epochs']), '{:.0f}')}{capped} |"
            )
        if source == "kitti":
            lines += [
                "",
                f"The paper on KITTI ({paper['kitti']['train_size']:,} / "
                f"{paper['kitti']['test_size']:,} crops): "
                + ", ".join(f"{k} {v:.2f} %" for k, v in kitti.items())
                + f"; the SCNN used "
                f"{paper['kitti']['data_ratio_scnn']:.0%} of the input spikes.",
            ]
        lines.append("")
    return lines


def _stepped_columns(runs: list[dict]) -> list[str]:
    """The decision columns of a time-stepped network (simlidar.bench.stepped): the decision
    step of T by its readout, input spikes delivered by then, R_data, its neurons' spikes and
    the paper's spike energy."""

    def s(key):
        return _mean(runs, lambda cell: cell["stepped"][key])

    step = (
        s("decision_step_mean") if all(c["stepped"]["decision_step_mean"] for c in runs) else None
    )
    pj = [_mean(runs, lambda c, a=a: c["stepped"]["energy_pj_mean"][str(a)]) for a in ALPHAS_PJ]
    return [
        f"step {step:.1f} of {runs[0]['stepped']['steps']} ({runs[0]['stepped']['readout']})"
        if step is not None
        else "–",
        f"{s('input_spikes_mean'):.1f} of {s('input_spikes_total_mean'):.1f}",
        _num(s("data_ratio_mean"), "{:.3f}"),
        _num(s("neuron_spikes_mean"), "{:.1f}"),
        " / ".join(f"{v:.3g}" for v in pj),
        "–",
    ]
