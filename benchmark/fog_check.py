"""Fog against what has been published: points lost and the fog's own returns by visibility.

    python benchmark/fog_check.py [--samples 512] [--out benchmark/results/fog]

1. **Points lost.** The range at which a target of reflectance 0.1 and 0.8 (square to the beam)
   drops below the VLP-16 receiver's threshold, by the fog's extinction alpha, beside the
   model that Bijelic et al. fitted to their fog-chamber measurements of a Velodyne HDL-64E
   S3D (Seeing Through Fog, CVPR 2020; code ``princeton-computational-imaging/SeeingThroughFog``,
   ``tools/DatasetFoggification/lidar_foggification.py``): ``d_max = ln((rho + g) / n) /
   (2 alpha)`` with the S3D's noise level n = 0.04 and gain g = 0.45. Another sensor, and a fit
   rather than the raw measurements: read the ratio as an order-of-magnitude check.
2. **The dataset.** ``--samples`` train samples of the ``sensor`` profile at each visibility:
   the share of the clear-air returns lost, the share of pulses whose first return is the
   fog's own (surface 0), and its median range; once with the receiver's own biaxial crossover
   (:func:`simlidar.sensor.receiver.crossover_ranges`) and once with Hahner et al.'s slider
   defaults (0.9 m to 1.0 m), to show how much the fog's echo hangs on that unknown.

Writes fog.md, fog.json and fog.png under ``--out``.
"""

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from simlidar.generator.config import GeneratorConfig
from simlidar.generator.profiles import load_profile
from simlidar.generator.returns import receiver_physics
from simlidar.generator.simulate import simulate
from simlidar.scene.recipe import load_catalog
from simlidar.script_args import command_line, integers, run
from simlidar.sensor.model import SPEED_OF_LIGHT_M_PER_S
from simlidar.sensor.raycast import MAX_BATCH
from simlidar.sensor.receiver import crossover_ranges, max_range_m

ROOT = Path(__file__).resolve().parents[1]
# Seeing Through Fog's fit for the HDL-64E S3D (lidar_foggification.py: n, g)
STF_NOISE, STF_GAIN = 0.04, 0.45
ALPHAS = (0.05, 0.1, 0.15, 0.2)  # 1/m; STF's own runs used 0.10 to 0.20
REFLECTANCES = (0.1, 0.8)
VISIBILITIES = (math.inf, 500.0, 200.0, 100.0, 50.0, 30.0, 20.0, 10.0)
HAHNER_SLIDERS = (0.9, 1.0)  # Hahner et al.'s ParameterSet r_1, r_2


def stf_range_m(reflectance: float, alpha: float) -> float:
    """Seeing Through Fog's maximum range of a target of ``reflectance`` at extinction alpha."""
    return math.log((reflectance + STF_GAIN) / STF_NOISE) / (2.0 * alpha)


def ranges() -> list[dict]:
    receiver = receiver_physics(load_profile("sensor")).receiver
    rows = []
    for alpha in ALPHAS:
        for rho in REFLECTANCES:
            ours = float(max_range_m(receiver, rho, 0.0, alpha))
            theirs = stf_range_m(rho, alpha)
            rows.append(
                {
                    "alpha": alpha,
                    "reflectance": rho,
                    "ours_m": ours,
                    "stf_m": theirs,
                    "ratio": ours / theirs,
                }  # fmt: skip
            )
    return rows


def weather_rows(samples: int, option: str, values) -> list[dict]:
    """``samples`` train samples of the ``sensor`` profile with the GeneratorConfig field
    ``option`` at each of ``values`` (the first: clear air): the share of the clear-air returns
    lost, the share of pulses whose first return is the weather's own (surface 0) and its median
    range."""
    catalog, profile = load_catalog(), load_profile("sensor")
    rows, clear = [], None
    for value in values:
        config = GeneratorConfig.from_profile(
            profile, train_size=samples, test_size=32, **{option: value}
        )
        s = simulate(config, catalog, "train", 0, samples)
        returned = ~np.isnan(s.tof_ns)
        own = returned & (s.surface == 0)
        hard = returned & ~own
        clear = hard if clear is None else clear
        range_m = s.tof_ns[own] * 1e-9 * SPEED_OF_LIGHT_M_PER_S / 2.0
        rows.append(
            {
                option: value,
                "alpha": config.extinction_per_m,
                "lost_percent": 100.0 * float((clear & ~hard).sum() / clear.sum()),
                "weather_returns_percent": 100.0 * float(own.mean()),
                "weather_range_median_m": float(np.median(range_m)) if own.any() else None,
            }
        )
    return rows


def dataset(samples: int, crossover: tuple[float, float] | None) -> list[dict]:
    """:func:`weather_rows` over the visibilities, with the receiver's own crossover (None) or
    with ``crossover`` (r_1, r_2) in its place."""
    import simlidar.generator.returns as returns

    kept = returns.crossover_ranges
    if crossover is not None:
        returns.crossover_ranges = lambda receiver: crossover
    try:
        rows = weather_rows(samples, "fog_visibility_m", VISIBILITIES)
    finally:
        returns.crossover_ranges = kept
    return [
        {
            "visibility_m": r["fog_visibility_m"],
            "alpha": r["alpha"],
            "lost_percent": r["lost_percent"],
            "fog_returns_percent": r["weather_returns_percent"],
            "fog_range_median_m": r["weather_range_median_m"],
        }
        for r in rows
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=integers(32, MAX_BATCH, one=True), default=512)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/fog")
    args = parser.parse_args(argv)
    result = {
        "command": command_line("fog_check.py", argv),
        "ranges": ranges(),
        "crossover_m": list(crossover_ranges(receiver_physics(load_profile("sensor")).receiver)),
        "dataset": dataset(args.samples, None),
        "dataset_hahner_sliders": dataset(args.samples, HAHNER_SLIDERS),
        "samples": args.samples,
    }
    write_results(args.out, "fog", result, report, plot)
    return 0


def write_results(out: Path, stem: str, result: dict, report, plot) -> None:
    """``stem``.json, .md (``report(result)``, also printed) and .png (``plot``) under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    text = report(result)
    (out / f"{stem}.md").write_text(text)
    plot(result, out / f"{stem}.png")
    print(text)


def report(result: dict) -> str:
    low, high = result["crossover_m"]
    lines = [
        "# Fog: points lost and the fog's own returns",
        "",
        f"Made by `{result['command']}` (`benchmark/fog_check.py`; its docstring says what is "
        "compared).",
        "",
        "## Maximum range by extinction, beside Seeing Through Fog's HDL-64E S3D fit",
        "",
        "| alpha (1/m) | reflectance | ours (m) | STF fit (m) | ours / STF |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in result["ranges"]:
        lines.append(
            f"| {r['alpha']:g} | {r['reflectance']:g} | {r['ours_m']:.1f} | {r['stf_m']:.1f} | "
            f"{r['ratio']:.2f} |"
        )
    for key, name in (
        ("dataset", f"the generator's crossover ({low:.2f} m to {high:.2f} m)"),
        ("dataset_hahner_sliders", "Hahner et al.'s slider defaults (0.9 m to 1.0 m)"),
    ):
        lines += [
            "",
            f"## {result['samples']} `sensor` samples by visibility, {name}",
            "",
            "| visibility (m) | alpha (1/m) | clear returns lost | fog's returns (of pulses) | "
            "their median range (m) |",
            "| ---: | ---: | ---: | ---: | ---: |",
        ]
        for r in result[key]:
            median = "-" if r["fog_range_median_m"] is None else f"{r['fog_range_median_m']:.2f}"
            lines.append(
                f"| {r['visibility_m']:g} | {r['alpha']:.4f} | {r['lost_percent']:.1f} % | "
                f"{r['fog_returns_percent']:.1f} % | {median} |"
            )
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    left, right = fig.subplots(1, 2)
    for rho, colour in zip(REFLECTANCES, ("tab:blue", "tab:red")):
        rows = [r for r in result["ranges"] if r["reflectance"] == rho]
        alphas = [r["alpha"] for r in rows]
        ours, stf = [r["ours_m"] for r in rows], [r["stf_m"] for r in rows]
        left.plot(alphas, ours, "o-", color=colour, label=f"ours, {rho:g}")
        left.plot(alphas, stf, "s--", color=colour, label=f"STF fit, {rho:g}")
    left.set(xlabel="extinction alpha (1/m)", ylabel="maximum range (m)",
             title="Target lost beyond (square to the beam)")  # fmt: skip
    left.legend(fontsize=7)
    for key, style, name in (
        ("dataset", "-", "generator's crossover"),
        ("dataset_hahner_sliders", ":", "Hahner's sliders"),
    ):
        rows = [r for r in result[key] if math.isfinite(r["visibility_m"])]
        v = [r["visibility_m"] for r in rows]
        right.plot(v, [r["lost_percent"] for r in rows], style, color="tab:blue",
                   marker="o", label=f"clear returns lost, {name}")  # fmt: skip
        right.plot(v, [r["fog_returns_percent"] for r in rows], style, color="tab:orange",
                   marker="s", label=f"fog's returns, {name}")  # fmt: skip
    right.set_xscale("log")
    right.set(xlabel="visibility (m)", ylabel="% of pulses", ylim=(0, 101),
              title=f"{result['samples']} sensor samples")  # fmt: skip
    right.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    run(main)
