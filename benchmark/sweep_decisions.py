"""Networks that decide mid-sweep: accuracy against sensor time on a spinning LiDAR (issue 42).

    python benchmark/sweep_decisions.py --data /tmp/data          # the published grid, 5 seeds
    python benchmark/sweep_decisions.py --data /tmp/data --datasets paper:0.1 --columns 10 \\
        --seeds 0                                                  # one point, a quick look
    python benchmark/sweep_decisions.py --data /tmp/data --datasets physical:0.2 --columns 16 \\
        --recipe scnn_simlidar_tuned --jobs 1 \\
        --out benchmark/results/sweep-decisions-scnn               # the spiking CNN's point

A VLP-16 fires its 16 lasers column after column while the head turns: the 16 columns of a
36-degree window leave over 9.4 ms, one firing about every 593 us, and each firing's returns are
back within ``tof_max`` (667 ns). The sensor knows when it fired each laser, so per-pixel delay
lines of fixed length (the firing schedule: the same for every sample, whatever its phase)
can hold each return until the last pulse of the first C columns is back, and hand the network
the C columns' times of flight together, as a flash would: a network behind the column gate
``input_columns = C`` (:class:`simlidar.models.networks.SpikingNet`) on the flash delays is that
network, and it decides at

    sensor time = E_C + t_out

where E_C is when the last pulse of the sample's first C columns left (its scan twin's
``emission_ns``, counted from the window's first firing) and t_out the network's first output
spike after its flash-aligned input (ns). The network is trained and scored on the flash twin
(the same scenes, phases and noise: only the clock differs), whose times of flight the scan
twin's float32 arrival times give to within 0.3 ns; the decision time is then read on the scan
twin's clock. The later columns would reach the network at least 593 us after the aligned ones,
long after it has decided (every decision below is checked to come before the next firing).

Trains ``snn_simlidar_tuned`` (the paper's protocol: all 3000 training samples, its 60 epochs of a
cosine schedule, fresh noise every epoch, the last epoch scored) behind each gate of ``--columns``
on each dataset of ``--datasets`` (profile:noise), every seed of ``--seeds``; each cell is a JSON
file under ``--out``/cells (a rerun resumes). Beside each point it puts the early-information
estimate at the same moment: the row of ``--bound`` (``benchmark/early_bound.py --columns``: three
learner families with fresh noise, on the scan twin by the sensor's clock; the flag and the file
keep the older name) for the same C, which sees every sensor time from E_C + tof_max until the
next firing. The estimate is the best accuracy of the learners tried, not a bound: a network can
beat it (docs/paper-table.md). Writes sweep.md / .json / .png: per point the accuracy (mean ±
sample std [95 % interval, Student's t] over seeds), the median decision in sensor time (us; p10 /
p90 over every test sample of every seed), the estimate there and the gap (estimate minus the
interval's lower end), and the issue's targets: on ``paper`` noise 0.1 a point within 3 points of
the estimate with its median at most 6 ms into the window; on ``physical`` noise 0.2 the network
with every column within 5 points of the estimate.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from early_objectives import low_end
from paper_table import JOBS, ROOT, SEEDS, check_recipes, interval, run_cells
from scan_timing import twin_datasets

from simlidar.script_args import command_line, integers, run

RECIPE = "snn_simlidar_tuned"
HIDDEN = 400  # the recipe's hidden layer; --hidden adds wider ones beside it
MIN_SEEDS = 5  # a point counts toward a target with this many seeds (issue 42)
PROFILES = ("paper", "physical")
NOISES = (0.1, 0.2)
# (profile, noise): (most us into the window, most points below the estimate, columns: None: any)
TARGETS = {("paper", 0.1): (6000.0, 3.0, None), ("physical", 0.2): (None, 5.0, "all")}


def cell_name(dataset: str, columns: int, seed: int, recipe: str = RECIPE, hidden: int = HIDDEN):
    """The file name of a cell: the network ``recipe`` (``--hidden`` wide) behind a gate of
    ``columns`` on the flash dataset named ``dataset``, seed ``seed``."""
    wider = "" if hidden == HIDDEN else f"-hidden{hidden}"
    wider += "" if recipe == RECIPE else f"-{recipe}"
    return f"{dataset}__columns{columns}{wider}__seed{seed}.json"


# where each network's committed cells are: benchmark/results/<folder>/cells (docs/snn.md)
COMMITTED = {"snn_simlidar_tuned": "sweep-decisions", "scnn_simlidar_tuned": "sweep-decisions-scnn"}


def committed_cell(
    dataset: Path, recipe: str, seed: int, columns: int | None = None
) -> tuple[dict, dict]:
    """The committed cell of ``recipe`` (a network of :data:`COMMITTED`) behind ``columns``
    (None: every column) of the flash dataset ``dataset``, seed ``seed``, and the recipe as
    that cell was trained (the paper's protocol: :func:`paper_table.run_cells`' cells hold no
    validation rows; the cell's architecture); a ConfigError where there is no such cell."""
    from simlidar.dataset.loaders import split_info
    from simlidar.errors import ConfigError
    from simlidar.models.registry import load_recipe

    columns = columns or split_info(dataset, "test").width
    folder = ROOT / "benchmark/results" / COMMITTED[recipe] / "cells"
    path = folder / cell_name(dataset.name, columns, seed, recipe)
    if not path.is_file():
        raise ConfigError(f"{path}: no committed cell for this dataset, network and seed")
    cell = json.loads(path.read_text())
    trained = load_recipe(recipe)
    trained["training"]["validation"] = 0
    trained["architecture"].update(cell.get("architecture", {}))
    return cell, trained


def dataset_pairs(text: str) -> list[tuple[str, float]]:
    """``--datasets``: comma-separated profile:noise, each of PROFILES x NOISES."""
    pairs = []
    for item in text.split(","):
        profile, _, noise = item.partition(":")
        try:
            level = float(noise)
        except ValueError:
            level = None
        if profile not in PROFILES or level not in NOISES:
            raise argparse.ArgumentTypeError(
                f"{item!r}: expected profile:noise with a profile of {list(PROFILES)} and a "
                f"noise of {list(NOISES)}"
            )
        pairs.append((profile, level))
    return pairs


def firing_times(scan: Path, columns: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Per test sample of the scan twin: when the last pulse of its first ``columns`` columns
    left (E_C, ns after the window's first firing), and when the next column's first pulse
    leaves (None for the last column). A ValueError if the columns do not fire in order."""
    from simlidar.dataset.loaders import load_split

    emission = load_split(scan, "test", "emission_ns")[0]  # (N, H, W) ns
    starts, ends = emission.min(axis=1), emission.max(axis=1)  # (N, W) per column
    if not (starts[:, 1:] > ends[:, :-1]).all():
        raise ValueError(f"{scan.name}: expected the columns to fire one after another")
    after = starts[:, columns] if columns < emission.shape[-1] else None
    return ends[:, :columns].max(axis=1), after


def sensor_times(cell: dict, fired: np.ndarray, after: np.ndarray | None) -> tuple[np.ndarray, int]:
    """A cell's decisions in sensor time (us; NaN undecided) and how many came after the next
    column fired (the delay lines' premise: 0); ``fired``, ``after``: :func:`firing_times`."""
    t_out = np.array([np.nan if t is None else t for t in cell["decision_time_ns"]], dtype=float)
    at = fired + t_out
    late = 0 if after is None else int(np.sum(at[np.isfinite(at)] >= after[np.isfinite(at)]))
    return at / 1000.0, late


def bound_rows(bound_json: Path, scan_name: str) -> dict:
    """The estimate's rows by columns for the scan twin (near first, sensor clock): C -> row, and
    "all" -> the row with every spike arrived (k None)."""
    if not bound_json.is_file():
        return {}
    for b in json.loads(bound_json.read_text())["bounds"]:
        encoding = b["encoding"]
        if b["dataset"] == scan_name and (encoding["direction"], encoding.get("clock")) == (
            "near_first",
            "sensor",
        ):
            every = [r for r in b["rows"] if r["k"] is None]
            return {r["columns"]: r for r in b.get("column_rows", [])} | {"all": every[0]}
    return {}


def bound_for(bound: dict, columns: int, width: int) -> dict | None:
    """The estimate for a network behind ``columns`` of ``width`` columns: the best of the rows
    measured with as much information or less (fewer columns: a learner may ignore the later
    ones; with every column also the every-spike row, the same information). None without a
    row for ``columns`` itself."""
    if columns not in bound:
        return None
    rows = [r for c, r in bound.items() if c != "all" and c <= columns]
    rows += [bound["all"]] if columns == width and "all" in bound else []
    return max(rows, key=lambda r: r["accuracy_mean"])


def summarise(
    found: list[dict], scan: Path, columns: int, width: int, bound: dict, hidden: int = HIDDEN
) -> dict:
    """One point: the seeds' cells of one dataset, gate and hidden width beside the estimate
    (under the keys ``bound``, ``bound_time_us``, ... : the older name, kept)."""
    acc = np.array([100 * c["test_accuracy"] for c in found])
    times, late = [], 0
    firings = firing_times(scan, columns)  # the test split's emission, read once a point
    for cell in found:
        t, n = sensor_times(cell, *firings)
        times.append(t)
        late += n
    times = np.concatenate(times)
    decided = times[np.isfinite(times)]
    row = {
        "columns": columns,
        "hidden": hidden,
        "every_column": columns == width,
        "seeds": [c["seed"] for c in found],
        "accuracy": float(acc.mean()),
        "accuracy_std": float(acc.std(ddof=1)) if len(acc) > 1 else None,
        "accuracy_ci95": interval(acc),
        "accuracy_per_seed": acc.tolist(),
        "decision_us_median": float(np.median(decided)),
        "decision_us_p10": float(np.percentile(decided, 10)),
        "decision_us_p90": float(np.percentile(decided, 90)),
        "undecided": int(np.isnan(times).sum()),
        "after_next_firing": late,
        "t_out_ns_median": float(
            np.median([t for c in found for t in c["decision_time_ns"] if t is not None])
        ),
        "input_spikes_median": float(np.median(np.concatenate([c["input_spikes"] for c in found]))),
    }
    b = bound_for(bound, columns, width)
    if b is not None:
        row.update(
            bound=100 * b["accuracy_mean"],
            bound_time_us=bound[columns]["time_us_median"],
            bound_from=b.get("columns", "every spike"),
            bound_best=b.get("best"),
            gap=100 * b["accuracy_mean"] - low_end(row),
        )
    return row


def targets(points: dict) -> list[dict]:
    """The issue's targets (:data:`TARGETS`) against the points of at least
    :data:`MIN_SEEDS` seeds, each counted by its 95 % interval's lower end (the gap is the
    estimate minus that end)."""
    found = []
    for (profile, noise), (limit_us, gap, which) in TARGETS.items():
        rows = points.get(f"{profile}:{noise:g}")
        if not rows:
            continue
        pool = [
            r
            for r in rows
            if "gap" in r and len(r["seeds"]) >= MIN_SEEDS and (which != "all" or r["every_column"])
        ]
        if limit_us is not None:
            pool = [r for r in pool if r["decision_us_median"] <= limit_us]
        met = [f"{r['columns']} (hidden {r['hidden']})" for r in pool if r["gap"] <= gap]
        closest = min(pool, key=lambda r: r["gap"], default=None)
        found.append(
            {
                "dataset": f"{profile}:{noise:g}",
                "rule": (
                    f"within {gap:g} points of the estimate"
                    + (f", median decision <= {limit_us / 1000:g} ms" if limit_us else "")
                    + (", every column" if which == "all" else "")
                ),
                "met_by_columns": met,
                "closest": None
                if closest is None
                else {k: closest[k] for k in ("columns", "hidden", "gap", "decision_us_median")},
            }
        )
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument(
        "--datasets",
        type=dataset_pairs,
        default="paper:0.1,physical:0.2,paper:0.2,physical:0.1",
        help="profile:noise, comma-separated (flash and scan twins under --data, made if missing)",
    )
    parser.add_argument("--columns", type=integers(1, 16), default="4,6,8,10,12,16")
    parser.add_argument(
        "--hidden",
        type=integers(1, 4096),
        default=str(HIDDEN),
        help="the hidden layer's widths to train (the recipe's: 400)",
    )
    parser.add_argument(
        "--recipe",
        default=RECIPE,
        help=f"the network (a recipe of baselines/; default {RECIPE}; --hidden widens only it)",
    )
    parser.add_argument("--seeds", type=SEEDS, default="0,1,2,3,4")
    parser.add_argument("--jobs", type=JOBS, default=2)
    parser.add_argument(
        "--bound",
        type=Path,
        default=ROOT / "benchmark/results/bound-scan/bound.json",
        help="the early-information estimate's runs (benchmark/early_bound.py --columns: its "
        "bound.json; the flag and the file keep the older name)",
    )
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/sweep-decisions")
    parser.add_argument("--no-train", action="store_true", help="summarise the cells there are")
    args = parser.parse_args(argv)
    if args.recipe != RECIPE and list(args.hidden) != [HIDDEN]:
        parser.error(
            f"--hidden {list(args.hidden)}: expected {HIDDEN} (--hidden widens {RECIPE} alone)"
        )
    check_recipes([args.recipe])
    cells = args.out / "cells"
    pairs = {f"{p}:{n:g}": twin_datasets(args.data, p, n) for p, n in args.datasets}
    cells.mkdir(parents=True, exist_ok=True)

    def cell_path(flash: Path, columns: int, hidden: int, seed: int) -> Path:
        return cells / cell_name(flash.name, columns, seed, args.recipe, hidden)

    def architecture(columns: int, hidden: int) -> dict:
        return {"input_columns": columns} | ({} if hidden == HIDDEN else {"hidden": [hidden]})

    todo = [
        (args.recipe, str(twins["flash"]), s, str(cell_path(twins["flash"], c, h, s)), None, None,
         architecture(c, h))
        for s in args.seeds  # seed 0 of every point first: a first look comes early
        for twins in pairs.values()
        for h in args.hidden
        for c in args.columns
        if not cell_path(twins["flash"], c, h, s).is_file()
    ]  # fmt: skip
    if not args.no_train:
        run_cells(todo, args.jobs)
    points = {}
    for name, twins in pairs.items():
        flash, scan = twins["flash"], twins["scan"]
        width = _width(scan)
        bound = bound_rows(args.bound, scan.name)
        rows = []
        for h in args.hidden:
            for c in args.columns:
                found = [
                    json.loads(cell_path(flash, c, h, s).read_text())
                    for s in args.seeds
                    if cell_path(flash, c, h, s).is_file()
                ]
                if found:
                    rows.append(
                        summarise(found, scan, c, width, bound, h) | {"recipe": args.recipe}
                    )
        points[name] = rows
    goals = targets(points)
    command = command_line("sweep_decisions.py", argv)
    bounds = {name: bound_rows(args.bound, t["scan"].name) for name, t in pairs.items()}
    write(args.out, points, goals, bounds, command, args.recipe)
    return 0


def _width(scan: Path) -> int:
    from simlidar.dataset.loaders import split_info

    return int(split_info(scan, "test").attrs["config"]["width"])


def write(
    out: Path, points: dict, goals: list[dict], bounds: dict, command: str, recipe: str = RECIPE
) -> None:
    lines = [
        "# Deciding mid-sweep: accuracy against sensor time",
        "",
        f"Made by `{command}` (`benchmark/sweep_decisions.py`; its docstring says what the "
        f"network is). {recipe} behind a column gate of C columns (the sweep's first C "
        "firings, aligned by delay lines), the paper's protocol (all 3000 training samples, "
        "60 epochs, the last scored); accuracy: mean ± sample std over seeds [95 % interval of "
        "the mean, Student's t]; decision: sensor time, us after the window's first firing "
        "(median and p10 / p90 over every test sample of every seed); `t_out`: the network's "
        "own latency after its aligned input (median, ns). Estimate: the early-information "
        "estimate once the first C columns are back (`benchmark/early_bound.py --columns`, "
        "three learner families (two MLPs, the paper's CNN) with fresh noise, the best of their "
        "seed means and ensembles; the best row with as much information or less, named where "
        "it is another row), at the median time shown: the best of the learners tried, not a "
        "bound (a network can beat it; docs/paper-table.md); gap: estimate minus the lower end "
        "of the 95 % interval.",
        "",
    ]
    for name, rows in points.items():
        lines += [
            f"## {name}",
            "",
            "| columns | hidden | accuracy % | decision (us): median (p10 / p90) | t_out (ns) | "
            "input spikes (median) | estimate % (at us) | gap | undecided | after the next "
            "firing |",
            "| ---: | ---: | --- | --- | ---: | ---: | --- | ---: | ---: | ---: |",
        ]
        for r in rows:
            std = f" ± {r['accuracy_std']:.2f}" if r["accuracy_std"] is not None else ""
            if r["accuracy_ci95"]:
                std += f" [{r['accuracy_ci95'][0]:.2f}, {r['accuracy_ci95'][1]:.2f}]"
            source = "" if r.get("bound_from") == r["columns"] else f", from {r['bound_from']}"
            bound = (
                f"{r['bound']:.1f} ({r['bound_time_us']:.0f} us{source}) | {r['gap']:+.1f}"
                if "bound" in r
                else "- | -"
            )
            lines.append(
                f"| {r['columns']} | {r['hidden']} | {r['accuracy']:.2f}{std} "
                f"(n={len(r['seeds'])}) | "
                f"{r['decision_us_median']:.0f} ({r['decision_us_p10']:.0f} / "
                f"{r['decision_us_p90']:.0f}) | {r['t_out_ns_median']:.0f} | "
                f"{r['input_spikes_median']:.0f} | {bound} | {r['undecided']} | "
                f"{r['after_next_firing']} |"
            )
        lines.append("")
    if goals:
        lines += ["## Targets (issue 42, item 3)", ""]
        for g in goals:
            closest = g["closest"]
            near = (
                f"closest: {closest['columns']} columns, hidden {closest['hidden']}, "
                f"{closest['gap']:+.1f} points at "
                f"{closest['decision_us_median'] / 1000:.2f} ms"
                if closest
                else "no point with an estimate"
            )
            lines.append(
                f"* {g['dataset']}, {g['rule']}: met by columns {g['met_by_columns'] or 'none'}"
                f" ({near})"
            )
        lines.append("")
    text = "\n".join(lines)
    (out / "sweep.md").write_text(text)
    (out / "sweep.json").write_text(
        json.dumps({"points": points, "targets": goals, "command": command}, indent=1) + "\n"
    )
    plot(points, bounds, out / "sweep.png")
    print(text)


def plot(points: dict, bounds: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 4.8))
    ax = fig.subplots()
    colours = dict(zip(points, ("tab:blue", "tab:red", "tab:cyan", "tab:orange")))
    for name, rows in points.items():
        colour = colours[name]
        b = [r for key, r in bounds.get(name, {}).items() if key != "all"]
        b.sort(key=lambda r: r["time_us_median"])
        if b:
            ax.plot(
                [r["time_us_median"] / 1000 for r in b],
                [100 * r["accuracy_mean"] for r in b],
                "--",
                color=colour,
                label=f"estimate, {name}",
            )
        for r in rows:
            low, high = r["accuracy_ci95"] or (r["accuracy"], r["accuracy"])
            ax.errorbar(
                r["decision_us_median"] / 1000,
                r["accuracy"],
                yerr=[[r["accuracy"] - low], [high - r["accuracy"]]],
                fmt="o",
                color=colour,
                ms=4,
                capsize=2,
            )
        ax.plot([], [], "o", color=colour, label=f"network, {name} (95 % interval)")
    ax.axvline(6.0, color="0.6", ls=":", label="6 ms (issue 42's limit on paper:0.1)")
    ax.axvline(9.44, color="0.3", ls="--", lw=0.8, label="the window's last firing")
    ax.set(
        xlabel="decision, ms after the window's first firing (median)",
        ylabel="test accuracy (%)",
        ylim=(0, 101),
        xlim=(0, 10),
        title="Deciding mid-sweep: column-gated TTFS networks and the estimate",
    )
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    run(main)
