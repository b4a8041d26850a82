"""A catalog's motion.toml (issue 59): read and checked as a recipe is, never part of the
stored catalog."""

import pytest

from simlidar.errors import RecipeError
from simlidar.scene.recipe import load_catalog


def test_the_shipped_motion_and_the_catalog_fingerprint(catalog):
    assert sorted(catalog.motion) == ["car", "pedestrian", "truck"]
    walk = catalog.motion["pedestrian"]
    assert walk.speed_mps.values == (1.0, 1.6) and walk.yaw_rate_deg_s.values == (0.0,)
    assert "motion" not in catalog.to_dict()  # the recipes' fingerprint stays what it was


def test_without_a_motion_file_objects_stand_still(catalog_copy):
    before = load_catalog(catalog_copy).fingerprint()
    (catalog_copy / "motion.toml").unlink()
    catalog = load_catalog(catalog_copy)
    assert catalog.motion == {} and catalog.fingerprint() == before


@pytest.mark.parametrize(
    "text, expected",
    [
        ("[bicycle]\nspeed_mps = 3.0\n", "key 'bicycle': expected one of the catalog's objects"),
        ("[car]\nheading_deg = 0.0\n", "key 'speed_mps' is missing"),
        ("[car]\nspeed_mps = 3.0\nwheels = 4\n", "key 'wheels': expected one of"),
        ("[car]\nspeed_mps = [-1.0, 3.0]\n", "key 'car.speed_mps': expected values in [0, 70]"),
        ("[car]\nspeed_mps = 3.0\nyaw_rate_deg_s = 1e9\n", "expected values in [-180, 180]"),
        ("[car]\nspeed_mps = nan\n", "key 'car.speed_mps': expected a number"),
        ("car = 3\n", "key 'car': expected a table of"),
    ],
)
def test_a_bad_motion_table_is_one_line(catalog_copy, text, expected):
    (catalog_copy / "motion.toml").write_text(text)
    with pytest.raises(RecipeError) as caught:
        load_catalog(catalog_copy)
    assert expected in str(caught.value) and "\n" not in str(caught.value)
    assert "motion.toml" in str(caught.value)
