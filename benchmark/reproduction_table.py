"""The reproduction table: each claim of Wang et al. (IJCAI 2020) beside what the committed
results under benchmark/results/ give, with a verdict by fixed rules.

    python benchmark/reproduction_table.py                    # print the table
    python benchmark/reproduction_table.py --check README.md  # exit 1 if README's table differs
    python benchmark/reproduction_table.py --write README.md  # replace README's table

The paper's figures come from ``baselines/reported/wang2020.toml``; ours from the committed
cells (one JSON file a training seed) and the early-information estimate's runs (its folder
``bound/``, the older name), read by the functions below, never typed in. "Ours" is the mean
over training seeds with the 95 % interval of the mean (Student's t, ``paper_table.interval``);
where a committed figure has no per-seed values (an ensemble, one seed) the cell says so. The
verdict comes from :func:`verdict`'s rules. In FILE the table sits between the lines
``<!-- reproduction-table:start -->`` and ``<!-- reproduction-table:end -->``.
"""

import argparse
import json
import sys
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paper_table import ROOT, interval

from simlidar.errors import ResultsError
from simlidar.script_args import run

RESULTS = ROOT / "benchmark" / "results"
PAPER_FILE = ROOT / "baselines" / "reported" / "wang2020.toml"
START = "<!-- reproduction-table:start -->"
END = "<!-- reproduction-table:end -->"
COMMAND = "python benchmark/reproduction_table.py"  # the README says how to run it again
TOLERANCE_POINTS = 1.0  # an accuracy this close to the paper's, by its mean, is "within 1 point"
PAPER_TABLE = "simlidar-32c-noise{noise:g}-paper-v2.0.0"  # the committed cells' dataset names
CROPS = "kitti-front-50x118-sim-v1.0.0"  # the simulated HDL-64E crops of early-objectives-crops
# how the table names the paper's data and models (keys of wang2020.toml)
NAMES = {"kitti": "KITTI", "dvs_barrel": "DVS barrel", "snn": "SNN", "cnn": "CNN",
         "vgg16": "VGG-16", "resnet50": "ResNet-50"}  # fmt: skip
# a unit: (its suffix, decimals of a value, what a difference is counted in)
UNITS = {"%": (" %", 2, "points"), "spikes": ("", 0, "input spikes"), "ns": (" ns", 0, "ns")}


@dataclass(frozen=True)
class Measured:
    """Our figure for a claim, as the committed files hold it."""

    values: tuple[float, ...]  # one a training seed; one value where there are no seeds to average
    unit: str  # a key of UNITS
    seeds: int  # training seeds behind the figure (an ensemble's learners too)
    alone: str = ""  # why one value has no interval ("an ensemble of 5 learner seeds")
    note: str = ""  # what else the cell says ("median 250 of 256")


@dataclass(frozen=True)
class Claim:
    """One claim of the paper: its words, its figure (low, high; one figure twice), how ours is
    read from the committed results, the doc that explains the difference."""

    text: str
    paper: tuple[float, float]
    paper_text: str
    measure: Callable[[dict], Measured]  # the paper's numbers (wang2020.toml) -> ours
    doc: str
    other_measure: str = ""  # not comparable: why ours measures something else


def read_json(path: Path) -> dict:
    """A committed result file; a ResultsError names a missing or unreadable one."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ResultsError(f"{path}: expected a committed result file (JSON): {exc}") from None


def cells(folder: str, dataset: str, recipe: str) -> list[dict]:
    """The committed cells ``<folder>/cells/<dataset>__<recipe>__seed*.json``, by seed."""
    paths = sorted((RESULTS / folder / "cells").glob(f"{dataset}__{recipe}__seed*.json"))
    if not paths:
        raise ResultsError(
            f"{RESULTS / folder / 'cells'}: expected cells {dataset}__{recipe}__seed*.json"
        )
    return sorted((read_json(p) for p in paths), key=lambda c: c["seed"])


def accuracy(recipe: str, noise: float) -> Callable[[dict], Measured]:
    """The paper-table cells' test accuracy of ``recipe`` at ``noise``, one value a seed."""

    def measure(_paper: dict) -> Measured:
        found = cells("paper-table", PAPER_TABLE.format(noise=noise), recipe)
        return Measured(tuple(100 * c["test_accuracy"] for c in found), "%", len(found))

    return measure


def fewest_spikes(noise: float) -> Callable[[dict], Measured]:
    """The fewest input spikes any test decision of a seed consumed (the paper: "as few as"),
    one value a seed; the median over every decision of every seed beside it."""

    def measure(_paper: dict) -> Measured:
        found = cells("paper-table", PAPER_TABLE.format(noise=noise), "snn_simlidar_tuned")
        every = np.concatenate([c["input_spikes"] for c in found])
        total = max(c["early"]["input_spikes_total_mean"] for c in found)
        return Measured(
            tuple(float(min(c["input_spikes"])) for c in found),
            "spikes",
            len(found),
            note=f"the fewest before a decision (median {np.median(every):.0f} of {total:.0f})",
        )

    return measure


def decision_time(noise: float) -> Callable[[dict], Measured]:
    """The mean decision time after the pulses left, in sensor time (ns), one value a seed."""

    def measure(_paper: dict) -> Measured:
        found = cells("paper-table", PAPER_TABLE.format(noise=noise), "snn_simlidar_tuned")
        times = tuple(c["early"]["decision_time_ns_mean"] for c in found)
        return Measured(times, "ns", len(found), note="after the pulses left")

    return measure


def bound_after(noise: float) -> Callable[[dict], Measured]:
    """The early-information estimate with what has arrived by the paper's fewest spikes (its
    "as few as 13-16": the 16th), the better of the two encodings (bound/runs): the best
    learner tried, not a bound (docs/paper-table.md)."""

    def measure(paper: dict) -> Measured:
        k = paper["simlidar"]["input_spikes"][1]
        best = None
        for encoding, words in (("far_first", "far returns first"), ("near_first", "near first")):
            name = f"{PAPER_TABLE.format(noise=noise)}__{encoding}-as_value.json"
            run_ = read_json(RESULTS / "bound" / "runs" / name)
            row = next((r for r in run_["rows"] if r.get("k") == k), None)
            if row is None:
                raise ResultsError(f"{name}: expected an estimate's row at k = {k}")
            if best is None or row["accuracy_mean"] > best[0]["accuracy_mean"]:
                best = row, words, len(run_["seeds"])
        row, words, seeds = best
        note = f"the early-information estimate (the best learner tried) given the first {k} "
        note += f"spikes, {words}"
        if row["best"].endswith("/ensemble"):  # one value: the learners' averaged answers
            alone = f"an ensemble of {seeds} learner seeds"
            return Measured((100 * row["accuracy_mean"],), "%", seeds, alone, note)
        return Measured(tuple(100 * a for a in row["accuracy"]), "%", seeds, note=note)

    return measure


def crops_accuracy(paper: dict) -> Measured:
    """The spiking CNN (``scnn_kitti``, trained for accuracy alone) on the simulated crops."""
    found = cells("early-objectives-crops", CROPS, "crops-near-e10")
    share = np.mean([c["early"]["data_ratio_mean"] for c in found])
    return Measured(
        tuple(100 * c["test_accuracy"] for c in found),
        "%",
        len(found),
        alone="one seed" if len(found) == 1 else "",
        note=f"after {100 * share:.0f} % of its input spikes",
    )


def claims(paper: dict) -> list[Claim]:
    """Every claim of the paper that we measured, in the table's order."""
    sim, kitti = paper["simlidar"], paper["kitti"]
    why = "docs/paper-table.md#every-difference-and-why"
    rows = [
        Claim(f"Sim LiDAR accuracy, noise {n:.2f} (our training)", (a, a), f"{a:.2f} %",
              accuracy("snn_simlidar_tuned", n), why)
        for n, a in zip(sim["noise"], sim["snn_accuracy"])
    ]  # fmt: skip
    rows += [
        Claim(f"Sim LiDAR accuracy, noise {n:.2f} (the paper's SGD recipe, 60 epochs)", (a, a),
              f"{a:.2f} %", accuracy("snn_simlidar-e60", n), "docs/paper-table.md#the-table")
        for n, a in zip(sim["noise"], sim["snn_accuracy"])
    ]  # fmt: skip
    low, high = sim["input_spikes"]
    first = sim["noise"][0]
    span_ms = "{:.2f}-{:.2f} ms".format(*sim["decision_time_ms"])
    rows += [
        Claim(
            f"decides after as few as {low}-{high} input spikes (noise {first:.2f})",
            (low, high),
            f"{low}-{high} of 256",
            fewest_spikes(first),
            "docs/paper-table.md#early-decisions-against-the-papers-claim",
        ),
        Claim(
            f"its accuracy after as few as {high} input spikes (noise {first:.2f})",
            (sim["snn_accuracy"][0],) * 2,
            f"{sim['snn_accuracy'][0]:.2f} %",
            bound_after(first),
            "docs/paper-table.md#how-early-a-decision-can-be-right",
        ),
        Claim(
            f"decides within {span_ms} (noise {first:.2f})",
            tuple(1e6 * t for t in sim["decision_time_ms"]),
            span_ms,
            decision_time(first),
            "docs/paper-table.md#what-fast-can-mean-for-a-real-sensor",
            other_measure="the paper's is its network's simulated time; ours the sensor's",
        ),
        Claim(
            "KITTI: spiking CNN accuracy",
            (kitti["accuracy"]["scnn"],) * 2,
            f"{kitti['accuracy']['scnn']:.2f} % after {100 * kitti['data_ratio_scnn']:.0f} % "
            "of its input spikes",
            crops_accuracy,
            "docs/paper-table.md#the-spiking-cnn-on-simulated-crops",
            other_measure="simulated HDL-64E crops of 3 object classes, not recorded KITTI",
        ),
    ]
    return rows


def verdict(paper: tuple[float, float], values, unit: str, other_measure: str = "") -> str:
    """The verdict on one claim, by these rules in this order:

    1. ours measures something else (``other_measure``): "not comparable: <why>";
    2. the 95 % interval of our mean (one value: the value) meets the paper's figure or range:
       "reproduced";
    3. an accuracy (``unit`` "%") whose mean is within TOLERANCE_POINTS of the paper's:
       "within 1 point";
    4. otherwise "not reproduced: <distance> <unit> above|below", the mean's distance from the
       paper's figure or range.
    """
    if other_measure:
        return f"not comparable: {other_measure}"
    values = np.asarray(values, dtype=float)
    low, high = paper
    mean = float(values.mean())
    span = interval(values) or [mean, mean]
    if span[0] <= high and span[1] >= low:
        return "reproduced"
    distance = low - mean if mean < low else mean - high
    if unit == "%" and distance <= TOLERANCE_POINTS:
        return f"within {TOLERANCE_POINTS:g} point"
    _, decimals, counted = UNITS[unit]
    side = "below" if mean < low else "above"
    return f"not reproduced: {distance:.{max(decimals - 1, 0)}f} {counted} {side}"


def ours(measured: Measured) -> str:
    """A table cell: the mean, its 95 % interval or why there is none, and the note."""
    suffix, decimals, _ = UNITS[measured.unit]
    values = np.asarray(measured.values, dtype=float)
    text = f"{values.mean():.{decimals}f}{suffix}"
    span = interval(values)
    if span:
        text += f" [{span[0]:.{decimals}f}, {span[1]:.{decimals}f}]"
    else:
        text += f" (no interval: {measured.alone or 'one value'})"
    return f"{text}, {measured.note}" if measured.note else text


def unmeasured(paper: dict) -> list[str]:
    """The paper's accuracies that no row holds: every model of [<data>.accuracy] but KITTI's
    spiking CNN (rows above)."""
    return [
        f"{NAMES.get(data, data)} {NAMES.get(model, model)} {figure:.2f} %"
        for data in sorted(paper)
        if isinstance(paper[data], dict) and "accuracy" in paper[data]
        for model, figure in paper[data]["accuracy"].items()
        if (data, model) != ("kitti", "scnn")
    ]


def table(paper: dict) -> str:
    """The Markdown that sits between START and END."""
    lines = [
        "Every claim of Wang et al. (IJCAI 2020) that we measured, beside our figure on the "
        "data rebuilt here: the mean over training seeds [its 95 % interval, Student's t], from "
        f"the committed results under `benchmark/results/`. Written by `{COMMAND} --write "
        "README.md`; a test checks that it is what those files give.",
        "",
        "| claim of the paper | paper | ours | seeds | verdict | why |",
        "| --- | ---: | --- | ---: | --- | --- |",
    ]
    for claim in claims(paper):
        measured = claim.measure(paper)
        ruled = verdict(claim.paper, measured.values, measured.unit, claim.other_measure)
        lines.append(
            f"| {claim.text} | {claim.paper_text} | {ours(measured)} | {measured.seeds} | "
            f"{ruled} | [{claim.doc.split('#')[0].split('/')[-1]}]({claim.doc}) |"
        )
    lines += [
        "",
        "Simulated data rebuilt from the paper's description: its generator was never "
        "published. Not measured here (recorded data): " + "; ".join(unmeasured(paper)) + ".",
    ]
    return "\n".join(lines)


def paper_numbers() -> dict:
    """What the paper reported (``baselines/reported/wang2020.toml``)."""
    try:
        return tomllib.loads(PAPER_FILE.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ResultsError(f"{PAPER_FILE}: expected the paper's numbers (TOML): {exc}") from None


def split(text: str, path: Path, start: str = START, end: str = END) -> tuple[str, str, str]:
    """``text`` cut around its table: (before ``start``'s line, the table, from ``end``'s line
    on); other generated blocks of a page have markers of their own (benchmark/weather.py)."""
    lines = text.split("\n")
    starts = [i for i, line in enumerate(lines) if line.strip() == start]
    ends = [i for i, line in enumerate(lines) if line.strip() == end]
    if len(starts) != 1 or len(ends) != 1 or ends[0] < starts[0]:
        raise ResultsError(f"{path}: expected one line {start} and, after it, one line {end}")
    (i,), (j,) = starts, ends
    before = "\n".join(lines[: i + 1]) + "\n"
    return before, "\n".join(lines[i + 1 : j]).strip("\n"), "\n" + "\n".join(lines[j:])


def markdown_file(text: str) -> Path:
    """An argparse type: an existing file to read (and, with --write, replace)."""
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r}: expected an existing file")
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="Without --check or --write the table is printed.",
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--check",
        type=markdown_file,
        metavar="FILE",
        help="exit 1, in one line, when FILE's table differs from what the results give",
    )
    mode.add_argument(
        "--write",
        type=markdown_file,
        metavar="FILE",
        help="replace FILE's table (between its two marker lines) with what the results give",
    )
    args = parser.parse_args(argv)
    made = table(paper_numbers())
    path = args.check or args.write
    if path is None:
        print(made)
        return 0
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ResultsError(f"{path}: expected a Markdown file to read: {exc}") from None
    before, found, after = split(text, path)
    if found == made:
        print(f"{path}: the reproduction table is what the committed results give")
        return 0
    if args.check:
        old, new = found.split("\n"), made.split("\n")
        line = next(
            (i for i, (a, b) in enumerate(zip(old, new)) if a != b), min(len(old), len(new))
        )
        print(
            f"error: {path}: the reproduction table differs from what the committed results "
            f"give (its line {line + 1} after {START}); run {COMMAND} --write {path}",
            file=sys.stderr,
        )
        return 1
    from simlidar.atomic import write_file

    write_file(path, lambda temporary: temporary.write_text(before + made + after))
    print(f"{path}: wrote the reproduction table")
    return 0


if __name__ == "__main__":
    run(main)
