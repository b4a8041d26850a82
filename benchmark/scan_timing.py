"""Flash against scan timing: the same spiking network on the same scenes, two clocks.

    python benchmark/scan_timing.py                  # 3 seeds, noise 0.2, physical profile
    python benchmark/scan_timing.py --seeds 0 --epochs 10    # a quick look

The paper's delays are times of flight, as if every pulse of a window left the sensor at once
(a flash). A VLP-16 fires its lasers one after another while the head turns: the 256 pulses of
a 36-degree window leave over about 9.4 ms. A flash network can only start once the window's
last pulse has had its listening window (last emission + tof_max); a network fed scan-timed
spikes (``simlidar generate --timing scan``: arrival = emission + time of flight) can decide
while the sweep is still going.

This script generates one dataset of each timing from the same seed (same scenes, phases and
noise: only the clock differs; ``--profile``, default ``physical``, where a missing return is
no spike), trains ``snn_simlidar_tuned`` on each with every seed of ``--seeds`` under the
paper's protocol (``benchmark/paper_table.py``: the whole train split, the recipe's epochs, no
time cap, the last epoch scored) and prints, per timing, test accuracy (mean and sample
standard deviation over seeds) and the decision latency in sensor time, per sample, counted
from the window's first firing:

* scan: the event-driven run's decision time (``simlidar.bench.early``);
* flash: the end of the window's listening (its last emission, from the scan twin's
  ``emission_ns``, + tof_max) plus the flash decision time.

With ``--penalties`` (default ``0,1``) each timing is trained once more with the training
option ``early_penalty`` (``benchmark/early_tradeoff.py``: a reward for an early correct
output spike), to see whether the network can be taught to decide before the sweep ends.

Each (timing, penalty, seed) cell is a JSON file under ``--out``/cells (a rerun resumes); the
summary goes to ``--out``/scan_timing.json, the decision times' histogram to
``--out``/scan_timing.png and a picture of one sample under both clocks to ``--picture``
(docs/img/scan-timing.png).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paper_table import EPOCHS, JOBS, NOISE, PENALTIES, ROOT, SEEDS, done, made, run_cells

from simlidar.script_args import in_folder, run

RECIPE = "snn_simlidar_tuned"
TIMINGS = ("flash", "scan")


def twin_datasets(root: Path, profile: str, noise: float) -> dict[str, Path]:
    """The flash and the scan dataset of one seed and profile (3000 / 600), made if missing."""
    from dataclasses import replace

    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.profiles import load_profile

    flash = GeneratorConfig.from_profile(load_profile(profile), noise=noise)
    return {timing: made(root, replace(flash, timing=timing)) for timing in TIMINGS}


def flash_ready_ns(scan_dataset: Path) -> np.ndarray:
    """Per test sample: when a flash network can start, ns after the window's first firing
    (the last pulse's emission plus the listening window tof_max)."""
    from simlidar.dataset.loaders import split_info

    info = split_info(scan_dataset, "test")
    emission = info.read(("emission_ns",))["emission_ns"]
    return emission.reshape(len(emission), -1).max(axis=1) + float(info.attrs["tof_max_ns"])


def summarise(cells: dict[str, list[dict]], ready_ns: np.ndarray) -> dict:
    """Accuracy and latency (us from the window's first firing) per timing."""
    rows = {}
    for timing, mine in cells.items():
        if not mine:
            continue
        acc = np.array([100 * c["test_accuracy"] for c in mine])
        latency = []
        for c in mine:
            t = np.array([np.nan if v is None else v for v in c["decision_time_ns"]])
            latency.append(t + ready_ns if timing.startswith("flash") else t)
        latency = np.concatenate(latency) / 1e3
        decided = latency[np.isfinite(latency)]
        rows[timing] = {
            "seeds": [c["seed"] for c in mine],
            "accuracy": [round(a, 2) for a in acc],
            "mean": round(float(acc.mean()), 2),
            "std": round(float(acc.std(ddof=1)), 2) if len(acc) > 1 else None,
            "latency_us_median": round(float(np.median(decided)), 1),
            "latency_us_p10": round(float(np.percentile(decided, 10)), 1),
            "latency_us_p90": round(float(np.percentile(decided, 90)), 1),
            "undecided": int(len(latency) - len(decided)),
            "input_spikes_median": float(
                np.median(np.concatenate([c["input_spikes"] for c in mine]))
            ),
            "data_ratio_mean": round(
                float(np.mean([c["early"]["data_ratio_mean"] for c in mine])), 3
            ),
        }
    return rows


def plot(cells: dict[str, list[dict]], ready_ns: np.ndarray, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.6))
    latencies = {}
    for timing, mine in cells.items():
        for c in mine:
            t = np.array([np.nan if v is None else v for v in c["decision_time_ns"]])
            t = (t + ready_ns if timing.startswith("flash") else t) / 1e3
            latencies.setdefault(timing, []).append(t[np.isfinite(t)])
    top = max([ready_ns.max() / 1e3] + [t.max() for ts in latencies.values() for t in ts if len(t)])
    bins = np.linspace(0, top * 1.02, 100)
    for colour, (timing, ts) in enumerate(latencies.items()):
        for k, t in enumerate(ts):
            ax.hist(
                t, bins=bins, histtype="step", color=f"C{colour}", label=timing if k == 0 else None
            )
    ax.axvline(
        np.median(ready_ns) / 1e3, color="grey", ls=":", label="window's last pulse back (median)"
    )
    ax.set_xlabel("decision, us after the window's first firing")
    ax.set_ylabel("test samples")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"{RECIPE}: when it decides, flash vs scan timing", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def timing_picture(data: dict[str, Path], rows: dict, out: Path) -> Path:
    """One test sample under both clocks: when each pulse arrives in the sweep (scan), and how
    many input spikes a network has received by each instant, flash against scan, with the
    measured median decisions."""
    import h5py
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with h5py.File(data["scan"] / "test.h5") as f:
        pick = int(np.nonzero(f["object"][:] == 1)[0][0])  # the first sample with a car
        scan, emission = f["delays"][pick], f["emission_ns"][pick]
        unit, tof_max = f.attrs["delay_unit_ns"], f.attrs["tof_max_ns"]
        name = f.attrs["class_names"][f["labels"][pick]]
        name = name.decode() if isinstance(name, bytes) else name
    with h5py.File(data["flash"] / "test.h5") as f:
        flash = f["delays"][pick]
    back = scan < 1.0
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6), width_ratios=(1, 1.4))
    shown = np.where(back, scan * unit / 1e6, np.nan)
    im = left.imshow(shown, cmap="viridis", aspect="auto")
    left.set_title(f"test sample {pick} ({name}), scan timing:\narrival of each pulse", fontsize=9)
    left.set_xlabel("column (azimuth, left to right)")
    left.set_ylabel("row (laser, highest first)")
    fig.colorbar(im, ax=left, label="ms after the window's first firing")
    ready = emission.max() + tof_max  # the flash sample is complete
    t_scan = np.sort(scan[back] * unit) / 1e3
    t_flash = np.sort(ready + flash[flash < 1.0] * tof_max) / 1e3
    for t, label, k in (
        (t_flash, "flash: wait for the window, then every pulse", 0),
        (t_scan, "scan: each pulse as it arrives", 1),
    ):
        right.step(
            np.concatenate([[0], t]),
            np.arange(len(t) + 1),
            where="post",
            color=f"C{k}",
            label=label,
        )
    for k, (variant, row) in enumerate(rows.items()):  # the colours of plot()
        right.axvline(
            row["latency_us_median"],
            color=f"C{k}",
            ls="--" if variant in ("flash", "scan") else ":",
            lw=1,
            label=f"{variant}: median decision ({row['mean']:.1f} % correct)",
        )
    right.set_xlabel("us after the window's first firing")
    right.set_ylabel("input spikes received")
    right.set_title("VLP-16, 600 RPM, 16 x 16 window of 36 deg", fontsize=9)
    right.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=SEEDS, default="0,1,2")
    parser.add_argument(
        "--penalties",
        type=PENALTIES,
        default="0,1",
        help="training option early_penalty of each variant (benchmark/early_tradeoff.py)",
    )
    parser.add_argument("--noise", type=NOISE, default=0.2)
    parser.add_argument("--profile", default="physical")
    parser.add_argument("--epochs", type=EPOCHS, default=None, help="override the recipe's 60")
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/scan-timing")
    parser.add_argument("--jobs", type=JOBS, default=2)
    parser.add_argument(
        "--picture",
        type=lambda text: in_folder(text) if text else None,
        default=ROOT / "docs/img/scan-timing.png",
        help="the docs' picture of one sample under both clocks ('' for none)",
    )
    args = parser.parse_args(argv)
    seeds, penalties = list(args.seeds), list(args.penalties)
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.profiles import load_profile

    # the profile and the configuration, before a dataset or a cell is written
    GeneratorConfig.from_profile(load_profile(args.profile), noise=args.noise)
    data = twin_datasets(args.data, args.profile, args.noise)
    cell_dir = args.out / "cells"
    cell_dir.mkdir(parents=True, exist_ok=True)

    def cell_path(timing: str, penalty: float, seed: int) -> Path:
        epochs = f"-e{args.epochs}" if args.epochs else ""
        early = f"__early{penalty!r}" if penalty else ""
        return cell_dir / f"{data[timing].name}__{RECIPE}{early}{epochs}__seed{seed}.json"

    variants = {
        (t if not p else f"{t}, early penalty {p:g}"): (t, p) for p in penalties for t in TIMINGS
    }
    todo = [
        (
            RECIPE,
            str(data[t]),
            seed,
            str(cell_path(t, p, seed)),
            {"early_penalty": p} if p else None,
            args.epochs,
        )
        for t, p in variants.values()
        for seed in seeds
        if not done(cell_path(t, p, seed), RECIPE, args.epochs)
    ]
    run_cells(todo, args.jobs)
    cells = {
        key: [
            json.loads(cell_path(t, p, s).read_text())
            for s in seeds
            if cell_path(t, p, s).is_file()
        ]
        for key, (t, p) in variants.items()
    }
    ready = flash_ready_ns(data["scan"])
    rows = summarise(cells, ready)
    summary = {
        "recipe": RECIPE,
        "profile": args.profile,
        "noise": args.noise,
        "datasets": {t: p.name for t, p in data.items()},
        "flash_ready_us_median": round(float(np.median(ready)) / 1e3, 1),
        "rows": rows,
    }
    (args.out / "scan_timing.json").write_text(json.dumps(summary, indent=1) + "\n")
    plot(cells, ready, args.out / "scan_timing.png")
    if args.picture:
        timing_picture(data, rows, args.picture)
    print(
        f"{RECIPE}, profile {args.profile}, noise {args.noise}; flash input complete at "
        f"{summary['flash_ready_us_median']} us (median)"
    )
    width = max(len(t) for t in rows)
    print(
        f"{'variant':{width}}  accuracy %        decision us (median, p10..p90)  input spikes "
        "(median)  R_data"
    )
    for t, r in rows.items():
        sd = f" +- {r['std']:.2f}" if r["std"] is not None else ""
        spread = f"({r['latency_us_p10']:.1f}..{r['latency_us_p90']:.1f})"
        print(
            f"{t:{width}}  {r['mean']:6.2f}{sd:9}  {r['latency_us_median']:8.1f} {spread:22}  "
            f"{r['input_spikes_median']:6.1f}                 {r['data_ratio_mean']:.3f}"
        )
    return 0


if __name__ == "__main__":
    run(main)
