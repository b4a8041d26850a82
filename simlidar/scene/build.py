"""Sampled parameters -> the triangles of a whole batch of scenes, with numpy.

No per-sample mesh object is made: for each recipe present in the batch, each primitive is
expanded for all of its samples at once (expressions evaluated on arrays), and its unit template
is scaled, turned and moved with broadcasting. Each sample lives in its own local frame: the
road surface is z = 0 and the sensor's rotation axis stands at x = y = 0.
"""

from dataclasses import dataclass

import numpy as np

from simlidar.errors import RecipeError
from simlidar.scene import expr
from simlidar.scene.parse import Primitive, Recipe
from simlidar.scene.primitives import template
from simlidar.scene.recipe import Catalog

# Every vertex of a scene must lie within this distance of the sensor along each axis; the ray
# caster relies on it to pack many scenes into one Embree scene without them seeing each other.
CELL_HALF_EXTENT_M = 150.0


@dataclass(frozen=True)
class SceneBatch:
    """The triangles of B scenes, each in its own local frame."""

    triangles: np.ndarray  # (T, 3, 3) float64
    surface: np.ndarray  # (T,) uint8, index into Catalog.surfaces
    sample: np.ndarray  # (T,) int64, which scene of the batch
    closed: np.ndarray  # (T,) bool, part of a closed solid with outward winding
    is_object: np.ndarray  # (T,) bool, part of the labelled object
    object_pose: np.ndarray  # (B, 3) float64: x_m, y_m, yaw_deg; NaN where there is no object

    @property
    def size(self) -> int:
        return len(self.object_pose)


def sample_params(recipe: Recipe, uniforms: np.ndarray) -> dict[str, np.ndarray]:
    """Parameter values of n samples of ``recipe`` from their uniform variates (n, >= P)."""
    return {p.name: p.sample(uniforms[:, k]) for k, p in enumerate(recipe.params)}


def _rotate_z(xyz: np.ndarray, yaw_deg: np.ndarray) -> np.ndarray:
    """Turn (..., 3) points counter-clockwise by yaw_deg, broadcast over the leading axes."""
    c, s = np.cos(np.deg2rad(yaw_deg)), np.sin(np.deg2rad(yaw_deg))
    x, y = xyz[..., 0], xyz[..., 1]
    return np.stack([c * x - s * y, s * x + c * y, xyz[..., 2]], axis=-1)


def _instances(prim: Primitive, values: dict[str, np.ndarray], n: int):
    """Expand a primitive for n samples: at (n, R, 3), size (n, R, 3), yaw (n, R), mask (n, R)."""
    shape = (n, prim.repeat_max)
    env = {k: v[:, None] for k, v in values.items()}
    env["i"] = np.arange(prim.repeat_max, dtype=np.float64)[None, :]

    at, size, yaw = np.empty(shape + (3,)), np.empty(shape + (3,)), np.empty(shape)
    for out, compiled in (
        *((at[..., k], t) for k, t in enumerate(prim.at)),
        *((size[..., k], t) for k, t in enumerate(prim.size)),
        (yaw, prim.yaw_deg),
    ):
        try:
            out[...] = np.asarray(expr.evaluate(compiled, env), dtype=np.float64)
        except (ArithmeticError, TypeError, ValueError) as exc:
            raise RecipeError(f"{prim.where}: {exc}: expected finite real values") from None
    if prim.repeat_param is None:
        mask = np.ones(shape, dtype=bool)
    else:
        mask = env["i"] < values[prim.repeat_param][:, None]
    bad = mask[..., None] & ~(size > 0)
    if bad.any():
        raise RecipeError(
            f"{prim.where}: key 'size' evaluated to {size[bad.any(axis=-1)][0].tolist()}: "
            "expected positive sizes for every sampled value"
        )
    return at, size, yaw, mask


@dataclass(frozen=True)
class Instances:
    """Every copy of one primitive in a batch, placed in its scene's frame."""

    primitive: Primitive
    sample: np.ndarray  # (M,) int64, which scene of the batch
    at: np.ndarray  # (M, 3) float64, bottom centre
    size: np.ndarray  # (M, 3) float64, extent along x, y, z before yaw
    yaw_deg: np.ndarray  # (M,) float64, counter-clockwise
    is_object: bool  # part of the labelled object


def _recipe_instances(recipe: Recipe, rows: np.ndarray, values, pose, is_object: bool):
    """Instances of every primitive of one recipe for the batch rows ``rows``."""
    placed = []
    for prim in recipe.primitives:
        at, size, yaw, mask = _instances(prim, values, len(rows))
        if pose is not None:  # object frame -> scene frame
            at = (
                _rotate_z(at, pose[:, None, 2])
                + np.stack([pose[:, 0], pose[:, 1], np.zeros(len(rows))], axis=-1)[:, None, :]
            )
            yaw = yaw + pose[:, None, 2]
        sample = np.broadcast_to(rows[:, None], mask.shape)[mask]
        placed.append(Instances(prim, sample, at[mask], size[mask], yaw[mask], is_object))
    return placed


def place_instances(
    catalog: Catalog,
    layout_ids: np.ndarray,
    object_ids: np.ndarray,
    layout_uniforms: np.ndarray,
    object_uniforms: np.ndarray,
    placement: np.ndarray | None = None,
):
    """Sample the parameters of B scenes and place their primitives.

    layout_ids, object_ids : (B,) int, indices into catalog.layouts / catalog.objects
    layout_uniforms : (B, catalog.layout_columns) float in [0, 1)
    object_uniforms : (B, catalog.object_columns) float in [0, 1)
    placement : (B, 3) [x_m, y_m, yaw_deg], each object's pose in place of its recipe's
        placement draws (a stream's scenario, :mod:`simlidar.scene.scenarios`); None: the
        recipes' (the draws are made either way, so the other parameters keep their values)
    returns : list of Instances, object pose (B, 3) [x_m, y_m, yaw_deg], NaN without object
    """
    pose = np.full((len(layout_ids), 3), np.nan)
    placed = []
    for group, uniforms, recipes in (
        (layout_ids, layout_uniforms, catalog.layouts),
        (object_ids, object_uniforms, catalog.objects),
    ):
        objects = recipes is catalog.objects
        for rid in np.unique(group):
            rows = np.nonzero(group == rid)[0]
            recipe = recipes[rid]
            values = sample_params(recipe, uniforms[rows])
            at = None
            if objects and recipe.primitives:
                at = np.stack(
                    [values["distance_m"], values["lateral_m"], values["yaw_deg"]], axis=-1
                )
                pose[rows] = at if placement is None else placement[rows]
                at = pose[rows]
            placed += _recipe_instances(recipe, rows, values, at, objects)
    return placed, pose


def instance_triangles(inst: Instances) -> np.ndarray:
    """The triangles of every instance: (M, T, 3, 3) float64, T from the primitive's template."""
    tmpl = template(inst.primitive.kind, inst.primitive.segments).triangles  # (T, 3, 3)
    c, s = np.cos(np.deg2rad(inst.yaw_deg)), np.sin(np.deg2rad(inst.yaw_deg))
    # vertex' = Rz(yaw) diag(size) vertex + at, as one batched matrix product
    m = np.zeros((len(c), 3, 3))
    m[:, 0, 0], m[:, 0, 1] = c * inst.size[:, 0], -s * inst.size[:, 1]
    m[:, 1, 0], m[:, 1, 1] = s * inst.size[:, 0], c * inst.size[:, 1]
    m[:, 2, 2] = inst.size[:, 2]
    tris = tmpl.reshape(1, -1, 3) @ m.transpose(0, 2, 1) + inst.at[:, None, :]
    return tris.reshape(len(c), *tmpl.shape)


def _check_reach(inst: Instances, triangles: np.ndarray) -> None:
    """Raise a RecipeError naming the primitive if a vertex of its ``triangles`` is not finite
    or lies more than :data:`CELL_HALF_EXTENT_M` from the sensor along an axis."""
    reach = np.abs(triangles).max(initial=0.0)
    if not reach <= CELL_HALF_EXTENT_M:  # NaN fails too
        raise RecipeError(
            f"{inst.primitive.where}: geometry reaches {reach:.1f} m from the sensor: "
            f"expected every vertex finite and within {CELL_HALF_EXTENT_M:.0f} m along "
            "each axis"
        )


def build_batch(
    catalog: Catalog,
    layout_ids: np.ndarray,
    object_ids: np.ndarray,
    layout_uniforms: np.ndarray,
    object_uniforms: np.ndarray,
    compiled: bool = False,
    placement: np.ndarray | None = None,
) -> SceneBatch:
    """Build the triangles of B scenes (arguments as :func:`place_instances`). A RecipeError
    names the primitive of any vertex that is not finite or lies more than
    :data:`CELL_HALF_EXTENT_M` from the sensor along an axis.

    catalog : the scene recipes that the ids index and the variates parametrise
    layout_ids, object_ids : (B,) int, each scene's index into ``catalog.layouts`` and
        ``catalog.objects`` (0: the empty "none" object)
    layout_uniforms : (B, catalog.layout_columns) float in [0, 1), the uniform variates of each
        scene's layout parameters
    object_uniforms : (B, catalog.object_columns) float in [0, 1), those of its object's
    compiled : place the templates' copies by the compiled kernel
        (:func:`simlidar.scene.kernels.place_copies`: the same triangles, bit for bit; asked on
        long runs, as the ray cast's kernels are, :func:`simlidar.sensor.raycast.compiled_for`)
    placement : (B, 3) each object's pose in place of its recipe's placement draws
        (:func:`place_instances`); None: the recipes'
    """
    placed, pose = place_instances(
        catalog, layout_ids, object_ids, layout_uniforms, object_uniforms, placement
    )
    shapes = [template(inst.primitive.kind, inst.primitive.segments) for inst in placed]
    counts = [len(inst.sample) * len(shape.triangles) for inst, shape in zip(placed, shapes)]
    if compiled:
        from simlidar.scene.kernels import place_copies

        triangles = np.empty((sum(counts), 3, 3))
        start = 0
        for inst, shape, count in zip(placed, shapes, counts):
            out = triangles[start : start + count]
            yaw = np.deg2rad(inst.yaw_deg)
            if not place_copies(
                shape.triangles, np.cos(yaw), np.sin(yaw), inst.size, inst.at,
                CELL_HALF_EXTENT_M, out,
            ):  # fmt: skip
                _check_reach(inst, out)
            start += count
    else:
        pieces = []
        for inst in placed:
            t = instance_triangles(inst)
            _check_reach(inst, t)
            pieces.append(t.reshape(-1, 3, 3))
        triangles = np.concatenate(pieces)
    return SceneBatch(
        triangles=triangles,
        surface=np.repeat(np.array([inst.primitive.surface for inst in placed], np.uint8), counts),
        sample=np.concatenate(
            [np.repeat(inst.sample, len(shape.triangles)) for inst, shape in zip(placed, shapes)]
        ),
        closed=np.repeat(np.array([shape.closed for shape in shapes], bool), counts),
        is_object=np.repeat(np.array([inst.is_object for inst in placed], bool), counts),
        object_pose=pose,
    )
