"""Receiver files (sensors/receivers/*.toml), scenes/materials.toml and the receiver's pure
functions (simlidar/sensor/receiver.py), checked against numbers derived by hand."""

import math
import re

import numpy as np
import pytest

from simlidar.content import content_dir
from simlidar.errors import ConfigError
from simlidar.sensor.receiver import (
    detected,
    koschmieder_extinction_per_m,
    load_materials,
    load_receiver,
    max_range_m,
    range_noise_m,
    received_power_w,
    receiver_names,
)

KEY_LINE = re.compile(r"^\s*[A-Za-z_][A-Za-z0-9_]*\s*=")


def shipped_files():
    return sorted(content_dir("sensors/receivers").glob("*.toml")) + [
        content_dir("scenes") / "materials.toml"
    ]


def test_the_shipped_receivers_and_materials_load():
    assert receiver_names() == ["hdl64e", "vlp16"]
    for name in receiver_names():
        receiver = load_receiver(name)
        assert receiver.name == name
        assert "dual" in receiver.return_modes
    materials, surfaces = load_materials()
    catalog = (content_dir("scenes") / "catalog.toml").read_text()
    for surface in surfaces:
        assert f'"{surface}"' in catalog  # every mapped surface is one of the catalog's
    assert materials["retroreflector"].kind == "retroreflective"
    assert materials["retroreflector"].reflectance > 1.0  # a gain, not a fraction


@pytest.mark.parametrize("path", shipped_files(), ids=lambda p: p.name)
def test_every_value_carries_its_source(path):
    """A line that sets a key must say where the value comes from in a comment of at least a
    few words (a source, or "calibrated:", "assumption:", "unsourced estimate:", "choice:")."""
    bare = [
        line
        for line in path.read_text().splitlines()
        if KEY_LINE.match(line) and len(line.partition("#")[2].strip()) < 10
    ]
    assert bare == []


@pytest.mark.parametrize("name", ["vlp16", "hdl64e"])
def test_the_rated_range_holds_for_the_rated_reflectance(name):
    """The threshold in the file is calibrated so that the range equation gives the manual's
    rated range for its rated reflectance; by hand for the VLP-16: P_th = 80 W * 0.8 *
    3.1416e-4 m^2 * 0.05 / (pi * 100^2 m^2) = 3.2e-8 W, so R_max = 100 m."""
    receiver = load_receiver(name)
    found = max_range_m(receiver, receiver.rated_reflectance)
    assert found == pytest.approx(receiver.rated_range_m, rel=0.05)
    assert load_receiver("vlp16").threshold_w == pytest.approx(3.2e-8, rel=1e-4)


def test_max_range_scales_as_the_square_root_of_reflectance():
    """No atmosphere, extended target: P_r ~ rho / R^2, so R_max ~ sqrt(rho); a 10 % target
    against the VLP-16's rated 80 %: 100 m * sqrt(0.1 / 0.8) = 35.36 m."""
    receiver = load_receiver("vlp16")
    ranges = max_range_m(receiver, np.array([0.8, 0.1]))
    assert ranges[1] / ranges[0] == pytest.approx(math.sqrt(0.1 / 0.8), rel=1e-6)
    assert ranges[1] == pytest.approx(35.355, abs=0.01)


def test_power_falls_as_range_squared_and_with_the_cosine():
    """Twice as far: a quarter of the power; at 60 degrees incidence: half (cos 60 = 0.5); at
    90 degrees or beyond: none. VLP-16, rho = 0.8 at 10 m: 80 * 0.8 * 3.1416e-4 * 0.05 /
    (pi * 100) = 3.2e-6 W."""
    receiver = load_receiver("vlp16")
    near, far = received_power_w(receiver, np.array([10.0, 20.0]), 0.8)
    assert near == pytest.approx(3.2e-6, rel=1e-4)
    assert far / near == pytest.approx(0.25)
    tilted = received_power_w(receiver, 10.0, 0.8, incidence_rad=math.radians(60.0))
    assert tilted / near == pytest.approx(0.5)
    assert received_power_w(receiver, 10.0, 0.8, incidence_rad=math.pi) == 0.0
    assert detected(
        receiver, [near, receiver.threshold_w, 0.99 * receiver.threshold_w]
    ).tolist() == [
        True,
        True,
        False,
    ]


def test_two_way_extinction_from_visibility():
    """Koschmieder: alpha = -ln(0.05) / V = 2.9957 / V; at V = 100 m, alpha = 0.029957 /m, and a
    target at R = 50 m keeps exp(-2 * 0.029957 * 50) = exp(-2.9957) = 0.05 of its power (the
    two-way path of 100 m is exactly the visibility: the 5 % contrast)."""
    alpha = koschmieder_extinction_per_m(100.0)
    assert alpha == pytest.approx(0.029957, rel=1e-4)
    receiver = load_receiver("vlp16")
    clear = received_power_w(receiver, 50.0, 0.5)
    foggy = received_power_w(receiver, 50.0, 0.5, extinction_per_m=alpha)
    assert foggy / clear == pytest.approx(0.05, rel=1e-9)
    # with the loss the rated target is no longer seen at 100 m: R^2 exp(2 alpha R) = 100^2
    assert max_range_m(receiver, 0.8, extinction_per_m=alpha) < 50.0
    with pytest.raises(ConfigError, match="visibility_m"):
        koschmieder_extinction_per_m([100.0, 0.0])


def test_range_noise_grows_as_the_signal_falls():
    """sigma = accuracy * sqrt(P_th / P): 3 cm at the threshold, 1.5 cm at four times its
    power, 6 cm at a quarter of it (VLP-16), and no range at all without a signal."""
    receiver = load_receiver("vlp16")
    powers = receiver.threshold_w * np.array([1.0, 4.0, 0.25, 0.0])
    assert range_noise_m(receiver, powers).tolist() == pytest.approx([0.03, 0.015, 0.06, math.inf])


VLP16 = (content_dir("sensors/receivers") / "vlp16.toml").read_text()


@pytest.mark.parametrize(
    "old,new,match",
    [
        ("accuracy_m = 0.03 ", "", "key 'accuracy_m' is missing"),
        ("peak_power_w = 80.0", "peak_power_w = -80.0", "key 'peak_power_w': expected a positive"),
        (
            "divergence_h_mrad = 3.0",
            "divergence_h_rad = 0.003",
            "key 'divergence_h_rad': expected one of",
        ),
        (
            "wavelength_nm = 903.0",
            "wavelength_nm = 0.903",
            "key 'wavelength_nm': expected 200 to 2000",
        ),
        ("rated_reflectance = 0.8", "rated_reflectance = 80", "key 'rated_reflectance'"),
        ('"strongest", "last", "dual"', '"strongest", "first"', "key 'return_modes'"),
        ("threshold_w = 3.2e-8", 'threshold_w = "3.2e-8"', "key 'threshold_w': expected a finite"),
    ],
)
def test_a_bad_receiver_file_is_a_one_line_error_naming_the_key(tmp_path, old, new, match):
    path = tmp_path / "vlp16.toml"
    assert old in VLP16
    path.write_text(VLP16.replace(old, new))
    with pytest.raises(ConfigError, match=match) as caught:
        load_receiver(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_an_unknown_receiver_name_lists_the_shipped_ones():
    with pytest.raises(ConfigError, match=r"expected one of \['hdl64e', 'vlp16'\]"):
        load_receiver("vlp99")


MATERIALS = (content_dir("scenes") / "materials.toml").read_text()


@pytest.mark.parametrize(
    "old,new,match",
    [
        ("reflectance = 0.10 ", "reflectance = 10.0 ", "material.asphalt.reflectance"),
        ("reflectance = 0.30 ", "reflectance = -0.3 ", "material.concrete.reflectance"),
        ('kind = "specular"', 'kind = "mirror"', "material.glass.kind"),
        ("reflectance_range = [0.20, 0.45]", "reflectance_range = 0.2", "reflectance_range"),
        ('pedestrian = ["clothing"]', 'pedestrian = ["cloth"]', "surfaces.pedestrian"),
        ("reflectance = 0.59 ", "reflectivity = 0.59 ", "material.galvanised_metal.reflectivity"),
    ],
)
def test_a_bad_materials_file_is_a_one_line_error_naming_the_key(tmp_path, old, new, match):
    path = tmp_path / "materials.toml"
    assert old in MATERIALS
    path.write_text(MATERIALS.replace(old, new, 1))
    with pytest.raises(ConfigError, match=re.escape(match)) as caught:
        load_materials(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)
