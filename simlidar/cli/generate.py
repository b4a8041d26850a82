"""``simlidar generate``, ``profiles``, ``sensors`` and ``scenes``: making datasets."""

import json
import time
from pathlib import Path

import click

from simlidar.cli.options import (
    DEFAULT_OUT,
    IntegerRange,
    NoiseLevels,
    OutFolder,
    batch_options,
    load_scene_catalog,
    scenes_option,
    scheduler_option,
    setting_option,
)
from simlidar.dataset.shards import SHARD_SAMPLES
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.exports import EXPORTS
from simlidar.generator.generate import BATCH
from simlidar.generator.generate import generate as generate_datasets
from simlidar.generator.profiles import DEFAULT_PROFILE, load_profile, profile_names
from simlidar.generator.sweep import SweepConfig
from simlidar.generator.sweep import sweep as run_sweep
from simlidar.sensor.model import DEFAULT_SENSOR, load_sensor, sensor_names
from simlidar.sensor.raycast import MAX_BATCH
from simlidar.settings import help_of


def out_option(what: str):
    """``--out``: the folder that receives ``what``."""
    return click.option(
        "--out",
        type=OutFolder(),
        default=DEFAULT_OUT,
        show_default=True,
        help=f"Folder that receives {what}.",
    )


sensor_option = click.option(
    "--sensor",
    default=None,
    help=f"Sensor model: a name in sensors/ ({', '.join(sensor_names())}) or a .toml file; see "
    f"`simlidar sensors`. Rows of a sample = its beams. [default: {DEFAULT_SENSOR}]",
)


def receiver_options(profile_help: str):
    """``--profile`` (a profile with a receiver; ``profile_help`` says what it does), ``--fog``
    and ``--rain``: the receiver and its weather, as ``sweep`` and ``stream`` take them."""

    def apply(command):
        command = setting_option(
            GeneratorConfig, "rain_rate_mm_h", "--rain", "rain_rate_mm_h", metavar="MM_PER_H"
        )(command)
        command = setting_option(
            GeneratorConfig, "fog_visibility_m", "--fog", "fog_visibility_m",
            metavar="VISIBILITY_M",
        )(command)  # fmt: skip
        return click.option("--profile", default=None, help=profile_help)(command)

    return apply


def motion_options(command):
    """``--ego-speed``, ``--ego-yaw-rate`` and ``--moving-objects`` (generate's and sweep's)."""
    for option in reversed((
        setting_option(
            GeneratorConfig, "ego_speed_mps", "--ego-speed", "ego_speed_mps", metavar="MPS"
        ),
        setting_option(GeneratorConfig, "ego_yaw_rate_deg_s", "--ego-yaw-rate",
                       "ego_yaw_rate_deg_s", metavar="DEG_S"),
        click.option(
            "--moving-objects",
            is_flag=True,
            help="Move each scene's object as the scene catalog's motion.toml says (speed, "
            "heading of travel, yaw rate, drawn once a scene after the static scene's draws).",
        ),
    )):  # fmt: skip
        command = option(command)
    return command


def chosen_sensor_of(sensor):
    """The sensor an option names (default: the VLP-16); a bad one is a usage error."""
    try:
        return load_sensor(sensor if sensor is not None else DEFAULT_SENSOR)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--sensor'") from None


def catalog_for(scenes, classes: int):
    """The scene catalog of --scenes, checked to give ``classes`` classes."""
    from simlidar.generator.simulate import class_plan

    catalog = load_scene_catalog(scenes)
    try:
        class_plan(catalog, classes)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--classes'") from None
    return catalog


@click.command()
@setting_option(GeneratorConfig, "classes")
@setting_option(
    GeneratorConfig,
    "noise",
    type=NoiseLevels(),
    default=str(GeneratorConfig.noise),
    help=help_of(GeneratorConfig, "noise")[:-1] + "; a comma-separated list writes one dataset "
    "per level, with the same scenes.",
)
@setting_option(GeneratorConfig, "train_size")
@setting_option(GeneratorConfig, "test_size")
@setting_option(GeneratorConfig, "seed")
@click.option(
    "--profile",
    default=None,
    help=f"Dataset profile: a name in profiles/ ({', '.join(profile_names())}) or a .toml "
    f"file; see `simlidar profiles`. [default: {DEFAULT_PROFILE}]",
)
@setting_option(
    GeneratorConfig,
    "shift_max",
    "--shift",
    "shift",
    default=None,
    help=help_of(GeneratorConfig, "shift_max")
    + " Overrides the profile's value (named in the dataset's name).",
)
@setting_option(
    GeneratorConfig,
    "variation",
    default=None,
    help=help_of(GeneratorConfig, "variation")
    + " Overrides the profile's value (named in the dataset's name).",
)
@out_option("the dataset directories")
@setting_option(GeneratorConfig, "width")
@sensor_option
@setting_option(GeneratorConfig, "timing")
@setting_option(
    GeneratorConfig, "fog_visibility_m", "--fog", "fog_visibility_m", metavar="VISIBILITY_M"
)
@setting_option(GeneratorConfig, "rain_rate_mm_h", "--rain", "rain_rate_mm_h", metavar="MM_PER_H")
@setting_option(GeneratorConfig, "beam_samples", metavar="Q")
@setting_option(GeneratorConfig, "return_mode")
@setting_option(
    GeneratorConfig, "waveform_bin_ns", "--waveform-bin", "waveform_bin_ns", metavar="NS"
)
@motion_options
@scenes_option
@batch_options(MAX_BATCH, BATCH, "Samples")
@click.option(
    "--shard-size",
    type=IntegerRange(1),
    default=SHARD_SAMPLES,
    show_default=True,
    help="A split of more samples is written as shard files of this many samples "
    "(train-00000-of-00004.h5, ...; docs/dataset-format.md).",
)
@scheduler_option("every split file as one task")
@click.option("--force", is_flag=True, help="Overwrite existing datasets.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def generate(
    classes,
    noise,
    train_size,
    test_size,
    seed,
    profile,
    shift,
    variation,
    out,
    width,
    sensor,
    timing,
    fog_visibility_m,
    rain_rate_mm_h,
    beam_samples,
    return_mode,
    waveform_bin_ns,
    ego_speed_mps,
    ego_yaw_rate_deg_s,
    moving_objects,
    scenes,
    batch_size,
    workers,
    shard_size,
    scheduler,
    force,
    as_json,
):
    """Generate Sim LiDAR datasets: per noise level, train/test splits (HDF5), a preview
    picture, the dataset card, Croissant metadata and checksums.

    The profile (default: paper) decides the scene variation, the delay shift, what a missing
    return is written as and which pixels get the noise. --variation and --shift override its
    values; the dataset's name then says so (docs/profiles.md)."""

    try:
        chosen = load_profile(profile if profile is not None else DEFAULT_PROFILE)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--profile'") from None
    for option, value, own in (
        ("--variation", variation, chosen.variation),
        ("--shift", shift, chosen.shift),
    ):
        if value is not None and value != own:
            click.echo(
                f"Note: {option} {value!r} overrides profile {chosen.name}'s {own!r}", err=True
            )
    chosen_sensor = chosen_sensor_of(sensor)
    catalog = catalog_for(scenes, classes)
    config = GeneratorConfig.from_profile(
        chosen,
        variation=variation,
        shift_max=shift,
        classes=classes,
        noise=noise[0],
        train_size=train_size,
        test_size=test_size,
        seed=seed,
        width=width,
        sensor=chosen_sensor,
        timing=timing,
        fog_visibility_m=fog_visibility_m,
        rain_rate_mm_h=rain_rate_mm_h,
        beam_samples=beam_samples,
        return_mode=return_mode,
        waveform_bin_ns=waveform_bin_ns,
        ego_speed_mps=ego_speed_mps,
        ego_yaw_rate_deg_s=ego_yaw_rate_deg_s,
        moving_objects=moving_objects,
    )
    start = time.perf_counter()
    written = generate_datasets(
        config,
        noise,
        catalog,
        out,
        batch_size=batch_size,
        force=force,
        workers=workers,
        shard_samples=shard_size,
        scheduler=scheduler,
    )
    seconds = time.perf_counter() - start
    if as_json:
        record = {
            "datasets": [
                {
                    "path": str(w.path),
                    "noise": w.noise,
                    "classes": w.classes,
                    "splits": w.splits,
                    "kept": w.kept,
                }
                for w in written
            ],
            "seconds": round(seconds, 3),
        }
        click.echo(json.dumps(record))
    else:
        for w in written:
            sizes = f"train {w.splits['train']}, test {w.splits['test']}, noise {w.noise:g}"
            if w.kept:
                click.echo(f"kept {w.path} ({sizes}): already there, the same dataset, verified")
            else:
                click.echo(f"wrote {w.path} ({sizes}) and its preview.png")
        click.echo(f"done in {seconds:.1f} s")


class ExportFormats(click.ParamType):
    """A comma-separated list of point-cloud formats (simlidar.generator.exports.EXPORTS)."""

    name = "FORMATS"

    def convert(self, value, param, ctx):

        if isinstance(value, tuple):
            return value
        formats = tuple(dict.fromkeys(v.strip() for v in str(value).split(",") if v.strip()))
        bad = [f for f in formats if f not in EXPORTS]
        if bad:
            self.fail(f"{bad[0]!r}: expected a comma-separated list of {', '.join(EXPORTS)}")
        return formats


def _trajectory(path: Path | None):
    """The trajectory file ``--trajectory`` names, read and checked (a usage error, exit 2,
    names its line otherwise)."""
    if path is None:
        return None
    from simlidar.motion.trajectory import load_trajectory

    try:
        return load_trajectory(path, f"--trajectory {path}")
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--trajectory'") from None


@click.command()
@setting_option(SweepConfig, "frames")
@setting_option(GeneratorConfig, "classes")
@setting_option(GeneratorConfig, "seed")
@setting_option(GeneratorConfig, "variation")
@sensor_option
@scenes_option
@receiver_options(
    "A profile with a receiver (sensor, or a .toml file): a hit returns only when the "
    "receiver detects it, and the intensity is its reflectivity byte instead of the |cos| "
    "proxy (docs/sweeps.md). [default: none: every hit in range returns]"
)
@setting_option(GeneratorConfig, "beam_samples", metavar="Q")
@setting_option(GeneratorConfig, "return_mode")
@motion_options
@click.option(
    "--trajectory",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="The ego's poses from a file of rows 't x y z roll pitch yaw' (seconds from each "
    "sequence's start, metres, degrees; R = Rz(yaw) Ry(pitch) Rx(roll)), interpolated per "
    "pulse; instead of --ego-speed and --ego-yaw-rate (docs/sweeps.md, 'Motion').",
)
@setting_option(SweepConfig, "sequence_frames", metavar="L")
@click.option(
    "--export",
    "exports",
    type=ExportFormats(),
    default="",
    help="Also write every frame as point clouds: kitti (velodyne/*.bin and SemanticKITTI-style "
    "labels/*.label), ply, pcd; a comma-separated list.",
)
@out_option("the sweep directory")
@click.option("--force", is_flag=True, help="Overwrite an existing sweep directory.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def sweep(
    frames,
    classes,
    seed,
    variation,
    sensor,
    scenes,
    profile,
    fog_visibility_m,
    rain_rate_mm_h,
    beam_samples,
    return_mode,
    ego_speed_mps,
    ego_yaw_rate_deg_s,
    trajectory,
    moving_objects,
    sequence_frames,
    exports,
    out,
    force,
    as_json,
):
    """Simulate full 360-degree frames: every firing of whole rotations of the sensor over the
    scenes, with range, surface label, intensity proxy and emission time per point, into
    frames.h5, a bird's-eye picture (bev.png) and, with --export, point-cloud files
    (docs/sweeps.md). With --profile sensor, through the VLP-16's receiver."""

    chosen_sensor = chosen_sensor_of(sensor)
    catalog = catalog_for(scenes, classes)
    fields = dict(classes=classes, seed=seed, sensor=chosen_sensor)
    fields |= dict(ego_speed_mps=ego_speed_mps, ego_yaw_rate_deg_s=ego_yaw_rate_deg_s)
    fields |= dict(moving_objects=moving_objects, ego_trajectory=_trajectory(trajectory))
    if profile is None:
        fields |= dict(fog_visibility_m=fog_visibility_m, rain_rate_mm_h=rain_rate_mm_h)
        fields |= dict(beam_samples=beam_samples, return_mode=return_mode)
        config = GeneratorConfig(variation=variation, **fields)
    else:
        try:
            chosen = load_profile(profile)
        except ConfigError as exc:
            raise click.BadParameter(str(exc), param_hint="'--profile'") from None
        if chosen.receiver is None:
            raise click.BadParameter(
                f"{chosen.name!r}: expected a profile with a receiver (sensor): a sweep's "
                "pulses follow no other profile's rule",
                param_hint="'--profile'",
            )
        config = GeneratorConfig.from_profile(
            chosen,
            variation=variation,
            fog_visibility_m=fog_visibility_m,
            rain_rate_mm_h=rain_rate_mm_h,
            beam_samples=beam_samples,
            return_mode=return_mode,
            **fields,
        )
    start = time.perf_counter()
    chosen_sweep = SweepConfig(frames=frames, sequence_frames=sequence_frames)
    path = run_sweep(config, chosen_sweep, catalog, out, exports, force=force)
    seconds = time.perf_counter() - start
    if as_json:
        record = {"path": str(path), "frames": frames, "exports": list(exports)}
        click.echo(json.dumps(record | {"seconds": round(seconds, 3)}))
        return
    written = f" and {', '.join(exports)} files" if exports else ""
    click.echo(f"wrote {path} ({frames} frames, frames.h5, bev.png{written})")
    click.echo(f"done in {seconds:.1f} s")


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def sensors(as_json):
    """List the shipped sensor models (docs/sensor-model.md)."""
    from dataclasses import asdict

    shipped = [load_sensor(name) for name in sensor_names()]
    if as_json:
        click.echo(
            json.dumps(
                {
                    "default": DEFAULT_SENSOR,
                    "sensors": [asdict(s) | {"beams": s.beams} for s in shipped],
                }
            )
        )
        return
    for s in shipped:
        default = " (default)" if s.name == DEFAULT_SENSOR else ""
        low, high = min(s.elevations_deg), max(s.elevations_deg)
        click.echo(f"{s.name}{default}: {s.model}, {s.beams} beams ({low:+g} to {high:+g} deg)")
        steps = f" in steps of {s.rpm_step:g}" if s.rpm_step else ""
        click.echo(
            f"  cycle {s.cycle_us:g} us, {s.rpm:g} RPM ({s.rpm_min:g} to {s.rpm_max:g}{steps}), "
            f"range {s.min_range_m:g} to {s.max_range_m:g} m, mounted {s.mount_height_m:g} m up"
        )
        click.echo(f"  source: {s.manual}")


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def profiles(as_json):
    """List the shipped dataset profiles and their values (docs/profiles.md)."""

    shipped = [load_profile(name).to_dict() for name in profile_names()]
    if as_json:
        click.echo(json.dumps({"default": DEFAULT_PROFILE, "profiles": shipped}))
        return
    for p in shipped:
        default = " (default)" if p["name"] == DEFAULT_PROFILE else ""
        click.echo(f"{p['name']}{default}: {p['description']}")
        click.echo(
            f"  variation {p['variation']!r}, shift {p['shift']!r}, missing return "
            f"{p['missing_delay']!r}, noise on {p['noise_on']}, input spikes: "
            f"{p['spikes']}" + (f", receiver {p['receiver']}" if "receiver" in p else "")
        )


@click.command()
@scenes_option
@click.option(
    "--export",
    "export_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Write one sampled scene per layout x object into this folder.",
)
@click.option(
    "--format", "fmt", type=click.Choice(["glb", "ply"]), default="glb", show_default=True
)
@setting_option(GeneratorConfig, "seed", help="Root of the sampled scenes' random streams.")
@sensor_option
def scenes(scenes, export_dir, fmt, seed, sensor):
    """List the scene catalog, or export sampled scenes as mesh files (as --sensor sees them:
    the catalog's variant for that sensor, if it has one)."""
    base = load_scene_catalog(scenes)
    catalog = base.for_sensor(chosen_sensor_of(sensor).name)
    click.echo(f"scene catalog {catalog.root} (sha256 {catalog.fingerprint()[:12]})")
    for name, (layouts, objects) in base.variants.items():
        pairs = zip(layouts + objects, base.layouts + base.objects)
        changed = [new.name for new, old in pairs if new != old]
        chosen = f" (in use below: --sensor {name})" if name == catalog.sensor else ""
        click.echo(f"sensor variant {name}: its own parameters for {', '.join(changed)}{chosen}")
    click.echo(f"layouts ({len(catalog.layouts)}):")
    for k, r in enumerate(catalog.layouts):
        click.echo(f"  {k}  {r.name:<18} {len(r.params):2d} params  {r.description}")
    click.echo(f"objects ({len(catalog.objects)}):")
    for k, r in enumerate(catalog.objects):
        click.echo(f"  {k}  {r.name:<18} {len(r.params):2d} params  {r.description}")
    click.echo(f"surfaces: {', '.join(catalog.surfaces)}")
    if export_dir is not None:
        from simlidar.scene.export import export_scenes

        paths = export_scenes(catalog, export_dir, seed=seed, fmt=fmt)
        click.echo(f"wrote {len(paths)} scenes to {export_dir}")
