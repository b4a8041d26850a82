"""Reading and checking the scene catalog: road layouts and objects as TOML recipes.

A catalog is a folder with ``catalog.toml`` (surface labels, the layouts and objects in class
order) and one recipe per layout in ``layouts/`` and per object in ``objects/``. The format is
described in ``docs/scenes.md``. Every mistake is reported as a :class:`RecipeError` naming the
file, the key and what was expected, and so is a file or recipe over the limits below, which keep
a hostile or runaway recipe from taking the memory of the machine (the expression limits are
:data:`expr.MAX_EXPRESSION_CHARS` and :data:`expr.MAX_EXPRESSION_DEPTH`).
"""

import hashlib
import json
from dataclasses import dataclass, field, replace
from functools import cache
from pathlib import Path

import numpy as np

from simlidar.content import PLAIN_NAME, PLAIN_NAME_RULE, content_dir, finite_number, read_toml
from simlidar.errors import RecipeError, shown
from simlidar.scene import expr
from simlidar.scene.primitives import DEFAULT_SEGMENTS, KINDS, template

NO_OBJECT = "none"
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


@dataclass(frozen=True)
class Catalog:
    root: str
    surfaces: tuple[str, ...]  # index 0 is "none" (no return)
    layouts: tuple[Recipe, ...]
    objects: tuple[Recipe, ...]  # index 0 is the empty "none" object
    # sensor name -> (layouts, objects) with the parameters of sensors/<name>.toml: the
    # catalog that sensor sees (:meth:`for_sensor`); not part of the stored catalog
    variants: dict = field(default_factory=dict, compare=False, repr=False)
    sensor: str | None = None  # the sensor whose variant this catalog is, once chosen

    def for_sensor(self, name: str) -> "Catalog":
        """The catalog as the sensor ``name`` sees it: the recipes with the parameters of
        its file in the catalog's ``sensors/`` folder, if it has one, else the catalog as
        written. The stored catalog (:meth:`to_dict`) is then the recipes used."""
        if self.sensor is not None:
            if self.sensor != name:
                raise ValueError(f"catalog chosen for sensor {self.sensor}, not {name}")
            return self
        layouts, objects = self.variants.get(name, (self.layouts, self.objects))
        return replace(self, layouts=layouts, objects=objects, variants={}, sensor=name)

    @property
    def layout_names(self) -> list[str]:
        return [r.name for r in self.layouts]

    @property
    def object_names(self) -> list[str]:
        return [r.name for r in self.objects]

    @property
    def layout_columns(self) -> int:
        """Uniform variates a sample spends on its layout's parameters."""
        return max(len(r.params) for r in self.layouts)

    @property
    def object_columns(self) -> int:
        return max(len(r.params) for r in self.objects)

    def with_variation(self, factor: float) -> "Catalog":
        """The catalog with every uniform and integer parameter range of every layout and
        object (sizes, spacings, counts, placement) shrunk around its centre by ``factor``
        (see :meth:`Param.narrowed`); ``factor`` 1 is the catalog itself. The stored catalog
        (:meth:`to_dict`) stays the recipes as written: the factor is part of the generator's
        configuration (``GeneratorConfig.variation``)."""
        if factor == 1.0:
            return self

        def narrow(recipes):
            return tuple(
                replace(r, params=tuple(p.narrowed(factor) for p in r.params)) for r in recipes
            )

        return replace(self, layouts=narrow(self.layouts), objects=narrow(self.objects))

    def to_dict(self) -> dict:
        """Plain-JSON form of the whole catalog, as stored in every dataset file."""
        return {
            "surfaces": list(self.surfaces),
            "layouts": {r.name: r.source for r in self.layouts},
            "objects": {r.name: r.source for r in self.objects[1:]},
        }

    def fingerprint(self) -> str:
        """sha256 of the catalog's content (independent of where it lives on disk)."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def _fail(where: str, key: str, expected: str, got) -> RecipeError:
    key = key if len(key) <= 100 else f"{key[:100]}..."
    return RecipeError(f"{where}: key '{key}': expected {expected}, got {shown(got)}")


def _read_toml(path: Path) -> dict:
    """A scene catalog's TOML file (:func:`simlidar.content.read_toml`, RecipeError)."""
    return read_toml(path, MAX_RECIPE_BYTES, RecipeError)


def _check_keys(where: str, table: dict, allowed: set[str], required: set[str]) -> None:
    for key in table:
        if key not in allowed:
            raise _fail(where, key, f"one of {sorted(allowed)}", key)
    for key in required - set(table):
        raise RecipeError(f"{where}: key '{key}' is missing")


@cache
def _triangles(kind: str, segments: int) -> int:
    return len(template(kind, segments).triangles)


def _param(where: str, key: str, name: str, spec) -> Param:
    if finite_number(spec):
        return Param(name, "fixed", (float(spec),))
    if isinstance(spec, list) and len(spec) == 2 and all(map(finite_number, spec)):
        if spec[0] > spec[1]:
            raise _fail(where, key, "a range [low, high] with low <= high", spec)
        return Param(name, "uniform", (float(spec[0]), float(spec[1])))
    if isinstance(spec, dict) and set(spec) == {"int"}:
        v = spec["int"]
        integers = isinstance(v, list) and all(isinstance(x, int) and finite_number(x) for x in v)
        if not (integers and len(v) == 2 and 0 <= v[0] <= v[1]):
            raise _fail(where, key + ".int", "[low, high], integers with 0 <= low <= high", v)
        return Param(name, "int", (float(v[0]), float(v[1])))
    if isinstance(spec, dict) and set(spec) == {"choice"}:
        v = spec["choice"]
        if not (isinstance(v, list) and v and all(map(finite_number, v))):
            raise _fail(where, key + ".choice", "a non-empty list of numbers", v)
        return Param(name, "choice", tuple(float(x) for x in v))
    raise _fail(where, key, "a number, [low, high], {int = [low, high]} or {choice = [...]}", spec)


def _expression(where: str, key: str, value, known: set[str]):
    if finite_number(value):
        return expr.compile_tree(expr.parse(repr(float(value))))
    if not isinstance(value, str):
        raise _fail(where, key, "a number or an expression string", value)
    try:
        tree = expr.parse(value)
    except expr.ExpressionError as exc:
        raise RecipeError(f"{where}: key '{key}': {exc}") from None
    unknown = expr.names(tree) - known
    if unknown:
        raise _fail(where, key, f"an expression over {sorted(known)}", value)
    return expr.compile_tree(tree)


def _vector(where: str, key: str, value, known: set[str]) -> tuple:
    if not (isinstance(value, list) and len(value) == 3):
        raise _fail(where, key, "a list of 3 numbers or expressions", value)
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
    _check_keys(where, table, allowed, required)
    kind = table["kind"]
    if not isinstance(kind, str) or kind not in KINDS:
        raise _fail(where, "kind", f"one of {sorted(KINDS)}", kind)
    surface = table.get("surface", default_surface)
    if surface not in surfaces:
        raise _fail(where, "surface", f"a surface of catalog.toml {surfaces[1:]}", surface)
    repeat = table.get("repeat", 1)
    if isinstance(repeat, str):
        spec = params.get(repeat)
        if spec is None or spec.kind not in ("int", "fixed") or spec.upper != int(spec.upper):
            raise _fail(where, "repeat", "the name of an integer parameter", repeat)
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
        raise _fail(where, "repeat", expected, repeat)
    segments = table.get("segments", DEFAULT_SEGMENTS[kind])
    if kind == "box" and "segments" in table:
        raise _fail(where, "segments", "no segments on a box (only cylinder and arch)", segments)
    if kind != "box" and not (
        isinstance(segments, int) and not isinstance(segments, bool) and 3 <= segments <= 64
    ):
        raise _fail(where, "segments", "an integer in [3, 64]", segments)
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
    return _recipe(str(path), path.stem, _read_toml(path), surfaces, is_object)


def _recipe(where: str, stem: str, data: dict, surfaces: list[str], is_object: bool) -> Recipe:
    """Check one layout or object recipe's parsed TOML ``data``."""
    allowed = {"description", "params", "primitive"} | ({"placement"} if is_object else {"visible"})
    _check_keys(
        where, data, allowed, {"description", "primitive"} | ({"placement"} if is_object else set())
    )
    if not isinstance(data["description"], str):
        raise _fail(where, "description", "a string", data["description"])
    params: dict[str, Param] = {}
    if is_object:
        placement = data["placement"]
        if not isinstance(placement, dict):
            raise _fail(where, "placement", "a table", placement)
        _check_keys(where + " [placement]", placement, set(PLACEMENT_KEYS), set(PLACEMENT_KEYS))
        for key in PLACEMENT_KEYS:
            params[key] = _param(where, f"placement.{key}", key, placement[key])
    table = data.get("params", {})
    if not isinstance(table, dict):
        raise _fail(where, "params", "a table of parameters", table)
    for name, spec in table.items():
        if name in params or name == "i" or not name.isidentifier() or name in expr.FUNCTIONS:
            raise _fail(where, f"params.{name}", "a new identifier (not i or a function)", name)
        params[name] = _param(where, f"params.{name}", name, spec)
    prims = data["primitive"]
    if not (isinstance(prims, list) and prims and all(isinstance(p, dict) for p in prims)):
        raise _fail(where, "primitive", "one or more [[primitive]] tables", prims)
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
            raise _fail(
                where,
                key,
                "a table {surface = NAME, min_hits = N, side = ...} or a list of them",
                rule,
            )
        if rule["surface"] not in surfaces:
            raise _fail(
                where,
                f"{key}.surface",
                f"a surface of catalog.toml {surfaces[1:]}",
                rule["surface"],
            )
        hits = rule["min_hits"]
        if not (isinstance(hits, int) and finite_number(hits) and hits >= 1):
            raise _fail(where, f"{key}.min_hits", "a positive integer", hits)
        side = rule.get("side", "any")
        if side not in ("any", "left", "right"):
            raise _fail(where, f"{key}.side", "'any', 'left' or 'right'", side)
        checked.append((surfaces.index(rule["surface"]), hits, side))
    return tuple(checked)


def _name_list(where: str, data: dict, key: str) -> list[str]:
    value = data.get(key)
    if not (isinstance(value, list) and value and all(isinstance(v, str) for v in value)):
        raise _fail(where, key, "a non-empty list of names", value)
    for name in value:
        if not PLAIN_NAME.match(name):
            raise _fail(where, key, f"names of {PLAIN_NAME_RULE}", name)
    if len(set(value)) != len(value):
        raise _fail(where, key, "names without repeats", value)
    return value


def load_catalog(root: str | Path | None = None) -> Catalog:
    """Load the scene catalog at ``root`` (default: the catalog shipped with simlidar)."""
    root = Path(root) if root is not None else content_dir("scenes")
    if not root.is_dir():
        raise RecipeError(f"{root}: expected a scene catalog folder with catalog.toml")
    index = root / "catalog.toml"
    data = _read_toml(index)
    where = str(index)
    _check_keys(where, data, {"surfaces", "layouts", "objects"}, {"surfaces", "layouts", "objects"})
    for key in ("surfaces", "objects"):
        if NO_OBJECT in _name_list(where, data, key):
            raise _fail(where, key, f"names other than '{NO_OBJECT}' (it is implicit)", data[key])
    surfaces = [NO_OBJECT] + _name_list(where, data, "surfaces")
    layouts = tuple(
        load_scene_recipe(root / "layouts" / f"{n}.toml", surfaces, False)
        for n in _name_list(where, data, "layouts")
    )
    objects = tuple(
        load_scene_recipe(root / "objects" / f"{n}.toml", surfaces, True)
        for n in _name_list(where, data, "objects")
    )
    object_surfaces = {p.surface for r in objects for p in r.primitives}
    for recipe in layouts:
        for surface, _, _ in recipe.visible:
            if surface == 0 or surface in object_surfaces:
                raise _fail(
                    recipe.path,
                    "visible.surface",
                    "a surface of the layout itself (not 'none' nor an object's)",
                    surfaces[surface],
                )
    empty = Recipe(NO_OBJECT, "No object on the road.", "", (), (), {})
    objects = (empty,) + objects
    variants = {
        path.stem: _sensor_variant(path, surfaces, layouts, objects)
        for path in sorted((root / "sensors").glob("*.toml"))
    }
    return Catalog(str(root), tuple(surfaces), layouts, objects, variants)


def _sensor_variant(
    path: Path, surfaces: list[str], layouts: tuple[Recipe, ...], objects: tuple[Recipe, ...]
) -> tuple[tuple[Recipe, ...], tuple[Recipe, ...]]:
    """The layouts and objects of ``sensors/<sensor>.toml``: each recipe it names with the
    parameter ranges it gives (checked as the recipe itself is), the others as they are."""
    data = _read_toml(path)
    where = str(path)
    _check_keys(where, data, {"description", "layouts", "objects"}, {"description"})
    if not isinstance(data["description"], str):
        raise _fail(where, "description", "a string", data["description"])
    result = []
    for group, recipes in (("layouts", layouts), ("objects", objects)):
        by_name = {r.name: r for r in recipes if r.name != NO_OBJECT}
        table = data.get(group, {})
        if not isinstance(table, dict):
            raise _fail(where, group, "a table of recipe names", table)
        changed = dict(by_name)
        for name, values in table.items():
            key = f"{group}.{name}"
            if name not in by_name:
                raise _fail(where, group, f"names of the catalog's {group} {sorted(by_name)}", name)
            recipe = by_name[name]
            sections = ("params", "placement") if group == "objects" else ("params",)
            if not isinstance(values, dict) or not values:
                raise _fail(where, key, f"a table of {' or '.join(sections)}", values)
            _check_keys(f"{where} [{key}]", values, set(sections), set())
            source = json.loads(json.dumps(recipe.source))  # a deep copy
            for section, given in values.items():
                known = source.get(section, {})
                if not isinstance(given, dict) or not given:
                    raise _fail(where, f"{key}.{section}", "a table of parameters", given)
                for param, spec in given.items():
                    if param not in known:
                        expected = f"parameters of {recipe.path} {sorted(known)}"
                        raise _fail(where, f"{key}.{section}", expected, param)
                    known[param] = spec
            changed[name] = _recipe(f"{where} [{key}]", name, source, surfaces, group == "objects")
        kept = tuple(changed.get(r.name, r) for r in recipes)
        result.append(kept)
    return result[0], result[1]
