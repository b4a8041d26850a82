"""How a catalog's objects move: its ``motion.toml`` (docs/scenes.md, "Motion").

One table per object of the catalog, each key a parameter as a recipe writes one (a number,
``[low, high]``, ``{choice = [...]}``): the object's speed over the road, the heading of its
travel (counter-clockwise from the road's direction, x; 180 is oncoming, +-90 crossing) and
its yaw rate (its travel and its body turn together: :class:`simlidar.motion.poses.
PlanarMotion`); the heading and the yaw rate are 0 where a table leaves them out. A sequence
that moves its objects draws them from its random stream after every draw its static scene
makes, so a scene without motion keeps its bytes. The file is not part of the stored catalog
(:meth:`~simlidar.scene.recipe.Catalog.to_dict`): a sweep with moving objects stores it on its
own (attribute ``motion``).
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.scene.parse import Param, check_keys, fail, parse_param, read_recipe_toml

MOTION_FILE = "motion.toml"
# each key and the values every draw must lie in: a speed up to 70 m/s (252 km/h, past any
# road's limit), a heading within a turn either way, a yaw rate up to half a turn a second (a
# car at its tightest, 5 m radius at 10 m/s, turns 115 deg/s)
KEYS = {
    "speed_mps": (0.0, 70.0),
    "heading_deg": (-360.0, 360.0),
    "yaw_rate_deg_s": (-180.0, 180.0),
}
COLUMNS = len(KEYS)  # uniform variates a moving object draws


@dataclass(frozen=True)
class ObjectMotion:
    """How one object moves: a Param per key of :data:`KEYS`, and its table as written."""

    speed_mps: Param
    heading_deg: Param
    yaw_rate_deg_s: Param
    source: dict

    def sample(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """Each key's values of n objects from their uniform variates (n, COLUMNS)."""
        return {key: getattr(self, key).sample(u[:, k]) for k, key in enumerate(KEYS)}


STILL = ObjectMotion(*(Param(key, "fixed", (0.0,)) for key in KEYS), source={})


def load_motion(path: Path, objects: list[str]) -> dict[str, ObjectMotion]:
    """The motion of each object named in ``path`` (a catalog's ``motion.toml``); ``objects``:
    the catalog's object names, which its tables must be. An object it leaves out stands
    still. A RecipeError names the file and the key of any mistake."""
    data = read_recipe_toml(path)
    where = str(path)
    motions = {}
    for name, table in data.items():
        if name not in objects:
            raise fail(where, name, f"one of the catalog's objects {objects}", name)
        if not isinstance(table, dict):
            raise fail(where, name, f"a table of {list(KEYS)}", table)
        check_keys(f"{where} [{name}]", table, set(KEYS), {"speed_mps"})
        params = {}
        for key, (low, high) in KEYS.items():
            param = parse_param(where, f"{name}.{key}", key, table.get(key, 0.0))
            if not (low <= min(param.values) and max(param.values) <= high):
                raise fail(where, f"{name}.{key}", f"values in [{low:g}, {high:g}]", table[key])
            params[key] = param
        motions[name] = ObjectMotion(**params, source=table)
    return motions
