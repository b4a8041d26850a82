"""The scene catalog: what ships, and every way a recipe can be wrong.

Attack list of ``test_catalog_names_are_plain_names`` (issue 35, item 8): a layout, object or
surface name that is a path (``../../x/layouts/open_road``, which read a recipe outside the
catalog and gave two classes named ``open_road``), has a folder part, starts with a dot, is
empty, holds a space or a NUL, or is longer than 64 characters: refused when the catalog is
loaded (and by ``simlidar generate --scenes``), one line naming the key and the name.
"""

from dataclasses import replace

import numpy as np
import pytest

from simlidar.errors import RecipeError
from simlidar.scene import expr
from simlidar.scene.parse import Param
from simlidar.scene.recipe import load_catalog

PAPER_LAYOUTS = [
    "tunnel",
    "open_road",
    "lower_bridge",
    "upper_bridge",
    "two_side_walls",
    "one_side_wall",
    "lamps_both_sides",
    "lamps_one_side",
]


def test_the_shipped_catalog_has_the_papers_classes(catalog):
    assert catalog.layout_names == PAPER_LAYOUTS
    assert catalog.object_names == ["none", "car", "pedestrian", "truck"]
    assert catalog.surfaces[0] == "none"
    assert {"road", "wall", "ceiling", "bridge", "lamp", "car", "pedestrian", "truck"} <= set(
        catalog.surfaces
    )


def test_the_fingerprint_does_not_depend_on_the_folder(catalog, catalog_copy):
    assert load_catalog(catalog_copy).fingerprint() == catalog.fingerprint()


def test_a_new_layout_needs_no_code(catalog_copy):
    (catalog_copy / "layouts" / "gantry.toml").write_text(
        'description = "A sign gantry over an open road."\n'
        "[params]\nat_m = [20.0, 40.0]\n"
        '[[primitive]]\nkind = "box"\nsurface = "road"\nat = [65, 0, -0.3]\n'
        "size = [150, 10, 0.3]\n"
        '[[primitive]]\nkind = "box"\nsurface = "bridge"\nat = ["at_m", 0, 5.5]\n'
        "size = [1.0, 14, 1.5]\n"
    )
    index = catalog_copy / "catalog.toml"
    index.write_text(index.read_text().replace('"lamps_one_side"]', '"lamps_one_side", "gantry"]'))
    assert load_catalog(catalog_copy).layout_names[-1] == "gantry"


def _edit(root, name, old, new):
    path = root / name
    text = path.read_text()
    assert old in text, f"test setup: {old!r} not in {name}"
    path.write_text(text.replace(old, new, 1))
    return path


# one broken recipe a row: the cases are data, alike in form
@pytest.mark.parametrize(
    "name, old, new, key",
    [
        ("layouts/tunnel.toml", 'kind = "arch"', 'kind = "dome"', "kind"),
        (
            "layouts/tunnel.toml",
            'surface = "ceiling"\nsegments',
            'surface = "sky"\nsegments',
            "surface",
        ),
        ("layouts/tunnel.toml", "rise_m = [1.5, 3.0]", "rise_m = [3.0, 1.5]", "params.rise_m"),
        ("layouts/tunnel.toml", "rise_m = [1.5, 3.0]", 'rise_m = "tall"', "params.rise_m"),
        ("layouts/tunnel.toml", '"wall_height_m + 0.3"]', '"wall_hieght_m + 0.3"]', "size[2]"),
        ("layouts/tunnel.toml", "at = [65.0, 0.0, -0.3]", "at = [65.0, 0.0]", "at"),
        ("layouts/tunnel.toml", "at = [65.0, 0.0, -0.3]", 'at = ["__import__(1)", 0, 0]', "at[0]"),
        ("layouts/tunnel.toml", "segments = 8", "segments = 2", "segments"),
        ("layouts/tunnel.toml", "repeat = 2", 'repeat = "half_width_m"', "repeat"),
        ("layouts/tunnel.toml", "repeat = 2", "repeat = true", "repeat"),
        ("layouts/tunnel.toml", 'surface = "road"', 'surface = "road"\nsegments = 4', "segments"),
        ("layouts/tunnel.toml", '"wall_height_m + 0.3"]', '"min(1, 2, 3)"]', "size[2]"),
        ("layouts/tunnel.toml", '"wall_height_m + 0.3"]', '"True"]', "size[2]"),
        ("layouts/tunnel.toml", 'kind = "arch"', 'kind = "arch"\ncolour = "red"', "colour"),
        ("layouts/tunnel.toml", "min_hits = 3", "min_hits = 0", "visible.min_hits"),
        ("layouts/tunnel.toml", "min_hits = 3 }", 'min_hits = 3, side = "up" }', "visible.side"),
        (
            "layouts/two_side_walls.toml",
            'side = "right" }',
            'side = "right", x = 1 }',
            "visible[1]",
        ),
        (
            "layouts/tunnel.toml",
            'surface = "ceiling", min',
            'surface = "none", min',
            "visible.surface",
        ),
        (
            "layouts/tunnel.toml",
            'surface = "ceiling", min',
            'surface = "car", min',
            "visible.surface",
        ),
        ("objects/car.toml", "distance_m = [6.0, 20.0]", "", "distance_m"),
        ("objects/car.toml", "[placement]", "[placement]\nheight_m = 1.0", "height_m"),
        ("catalog.toml", '"truck"]\n', '"truck", "none"]\n', "surfaces"),
        ("catalog.toml", 'objects = ["car",', 'objects = ["none", "car",', "objects"),
        ("catalog.toml", 'objects = ["car"', 'objects = ["bus"', None),
    ],
)
def test_a_bad_recipe_names_the_file_and_the_key(catalog_copy, name, old, new, key):
    _edit(catalog_copy, name, old, new)
    with pytest.raises(RecipeError) as err:
        load_catalog(catalog_copy)
    message = str(err.value)
    if key is None:  # a recipe listed in the catalog but missing on disk
        assert "bus.toml" in message and "not found" in message
    else:
        assert name.split("/")[-1] in message and key in message
    assert "\n" not in message


def test_broken_toml_names_the_file(catalog_copy):
    _edit(catalog_copy, "objects/truck.toml", "[params]", "[params")
    with pytest.raises(RecipeError, match="truck.toml: not valid TOML"):
        load_catalog(catalog_copy)


def test_a_missing_catalog_is_named(tmp_path):
    with pytest.raises(RecipeError, match="expected a scene catalog folder"):
        load_catalog(tmp_path / "nowhere")


@pytest.mark.parametrize(
    "old, new, words",
    [
        ('size = [2.2, "width_m"', 'size = [-2.2, "width_m"', r"primitive\[1\]: key 'size'"),
        ('at = ["1.1", 0.0, 0.45]', 'at = ["1.1 / 0", 0.0, 0.45]', r"primitive\[2\]: .*finite"),
        ('at = ["1.1", 0.0, 0.45]', 'at = ["(-1) ** 0.5", 0.0, 0.45]', r"primitive\[2\]: .*finite"),
        ('at = ["1.1", 0.0, 0.45]', 'at = ["9 ** 9 ** 9", 0.0, 0.45]', r"primitive\[2\]: .*finite"),
        (
            'at = ["1.1", 0.0, 0.45]',
            "at = [200.0, 0.0, 0.45]",
            r"primitive\[2\]: geometry reaches 2\d\d\.\d m",
        ),
    ],
)
@pytest.mark.parametrize("compiled", [False, True])
def test_sampled_geometry_is_checked_at_build_time(catalog_copy, old, new, words, compiled):
    from simlidar.scene.build import build_batch

    _edit(catalog_copy, "objects/truck.toml", old, new)
    catalog = load_catalog(catalog_copy)
    u = np.full((1, 16), 0.5)
    with pytest.raises(RecipeError, match=r"truck.toml: " + words), np.errstate(all="ignore"):
        build_batch(
            catalog,
            np.array([1]),
            np.array([3]),
            u[:, : catalog.layout_columns],
            u[:, : catalog.object_columns],
            compiled=compiled,
        )


@pytest.mark.parametrize(
    "text",
    ["__import__('os')", "a.b", "x[0]", "lambda: 1", "'s'", "x if y else z", "exp(1)", "max(a=1)"],
)
def test_expressions_accept_arithmetic_only(text):
    with pytest.raises(expr.ExpressionError):
        expr.parse(text)


def test_expressions_evaluate_on_arrays():
    tree = expr.parse("first_m + i * spacing_m - abs(-2) + cos(0) * 2 ** 2")
    assert expr.names(tree) == {"first_m", "i", "spacing_m"}
    env = {
        "first_m": np.array([[1.0], [2.0]]),
        "i": np.arange(3.0)[None],
        "spacing_m": np.array([[10.0], [20.0]]),
    }
    value = expr.evaluate(expr.compile_tree(tree), env)
    np.testing.assert_allclose(value, [[3, 13, 23], [4, 24, 44]])


@pytest.mark.parametrize(
    "text", ["2.5", "-0.0", "cos(90) * 3 - abs(-2) ** 0.5", "1 / 0", "sqrt(-1)", "min(-0.0, 0)"]
)
def test_an_expression_of_numbers_is_worked_out_once_to_the_same_bits(text):
    compiled = expr.compile_tree(expr.parse(text))
    assert isinstance(compiled.constant, np.float64)
    each_time = expr.evaluate(compiled._replace(constant=None), {})  # the bytecode run again
    assert np.array([compiled.constant]).tobytes() == np.array([each_time]).tobytes()
    assert expr.evaluate(compiled, {"i": np.arange(3.0)}) is compiled.constant
    assert expr.compile_tree(expr.parse("i * 2")).constant is None


def test_scenes_are_the_same_bits_with_every_constant_evaluated_on_each_batch(catalog):
    from simlidar.scene.build import build_batch

    def each_batch(recipe):
        def again(field):
            return field._replace(constant=None)

        return replace(recipe, primitives=tuple(
            replace(p, at=tuple(map(again, p.at)), size=tuple(map(again, p.size)),
                    yaw_deg=again(p.yaw_deg))
            for p in recipe.primitives
        ))  # fmt: skip

    plain = replace(
        catalog,
        layouts=tuple(map(each_batch, catalog.layouts)),
        objects=tuple(map(each_batch, catalog.objects)),
    )
    fields = [f for r in catalog.layouts + catalog.objects for p in r.primitives
              for f in (*p.at, *p.size, p.yaw_deg)]  # fmt: skip
    assert sum(f.constant is not None for f in fields) > len(fields) // 2
    rng = np.random.default_rng(4)
    layout, obj = np.arange(64) % 8, np.arange(64) // 8 % 4
    u = rng.random((64, 16))
    args = layout, obj, u[:, : catalog.layout_columns], u[:, : catalog.object_columns]
    want, got = build_batch(plain, *args), build_batch(catalog, *args)
    for name in ("triangles", "surface", "sample", "closed", "is_object", "object_pose"):
        assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), name


def test_parameter_kinds_cover_their_ranges():
    u = np.linspace(0, 1, 1001, endpoint=False)
    assert set(Param("n", "int", (4.0, 6.0)).sample(u)) == {4.0, 5.0, 6.0}
    assert set(Param("s", "choice", (-1.0, 1.0)).sample(u)) == {-1.0, 1.0}
    values = Param("w", "uniform", (2.0, 3.0)).sample(u)
    assert values.min() == 2.0 and values.max() < 3.0
    assert (Param("f", "fixed", (7.0,)).sample(u) == 7.0).all()


def test_variation_shrinks_ranges_around_their_centre(catalog):
    assert Param("a", "uniform", (2.0, 6.0)).narrowed(0.5).values == (3.0, 5.0)
    assert Param("n", "int", (1.0, 9.0)).narrowed(0.5).values == (3.0, 7.0)
    assert Param("n", "int", (1.0, 9.0)).narrowed(0.1).values == (5.0, 5.0)  # 4.6, 5.4 rounded
    assert Param("c", "choice", (1.0, 5.0)).narrowed(0.1).values == (1.0, 5.0)
    assert Param("f", "fixed", (4.0,)).narrowed(0.1).values == (4.0,)
    assert catalog.with_variation(1.0) is catalog
    narrow = catalog.with_variation(0.25)
    assert narrow.to_dict() == catalog.to_dict()  # the stored recipes stay as written
    for old, new in zip(catalog.layouts + catalog.objects, narrow.layouts + narrow.objects):
        for p, q in zip(old.params, new.params):
            if p.kind == "uniform":
                (a, b), (c, d) = p.values, q.values
                assert d - c == pytest.approx(0.25 * (b - a)) and c + d == pytest.approx(a + b)


def test_a_sensor_variant_changes_only_the_parameters_it_names(catalog):
    """sensors/hdl64e.toml gives the lower bridge and the tunnel other ranges; the VLP-16, which
    has no variant, sees the recipes as written (so its datasets keep their bytes)."""
    assert sorted(catalog.variants) == ["hdl64e"]
    assert catalog.for_sensor("vlp16").to_dict() == catalog.to_dict()
    kitti = catalog.for_sensor("hdl64e")
    assert kitti.fingerprint() != catalog.fingerprint() and kitti.sensor == "hdl64e"
    changed = {r.name for r, o in zip(kitti.layouts, catalog.layouts) if r != o}
    assert changed == {"lower_bridge", "tunnel"} and kitti.objects == catalog.objects
    bridge = dict(zip(kitti.layout_names, kitti.layouts))["lower_bridge"]
    ranges = {p.name: p.values for p in bridge.params}
    assert ranges["bridge_m"] == (85.0, 105.0) and ranges["half_width_m"] == (3.5, 7.0)
    stored = kitti.to_dict()["layouts"]["lower_bridge"]
    assert stored["params"]["clearance_m"] == [4.2, 5.0]
    assert stored["primitive"] == catalog.to_dict()["layouts"]["lower_bridge"]["primitive"]
    assert kitti.for_sensor("hdl64e") is kitti  # chosen once
    with pytest.raises(ValueError, match="chosen for sensor hdl64e, not vlp16"):
        kitti.for_sensor("vlp16")


@pytest.mark.parametrize(
    "text, words",
    [
        ('description = "x"\n[layouts.viaduct.params]\nspan_m = 1.0\n', "key 'layouts'"),
        ('description = "x"\n[layouts.tunnel.params]\nlong_m = 1.0\n', "'layouts.tunnel.params'"),
        ('description = "x"\n[layouts.tunnel.params]\nrise_m = [3.0, 2.0]\n', "low <= high"),
        ('description = "x"\n[layouts.tunnel.placement]\ndistance_m = 1.0\n', "placement"),
        ('description = "x"\n[objects.car.params]\nlength_m = "long"\n', "key 'params.length_m'"),
        ('description = "x"\n[layouts.tunnel]\n', "key 'layouts.tunnel'"),
        ("[layouts.tunnel.params]\nrise_m = 2.0\n", "key 'description' is missing"),
        ('description = "x"\nlayout = 1\n', "key 'layout'"),
    ],
)
def test_a_bad_sensor_variant_names_the_file_and_the_key(catalog_copy, text, words):
    (catalog_copy / "sensors" / "hdl64e.toml").write_text(text)
    with pytest.raises(RecipeError) as err:
        load_catalog(catalog_copy)
    message = str(err.value)
    assert "hdl64e.toml" in message and words in message and "\n" not in message


def test_a_variant_object_keeps_its_placement_and_may_change_it(catalog_copy):
    (catalog_copy / "sensors" / "hdl32e.toml").write_text(
        'description = "x"\n[objects.truck.placement]\ndistance_m = [10.0, 12.0]\n'
    )
    catalog = load_catalog(catalog_copy)
    truck = dict(zip(catalog.object_names, catalog.for_sensor("hdl32e").objects))["truck"]
    assert truck.params[0].name == "distance_m" and truck.params[0].values == (10.0, 12.0)
    assert catalog.for_sensor("hdl64e").objects == catalog.objects


@pytest.mark.parametrize(
    "key, name",
    [
        ("layouts", "../../x/layouts/open_road"),
        ("layouts", "sub/open_road"),
        ("objects", ".car"),
        ("objects", ""),
        ("surfaces", "road surface"),
        ("surfaces", "a\\u0000b"),
        ("layouts", "x" * 65),
    ],
)
def test_catalog_names_are_plain_names(catalog_copy, tmp_path, key, name, cli):
    import shutil

    outside = tmp_path / "x" / "layouts"
    outside.mkdir(parents=True)
    shutil.copy(catalog_copy / "layouts" / "open_road.toml", outside)  # what the path reads
    first = {"layouts": '"tunnel"', "objects": '"car"', "surfaces": '"road"'}[key]
    text = (catalog_copy / "catalog.toml").read_text()
    before = text.split(f"{key} = [", 1)
    (catalog_copy / "catalog.toml").write_text(
        before[0] + f"{key} = [" + before[1].replace(first, f'"{name}"', 1)
    )
    with pytest.raises(RecipeError) as err:
        load_catalog(catalog_copy)
    message = str(err.value)
    assert f"key '{key}': expected names of letters, digits, '_' or '-'" in message
    assert "\n" not in message
    out = tmp_path / "out"
    result = cli("generate", "--scenes", str(catalog_copy), "--train-size", "32", "--out", str(out))
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert result.stderr.count("\n") == 1 and f"key '{key}'" in result.stderr
    assert not out.exists()
