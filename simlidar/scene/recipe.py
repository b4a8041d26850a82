"""Reading and checking the scene catalog: road layouts and objects as TOML recipes.

A catalog is a folder with ``catalog.toml`` (surface labels, the layouts and objects in class
order), one recipe per layout in ``layouts/`` and per object in ``objects/`` (each read by
:mod:`simlidar.scene.parse`) and, optionally, a sensor's parameter ranges per file in
``sensors/`` (sensor variants). The format is described in ``docs/scenes.md``. Every mistake is
reported as a :class:`RecipeError` naming the file, the key and what was expected; the files'
limits are those of :mod:`simlidar.scene.parse`.
"""

import hashlib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from simlidar.content import PLAIN_NAME, PLAIN_NAME_RULE, content_dir
from simlidar.errors import RecipeError
from simlidar.scene.motion import KEYS, MOTION_FILE, STILL, load_motion
from simlidar.scene.parse import (
    Recipe,
    check_keys,
    fail,
    load_scene_recipe,
    parse_recipe,
    read_recipe_toml,
)
from simlidar.scene.scenarios import SCENARIOS_FILE, load_scenarios

NO_OBJECT = "none"


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
    # object name -> how it moves (the catalog's motion.toml, :mod:`simlidar.scene.motion`);
    # not part of the stored catalog: a sweep with moving objects stores it on its own
    motion: dict = field(default_factory=dict, compare=False, repr=False)
    # how objects come into view in a stream (the catalog's scenarios.toml,
    # :mod:`simlidar.scene.scenarios`); None without the file; not part of the stored catalog:
    # a stream stores it on its own
    scenarios: object = field(default=None, compare=False, repr=False)

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

    def object_motion(self, object_ids, uniforms) -> dict:
        """How each scene's object moves (:mod:`simlidar.scene.motion`; an object the catalog's
        motion.toml leaves out, and "none", stand still): (B,) object indices and (B,
        motion.COLUMNS) uniform variates -> each key of motion.KEYS -> (B,) float64."""
        drawn = {key: np.zeros(len(object_ids)) for key in KEYS}
        for oid in np.unique(object_ids):
            rows = np.nonzero(object_ids == oid)[0]
            motion = self.motion.get(self.objects[oid].name, STILL)
            for key, values in motion.sample(uniforms[rows]).items():
                drawn[key][rows] = values
        return drawn

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


def _name_list(where: str, data: dict, key: str) -> list[str]:
    value = data.get(key)
    if not (isinstance(value, list) and value and all(isinstance(v, str) for v in value)):
        raise fail(where, key, "a non-empty list of names", value)
    for name in value:
        if not PLAIN_NAME.match(name):
            raise fail(where, key, f"names of {PLAIN_NAME_RULE}", name)
    if len(set(value)) != len(value):
        raise fail(where, key, "names without repeats", value)
    return value


def load_catalog(root: str | Path | None = None) -> Catalog:
    """Load the scene catalog at ``root`` (default: the catalog shipped with simlidar)."""
    root = Path(root) if root is not None else content_dir("scenes")
    if not root.is_dir():
        raise RecipeError(f"{root}: expected a scene catalog folder with catalog.toml")
    index = root / "catalog.toml"
    data = read_recipe_toml(index)
    where = str(index)
    check_keys(where, data, {"surfaces", "layouts", "objects"}, {"surfaces", "layouts", "objects"})
    for key in ("surfaces", "objects"):
        if NO_OBJECT in _name_list(where, data, key):
            raise fail(where, key, f"names other than '{NO_OBJECT}' (it is implicit)", data[key])
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
                raise fail(
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
    motion_file = root / MOTION_FILE
    motion = load_motion(motion_file, [r.name for r in objects[1:]]) if motion_file.exists() else {}
    scenarios_file = root / SCENARIOS_FILE
    scenarios = None
    if scenarios_file.exists():
        scenarios = load_scenarios(scenarios_file, [r.name for r in objects[1:]])
    return Catalog(str(root), tuple(surfaces), layouts, objects, variants, motion=motion,
                   scenarios=scenarios)  # fmt: skip


def _sensor_variant(
    path: Path, surfaces: list[str], layouts: tuple[Recipe, ...], objects: tuple[Recipe, ...]
) -> tuple[tuple[Recipe, ...], tuple[Recipe, ...]]:
    """The layouts and objects of ``sensors/<sensor>.toml``: each recipe it names with the
    parameter ranges it gives (checked as the recipe itself is), the others as they are."""
    data = read_recipe_toml(path)
    where = str(path)
    check_keys(where, data, {"description", "layouts", "objects"}, {"description"})
    if not isinstance(data["description"], str):
        raise fail(where, "description", "a string", data["description"])
    result = []
    for group, recipes in (("layouts", layouts), ("objects", objects)):
        by_name = {r.name: r for r in recipes if r.name != NO_OBJECT}
        table = data.get(group, {})
        if not isinstance(table, dict):
            raise fail(where, group, "a table of recipe names", table)
        changed = dict(by_name)
        for name, values in table.items():
            key = f"{group}.{name}"
            if name not in by_name:
                raise fail(where, group, f"names of the catalog's {group} {sorted(by_name)}", name)
            recipe = by_name[name]
            sections = ("params", "placement") if group == "objects" else ("params",)
            if not isinstance(values, dict) or not values:
                raise fail(where, key, f"a table of {' or '.join(sections)}", values)
            check_keys(f"{where} [{key}]", values, set(sections), set())
            source = json.loads(json.dumps(recipe.source))  # a deep copy
            for section, given in values.items():
                known = source.get(section, {})
                if not isinstance(given, dict) or not given:
                    raise fail(where, f"{key}.{section}", "a table of parameters", given)
                for param, spec in given.items():
                    if param not in known:
                        expected = f"parameters of {recipe.path} {sorted(known)}"
                        raise fail(where, f"{key}.{section}", expected, param)
                    known[param] = spec
            changed[name] = parse_recipe(
                f"{where} [{key}]", name, source, surfaces, group == "objects"
            )
        kept = tuple(changed.get(r.name, r) for r in recipes)
        result.append(kept)
    return result[0], result[1]
