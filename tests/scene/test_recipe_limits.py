"""Hostile or oversized scene recipes: refused with one RecipeError line, by the library and by
``simlidar scenes``, before anything large is read, parsed or allocated."""

import re
from pathlib import Path

import numpy as np
import pytest

from simlidar.errors import RecipeError, shown
from simlidar.scene import expr
from simlidar.scene.expr import MAX_EXPRESSION_CHARS, MAX_EXPRESSION_DEPTH
from simlidar.scene.parse import MAX_RECIPE_BYTES, MAX_REPEAT, MAX_TRIANGLES
from simlidar.scene.recipe import load_catalog

TUNNEL = "layouts/tunnel.toml"
WALL = "tunnel.toml: primitive[1]"  # the tunnel's walls: a repeated box
WALL_HEIGHT = '"wall_height_m + 0.3"]'  # the last value of the walls' size, an expression


def _edit(root: Path, name: str, old: str, new: str) -> Path:
    path = root / name
    text = path.read_text()
    assert old in text, f"test setup: {old!r} not in {name}"
    path.write_text(text.replace(old, new, 1))
    return path


def _refused(cli, root: Path, *words: str) -> str:
    """The catalog at ``root`` is refused with one RecipeError line holding ``words``, and
    ``simlidar scenes`` prints that line after "Error: " and exits with code 1."""
    with pytest.raises(RecipeError) as err:
        load_catalog(root)
    message = str(err.value)
    assert "\n" not in message and len(message) < 400 + len(str(root))
    for word in words:
        assert word in message
    result = cli("scenes", "--scenes", str(root))
    assert result.exit_code == 1
    assert result.stderr == f"Error: {message}\n"
    assert result.stdout == "" and "Traceback" not in result.output
    return message


def test_a_repeat_beyond_any_array_size_is_refused(catalog_copy, cli):
    # was: loaded, then ValueError "Maximum allowed size exceeded" when the scenes were built
    _edit(catalog_copy, TUNNEL, "repeat = 2", "repeat = 99999999999999999999")
    _refused(
        cli,
        catalog_copy,
        f"{WALL}: key 'repeat'",
        f"an integer in 1..{MAX_REPEAT}",
        "got 99999999999999999999",
    )


@pytest.mark.parametrize(
    "name, old, new, words",
    [
        (TUNNEL, "repeat = 2", "repeat = 1000000", [f"1..{MAX_REPEAT}", "got 1000000"]),
        (TUNNEL, "repeat = 2", f"repeat = {MAX_REPEAT + 1}", [f"got {MAX_REPEAT + 1}"]),
        (
            "layouts/lamps_both_sides.toml",
            "n_lamps = { int = [3, 5] }",
            "n_lamps = { int = [3, 1000000] }",
            [
                "lamps_both_sides.toml: primitive[2]: key 'repeat'",
                f"a parameter with values in 0..{MAX_REPEAT}",
                "got 'n_lamps' up to 1e+06",
            ],
        ),
        (  # 256 arches of 16 triangles and the rest of the tunnel: 4132 triangles
            TUNNEL,
            "segments = 8",
            f"segments = 8\nrepeat = {MAX_REPEAT}",
            ["tunnel.toml: key 'primitive'", f"at most {MAX_TRIANGLES} triangles", "got 4132"],
        ),
    ],
)
def test_a_repeat_over_the_limit_is_refused(catalog_copy, name, old, new, words, cli):
    # was: loaded, then 7.6 GB in 30 s for a million copies before a MemoryError
    _edit(catalog_copy, name, old, new)
    _refused(cli, catalog_copy, *words)


@pytest.mark.parametrize(
    "text, words",
    [
        ("1+" * 29_999 + "1", [f"at most {MAX_EXPRESSION_CHARS} characters", "59999 characters"]),
        ("-" * 60_000 + "1", [f"at most {MAX_EXPRESSION_CHARS} characters", "60001 characters"]),
        ("-" * (MAX_EXPRESSION_DEPTH + 1) + "1", [f"nested at most {MAX_EXPRESSION_DEPTH} deep"]),
        (
            "(" * (MAX_EXPRESSION_DEPTH + 1) + "1" + ")" * (MAX_EXPRESSION_DEPTH + 1),
            [f"got {MAX_EXPRESSION_DEPTH + 1} deep"],
        ),
    ],
)
def test_a_long_or_deep_expression_is_refused_before_parsing(catalog_copy, text, words, cli):
    # was: RecursionError or MemoryError inside Python's parser (or later, in compile)
    _edit(catalog_copy, TUNNEL, WALL_HEIGHT, f'"{text}"]')
    _refused(cli, catalog_copy, f"{WALL}: key 'size[2]'", *words)


def test_the_expression_limits_hold_at_any_size_and_are_not_too_tight():
    # was: RecursionError and MemoryError inside Python's parser
    for text in ("+".join(["1"] * 100_000), "-" * 200_000 + "1"):
        with pytest.raises(expr.ExpressionError, match=f"at most {MAX_EXPRESSION_CHARS} char"):
            expr.parse(text)
    pairs = MAX_EXPRESSION_DEPTH // 2 + 1  # "-(" nests 2 deep
    with pytest.raises(expr.ExpressionError, match=f"got {2 * pairs} deep"):
        expr.parse("-(" * pairs + "1" + ")" * pairs)
    # the deepest syntax trees within the limits still compile and evaluate
    for fits in (
        "-" * MAX_EXPRESSION_DEPTH + "1",
        "1+" * (MAX_EXPRESSION_CHARS // 2 - 1) + "1",
        "2**" * (MAX_EXPRESSION_CHARS // 3 - 1) + "1",
    ):
        assert len(fits) <= MAX_EXPRESSION_CHARS
        assert float(expr.evaluate(expr.compile_tree(expr.parse(fits)), {})) > 0


def test_a_binary_recipe_is_refused(catalog_copy, cli):
    # was: UnicodeDecodeError
    (catalog_copy / TUNNEL).write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
    _refused(cli, catalog_copy, "tunnel.toml: expected UTF-8 text, got byte 0x89 at offset 0")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_recipe_linked_to_an_endless_device_is_refused(catalog_copy, cli):
    # was: MemoryError after reading /dev/zero into memory
    (catalog_copy / TUNNEL).unlink()
    (catalog_copy / TUNNEL).symlink_to("/dev/zero")
    _refused(
        cli,
        catalog_copy,
        "tunnel.toml: expected a regular file, got a character device",
        "(/dev/zero)",
    )


def test_an_oversized_recipe_file_is_refused(catalog_copy, cli):
    # was: read and parsed whatever its size
    path = _edit(catalog_copy, TUNNEL, 'description = "', 'description = "' + "x" * 70_000)
    _refused(
        cli,
        catalog_copy,
        f"tunnel.toml: expected a file of at most {MAX_RECIPE_BYTES} bytes",
        f"got {path.stat().st_size} bytes",
    )


HUGE = "0x" + "f" * 300  # a TOML integer of 1200 bits: too large for a float


@pytest.mark.parametrize(
    "old, new, words",
    [
        # was: TypeError from numpy
        ("rise_m = [1.5, 3.0]", f"rise_m = {HUGE}", ["key 'params.rise_m'", "(362 characters)"]),
        # was: OverflowError
        ("rise_m = [1.5, 3.0]", f"rise_m = {{ int = [0, {HUGE}] }}", ["'params.rise_m.int'"]),
        # was: loaded, then ValueError when the catalog's fingerprint was computed
        ("min_hits = 3", "min_hits = 0x" + "f" * 4000, ["'visible.min_hits'", "too large"]),
        # was: ValueError (integer string conversion)
        ("rise_m = [1.5, 3.0]", "rise_m = " + "9" * 5000, ["not valid TOML", "4300 digits"]),
        # was: RecursionError in tomllib
        ("rise_m = [1.5, 3.0]", "rise_m = " + "[" * 5000 + "]" * 5000, ["nested too deeply"]),
        # was: RecursionError printing the value
        ("at = [65.0, 0.0, -0.3]", "at" + ".a" * 5000 + " = 1", ["key 'at'", "too deeply"]),
        # was: TypeError (unhashable type)
        ('kind = "arch"', 'kind = ["arch"]', ["primitive[2]: key 'kind'", "got ['arch']"]),
    ],
)
def test_hostile_values_are_refused(catalog_copy, old, new, words, cli):
    _edit(catalog_copy, TUNNEL, old, new)
    _refused(cli, catalog_copy, "tunnel.toml", *words)


# Issue 58, finding 5: an expression's numbers are bound to _c0, _c1, ... and a parameter of
# that name replaced them (the tunnel's "2 * half_width_m" became "_c0 * half_width_m": a road
# 7 times its half width, built and stored without a word). Each name below is one the language
# keeps, one Python would fold into another (the full-width "ｉ" reads "i"), or one no
# expression could read; the last is a key that would have split the message in two.
@pytest.mark.parametrize(
    "name, toml_key",
    [
        ("_c0", "_c0"),
        ("_c1", "_c1"),
        ("__builtins__", "__builtins__"),
        ("_", "_"),
        ("sin", "sin"),
        ("max", "max"),
        ("i", "i"),
        ("None", "None"),
        ("lambda", "lambda"),
        ("\uff49", "\\uff49"),
        ("2x", "2x"),
        ("a\nb", "a\\nb"),
    ],
)
def test_a_parameter_cannot_take_the_languages_own_names(catalog_copy, cli, name, toml_key):
    _edit(catalog_copy, TUNNEL, "[params]\n", f'[params]\n"{toml_key}" = 7.0\n')
    shown_key = name.encode("unicode_escape").decode() if not name.isprintable() else name
    _refused(
        cli,
        catalog_copy,
        f"tunnel.toml: key 'params.{shown_key}'",
        f"expected a new name: {expr.PARAMETER_NAME_RULE}, got {shown(name)}",
    )


def test_generate_refuses_a_parameter_named_like_a_number_and_writes_nothing(
    catalog_copy, tmp_path, cli
):
    _edit(catalog_copy, "objects/car.toml", "[params]\n", "[params]\n_c0 = 7.0\n")
    out = tmp_path / "out"
    result = cli("generate", "--scenes", catalog_copy, "--train-size", 32, "--out", out)
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert result.stderr.count("\n") == 1
    assert "car.toml: key 'params._c0': expected a new name" in result.stderr
    assert not out.exists()


@pytest.mark.parametrize("text", ["_c0 + 1", "2 * __builtins__", "_ * 2", "sin * 2", "max"])
def test_an_expression_cannot_read_the_languages_own_names(text):
    with pytest.raises(expr.ExpressionError, match="is the language's own name, not a parameter"):
        expr.parse(text)


@pytest.mark.parametrize(
    "text, env, taken, want",
    [
        ("2 * w", {"_c0": 7.0}, "['_c0']", 6.0),
        # "sin(w) + 1" binds only _c0: a _c1 hides nothing and is let through
        ("sin(w) + 1", {"sin": np.cos, "_c1": 0.0}, "['sin']", 1 + np.sin(np.deg2rad(3.0))),
        ("w ** 2", {"__builtins__": {"abs": print}}, "['__builtins__']", 9.0),
    ],
)
def test_evaluation_refuses_variables_named_like_its_own(text, env, taken, want):
    """A caller that skips the recipe's checks still cannot replace a number or a function."""
    compiled = expr.compile_tree(expr.parse(text))
    w = np.array([3.0])
    with pytest.raises(expr.ExpressionError, match=re.escape(f"own names, got {taken}")):
        expr.evaluate(compiled, {"w": w, **env})
    assert expr.evaluate(compiled, {"w": w, "i": np.arange(2.0)}) == [want]
