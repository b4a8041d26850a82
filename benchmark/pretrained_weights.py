"""The pretrained weights shipped in weights/: the paper's dense spiking network with our
training (``snn_simlidar_tuned``) on the paper's four Sim LiDAR datasets, seed 0, scored by
``simlidar evaluate``; their manifest and the table of weights/README.md.

    python benchmark/pretrained_weights.py --data DATA --write   # score, write the manifest
    python benchmark/pretrained_weights.py --check               # files against the manifest

Made by (about 1.5 minutes a network on one core, 460 KB a file):

    simlidar generate --classes 32 --noise 0.1,0.2,0.33,0.5 --out DATA
    simlidar train --model snn_simlidar_tuned --dataset DATA/<dataset> --out weights --seed 0

``--write`` scores every ``weights/*.pt`` on the test split of the dataset it names (in DATA,
by its directory name) with :func:`simlidar.bench.evaluate.evaluate` and writes
``weights/manifest.json`` (each file's sha256, size, dataset, the command that made it, its
accuracy and how many input spikes it reads before deciding) and the table between the markers
of ``weights/README.md``. ``--check`` exits 1 in one line where a file's bytes or the README's
table are not the manifest's. The figures are those of one training seed: the paper table's
five seeds and their intervals are in docs/paper-table.md.
"""

import argparse
import hashlib
import json
from pathlib import Path

from simlidar.errors import DatasetError
from simlidar.script_args import run

ROOT = Path(__file__).resolve().parents[1]
WEIGHTS = ROOT / "weights"
MANIFEST = "manifest.json"
START, END = "<!-- weights-table:start -->", "<!-- weights-table:end -->"
MODEL = "snn_simlidar_tuned"
COMMAND = "simlidar train --model {model} --dataset data/{dataset} --out weights --seed 0"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def entries(weights: Path, data: Path) -> list[dict]:
    """Every checkpoint of ``weights`` scored on its dataset's test split in ``data``."""
    from simlidar.bench.evaluate import evaluate

    found = []
    for path in sorted(weights.glob("*.pt")):
        name = path.stem.removeprefix(f"{MODEL}-").rsplit("-seed", 1)[0]
        if not (data / name).is_dir():
            raise DatasetError(f"{path.name}: no dataset {data / name}; expected --data to hold it")
        record = evaluate(path, data / name)
        early = record.get("early", {})
        found.append({
            "file": path.name,
            "sha256": _sha256(path),
            "bytes": path.stat().st_size,
            "model": MODEL,
            "dataset": name,
            "seed": 0,
            "command": COMMAND.format(model=MODEL, dataset=name),
            "test_size": record["test_size"],
            "accuracy": record["accuracy"],
            "input_spikes_mean": early.get("input_spikes_mean"),
        })  # fmt: skip
    return found


def table(manifest: list[dict]) -> str:
    """The Markdown table of the manifest, between its markers."""
    rows = [
        "| file | dataset | test accuracy | input spikes read before deciding (mean) |",
        "| --- | --- | ---: | ---: |",
    ]
    for e in manifest:
        correct = round(e["accuracy"] * e["test_size"])
        spikes = "-" if e["input_spikes_mean"] is None else f"{e['input_spikes_mean']:.1f} of 256"
        rows.append(
            f"| `{e['file']}` | `{e['dataset']}` | {100 * e['accuracy']:.2f} % ({correct} of "
            f"{e['test_size']}) | {spikes} |"
        )
    return "\n".join([START, *rows, END])


def _with_table(text: str, manifest: list[dict], where: Path) -> str:
    if text.count(START) != 1 or text.count(END) != 1 or text.index(START) > text.index(END):
        raise DatasetError(f"{where}: expected one {START} line before one {END} line")
    head, rest = text.split(START)
    return head + table(manifest) + rest.split(END, 1)[1]


def check(weights: Path) -> list[str]:
    """Where ``weights`` differs from its manifest: a file missing, changed or not listed, or
    README.md's table not the manifest's."""
    try:
        manifest = json.loads((weights / MANIFEST).read_text())
        files = {e["file"]: e["sha256"] for e in manifest}
    except (OSError, ValueError, TypeError, KeyError) as exc:
        raise DatasetError(f"{weights / MANIFEST}: cannot read it as a manifest ({exc})") from None
    problems = []
    for extra in sorted({p.name for p in weights.glob("*.pt")} - files.keys()):
        problems.append(f"{weights / extra}: not in {MANIFEST}")
    for name, sha256 in files.items():
        path = weights / name
        if not path.is_file():
            problems.append(f"{path}: missing")
        elif _sha256(path) != sha256:
            problems.append(f"{path}: sha256 {_sha256(path)}, {MANIFEST} says {sha256}")
    readme = weights / "README.md"
    text = readme.read_text()
    if _with_table(text, manifest, readme) != text:
        problems.append(f"{readme}: its table is not {MANIFEST}'s (run --write)")
    return problems


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", type=Path, default=WEIGHTS, help="the weights folder")
    parser.add_argument(
        "--data", type=Path, default=None, help="with --write: the folder of their datasets"
    )
    how = parser.add_mutually_exclusive_group(required=True)
    how.add_argument("--write", action="store_true", help="score the weights, write the manifest")
    how.add_argument("--check", action="store_true", help="check the files against the manifest")
    args = parser.parse_args(argv)
    if args.check:
        problems = check(args.weights)
        if problems:
            more = f" (and {len(problems) - 1} more)" * (len(problems) > 1)
            raise DatasetError(problems[0] + more)
        print(f"{args.weights}: every file is its manifest's")
        return 0
    if args.data is None:
        parser.error("--write needs --data: the folder holding the datasets")
    manifest = entries(args.weights, args.data)
    (args.weights / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    readme = args.weights / "README.md"
    readme.write_text(_with_table(readme.read_text(), manifest, readme))
    print(table(manifest))
    return 0


if __name__ == "__main__":
    run(main)
