"""Full sweeps: every firing of whole rotations of a sensor over a scene (``simlidar sweep``).

A *frame* is one rotation: :func:`~simlidar.sensor.rays.cycles_per_rotation` firing cycles
(1808 for a VLP-16 at 600 RPM), each firing every laser, so a frame holds H x C pulses (28,928
for the VLP-16, 133,312 for the HDL-64E). Cycle ``k`` of a frame starts at azimuth
``-180 + (k + phase) * azimuth_step_deg``: behind the sensor, turning clockwise (right) through
the front, as a Velodyne frame packet stream does. Frame ``f`` shows the scene of class
``f mod classes`` (the window generator's labelling) drawn from its own random stream,
``SeedSequence(seed, spawn_key=(2, f))``: one draw of the rotation phase and the scene's
parameters, without the window generator's redraws (the shipped scenes put their object ahead,
where every frame sees it: ``object_points`` counts its returns).

Each pulse keeps its quantised range (NaN: no return), the surface it hit (a per-point label:
segmentation), an intensity proxy (``|cos|`` of the angle of incidence: real intensities also
depend on the surface's reflectivity) and, shared by every frame, its emission time within the
rotation. Through a profile with a receiver (``--profile sensor``, :mod:`simlidar.generator.
returns`) a hit returns only when the receiver detects it, with its range noise, and the intensity
is the sensor's reflectivity byte of the surface's drawn material (frame f's draws:
``SeedSequence(seed, spawn_key=(2, f, 41))``); fog (``--fog``) and rain (``--rain``) take the
waveform path, one ray a pulse and its strongest return. :func:`sweep` writes them into a frames
file (its schema and version: :mod:`simlidar.dataset.schema`, :mod:`simlidar.dataset.version`),
draws its bird's-eye picture (:mod:`simlidar.generator.bev`) and exports its frames
(:mod:`simlidar.generator.exports`: KITTI ``.bin`` with a SemanticKITTI-style ``.label`` of
surfaces, PLY or PCD); :func:`~simlidar.generator.frames.frame_points` turns a frame of the file
into a point cloud in the sensor's frame. The file format: docs/sweeps.md.

The scenes were written for a window ahead of the sensor: behind it the road ends 0-10 m back
(``entry_m`` of the tunnel, the road box of every layout), so the rear half of a frame sees
little. That is the catalog's extent, not the sweep's.
"""

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from simlidar import __version__
from simlidar.atomic import building
from simlidar.dataset.schema import SWEEP_FILE, SWEEP_FORMAT, reported_returns, sweep_schema
from simlidar.dataset.version import (
    SWEEP_CALIBRATED_VERSION,
    SWEEP_MOTION_VERSION,
    SWEEP_VERSION,
)
from simlidar.dataset.writer import SplitWriter
from simlidar.errors import ConfigError
from simlidar.generator.bev import draw_bev, draw_motion
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.exports import EXPORTS, export_frame
from simlidar.generator.frames import frame_points as frame_points  # docs/sweeps.md's path
from simlidar.generator.pulses import quantise_range
from simlidar.generator.returns import (
    check_physics,
    receive_hits,
    receiver_physics,
    receiver_stream,
)
from simlidar.generator.sequences import (
    check_motion,
    frame_cycles,
    frame_motion,
    motion_attrs,
    ray_times,
)
from simlidar.generator.simulate import (
    FIXED_COLUMNS,
    SPLIT_IDS,
    axis_hits,
    class_plan,
    factors,
    split_beams,
)
from simlidar.generator.streams import Streams
from simlidar.resources import check_memory
from simlidar.scene.build import build_batch
from simlidar.scene.motion import COLUMNS
from simlidar.scene.recipe import Catalog
from simlidar.sensor.footprint import subray_count, subray_directions
from simlidar.sensor.model import row_order
from simlidar.sensor.moving import cast_moving
from simlidar.sensor.raycast import MAX_BATCH, cast, compiled_for
from simlidar.sensor.rays import cycles_per_rotation, sweep_emission_ns, sweep_rays
from simlidar.settings import Range, check, setting

FRAME_BATCH = 16  # frames ray-cast together at most (does not change the files)
MAX_FRAMES = 10**6
# Memory a frame takes while it is simulated, bytes, from the peak RSS of `simlidar sweep` over
# 16 frames less that over 1 (/usr/bin/time -f %M): about 150 a ray cast (16 frames of the
# HDL-64E, 2.1 M rays: 0.33 GB; 16 VLP-16 frames of 37 sub-rays a pulse against 19: 128 a ray),
# and 1.4 to 2.5 KB more a pulse whose returns come from its waveform (16 VLP-16 frames, 0.46 M
# pulses: 0.63 GB in dual mode, 1.15 GB in fog).
RAY_BYTES = 160
WAVEFORM_PULSE_BYTES = 2560
# Frames are simulated FRAME_BATCH at a time, fewer where they would take more memory than this
# (no effect on the files): 16 frames of the HDL-64E take about 0.34 GB, of the VLP-16 with
# --beam-samples 8 (169 rays a pulse) 13.7 GB, where one takes 0.86 GB.
MAX_BATCH_BYTES = 2**30


@dataclass(frozen=True)
class SweepConfig:
    """What a sweep file holds beyond the scenes' settings (a GeneratorConfig's classes,
    seed, variation and sensor)."""

    frames: int = setting(
        10,
        "Frames: full rotations of the sensor; frame f shows class f mod classes (in "
        "sequences: sequence s shows class s mod classes).",
        Range(1, MAX_FRAMES, "an integer"),
    )
    # stored only when not 0, so that sweeps before it keep their bytes
    sequence_frames: int = setting(
        0,
        "Frames of one continuous sequence: one scene, the sensor turning on from rotation to "
        "rotation while the ego and the objects move on; 0: every frame its own scene, or, "
        "when anything moves, all frames one sequence.",
        Range(0, MAX_FRAMES, "an integer"),
    )

    def __post_init__(self) -> None:
        check(self)

    def to_dict(self) -> dict:
        """What the ``sweep`` attribute stores: ``sequence_frames`` only where set."""
        values = asdict(self)
        if not values["sequence_frames"]:
            del values["sequence_frames"]
        return values

    def sequence(self, config: GeneratorConfig) -> int:
        """Frames of one sequence: ``sequence_frames``, or where it is 0 every frame (when
        ``config`` moves anything) or one."""
        return self.sequence_frames or (self.frames if config.moves else 1)


@dataclass(frozen=True)
class Frames:
    """A block of consecutive frames (n frames, H lasers in rows, C cycles)."""

    range_m: np.ndarray  # (n, H, C) float32, quantised; NaN: no return
    surface: np.ndarray  # (n, H, C) uint8, 0: no return
    intensity: np.ndarray  # (n, H, C) float32, |cos incidence|, 0: no return
    labels: np.ndarray  # (n,) int64
    layout: np.ndarray  # (n,) uint8
    object: np.ndarray  # (n,) uint8
    object_pose: np.ndarray  # (n, 3) float32: x_m, y_m, yaw_deg; NaN without object
    # (n, 7) float32: the object's box, length_m, width_m, height_m along its yaw, and its
    # bottom centre x_m, y_m, z_m in the scene frame, yaw_deg; NaN without object
    object_box: np.ndarray
    object_points: np.ndarray  # (n,) int32, returns from the labelled object
    phase: np.ndarray  # (n,) float64, rotation phase in azimuth steps
    # with a beam footprint or a return mode other than strongest (SWEEP_RETURNS_SCHEMA) only:
    echoes: np.ndarray | None = None  # (n, H, C) uint8, echoes detected in the waveform
    returns_range_m: np.ndarray | None = None  # (n, H, C, R) float32, NaN: none
    returns_intensity: np.ndarray | None = None  # (n, H, C, R) float32, 0: none
    returns_surface: np.ndarray | None = None  # (n, H, C, R) uint8, 0: none
    # in motion (SWEEP_MOTION_SCHEMA) only:
    sequence: np.ndarray | None = None  # (n,) int64, the frame's sequence
    start_ns: np.ndarray | None = None  # (n,) float64, its first firing, ns into its sequence
    ego_pose: np.ndarray | None = None  # (n, 3, 4) float64, the sensor at its reference time
    object_motion: np.ndarray | None = None  # (n, 3) float32 speed, heading, yaw rate


def simulate_frames(
    config: GeneratorConfig,
    catalog: Catalog,
    start: int,
    stop: int,
    total: int | None = None,
    sequence: int = 1,
) -> Frames:
    """Frames ``start .. stop - 1`` of a sweep of ``config``'s sensor and scenes (its classes,
    seed and variation; at most MAX_BATCH / 2 frames) from ``catalog``'s recipes. ``total``:
    the sweep's frames, by default these (the whole run's rays choose the ray caster's form,
    not the bytes: :func:`simlidar.sensor.raycast.compiled_for`). ``sequence``: frames of one
    sequence (:meth:`SweepConfig.sequence`): sequence s, frames s L .. s L + L - 1, is one
    scene drawn from the stream of index s, seen rotation after rotation (:func:`frame_cycles`)
    and, where ``config`` moves anything, each pulse cast at its own time
    (:func:`~simlidar.sensor.moving.cast_moving`)."""
    if not 0 < stop - start <= MAX_BATCH // 2:
        raise ConfigError(f"batch of {stop - start} frames: expected 1..{MAX_BATCH // 2}")
    sensor = config.sensor
    catalog = catalog.for_sensor(sensor.name).with_variation(config.variation)
    plan = class_plan(catalog, config.classes)
    index = np.arange(start, stop)
    scene_of, step = index // sequence, index % sequence
    labels = scene_of % plan.classes
    streams = Streams(config.seed, SPLIT_IDS["sweep"], scene_of)  # sample_stream's, batched
    free = streams.random(2)
    layout, obj = factors(plan, labels, free, len(catalog.layouts), len(catalog.objects))
    lc = catalog.layout_columns
    u = streams.random(FIXED_COLUMNS + lc + catalog.object_columns)
    # after every draw of the static scene, so that a scene without motion keeps its bytes
    drawn = catalog.object_motion(obj, streams.random(COLUMNS)) if config.moving_objects else None
    first_cycle, phase = frame_cycles(sensor, step, u[:, 0])
    beams = stores_returns(config)
    rays = (total or len(index)) * sensor.beams * cycles_per_rotation(sensor) * rays_a_pulse(config)
    compiled = compiled_for(rays)  # the sweep's rays: the kernels pay on long runs
    origins, directions = sweep_rays(sensor, phase, compiled)
    if beams:  # every sub-ray, cast with the others; sub-ray 0 is the beam's axis
        receiver = receiver_physics(config.profile).receiver
        directions, weights = subray_directions(
            directions, receiver.divergence_h_mrad, receiver.divergence_v_mrad,
            config.beam_samples,
        )  # fmt: skip
        origins = np.broadcast_to(origins[..., None, :], directions.shape)
        origins, directions = (a.reshape(len(index), sensor.beams, -1, 3)
                               for a in (origins, directions))  # fmt: skip
    scene = build_batch(
        catalog,
        layout,
        obj,
        u[:, FIXED_COLUMNS : FIXED_COLUMNS + lc],
        u[:, FIXED_COLUMNS + lc :],
        compiled=compiled,
    )
    in_sequence = config.moves or sequence != 1  # the frames' SWEEP_MOTION_SCHEMA fields
    motion = frame_motion(config, scene, first_cycle, drawn) if in_sequence else None
    if not config.moves:
        hits = cast(scene, origins, directions, index % MAX_BATCH, sensor.max_range_m,
                    incidence=True, compiled=compiled)  # fmt: skip
    else:
        times = ray_times(motion.times_s, directions)
        hits = cast_moving(scene, origins, directions, index % MAX_BATCH, sensor.max_range_m,
                           motion.ego.poses(times), motion.things, times, incidence=True,
                           compiled=compiled)  # fmt: skip
    cycles = cycles_per_rotation(sensor)
    beam_hits, hits = (hits, axis_hits(hits, cycles)) if beams else (None, hits)
    r = quantise_range(hits.range_m, sensor)
    returned = ~np.isnan(r)
    intensity = np.where(returned, hits.cos_incidence, 0.0)
    surface = np.where(returned, hits.surface, 0)
    more = {}
    if config.receiver is not None:
        got = received(config, catalog, index, hits, r, beam_hits, weights if beams else None)
        r, surface, intensity = got.range_m, got.surface, got.intensity
        returned = ~np.isnan(r)
        if beams:
            more = {
                "echoes": got.echoes,
                "returns_range_m": got.returns_range_m.astype(np.float32),
                "returns_intensity": got.returns_intensity.astype(np.float32),
                "returns_surface": got.returns_surface,
            }
    boxes = object_boxes(scene)
    if motion is not None:
        more |= motion.fields(scene_of, boxes, drawn)
    return Frames(
        range_m=r.astype(np.float32),
        surface=surface.astype(np.uint8),
        intensity=intensity.astype(np.float32),
        labels=labels.astype(np.int64),
        layout=layout.astype(np.uint8),
        object=obj.astype(np.uint8),
        object_pose=scene.object_pose.astype(np.float32),
        object_box=boxes.astype(np.float32),
        object_points=(hits.on_object & returned).sum(axis=(1, 2)).astype(np.int32),
        phase=phase,
        **more,
    )


def stores_returns(config: GeneratorConfig) -> bool:
    """Whether a sweep of ``config`` stores every reported return (SWEEP_RETURNS_SCHEMA): a
    receiver with a beam footprint or a return mode other than strongest (fog and rain alone
    keep one return a pulse, as sweeps of version 1.2.0 do)."""
    return config.receiver is not None and (
        config.beam_samples != 1 or config.return_mode != "strongest"
    )


def rays_a_pulse(config: GeneratorConfig) -> int:
    """Rays a sweep of ``config`` casts for each pulse: its beam footprint's sub-rays where it
    stores every reported return (:func:`stores_returns`), else 1."""
    return subray_count(config.beam_samples) if stores_returns(config) else 1


def frame_bytes(config: GeneratorConfig) -> int:
    """About the memory one frame of a sweep of ``config`` takes while it is simulated, bytes:
    :data:`RAY_BYTES` a ray cast, :data:`WAVEFORM_PULSE_BYTES` more a pulse whose returns come
    from its waveform. A ConfigError where the sensor's rotation fires too many pulses
    (:func:`~simlidar.sensor.rays.cycles_per_rotation`)."""
    pulses = config.sensor.beams * cycles_per_rotation(config.sensor)
    waveform = WAVEFORM_PULSE_BYTES if config.full_waveform else 0
    return pulses * (rays_a_pulse(config) * RAY_BYTES + waveform)


def frames_a_batch(config: GeneratorConfig, batch: int = FRAME_BATCH) -> int:
    """Frames of a sweep of ``config`` simulated together: ``batch``, fewer where they would
    take more than :data:`MAX_BATCH_BYTES` (:func:`frame_bytes`), at least 1."""
    return max(1, min(batch, MAX_BATCH_BYTES // frame_bytes(config)))


def received(
    config: GeneratorConfig,
    catalog: Catalog,
    index: np.ndarray,
    hits,
    range_m,
    beam_hits=None,
    weights=None,
):
    """Frames' hits through the profile's receiver (:func:`simlidar.generator.returns.
    receive_hits`; ``beam_hits`` (n, H, C x S) the sub-rays' hits where the beam has a
    footprint or the mode is not strongest, of ``weights``): its Returns, (n, H, C) and the
    reported returns (n, H, C, R).

    config : the sweep's scenes, sensor and receiver (its profile, seed and return mode)
    catalog : the scene recipes, the sensor's part (its surface labels)
    index : (n,) the frames' indices in the sweep, which key their receiver streams
    hits, range_m : the frames' first hits (n, H, C) (of each beam's axis with ``beam_hits``)
        and their quantised ranges (NaN: no return); read only without ``beam_hits``
    """
    physics = receiver_physics(config.profile)
    choices = check_physics(physics, config.sensor, catalog.surfaces, config.return_mode)
    streams = [receiver_stream(config.seed, SPLIT_IDS["sweep"], i) for i in index]
    if beam_hits is not None:  # as simulate does for windows: hits within range, per sub-ray
        got = split_beams(beam_hits, cycles_per_rotation(config.sensor))
        inside = ~np.isnan(quantise_range(got.range_m, config.sensor))
        hit_m = np.where(inside, got.range_m, np.nan)
        surface = np.where(inside, got.surface, 0).astype(np.uint8)
        return receive_hits(
            config, physics, choices, streams, hit_m, surface, got.cos_incidence, weights
        )
    hit_m = np.where(np.isnan(range_m), np.nan, hits.range_m)  # unquantised, within range
    surface = np.where(np.isnan(range_m), 0, hits.surface).astype(np.uint8)
    return receive_hits(config, physics, choices, streams, hit_m, surface, hits.cos_incidence)


def object_boxes(scene) -> np.ndarray:
    """The box of each scene's object, aligned with its yaw: (B, 7) float64 length, width,
    height, bottom centre x, y, z (scene frame), yaw_deg; NaN rows where there is none."""
    boxes = np.full((scene.size, 7), np.nan)
    for i in np.unique(scene.sample[scene.is_object]):
        v = scene.triangles[scene.is_object & (scene.sample == i)].reshape(-1, 3)
        x, y, yaw = scene.object_pose[i]
        c, s = np.cos(np.deg2rad(yaw)), np.sin(np.deg2rad(yaw))
        along = c * (v[:, 0] - x) + s * (v[:, 1] - y)  # in the object's own axes
        across = -s * (v[:, 0] - x) + c * (v[:, 1] - y)
        mid_a, mid_c = (along.max() + along.min()) / 2, (across.max() + across.min()) / 2
        boxes[i] = (
            np.ptp(along),
            np.ptp(across),
            np.ptp(v[:, 2]),
            x + c * mid_a - s * mid_c,
            y + s * mid_a + c * mid_c,
            v[:, 2].min(),
            yaw,
        )
    return boxes


def sweep_version(config: GeneratorConfig, sweep: SweepConfig | None = None) -> str:
    """SWEEP_CALIBRATED_VERSION through a receiver (the 1.2.0 and 1.3.0 receiver versions are
    no longer made), SWEEP_MOTION_VERSION where anything moves, else SWEEP_VERSION."""
    if config.receiver is not None:
        return SWEEP_CALIBRATED_VERSION
    if config.moves or (sweep is not None and sweep.sequence(config) != 1):
        return SWEEP_MOTION_VERSION
    return SWEEP_VERSION


def sweep_name(config: GeneratorConfig, sweep: SweepConfig) -> str:
    """``simlidar-sweep-<classes>c-<sensor>-<frames>f-seed<seed>[-<profile>][-fog<V>][-rain<R>][-beam<Q>][-<mode>][-var<v>]-v<version>``;
    ``-<profile>`` names a profile with a receiver (``-sensor``)."""
    variation = f"-var{float(config.variation)!r}" if config.variation != 1.0 else ""
    receiver = f"-{config.profile_name}" if config.receiver is not None else ""
    receiver += config.receiver_tag  # a sweep refuses waveforms: no -wave
    motion = motion_tag(config, sweep)
    return (
        f"simlidar-sweep-{config.classes}c-{config.sensor.name}-{sweep.frames}f-seed"
        f"{config.seed}{receiver}{motion}{variation}-v{sweep_version(config, sweep)}"
    )


def motion_tag(config: GeneratorConfig, sweep: SweepConfig) -> str:
    """What a sweep's name says of its motion and sequences:
    ``[-ego<v>][-traj<sha256, 8 digits>][-yaw<w>][-moving][-seq<L>]``, numbers as Python's
    repr; ``-seq<L>`` where
    sequences are not the default's (:meth:`SweepConfig.sequence`)."""
    tag = config.motion_tag
    default = SweepConfig(frames=sweep.frames).sequence(config)
    return tag + (f"-seq{sweep.sequence(config)}" if sweep.sequence(config) != default else "")


def sweep(
    config: GeneratorConfig,
    sweep_config: SweepConfig,
    catalog: Catalog,
    out: str | Path,
    exports: tuple[str, ...] = (),
    force: bool = False,
    progress: bool = True,
    batch: int = FRAME_BATCH,
) -> Path:
    """Simulate ``sweep_config.frames`` frames into ``out/<sweep_name>/frames.h5`` (one frame
    a chunk), draw ``bev.png`` (:func:`draw_bev`: up to four frames) and write every frame in
    each format of ``exports`` (:data:`EXPORTS`); the folder appears complete or not at all.

    config : the scenes, sensor, receiver and weather (as for
        :func:`simlidar.generator.generate.generate`)
    sweep_config : the frames: how many, the sweep's own settings (:class:`SweepConfig`)
    catalog : the scene recipes; the sensor's part of it is used and stored
    out : the folder that receives the sweep's folder (made if missing)
    exports : formats to write every frame in as well (:data:`EXPORTS`)
    force : replace a sweep folder of the same name (else an error names it)
    progress : a progress bar on stderr
    batch : frames simulated at a time, at most (:func:`frames_a_batch`); no effect on the bytes

    A rotation of more than :data:`~simlidar.sensor.rays.MAX_ROTATION_PULSES` pulses is a
    ConfigError, a batch of frames this process cannot hold in memory a ResourceError, both
    before anything is written.
    """
    from tqdm import tqdm

    for fmt in exports:
        if fmt not in EXPORTS:
            raise ConfigError(f"export {fmt!r}: expected one of {', '.join(EXPORTS)}")
    sensor, n = config.sensor, sweep_config.frames
    h, c = sensor.beams, cycles_per_rotation(sensor)  # a rotation too large fails here
    catalog = catalog.for_sensor(config.sensor.name)  # its fingerprint: the recipes used
    plan = class_plan(catalog, config.classes)  # a bad class count fails before any file
    attrs = {
        "format": SWEEP_FORMAT,
        "sweep_version": sweep_version(config, sweep_config),
        "simlidar_version": __version__,
        "config": config.to_json(),
        "sweep": json.dumps(sweep_config.to_dict(), sort_keys=True),
        "sensor": json.dumps(sensor.to_dict(), sort_keys=True),
        "catalog_sha256": catalog.fingerprint(),
        "class_names": json.dumps(list(plan.names)),
        "surface_names": json.dumps(list(catalog.surfaces)),
        "object_names": json.dumps(list(catalog.object_names)),
        "row_laser_ids": np.array(row_order(sensor), dtype=np.int32),
        "cycles": c,
    }
    if config.receiver is not None:  # absent: every hit in range returns (1.1.0's bytes)
        if config.waveform_bin_ns:
            raise ConfigError(
                f"waveform_bin_ns={config.waveform_bin_ns!r}: a sweep stores no waveforms "
                f"({sensor.beams} x {c} pulses a frame); expected 0 (generate --waveform-bin "
                "stores them for windows)"
            )
        if stores_returns(config):
            attrs |= {"return_mode": config.return_mode, "beam_samples": config.beam_samples}
        physics = receiver_physics(config.profile)
        check_physics(physics, sensor, catalog.surfaces, config.return_mode)
        attrs |= physics.attrs()
    sequence = sweep_config.sequence(config)
    check_motion(config, catalog, sequence)
    if config.moves or sequence != 1:
        attrs["sequence_frames"] = sequence
    attrs |= motion_attrs(config, catalog)
    schema = sweep_schema(reported_returns(attrs), "sequence_frames" in attrs)
    shapes = {name: (dtype, tail(h, c)) for name, (dtype, tail) in schema.items()}
    name = sweep_name(config, sweep_config)
    batch = frames_a_batch(config, batch)
    check_memory(
        batch * frame_bytes(config),
        f"sweep of sensor {sensor.name}: {batch} frame(s) of {h} x {c} pulses, "
        f"{rays_a_pulse(config)} ray(s) a pulse",
    )
    with building(out, name, force) as folder:
        writer = SplitWriter(folder / SWEEP_FILE, n, shapes, attrs, frozenset(), chunk=1)
        try:
            writer.file.create_dataset("emission_ns", data=sweep_emission_ns(sensor))
            if config.ego_trajectory is not None:  # the poses the configuration's digest names
                writer.file.create_dataset("ego_trajectory", data=config.ego_trajectory.rows())
            bar = tqdm(total=n, desc="sweep", unit="frame", disable=not progress)
            for first in range(0, n, batch):
                frames = simulate_frames(config, catalog, first, min(first + batch, n), n, sequence)
                writer.append({name: getattr(frames, name) for name in schema})
                bar.update(len(frames.labels))
            bar.close()
            writer.close()
        except BaseException:
            writer.abort()
            raise
        draw_bev(folder / SWEEP_FILE, folder / "bev.png")
        draw_motion(folder / SWEEP_FILE, folder)  # in motion: motion.png and sequence.gif
        for fmt in exports:
            for f in range(n):
                export_frame(folder / SWEEP_FILE, f, folder, fmt)
    return Path(out) / name
