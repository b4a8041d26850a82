"""Hits -> returns through a receiver: the profiles with a ``receiver`` key (``sensor``; issues
41 and 62).

Every hit in range of the ray caster becomes a return under the other profiles. Here a hit
returns only if the receiver detects it (:mod:`simlidar.sensor.receiver`,
:mod:`simlidar.sensor.detection`; every formula in ``docs/sensor-model.md``, "The calibrated
receiver"; with a beam footprint, a return mode or weather, through each pulse's waveform:
:func:`receive_beams`):

1. each catalog surface of a sample is made of one material, a choice among the materials
   file's ``[surfaces]`` list, with a reflectance drawn uniformly in that material's
   ``reflectance_range`` and the material's angle law;
2. per pixel, the received power of the LiDAR range equation, from the hit's range, rho
   f(theta) of its surface (:func:`effective_reflectance`), the biaxial overlap and the
   atmosphere's two-way extinction (``--fog``, ``--rain``; clear air: 0);
3. the peak is measured with the detector's noise and detected where it reaches the threshold
   (a drop-out otherwise); the noise's own false alarms are echoes of surface 0
   (:mod:`simlidar.generator.measurement`); a return moves by the edge's timing jitter over
   the accuracy floor (:func:`simlidar.sensor.receiver.timing_noise_m`) and is quantised to
   the sensor's resolution as every return is (a return moved out of the sensor's range is
   no return);
4. the sensor's reflectivity byte (``intensity``) of each return, from its measured peak,
   range-compensated.

Randomness: a sample's draws here come from a stream of their own,
``SeedSequence(seed, spawn_key=(split, index, RECEIVER_STREAM))``, read in a fixed order: two
uniforms per catalog surface (label order: material, reflectance); the rain's drops (with
rain); ``ECHOES_MEASURED`` standard normals a pulse (the noise on its strongest echoes); the
false alarms (a Poisson count a pulse, two uniforms an alarm); one standard normal a pulse and
reported return (the range noise; a second block in ``dual`` mode); the stored waveform's noise
(on request). The sample's own stream, and with it the scenes, phases and noise of the other
profiles, is untouched: a ``sensor`` sample sees the scene its ``physical`` twin (same seed,
split and index) sees.
"""

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.content import content_dir
from simlidar.errors import ConfigError
from simlidar.generator.measurement import (
    ECHOES_MEASURED,
    false_alarm_echoes,
    fog_backscatter,
    measure_peaks,
    measured_echoes,
    reflectivity,
)
from simlidar.generator.pulses import quantise_range
from simlidar.sensor.model import SPEED_OF_LIGHT_M_PER_S, Sensor, tof_ns
from simlidar.sensor.receiver import (
    Material,
    Receiver,
    crossover_ranges,
    load_materials,
    load_receiver,
    materials_to_dict,
    received_power_w,
    receiver_to_dict,
    signal_noise_w,
    timing_noise_m,
)
from simlidar.sensor.waveform import BIN_NS, by_row, echoes, pulse_sigma_ns, reported, sampled
from simlidar.sensor.weather import CROSSOVER_M, Rain, fog_table, rain

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

    def attrs(self) -> dict:
        """The attributes a split (a window dataset's, a sweep's, a stream's) made through this
        receiver carries: ``receiver`` and ``materials`` as JSON, with their sha256."""
        receiver, materials = self.receiver_dict(), self.materials_dict()
        return {
            "receiver": json.dumps(receiver, sort_keys=True),
            "receiver_sha256": fingerprint(receiver),
            "materials": json.dumps(materials, sort_keys=True),
            "materials_sha256": fingerprint(materials),
        }


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


def check_physics(
    physics: Physics, sensor: Sensor, surface_names, return_mode: str = "strongest"
) -> list[list[Material]]:
    """The materials each catalog surface label may be made of (label 0, none: []); a
    ConfigError where a surface has no materials, the receiver is another sensor's or it has
    no such return mode."""
    if physics.receiver.name != sensor.name:
        raise ConfigError(
            f"receiver {physics.receiver.name!r} with sensor {sensor.name!r}: expected the "
            f"receiver of the sensor (sensors/receivers/{sensor.name}.toml, in a profile of "
            "its own)"
        )
    if return_mode not in physics.receiver.return_modes:
        raise ConfigError(
            f"return_mode={return_mode!r} (--return-mode): receiver {physics.receiver.name!r} "
            f"reports {list(physics.receiver.return_modes)}; expected one of them"
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
    each of its S surface labels (label 0: NaN, False), and each label's angle law as (S, 4)
    float64 (:func:`law_columns`: Oren-Nayar's B / A, the retro exponent, the coat's rho_s and
    lobe width; label 0: Lambert). Two uniforms a label, drawn for every label whether the
    sample shows it or not (a fixed number of draws)."""
    u = g.random((len(choices) - 1, 2))
    reflectance = np.full(len(choices), np.nan)
    retro = np.zeros(len(choices), bool)
    laws = np.tile(law_columns(None), (len(choices), 1))
    for label, (pick, level) in enumerate(u, start=1):
        options = choices[label]
        material = options[min(int(pick * len(options)), len(options) - 1)]
        low, high = material.reflectance_min, material.reflectance_max
        reflectance[label] = low + level * (high - low)
        retro[label] = material.kind == "retroreflective"
        laws[label] = law_columns(material)
    return reflectance, retro, laws


def law_columns(material: Material | None) -> np.ndarray:
    """A material's angle law as four numbers (None: Lambert): f(theta) = cos^n + r sin^2,
    r Oren-Nayar's B / A (0 but for ``oren_nayar``), n the retro exponent (1 but for
    ``retroreflective``), then the coat's rho_s and Ward lobe width (degrees)."""
    from simlidar.sensor.angle_laws import oren_nayar_ratio

    if material is None:
        return np.array([0.0, 1.0, 0.0, 0.0])
    ratio = oren_nayar_ratio(material.roughness_deg) if material.angle_law == "oren_nayar" else 0.0
    exponent = material.exponent if material.angle_law == "retroreflective" else 1.0
    return np.array([ratio, exponent, material.specular, material.lobe_deg])


def effective_reflectance(rho, cos_incidence, laws):
    """rho f(theta) + rho_s f_s(theta): what the range equation multiplies for each hit, from
    its reflectance, |cos(theta)| and law columns (``laws[..., 4]``, :func:`law_columns`)."""
    from simlidar.sensor.angle_laws import law_factor, specular_factor

    ratio, exponent, coat, lobe = (laws[..., k] for k in range(4))
    value = rho * law_factor(cos_incidence, ratio, exponent)
    glossy = coat > 0.0
    if np.any(glossy):
        lobe_s = specular_factor(cos_incidence, np.where(glossy, lobe, 1.0))
        value = value + np.where(glossy & (cos_incidence > 0.0), coat * lobe_s, 0.0)
    return value


@dataclass(frozen=True)
class Returns:
    """What the receiver makes of a block of hits (n samples, H x W pulses). With a beam
    footprint or a return mode other than the single ray's strongest (:func:`receive_beams`) the
    per-pixel fields describe the pulse's first reported return (the one that arrives first)."""

    range_m: np.ndarray  # (n, H, W) float64, quantised; NaN: no return (missed or dropped)
    intensity: np.ndarray  # (n, H, W) uint8, the sensor's reflectivity byte; 0: no return
    reflectance: np.ndarray  # (n, H, W) float32, the hit surface's drawn value; NaN: no hit
    # (n, H, W) float32, the measured peak power (noise included) of the reported return, or of
    # the hit (the strongest echo) where none is reported, at least 0; 0: no hit
    power_w: np.ndarray
    # receive_beams only, else None:
    surface: np.ndarray | None = None  # (n, H, W) uint8, the return's surface; 0: no return
    echoes: np.ndarray | None = None  # (n, H, W) uint8, echoes detected in the waveform
    # (n, H, W, R) the reported returns in the mode's order (dual: last, then strongest or
    # second strongest; the same return twice where one was detected); NaN / 0: none
    returns_range_m: np.ndarray | None = None
    returns_intensity: np.ndarray | None = None
    returns_surface: np.ndarray | None = None
    # (n, H, W, T) float32 watts, the waveform sampled every waveform_bin_ns (on request)
    waveform: np.ndarray | None = None


def _surface_tables(streams, choices):
    """Each sample's drawn reflectance (n, S), retro-reflectivity (n, S) and law columns (n, S,
    4) per surface label."""
    drawn = [draw_surfaces(g, choices) for g in streams]
    return tuple(np.stack([d[k] for d in drawn]) for k in range(3))


def _per_label(table: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """``table`` (n, S) read at each sample's ``labels`` (n, ...) (uint8 surface labels)."""
    flat = labels.reshape(len(table), -1).astype(np.int64)
    return np.take_along_axis(table, flat, axis=1).reshape(labels.shape)


def _hit_power(receiver, tables, range_m, surface, cos_incidence, alpha):
    """Per hit (any shape): whether there is one, the drawn reflectance (NaN: no hit), its
    retro-reflectivity, rho f(theta) (+ a coat's lobe; 0: no hit), the range it divides by
    (1 m where no hit) and the received power of the range equation with the biaxial overlap
    (0: no hit). ``tables``: :func:`_surface_tables`'."""
    table, retro_table, laws = tables
    hit = ~np.isnan(range_m)
    reflectance = np.where(hit, _per_label(table, surface), np.nan)
    retro = _per_label(retro_table, surface)
    flat = surface.reshape(len(laws), -1).astype(np.int64)
    law = np.take_along_axis(laws, flat[..., None], axis=1).reshape(surface.shape + (4,))
    rho = np.where(hit, effective_reflectance(np.nan_to_num(reflectance), cos_incidence, law), 0.0)
    safe_m = np.where(hit, range_m, 1.0)  # the equation divides by R^2
    power = received_power_w(receiver, safe_m, rho, 0.0, alpha) * overlap(receiver, safe_m)
    return hit, reflectance, retro, rho, safe_m, np.where(hit, power, 0.0)


def overlap(receiver: Receiver, range_m):
    """The biaxial overlap xi(R) of the receiver's geometry (1 where it has none)."""
    from simlidar.sensor.weather import crossover

    ranges = crossover_ranges(receiver)
    return np.ones(np.shape(range_m)) if ranges is None else crossover(range_m, ranges)


def receive_hits(
    config,
    physics: Physics,
    choices: list[list[Material]],
    streams: list[np.random.Generator],
    range_m: np.ndarray,
    surface: np.ndarray,
    cos_incidence: np.ndarray,
    weights: np.ndarray | None = None,
) -> Returns:
    """The returns of a block of hits under ``config`` (a GeneratorConfig with a receiver):
    through each pulse's waveform where ``config.full_waveform`` (:func:`receive_beams`; hits
    (n, H, W, S) of the sub-rays of ``weights``, or (n, H, W) for one ray a pulse), else by
    :func:`receive`; ``surface`` of the result is the returned surface (0: no return).

    physics, choices, streams : :func:`receive`'s: the profile's receiver and materials, each
        surface label's materials and each sample's receiver stream
    range_m, surface, cos_incidence : the hits, (n, H, W) as :func:`receive`'s, or per sub-ray
        (n, H, W, S) as :func:`receive_beams`'
    weights : (S,) the sub-rays' shares of the beam's power (None: one ray a pulse)
    """
    if config.full_waveform:
        if weights is None:  # one ray a pulse
            range_m, surface, cos_incidence = (
                a[..., None] for a in (range_m, surface, cos_incidence)
            )
            weights = np.ones(1)
        return receive_beams(
            physics, choices, config.sensor, streams, range_m, surface, cos_incidence,
            weights, config.return_mode, config.extinction_per_m, config.fog_visibility_m,
            config.rain_rate_mm_h, config.waveform_bin_ns, config.waveform_bins,
        )  # fmt: skip
    return receive(
        physics, choices, config.sensor, streams, range_m, surface, cos_incidence,
        config.extinction_per_m,
    )  # fmt: skip


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

    physics : the profile's receiver and materials (:func:`receiver_physics`)
    choices : per surface label, its materials (:func:`check_physics`)
    sensor : the sensor, whose range resolution quantises each return and out of whose range
        a return is none (:func:`simlidar.generator.pulses.quantise_range`)
    streams : (n,) each sample's receiver stream (:func:`receiver_stream`)
    range_m : (n, H, W) float64, unquantised range of each hit within the sensor's range; NaN
        where none
    surface : (n, H, W) uint8 labels; cos_incidence : (n, H, W) |cos| of the incidence angle
    extinction_per_m : the atmosphere's alpha (fog: ``GeneratorConfig.extinction_per_m``; 0:
        clear air), two-way Beer-Lambert in the range equation
    """
    receiver = physics.receiver
    tables = _surface_tables(streams, choices)
    hit, reflectance, retro, rho, safe_m, power = _hit_power(
        receiver, tables, range_m, surface, cos_incidence, extinction_per_m
    )
    shape = power.shape + (ECHOES_MEASURED,)
    padded = np.zeros(shape)
    padded[..., 0] = power  # one echo a pulse: the first of the draws measures it
    measured = measure_peaks(receiver, streams, padded, np.broadcast_to(rho[..., None], shape))
    measured = measured[..., 0]
    seen = hit & (measured >= receiver.threshold_w)
    alarm_m, alarm_w = false_alarm_echoes(receiver, streams, sensor, rho)
    z = np.stack([g.standard_normal(range_m.shape[1:]) for g in streams])  # (n, H, W)
    alarm = ~np.isnan(alarm_m) & (~seen | (alarm_w > measured))  # the strongest echo reported
    centre = np.where(alarm, alarm_m, np.where(seen, safe_m, np.nan))
    peak = np.where(alarm, alarm_w, np.where(seen, measured, 0.0))
    found = alarm | seen
    noise = signal_noise_w(receiver, peak, np.where(alarm, 0.0, rho))
    sigma = np.where(found, timing_noise_m(receiver, np.where(found, peak, 1.0), noise), 0.0)
    returned_m = quantise_range(np.where(found, centre + sigma * z, np.nan), sensor)
    returned = ~np.isnan(returned_m)
    intensity = np.where(
        returned, reflectivity(receiver, peak, np.nan_to_num(returned_m), retro & ~alarm), 0
    )
    return Returns(
        range_m=returned_m,
        intensity=intensity.astype(np.uint8),
        reflectance=reflectance.astype(np.float32),
        power_w=np.where(found, peak, np.where(hit, np.maximum(measured, 0.0), 0.0)).astype(
            np.float32
        ),
        surface=np.where(returned & ~alarm, surface, 0).astype(np.uint8),
    )


def receive_beams(
    physics: Physics,
    choices: list[list[Material]],
    sensor: Sensor,
    streams: list[np.random.Generator],
    range_m: np.ndarray,
    surface: np.ndarray,
    cos_incidence: np.ndarray,
    weights: np.ndarray,
    mode: str,
    extinction_per_m: float = 0.0,
    visibility_m: float = math.inf,
    rain_rate_mm_h: float = 0.0,
    waveform_bin_ns: float = 0.0,
    waveform_bins: int = 0,
) -> Returns:
    """The returns of a block of beams sampled by S sub-rays, in a return mode
    (docs/sensor-model.md, "Beam footprint and returns"):

    1. each sub-ray's received power is the range equation's for its hit, times its weight
       (:func:`simlidar.sensor.footprint.footprint`);
    2. the pulse's waveform is their sum of Gaussian pulses, its echoes the waveform's peaks
       (:func:`simlidar.sensor.waveform.echoes`), measured with the detector's noise and
       joined by the pulse's strongest false alarm (:func:`measured_echoes`), detected at the
       receiver's threshold;
    3. the mode picks the reported returns among them (:func:`simlidar.sensor.waveform.reported`);
       each reported return moves by the timing jitter of its own measured peak (one standard
       normal per pixel and reported return, a second block in ``dual`` mode; a return
       reported twice is one measurement) and is quantised;
    4. a return's surface and reflectance are those of the sub-ray that adds most to its peak
       (surface 0 where the surfaces make less than half of it: the weather's or the noise's
       echo); its intensity is its measured peak's, range-compensated.

    physics, choices, sensor, streams : :func:`receive`'s
    range_m, surface, cos_incidence : (n, H, W, S) as :func:`receive`'s, per sub-ray
    weights : (S,) the sub-rays' shares of the beam's power
    mode : of the receiver's ``return_modes``
    extinction_per_m : :func:`receive`'s: the atmosphere's alpha (fog, rain; 0: clear air)
    visibility_m : a fog's visibility: the fog's backscatter (Mie's, :func:`fog_backscatter`)
        joins the waveform (:mod:`simlidar.sensor.weather`), and an echo the fog makes is a
        return of surface 0, NaN reflectance and the reflectivity byte of its signal
    rain_rate_mm_h : a rain's rate (its extinction is in ``extinction_per_m``): the echoes of
        its drops (:class:`simlidar.sensor.weather.Rain`) join the waveform, drawn from each
        sample's stream after the draws above; an echo the drops make is a return of surface
        0, as the fog's
    waveform_bin_ns, waveform_bins : where ``waveform_bins`` > 0, each pulse's waveform (every
        echo above, the weather's too) sampled at k ``waveform_bin_ns``, k < ``waveform_bins``
        (:func:`simlidar.sensor.waveform.sampled`)
    """
    receiver = physics.receiver
    n, rows, cols, subrays = range_m.shape
    tables = _surface_tables(streams, choices)
    reports = 2 if mode == "dual" else 1
    hit, reflectance, retro, rho, safe_m, power = _hit_power(
        receiver, tables, range_m, surface, cos_incidence, extinction_per_m
    )
    power = (power * weights).reshape(-1, subrays)
    times = np.where(hit, tof_ns(safe_m), np.nan).reshape(-1, subrays)
    sigma_ns = pulse_sigma_ns(receiver.pulse_width_ns)
    geometry = crossover_ranges(receiver) or CROSSOVER_M
    fog = None
    if math.isfinite(visibility_m):
        fog = fog_table(
            receiver.peak_power_w, receiver.aperture_area_m2, receiver.optics_efficiency,
            receiver.threshold_w, visibility_m, extinction_per_m, sigma_ns, BIN_NS,
            sensor.max_range_m, fog_backscatter(visibility_m, receiver.wavelength_nm), geometry,
        )  # fmt: skip
    axis_m = range_m.reshape(-1, subrays)[:, 0]  # NaN: no hit
    drops = rain(
        receiver.peak_power_w, receiver.aperture_area_m2, receiver.optics_efficiency,
        receiver.threshold_w, receiver.divergence_h_mrad, receiver.divergence_v_mrad,
        rain_rate_mm_h, geometry,
    )  # fmt: skip
    all_times, all_power, drop_ns, drop_w = times, power, None, None
    if drops is not None:
        drop_ns, drop_w = _drop_echoes(drops, streams, rows * cols, axis_m, extinction_per_m)
        all_times, all_power = np.hstack([times, drop_ns]), np.hstack([power, drop_w])
    columns = None if fog is None else fog.column(axis_m)
    if fog is None and drops is None:
        echo = echoes(times, power, sigma_ns)
    else:
        echo = echoes(times, power, sigma_ns, BIN_NS, fog, columns, drop_ns, drop_w)
    stored = None
    if waveform_bins:
        stored = sampled(
            all_times, all_power, sigma_ns, waveform_bin_ns, waveform_bins, fog, columns
        ).reshape(n, rows, cols, waveform_bins)
    pixel_rho = rho.reshape(-1, subrays)[:, 0]  # the background's scene: the axis's hit
    echo = measured_echoes(receiver, streams, sensor, echo, pixel_rho, (rows, cols))
    z = np.stack([g.standard_normal((reports, rows, cols)) for g in streams])  # (n, R, H, W)
    z = np.moveaxis(z, 1, -1)  # (n, H, W, R)
    if waveform_bins and receiver.noise_w > 0.0:  # the stored waveform's noise, bin by bin
        sigma_bins = signal_noise_w(
            receiver, np.maximum(stored, 0.0), pixel_rho.reshape(n, rows, cols)[..., None]
        )
        bins_z = np.stack([g.standard_normal(stored.shape[1:]) for g in streams])
        stored = (stored + sigma_bins * bins_z).astype(np.float32)
    pick = reported(echo, receiver.threshold_w, mode, receiver.dual_when_strongest_is_last)
    pulses = np.arange(len(pick))[:, None]
    found = pick >= 0
    at = np.where(found, pick, 0)
    if echo.time_ns.shape[1] == 0:  # not one echo in the block
        peak_ns = np.full(pick.shape, np.nan)
        peak_w = np.zeros(pick.shape)
    else:
        peak_ns = np.where(found, echo.time_ns[pulses, at], np.nan)
        peak_w = np.where(found, echo.power_w[pulses, at], 0.0)
    # the sub-ray that adds most to each reported peak
    share = power[:, None, :] * np.exp(
        -((peak_ns[:, :, None] - np.nan_to_num(times, nan=np.inf)[:, None, :]) ** 2)
        / (2.0 * sigma_ns**2)
    )
    main = np.argmax(np.nan_to_num(share, nan=-1.0), axis=2)  # (P, R)
    flat = (n * rows * cols, subrays)
    main_rho = np.take_along_axis(reflectance.reshape(flat), main, axis=1)  # as drawn
    main_retro = np.take_along_axis(retro.reshape(flat), main, axis=1)
    main_surface = np.take_along_axis(surface.reshape(flat), main, axis=1)
    # an echo the surfaces make less than half of is the weather's or the noise's (fog,
    # drops, false alarms)
    fogged = found & (np.nan_to_num(share, nan=0.0).sum(axis=2) < 0.5 * peak_w)
    main_retro = np.where(fogged, False, main_retro)
    main_surface = np.where(fogged, 0, main_surface)
    same = (pick[:, -1] == pick[:, 0])[:, None]  # dual: one return reported twice
    noise = z.reshape(-1, reports)
    noise = np.where(same, noise[:, :1], noise)
    back = np.where(fogged, 0.0, pixel_rho[:, None])
    sigma_w = signal_noise_w(receiver, np.where(found, peak_w, 0.0), back)
    sigma_m = np.where(found, timing_noise_m(receiver, np.where(found, peak_w, 1.0), sigma_w), 0.0)
    centre_m = peak_ns * 1e-9 * SPEED_OF_LIGHT_M_PER_S / 2.0
    returned_m = quantise_range(np.where(found, centre_m + sigma_m * noise, np.nan), sensor)
    returned = ~np.isnan(returned_m)
    intensity = np.where(
        returned, reflectivity(receiver, peak_w, np.nan_to_num(returned_m), main_retro), 0
    )
    labels = np.where(returned, main_surface, 0)
    first = np.argmin(np.where(returned, returned_m, np.inf), axis=1)[:, None]
    primary = {
        "range_m": np.take_along_axis(returned_m, first, axis=1)[:, 0],
        "intensity": np.take_along_axis(intensity, first, axis=1)[:, 0],
        "surface": np.take_along_axis(labels, first, axis=1)[:, 0],
        "power_w": np.take_along_axis(peak_w, first, axis=1)[:, 0],
        "reflectance": np.take_along_axis(
            np.where(found & ~fogged, main_rho, np.nan), first, axis=1
        )[:, 0],
    }
    # no return: the power of the pulse's strongest echo (0: no hit), the central ray's surface
    silent = ~returned.any(axis=1)
    peaks_w = np.where(np.isnan(echo.power_w), 0.0, echo.power_w)
    strongest_w = peaks_w.max(axis=1, initial=0.0)
    primary["power_w"] = np.where(silent, strongest_w, primary["power_w"])
    central = reflectance.reshape(flat)[:, 0]
    primary["reflectance"] = np.where(silent, central, primary["reflectance"])
    detected_echoes = (echo.power_w >= receiver.threshold_w).sum(axis=1)
    shape = (n, rows, cols)
    return Returns(
        range_m=primary["range_m"].reshape(shape),
        intensity=primary["intensity"].reshape(shape).astype(np.uint8),
        reflectance=primary["reflectance"].reshape(shape).astype(np.float32),
        power_w=primary["power_w"].reshape(shape).astype(np.float32),
        surface=primary["surface"].reshape(shape).astype(np.uint8),
        echoes=np.minimum(detected_echoes, 255).reshape(shape).astype(np.uint8),
        returns_range_m=returned_m.reshape(shape + (reports,)),
        returns_intensity=intensity.reshape(shape + (reports,)).astype(np.uint8),
        returns_surface=labels.reshape(shape + (reports,)).astype(np.uint8),
        waveform=stored,
    )


def _drop_echoes(drops: Rain, streams, pixels: int, axis_m: np.ndarray, extinction_per_m: float):
    """The echoes of the drops in front of each pulse's hard hit (beyond the crossover's r_1):
    times (ns) and powers (W), (P, D) NaN / 0 padded, P = samples x ``pixels`` pulses (``axis_m``
    (P,): the beam axis's hit, NaN: none, so the drops reach as far as they can be seen)."""
    pulse, range_m, diameter = [], [], []
    for i, g in enumerate(streams):
        p, r, d = drops.draw(g, pixels)
        pulse.append(p + i * pixels), range_m.append(r), diameter.append(d)
    pulse, range_m, diameter = (np.concatenate(a) for a in (pulse, range_m, diameter))
    blocked = np.nan_to_num(axis_m[pulse], nan=np.inf)
    seen = (range_m > drops.nearest_m) & (range_m < blocked)
    pulse, range_m, diameter = pulse[seen], range_m[seen], diameter[seen]
    (times, power), _ = by_row(
        pulse,
        len(axis_m),
        (tof_ns(range_m), np.nan),
        (drops.echo_w(range_m, diameter, extinction_per_m), 0.0),
    )
    return times, power
