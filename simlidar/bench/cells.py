"""What a benchmark cell is made from, and whether it is done: a cell (one model, one dataset,
one seed) records the fingerprints of its data and recipe and the training rules it ran by, and
a rerun never reuses a cell made from other inputs (docs/benchmark.md)."""

import hashlib
import json
import math
from pathlib import Path

from simlidar.bench.selection import selection_rule
from simlidar.bench.suite import BUDGET_KEYS
from simlidar.errors import DatasetError
from simlidar.models.registry import builder_source, load_recipe, model_name
from simlidar.models.training_config import TrainingConfig
from simlidar.release.checksums import SUMS, read_sums


def cell_id(dataset: Path, model: str, seed: int) -> str:
    return f"{dataset.name}__{model_name(model)}__seed{seed}"


def recorded_rules(rules: dict) -> dict:
    """Training rules (a budget) as a cell records them: no time cap (``max_seconds`` inf) is
    null, as JSON has no infinity (cells written before wrote a bare ``Infinity``, which
    Python reads back as inf: this maps those to the same record)."""
    return {
        key: None if isinstance(value, float) and math.isinf(value) else value
        for key, value in rules.items()
    }


def training_rules(model: str, budget: dict) -> dict:
    """The rules a cell trains by: the recipe's [training] with the suite's budget over it
    (epochs, time cap, validation fraction, patience), defaults filled in, and the selection
    rule's name (:func:`recorded_rules`' form)."""
    training = TrainingConfig.from_table({**load_recipe(model)["training"], **budget}, model)
    return recorded_rules(
        {
            **{key: getattr(training, key) for key in BUDGET_KEYS},
            "selection": selection_rule(training),
        }
    )


def splits_sha256(dataset: Path) -> str | None:
    """sha256 of the split files' lines of the dataset's SHA256SUMS (``train.h5``, ``test.h5``):
    the data a cell trains and is tested on, not the card, whose text follows the simlidar
    version. None without SHA256SUMS."""
    if not (dataset / SUMS).is_file():
        return None
    sums = read_sums(dataset)
    lines = "".join(f"{sums[name]}  {name}\n" for name in sorted(sums) if name.endswith(".h5"))
    return hashlib.sha256(lines.encode()).hexdigest()


def recipe_sha256(recipe: dict) -> str:
    """sha256 of a recipe's content without the [training] keys that a cell's rules record
    (:data:`BUDGET_KEYS`, which a suite's budget overrides): a recipe whose default epoch cap
    or time cap changes still makes the same cells, and a cell whose rules did change is
    refused on its rules."""
    training = {k: v for k, v in recipe.get("training", {}).items() if k not in BUDGET_KEYS}
    content = {k: v for k, v in recipe.items() if k != "base"}  # not where it lies: what it is
    content["training"] = training
    source = builder_source(recipe)
    if source is not None:  # an outside builder: its code is part of what it makes
        content["builder_sha256"] = source
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()


def cell_inputs(dataset: Path, model: str, budget: dict) -> dict:
    """Fingerprints of what a cell was made from: the data (:func:`splits_sha256`), the recipe
    (:func:`recipe_sha256`) and the training rules."""
    return {
        "splits_sha256": splits_sha256(dataset),
        "recipe_sha256": recipe_sha256(load_recipe(model)),
        "rules": training_rules(model, budget),
    }


def finished(out: Path, dataset: Path, model: str, seed: int, budget: dict) -> bool:
    """Whether the cell is done in ``out``; a cell made from another dataset, recipe of the
    same name or other training rules is refused (results are never silently reused for
    different inputs).

    out : the run's output directory (its ``cells/<cell>.json``)
    dataset, model, seed : the cell (:func:`cell_id`): a dataset directory, a recipe name or
        path (or an outside builder named alone) and the training seed
    budget : the suite's budget for the model (:meth:`simlidar.bench.suite.Suite.budget_for`),
        which the cell's recorded rules must match
    """
    path = out / "cells" / f"{cell_id(dataset, model, seed)}.json"
    if not path.is_file():
        return False
    recorded = json.loads(path.read_text()).get("inputs")
    if recorded is None:  # made before fingerprints and model selection were recorded
        recorded = {"rules": "none recorded (a run before model selection)"}
    elif isinstance(recorded.get("rules"), dict):
        recorded = {**recorded, "rules": recorded_rules(recorded["rules"])}
    for key, value in cell_inputs(dataset, model, budget).items():
        if recorded.get(key) == value:
            continue
        if key == "rules":
            raise DatasetError(
                f"--out {out}: cell {path.stem} was made with other training rules "
                f"({_rules(recorded.get(key))}; now {_rules(value)}); expected the same "
                "rules: use a new --out"
            )
        what = "dataset" if key == "splits_sha256" else "recipe"
        raise DatasetError(
            f"--out {out}: cell {path.stem} was made from another {what} ({key} "
            f"{str(recorded.get(key))[:12]}, now {str(value)[:12]}); expected the same inputs: "
            "use a new --out"
        )
    return True


def _rules(rules) -> str:
    if not isinstance(rules, dict):
        return str(rules)
    return ", ".join(f"{k} {'none' if v is None else v}" for k, v in rules.items())
