"""How much does the scenes' variation make Sim LiDAR hard? Accuracy vs parameter spread.

For each factor f, the generator's ``variation`` (``simlidar generate --variation f``) shrinks
every uniform parameter range [lo, hi] of the scene catalog (layout parameters and object
placement and size) around its centre to [c - f (hi - lo) / 2, c + f (hi - lo) / 2], integer
ranges likewise (rounded); f = 1 is the shipped catalog as written. A dataset is generated for
each factor and the benchmark harness trains the same models with the same budget on it. The
printed table (and ``<out>/variation.json``) shows how the accuracy of the spiking network and
of the CNN depends on the within-class variation.

    python benchmark/scene_variation.py --out /tmp/variation            # f = 1, 0.5, 0.25
    python benchmark/scene_variation.py --factors 1,0.1 --models cnn --out /tmp/v2
"""

import argparse
import json
import time
from pathlib import Path

from simlidar.bench.run import run_suite
from simlidar.bench.suite import load_suite
from simlidar.generator.config import MAX_SPLIT_SIZE, GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.models.registry import load_recipe
from simlidar.models.training_config import MAX_EPOCHS
from simlidar.scene.recipe import load_catalog
from simlidar.script_args import integers, numbers, run

SIZE = integers(32, MAX_SPLIT_SIZE, one=True)  # at least one sample of each of the 32 classes
EPOCHS = integers(1, MAX_EPOCHS, one=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--factors", type=numbers(0, 1), default="1,0.5,0.25")
    parser.add_argument("--noise", type=numbers(0, 1, one=True), default=0.1)
    parser.add_argument("--train-size", type=SIZE, default=3000)
    parser.add_argument("--test-size", type=SIZE, default=600)
    parser.add_argument("--models", default="snn_simlidar,cnn")
    parser.add_argument("--snn-epochs", type=EPOCHS, default=10)
    parser.add_argument("--cnn-epochs", type=EPOCHS, default=60)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    models = args.models.split(",")
    for model in models:  # each one a recipe, and each factor a configuration, before any work
        load_recipe(model)
    configs = [
        (
            factor,
            GeneratorConfig(
                noise=args.noise,
                train_size=args.train_size,
                test_size=args.test_size,
                variation=factor,
            ),
        )
        for factor in args.factors
    ]
    args.out.mkdir(parents=True, exist_ok=True)
    epochs = {"snn_simlidar": args.snn_epochs, "cnn": args.cnn_epochs}  # the rest: recipe's own
    rows = []
    for factor, config in configs:
        start = time.perf_counter()
        written = generate(
            config,
            [args.noise],
            load_catalog(),
            args.out / f"data-f{factor:g}",
            force=True,
            progress=False,
        )
        dataset = written[0].path
        suite = args.out / f"suite-f{factor:g}.toml"
        suite.write_text(
            f'name = "variation-f{factor:g}"\nmodels = {json.dumps(models)}\n'
            f'datasets = ["{dataset}"]\n[budget]\nmax_seconds = 600\n'
            + "".join(f"[budget.{m}]\nepochs = {epochs[m]}\n" for m in models if m in epochs)
        )
        results = run_suite(load_suite(suite), args.out / f"bench-f{factor:g}", progress=False)
        for cell in results["cells"]:
            rows.append(
                {
                    "factor": factor,
                    "model": cell["model"],
                    "accuracy": cell["accuracy"],
                    "epochs": cell["epochs"],
                    "seconds": cell["seconds"],
                }
            )
            print(
                f"f = {factor:<5g} {cell['model']:<14} accuracy {cell['accuracy']:.4f} "
                f"({cell['epochs']} epochs, {cell['seconds']:.0f} s)",
                flush=True,
            )
        print(f"f = {factor:g} done in {time.perf_counter() - start:.0f} s", flush=True)
    (args.out / "variation.json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    run(main)
