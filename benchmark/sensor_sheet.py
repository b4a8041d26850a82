"""The receiver's calibration and its sensor sheet (issue 62, items 2 and 7): the simulated
sensor's curves beside the published and measured ones, with the residuals.

    python benchmark/sensor_sheet.py --fit            # fit sensitivity and asphalt roughness
    python benchmark/sensor_sheet.py                  # draw the sheet and its table
    python benchmark/sensor_sheet.py --doc docs/sensor-model.md   # and write the table there

**What is fitted.** Two numbers no source gives: the HDL-64E's sensitivity S = K / T (K = P_0
A_r eta / pi, T the detection threshold: a target of reflectance rho at normal incidence is
detected at half its pulses at sqrt(S rho)), and the roughness sigma of asphalt's Oren-Nayar
law (:mod:`simlidar.sensor.angle_laws`). They are fitted, on a grid, to the figures of
``benchmark/sensor_sheet/reference.toml``: the HDL-64E S2's two rated ranges (50 m at 0.10,
120 m at 0.80, read as the ranges of half detection; log range, weight 1 / 0.1^2) and the share
of firings that returned the road in six KITTI scans, ring by ring (weight 1 / 0.15^2). The
model's share on the road is the detection probability at the road's incidence (a flat road:
cos(theta) = h / R) averaged over asphalt's reflectance range in ``scenes/materials.toml``
(uniform, as the generator draws it), with the receiver's noise (:mod:`simlidar.sensor.detection`):
sigma_0 from the threshold and the false-alarm rate, shot noise of the signal. The VLP-16 has
no rated reflectance: its sensitivity is the HDL-64E's scaled by (100 m / 120 m)^2, their rated
ranges (assumption: both rated alike). ``--fit`` prints the fitted values and the receiver-file
lines they make; a test holds the shipped files to them.

**The sheet** (``docs/img/sensor-sheet.png`` and a table, between the lines ``START`` and
``END`` of ``--doc``): range of half detection against reflectance (ratings beside), the road's
detected share against range (KITTI beside), the VLP-16's road rings, the fog's and the rain's
extinction and backscatter against visibility and rain rate (Hahner et al.'s and the
receiver's before issue 62 beside Mie's); each measured figure with the model's value and the
residual. Writes ``benchmark/results/sensor-sheet/sheet.json``.
"""

import argparse
import json
import math
import sys
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import reproduction_table

from simlidar.atomic import write_file
from simlidar.script_args import command_line, run
from simlidar.sensor.angle_laws import angle_factor
from simlidar.sensor.detection import detection_probability
from simlidar.sensor.model import load_sensor
from simlidar.sensor.receiver import load_materials, load_receiver, signal_noise_w

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "benchmark/sensor_sheet/reference.toml"
OUT = ROOT / "benchmark/results/sensor-sheet"
PICTURE = ROOT / "docs/img/sensor-sheet.png"
START = "<!-- sensor-sheet:start -->"
END = "<!-- sensor-sheet:end -->"
RATING_TOLERANCE = 0.1  # log range
ROAD_TOLERANCE = 0.15  # share of firings
SENSITIVITIES = np.geomspace(1e4, 1e5, 121)  # m^2
ROUGHNESS_DEG = np.arange(0.0, 90.5, 2.0)
# assumption: a false alarm in 1 of 10,000 pulses' listening windows sets T / sigma_0
FALSE_ALARM_SHARE = 1e-4


def reference() -> dict:
    return tomllib.loads(REFERENCE.read_text())


def asphalt_range() -> tuple[float, float]:
    materials, _ = load_materials()
    m = materials["asphalt"]
    return m.reflectance_min, m.reflectance_max


def road_share(receiver, sensitivity: float, roughness_deg: float, range_m, mount_m: float):
    """The share of pulses a flat asphalt road returns at ``range_m`` to ``receiver`` made of
    ``sensitivity`` (:func:`calibrated`): the detection probability averaged over asphalt's
    reflectance range."""
    low, high = asphalt_range()
    rho = np.linspace(low, high, 201)[:, None]
    r = np.asarray(range_m, dtype=np.float64)[None, :]
    f = angle_factor("oren_nayar", np.clip(mount_m / r, 0.0, 1.0), roughness_deg)
    mine = calibrated(receiver, sensitivity)
    signal = constant_w(mine) * rho * f / r**2
    sigma = signal_noise_w(mine, signal, rho * f)
    return detection_probability(signal, mine.threshold_w, sigma).mean(axis=0)


def constant_w(receiver) -> float:
    """K = P_0 A_r eta / pi (W m^2): a target of rho at R returns K rho f / R^2."""
    return receiver.peak_power_w * receiver.aperture_area_m2 * receiver.optics_efficiency / math.pi


def listen_s(receiver) -> float:
    """A pulse listens 2 R_max / c (its sensor's range)."""
    return 2.0 * load_sensor(receiver.name).max_range_m / 299_792_458.0


def threshold_snr(receiver) -> float:
    """T / sigma_0 for ``FALSE_ALARM_SHARE`` of a pulse's listening windows with a false alarm
    (Rice's rate, :func:`simlidar.sensor.detection.threshold_for_rate`)."""
    rate = FALSE_ALARM_SHARE / listen_s(receiver)
    return math.sqrt(2.0 * math.log(receiver.bandwidth_hz / math.sqrt(3.0) / rate))


def calibrated(receiver, sensitivity: float):
    """``receiver`` with the threshold of ``sensitivity`` (T = K / S) and the noise sigma_0 =
    T / :func:`threshold_snr`."""
    threshold = constant_w(receiver) / sensitivity
    return replace(receiver, threshold_w=threshold, noise_w=threshold / threshold_snr(receiver))


def fit(ref: dict) -> dict:
    """The grid's best sensitivity and roughness, with each figure's residual."""
    road = ref["road"]
    receiver = load_receiver(road["sensor"])
    ratings = [r for r in ref["rating"] if r["sensor"] == road["sensor"]]
    measured = np.asarray(road["detected"])
    best = None
    for roughness in ROUGHNESS_DEG:
        for s in SENSITIVITIES:
            share = road_share(receiver, s, roughness, road["range_m"], road["mount_height_m"])
            loss = float((((share - measured) / ROAD_TOLERANCE) ** 2).sum())
            loss += sum(
                ((0.5 * math.log(s * r["reflectance"]) - math.log(r["range_m"])) / RATING_TOLERANCE)
                ** 2
                for r in ratings
            )
            if best is None or loss < best[0]:
                best = (loss, float(s), float(roughness))
    loss, sensitivity, roughness = best
    share = road_share(receiver, sensitivity, roughness, road["range_m"], road["mount_height_m"])
    return {
        "sensor": road["sensor"],
        "sensitivity_m2": sensitivity,
        "roughness_deg": roughness,
        "threshold_snr": threshold_snr(receiver),
        "loss": loss,
        "ratings": [
            {
                "reflectance": r["reflectance"],
                "rated_m": r["range_m"],
                "model_m": math.sqrt(sensitivity * r["reflectance"]),
            }
            for r in ratings
        ],
        "road": [
            {"range_m": r, "measured": m, "model": float(v)}
            for r, m, v in zip(road["range_m"], road["detected"], share, strict=True)
        ],
    }


def receiver_values(result: dict) -> dict[str, dict[str, float]]:
    """The threshold and noise each shipped receiver takes from the fit: the HDL-64E's own,
    the VLP-16's sensitivity scaled by its rated range over the HDL-64E's, squared."""
    values = {}
    for name in ("hdl64e", "vlp16"):
        receiver = load_receiver(name)
        scale = (receiver.rated_range_m / load_receiver(result["sensor"]).rated_range_m) ** 2
        mine = calibrated(receiver, result["sensitivity_m2"] * scale)
        values[name] = {"threshold_w": mine.threshold_w, "noise_w": mine.noise_w}
    return values


OLD_SENSITIVITY = {"vlp16": 100.0**2 / 0.8, "hdl64e": 120.0**2 / 0.8}  # before issue 62
VLP16_ELEVATIONS = np.arange(-15.0, 0.0, 2.0)
# measured reflectivity bytes of road returns against incidence (docs/research notes)
BYTES = [
    ("HDL-32E, nuScenes sample sweep, road", (69.0, 85.0), (5.0, 17.0)),
    ("VLP-16, sample pcap, ground (surface unknown)", (73.0, 81.0), (4.0, 7.0)),
]
ULBRICH_ATLAS = (1.45, 0.64)  # k = 1.45 R^0.64 dB/km (Ulbrich & Atlas, as LISA's mie_plots.py)


def old_share(sensitivity: float, range_m, mount_m: float):
    """The receiver before issue 62 on the same road: Lambert, a deterministic threshold."""
    low, high = asphalt_range()
    rho = np.linspace(low, high, 201)[:, None]
    r = np.asarray(range_m, dtype=np.float64)[None, :]
    return (sensitivity * rho * np.clip(mount_m / r, 0, 1) / r**2 >= 1.0).mean(axis=0)


def sheet(result: dict, ref: dict) -> dict:
    """Every curve of the sheet and its table's rows (JSON-able)."""
    from simlidar.sensor.scattering import fog_coefficients, load_atmosphere, rain_coefficients

    road = ref["road"]
    hdl = load_receiver("hdl64e")
    vlp = load_receiver("vlp16")
    ranges = np.linspace(5.0, 90.0, 86)
    curves = {
        "road_range_m": ranges.tolist(),
        "road_calibrated": road_share(
            hdl, sensitivity_of(hdl), result["roughness_deg"], ranges, road["mount_height_m"]
        ).tolist(),
        "road_before": old_share(
            OLD_SENSITIVITY["hdl64e"], ranges, road["mount_height_m"]
        ).tolist(),
    }
    mount = load_sensor("vlp16").mount_height_m
    ring_m = mount / np.sin(np.radians(-VLP16_ELEVATIONS))
    curves["vlp16_ring_elevation_deg"] = VLP16_ELEVATIONS.tolist()
    curves["vlp16_ring_range_m"] = ring_m.tolist()
    curves["vlp16_ring_calibrated"] = road_share(
        vlp, sensitivity_of(vlp), result["roughness_deg"], ring_m, mount
    ).tolist()
    curves["vlp16_ring_before"] = old_share(OLD_SENSITIVITY["vlp16"], ring_m, mount).tolist()
    visibilities = [200.0, 100.0, 50.0, 30.0]
    rates = [1.0, 10.0, 25.0, 50.0, 100.0, 200.0]
    fogs = {
        name: [fog_coefficients(v, vlp.wavelength_nm, name).backscatter_per_m_sr * v
               for v in visibilities]
        for name in load_atmosphere().fogs
    }  # fmt: skip
    rain_alpha = [rain_coefficients(r, vlp.wavelength_nm).extinction_per_m for r in rates]
    rain_beta = [rain_coefficients(r, vlp.wavelength_nm).backscatter_per_m_sr for r in rates]
    a, b = ULBRICH_ATLAS
    fitted = [a * r**b / (10 * math.log10(math.e)) / 1000.0 for r in rates]  # dB/km -> 1/m
    curves.update(
        visibilities_m=visibilities,
        fog_beta_times_v=fogs,
        fog_lidar_ratio_sr={
            n: fog_coefficients(50.0, vlp.wavelength_nm, n).lidar_ratio_sr for n in fogs
        },
        rain_rate_mm_h=rates,
        rain_extinction_per_m=rain_alpha,
        rain_backscatter_per_m_sr=rain_beta,
        rain_ulbrich_atlas_per_m=fitted,
    )
    angles = np.linspace(0.0, 89.0, 90)
    asphalt = load_materials()[0]["asphalt"]
    curves["incidence_deg"] = angles.tolist()
    curves["asphalt_byte_calibrated"] = (
        100 * asphalt.reflectance * asphalt.angle_factor(np.cos(np.radians(angles)))
    ).tolist()
    rows = [
        {
            "figure": f"HDL-64E S2 range at reflectance {r['reflectance']:g}",
            "measured": f"{r['rated_m']:g} m (rated)",
            "simulated": f"{r['model_m']:.1f} m",
            "residual": f"{100 * (r['model_m'] / r['rated_m'] - 1):+.0f} %",
        }
        for r in result["ratings"]
    ]
    residual = np.array([p["model"] - p["measured"] for p in result["road"]])
    rows.append(
        {
            "figure": f"HDL-64E road returned, {len(residual)} ring-corridor shares at "
            f"{min(road['range_m']):g}-{max(road['range_m']):g} m (six KITTI scans)",
            "measured": f"{min(road['detected']):.2f}-{max(road['detected']):.2f}",
            "simulated": "see the picture",
            "residual": f"RMS {np.sqrt(np.mean(residual**2)):.2f}, "
            f"largest {residual[np.argmax(abs(residual))]:+.2f}",
        }
    )
    for label, (low_deg, high_deg), (low_b, high_b) in BYTES:
        inside = (angles >= low_deg) & (angles <= high_deg)
        model = np.asarray(curves["asphalt_byte_calibrated"])[inside]
        rows.append(
            {
                "figure": f"reflectivity byte of {label}, incidence {low_deg:g}-{high_deg:g} deg",
                "measured": f"{low_b:g}-{high_b:g} (median range)",
                "simulated": f"{model.min():.1f}-{model.max():.1f} (asphalt, nominal 0.10)",
                "residual": "inside"
                if low_b <= model.min() and model.max() <= high_b
                else "outside",
            }
        )
    rings = zip(
        curves["vlp16_ring_elevation_deg"], curves["vlp16_ring_range_m"],
        curves["vlp16_ring_calibrated"], curves["vlp16_ring_before"], strict=True,
    )  # fmt: skip
    for elevation, ring_m, now, before in rings:
        if -7.0 <= elevation <= -1.0:
            rows.append(
                {
                    "figure": f"VLP-16 asphalt ring {elevation:g} deg ({ring_m:.0f} m), "
                    "share returned",
                    "measured": "(no measurement found)",
                    "simulated": f"{now:.2f} (before 5.0.0: {before:.2f})",
                    "residual": "",
                }
            )
    for name, ratio in curves["fog_lidar_ratio_sr"].items():
        rows.append(
            {
                "figure": f"fog lidar ratio at 903 nm, {name.replace('_', ' ')} fog",
                "measured": "65 sr (Hahner et al.'s 0.046 / V, source not found)",
                "simulated": f"{ratio:.1f} sr (Mie)",
                "residual": "",
            }
        )
    for rate, mine, theirs in zip(rates, rain_alpha, fitted, strict=True):
        if rate in (10.0, 50.0):
            rows.append(
                {
                    "figure": f"rain extinction at {rate:g} mm/h",
                    "measured": f"{theirs * 1e3:.2f} per km (Ulbrich & Atlas fit)",
                    "simulated": f"{mine * 1e3:.2f} per km (Mie, Marshall-Palmer)",
                    "residual": f"{100 * (mine / theirs - 1):+.0f} %",
                }
            )
    for share in weather_shares():
        rows.append(
            {
                "figure": f"{share['weather']}: pulses a surface returns; the weather's own "
                "returns (median range)",
                "measured": "(no measurement reached)",
                "simulated": f"{share['surfaces']:.3f}; {share['own']:.4f}"
                + (f" ({share['own_median_m']:.1f} m)" if share["own_median_m"] else ""),
                "residual": "",
            }
        )
    return {"curves": curves, "rows": rows}


WEATHER_SAMPLES = 256  # train samples of each weather's small dataset (4 classes)
VISIBILITIES_M = (500.0, 200.0, 50.0, 20.0)
RAIN_RATES = (10.0, 50.0, 200.0)


def weather_shares() -> list[dict]:
    """The share of all pulses the fog or the drops return (surface 0) and the share of
    pulses a surface returns, in clear air and in each weather, on small ``sensor`` datasets
    (4 classes, ``WEATHER_SAMPLES`` train samples, seed 0, noise 0): made in a temporary folder
    with ``simlidar generate``'s code."""
    import tempfile

    import h5py

    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.generate import generate
    from simlidar.generator.profiles import load_profile
    from simlidar.scene.recipe import load_catalog

    catalog = load_catalog()
    weathers = [("clear air", {})]
    weathers += [(f"fog V = {v:g} m", {"fog_visibility_m": v}) for v in VISIBILITIES_M]
    weathers += [(f"rain {r:g} mm/h", {"rain_rate_mm_h": r}) for r in RAIN_RATES]
    shares = []
    with tempfile.TemporaryDirectory() as folder:
        for i, (label, options) in enumerate(weathers):
            config = GeneratorConfig.from_profile(
                load_profile("sensor"), classes=4, train_size=WEATHER_SAMPLES, test_size=32,
                **options,
            )  # fmt: skip
            (written,) = generate(
                config, [0.0], catalog, Path(folder) / str(i), progress=False, preview=False
            )
            with h5py.File(written.path / "train.h5") as f:
                returned = f["delays"][:] < 1.0
                own = returned & (f["surface"][:] == 0)
                near = f["tof_ns"][:][own] * 0.299792458 / 2.0
            shares.append(
                {
                    "weather": label,
                    "surfaces": float((returned & ~own).mean()),
                    "own": float(own.mean()),
                    "own_median_m": float(np.median(near)) if len(near) else None,
                }
            )
    return shares


def sensitivity_of(receiver) -> float:
    """A shipped receiver's sensitivity K / T (m^2)."""
    return constant_w(receiver) / receiver.threshold_w


def table(rows: list[dict]) -> str:
    lines = [
        "| figure | measured | simulated | residual |",
        "| --- | --- | --- | --- |",
    ]
    lines += [
        f"| {r['figure']} | {r['measured']} | {r['simulated']} | {r['residual']} |" for r in rows
    ]
    return "\n".join(lines)


def draw(result: dict, ref: dict, made: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    c = made["curves"]
    fig = Figure(figsize=(15, 9))
    ax = fig.subplots(2, 3)
    rho = np.geomspace(0.02, 1.0, 100)
    for name, colour in (("hdl64e", "C0"), ("vlp16", "C1")):
        receiver = load_receiver(name)
        ax[0, 0].plot(rho, np.sqrt(sensitivity_of(receiver) * rho), "-", color=colour,
                      label=f"{name}, calibrated")  # fmt: skip
        ax[0, 0].plot(rho, np.sqrt(OLD_SENSITIVITY[name] * rho), ":", color=colour,
                      label=f"{name}, before")  # fmt: skip
    for r in result["ratings"]:
        ax[0, 0].plot(r["reflectance"], r["rated_m"], "ks")
    ax[0, 0].plot([], [], "ks", label="HDL-64E S2 rated")
    ax[0, 0].set(xscale="log", xlabel="reflectance (normal incidence)",
                 ylabel="range of half detection (m)",
                 title="Range against reflectance")  # fmt: skip
    ax[0, 0].legend(fontsize=7)
    road = ref["road"]
    ax[0, 1].plot(c["road_range_m"], c["road_calibrated"], "C0-", label="calibrated")
    ax[0, 1].plot(c["road_range_m"], c["road_before"], "C0:", label="before (Lambert)")
    ax[0, 1].plot(road["range_m"], road["detected"], "ks", label="KITTI, six scans")
    ax[0, 1].set(xlabel="range along the road (m)", ylabel="share of pulses returned",
                 title="HDL-64E: the road ahead (1.76 m up)", ylim=(-0.02, 1.05))  # fmt: skip
    ax[0, 1].legend(fontsize=7)
    x = np.arange(len(c["vlp16_ring_elevation_deg"]))
    ax[0, 2].bar(x - 0.2, c["vlp16_ring_calibrated"], 0.4, label="calibrated")
    ax[0, 2].bar(x + 0.2, c["vlp16_ring_before"], 0.4, label="before")
    ax[0, 2].set_xticks(
        x,
        [
            f"{e:g}°\n{r:.0f} m"
            for e, r in zip(c["vlp16_ring_elevation_deg"], c["vlp16_ring_range_m"])
        ],
        fontsize=7,
    )
    ax[0, 2].set(ylabel="share of pulses returned", title="VLP-16: asphalt rings (1.8 m up)")
    ax[0, 2].legend(fontsize=7)
    ax[1, 0].plot(c["incidence_deg"], c["asphalt_byte_calibrated"], "C0-",
                  label="asphalt 0.10, calibrated")  # fmt: skip
    ax[1, 0].axhline(10, color="C0", ls=":", label="asphalt 0.10, before")
    for (label, (a0, a1), (b0, b1)), colour in zip(BYTES, ("C2", "C3")):
        ax[1, 0].fill_between([a0, a1], b0, b1, color=colour, alpha=0.3, label=label)
    ax[1, 0].set(xlabel="incidence (deg)", ylabel="reflectivity byte",
                 title="Intensity against incidence")  # fmt: skip
    ax[1, 0].legend(fontsize=6)
    v = c["visibilities_m"]
    for name, values in c["fog_beta_times_v"].items():
        ax[1, 1].plot(v, values, "o-", label=f"Mie, {name.replace('_', ' ')} fog")
    ax[1, 1].plot(v, [0.046] * len(v), "k:", label="Hahner et al. 0.046 / V (before)")
    ax[1, 1].set(xscale="log", ylim=(0, 0.2), xlabel="visibility V (m)",
                 ylabel="backscatter x V (1/sr)", title="Fog backscatter at 903 nm")  # fmt: skip
    ax[1, 1].legend(fontsize=7)
    rate = c["rain_rate_mm_h"]
    ax[1, 2].plot(rate, np.array(c["rain_extinction_per_m"]) * 1e3, "C0o-", label="extinction, Mie")
    ax[1, 2].plot(rate, np.array(c["rain_ulbrich_atlas_per_m"]) * 1e3, "k:",
                  label="extinction, Ulbrich & Atlas fit")  # fmt: skip
    ax[1, 2].plot(rate, np.array(c["rain_backscatter_per_m_sr"]) * 1e3, "C1s-",
                  label="backscatter (per km sr), Mie")  # fmt: skip
    ax[1, 2].set(xscale="log", yscale="log", xlabel="rain rate (mm/h)", ylabel="per km",
                 title="Rain at 903 nm")  # fmt: skip
    ax[1, 2].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fit", action="store_true", help="fit and print, writing nothing")
    parser.add_argument(
        "--doc",
        type=reproduction_table.markdown_file,
        metavar="FILE",
        help=f"also write the table into FILE between its lines {START} and {END}",
    )
    args = parser.parse_args(argv)
    if args.doc is not None:  # its markers, before anything is computed
        reproduction_table.split(args.doc.read_text(), args.doc, START, END)
    ref = reference()
    result = fit(ref)
    result["receivers"] = receiver_values(result)
    if args.fit:
        print(json.dumps(result, indent=1))
        return 0
    made = sheet(result, ref)
    OUT.mkdir(parents=True, exist_ok=True)
    result["command"] = command_line("sensor_sheet.py", argv)
    (OUT / "sheet.json").write_text(json.dumps(result | made, indent=1) + "\n")
    draw(result, ref, made, PICTURE)
    text = table(made["rows"])
    print(text)
    if args.doc is not None:
        before, _, after = reproduction_table.split(args.doc.read_text(), args.doc, START, END)
        write_file(args.doc, lambda t: t.write_text(before + text + after))
        print(f"{args.doc}: wrote the sensor sheet's table")
    return 0


if __name__ == "__main__":
    run(main)
