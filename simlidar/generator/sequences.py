"""Sequences and motion in a sweep (``simlidar sweep`` with ``--ego-speed``, ``--ego-yaw-rate``,
``--moving-objects`` or ``--sequence-frames``; docs/sweeps.md, "Motion"): where each frame of a
sequence starts as the head turns on (:func:`frame_cycles`), each pulse's time and the ego's and
objects' motions at it (:func:`frame_motion`), the fields a frame in motion stores, and what a
sweep in motion must satisfy (:func:`check_motion`)."""

import json
from dataclasses import dataclass

import numpy as np

from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.returns import fingerprint
from simlidar.motion.poses import PlanarMotion
from simlidar.motion.trajectory import Trajectory
from simlidar.scene.build import CELL_HALF_EXTENT_M
from simlidar.scene.motion import KEYS as MOTION_KEYS
from simlidar.scene.motion import MOTION_FILE
from simlidar.scene.recipe import Catalog
from simlidar.sensor.raycast import CELL_SPACING_M
from simlidar.sensor.rays import cycles_per_rotation, sweep_emission_ns

# what the sensor's mount and emitters add to the ego's reach (the tallest shipped: the
# HDL-64E, 1.73 m up)
MOUNT_ROOM_M = 3.0


def frame_cycles(sensor, step: np.ndarray, phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where frame ``step`` of a sequence starts: its first firing cycle, counted from the
    sequence's first, and its phase. The head turns on at 60e6 / rpm / cycle_us cycles a
    rotation (1808.45 for a VLP-16 at 600 RPM): rotation j holds the cycles whose azimuth
    ``-180 + (k + phase_0) * azimuth_step_deg`` lies in [-180 + 360 j, 180 + 360 j), and a
    frame is its first :func:`~simlidar.sensor.rays.cycles_per_rotation` cycles (the cycle
    left over, where there is one, belongs to no frame). Frame 0 starts at cycle 0 with the
    sequence's own phase, bit for bit (every sweep before sequences).

    step : (n,) int, each frame's place in its sequence
    phase : (n,) float64 in [0, 1), its sequence's phase (the scene's draw)
    returns : first cycle (n,) float64 (whole numbers), the frame's phase (n,) in [0, 1)
    """
    turned = step * (60e6 / sensor.rpm / sensor.cycle_us) - phase
    first = np.ceil(turned) + 0.0  # + 0.0: frame 0's ceil(-phase) is -0.0
    return first, first - turned


@dataclass(frozen=True)
class FrameMotion:
    """How a batch of frames moves: each pulse's time and the ego's and objects' motions."""

    times_s: np.ndarray  # (n, H, C) float64, each pulse's emission from its sequence's start
    start_ns: np.ndarray  # (n,) float64, each frame's first firing from its sequence's start
    reference_s: np.ndarray  # (n,) float64, each frame's middle cycle (the head facing ahead)
    ego: PlanarMotion | Trajectory  # the sensor's motion from the sequence's start
    things: PlanarMotion | None  # each frame's object's, fields (n, 1, 1); None: standing

    def fields(self, scene_of: np.ndarray, boxes: np.ndarray, drawn: dict | None) -> dict:
        """The frames' SWEEP_MOTION_SCHEMA fields; ``boxes`` (n, 7), each object's box at its
        placement, moved to the frame's reference time in place."""
        ego = self.ego.poses(self.reference_s)
        if self.things is not None:  # the fields' (n, 1, 1) against times (n, 1, 1)
            moved = self.things.poses(self.reference_s[:, None, None])
            boxes[:, 3:6] = moved.to_scene(boxes[:, None, None, 3:6])[:, 0, 0]
            boxes[:, 6] += self.things.yaw_rate_deg_s[:, 0, 0] * self.reference_s
        motion = np.zeros((len(scene_of), 3))
        if drawn is not None:
            motion = np.stack([drawn[key] for key in MOTION_KEYS], axis=-1)
        return {
            "sequence": scene_of.astype(np.int64),
            "start_ns": self.start_ns,
            "ego_pose": np.concatenate([ego.rotation, ego.translation_m[..., None]], axis=-1),
            "object_motion": motion.astype(np.float32),
        }


def frame_motion(
    config: GeneratorConfig, scene, first_cycle: np.ndarray, drawn: dict | None
) -> FrameMotion:
    """The motion of a batch of frames of ``config`` (which moves something): each pulse's
    time from its frame's ``first_cycle`` (n,) and the sweep's emission times, the ego's
    motion and, with ``drawn`` (each frame's object's speed, heading and yaw rate,
    :meth:`~simlidar.scene.recipe.Catalog.object_motion`), the objects' about their
    placements (``scene.object_pose``)."""
    sensor = config.sensor
    start_ns = first_cycle * sensor.cycle_us * 1000.0
    times_s = (start_ns[:, None, None] + sweep_emission_ns(sensor)[None]) * 1e-9
    middle = first_cycle + cycles_per_rotation(sensor) // 2
    things = placed_motion(scene.object_pose, drawn)
    return FrameMotion(times_s, start_ns, middle * sensor.cycle_us * 1e-6, config.ego_motion,
                       things)  # fmt: skip


def placed_motion(object_pose: np.ndarray, drawn: dict | None) -> PlanarMotion | None:
    """The motion of each scene's object about its placement, from its pose ``object_pose``
    (n, 3: x, y, yaw; NaN without object) and ``drawn`` (each key of motion.KEYS -> (n,),
    :meth:`~simlidar.scene.recipe.Catalog.object_motion`), fields (n, 1, 1); None without
    ``drawn`` (the objects stand still)."""
    if drawn is None:
        return None
    column = {key: value[:, None, None] for key, value in drawn.items()}
    at = np.nan_to_num(object_pose[:, :2])[:, :, None, None]  # none: no object
    return PlanarMotion(column["speed_mps"], column["yaw_rate_deg_s"], column["heading_deg"],
                        (at[:, 0], at[:, 1]))  # fmt: skip


def ray_times(times_s: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Each ray's time from its pulse's ``times_s`` (n, H, C), where ``directions`` (n, H, C S,
    3) holds S sub-rays a pulse (a beam footprint: every sub-ray leaves with its pulse)."""
    subrays = directions.shape[2] // times_s.shape[2]
    if subrays == 1:
        return times_s
    return np.repeat(times_s[..., None], subrays, axis=-1).reshape(directions.shape[:3])


def objects_reach_m(catalog: Catalog, span_s: float, ego_m: float) -> float:
    """A bound on how far a moving object of ``catalog`` can carry the sensor, in the object's
    own frame, over ``span_s`` seconds: its travel (the fastest speed of the catalog's
    motion.toml) and its turn about its placement point (the fastest yaw rate, over the
    farthest placement and the ego's own ``ego_m``), for the sensor's reach in the ray
    caster's cell. Conservative: it holds for every draw."""
    speed = max((m.speed_mps.upper for m in catalog.motion.values()), default=0.0)
    turn = max((abs(v) for m in catalog.motion.values() for v in m.yaw_rate_deg_s.values),
               default=0.0)  # fmt: skip
    placed = max(
        (
            float(np.hypot(*(abs(v) for v in pair)))
            for recipe in catalog.objects
            for pair in _placement_extremes(recipe)
        ),
        default=0.0,
    )
    return speed * span_s + min(np.deg2rad(turn) * span_s, 2.0) * (placed + ego_m)


def _placement_extremes(recipe) -> list[tuple[float, float]]:
    """The farthest (distance_m, lateral_m) corners an object recipe can place it at."""
    params = {p.name: p for p in recipe.params}
    if "distance_m" not in params:
        return []
    return [(d, lat) for d in params["distance_m"].values for lat in params["lateral_m"].values]


def check_motion(config: GeneratorConfig, catalog: Catalog, sequence: int) -> None:
    """Refuse in one line (ConfigError) moving objects of a catalog without a motion.toml, and
    a sequence along which the sensor, in the scene's or a moving object's frame
    (:func:`objects_reach_m`), leaves the ray caster's cell (its rays would reach another
    scene's: :data:`~simlidar.sensor.raycast.CELL_SPACING_M`), before anything is written."""
    if config.moving_objects and not catalog.motion:
        raise ConfigError(
            f"moving_objects (--moving-objects): the scene catalog {catalog.root} has no "
            f"{MOTION_FILE}; expected one saying how its objects move (docs/scenes.md)"
        )
    if not config.moves:  # the sensor stands where cast() checks its reach
        return
    sensor = config.sensor
    span_s = sequence * 60.0 / sensor.rpm  # every pulse of the sequence leaves before then
    room_m = CELL_SPACING_M - CELL_HALF_EXTENT_M - sensor.max_range_m - 1.0 - MOUNT_ROOM_M
    trajectory = config.ego_trajectory
    if trajectory is None:
        travel_m = config.ego_speed_mps * span_s
        how = f"ego_speed_mps={config.ego_speed_mps!r}"
    else:
        trajectory.check_covers(0.0, span_s, f"--trajectory {trajectory.source}")
        inside = (trajectory.t_s > 0.0) & (trajectory.t_s < span_s)
        ends = trajectory.poses(np.array([0.0, span_s])).translation_m
        points = np.concatenate([trajectory.positions_m[inside], ends])
        travel_m = float(np.abs(points).max())
        how = f"--trajectory {trajectory.source}"
    if config.moving_objects:  # the sensor as a moving object sees it, in its own frame
        travel_m += objects_reach_m(catalog, span_s, travel_m)
        how += " and the objects' motion"
    if travel_m > room_m:
        raise ConfigError(
            f"{how} over a sequence of {sequence} frames: {travel_m:.4g} m from the scene's "
            f"origin; expected at most {room_m:.4g} m (the scene's cell; fewer frames a "
            "sequence, --sequence-frames, or a lower speed)"
        )


def motion_attrs(config: GeneratorConfig, catalog: Catalog) -> dict:
    """The attributes a sweep's or a split's file stores of the objects' motion: with moving
    objects, the catalog's motion.toml as used (``motion``, not part of the stored catalog) and
    its digest (``motion_sha256``); none otherwise."""
    if not config.moving_objects:
        return {}
    motion = {name: m.source for name, m in sorted(catalog.motion.items())}
    return {"motion": json.dumps(motion, sort_keys=True), "motion_sha256": fingerprint(motion)}


def check_window_motion(config: GeneratorConfig, catalog: Catalog) -> None:
    """Refuse in one line (ConfigError) motion that windows cannot take: flash timing (every
    pulse at one instant: nothing moves between them), a trajectory file (a sweep's sequence
    follows one; a window is 10 ms of a rotation) and what a sweep's motion must satisfy over
    one rotation (:func:`~simlidar.generator.sequences.check_motion`)."""
    if config.timing != "scan":
        raise ConfigError(
            f"{_motion_words(config)} with timing={config.timing!r}: expected --timing scan "
            "(flash timing fires every pulse of a window at one instant, so nothing moves "
            "between them)"
        )
    if config.ego_trajectory is not None:
        raise ConfigError(
            f"ego_trajectory ({config.ego_trajectory.source}): expected --ego-speed and "
            "--ego-yaw-rate for windows (a trajectory file drives a sweep's sequences: "
            "simlidar sweep --trajectory)"
        )
    check_motion(config, catalog, 1)


def _motion_words(config: GeneratorConfig) -> str:
    """How ``config`` moves, as its options name it."""
    words = [f"--ego-speed {config.ego_speed_mps!r}"] * bool(config.ego_speed_mps)
    words += [f"--ego-yaw-rate {config.ego_yaw_rate_deg_s!r}"] * bool(config.ego_yaw_rate_deg_s)
    words += ["--trajectory"] * (config.ego_trajectory is not None)
    return " ".join(words + ["--moving-objects"] * config.moving_objects)
