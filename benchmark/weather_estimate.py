"""The weather benchmark's early-information estimate (``benchmark/weather.py``): the
estimate's runs with every spike on each weather's own dataset (``early_bound.py --ks 256``,
near first), the estimate per weather with its uncertainty, and the committed scores above it.
It is an estimate, not a bound (docs/paper-table.md, "An estimate, not a bound"); functions
and files keep the older name "bound" so that committed results still read."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from simlidar.errors import ResultsError


def bounds(sets: dict[str, Path], out: Path, learners: str = "mlp,wide,cnn") -> dict[str, dict]:
    """The estimate's runs with every spike per weather (early_bound.py's, made where missing,
    and given the families of ``learners`` they lack; the function keeps the older name)."""
    import early_bound

    early_bound.main(
        [
            *map(str, sets.values()),
            "--encodings",
            "near_first/as_value",
            "--ks",
            "256",
            "--learners",
            learners,
            "--out",
            str(out),
        ]  # fmt: skip
    )
    return estimate_runs({w: p.name for w, p in sets.items()}, out)


def estimate_runs(names: dict[str, str], out: Path) -> dict[str, dict]:
    """Weather -> the estimate's run on its dataset (``names``: weather -> dataset name) under
    ``out``/runs; a ResultsError names a missing one."""
    runs = {}
    for weather, name in names.items():
        path = out / "runs" / f"{name}__near_first-as_value.json"
        if not path.is_file():
            raise ResultsError(f"{path}: expected the estimate's run of {name} (or --no-bound)")
        runs[weather] = json.loads(path.read_text())
    return runs


def every_spike(run: dict) -> dict:
    """A run's row with every spike (k = each sample's own count)."""
    return next(r for r in run["rows"] if r["k"] is None)


def estimate(runs: dict[str, dict]) -> dict[str, dict]:
    """Weather -> the estimate with every spike (%), the learner it is (``best``) and its
    uncertainty: the best family's seed mean and sample std (%) and its learner seeds."""
    rows = {}
    for weather, found in runs.items():
        every = every_spike(found)
        family = every["learners"][every["best"].split("/")[0]]
        rows[weather] = {
            "accuracy": 100 * every["accuracy_mean"],
            "best": every.get("best"),
            "family_mean": 100 * family["accuracy_mean"],
            "family_std": 100 * family["accuracy_std"],
            "learner_seeds": len(found["seeds"]),
            "families": {n: family_name(c) for n, c in found["learner"].items()},
        }
    return rows


def family_name(config: dict) -> str:
    """A learner family as the reports name it: its layers and kind ("MLP 256-256")."""
    kind = "CNN, dense" if config.get("model") == "cnn" else "MLP"
    return f"{kind} {'-'.join(map(str, config['hidden']))}"


def above_the_estimate(found: dict, names: dict[str, str], runs: dict[str, dict]) -> list[dict]:
    """Every committed score above the estimate of the weather it is tested in, with its lead
    in test samples over the estimate's best seed ensemble there and what that lead can mean
    (``early_bound.above_the_bound``, as for the flash cells); ``found``: row name -> cells,
    ``names``: weather -> dataset name."""
    import early_bound

    from simlidar.bench.bound import test_samples

    entries = []
    for model, cells in found.items():
        for weather, made in runs.items():
            every = every_spike(made)
            ensemble = max(f["ensemble"] for f in every["learners"].values())
            for c in cells:
                entries.append(
                    {
                        "source": "weather",
                        "variant": model,
                        "dataset": names[weather],
                        "weather": weather,
                        "seed": c["seed"],
                        "accuracy": c["test_accuracy"][weather],
                        "bound": every["accuracy_mean"],  # the estimate (the older key)
                        "best": every["best"],
                        "ensemble": ensemble,
                        "samples": test_samples(made),
                    }
                )
    return early_bound.above_the_bound(entries)
