"""One batch through the whole pipeline: classes, visibility and batch-size independence."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simlidar.errors import ConfigError, SimlidarError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.simulate import class_plan, simulate


@pytest.fixture(scope="module")
def batch(catalog):
    return simulate(GeneratorConfig(), catalog, "train", 0, 256)


def test_every_class_is_produced_and_balanced(batch):
    assert np.bincount(batch.labels, minlength=32).tolist() == [8] * 32
    assert (batch.layout == batch.labels // 4).all() and (batch.object == batch.labels % 4).all()


def test_every_labelled_object_is_visible(batch, catalog):
    k = GeneratorConfig().min_object_hits
    has_object = batch.object > 0
    assert (batch.object_hits[has_object] >= k).all()
    assert (batch.object_hits[~has_object] == 0).all()
    # the stored count is the number of pulses that show the object's surface
    names = np.array(catalog.surfaces)[batch.surface]
    expected = np.array(catalog.object_names)[batch.object]
    shown = (names == expected[:, None, None]).sum(axis=(1, 2))
    assert (shown[has_object] == batch.object_hits[has_object]).all()


def test_layouts_show_their_defining_surfaces(batch, catalog):
    from simlidar.sensor import column_centres_deg

    left = column_centres_deg(16, GeneratorConfig().fov_deg) < 0
    checked = 0
    for lid, recipe in enumerate(catalog.layouts):
        rows = batch.layout == lid
        for surface, min_hits, side in recipe.visible:
            seen = batch.surface[rows] == surface
            if side != "any":
                seen = seen[..., left if side == "left" else ~left]
            assert (seen.sum(axis=(1, 2)) >= min_hits).all(), (recipe.name, side)
            checked += 1
    assert checked >= 9  # both lamp rows and both walls count separately


@pytest.mark.parametrize(
    "name, median, share", [("car", 4, 0.95), ("truck", 4, 0.95), ("pedestrian", 2, 0.5)]
)
def test_objects_cover_several_columns(batch, catalog, name, median, share):
    # the window is wide enough for the layouts and narrow enough that objects span columns
    columns = (batch.surface == catalog.surfaces.index(name)).any(axis=1).sum(axis=1)
    mine = columns[batch.object == catalog.object_names.index(name)]
    assert np.median(mine) >= median and np.mean(mine >= 2) >= share


def test_delays_tof_and_surfaces_agree(batch):
    returned = ~np.isnan(batch.tof_ns)
    assert ((batch.surface > 0) == returned).all()
    np.testing.assert_allclose(
        batch.clean_delays[returned], batch.tof_ns[returned] / 667.128190396, rtol=1e-5
    )
    assert (batch.clean_delays[~returned] == 1.0).all()


@settings(max_examples=6, deadline=None)
@given(start=st.integers(0, 40), sizes=st.lists(st.integers(1, 9), min_size=1, max_size=4))
def test_a_sample_does_not_depend_on_the_batch_it_is_made_in(catalog, start, sizes):
    config = GeneratorConfig(classes=8, width=12)
    stop = start + sum(sizes)
    whole = simulate(config, catalog, "test", start, stop)
    offset = start
    for size in sizes:
        part = simulate(config, catalog, "test", offset, offset + size)
        for field in dataclasses.fields(part):
            a, b = getattr(part, field.name), getattr(whole, field.name)
            # a receiver's field (tests/generator/test_sensor_profile.py: batch sizes)
            if a is None:
                assert b is None, field.name
                continue
            b = b[offset - start : offset - start + size]
            np.testing.assert_array_equal(a, b, err_msg=field.name)
        offset += size


def test_the_embree_cell_follows_the_sample_index(catalog):
    from simlidar.generator.simulate import batched_backend

    seen = []

    def spy(*args):
        seen.append(args[7].copy())  # slots
        return batched_backend(*args)

    simulate(GeneratorConfig(classes=4), catalog, "train", 4093, 4100, backend=spy)
    assert seen[0].tolist() == [4093, 4094, 4095, 0, 1, 2, 3]  # index mod 4096


def test_splits_and_seeds_draw_different_scenes(catalog):
    a = simulate(GeneratorConfig(), catalog, "train", 0, 32)
    b = simulate(GeneratorConfig(), catalog, "test", 0, 32)
    c = simulate(GeneratorConfig(seed=1), catalog, "train", 0, 32)
    assert not np.array_equal(a.clean_delays, b.clean_delays)
    assert not np.array_equal(a.clean_delays, c.clean_delays)


@pytest.mark.parametrize("classes, mode", [(8, "layout"), (4, "object")])
def test_fewer_classes_label_one_factor(catalog, classes, mode):
    plan = class_plan(catalog, classes)
    assert plan.mode == mode and len(plan.names) == classes
    s = simulate(GeneratorConfig(classes=classes), catalog, "train", 0, 64)
    factor = s.layout if mode == "layout" else s.object
    other = s.object if mode == "layout" else s.layout
    assert (factor == s.labels).all()
    assert len(np.unique(other)) > 1  # the other factor varies


def test_an_unknown_class_count_is_refused(catalog):
    with pytest.raises(ConfigError, match=r"classes=5: expected one of \[4, 8, 32\]"):
        class_plan(catalog, 5)


def test_a_catalog_with_more_layouts_has_more_classes(catalog_copy):
    from simlidar.scene.recipe import load_catalog

    source = (catalog_copy / "layouts" / "open_road.toml").read_text()
    (catalog_copy / "layouts" / "country_road.toml").write_text(source)
    index = catalog_copy / "catalog.toml"
    index.write_text(
        index.read_text().replace('"lamps_one_side"]', '"lamps_one_side",\n"country_road"]')
    )
    catalog = load_catalog(catalog_copy)
    assert class_plan(catalog, 36).names[-1] == "country_road/truck"
    assert class_plan(catalog, 9).mode == "layout"
    s = simulate(GeneratorConfig(classes=36), catalog, "train", 0, 36)
    assert sorted(s.labels) == list(range(36))


def test_an_ambiguous_class_count_is_refused(catalog_copy):
    from simlidar.scene.recipe import load_catalog

    index = catalog_copy / "catalog.toml"
    text = index.read_text()
    start = text.index("layouts = [")
    index.write_text(
        text[:start] + 'layouts = ["tunnel", "open_road", "lower_bridge", '
        '"upper_bridge"]\nobjects = ["car", "pedestrian", "truck"]\n'
    )
    with pytest.raises(ConfigError, match="classes=4 is ambiguous"):
        class_plan(load_catalog(catalog_copy), 4)


def test_an_invisible_object_is_reported_not_looped_on(catalog_copy):
    from simlidar.scene.recipe import load_catalog

    path = catalog_copy / "objects" / "pedestrian.toml"
    path.write_text(
        path.read_text().replace("distance_m = [3.0, 10.0]", "distance_m = [-10.0, -3.0]")
    )  # behind the sensor
    catalog = load_catalog(catalog_copy)
    config = GeneratorConfig(max_attempts=3)
    with pytest.raises(SimlidarError, match=r"pedestrian\): no draw in 3"):
        simulate(config, catalog, "train", 0, 8)


def test_too_few_columns_is_named_as_the_cause(catalog):
    config = GeneratorConfig(width=2, train_size=32, test_size=32, max_attempts=5)
    with pytest.raises(SimlidarError, match=r"with width 2 \(18 deg between columns\)"):
        simulate(config, catalog, "train", 0, 8)
