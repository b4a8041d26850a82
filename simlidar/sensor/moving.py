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
are the same in every frame. The two bodies of every sample are cast in one Embree scene
(:func:`simlidar.sensor.raycast.cast`): the object in a grid cell of its own, its rays beside
the world's. The light's own flight is left out: a car at 10 m/s moves 6.7 um in the 667 ns a
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

from simlidar.motion.poses import Poses
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
    objects: Poses | None = None,
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
    objects : (B, H, C) motions of each sample's object at each pulse's time (its pose then
        relative to its placement); None: the objects stand still
    incidence, compiled : as :func:`~simlidar.sensor.raycast.cast`
    returns : the hits, ranges along each ray (the same in every frame)
    """
    batch = len(slots)
    world_origins, world_directions = ego.to_scene(origins), ego.rotate(directions)
    if objects is None or not scene.is_object.any():
        return cast(scene, world_origins, world_directions, slots, max_range_m, cull=False,
                    incidence=incidence, compiled=compiled)  # fmt: skip
    both = SceneBatch(*(np.concatenate(pair) for pair in zip(
        _fields(_part(scene, ~scene.is_object, scene.sample)),
        _fields(_part(scene, scene.is_object, scene.sample + batch)),
    )), object_pose=np.concatenate([scene.object_pose] * 2))  # fmt: skip
    hits = cast(
        both,
        np.concatenate([world_origins, objects.to_body(world_origins)]),
        np.concatenate([world_directions, objects.unrotate(world_directions)]),
        np.concatenate([slots, (np.asarray(slots) + OBJECT_CELLS) % MAX_BATCH]),
        max_range_m,
        cull=False,
        incidence=incidence,
        compiled=compiled,
    )
    return nearest(hits, batch)


def _fields(scene: SceneBatch) -> tuple:
    """A scene's per-triangle arrays, in SceneBatch's order."""
    return scene.triangles, scene.surface, scene.sample, scene.closed, scene.is_object


def nearest(hits: Hits, batch: int) -> Hits:
    """The nearer of two casts of the same pulses stacked as ``hits`` (2 B, ...): the world's
    (the first B) and the objects' (the last B); a pulse that hits neither has none."""
    first = {name: getattr(hits, name) for name in ("range_m", "surface", "on_object")}
    world = np.nan_to_num(hits.range_m[:batch], nan=np.inf)
    thing = np.nan_to_num(hits.range_m[batch:], nan=np.inf)
    take = thing < world  # ties go to the world: it was built first
    picked = {name: np.where(take, value[batch:], value[:batch]) for name, value in first.items()}
    cos = hits.cos_incidence
    if cos is not None:
        cos = np.where(take, cos[batch:], cos[:batch])
    return Hits(picked["range_m"], picked["surface"], picked["on_object"], cos)
