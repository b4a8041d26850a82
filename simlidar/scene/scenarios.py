"""How an object comes into view in a stream: a catalog's ``scenarios.toml`` (docs/streams.md,
"Scenarios").

Each ``[scenario.NAME]`` table applies to the objects it lists and gives, as a recipe's
parameters (a number, ``[low, high]``, ``{choice = [...]}``), the object's start at t = 0 (the
stream's first firing; the sensor at the scene's origin facing +x, the road's direction) and
its motion: its start along the road (``distance_m``) and across it (``lateral_m``, from the
lane centre or, with ``from_window_edge``, outward from the edge of the sensor's window at that
distance), its speed over the road (or over the ego's, ``relative_to_ego``), the heading of its
travel and body and its yaw rate; ``mirrored`` puts each draw on either side. ``[ego]`` gives
the ego's speed along the road, ``[visibility]`` how long before the span's end the object must
first return. A stream draws all of it from its random stream after every draw of its static
scene (:data:`COLUMNS` variates, whatever the scenario), so the static scene is the window
datasets' own.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.scene.motion import KEYS as MOTION_KEYS
from simlidar.scene.parse import Param, check_keys, fail, parse_param, read_recipe_toml

SCENARIOS_FILE = "scenarios.toml"
PARAMS = ("distance_m", "lateral_m", "speed_mps", "heading_deg", "yaw_rate_deg_s")
FLAGS = ("relative_to_ego", "from_window_edge", "mirrored")
# every value a draw may take: a start within the scene's reach (the ray caster's cell,
# simlidar.scene.build.CELL_HALF_EXTENT_M, less a truck's length), the motions' own bounds
LIMITS = {
    "distance_m": (-120.0, 120.0),
    "lateral_m": (-120.0, 120.0),
    **MOTION_KEYS,
}
# the uniform variates a stream draws after its static scene's, in this order: the scenario,
# the side, the PARAMS, the ego's speed, and the reference time of a stream without an object
COLUMNS = 2 + len(PARAMS) + 2
EGO_COLUMN = 2 + len(PARAMS)  # the ego's speed
REFERENCE_COLUMN = EGO_COLUMN + 1  # the reference time of a stream without object


@dataclass(frozen=True)
class Scenario:
    """One way an object comes into view (module docstring); ``source``: its table as written."""

    name: str
    description: str
    objects: tuple[str, ...]
    params: dict[str, Param]
    relative_to_ego: bool
    from_window_edge: bool
    mirrored: bool
    source: dict


@dataclass(frozen=True)
class Scenarios:
    """A catalog's scenarios, the ego's speed and the visibility rule; ``source``: the file's
    tables as written (stored in every stream split, attribute ``scenarios``)."""

    scenarios: tuple[Scenario, ...]
    ego_speed_mps: Param
    tail_ms: float
    source: dict

    @property
    def names(self) -> tuple[str, ...]:
        """The scenario names, in file order after "none" (index 0: a stream without object)."""
        return ("none",) + tuple(s.name for s in self.scenarios)

    def draw(self, objects: list[str], object_ids: np.ndarray, u: np.ndarray, edge_slope: float):
        """Each stream's scenario, start and motion.

        objects : the catalog's object names, "none" first
        object_ids : (n,) int, each stream's object (an index into ``objects``; 0: none)
        u : (n, >= COLUMNS) uniform variates, in the order of :data:`COLUMNS`
        edge_slope : tan of half the window's field of view (the window's edge: |y| = slope x)
        returns : dict of (n,) float64 arrays: scenario (index into :attr:`names`; 0 for none),
            x_m, y_m, heading_deg (the start pose), speed_mps, yaw_rate_deg_s (over the road),
            ego_speed_mps; for a stream without object the object's entries are 0
        """
        n = len(object_ids)
        ego = self.ego_speed_mps.sample(u[:, EGO_COLUMN])
        out = {key: np.zeros(n) for key in ("scenario", "x_m", "y_m", "heading_deg",
                                            "speed_mps", "yaw_rate_deg_s")}  # fmt: skip
        out["ego_speed_mps"] = ego
        for oid in np.unique(object_ids):
            if oid == 0:
                continue
            rows = np.nonzero(object_ids == oid)[0]
            mine = [k for k, s in enumerate(self.scenarios) if objects[oid] in s.objects]
            pick = np.minimum((u[rows, 0] * len(mine)).astype(np.int64), len(mine) - 1)
            for choice, k in enumerate(mine):
                at = rows[pick == choice]
                scenario = self.scenarios[k]
                values = {
                    key: scenario.params[key].sample(u[at, 2 + c]) for c, key in enumerate(PARAMS)
                }
                side = np.where(scenario.mirrored & (u[at, 1] >= 0.5), -1.0, 1.0)
                lateral = values["lateral_m"]
                if scenario.from_window_edge:
                    lateral = np.abs(values["distance_m"]) * edge_slope + lateral
                speed = values["speed_mps"] + (ego[at] if scenario.relative_to_ego else 0.0)
                out["scenario"][at] = k + 1
                out["x_m"][at] = values["distance_m"]
                out["y_m"][at] = side * lateral
                out["heading_deg"][at] = side * values["heading_deg"]
                out["speed_mps"][at] = speed
                out["yaw_rate_deg_s"][at] = side * values["yaw_rate_deg_s"]
        return out


def _flag(where: str, name: str, table: dict, key: str) -> bool:
    value = table.get(key, False)
    if not isinstance(value, bool):
        raise fail(where, f"{name}.{key}", "true or false", value)
    return value


def _param(where: str, key: str, spec, limits: tuple[float, float]) -> Param:
    param = parse_param(where, key, key.rsplit(".", 1)[-1], spec)
    low, high = limits
    if not (low <= min(param.values) and max(param.values) <= high):
        raise fail(where, key, f"values in [{low:g}, {high:g}]", spec)
    return param


def load_scenarios(path: Path, objects: list[str]) -> Scenarios:
    """The scenarios of ``path`` (a catalog's ``scenarios.toml``); ``objects``: the catalog's
    object names, which each scenario's ``objects`` must be among. Every object must have a
    scenario. A RecipeError names the file and the key of any mistake."""
    data = read_recipe_toml(path)
    where = str(path)
    check_keys(where, data, {"ego", "visibility", "scenario"}, {"scenario"})
    ego = data.get("ego", {})
    if not isinstance(ego, dict):
        raise fail(where, "ego", "a table with speed_mps", ego)
    check_keys(f"{where} [ego]", ego, {"speed_mps"}, {"speed_mps"})
    ego_speed = _param(where, "ego.speed_mps", ego["speed_mps"], MOTION_KEYS["speed_mps"])
    visibility = data.get("visibility", {"tail_ms": 0.0})
    if not isinstance(visibility, dict):
        raise fail(where, "visibility", "a table with tail_ms", visibility)
    check_keys(f"{where} [visibility]", visibility, {"tail_ms"}, {"tail_ms"})
    tail = visibility["tail_ms"]
    if isinstance(tail, bool) or not isinstance(tail, int | float) or not 0 <= tail <= 10_000:
        raise fail(where, "visibility.tail_ms", "milliseconds in [0, 10000]", tail)
    tables = data["scenario"]
    if not isinstance(tables, dict) or not tables:
        raise fail(where, "scenario", "tables [scenario.NAME]", tables)
    scenarios = []
    for name, table in tables.items():
        if name == "none":  # the name of a stream without object
            raise fail(where, "scenario.none", "another name (none: a stream without object)", name)
        if not isinstance(table, dict):
            raise fail(where, f"scenario.{name}", "a table", table)
        check_keys(f"{where} [scenario.{name}]", table,
                   {"description", "objects", *PARAMS, *FLAGS},
                   {"description", "objects", "distance_m", "lateral_m", "speed_mps"})  # fmt: skip
        if not isinstance(table["description"], str):
            raise fail(where, f"scenario.{name}.description", "a string", table["description"])
        listed = table["objects"]
        if not (isinstance(listed, list) and listed and all(o in objects for o in listed)):
            raise fail(
                where, f"scenario.{name}.objects", f"a list of names among {objects}", listed
            )
        params = {
            key: _param(where, f"scenario.{name}.{key}", table.get(key, 0.0), LIMITS[key])
            for key in PARAMS
        }
        flags = {key: _flag(where, f"scenario.{name}", table, key) for key in FLAGS}
        scenarios.append(Scenario(name, table["description"], tuple(listed), params, **flags,
                                  source=table))  # fmt: skip
    for name in objects:
        if not any(name in s.objects for s in scenarios):
            raise fail(where, "scenario", f"a scenario for every object ({name} has none)", name)
    return Scenarios(tuple(scenarios), ego_speed, float(tail), source=data)
