"""The shipped weights (weights/): every file is its manifest's, the README's table is the
manifest's, and the noise 0.1 network scores on a freshly generated test split exactly what the
manifest says (the test split does not depend on the train split's size)."""

import importlib.util
import json
import shutil
from pathlib import Path

import pytest

from simlidar.errors import DatasetError

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location(
        "pretrained_weights", ROOT / "benchmark" / "pretrained_weights.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_weights_are_their_manifests():
    script = _script()
    assert script.check(ROOT / "weights") == []
    manifest = json.loads((ROOT / "weights" / "manifest.json").read_text())
    assert [e["dataset"] for e in manifest] == [
        f"simlidar-32c-noise{n}-paper-v2.0.0" for n in ("0.1", "0.2", "0.33", "0.5")
    ]
    assert all(e["bytes"] < 600_000 for e in manifest)  # small enough to ship


def test_a_changed_file_or_table_is_named(tmp_path):
    script = _script()
    copy = tmp_path / "weights"
    shutil.copytree(ROOT / "weights", copy)
    first = sorted(copy.glob("*.pt"))[0]
    blob = bytearray(first.read_bytes())
    blob[-10] ^= 1
    first.write_bytes(bytes(blob))
    readme = copy / "README.md"
    readme.write_text(readme.read_text().replace(" %", "%", 1))
    problems = script.check(copy)
    assert problems[0].startswith(f"{first}: sha256 ")
    assert problems[1] == f"{readme}: its table is not manifest.json's (run --write)"
    with pytest.raises(DatasetError, match="sha256"):
        script.main(["--check", "--weights", str(copy)])


def test_the_noise_0_1_network_scores_what_its_manifest_says(tmp_path, catalog):
    from simlidar.bench.evaluate import evaluate
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.generate import generate
    from simlidar.generator.profiles import load_profile

    entry = json.loads((ROOT / "weights" / "manifest.json").read_text())[0]
    config = GeneratorConfig.from_profile(
        load_profile("paper"), classes=32, train_size=32, test_size=600, noise=0.1
    )
    dataset = generate(config, [0.1], catalog, tmp_path, progress=False, preview=False)[0].path
    assert dataset.name == entry["dataset"]
    record = evaluate(ROOT / "weights" / entry["file"], dataset)
    assert record["accuracy"] == entry["accuracy"]
    assert record["early"]["input_spikes_mean"] == pytest.approx(entry["input_spikes_mean"])
    assert record["evaluated"]["warnings"] == []
