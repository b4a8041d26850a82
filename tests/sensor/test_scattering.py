"""Fog and rain from Mie theory over drop-size distributions (issue 62, item 5): the committed
tables against the series, the distributions by hand, the coefficients against Koschmieder,
the large-drop limit and the fog's lidar ratio."""

import json
import math

import numpy as np
import pytest

from simlidar.errors import ConfigError
from simlidar.sensor import scattering
from simlidar.sensor.scattering import (
    FogDistribution,
    cell_means,
    checked_table,
    fog_optics,
    load_atmosphere,
    load_table,
    rain_optics,
    table_path,
)
from simlidar.sensor.weather import rain_extinction_per_m

SAMPLES = 128  # benchmark/mie_tables.py's


@pytest.mark.parametrize("band", ["visible", "nir"])
def test_committed_table_cells_are_the_series_means(band):
    """Cells of small and medium size parameters computed again (the same draws) equal the
    committed file's within 1e-9: the file is what benchmark/mie_tables.py makes."""
    table = load_table(band)
    cells = [0, 40, 80, 120]  # x = 0.1 .. about 100
    assert load_atmosphere().index[band] == table.index
    q_ext, q_back, error = cell_means(table.index, table.edges, SAMPLES, only=cells)
    np.testing.assert_allclose(q_ext[cells], table.q_ext[cells], rtol=1e-9)
    np.testing.assert_allclose(q_back[cells], table.q_back[cells], rtol=1e-9)
    np.testing.assert_allclose(error[cells], table.q_back_error[cells], rtol=1e-9)


def test_a_hostile_table_is_refused_in_one_line():
    good = json.loads(table_path("nir").read_text())
    for key, value, expected in [
        ("q_ext", good["q_ext"][:-1], "one a cell"),
        ("q_back", [float("nan")] * len(good["q_back"]), "non-negative numbers"),
        ("edges", good["edges"][::-1], "increasing"),
        ("index", "1.33", "[n, k]"),
        ("band", "uv", "'visible' or 'nir'"),
    ]:
        with pytest.raises(ConfigError, match=expected) as err:
            checked_table("t.json", good | {key: value})
        assert "\n" not in str(err.value) and key in str(err.value)


def test_fog_distributions_by_hand():
    """Modified gamma: N = a Gamma((alpha + 1) / gamma) / (gamma b^((alpha + 1) / gamma)), the
    mode (alpha / (b gamma))^(1 / gamma); the advection fog's 20 drops a cm^3 at 10 um."""
    fog = FogDistribution("f", a=0.027, alpha=3.0, b=0.3, gamma=1.0)
    assert fog.number_per_cm3 == pytest.approx(0.027 * 6 / 0.3**4)
    assert fog.mode_radius_um == pytest.approx(10.0)
    r = np.linspace(0.01, 200.0, 200_001)
    assert np.sum(fog.density(r)) * (r[1] - r[0]) == pytest.approx(fog.number_per_cm3, rel=1e-4)


@pytest.mark.parametrize("name", ["advection", "moderate_advection", "chu_hogg"])
def test_fog_visibility_sets_its_extinction_and_backscatter_scales_with_it(name):
    """At 550 nm a fog's extinction is ln(20) / V by construction; at 903 nm the drops (far
    larger than the wavelength) take within 5 % of it; alpha and beta scale as 1 / V, and the
    lidar ratio alpha / beta is that of cloud and fog drops (about 18 sr: a water cloud's
    lidar ratio of 18.5 sr is the figure issue 62 quotes for a Mie computation of fog)."""
    fog = load_atmosphere().fogs[name]
    visible = fog_optics(fog, 50.0, 550.0)
    assert visible.extinction_per_m == pytest.approx(math.log(20) / 50.0, rel=1e-12)
    near = fog_optics(fog, 50.0, 903.0)
    assert near.extinction_per_m == pytest.approx(math.log(20) / 50.0, rel=0.05)
    far = fog_optics(fog, 200.0, 903.0)
    assert far.backscatter_per_m_sr == pytest.approx(near.backscatter_per_m_sr / 4, rel=1e-12)
    assert 15.0 < near.lidar_ratio_sr < 22.0
    assert near.backscatter_error < 0.05 * near.backscatter_per_m_sr


def test_rain_extinction_is_the_large_drop_limit():
    """Marshall-Palmer drops are far larger than 903 nm: Mie's extinction is within 2 % of
    Q_ext = 2's closed form (pi / 2) 1e-6 Q N0 / Lambda^3 at every rate."""
    atmosphere = load_atmosphere()
    for rate in (1.0, 10.0, 50.0, 200.0):
        got = rain_optics(atmosphere, rate, 903.0).extinction_per_m
        assert got == pytest.approx(rain_extinction_per_m(rate), rel=0.02)
    with pytest.raises(ConfigError, match="expected a positive rain rate"):
        rain_optics(atmosphere, 0.0, 903.0)


def test_wavelengths_outside_the_tables_are_refused():
    with pytest.raises(ConfigError, match="expected 850 to 950 nm"):
        scattering.band_of(1550.0)
