"""One layout or object recipe of a scene catalog: its parsed form (:class:`Param`,
:class:`Primitive`, :class:`Recipe`) and the checks that read it from TOML.

The format is described in ``docs/scenes.md``; the catalog that lists the recipes is read by
:mod:`simlidar.scene.recipe`. Every mistake is reported as a :class:`RecipeError` naming the
file, the key and what was expected, and so is a file or recipe over the limits below, which keep
a hostile or runaway recipe from taking the memory of the machine (the expression limits are
:data:`expr.MAX_EXPRESSION_CHARS` and :data:`expr.MAX_EXPRESSION_DEPTH`).
"""

from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path

import numpy as np

from simlidar.content import finite_number, read_toml
from simlidar.errors import RecipeError, shown
from simlidar.scene import expr
from simlidar.scene.primitives import DEFAULT_SEGMENTS, KINDS, template

PLACEMENT_KEYS = ("distance_m", "lateral_m", "yaw_deg")

# Limits, documented in docs/scenes.md ("Limits"). The shipped recipes have at most 1,774 bytes,
# 5 copies of a primitive and 356 triangles; a generator batch builds 1,024 scenes at once.
MAX_RECIPE_BYTES = 64 * 1024  # size of catalog.toml and of every recipe file
MAX_REPEAT = 256  # copies of one primitive: a post every 0.6 m along the 150 m road
MAX_TRIANGLES = 4096  # triangles of one recipe, every primitive at its largest repeat


@dataclass(frozen=True)
class Param:
    """A per-sample parameter: fixed, uniform in a range, a uniform integer, or a choice."""

    name: str
    kind: str  # "fixed" | "uniform" | "int" | "choice"
    values: tuple[float, ...]  # (v,) | (lo, hi) | (lo, hi) | (v1, v2, ...)

    def sample(self, u: np.ndarray) -> np.ndarray:
        """Map uniform variates ``u`` in [0, 1) to parameter values (same shape, float64)."""
        v = self.values
        if self.kind == "fixed":
            return np.full(u.shape, v[0])
        if self.kind == "uniform":
            return v[0] + u * (v[1] - v[0])
        if self.kind == "int":
            return v[0] + np.minimum(np.floor(u * (v[1] - v[0] + 1)), v[1] - v[0])
        choices = np.asarray(v)
        return choices[np.minimum((u * len(v)).astype(np.int64), len(v) - 1)]

    @property
    def upper(self) -> float:
        return max(self.values)

    def narrowed(self, factor: float) -> "Param":
        """This parameter with a uniform or integer range [lo, hi] shrunk around its centre c
        to [c - f (hi - lo) / 2, c + f (hi - lo) / 2] (integers rounded); others unchanged."""
        if factor == 1.0 or self.kind not in ("uniform", "int"):
            return self
        lo, hi = self.values
        c, h = (lo + hi) / 2, factor * (hi - lo) / 2
        if self.kind == "uniform":
            return replace(self, values=(c - h, c + h))
        low = round(c - h)
        return replace(self, values=(float(low), float(max(low, round(c + h)))))


@dataclass(frozen=True)
class Primitive:
    """One primitive of a recipe, its fields parsed into expressions."""

    where: str  # "file.toml: primitive[k]", for error messages
    kind: str  # a key of primitives.KINDS
    surface: int  # index into Catalog.surfaces
    at: tuple  # 3 compiled expressions: bottom centre, metres
    size: tuple  # 3 compiled expressions: extent along x, y, z before yaw, metres
    yaw_deg: object  # compiled expression, counter-clockwise seen from above
    repeat_max: int  # number of copies to build (1 when not repeated)
    repeat_param: str | None  # parameter that says how many of them exist
    segments: int  # resolution of round primitives


@dataclass(frozen=True)
class Recipe:
    name: str
    description: str
    path: str
    params: tuple[Param, ...]  # for objects, the placement params come first
    primitives: tuple[Primitive, ...]
    source: dict  # the parsed TOML, stored in every dataset
    # What the sensor must see for the label to hold: (surface index, min hits, side), side
    # being "any", "left" or "right" (the half of the window, by column azimuth).
    visible: tuple[tuple[int, int, str], ...] = ()


def fail(where: str, key: str, expected: str, got) -> RecipeError:
    """The error for key ``key`` of ``where``: ``expected``, but ``got`` (shown shortened)."""
    if not key.isprintable():  # a TOML key may hold any character: keep the message one line
        key = key.encode("unicode_escape").decode("ascii")
    key = key if len(key) <= 100 else f"{key[:100]}..."
    return RecipeError(f"{where}: key '{key}': expected {expected}, got {shown(got)}")


def read_recipe_toml(path: Path) -> dict:
    """A scene catalog's TOML file (:func:`simlidar.content.read_toml`, RecipeError)."""
    return read_toml(path, MAX_RECIPE_BYTES, RecipeError)


def check_keys(where: str, table: dict, allowed: set[str], required: set[str]) -> None:
    """A RecipeError unless ``table``'s keys are among ``allowed`` and hold ``required``."""
    for key in table:
        if key not in allowed:
            raise fail(where, key, f"one of {sorted(allowed)}", key)
    for key in required - set(table):
        raise RecipeError(f"{where}: key '{key}' is missing")


@cache
def _triangles(kind: str, segments: int) -> int:
    return len(template(kind, segments).triangles)


def parse_param(where: str, key: str, name: str, spec) -> Param:
    if finite_number(spec):
        return Param(name, "fixed", (float(spec),))
    if isinstance(spec, list) and len(spec) == 2 and all(map(finite_number, spec)):
        if spec[0] > spec[1]:
            raise fail(where, key, "a range [low, high] with low <= high", spec)
        return Param(name, "uniform", (float(spec[0]), float(spec[1])))
    if isinstance(spec, dict) and set(spec) == {"int"}:
        v = spec["int"]
        integers = isinstance(v, list) and all(isinstance(x, int) and finite_number(x) for x in v)
        if not (integers and len(v) == 2 and 0 <= v[0] <= v[1]):
            raise fail(where, key + ".int", "[low, high], integers with 0 <= low <= high", v)
        return Param(name, "int", (float(v[0]), float(v[1])))
    if isinstance(spec, dict) and set(spec) == {"choice"}:
        v = spec["choice"]
        if not (isinstance(v, list) and v and all(map(finite_number, v))):
            raise fail(where, key + ".choice", "a non-empty list of numbers", v)
        return Param(name, "choice", tuple(float(x) for x in v))
    raise fail(where, key, "a number, [low, high], {int = [low, high]} or {choice = [...]}", spec)


def _expression(where: str, key: str, value, known: set[str]):
    if finite_number(value):
        return expr.compile_tree(expr.parse(repr(float(value))))
    if not isinstance(value, str):
        raise fail(where, key, "a number or an expression string", value)
    try:
        tree = expr.parse(value)
    except expr.ExpressionError as exc:
        raise RecipeError(f"{where}: key '{key}': {exc}") from None
    unknown = expr.names(tree) - known
    if unknown:
        raise fail(where, key, f"an expression over {sorted(known)}", value)
    return expr.compile_tree(tree)


def _vector(where: str, key: str, value, known: set[str]) -> tuple:
    if not (isinstance(value, list) and len(value) == 3):
        raise fail(where, key, "a list of 3 numbers or expressions", value)
    return tuple(_expression(where, f"{key}[{k}]", v, known) for k, v in enumerate(value))


def _primitive(
    where: str,
    table: dict,
    params: dict[str, Param],
    surfaces: list[str],
    default_surface: str | None,
) -> Primitive:
    allowed = {"kind", "surface", "at", "size", "yaw_deg", "repeat", "segments"}
    required = {"kind", "at", "size"} | ({"surface"} if default_surface is None else set())
    check_keys(where, table, allowed, required)
    kind = table["kind"]
    if not isinstance(kind, str) or kind not in KINDS:
        raise fail(where, "kind", f"one of {sorted(KINDS)}", kind)
    surface = table.get("surface", default_surface)
    if surface not in surfaces:
        raise fail(where, "surface", f"a surface of catalog.toml {surfaces[1:]}", surface)
    repeat = table.get("repeat", 1)
    if isinstance(repeat, str):
        spec = params.get(repeat)
        if spec is None or spec.kind not in ("int", "fixed") or spec.upper != int(spec.upper):
            raise fail(where, "repeat", "the name of an integer parameter", repeat)
        if not 0 <= spec.upper <= MAX_REPEAT:
            raise RecipeError(
                f"{where}: key 'repeat': expected a parameter with values in 0..{MAX_REPEAT}, "
                f"got {shown(repeat)} up to {spec.upper:g}"
            )
        repeat_max, repeat_param = int(spec.upper), repeat
    elif isinstance(repeat, int) and not isinstance(repeat, bool) and 1 <= repeat <= MAX_REPEAT:
        repeat_max, repeat_param = repeat, None
    else:
        expected = f"an integer in 1..{MAX_REPEAT} or an integer parameter's name"
        raise fail(where, "repeat", expected, repeat)
    segments = table.get("segments", DEFAULT_SEGMENTS[kind])
    if kind == "box" and "segments" in table:
        raise fail(where, "segments", "no segments on a box (only cylinder and arch)", segments)
    if kind != "box" and not (
        isinstance(segments, int) and not isinstance(segments, bool) and 3 <= segments <= 64
    ):
        raise fail(where, "segments", "an integer in [3, 64]", segments)
    known = set(params) | ({"i"} if "repeat" in table else set())
    return Primitive(
        where=where,
        kind=kind,
        surface=surfaces.index(surface),
        at=_vector(where, "at", table["at"], known),
        size=_vector(where, "size", table["size"], known),
        yaw_deg=_expression(where, "yaw_deg", table.get("yaw_deg", 0.0), known),
        repeat_max=repeat_max,
        repeat_param=repeat_param,
        segments=segments,
    )


def load_scene_recipe(path: Path, surfaces: list[str], is_object: bool) -> Recipe:
    """Read and check one layout or object recipe."""
    return parse_recipe(str(path), path.stem, read_recipe_toml(path), surfaces, is_object)


def parse_recipe(where: str, stem: str, data: dict, surfaces: list[str], is_object: bool) -> Recipe:
    """Check one layout or object recipe's parsed TOML ``data``.

    where : what an error names the recipe by (its file's path, or a sensor file's path and
        key), kept as ``Recipe.path``
    stem : the recipe's name (its file's stem), and an object's default surface
    surfaces : the catalog's surface names ("none" first); a primitive's surface must be one of
        them and is kept as its index
    is_object : an object recipe (a ``[placement]``, whose parameters come first) rather than a
        layout (``visible`` rules)
    returns : the checked :class:`Recipe`; a RecipeError names the file, the key and what was
        expected otherwise
    """
    allowed = {"description", "params", "primitive"} | ({"placement"} if is_object else {"visible"})
    check_keys(
        where, data, allowed, {"description", "primitive"} | ({"placement"} if is_object else set())
    )
    if not isinstance(data["description"], str):
        raise fail(where, "description", "a string", data["description"])
    params: dict[str, Param] = {}
    if is_object:
        placement = data["placement"]
        if not isinstance(placement, dict):
            raise fail(where, "placement", "a table", placement)
        check_keys(where + " [placement]", placement, set(PLACEMENT_KEYS), set(PLACEMENT_KEYS))
        for key in PLACEMENT_KEYS:
            params[key] = parse_param(where, f"placement.{key}", key, placement[key])
    table = data.get("params", {})
    if not isinstance(table, dict):
        raise fail(where, "params", "a table of parameters", table)
    for name, spec in table.items():
        if name in params or not expr.is_parameter_name(name):
            raise fail(where, f"params.{name}", f"a new name: {expr.PARAMETER_NAME_RULE}", name)
        params[name] = parse_param(where, f"params.{name}", name, spec)
    prims = data["primitive"]
    if not (isinstance(prims, list) and prims and all(isinstance(p, dict) for p in prims)):
        raise fail(where, "primitive", "one or more [[primitive]] tables", prims)
    default_surface = stem if is_object else None
    primitives = tuple(
        _primitive(f"{where}: primitive[{k}]", p, params, surfaces, default_surface)
        for k, p in enumerate(prims)
    )
    triangles = sum(p.repeat_max * _triangles(p.kind, p.segments) for p in primitives)
    if triangles > MAX_TRIANGLES:
        raise RecipeError(
            f"{where}: key 'primitive': expected at most {MAX_TRIANGLES} triangles "
            f"(every primitive at its largest repeat), got {triangles}"
        )
    return Recipe(
        stem,
        data["description"],
        where,
        tuple(params.values()),
        primitives,
        data,
        _visible(where, data.get("visible", []), surfaces),
    )


def _visible(where: str, visible, surfaces: list[str]) -> tuple[tuple[int, int, str], ...]:
    """Check a layout's `visible` rules: a table or a list of tables."""
    rules = visible if isinstance(visible, list) else [visible]
    checked = []
    for k, rule in enumerate(rules):
        key = f"visible[{k}]" if isinstance(visible, list) else "visible"
        if not (
            isinstance(rule, dict)
            and {"surface", "min_hits"} <= set(rule)
            and set(rule) <= {"surface", "min_hits", "side"}
        ):
            raise fail(
                where,
                key,
                "a table {surface = NAME, min_hits = N, side = ...} or a list of them",
                rule,
            )
        if rule["surface"] not in surfaces:
            raise fail(
                where,
                f"{key}.surface",
                f"a surface of catalog.toml {surfaces[1:]}",
                rule["surface"],
            )
        hits = rule["min_hits"]
        if not (isinstance(hits, int) and finite_number(hits) and hits >= 1):
            raise fail(where, f"{key}.min_hits", "a positive integer", hits)
        side = rule.get("side", "any")
        if side not in ("any", "left", "right"):
            raise fail(where, f"{key}.side", "'any', 'left' or 'right'", side)
        checked.append((surfaces.index(rule["surface"]), hits, side))
    return tuple(checked)
