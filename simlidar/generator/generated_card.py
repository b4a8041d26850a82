"""The generator's release files: its datasets' card (``README.md``: Hugging Face front matter
and a datasheet) and Croissant description, made from :mod:`simlidar.generator.about` and the
split files' own attributes."""

import math
from functools import cache
from pathlib import Path

from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.schema import SCHEMA, SPLITS, generated_schema, reported_returns
from simlidar.dataset.shards import SHARD_SAMPLES
from simlidar.dataset.version import RELEASE_DATES, RELEASE_NOTES, notes_until
from simlidar.errors import ConfigError, DatasetError
from simlidar.generator.about import (
    CITATION,
    CREATOR,
    DELAY_MEANING,
    DISTRIBUTION,
    HOMEPAGE,
    LICENSE,
    LICENSE_URL,
    MAINTENANCE,
    MOTIVATION,
    NAME,
    OUT_OF_SCOPE,
    PREPROCESSING,
    USES,
    description,
    tags,
)
from simlidar.generator.config import GeneratorConfig
from simlidar.release.card import (
    card_head,
    class_table,
    hf_feature,
    hf_front_matter,
    table,
)
from simlidar.release.croissant import CONTEXT, field, file_objects
from simlidar.release.info import dataset_info
from simlidar.sensor.footprint import subray_count
from simlidar.sensor.model import Sensor, load_sensor, sensor_names
from simlidar.sensor.receiver import koschmieder_extinction_per_m
from simlidar.sensor.weather import CROSSOVER_M, rain_extinction_per_m

_DOCS = {  # one line per dataset of a split file; the full table is docs/dataset-format.md
    "delays": "normalised delays with noise: the network input (1.0 = no return)",
    "clean_delays": "the same pulses without noise",
    "tof_ns": "round-trip time of flight, ns (NaN = no return)",
    "surface": "surface label of what each pulse hit (0 = none)",
    "labels": "class index",
    "layout": "road layout index",
    "object": "object index (0 = none)",
    "object_pose": "object x_m, y_m, yaw_deg (NaN without object)",
    "object_hits": "pulses that hit the labelled object",
    "attempts": "scene draws until the object and layout were seen",
    "phase": "head rotation phase, in azimuth steps",
    "shift": "delay shift applied to the sample's returns",
    "emission_ns": "when each pulse left the sensor, ns from the window's first firing",
    "intensity": "the receiver's reflectivity byte of each return (0 = no return)",
    "reflectance": "drawn reflectance of the surface each pulse hit (NaN = nothing hit)",
    "power_w": "received power of the hit, W, detected or not (0 = nothing hit)",
    "echoes": "echoes of each pulse's waveform at or above the receiver's threshold",
    "returns_tof_ns": "time of flight of each reported return, ns (NaN = none)",
    "returns_intensity": "reflectivity byte of each reported return (0 = none)",
    "returns_surface": "surface label of each reported return (0 = none)",
    "waveform": "each pulse's received waveform, W, sampled every `waveform_bin_ns` from its "
    "emission",
    "object_motion": "object's speed m/s, heading deg, yaw rate deg/s as drawn (0 = still)",
    "ego_motion": "the ego's speed m/s and yaw rate deg/s",
}


def _schema(config: GeneratorConfig, attrs) -> dict:
    """The datasets a generated split of ``config`` and ``attrs`` holds (generated_schema)."""
    returns, bins = reported_returns(attrs), attrs.get("waveform_bins", 0)
    return generated_schema(config.timing, "receiver" in attrs, returns, bins, config.moves)


def stored_config(info) -> GeneratorConfig:
    """The configuration a generated split (a :class:`~simlidar.dataset.reader.SplitInfo`)
    stores; a DatasetError naming the file and the key when it is not one."""
    try:
        return GeneratorConfig.from_dict(info.attrs["config"])
    except ConfigError as exc:
        raise DatasetError(f"{info.path}: attribute 'config': {exc}") from None


def generated_front_matter(path: Path) -> dict:
    """The YAML front matter (Hugging Face dataset card metadata) of a dataset directory."""
    splits = dataset_splits(path)
    attrs = splits["train"].attrs
    height, width = splits["train"].height, splits["train"].width
    config = stored_config(splits["train"])
    features = [
        hf_feature(name, dtype, tail(height, width), attrs["class_names"])
        for name, (dtype, tail) in _schema(config, attrs).items()
    ]
    title = f"{NAME}, {attrs['classes']} classes, noise {attrs['noise']}"
    config_name = f"noise{float(attrs['noise'])!r}"
    if config.profile is not None:  # the physical profile's card keeps the 1.0.0 names
        title = f"{title}, profile {config.profile_name}"
        config_name = f"{config_name}-{config.profile_name}"
    over = config.overrides
    if "variation" in over:
        title, config_name = (
            f"{title}, scene variation {over['variation']!r}",
            f"{config_name}-var{over['variation']!r}",
        )
    if "shift_max" in over:
        title, config_name = (
            f"{title}, delay shift {over['shift_max']!r}",
            f"{config_name}-shift{over['shift_max']!r}",
        )
    sensor = Sensor.from_dict(attrs["sensor"])
    if sensor.name != "vlp16":
        title, config_name = f"{title}, sensor {sensor.name}", f"{config_name}-{sensor.name}"
    if config.timing == "scan":
        title, config_name = f"{title}, scan timing", f"{config_name}-scan"
    if config.moves:
        title, config_name = f"{title}, in motion", f"{config_name}{config.motion_tag}"
    return hf_front_matter(splits, features, LICENSE, title, tags(sensor), config_name)


@cache
def _shipped_catalog_sha256(sensor: str) -> str:
    """The fingerprint of the shipped catalog as ``sensor`` sees it."""
    from simlidar.scene.recipe import load_catalog

    return load_catalog().for_sensor(sensor).fingerprint()


def shard_option(splits: dict) -> int | None:
    """The shard size that writes these splits' files again (their names and bytes); None
    where the default (:data:`~simlidar.dataset.shards.SHARD_SAMPLES`) does."""
    sharded = [info for info in splits.values() if info.sharded]
    if sharded:
        size = sharded[0].sizes[0]
    else:
        size = max(info.size for info in splits.values())
        if size <= SHARD_SAMPLES:
            return None
    return None if size == SHARD_SAMPLES else size


def regenerate_command(
    config: GeneratorConfig, catalog_sha256: str, shard_samples: int | None = None
) -> str:
    """The command that writes this dataset again, bit for bit (or the Python equivalent);
    ``shard_samples``: a shard size other than the default (:func:`shard_option`)."""
    from simlidar.generator.profiles import load_profile, profile_names

    default = GeneratorConfig()
    cli_fields = {
        "classes",
        "noise",
        "train_size",
        "test_size",
        "seed",
        "width",
        "shift_max",
        "variation",
        "profile",
        "sensor",
        "timing",
        "fog_visibility_m",
        "rain_rate_mm_h",
        "beam_samples",
        "return_mode",
        "waveform_bin_ns",
        "ego_speed_mps",
        "ego_yaw_rate_deg_s",
        "moving_objects",
    }
    other = {k for k, v in config.to_dict().items() if k not in cli_fields}
    shipped = config.profile is None or (
        config.profile.name in profile_names()
        and load_profile(config.profile.name) == config.profile
    )
    sensor = config.sensor
    shipped &= sensor.name in sensor_names() and load_sensor(sensor.name) == sensor
    if not shipped or any(config.to_dict()[k] != default.to_dict()[k] for k in other):
        return (
            "from simlidar.generator.config import GeneratorConfig\n"
            "from simlidar.generator.generate import generate\n"
            "from simlidar.scene.recipe import load_catalog\n"
            f"config = GeneratorConfig.from_dict({config.to_dict()!r})\n"
            f"generate(config, [{config.noise!r}], load_catalog(CATALOG), 'data'"
            + (f", shard_samples={shard_samples}" if shard_samples else "")
            + ")"
            f"  # CATALOG: the scene catalog with sha256 {catalog_sha256}"
        )
    parts = [
        "simlidar generate",
        f"--profile {config.profile_name}",
        f"--classes {config.classes}",
        f"--noise {config.noise!r}",
        f"--train-size {config.train_size}",
        f"--test-size {config.test_size}",
        f"--seed {config.seed}",
        f"--width {config.width}",
    ]
    if sensor.name != "vlp16":
        parts.append(f"--sensor {sensor.name}")
    if config.timing != "flash":
        parts.append(f"--timing {config.timing}")
    if math.isfinite(config.fog_visibility_m):
        parts.append(f"--fog {config.fog_visibility_m!r}")
    if config.rain_rate_mm_h:
        parts.append(f"--rain {config.rain_rate_mm_h!r}")
    if config.beam_samples != 1:
        parts.append(f"--beam-samples {config.beam_samples}")
    if config.return_mode != "strongest":
        parts.append(f"--return-mode {config.return_mode}")
    if config.waveform_bin_ns:
        parts.append(f"--waveform-bin {config.waveform_bin_ns!r}")
    if config.ego_speed_mps:
        parts.append(f"--ego-speed {config.ego_speed_mps!r}")
    if config.ego_yaw_rate_deg_s:
        parts.append(f"--ego-yaw-rate {config.ego_yaw_rate_deg_s!r}")
    if config.moving_objects:
        parts.append("--moving-objects")
    over = config.overrides
    if "shift_max" in over:
        parts.append(f"--shift {config.shift_max!r}")
    if "variation" in over:
        parts.append(f"--variation {config.variation!r}")
    if shard_samples:
        parts.append(f"--shard-size {shard_samples}")
    if catalog_sha256 != _shipped_catalog_sha256(sensor.name):
        parts.append(f"--scenes CATALOG  # the scene catalog with sha256 {catalog_sha256}")
    return " ".join(parts)


def _shards_line(splits: dict) -> str:
    """The Distribution paragraph's words on shard files (none for one-file splits)."""
    sharded = {s: info for s, info in splits.items() if info.sharded}
    if not sharded:
        return ""
    parts = [
        f"the {s} split is {len(i.files)} files, `{i.files[0].name}` to `{i.files[-1].name}`, "
        f"of {i.sizes[0]} samples each (the last: {i.sizes[-1]})"
        for s, i in sharded.items()
    ]
    return (
        " Sharded (the Hugging Face convention): " + "; ".join(parts) + ". Each shard is a "
        "complete split file with its index and count in the attributes `shard` and `shards`; "
        "`load_split` and `PulseDataset` read a split's shards in order."
    )


def _profile_line(config: GeneratorConfig) -> str:
    rule = config.pulse_rule
    return (
        f"missing return written as {rule['missing_delay']!r}, noise on "
        f"{'every pixel' if rule['noise_on'] == 'all' else 'returns only'}, input spikes: "
        f"{'every pixel' if rule['spikes'] == 'all' else 'returns only'}; scene variation "
        f"{config.variation!r}, delay shift {config.shift_max!r}"
        + (f", receiver `{config.receiver}`" if config.receiver is not None else "")
        + " (simlidar's `docs/profiles.md`)"
    )


def _noised(config: GeneratorConfig) -> str:
    return "every pixel" if config.pulse_rule["noise_on"] == "all" else "every pulse"


def _noise_details(config: GeneratorConfig) -> str:
    every = config.pulse_rule["noise_on"] == "all"
    shift = config.shift_max
    return (", on every pixel: a missing return (0.0) reads U(0, a)" if every else "") + (
        f"; each sample's returns shifted by U(-{shift!r}, {shift!r}) before noise" if shift else ""
    )


_TIMING_LINE = {
    "flash": "`flash`: a delay is the pulse's time of flight (the paper's)",
    "scan": "`scan`: a delay is the pulse's arrival time in the sweep (emission + time of flight)",
}


def _missing_meaning(config: GeneratorConfig) -> str:
    text = ""
    if config.pulse_rule["missing_delay"] != 1.0:
        text = (
            " Under this dataset's profile a missing return is written as 0.0 (before noise), "
            "not 1.0, and every pixel is an input spike (the paper's protocol)."
        )
    if config.receiver is not None:
        text += (
            " Under this dataset's receiver a hit too weak to detect is no return too (a "
            "drop-out: `power_w` > 0 where `tof_ns` is NaN), and a return's time of flight "
            "carries the receiver's range noise (in `clean_delays` too: clean means without "
            "the U(0, a) noise)."
        )
    if config.timing == "scan":
        text += (
            f" Scan timing: each value is then made the pulse's arrival time in the sweep, "
            f"its emission time (`emission_ns`: firing order, cycle, column) plus that time of "
            f"flight, divided by the attribute `delay_unit_ns` ({config.scan_window_ns / 1e6:.4f} "
            "ms); 1.0 stays 1.0."
        )
    return text


def _motion_lines(attrs, config: GeneratorConfig) -> str:
    """The Generation process paragraph on motion (none where nothing moves)."""
    if not config.moves:
        return ""
    ego = (
        f"the ego vehicle drives at {config.ego_speed_mps!r} m/s with a yaw rate of "
        f"{config.ego_yaw_rate_deg_s!r} deg/s"
        if config.ego_speed_mps or config.ego_yaw_rate_deg_s
        else "the ego vehicle stands"
    )
    things = "the objects stand"
    if "motion" in attrs:
        tables = "; ".join(
            f"`{name}` " + ", ".join(f"{key} {value}" for key, value in table.items())
            for name, table in attrs["motion"].items()
        )
        things = (
            f"each scene's object moves as the scene catalog's motion table says ({tables}; "
            f"sha256 `{attrs['motion_sha256']}`), drawn after the scene's own parameters "
            "(`object_motion`)"
        )
    return (
        f"In motion: {ego}, and {things}. Every pulse is cast at its own emission time "
        "(`emission_ns`), exactly for rigid motion: t = 0 is the window's first firing, the "
        "sensor then at the scene's origin and the object at `object_pose`; the light's own "
        'flight is left out (simlidar\'s `docs/sweeps.md`, "Motion").\n'
    )


def _receiver_lines(attrs, config: GeneratorConfig) -> str:
    """The Generation process paragraph on the receiver (none without one)."""
    if "receiver" not in attrs:
        return ""
    receiver, surfaces = attrs["receiver"], attrs["materials"]["surfaces"]
    air = "(no atmosphere)"
    weather = []
    if math.isfinite(config.fog_visibility_m):
        alpha = koschmieder_extinction_per_m(config.fog_visibility_m)
        weather.append(
            f"fog of visibility {config.fog_visibility_m:g} m: two-way extinction "
            f"exp(-2 alpha R), alpha = ln(20) / V = {alpha:.4g} per m, "
            "Koschmieder's law; the fog's own backscatter, beta = 0.046 / V per m and sr "
            "(Hahner et al. 2021), joins each pulse's waveform"
        )
    if config.rain_rate_mm_h:
        alpha = rain_extinction_per_m(config.rain_rate_mm_h)
        weather.append(
            f"rain of {config.rain_rate_mm_h:g} mm/h: two-way extinction by drops of the "
            f"Marshall-Palmer distribution, alpha = {alpha:.4g} per m; the echoes of the drops "
            "in each beam (LISA, Kilic et al. 2021) join its waveform"
        )
    if weather:
        air = (
            "(" + "; ".join(weather) + ", seen by the receiver from "
            f"{CROSSOVER_M[0]:.2f} m, wholly from {CROSSOVER_M[1]:.2f} m (an assumed biaxial "
            "geometry))"
        )
    return (
        f"Receiver: a hit returns only when the {receiver['model']} receiver detects it "
        f"(`sensors/receivers/{receiver['name']}.toml`, values from {receiver['manual']} and "
        f"the sources it cites; sha256 `{attrs['receiver_sha256']}`): received power by the "
        "LiDAR range equation from the range, the surface's reflectance and the incidence angle "
        f"{air}, at least the threshold {receiver['threshold_w']:g} W; a return "
        f"moves by Gaussian range noise of {receiver['accuracy_m']:g} m x sqrt(threshold / "
        "power) before the range is quantised. Each catalog surface of a sample is one "
        "material drawn from the materials file (sha256 "
        f"`{attrs['materials_sha256']}`), with a reflectance drawn uniformly in its range: "
        + "; ".join(f"{s}: {', '.join(m)}" for s, m in surfaces.items())
        + ". These draws come from a stream of the sample's own, "
        "`SeedSequence(seed, spawn_key=(split, index, 41))`, so the scenes are those of the "
        "`physical` profile with the same seed (simlidar's `docs/sensor-model.md`).\n"
        + _beam_lines(attrs, config)
    )


def _beam_lines(attrs, config: GeneratorConfig) -> str:
    """The Generation process paragraph on beam footprints and returns (none for one ray a
    pulse and its strongest return)."""
    if "return_mode" not in attrs:
        return ""
    receiver = attrs["receiver"]
    rays = subray_count(config.beam_samples)
    mode = {
        "strongest": "the strongest echo",
        "last": "the last echo",
        "dual": "two returns, the last echo and the strongest (the second strongest where the "
        "strongest is the last; one echo is reported twice), as the VLP-16 manual's dual mode",
    }[config.return_mode]
    return (
        f"\nBeam footprint and returns: each pulse is {rays} sub-ray(s) in "
        f"{config.beam_samples} ring(s) over the beam's divergence ("
        f"{receiver['divergence_h_mrad']:g} x {receiver['divergence_v_mrad']:g} mrad, read as "
        "full angles at 1/e^2), weighted by a Gaussian beam profile (HELIOS++'s beam "
        "sampling); every sub-ray hit adds a Gaussian pulse of "
        f"{receiver['pulse_width_ns']:g} ns full width at half maximum, scaled by its "
        "received power, to the pulse's waveform, sampled every 0.25 ns; its peaks at or above "
        f"the threshold are the echoes (`echoes`), and the pulse reports {mode} "
        "(`returns_tof_ns`, `returns_intensity`, `returns_surface`, in that order). The "
        "per-pixel datasets (`delays`, `tof_ns`, `surface`, `intensity`, ...) hold the first "
        "reported return to arrive." + _waveform_line(attrs) + "\n"
    )


def _waveform_line(attrs) -> str:
    """The sentence on the stored waveform (none where it is not stored)."""
    if "waveform_bins" not in attrs:
        return ""
    bin_ns, bins = attrs["waveform_bin_ns"], attrs["waveform_bins"]
    return (
        f" Each pulse's waveform, every echo's and the weather's, is stored (`waveform`): "
        f"{bins} samples, one every {bin_ns:g} ns from the pulse's emission to "
        f"{(bins - 1) * bin_ns:g} ns, in watts (the detection threshold is "
        f"{attrs['receiver']['threshold_w']:g} W)."
    )


def generated_card(path: str | Path) -> str:
    """The whole card of a dataset directory, from its files alone."""
    path = Path(path)
    splits = dataset_splits(path)
    attrs = splits["train"].attrs
    config = stored_config(splits["train"])
    names = attrs["class_names"]
    counts = dataset_info(path)["counts"]  # split -> class name -> count
    catalog = attrs["catalog"]
    sensor = Sensor.from_dict(attrs["sensor"])
    version = attrs["dataset_version"]
    height, width = splits["train"].height, splits["train"].width
    sections = [
        *card_head(
            path,
            generated_front_matter(path),
            f"{NAME}: {len(names)} classes, noise {attrs['noise']}",
            description(sensor),
        ),
        table(
            ["", ""],
            [
                ["dataset version", version],
                ["simlidar version", attrs["simlidar_version"]],
                ["classes", f"{len(names)} ({attrs['class_mode']})"],
                ["samples", ", ".join(f"{s} {info.size}" for s, info in splits.items())],
                ["sample", f"{height} x {width} float32 delays in [0, 1]"],
                ["profile", f"`{config.profile_name}`: {_profile_line(config)}"],
                ["timing", _TIMING_LINE[config.timing]],
                ["noise", f"U(0, {attrs['noise']}) added to {_noised(config)}"],
                ["seed", attrs["seed"]],
            ],
        )
        + "\n",
        f"## Motivation\n\n{MOTIVATION}\n",
        "## Composition\n",
        f"What a value means: {DELAY_MEANING}{_missing_meaning(config)}\n",
        class_table(names, splits, counts),
        "Each split file holds these datasets (N samples):\n",
        table(
            ["dataset", "dtype", "shape", "meaning"],
            [
                [f"`{name}`", dtype, str(("N", *tail(height, width))).replace("'", ""), _DOCS[name]]
                for name, (dtype, tail) in _schema(config, attrs).items()
            ],
        )
        + "\n",
        "## Generation process\n",
        f"A simulated {sensor.model} ray-casts (Embree) into procedurally built road scenes. "
        "Each pixel is the centre firing of its azimuth bin; see simlidar's "
        "`docs/sensor-model.md`.\n",
        table(
            ["sensor parameter", "value"],
            [
                [f"`{k}`", v if not isinstance(v, list) else ", ".join(map(str, v))]
                for k, v in attrs["sensor"].items()
            ],
        )
        + "\n",
        f"Horizontal field of view {config.fov_deg} deg over {config.width} columns; objects "
        f"must be hit by at least {config.min_object_hits} pulses. Scene catalog sha256 "
        f"`{attrs['catalog_sha256']}`"
        + (
            f", every parameter range shrunk around its centre by the variation factor "
            f"{config.variation!r} (less within-class variation than the recipes as written)"
            if config.variation != 1.0
            else ""
        )
        + ":\n",
        "\n".join(
            [
                f"* layout `{n}`: {catalog['layouts'][n]['description']}"
                for n in attrs["layout_names"]
            ]
            + [
                f"* object `{n}`: {catalog['objects'][n]['description']}"
                for n in attrs["object_names"][1:]
            ]
        )
        + "\n",
        _receiver_lines(attrs, config),
        _motion_lines(attrs, config),
        f"Noise: `delays = min(clean_delays + a * u, 1)` with `u ~ U(0, 1)` per pulse and "
        f"a = {attrs['noise']}{_noise_details(config)}. Seed {attrs['seed']}: every sample has "
        "its own random stream "
        "(numpy `SeedSequence(seed, spawn_key=(split, index))`).\n",
        f"## Preprocessing\n\n{PREPROCESSING}\n",
        f"## Uses\n\n{USES}\n\n### Out-of-scope uses\n\n{OUT_OF_SCOPE}\n",
        f"## Distribution\n\n{DISTRIBUTION}{_shards_line(splits)}\n",
        f"## Maintenance\n\n{MAINTENANCE}\n",
        "## Regenerate\n",
        f"With simlidar {attrs['simlidar_version']} (dataset version {version}):\n",
        "```\n"
        + regenerate_command(config, attrs["catalog_sha256"], shard_option(splits))
        + "\n```\n",
        "## Versions\n",
        "\n".join(
            f"* {v} ({RELEASE_DATES.get(v, 'unreleased')}): {notes}"
            for v, notes in notes_until(RELEASE_NOTES, version).items()
        )
        + "\n",
        "## Loading\n",
        "```python\nfrom simlidar.data import load_split\n"
        "x, y = load_split('.', 'train')  # x: (N, 16, W) float32, y: (N,) int64\n```\n",
        "## Citation\n\nPlease cite the paper whose dataset this rebuilds:\n",
        f"```bibtex\n{CITATION}\n```\n",
    ]
    return "\n".join(s for s in sections if s)


RECORD_FIELDS = ("delays", "labels", "clean_delays", "tof_ns", "surface", "layout", "object")


def generated_croissant(path: str | Path, name: str | None = None) -> dict:
    """The Croissant description of a dataset directory (its split files must exist).

    name : the dataset's name (default: the directory's name)
    """
    path = Path(path)
    splits = dataset_splits(path)
    attrs = splits["train"].attrs
    version = attrs["dataset_version"]
    distribution = file_objects(splits, "HDF5, one row per sample")
    record_sets = [
        {
            "@type": "cr:RecordSet",
            "@id": split,
            "name": split,
            "description": f"{splits[split].size} samples of the {split} split.",
            "field": [
                field(
                    split,
                    split,
                    name,
                    SCHEMA[name][0],
                    ("N", *SCHEMA[name][1](splits[split].height, splits[split].width)),
                    sharded=splits[split].sharded,
                )
                for name in RECORD_FIELDS
            ],
        }
        for split in SPLITS
    ]
    return {
        "@context": CONTEXT,
        "@type": "sc:Dataset",
        "conformsTo": "http://mlcommons.org/croissant/1.0",
        "name": name or path.name,
        "alternateName": NAME,
        "description": description(Sensor.from_dict(splits["train"].attrs["sensor"])),
        "license": LICENSE_URL,
        "url": HOMEPAGE,
        "creator": {"@type": "sc:Organization", "name": CREATOR},
        "datePublished": RELEASE_DATES.get(version, "1970-01-01"),
        "version": version,
        "citeAs": CITATION,
        "keywords": ["LiDAR", "spiking neural networks", "temporal pulses", "synthetic data"],
        "distribution": distribution,
        "recordSet": record_sets,
    }
