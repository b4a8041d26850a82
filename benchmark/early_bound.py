"""The early-information estimate: how early a decision can be right, per dataset and encoding.

    python -m simlidar.cli generate --profile paper --noise 0.1,0.2 --train-size 3000 \\
        --test-size 600 --seed 0 --out /tmp/data
    python benchmark/early_bound.py /tmp/data/simlidar-32c-noise0.1-paper-v2.0.0 \\
        --encodings near_first/as_value,far_first/as_value --seeds 0,1,2

For each dataset and encoding (``direction/missing``, :func:`simlidar.models.ttfs.encode`),
:func:`simlidar.bench.bound.dataset_bound` trains the learner on what has arrived by the k-th
input spike, k in ``--ks`` and each sample's own count, for every seed: the best accuracy of
the learners tried, an estimate of what the data allow, not a bound (a stronger learner can beat
it; docs/paper-table.md, "How early a decision can be right"; the folders, files and JSON keys
keep the older name "bound"). Each (dataset,
encoding) is a JSON file under ``--out``/runs (a rerun skips the ones present, or adds to a
run of several families those of ``--learners`` it lacks, at its own seeds, k and columns:
``--learners mlp,wide,cnn`` adds the CNN; given more ``--seeds`` than a run of several
families has, including all of its own, it trains that run again with them, at its k and
columns, and refuses before writing if a seed it had scores otherwise: ``--seeds 0,1,2,3,4``
takes a 3-seed run to 5); then
``bound.json`` (every run), ``bound.md`` (a table) and ``bound.png`` (accuracy against input
spikes consumed, one curve per dataset and encoding, seed spread as error bars, with the
committed ``snn_simlidar_tuned`` cells of benchmark/results/paper and /physical as points: their
median input spikes consumed and accuracy) are written from every run under ``--out``.
"""

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from simlidar.bench.bound import LEARNERS
from simlidar.bench.hardware import MAX_THREADS, check_threads
from simlidar.models import ttfs
from simlidar.script_args import choices, integers, run

ROOT = Path(__file__).resolve().parents[1]
SUITE_CELLS = [ROOT / f"benchmark/results/{suite}/cells" for suite in ("paper", "physical")]


# the learner's widest hidden layer: 16 times the published 256 (a 4096 x 4096 layer is 64 MiB)
MAX_HIDDEN = 4096
# the view has an arrived channel of its own: a missing return's channel is not an encoding here
ENCODINGS = tuple(
    f"{d}/{m}" for d in ttfs.DIRECTIONS for m in ttfs.MISSING if m != ttfs.OWN_CHANNEL
)
LEARNER_CHOICES = (*LEARNERS, "published")  # the families, or the runs before issue 42


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("datasets", nargs="*", type=Path, help="dataset directories")
    parser.add_argument(
        "--encodings", type=choices(ENCODINGS), default="near_first/as_value,far_first/as_value"
    )
    parser.add_argument("--ks", type=integers(1), default="4,8,16,32,64,128,180,256")
    parser.add_argument("--seeds", type=integers(0, 2**32 - 1), default="0,1,2")
    parser.add_argument(
        "--columns",
        type=integers(1),
        default=None,
        help="scan-timed data on the sensor's clock: also the estimate once the sweep's first C "
        "firings are back, for each C (simlidar.bench.bound.bound's columns; the rows that "
        "benchmark/sweep_decisions.py reads)",
    )
    parser.add_argument(
        "--hidden",
        type=integers(1, MAX_HIDDEN),
        default="256,256",
        help="the learner's hidden layers",
    )
    parser.add_argument(
        "--clock",
        choices=("sensor", "arrival"),
        default="sensor",
        help="scan-timed data: the learner reads each pixel's time of flight by the sensor's "
        "firing clock (sensor) or the arrival times as they are (arrival)",
    )
    parser.add_argument(
        "--learners",
        type=choices(LEARNER_CHOICES),
        default="mlp,wide,cnn",
        help="the learner families whose best each row gives, trained with the networks' "
        "advantages (fresh noise every epoch, every training row; each also as its seeds' "
        "ensemble: simlidar.bench.bound.LEARNERS), or 'published': the one MLP of --hidden on "
        "the file's noise draw, as the runs before issue 42",
    )
    parser.add_argument(
        "--per-sample",
        action="store_true",
        help="also the per-sample form: one learner (wide) for views at any k, asked about "
        "each test sample at every k (simlidar.bench.bound.per_sample)",
    )
    parser.add_argument("--threads", type=integers(1, MAX_THREADS, one=True), default=1)
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("early-bound"),
        help="results folder (default: ./early-bound; the published runs name "
        "benchmark/results/early-bound*)",
    )
    args = parser.parse_args(argv)
    if not args.datasets and not any((args.out / "runs").glob("*.json")):
        parser.error(f"no datasets given and no runs under {args.out / 'runs'} to report")

    import torch

    from simlidar.bench.bound import BoundConfig, dataset_bound, with_families
    from simlidar.dataset.loaders import split_info

    check_threads(args.threads)
    for dataset in args.datasets:  # each one a dataset, before anything is written
        attrs = split_info(dataset, "train").attrs
        split_info(dataset, "test")
        if args.columns and (attrs.get("timing") != "scan" or args.clock != "sensor"):
            parser.error(
                f"--columns with {dataset.name}: expected a scan-timed dataset read by the "
                "sensor's clock"
            )
        if args.columns and max(args.columns) > attrs["config"]["width"]:
            parser.error(
                f"--columns {max(args.columns)}: expected at most the width of "
                f"{dataset.name} ({attrs['config']['width']} columns)"
            )
    torch.set_num_threads(args.threads)
    config = replace(BoundConfig(), hidden=args.hidden)
    options = {"config": config}
    if "published" in args.learners:
        if len(args.learners) > 1:
            parser.error("--learners published: expected it alone (the runs before issue 42)")
    else:
        options["learners"] = {name: LEARNERS[name] for name in args.learners}
    if args.per_sample:
        options["per_sample"] = LEARNERS["wide"]
    if args.columns:
        options["columns"] = args.columns
    runs = args.out / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    for dataset in args.datasets:
        for encoding in args.encodings:
            direction, missing = encoding.split("/")
            scan = "-scan-" in dataset.name
            clock = f"-{args.clock}-clock" if scan and args.clock == "sensor" else ""
            path = runs / f"{dataset.name}__{direction}-{missing}{clock}.json"
            start = time.perf_counter()
            if path.exists():
                present = json.loads(path.read_text())
                lacking = [n for n in options.get("learners", {}) if n not in present["learner"]]
                more = of_families(present) and set(args.seeds) > set(present["seeds"])
                if not more and (not of_families(present) or not lacking):
                    print(f"{path.name}: present, skipped")
                    continue
                kept = ("per_sample", "learners", "columns")  # set below, from the present run
                again = {k: v for k, v in options.items() if k not in kept}
                if more:  # every seed again: an ensemble needs the scores, which runs do not keep
                    print(f"{path.name}: present with seeds {present['seeds']}, trained again "
                          f"with seeds {list(args.seeds)}")  # fmt: skip
                    seeds, families = args.seeds, [*present["learner"], *lacking]
                    if "per_sample" in present:
                        again["per_sample"] = LEARNERS["wide"]
                else:
                    print(f"{path.name}: present, adding the families {lacking}")
                    seeds, families = present["seeds"], lacking
                result = dataset_bound(
                    dataset,
                    direction,
                    missing,
                    args.clock,
                    ks=[row["k"] for row in present["rows"] if row["k"] is not None],
                    seeds=seeds,
                    **again,
                    learners={n: LEARNERS[n] for n in families},
                    columns=[row["columns"] for row in present.get("column_rows", [])],
                )
                if more:
                    reproduced(present, result, path.name)
                else:  # the present run's per-sample form stays
                    result = with_families(present, result)
                seconds = present["seconds"] + time.perf_counter() - start
            else:
                result = dataset_bound(
                    dataset, direction, missing, args.clock, ks=args.ks, seeds=args.seeds,
                    **options,
                )  # fmt: skip
                seconds = time.perf_counter() - start
            result.update(dataset=dataset.name, seconds=seconds)
            path.write_text(json.dumps(result, indent=1) + "\n")
            print(f"{path.name}: {result['seconds']:.0f} s")
            for row in result["rows"]:
                print(
                    f"  k={row['k']}: {row['input_spikes_median']:.0f} spikes (median), "
                    f"accuracy {row['accuracy_mean']:.3f} +- {row['accuracy_std']:.3f} "
                    f"{row.get('best', '')}"
                )
            for row in result.get("column_rows", []):
                print(
                    f"  {row['columns']} columns, {row['time_us_median']:.0f} us: accuracy "
                    f"{row['accuracy_mean']:.3f} {row.get('best', '')}"
                )
    report(args.out)
    return 0


def reproduced(present: dict, result: dict, name: str) -> None:
    """Refuse, in one line and before anything is written, a run with more seeds whose seeds
    in common with the ``present`` run do not score as they did there, in every row and
    family (the learners are seeded: the same seed is the same learner)."""
    from simlidar.errors import ConfigError

    index = {seed: i for i, seed in enumerate(result["seeds"])}
    for key in ("rows", "column_rows"):
        for old, new in zip(present.get(key, []), result.get(key, [])):
            where = f"k = {old['k']}" if key == "rows" else f"columns = {old['columns']}"
            for family, found in old["learners"].items():
                again = [new["learners"][family]["accuracy"][index[s]] for s in present["seeds"]]
                if again != found["accuracy"]:
                    raise ConfigError(
                        f"{name}: seeds {present['seeds']} of {family} at {where} "
                        f"scored {found['accuracy']}, now {again}: expected the present run's "
                        "figures again; nothing written"
                    )


def of_families(run: dict) -> bool:
    """Whether a run is of several learner families (issue 42: ``learner`` maps each family to
    its configuration), not the one MLP of the runs before (``learner`` that configuration)."""
    learner = run["learner"]
    return isinstance(learner, dict) and all(isinstance(c, dict) for c in learner.values())


def _encoding(run: dict) -> str:
    """direction / missing, and a scan-timed run's clock (runs made before the clock was a
    choice read the arrival times)."""
    enc = run["encoding"]
    scan = "-scan-" in run["dataset"]
    clock = f", {enc.get('clock', 'arrival')} clock" if scan else ""
    return f"{enc['direction']} / {enc['missing']}{clock}"


def snn_points() -> list[dict]:
    """The committed snn_simlidar_tuned cells: dataset, seed, accuracy, input spikes."""
    points = []
    paths = [p for cells in SUITE_CELLS for p in cells.glob("*__snn_simlidar_tuned__seed*.json")]
    for path in sorted(paths):
        cell = json.loads(path.read_text())
        spikes = cell["per_sample"]["input_spikes"]
        points.append(
            {
                "dataset": cell["dataset"],
                "seed": cell["seed"],
                "accuracy": cell["early"]["accuracy"],
                "input_spikes_median": float(np.median(spikes)),
                "input_spikes_mean": cell["early"]["input_spikes_mean"],
            }
        )
    return points


# the committed cells of spiking networks trained by the benchmark scripts (their own layout)
SCRIPT_CELLS = [ROOT / f"benchmark/results/{name}/cells" for name in
                ("early-objectives", "early-tradeoff", "paper-table")]  # fmt: skip


def network_cells() -> list[dict]:
    """Every committed spiking-network cell (the benchmark scripts' and the suites'
    ``snn_*`` cells): source folder, variant, dataset, seed, the encoding it read
    (``direction``, ``missing``), its gate (``input_budget``, or None), its accuracy by the
    event-driven run, and the input spikes it consumed before each test decision."""
    cells = []
    for folder in SCRIPT_CELLS:
        for path in sorted(folder.glob("*.json")):
            cell = json.loads(path.read_text())
            architecture = cell.get("architecture") or {}
            cells.append(
                {
                    "source": folder.parent.name,
                    "variant": path.stem.split("__")[1],
                    "dataset": cell["dataset"],
                    "seed": cell["seed"],
                    "direction": architecture.get("direction", "near_first"),
                    "missing": architecture.get("missing", "as_value"),
                    "gate": architecture.get("input_budget"),
                    "accuracy": cell["early"]["accuracy"],
                    "spikes": cell["input_spikes"],
                }
            )
    for folder in SUITE_CELLS:
        for path in sorted(folder.glob("*__snn_*__seed*.json")):
            cell = json.loads(path.read_text())
            cells.append(
                {
                    "source": folder.parent.name,
                    "variant": cell["model"],
                    "dataset": cell["dataset"],
                    "seed": cell["seed"],
                    "direction": "near_first",  # the shipped recipes' encoding
                    "missing": "as_value",
                    "gate": None,
                    "accuracy": cell["early"]["accuracy"],
                    "spikes": cell["per_sample"]["input_spikes"],
                }
            )
    return cells


def cell_bounds(results: list[dict], cells: list[dict]) -> list[dict]:
    """Each cell beside the estimate of its dataset and encoding, where a run of several
    learners on a test split of the cell's size has one: behind a gate of k the row at k (the
    network read at most k spikes); otherwise the per-sample form at the cell's own decision
    counts (the better of the seeds' mean and their ensemble) and the looser rounded-up form,
    and the larger of the two, under the key ``bound`` (the older name, kept). ``ensemble``:
    the estimate's best seed ensemble there (a learner with a right or wrong on each test
    sample, which a seed mean is not; None where the run keeps none), ``samples`` the test
    split's size."""
    from simlidar.bench.bound import per_sample_accuracy, rounded_up_accuracy, test_samples

    runs = {
        (r["dataset"], r["encoding"]["direction"], r["encoding"]["missing"]): r
        for r in results
        if of_families(r) and "clock" not in r["encoding"]
    }
    found = []
    for cell in cells:
        run = runs.get((cell["dataset"], cell["direction"], cell["missing"]))
        if run is None or test_samples(run) != len(cell["spikes"]):
            continue  # none, or a dataset of the same name and another size (a user's own)
        entry = {**{k: v for k, v in cell.items() if k != "spikes"}}
        entry["samples"] = len(cell["spikes"])
        if cell["gate"] is not None:
            row = next((r for r in run["rows"] if r["k"] == cell["gate"]), None)
            if row is None:
                continue
            ensemble = max(f["ensemble"] for f in row["learners"].values())
            entry.update(form="at the gate's k", bound=row["accuracy_mean"], ensemble=ensemble)
        else:
            form = run.get("per_sample")
            exact = ensemble = None
            if form is not None:
                seeds = [per_sample_accuracy(form, cell["spikes"], str(s)) for s in form["seeds"]]
                ensemble = per_sample_accuracy(form, cell["spikes"], "ensemble")
                exact = max(float(np.mean(seeds)), ensemble)
            rounded = rounded_up_accuracy(run, cell["spikes"])
            entry.update(
                form="per sample",
                per_sample=exact,
                rounded_up=rounded,
                bound=max(rounded, exact if exact is not None else 0.0),
                ensemble=ensemble,
            )
        found.append(entry)
    return found


def above_the_bound(found: list[dict]) -> list[dict]:
    """The cells of :func:`cell_bounds` (or any entries with its keys: ``source``, ``variant``,
    ``dataset``, ``accuracy``, ``bound``: the estimate, ``ensemble``, ``samples``) that score
    above their estimate, each with what its lead can mean on its test split: ``lead`` in test
    samples over the estimate's best seed ensemble there (the learner that has a right or wrong
    on every sample); ``mcnemar_p_min``, the smallest two-sided exact McNemar p-value any
    pattern of right and wrong gives that lead (the network alone right on ``lead`` samples and
    the ensemble alone right on none: 2 ** (1 - lead), 1 for a lead of one sample or none; above
    0.05 up to a lead of 5, so such a lead is within the test split's sampling whichever samples
    it is made of); ``mcnemar_p_max``, the largest (:func:`mcnemar_p_max`: the two disagreeing
    on as many samples as their counts allow); and the mean over its variant's seeds
    (``seeds_mean``), which the estimate may still hold. Where ``mcnemar_p_min`` is at most
    0.05 and ``mcnemar_p_max`` above, whether the lead is beyond the test split's sampling
    depends on which samples make it: only the cell's right or wrong on each sample tells."""
    variants: dict[tuple, list[float]] = {}
    for e in found:
        variants.setdefault((e["source"], e["variant"], e["dataset"]), []).append(e["accuracy"])
    above = []
    for e in found:
        if e["accuracy"] <= e["bound"] + 1e-6:  # a tie in float32's rounding is no lead
            continue
        lead = None
        if e["ensemble"] is not None:
            lead = round((e["accuracy"] - e["ensemble"]) * e["samples"])
        p = None if lead is None else min(1.0, 2.0 ** (1 - lead))
        p_max = None
        if lead is not None:
            right = round(e["accuracy"] * e["samples"])
            p_max = mcnemar_p_max(lead, right, right - lead, e["samples"])
        seeds = variants[(e["source"], e["variant"], e["dataset"])]
        above.append(
            {**e, "lead": lead, "mcnemar_p_min": p, "mcnemar_p_max": p_max,
             "seeds_mean": float(np.mean(seeds))}
        )  # fmt: skip
    return above


def mcnemar_p_max(lead: int, right: int, ensemble_right: int, samples: int) -> float:
    """The largest two-sided exact McNemar p-value that any pattern of right and wrong gives a
    network ``right`` of ``samples`` test samples, ``lead`` more than an ensemble
    (``ensemble_right``): the two disagreeing on as many samples as the counts allow, the
    ensemble alone right on min(ensemble_right, samples - right) of them, the network on those
    plus ``lead``; 1 for no lead."""
    from scipy.stats import binomtest

    if lead <= 0:
        return 1.0
    alone = min(ensemble_right, samples - right)
    return float(binomtest(alone + lead, 2 * alone + lead).pvalue)


def report(out: Path) -> None:
    """bound.json, bound.md and bound.png (the estimate's; the files keep the older name)
    from every run under ``out``/runs."""
    results = [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*.json"))]
    points = snn_points()
    (out / "bound.json").write_text(
        json.dumps({"bounds": results, "snn_simlidar_tuned": points}, indent=1) + "\n"
    )
    lines = [
        "# The early-information estimate",
        "",
        "Test accuracy of a learner given what has arrived by the k-th input spike (one MLP,",
        "mean +- population std over seeds; or, in runs of several learner families, the best",
        "family's seed mean or seed ensemble); `spikes` is the median arrived in the test split",
        "(ties at the k-th spike's time arrive together), `authors` the mean counted by the",
        "authors' rule (t > 0). Made by `benchmark/early_bound.py` (its docstring has the",
        "command; docs/paper-table.md the published ones).",
        "",
        "The estimate is the best accuracy of the learners tried, an estimate of what the data",
        "allow, not a bound: a stronger learner can beat it. Its uncertainty: where it is a seed",
        "mean, its family's seed spread (+-); where it is an ensemble, one figure, its family's",
        "seeds beside it; a test split of N samples puts a binomial standard error of up to",
        "50 / sqrt(N) points on any figure (2.0 at 600). The folder, files and JSON keys keep the",
        "older name, `bound`.",
        "",
    ]
    for r in results:
        if of_families(r):
            lines += _families_table(r)
            continue
        lines += [
            f"## {r['dataset']}, {_encoding(r)}",
            "",
            f"seeds {r['seeds']}, learner {r['learner']}, {r['seconds']:.0f} s",
            "",
            "| k | spikes (median) | authors (mean) | accuracy % | per seed |",
            "| ---: | ---: | ---: | ---: | --- |",
        ]
        for row in r["rows"]:
            k = "all" if row["k"] is None else row["k"]
            seeds = ", ".join(f"{a:.1%}" for a in row["accuracy"])
            lines.append(
                f"| {k} | {row['input_spikes_median']:.0f} | "
                f"{row['input_spikes_authors_mean']:.1f} | {row['accuracy_mean']:.1%} +- "
                f"{row['accuracy_std']:.1%} | {seeds} |"
            )
        lines.append("")
    lines += [
        "## snn_simlidar_tuned (committed cells, near_first / as_value)",
        "",
        "| dataset | seed | accuracy % | input spikes (median) |",
        "| --- | ---: | ---: | ---: |",
    ]
    for p in points:
        lines.append(
            f"| {p['dataset']} | {p['seed']} | {p['accuracy']:.1%} | "
            f"{p['input_spikes_median']:.0f} |"
        )
    (out / "bound.md").write_text("\n".join(lines) + "\n")
    plot(results, points, out / "bound.png")
    found = cell_bounds(results, network_cells())
    if found:
        (out / "cells.md").write_text(_cells_table(found))


def _families_table(r: dict) -> list[str]:
    """A run of several learner families (issue 42): per k the estimate (the best family's seed
    mean or seed ensemble, named), every family's seed mean +- sample standard deviation and
    ensemble, and the per-sample form's learner asked about every test sample at that k."""
    from simlidar.bench.bound import per_sample_accuracy

    names = list(r["learner"])
    form = r.get("per_sample")
    lines = [
        f"## {r['dataset']}, {_encoding(r)}",
        "",
        f"seeds {r['seeds']}; learner families {names} (fresh noise every epoch, every training "
        f"row once validation chose the epochs), {r['seconds']:.0f} s; +- is the sample "
        "standard deviation over seeds",
        "",
        "| k | spikes (median) | authors (mean) | estimate % | best | "
        + " | ".join(f"{n} % | {n} ensemble %" for n in names)
        + (" | any-k learner, ensemble % |" if form else " |"),
        "| ---: | ---: | ---: | ---: | --- | " + " | ".join("---: | ---:" for _ in names)
        + (" | ---: |" if form else " |"),
    ]  # fmt: skip
    for row in r["rows"]:
        k = "all" if row["k"] is None else row["k"]
        cells = [
            f"{f['accuracy_mean']:.1%} +- {f['accuracy_std']:.1%} | {f['ensemble']:.1%}"
            for f in (row["learners"][n] for n in names)
        ]
        tail = ""
        if form:
            count = form["k_max"] if row["k"] is None else min(row["k"], form["k_max"])
            spikes = np.full(form["samples"], count)
            tail = f" | {per_sample_accuracy(form, spikes):.1%}"
        lines.append(
            f"| {k} | {row['input_spikes_median']:.0f} | {row['input_spikes_authors_mean']:.1f} "
            f"| {row['accuracy_mean']:.1%} | {row['best']} | " + " | ".join(cells) + tail + " |"
        )
    lines.append("")
    if r.get("column_rows"):
        lines += [
            "By the sweep's first C firings: each sample seen once the last pulse of its first",
            "C columns has had its listening window (its emission + tof_max); `time` is the",
            "median of that moment, us after the window's first firing.",
            "",
            "| columns | time (us, median) | spikes (median) | estimate % | best | "
            + " | ".join(f"{n} % | {n} ensemble %" for n in names) + " |",
            "| ---: | ---: | ---: | ---: | --- | " + " | ".join("---: | ---:" for _ in names)
            + " |",
        ]  # fmt: skip
        for row in r["column_rows"]:
            cells = [
                f"{f['accuracy_mean']:.1%} +- {f['accuracy_std']:.1%} | {f['ensemble']:.1%}"
                for f in (row["learners"][n] for n in names)
            ]
            lines.append(
                f"| {row['columns']} | {row['time_us_median']:.0f} | "
                f"{row['input_spikes_median']:.0f} | {row['accuracy_mean']:.1%} | "
                f"{row['best']} | " + " | ".join(cells) + " |"
            )
        lines.append("")
    return lines


# how a table of cells above the estimate reads (cells.md here, weather.md of benchmark/weather.py)
ABOVE_LEGEND = (
    "Lead: test samples right beyond the estimate's best seed ensemble there; p: the smallest",
    "and the largest two-sided exact McNemar p-value that any pattern of right and wrong gives",
    "that lead (`early_bound.above_the_bound`): where even the smallest is above 0.05, the lead",
    "is within the test split's sampling whichever samples make it; where only the largest is,",
    "it may be, and only the cell's right or wrong on each sample would tell. Seeds' mean: the",
    "variant's, beside the estimate.",
)


def p_text(p: float | None) -> str:
    """A p-value of :func:`above_the_bound` as its tables show it: two decimals, 3 significant
    digits below 0.01, "-" for none."""
    if p is None:
        return "-"
    return f"{p:.2f}" if p >= 0.01 else f"{p:.3g}"


def _cells_table(found: list[dict]) -> str:
    """Every committed spiking-network cell beside the estimate (:func:`cell_bounds`), grouped
    by source, variant and dataset: the accuracy of each seed and the estimate's smallest
    margin."""
    groups: dict[tuple, list[dict]] = {}
    for entry in found:
        groups.setdefault((entry["source"], entry["variant"], entry["dataset"]), []).append(entry)
    lines = [
        "# Committed spiking-network cells beside the early-information estimate",
        "",
        "The estimate: the best accuracy of the learners tried, not a bound (a stronger learner",
        "can beat it; docs/paper-table.md). Behind a gate of k: the estimate's row at k.",
        "Otherwise the per-sample form at each test sample's own decision count (the any-k",
        "learner: the better of its seeds' mean and ensemble) and the looser rounded-up form",
        "(each sample read at the first measured k at or above its count), the estimate being",
        "the larger (per seed: each seed decided at its own counts; the lowest shown). Margin:",
        "the smallest of estimate minus accuracy over the seeds.",
        "",
        "| source | variant | dataset | encoding | seeds: accuracy % | form | per sample % | "
        "rounded up % | estimate % | margin |",
        "| --- | --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for (source, variant, dataset), entries in sorted(groups.items()):
        margin = min(e["bound"] - e["accuracy"] for e in entries)  # the closest seed
        bound = min(e["bound"] for e in entries)  # per seed: each seed's own decision counts
        seeds = ", ".join(f"{e['accuracy']:.2%}" for e in sorted(entries, key=lambda e: e["seed"]))
        exact = [e.get("per_sample") for e in entries]
        rounded = [e.get("rounded_up") for e in entries]
        shown = lambda values: (  # noqa: E731
            f"{min(values):.1%}" if all(v is not None for v in values) else "-"
        )
        lines.append(
            f"| {source} | {variant} | {dataset} | {entries[0]['direction']} | {seeds} | "
            f"{entries[0]['form']} | {shown(exact)} | {shown(rounded)} | {bound:.1%} | "
            f"{100 * margin:+.1f} |"
        )
    above = above_the_bound(found)
    if above:
        lines += [
            "",
            "## Cells above the estimate",
            "",
            *ABOVE_LEGEND,
            "",
            "| source | variant | dataset | seed | accuracy % | estimate % | best ensemble % | "
            "lead (samples) | p at least | p at most | seeds' mean % |",
            "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        ]
        for e in above:
            ensemble = "-" if e["ensemble"] is None else f"{e['ensemble']:.2%}"
            lead = "-" if e["lead"] is None else f"{e['lead']} of {e['samples']}"
            lines.append(
                f"| {e['source']} | {e['variant']} | {e['dataset']} | {e['seed']} | "
                f"{e['accuracy']:.2%} | {e['bound']:.2%} | {ensemble} | {lead} | "
                f"{p_text(e['mcnemar_p_min'])} | {p_text(e['mcnemar_p_max'])} | "
                f"{e['seeds_mean']:.2%} |"
            )
    return "\n".join(lines) + "\n"


def plot(results: list[dict], points: list[dict], path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5))
    ax = fig.subplots()
    noises = sorted({r["dataset"] for r in results})
    for r in results:
        rows = r["rows"]
        x = [row["input_spikes_median"] for row in rows]
        y = [100 * row["accuracy_mean"] for row in rows]
        e = [100 * row["accuracy_std"] for row in rows]
        label = f"{r['dataset']}: {_encoding(r)}"
        ax.errorbar(x, y, yerr=e, marker="o", ms=3, capsize=2, label=label)
    for p in points:
        if p["dataset"] in noises:
            ax.plot(p["input_spikes_median"], 100 * p["accuracy"], "k*", ms=9)
    ax.plot([], [], "k*", label="snn_simlidar_tuned (committed cells)")
    ax.axvspan(13, 16, color="0.85", label="the paper: 13-16 spikes")
    ax.axvline(180, color="0.6", ls="--", label="the paper: never more than 180")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("input spikes arrived / consumed (median over test samples)")
    ax.set_ylabel("test accuracy %")
    ax.set_ylim(0, 101)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("How early a decision can be right: the estimate and the networks")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    run(main)
