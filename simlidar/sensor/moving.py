"""Casting in a moving world: every pulse at its own emission time, exactly for rigid motion.

A spinning sensor fires its pulses over a whole rotation (100 ms for a VLP-16 at 600 RPM), from
a car that moves, at objects that move. Nothing here steps time: a pulse's ray, given in the
sensor's frame, is expressed in each body's own frame at the pulse's time and cast against
that body as it was built, and the nearest hit is kept:

* the static world (the layout, in the scene frame): the ray moved by the ego's pose at its
  time, ``E(t)``;
* the sample's object, built at its placement (its pose at t = 0): the scene ray moved back by
  the object's motion at the same time, ``M(t)^-1 E(t)``.

Rigid maps keep lengths and angles, so the range along the ray, and the angle of incidence,
are the same in every frame. The world is cast with every ray; the object only with the rays
that pass within a sphere holding it over the frame (:func:`frame_spheres`: about 4 % of a
VLP-16 frame's; the others cannot hit it), in a grid cell of its own
(:func:`simlidar.sensor.raycast.cast`), each ray's hits those of casting every ray. The
light's own flight is left out: a car at 10 m/s moves 6.7 um in the 667 ns a
pulse takes to 100 m and back, 3.3e-3 of the VLP-16's 2 mm range resolution and 2.2e-4 of
its +-3 cm accuracy (its user manual, 63-9243 Rev D).

Every triangle is cast against (no culling of back faces): culling rests on every origin lying
outside every closed solid, which a moving world breaks (an oncoming car that drives through
the sensor), and a batch's culling then changed its frames with the batch's size. Without it
the hits are exact wherever the origins are, and cheaper here: culling origins spread along a
trajectory cost more than the Embree build it saved (``benchmark/motion_speed.py``).
"""

from dataclasses import replace

import numpy as np

from simlidar.motion.poses import PlanarMotion, Poses
from simlidar.scene.build import SceneBatch
from simlidar.sensor.raycast import MAX_BATCH, Hits, cast

# The object of sample b is cast in cell (slot_b + OBJECT_CELLS) mod MAX_BATCH: a batch of at
# most MAX_BATCH / 2 samples of consecutive indices never puts an object in a world's cell
OBJECT_CELLS = MAX_BATCH // 2


def _part(scene: SceneBatch, keep: np.ndarray, sample: np.ndarray) -> SceneBatch:
    """The triangles ``keep`` (T,) bool of ``scene``, tagged with the samples ``sample`` (T,)."""
    return replace(
        scene,
        triangles=scene.triangles[keep],
        surface=scene.surface[keep],
        sample=sample[keep],
        closed=scene.closed[keep],
        is_object=scene.is_object[keep],
    )


def cast_moving(
    scene: SceneBatch,
    origins: np.ndarray,
    directions: np.ndarray,
    slots: np.ndarray,
    max_range_m: float,
    ego: Poses,
    things: PlanarMotion | None = None,
    times_s: np.ndarray | None = None,
    incidence: bool = False,
    compiled: bool = False,
) -> Hits:
    """First hit of every pulse of B samples, each cast at its own time (module docstring).

    scene : the B samples' triangles as built (the scene frame; each object at its placement)
    origins, directions : (B, H, C, 3) float64, each pulse's ray in the sensor's frame
    slots : (B,) int, distinct grid cells, in at most MAX_BATCH / 2 consecutive indices (the
        samples' indices mod MAX_BATCH, as :func:`~simlidar.sensor.raycast.cast` takes them)
    max_range_m : the sensor's range
    ego : (B, H, C) poses of the sensor in the scene frame at each pulse's time
    things : the motion of each sample's object about its placement (fields that broadcast
        against (B, 1, 1)); None: the objects stand still
    times_s : with ``things``: (B, H, C) each pulse's time, s
    incidence, compiled : as :func:`~simlidar.sensor.raycast.cast`
    returns : the hits, ranges along each ray (the same in every frame)
    """
    world_origins, world_directions = ego.to_scene(origins), ego.rotate(directions)
    rays = (world_origins, world_directions, max_range_m)
    more = dict(cull=False, incidence=incidence, compiled=compiled)
    part = scene.is_object
    if things is None or not part.any():
        return cast(scene, *rays[:2], slots, max_range_m, **more)
    world = cast(_part(scene, ~part, scene.sample), *rays[:2], slots, max_range_m, **more)
    thing = _object_hits(scene, rays, slots, things, times_s, more)
    return nearest(world, thing)


def _object_hits(scene: SceneBatch, rays, slots, things: PlanarMotion, times_s, more) -> Hits:
    """The hits of the samples' objects alone, each ray moved into its object's frame at its
    time: only the rays that pass near the object over the frame (:func:`frame_spheres`) are
    moved and cast (4 % of a VLP-16 frame's; the others cannot hit it), each sample's padded
    to the most any sample has, in the object cells."""
    world_origins, world_directions, max_range_m = rays
    shape = world_origins.shape[:-1]
    batch = shape[0]
    things = _per_sample(things, batch)
    times = np.broadcast_to(np.asarray(times_s, np.float64), shape)
    centre, radius = frame_spheres(things, times, *object_spheres(scene))
    near = reaches(world_origins, world_directions, centre[:, None, None],
                   radius[:, None, None] + SPHERE_MARGIN_M, max_range_m + 1.0)  # fmt: skip
    near &= (radius >= 0)[:, None, None]
    frame, _ = np.nonzero(near.reshape(batch, -1))
    flat = np.flatnonzero(near)
    hits = Hits(np.full(shape, np.nan), np.zeros(shape, np.uint8), np.zeros(shape, bool),
                np.zeros(shape, np.float32) if more["incidence"] else None)  # fmt: skip
    if len(flat) == 0:
        return hits
    counts = np.bincount(frame, minlength=batch)
    cast_of = np.nonzero(counts)[0]  # the samples cast, in order
    rank = np.arange(len(flat)) - (np.cumsum(counts) - counts)[frame]
    row = np.cumsum(counts > 0)[frame] - 1  # each ray's sample among cast_of
    padded = np.repeat(flat[np.searchsorted(frame, cast_of)][:, None], counts.max(), axis=1)
    padded[row, rank] = flat  # each sample's rays, then its first again
    pulses = padded.reshape(-1)

    def each(field) -> np.ndarray:
        return np.broadcast_to(field, shape).reshape(-1)[pulses]

    moved = PlanarMotion(
        each(things.speed_mps),
        each(things.yaw_rate_deg_s),
        each(things.heading_deg),
        tuple(each(f) for f in things.origin_m),
    )
    poses = moved.poses(times.reshape(-1)[pulses])  # fmt: skip
    local = (len(cast_of), 1, counts.max(), 3)
    origins = poses.to_body(world_origins.reshape(-1, 3)[pulses]).reshape(local)
    directions = poses.unrotate(world_directions.reshape(-1, 3)[pulses]).reshape(local)
    renumber = np.full(batch, -1)
    renumber[cast_of] = np.arange(len(cast_of))
    keep = scene.is_object & (renumber[scene.sample] >= 0)
    cells = (np.asarray(slots)[cast_of] + OBJECT_CELLS) % MAX_BATCH
    got = cast(_part(scene, keep, renumber[scene.sample]), origins, directions, cells,
               max_range_m, **more)  # fmt: skip
    for name in ("range_m", "surface", "on_object", "cos_incidence"):
        value = getattr(got, name)
        if value is not None:
            getattr(hits, name).reshape(-1)[flat] = value[row, 0, rank]
    return hits


def _per_sample(things: PlanarMotion, batch: int) -> PlanarMotion:
    """``things`` with every field an array (B, 1, 1)."""

    def field(value) -> np.ndarray:
        return np.broadcast_to(np.asarray(value, np.float64), (batch, 1, 1))

    origin = tuple(field(f) for f in things.origin_m)
    return PlanarMotion(field(things.speed_mps), field(things.yaw_rate_deg_s),
                        field(things.heading_deg), origin)  # fmt: skip


def object_spheres(scene: SceneBatch) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's object's bounding sphere as built: centres (B, 3) m (its box's centre) and
    radii (B,) m (its farthest vertex); a radius of -1 where a sample has no object."""
    batch = len(scene.object_pose)
    part = scene.is_object
    vertices, sample = scene.triangles[part], scene.sample[part]
    low, high = np.full((batch, 3), np.inf), np.full((batch, 3), -np.inf)
    np.minimum.at(low, sample, vertices.min(axis=1))
    np.maximum.at(high, sample, vertices.max(axis=1))
    found = np.isfinite(low[:, 0])
    centres = np.zeros((batch, 3))
    centres[found] = (low[found] + high[found]) / 2
    far = ((vertices - centres[sample][:, None, :]) ** 2).sum(axis=-1).max(axis=1)
    squared = np.full(batch, -1.0)
    np.maximum.at(squared, sample, far)
    return centres, np.where(squared >= 0, np.sqrt(np.maximum(squared, 0.0)), -1.0)


# the times a frame's sphere is taken at (frame_spheres): with 9, what the sphere grows for
# the path between them is a sixteenth of the frame's travel (0.09 m for a car at 15 m/s over
# a 100 ms frame), under 4 % of a car's radius (2.5 m)
SPHERE_TIMES = 9
# what a sphere grows by for the float32 the ray caster works in (3e-5 m at 320 m from the
# grid's centre), a margin of 300 times
SPHERE_MARGIN_M = 0.01


def frame_spheres(things: PlanarMotion, times_s, centres, radii) -> tuple[np.ndarray, ...]:
    """One sphere a frame that holds its object at every pulse: centres (B, 3), radii (B,)
    (-1 where ``radii`` is).

    A rigid motion keeps the object within ``radii`` of where it takes its sphere's centre, so
    the frame's sphere holds the centre's path over the frame's span grown by ``radii``. The
    path is taken at SPHERE_TIMES times; between two of them the centre moves at most its
    speed (the body's, plus its yaw rate times its distance from the point it turns about)
    times their gap, so no point of the path is farther than half that from one of them.

    things : the objects' motions, fields (B, 1, 1)
    times_s : (B, H, C) each pulse's time
    centres, radii : each object's sphere as built (:func:`object_spheres`)
    """
    low, high = times_s.min(axis=(1, 2)), times_s.max(axis=(1, 2))
    at = low[:, None] + (high - low)[:, None] * np.linspace(0.0, 1.0, SPHERE_TIMES)  # (B, K)
    path = things.poses(at[:, None, :]).to_scene(centres[:, None, None, :])[:, 0]  # (B, K, 3)
    origin = np.stack(np.broadcast_arrays(*things.origin_m), axis=-1)[:, 0, 0]  # (B, 2)
    arm = np.sqrt(((centres[:, :2] - origin) ** 2).sum(-1))
    speed = np.abs(things.speed_mps[:, 0, 0]) + np.deg2rad(
        np.abs(things.yaw_rate_deg_s[:, 0, 0])) * arm  # fmt: skip
    gap = (high - low) / (SPHERE_TIMES - 1)
    lo, hi = path.min(axis=1), path.max(axis=1)
    spread = np.sqrt(((hi - lo) ** 2).sum(-1)) / 2 + speed * gap / 2
    return (lo + hi) / 2, np.where(radii >= 0, radii + spread, -1.0)


def reaches(origins, directions, centres, radii, length_m: float) -> np.ndarray:
    """Whether each ray's first ``length_m`` metres pass within ``radii`` of ``centres``
    (each broadcast against the rays' leading shape): rays of ``origins`` and unit
    ``directions`` (..., 3) -> (...) bool."""
    to_centre = centres - origins
    along = np.clip(np.einsum("...k,...k->...", to_centre, directions), 0.0, length_m)
    miss = to_centre - along[..., None] * directions
    return np.einsum("...k,...k->...", miss, miss) <= radii**2


def nearest(world: Hits, thing: Hits) -> Hits:
    """The nearer of two casts of the same pulses: the world's and the objects'; a pulse that
    hits neither has none."""
    near, far = (np.nan_to_num(h.range_m, nan=np.inf) for h in (thing, world))
    take = near < far  # ties go to the world: it was built first
    picked = [np.where(take, getattr(thing, name), getattr(world, name))
              for name in ("range_m", "surface", "on_object")]  # fmt: skip
    cos = world.cos_incidence
    if cos is not None:
        cos = np.where(take, thing.cos_incidence, cos)
    return Hits(*picked, cos)
