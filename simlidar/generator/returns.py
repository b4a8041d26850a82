"""Hits -> returns through a receiver: the profiles with a ``receiver`` key (``sensor``; issue 41).

Every hit in range of the ray caster becomes a return under the other profiles. Here a hit
returns only if the receiver detects it (:mod:`simlidar.sensor.receiver`, every formula in
``docs/sensor-model.md``):

1. each catalog surface of a sample is made of one material, a choice among the materials
   file's ``[surfaces]`` list, with a reflectance drawn uniformly in that material's
   ``reflectance_range``;
2. per pixel, the received power of the LiDAR range equation, from the hit's range, the
   surface's reflectance and the incidence angle, and the fog's two-way extinction where the
   dataset has one (``--fog``; clear air: extinction 0);
3. a power below the receiver's threshold is no return (a drop-out); a detected return moves
   by Gaussian range noise of sigma ``range_noise_m(power)`` and is quantised to the sensor's
   resolution as every return is (a return moved out of the sensor's range is no return);
4. the sensor's calibrated reflectivity byte (``intensity``) of each return.

Randomness: a sample's draws here come from a stream of their own,
``SeedSequence(seed, spawn_key=(split, index, RECEIVER_STREAM))``, read in a fixed order (two
uniforms per catalog surface, label order: material, reflectance; then one standard normal per
pixel), so the sample's own stream, and with it the scenes, phases and noise of the other
profiles, is untouched: a ``sensor`` sample sees the scene its ``physical`` twin (same seed,
split and index) sees.
"""

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.content import content_dir
from simlidar.errors import ConfigError
from simlidar.generator.pulses import quantise_range
from simlidar.sensor.model import Sensor
from simlidar.sensor.receiver import (
    Material,
    Receiver,
    detected,
    load_materials,
    load_receiver,
    materials_to_dict,
    range_noise_m,
    received_power_w,
    receiver_to_dict,
    reflectivity_byte,
)

# The child stream key of a sample's receiver draws (the number: any constant will do,
# as long as no other stream of a sample uses it)
RECEIVER_STREAM = 41


@dataclass(frozen=True)
class Physics:
    """A profile's receiver and materials, read from their files."""

    receiver: Receiver
    materials: dict[str, Material]  # name -> material
    surfaces: dict[str, list[str]]  # catalog surface label -> the materials a sample draws from

    def receiver_dict(self) -> dict:
        """The receiver as stored in a split's ``receiver`` attribute (its file's keys, name)."""
        return receiver_to_dict(self.receiver)

    def materials_dict(self) -> dict:
        """The materials as stored in a split's ``materials`` attribute (the file's form)."""
        return materials_to_dict(self.materials, self.surfaces)


def fingerprint(values: dict) -> str:
    """sha256 of a JSON-able content (as the scene catalog's fingerprint is made)."""
    text = json.dumps(values, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def receiver_physics(profile) -> Physics:
    """The receiver and materials a profile (with a ``receiver``) names, read and checked: a
    ConfigError naming the key and the file otherwise."""
    try:
        receiver = load_receiver(profile.receiver)
    except ConfigError as exc:
        raise ConfigError(f"key 'receiver': {exc}") from None
    if receiver.reflectivity_diffuse_max == 0:
        raise ConfigError(
            f"key 'receiver': receiver {receiver.name!r} has no reflectivity scale "
            "(reflectivity_diffuse_max, reflectivity_max); expected a receiver whose manual "
            "defines the intensity it reports (vlp16)"
        )
    path = content_dir("scenes") / "materials.toml" if profile.materials is None else None
    try:
        materials, surfaces = load_materials(Path(profile.materials) if path is None else path)
    except ConfigError as exc:
        raise ConfigError(f"key 'materials': {exc}") from None
    return Physics(receiver, materials, surfaces)


def check_physics(physics: Physics, sensor: Sensor, surface_names) -> list[list[Material]]:
    """The materials each catalog surface label may be made of (label 0, none: []); a
    ConfigError where a surface has no materials or the receiver is another sensor's."""
    if physics.receiver.name != sensor.name:
        raise ConfigError(
            f"receiver {physics.receiver.name!r} with sensor {sensor.name!r}: expected the "
            f"receiver of the sensor (sensors/receivers/{sensor.name}.toml, in a profile of "
            "its own)"
        )
    missing = [s for s in surface_names[1:] if s not in physics.surfaces]
    if missing:
        raise ConfigError(
            f"surfaces {missing} of the scene catalog have no materials: expected a list for "
            "each under [surfaces] of the materials file"
        )
    return [[]] + [[physics.materials[m] for m in physics.surfaces[s]] for s in surface_names[1:]]


def receiver_stream(seed: int, split_id: int, index: int) -> np.random.Generator:
    seq = np.random.SeedSequence(seed, spawn_key=(split_id, int(index), RECEIVER_STREAM))
    return np.random.Generator(np.random.PCG64(seq))


def draw_surfaces(g: np.random.Generator, choices: list[list[Material]]):
    """One sample's materials: the reflectance (S,) float64 and retro-reflectivity (S,) bool of
    each of its S surface labels (label 0: NaN, False). Two uniforms a label, drawn for every
    label whether the sample shows it or not (a fixed number of draws)."""
    u = g.random((len(choices) - 1, 2))
    reflectance = np.full(len(choices), np.nan)
    retro = np.zeros(len(choices), bool)
    for label, (pick, level) in enumerate(u, start=1):
        options = choices[label]
        material = options[min(int(pick * len(options)), len(options) - 1)]
        low, high = material.reflectance_min, material.reflectance_max
        reflectance[label] = low + level * (high - low)
        retro[label] = material.kind == "retroreflective"
    return reflectance, retro


@dataclass(frozen=True)
class Returns:
    """What the receiver makes of a block of hits (n samples, H x W pulses)."""

    range_m: np.ndarray  # (n, H, W) float64, quantised; NaN: no return (missed or dropped)
    intensity: np.ndarray  # (n, H, W) uint8, the sensor's reflectivity byte; 0: no return
    reflectance: np.ndarray  # (n, H, W) float32, the hit surface's drawn value; NaN: no hit
    power_w: np.ndarray  # (n, H, W) float32, received power of the hit; 0: no hit


def receive(
    physics: Physics,
    choices: list[list[Material]],
    sensor: Sensor,
    streams: list[np.random.Generator],
    range_m: np.ndarray,
    surface: np.ndarray,
    cos_incidence: np.ndarray,
    extinction_per_m: float = 0.0,
) -> Returns:
    """The returns of a block of hits.

    choices : per surface label, its materials (:func:`check_physics`)
    streams : (n,) each sample's receiver stream (:func:`receiver_stream`)
    range_m : (n, H, W) float64, unquantised range of each hit within the sensor's range; NaN
        where none
    surface : (n, H, W) uint8 labels; cos_incidence : (n, H, W) |cos| of the incidence angle
    extinction_per_m : the atmosphere's alpha (fog: ``GeneratorConfig.extinction_per_m``; 0:
        clear air), two-way Beer-Lambert in the range equation
    """
    receiver = physics.receiver
    drawn = [draw_surfaces(g, choices) for g in streams]
    z = np.stack([g.standard_normal(range_m.shape[1:]) for g in streams])  # (n, H, W)
    table = np.stack([r for r, _ in drawn])  # (n, S)
    retro_table = np.stack([t for _, t in drawn])
    labels = surface.reshape(len(streams), -1).astype(np.int64)
    reflectance = np.take_along_axis(table, labels, axis=1).reshape(surface.shape)
    retro = np.take_along_axis(retro_table, labels, axis=1).reshape(surface.shape)
    hit = ~np.isnan(range_m)
    reflectance = np.where(hit, reflectance, np.nan)
    rho = np.where(hit, reflectance, 0.0)
    safe_m = np.where(hit, range_m, 1.0)  # the equation divides by R^2
    incidence = np.arccos(np.clip(cos_incidence.astype(np.float64), 0.0, 1.0))
    power = received_power_w(receiver, safe_m, rho, incidence, extinction_per_m)
    power = np.where(hit, power, 0.0)
    seen = hit & detected(receiver, power)
    sigma = np.where(seen, range_noise_m(receiver, np.where(seen, power, 1.0)), 0.0)
    returned_m = quantise_range(np.where(seen, safe_m + sigma * z, np.nan), sensor)
    returned = ~np.isnan(returned_m)
    intensity = np.where(returned, reflectivity_byte(receiver, rho, retro), 0)
    return Returns(
        range_m=returned_m,
        intensity=intensity.astype(np.uint8),
        reflectance=reflectance.astype(np.float32),
        power_w=power.astype(np.float32),
    )
