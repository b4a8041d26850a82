"""The pipeline for one batch: class plan -> random streams -> scenes -> rays -> hits -> pulses.

Randomness: every sample has its own stream, ``SeedSequence(seed, spawn_key=(split, index))``,
read in a fixed order: 2 variates for the class factor not fixed by the label, the noise
variates (H x W, H the sensor's beams), then one block of parameters per attempt (in motion,
with moving objects, each block ends with the object's motion: drawn after every draw of the
static scene, so that a scene without motion keeps its bytes). A sample's
content therefore depends on (seed, split, index, config, catalog) only, never on the batch
it was made in (the streams of a batch are made and drawn together, numpy's numbers bit for
bit: :mod:`simlidar.generator.streams`). A profile with a receiver (``sensor``) draws its own
variates from a second stream of the sample (:mod:`simlidar.generator.returns`), after the
scene is accepted; the stream above is read exactly as under the other profiles.
"""

from dataclasses import dataclass

import numpy as np

from simlidar.errors import ConfigError, SimlidarError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.pulses import delays_from_range, quantise_range, shift_delays
from simlidar.generator.returns import (
    check_physics,
    receive_hits,
    receiver_physics,
    receiver_stream,
)
from simlidar.generator.sequences import placed_motion, ray_times
from simlidar.generator.streams import Streams
from simlidar.scene.build import build_batch
from simlidar.scene.motion import COLUMNS as MOTION_COLUMNS
from simlidar.scene.motion import KEYS as MOTION_KEYS
from simlidar.scene.recipe import Catalog
from simlidar.sensor.footprint import subray_count, subray_directions
from simlidar.sensor.model import tof_ns
from simlidar.sensor.moving import cast_moving
from simlidar.sensor.raycast import MAX_BATCH, Hits, cast, compiled_for
from simlidar.sensor.rays import column_centres_deg, emission_times_ns, window_rays

SPLIT_IDS = {"train": 0, "test": 1, "sweep": 2}  # random stream keys (sweep: full frames)
# The uniform columns an attempt draws before its layout's and object's: rotation phase,
# delay shift (a sweep's frame draws the same, simulate_frames in generator/sweep.py)
FIXED_COLUMNS = 2


@dataclass(frozen=True)
class ClassPlan:
    """How labels map to (layout, object) for a given ``--classes``."""

    classes: int
    mode: str  # "layout x object" | "layout" | "object"
    names: tuple[str, ...]


def class_plan(catalog: Catalog, classes: int) -> ClassPlan:
    """The labelling that gives ``classes`` classes with this catalog (32 / 8 / 4 by default)."""
    layouts, objects = catalog.layout_names, catalog.object_names
    modes = [
        ("layout x object", tuple(f"{a}/{b}" for a in layouts for b in objects)),
        ("layout", tuple(layouts)),
        ("object", tuple(objects)),
    ]
    matches = [(mode, names) for mode, names in modes if len(names) == classes]
    counts = sorted({len(names) for _, names in modes})
    if not matches:
        raise ConfigError(
            f"classes={classes}: expected one of {counts} for this scene catalog "
            f"({len(layouts)} layouts x {len(objects)} objects)"
        )
    if len(matches) > 1:
        raise ConfigError(
            f"classes={classes} is ambiguous for this scene catalog: it labels "
            f"{' and '.join(m for m, _ in matches)} alike; expected a catalog whose layout, "
            "object and layout x object counts differ"
        )
    mode, names = matches[0]
    return ClassPlan(classes, mode, names)


def factors(plan: ClassPlan, labels: np.ndarray, free: np.ndarray, n_layouts: int, n_objects: int):
    """(layout id, object id) of each label; ``free`` (n, 2) uniforms pick the unfixed factor.

    plan : the labelling (:func:`class_plan`): a label is a layout x object pair, a layout or
        an object
    labels : (n,) int class labels, 0 .. ``plan.classes`` - 1
    n_layouts, n_objects : the catalog's layouts and objects (object 0: the empty "none")
    """
    pick_layout = np.minimum((free[:, 0] * n_layouts).astype(np.int64), n_layouts - 1)
    pick_object = np.minimum((free[:, 1] * n_objects).astype(np.int64), n_objects - 1)
    if plan.mode == "layout x object":
        return labels // n_objects, labels % n_objects
    if plan.mode == "layout":
        return labels, pick_object
    return pick_layout, labels


@dataclass(frozen=True)
class Samples:
    """A block of consecutive samples of one split (n samples, W columns)."""

    clean_delays: np.ndarray  # (n, H, W) float32, after delay shift, before noise
    noise_u: np.ndarray  # (n, H, W) float32 in [0, 1): noise = level * noise_u
    tof_ns: np.ndarray  # (n, H, W) float32, NaN for no return (unshifted physics)
    surface: np.ndarray  # (n, H, W) uint8
    labels: np.ndarray  # (n,) int64
    layout: np.ndarray  # (n,) uint8
    object: np.ndarray  # (n,) uint8
    object_pose: np.ndarray  # (n, 3) float32: x_m, y_m, yaw_deg; NaN without object
    object_hits: np.ndarray  # (n,) int32
    attempts: np.ndarray  # (n,) int32, draws until the object and the layout were seen
    phase: np.ndarray  # (n,) float32, head rotation phase in azimuth steps
    shift: np.ndarray  # (n,) float32, delay shift applied
    # (n, H, W) float64, when each pulse left the sensor, ns from the window's first firing
    # (from the phase of the draw, before it is stored as float32)
    emission_ns: np.ndarray
    # under a profile with a receiver only (simlidar.generator.returns.Returns), else None:
    intensity: np.ndarray | None = None  # (n, H, W) uint8, reflectivity byte, 0: no return
    reflectance: np.ndarray | None = None  # (n, H, W) float32, NaN: no hit
    power_w: np.ndarray | None = None  # (n, H, W) float32, 0: no hit
    # where returns come from waveforms (GeneratorConfig.full_waveform) only, else None:
    echoes: np.ndarray | None = None  # (n, H, W) uint8, echoes detected in the waveform
    returns_tof_ns: np.ndarray | None = None  # (n, H, W, R) float32, NaN: none
    returns_intensity: np.ndarray | None = None  # (n, H, W, R) uint8, 0: none
    returns_surface: np.ndarray | None = None  # (n, H, W, R) uint8, 0: none
    # where a waveform is stored (GeneratorConfig.waveform_bins) only, else None:
    waveform: np.ndarray | None = None  # (n, H, W, T) float32, watts
    # in motion (GeneratorConfig.moves) only, else None:
    object_motion: np.ndarray | None = None  # (n, 3) float32 speed, heading, yaw rate as drawn
    ego_motion: np.ndarray | None = None  # (n, 2) float32 the ego's speed and yaw rate


def layouts_seen(
    catalog: Catalog, layout: np.ndarray, surface: np.ndarray, returned: np.ndarray, azimuth
) -> np.ndarray:
    """Whether each sample sees its layout: layouts whose defining structure can leave the
    window must be seen (recipe key ``visible``), as a label the sensor cannot see is not a
    label.

    catalog : the scene recipes; layout : (n,) each sample's layout id
    surface, returned : (n, H, C) each pulse's surface label and whether it returned
    azimuth : (C,) each column's azimuth, degrees (negative: the left half)
    returns : (n,) bool
    """
    ok = np.ones(len(layout), bool)
    for lid in np.unique(layout):
        rows = np.nonzero(layout == lid)[0]
        for label, min_hits, side in catalog.layouts[lid].visible:
            seen = (surface[rows] == label) & returned[rows]
            if side != "any":
                seen &= (azimuth < 0 if side == "left" else azimuth > 0)[None, None, :]
            ok[rows] &= seen.sum(axis=(1, 2)) >= min_hits
    return ok


def split_beams(hits: Hits, width: int) -> Hits:
    """Hits of B windows' sub-rays cast as (B, H, W x S) -> the same as (B, H, W, S)."""

    def beams(a):
        return None if a is None else a.reshape(a.shape[0], a.shape[1], width, -1)

    return Hits(*(beams(getattr(hits, f)) for f in ("range_m", "surface", "on_object",
                                                    "cos_incidence")))  # fmt: skip


def axis_hits(hits: Hits, width: int) -> Hits:
    """The hits of each beam's axis (sub-ray 0) among its sub-rays' (:func:`split_beams`)."""
    beams = split_beams(hits, width)
    return Hits(*(None if a is None else a[..., 0].copy() for a in (
        beams.range_m, beams.surface, beams.on_object, beams.cos_incidence)))  # fmt: skip


def sample_stream(seed: int, split: str, index: int) -> np.random.Generator:
    """A sample's random stream, the numpy way: the definition :class:`~simlidar.generator.
    streams.Streams` reproduces for a batch (and its tests compare with)."""
    seq = np.random.SeedSequence(seed, spawn_key=(SPLIT_IDS[split], int(index)))
    return np.random.Generator(np.random.PCG64(seq))


def batched_backend(
    catalog: Catalog,
    layout,
    obj,
    layout_uniforms,
    object_uniforms,
    origins,
    directions,
    slots,
    max_range_m,
    incidence=False,
    compiled=False,
    motion=None,
):
    """Scenes -> first hits for a whole batch: one array of triangles, one Embree scene, one call.

    catalog, layout, obj, layout_uniforms, object_uniforms : the scenes, as
        :func:`simlidar.scene.build.build_batch`'s: the scene recipes, each scene's (B,) layout
        and object ids, and the uniforms of their parameters, (B, catalog.layout_columns) and
        (B, catalog.object_columns)
    origins, directions, slots, max_range_m : the rays, as :func:`simlidar.sensor.raycast.cast`'s:
        (B, H, W, 3) in each sample's local frame, (B,) distinct grid cells, and the sensor's
        range (m)
    incidence : also give each hit's |cos incidence| (asked only under a receiver)
    compiled : build the scenes and cast by the compiled kernels (the same triangles and hits;
        asked only on long runs, :func:`simlidar.sensor.raycast.compiled_for`)
    motion : in motion only (asked only then): (the ego's motion, the objects' as drawn or
        None, each ray's time in s (B, H, W)); every pulse is cast at its own time
        (:func:`simlidar.sensor.moving.cast_moving`)
    returns : Hits, object pose (B, 3)
    """
    scene = build_batch(catalog, layout, obj, layout_uniforms, object_uniforms, compiled=compiled)
    if motion is None:
        hits = cast(
            scene, origins, directions, slots, max_range_m, incidence=incidence, compiled=compiled
        )
        return hits, scene.object_pose
    ego, drawn, times = motion
    things = placed_motion(scene.object_pose, drawn)
    hits = cast_moving(scene, origins, directions, slots, max_range_m, ego.poses(times), things,
                       times, incidence=incidence, compiled=compiled)  # fmt: skip
    return hits, scene.object_pose


def run_rays(config: GeneratorConfig) -> int:
    """The rays a whole run of ``config`` casts, first draws only: what
    :func:`simlidar.sensor.raycast.compiled_for` reads to choose the cast's form."""
    beams = config.receiver is not None and config.full_waveform
    subrays = subray_count(config.beam_samples) if beams else 1
    return sum(config.split_sizes.values()) * config.sensor.beams * config.width * subrays


def simulate(
    config: GeneratorConfig,
    catalog: Catalog,
    split: str,
    start: int,
    stop: int,
    backend=batched_backend,
) -> Samples:
    """Samples ``start .. stop - 1`` of ``split`` (at most MAX_BATCH of them).

    config : what decides the samples (profile, classes, seed, sensor, timing, receiver)
    catalog : the scene recipes (the sensor's part and the config's variation are taken here)
    split : ``train`` or ``test`` (each draws from its own random streams)

    ``backend`` has the signature of :func:`batched_backend`; the speed benchmark swaps in the
    naive per-sample trimesh way to compare with on the same samples.
    """
    largest = MAX_BATCH // 2 if config.moves else MAX_BATCH  # cast_moving's cells
    if not 0 < stop - start <= largest:
        raise ConfigError(f"batch of {stop - start} samples: expected 1..{largest}")
    sensor, width = config.sensor, config.width
    catalog = catalog.for_sensor(sensor.name).with_variation(config.variation)
    plan = class_plan(catalog, config.classes)
    physics = receiver_physics(config.profile) if config.receiver is not None else None
    if physics is not None:
        choices = check_physics(physics, sensor, catalog.surfaces, config.return_mode)
    beams = physics is not None and config.full_waveform  # returns from each pulse's waveform
    index = np.arange(start, stop)
    n = len(index)
    labels = index % plan.classes
    compiled = compiled_for(run_rays(config))  # the kernels' loading pays on long runs
    streams = Streams(config.seed, SPLIT_IDS[split], index, compiled)  # sample_stream's
    free = streams.random(2)
    noise_u = streams.random_float32((sensor.beams, width))
    layout, obj = factors(plan, labels, free, len(catalog.layouts), len(catalog.objects))

    lc, oc = catalog.layout_columns, catalog.object_columns
    azimuth = column_centres_deg(width, config.fov_deg)  # negative: left half of the window
    columns = FIXED_COLUMNS + lc + oc
    drawn_motion = np.zeros((n, 3))  # in motion: each sample's object's, as drawn
    motion_columns = MOTION_COLUMNS if config.moving_objects else 0
    range_m = np.full((n, sensor.beams, width), np.nan)
    surface = np.zeros((n, sensor.beams, width), np.uint8)
    pose = np.full((n, 3), np.nan)
    hits_out = np.zeros(n, np.int32)
    attempts = np.zeros(n, np.int32)
    phase = np.zeros(n)
    shift = np.zeros(n)
    emission = np.zeros((n, sensor.beams, width))
    if physics is not None:  # the hits within range, unquantised, and their incidence
        subrays = subray_count(config.beam_samples) if beams else 1
        shape = (n, sensor.beams, width) + ((subrays,) if beams else ())
        hit_m = np.full(shape, np.nan)
        cos_incidence = np.zeros(shape, np.float32)
        hit_surface = np.zeros(shape, np.uint8)
    more = {} if physics is None else {"incidence": True}  # other backends take no such key
    if compiled:
        more["compiled"] = True
    pending = np.arange(n)
    while len(pending):
        attempts[pending] += 1
        u = streams.random(columns + motion_columns, pending)
        origins, directions = window_rays(sensor, width, config.fov_deg, u[:, 0], compiled)
        times_ns = emission_times_ns(sensor, width, config.fov_deg, u[:, 0])
        if beams:  # every sub-ray, cast with the others; sub-ray 0 is the beam's axis
            directions, weights = subray_directions(
                directions,
                physics.receiver.divergence_h_mrad,
                physics.receiver.divergence_v_mrad,
                config.beam_samples,
            )
            origins = np.broadcast_to(origins[..., None, :], directions.shape)
            origins, directions = (a.reshape(len(pending), sensor.beams, -1, 3)
                                   for a in (origins, directions))  # fmt: skip
        if config.moves:  # t = 0: the window's first firing, the scene as built
            drawn = None
            if motion_columns:
                drawn = catalog.object_motion(obj[pending], u[:, columns:])
                drawn_motion[pending] = np.stack([drawn[key] for key in MOTION_KEYS], axis=-1)
            more["motion"] = (config.ego_motion, drawn, ray_times(times_ns * 1e-9, directions))
        hits, object_pose = backend(
            catalog,
            layout[pending],
            obj[pending],
            u[:, FIXED_COLUMNS : FIXED_COLUMNS + lc],
            u[:, FIXED_COLUMNS + lc : columns],
            origins,
            directions,
            index[pending] % MAX_BATCH,
            sensor.max_range_m,
            **more,
        )
        if beams:  # the scene is judged by the axes alone, as with one ray a pulse
            beam_hits = hits
            hits = axis_hits(hits, width)
        r = quantise_range(hits.range_m, sensor)
        on_object = (hits.on_object & ~np.isnan(r)).sum(axis=(1, 2))
        ok = (obj[pending] == 0) | (on_object >= config.min_object_hits)
        ok &= layouts_seen(catalog, layout[pending], hits.surface, ~np.isnan(r), azimuth)
        done = pending[ok]
        range_m[done] = r[ok]
        surface[done] = np.where(np.isnan(r[ok]), 0, hits.surface[ok])
        if beams:
            got = split_beams(beam_hits, width)
            inside = ~np.isnan(quantise_range(got.range_m[ok], sensor))
            hit_m[done] = np.where(inside, got.range_m[ok], np.nan)
            cos_incidence[done] = got.cos_incidence[ok]
            hit_surface[done] = np.where(inside, got.surface[ok], 0)
        elif physics is not None:
            hit_m[done] = np.where(np.isnan(r[ok]), np.nan, hits.range_m[ok])
            cos_incidence[done] = hits.cos_incidence[ok]
        pose[done] = object_pose[ok]
        hits_out[done] = on_object[ok]
        phase[done] = u[ok, 0]
        emission[done] = times_ns[ok]
        if config.shift_max > 0:
            shift[done] = (2.0 * u[ok, 1] - 1.0) * config.shift_max
        pending = pending[~ok]
        if len(pending) and attempts[pending].max() >= config.max_attempts:
            k = pending[0]
            step = config.fov_deg / width
            low, high = min(sensor.elevations_deg), max(sensor.elevations_deg)
            raise SimlidarError(
                f"{split} sample {index[k]} ({plan.names[labels[k]]}): no draw in "
                f"{config.max_attempts} showed the object (min_object_hits="
                f"{config.min_object_hits}) and the layout's `visible` surface with width "
                f"{width} ({step:.3g} deg between columns) and sensor {sensor.name} "
                f"({low:+g} to {high:+g} deg); expected a width whose columns are close enough "
                "to hit the object (the shipped scenes need about 8 or more at 36 deg) and "
                "recipes whose object and layout the sensor can see (docs/sensor-model.md)"
            )
    received = {}
    if physics is not None:
        split_id = SPLIT_IDS[split]
        streams = [receiver_stream(config.seed, split_id, i) for i in index]
        if beams:
            got = receive_hits(
                config, physics, choices, streams, hit_m, hit_surface, cos_incidence, weights
            )
            received = {
                "echoes": got.echoes,
                "returns_tof_ns": tof_ns(got.returns_range_m).astype(np.float32),
                "returns_intensity": got.returns_intensity,
                "returns_surface": got.returns_surface,
            }
            if got.waveform is not None:
                received["waveform"] = got.waveform
        else:
            got = receive_hits(config, physics, choices, streams, hit_m, surface, cos_incidence)
        range_m, surface = got.range_m, got.surface
        received |= {"intensity": got.intensity, "reflectance": got.reflectance}
        received["power_w"] = got.power_w
    if config.moves:
        ego = (config.ego_speed_mps, config.ego_yaw_rate_deg_s)
        received["object_motion"] = drawn_motion.astype(np.float32)
        received["ego_motion"] = np.tile(np.array(ego, np.float32), (n, 1))
    tof, clean = delays_from_range(range_m, sensor)
    if config.shift_max > 0:
        clean = shift_delays(clean, shift)
    return Samples(
        clean_delays=clean,
        noise_u=noise_u,
        tof_ns=tof.astype(np.float32),
        surface=surface,
        labels=labels.astype(np.int64),
        layout=layout.astype(np.uint8),
        object=obj.astype(np.uint8),
        object_pose=pose.astype(np.float32),
        object_hits=hits_out,
        attempts=attempts,
        phase=phase.astype(np.float32),
        shift=shift.astype(np.float32),
        emission_ns=emission,
        **received,
    )
