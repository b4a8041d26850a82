"""Rain against what has been published: extinction, points lost and the drops' own returns.

    python benchmark/rain_check.py [--samples 512] [--out benchmark/results/rain]

1. **Extinction.** The generator's alpha (Mie theory over Marshall-Palmer drops at the
   receiver's wavelength, :func:`simlidar.sensor.scattering.rain_coefficients`; the drops as
   LISA, Kilic et al. 2021, draws them) beside Ulbrich & Atlas's fit for rain in the near
   infrared, k = 1.45 R^0.64 dB/km (the curve LISA validates its own against,
   ``python_old/mie_plots.py``; fitted over 1 to 20 mm/h), and beside the 0.01 R^0.6 per
   metre of Goodin et al. 2019's MAVS simulator (``lidar.cpp``, also LISA's ``msu_rain``),
   which is some 25 times stronger: the models in use disagree, and this says where ours
   sits.
2. **Range.** The range at which a target of reflectance 0.1 and 0.8 (square to the beam) drops
   below the VLP-16 receiver's threshold, by rain rate.
3. **The dataset.** ``--samples`` train samples of the ``sensor`` profile at each rate: the share
   of the clear-air returns lost, the share of pulses whose first return is a drop's (surface 0)
   and its median range.

No measured Velodyne curve of points lost against rain rate could be read here (Filgueira et
al. 2017 measured a VLP-16 in rain; only their abstract was reachable): the checks are against
the published extinction fit and LISA's own drop model (``tests/sensor/test_rain.py``).

Writes rain.md, rain.json and rain.png under ``--out``.
"""

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fog_check import weather_rows, write_results

from simlidar.generator.profiles import load_profile
from simlidar.generator.returns import receiver_physics
from simlidar.script_args import command_line, integers, run
from simlidar.sensor.raycast import MAX_BATCH
from simlidar.sensor.receiver import max_range_m
from simlidar.sensor.scattering import rain_coefficients

ROOT = Path(__file__).resolve().parents[1]
RATES = (0.0, 5.0, 10.0, 25.0, 50.0, 100.0, 200.0)  # mm/h
DB_PER_NEPER = 10.0 * math.log10(math.e)  # one-way dB per km = 4.343 x alpha per km
REFLECTANCES = (0.1, 0.8)


def ulbrich_atlas_db_per_km(rate_mm_h: float) -> float:
    """Ulbrich & Atlas's fit, k = 1.45 R^0.64 dB/km (as LISA's mie_plots.py quotes it)."""
    return 1.45 * rate_mm_h**0.64


def mavs_per_m(rate_mm_h: float) -> float:
    """Goodin et al. 2019's MAVS rain extinction, 0.01 R^0.6, per metre as its code uses it."""
    return 0.01 * rate_mm_h**0.6


def extinction() -> list[dict]:
    receiver = receiver_physics(load_profile("sensor")).receiver
    rows = []
    for rate in RATES[1:]:
        alpha = rain_coefficients(rate, receiver.wavelength_nm).extinction_per_m
        ours_db = DB_PER_NEPER * alpha * 1e3
        rows.append(
            {
                "rate_mm_h": rate,
                "alpha_per_m": alpha,
                "ours_db_per_km": ours_db,
                "ulbrich_atlas_db_per_km": ulbrich_atlas_db_per_km(rate),
                "ratio": ours_db / ulbrich_atlas_db_per_km(rate),
                "mavs_per_m": mavs_per_m(rate),
                "max_range_m": {
                    str(rho): float(max_range_m(receiver, rho, 0.0, alpha)) for rho in REFLECTANCES
                },
            }
        )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=integers(32, MAX_BATCH, one=True), default=512)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmark/results/rain")
    args = parser.parse_args(argv)
    receiver = receiver_physics(load_profile("sensor")).receiver
    result = {
        "command": command_line("rain_check.py", argv),
        "clear_max_range_m": {str(rho): float(max_range_m(receiver, rho)) for rho in REFLECTANCES},
        "extinction": extinction(),
        "dataset": weather_rows(args.samples, "rain_rate_mm_h", RATES),
        "samples": args.samples,
    }
    write_results(args.out, "rain", result, report, plot)
    return 0


def report(result: dict) -> str:
    lines = [
        "# Rain: extinction, points lost and the drops' own returns",
        "",
        f"Made by `{result['command']}` (`benchmark/rain_check.py`; its docstring says what is "
        "compared).",
        "",
        "## Extinction and maximum range by rain rate",
        "",
        "| rate (mm/h) | alpha (1/m) | ours (dB/km) | Ulbrich & Atlas (dB/km) | ours / U&A | "
        "MAVS (1/m) | max range, 0.1 (m) | max range, 0.8 (m) |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in result["extinction"]:
        reach = r["max_range_m"]
        lines.append(
            f"| {r['rate_mm_h']:g} | {r['alpha_per_m']:.3e} | {r['ours_db_per_km']:.2f} | "
            f"{r['ulbrich_atlas_db_per_km']:.2f} | {r['ratio']:.2f} | {r['mavs_per_m']:.3f} | "
            f"{reach['0.1']:.1f} | {reach['0.8']:.1f} |"
        )
    lines += [
        "",
        f"Clear air: 0.1 reaches {result['clear_max_range_m']['0.1']:.1f} m, 0.8 "
        f"{result['clear_max_range_m']['0.8']:.1f} m.",
        "",
        f"## {result['samples']} `sensor` samples by rain rate",
        "",
        "| rate (mm/h) | alpha (1/m) | clear returns lost | drops' returns (of pulses) | "
        "their median range (m) |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in result["dataset"]:
        median = r["weather_range_median_m"]
        median = "-" if median is None else f"{median:.2f}"
        lines.append(
            f"| {r['rain_rate_mm_h']:g} | {r['alpha']:.2e} | {r['lost_percent']:.2f} % | "
            f"{r['weather_returns_percent']:.3f} % | {median} |"
        )
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    left, right = fig.subplots(1, 2)
    rows = result["extinction"]
    rate = [r["rate_mm_h"] for r in rows]
    left.plot(rate, [r["ours_db_per_km"] for r in rows], "o-", label="ours (Marshall-Palmer, Q=2)")
    left.plot(rate, [r["ulbrich_atlas_db_per_km"] for r in rows], "s--",
              label="Ulbrich & Atlas, 1.45 R^0.64 (fit over 1-20 mm/h)")  # fmt: skip
    left.plot(rate, [DB_PER_NEPER * r["mavs_per_m"] * 1e3 for r in rows], "^:",
              label="MAVS, 0.01 R^0.6 per m")  # fmt: skip
    left.set_xscale("log")
    left.set_yscale("log")
    left.set(xlabel="rain rate (mm/h)", ylabel="one-way extinction (dB/km)", title="Extinction")
    left.legend(fontsize=7)
    rows = [r for r in result["dataset"] if r["rain_rate_mm_h"] > 0]
    rate = [r["rain_rate_mm_h"] for r in rows]
    right.plot(rate, [r["lost_percent"] for r in rows], "o-", label="clear returns lost")
    right.plot(rate, [r["weather_returns_percent"] for r in rows], "s-",
               label="drops' returns (of pulses)")  # fmt: skip
    right.set_xscale("log")
    right.set(xlabel="rain rate (mm/h)", ylabel="%",
              title=f"{result['samples']} sensor samples")  # fmt: skip
    right.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    run(main)
