"""simlidar bench end to end on small datasets: suites, cells, reruns, reports, bad input.

Attack list (issue 35, item 10):

* ``--max-seconds inf`` and a suite's ``board_power_w`` of inf or 1e308: a bare ``Infinity`` in
  results.json and the cells (not JSON: strict parsers refuse it). Now no time cap is recorded
  as null (older cells' ``Infinity`` read as the same rules) and the power is refused above
  100 kW, in one line; every file bench writes parses as strict JSON.
* ``bench/<suite>/cells/`` deleted by hand: every later bench failed writing a cell; now the
  folder is made again and its cells run again.
* a file (or a dangling link) where the suite's generated dataset goes: the error suggested
  ``--force``, which bench does not have; now it says what is in the way and to remove it.
* a full disk while a cell is written (a real ``RLIMIT_FSIZE`` on a real process): the error
  was glued onto the progress bar's line; now it has a line of its own.
* an ``--out`` of another suite: the message says what to do, and names no option bench lacks.

Attack list of the suites that ask for more than a machine holds (issue 35, items 3 and 6):
``[generate] train_size = 1000000000`` (inside the documented range), run as a real process
under an 8 GiB address-space limit: refused in one line naming the memory it would take and
what is available, before anything is allocated or written (it used to build an array of 10^9
labels to check the validation split); the validation rule is checked from the class counts
(a class left without a training sample is still named); ``seeds`` beyond a 64-bit seed
(``[99999999999999999999999]``) refused by the suite reader, before anything is written.
"""

import json
import shutil
from pathlib import Path

import pytest

from simlidar.bench.run import run_suite
from simlidar.bench.suite import load_suite, suite_names
from simlidar.errors import ConfigError, DatasetError

TINY = """
name = "tiny"
description = "a test suite"
models = ["snn_simlidar", "cnn"]
seeds = [0]
datasets = [{paths}]

[budget]
epochs = 1
"""
PAPER_SIZED = {"classes": 32, "train_size": 3000, "test_size": 600}  # a paper-suite cell
RESNET = """
model = "resnet"
[architecture]
plan = "resnet18"
width = 4
[training]
optimizer = "adam"
lr = 1e-3
batch_size = 32
epochs = 1
"""


@pytest.fixture
def tiny_suite(tmp_path, datasets):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY.format(paths=", ".join(f'"{p}"' for p in datasets.values())))
    return path


def test_shipped_suites_load():
    assert {"quick", "paper", "physical"} <= set(suite_names())
    paper = load_suite("paper")
    assert paper.noise == (0.1, 0.2, 0.33, 0.5) and paper.seeds == (0, 1, 2)
    assert paper.generate.train_size == 3000 and paper.generate.test_size == 600
    assert paper.generate.profile_name == "paper"
    models = {"snn_simlidar", "snn_simlidar_tuned", "mlp", "cnn", "vgg16", "resnet18", "resnet50"}
    assert set(paper.models) == models
    physical = load_suite("physical")  # the same models, budgets and seeds on another profile
    assert physical.generate.profile_name == "physical"
    for key in ("models", "seeds", "noise", "budget"):
        assert getattr(physical, key) == getattr(paper, key)
    quick = load_suite("quick")
    # the first report a newcomer reads: none of the paper suite's models that cannot finish
    # learning in its minutes (the paper's SGD recipe, the deep networks), each of the others
    # trained as the paper trained (the whole train split, fixed epochs, the last epoch: no
    # "still improving" mark from a 96-sample validation part), the tuned SNN's schedule whole
    assert set(quick.models) == {"snn_simlidar_tuned", "mlp", "cnn"} < set(paper.models)
    assert all(quick.budget_for(model)["validation"] == 0 for model in quick.models)
    tuned = "snn_simlidar_tuned"
    assert quick.budget_for(tuned)["epochs"] == paper.budget_for(tuned)["epochs"]
    assert quick.generate.train_size < paper.generate.train_size
    # each suite keeps its own name (the default output folder), not its profile's
    assert (quick.name, paper.name, physical.name) == ("quick", "paper", "physical")


def test_the_physical_ablation_runs_the_physical_suites_data_and_rules(monkeypatch):
    """benchmark/ablation/physical-ablation.toml (its recipes are paths from the repository's
    root) makes the physical suite's datasets and trains by its budget defaults."""
    root = Path(__file__).resolve().parents[2]
    monkeypatch.chdir(root)
    ablation = load_suite("benchmark/ablation/physical-ablation.toml")
    physical = load_suite("physical")
    assert ablation.data_sha256 == physical.data_sha256 and ablation.seeds == physical.seeds
    for model in ablation.models:
        assert ablation.budget_for(model) == physical.budget["*"]


def test_a_suite_runs_reruns_and_reports(tiny_suite, tmp_path, datasets):
    out = tmp_path / "out"
    suite = load_suite(tiny_suite)
    results = run_suite(suite, out, progress=False)
    cells = results["cells"]
    assert len(cells) == 4  # 2 datasets x 2 models x 1 seed
    for cell in cells:
        for key in ("dataset", "noise", "model", "seed", "accuracy", "latency_ms", "params"):
            assert key in cell
        confusion = cell["confusion"]
        assert sum(map(sum, confusion)) == 64  # every test sample once
        assert cell["accuracy"] == pytest.approx(sum(r[i] for i, r in enumerate(confusion)) / 64)
        # the selection: 32 of the 96 train samples held out (one a class), one epoch run
        assert cell["validation_size"] == 32 and cell["best_epoch"] == 0
        assert cell["epochs_run"] == 1 and cell["stopped"] == "epochs"
        assert len(cell["validation_curve"]) == 1 and 0 <= cell["validation_curve"][0] <= 1
        rules = cell["inputs"]["rules"]
        assert rules["validation"] == 0.1 and rules["epochs"] == 1 and rules["patience"] == 10
        assert set(cell["timing_seconds"]) >= {"train", "latency_and_counts"}
    snn = [c for c in cells if c["model"] == "snn_simlidar"]
    cnn = [c for c in cells if c["model"] == "cnn"]
    for c in snn:  # event-driven figures agree with the batched accuracy
        assert c["early"]["accuracy"] == c["accuracy"]  # the same count, by construction
        assert 0.0 < c["early"]["data_ratio_mean"] <= 1.0
        assert c["kind"] == "spiking" and "macs" not in c
    for c in cnn:
        assert c["kind"] == "conventional" and c["macs"] == 644_096  # see test_metrics
        assert c["energy_pj_mac"] == pytest.approx(c["macs"] * 4.6)
    assert {c["noise"] for c in cells} == {0.1, 0.5}
    # every cell's kept weights, to re-measure a figure without training again
    from simlidar.bench.checkpoints import load_checkpoint

    saved = sorted((out / "checkpoints").glob("*.pt"))
    assert [p.stem for p in saved] == sorted(p.stem for p in (out / "cells").glob("*.json"))
    _, data = load_checkpoint(saved[0], (1, 16, 16), 32)
    assert len(data["history"]) == 1

    # re-measuring from the checkpoints gives the same figures, keeps the training record
    from simlidar.bench.measure import remeasure

    first = sorted((out / "cells").glob("*.json"))[0]
    measured = json.loads(first.read_text())
    changed = dict(measured, activation_sparsity=123.0, params=-1)
    first.write_text(json.dumps(changed))
    again = remeasure(out, suite, progress=False)
    redone = json.loads(first.read_text())
    stable = (
        "activation_sparsity",
        "params",
        "accuracy",
        "confusion",
        "synaptic_operations",
        "validation_curve",
        "best_epoch",
        "inputs",
        "metrics",
    )
    for key in stable:
        assert redone[key] == measured[key], key
    assert len(again["cells"]) == 4
    saved[0].unlink()
    with pytest.raises(DatasetError, match=f"cell {saved[0].stem} has no checkpoint"):
        remeasure(out, suite, progress=False)
    run_suite(suite, out, progress=False)  # nothing to train: the checkpoint stays missing
    assert not saved[0].exists()
    written = json.loads((out / "results.json").read_text())
    assert written["machine"]["cores"] and written["suite"]["name"] == "tiny"
    report = (out / "report.md").read_text()
    # 96 / 64 samples a dataset: the paper's figures stand apart from the table, marked
    assert "| *paper" not in report and "Not comparable with the paper's figures" in report
    assert "99.83 % at noise 0.1; 68.16 % at noise 0.5" in report
    assert "no pretrained weights" in report
    for picture in ("accuracy_vs_noise.png", "decisions.png", "confusion.png"):
        assert (out / picture).stat().st_size > 1000
        assert f"]({picture})" in report

    # a rerun skips the finished cells; a new model (a recipe file) runs only its own cells
    before = {p.name: p.read_bytes() for p in (out / "cells").iterdir()}
    small = tmp_path / "small_resnet.toml"
    small.write_text(RESNET)
    again = run_suite(suite, out, models=["snn_simlidar", "cnn", str(small)], progress=False)
    after = {p.name: p.read_bytes() for p in (out / "cells").iterdir()}
    assert all(after[name] == data for name, data in before.items())
    assert len(after) == 6 and len(again["cells"]) == 6

    # the same cells under other training rules are refused, not mixed in
    for rules in ({"patience": 3}, {"validation": 0.2}, {"epochs": 2}):
        with pytest.raises(DatasetError, match="was made with other training rules"):
            run_suite(suite.with_budget(**rules), out, models=["cnn"], progress=False)
    assert {p.name: p.read_bytes() for p in (out / "cells").iterdir()} == after

    # the suite file edited (a model's budget), same name and data: the directory stays its
    # own; the cells of the untouched model are kept, those of the changed one refused
    tiny_suite.write_text(tiny_suite.read_text() + "[budget.cnn]\npatience = 4\n")
    edited = load_suite(tiny_suite)
    assert edited.sha256 != suite.sha256 and edited.data_sha256 == suite.data_sha256
    assert len(run_suite(edited, out, models=["snn_simlidar"], progress=False)["cells"]) == 6
    assert json.loads((out / "suite.json").read_text())["sha256"] == edited.sha256
    with pytest.raises(DatasetError, match="cnn__seed0 was made with other training rules"):
        run_suite(edited, out, models=["cnn"], progress=False)
    other_data = tmp_path / "tiny2.toml"
    one_more = f'"{datasets[0.5]}", "{datasets[0.1]}"'  # the datasets list changed
    other_data.write_text(tiny_suite.read_text().replace(f'"{datasets[0.5]}"', one_more))
    with pytest.raises(DatasetError, match="not to 'tiny' .*: another data"):
        run_suite(load_suite(other_data), out, progress=False)
    assert {p.name: p.read_bytes() for p in (out / "cells").iterdir()} == after


def test_one_cell_is_seeded(tiny_suite, tmp_path, datasets):
    suite = load_suite(tiny_suite)
    one = run_suite(suite, tmp_path / "a", ["cnn"], datasets[0.1], progress=False)["cells"]
    two = run_suite(suite, tmp_path / "b", ["cnn"], datasets[0.1], progress=False)["cells"]
    assert [c["confusion"] for c in one] == [c["confusion"] for c in two]


GENERATED = (
    'models = ["cnn"]\n[generate]\nnoise = [0.2]\ntrain_size = 32\n'
    "test_size = 32\n[budget]\nepochs = 1\n"
)


def test_generated_datasets_are_made_once(tmp_path):
    path = tmp_path / "gen.toml"
    text = GENERATED
    path.write_text(text)
    out = tmp_path / "out"
    # one sample a class: nothing to hold out for validation; refused before anything is made
    with pytest.raises(
        ConfigError,
        match=r"recipe cnn: key 'training.validation': validation "
        r"fraction 0.1 leaves class 'tunnel/none' \(1 training sample",
    ):
        run_suite(load_suite(path), out, progress=False)
    assert not out.exists()
    path.write_text(text + "validation = 0\n")  # no validation: the last epoch is kept
    results = run_suite(load_suite(path), out, progress=False)
    assert results["cells"][0]["validation_size"] == 0
    assert results["cells"][0]["dataset"] == "simlidar-32c-noise0.2-paper-v2.0.0"
    assert (out / "datasets" / "simlidar-32c-noise0.2-paper-v2.0.0" / "train.h5").is_file()


@pytest.mark.parametrize(
    "text, message",
    [
        ('modles = ["cnn"]', "unknown key 'modles': expected one of"),
        ('models = ["nope"]', "model recipe 'nope': expected one of"),
        ("models = []", "key 'models': expected a non-empty list"),
        ('models = ["cnn"]\nseeds = [-1]\ndatasets = ["x"]', "key 'seeds'"),
        ('models = ["cnn"]', "expected exactly one of 'generate'"),
        ('models = ["cnn"]\n[generate]\nnoise = [2.0]', r"noise=2.0: expected a level in \[0, 1\]"),
        ('models = ["cnn"]\n[generate]\nnoise = [0.1]\ncolour = 1', "key 'generate.colour'"),
        ('models = ["cnn"]\ndatasets = ["x"]\n[budget]\nepochs = 0', "key 'budget.epochs'"),
        ('models = ["cnn"]\ndatasets = ["x"]\n[budget.vgg16]\nepochs = 2', "key 'budget.vgg16'"),
        (
            'models = ["cnn"]\ndatasets = ["x"]\n[budget]\npatience = 0',
            r"key 'budget.patience': expected an integer in \[1, 1000000\]",
        ),
        (
            'models = ["cnn"]\ndatasets = ["x"]\n[budget.cnn]\npatience = 1.5',
            r"key 'budget.cnn.patience': expected an integer in \[1, 1000000\]",
        ),
        (
            'models = ["cnn"]\ndatasets = ["x"]\n[budget]\nvalidation = 1',
            r"key 'budget.validation': expected a fraction of the train split in \[0, 1\)",
        ),
        ('models = ["cnn"', "not valid TOML"),
        ('models = ["cnn"]\ngenerate = 5', r"key 'generate': expected a table"),
        ('models = ["cnn"]\ndatasets = ["x"]\nbudget = [1]', r"key 'budget': expected a table"),
        ('models = ["cnn", "cnn"]\ndatasets = ["x"]', "key 'models': expected distinct"),
        ('models = ["cnn"]\nseeds = [1, 1]\ndatasets = ["x"]', "key 'seeds': expected distinct"),
        (
            'models = ["cnn"]\nseeds = [99999999999999999999999]\ndatasets = ["x"]',
            r"key 'seeds': expected a non-empty list of integers in \[0, 2\*\*63\), got "
            r"\[99999999999999999999999\]",
        ),
        ('models = ["cnn"]\nseeds = [9223372036854775808]\ndatasets = ["x"]', "key 'seeds'"),
        ('models = ["cnn"]\n[generate]\nnoise = [0.1, 0.1]', "distinct noise levels"),
        ('name = "../../evil"\nmodels = ["cnn"]\ndatasets = ["x"]', "key 'name': expected letters"),
        ('name = ".hidden"\nmodels = ["cnn"]\ndatasets = ["x"]', "key 'name'"),
        ('models = ["cnn"]\n[generate]\nnoise = [0.1]\nprofile = "nope"', "profile 'nope'"),
        ('models = ["cnn"]\n[generate]\nnoise = [0.1]\nprofile = 3', "key 'generate.profile'"),
        (
            'models = ["cnn"]\ndatasets = ["x"]\nboard_power_w = inf',
            r"key 'board_power_w': expected watts in \[0, 100000\], got inf",
        ),
        (
            'models = ["cnn"]\ndatasets = ["x"]\nboard_power_w = 1e308',
            r"key 'board_power_w': expected watts in \[0, 100000\], got 1e\+308",
        ),
        ('models = ["cnn"]\ndatasets = ["x"]\nboard_power_w = nan', "key 'board_power_w'"),
    ],
)
def test_bad_suites_are_named(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_suite(path)


def test_bench_on_a_dataset_of_ones_own_has_a_folder_of_its_own(
    tiny_suite, tmp_path, datasets, cli, monkeypatch
):
    """Without --out, a run with --dataset writes bench/<suite>-<dataset>, never the suite's
    own bench/<suite> (whose cells are of its datasets)."""
    monkeypatch.chdir(tmp_path)
    ok = cli("bench", "--suite", str(tiny_suite), "--models", "cnn", "--dataset",
             str(datasets[0.1]), "--epochs", "1")  # fmt: skip
    assert ok.exit_code == 0, ok.output
    name = json.loads((tmp_path / "bench").iterdir().__next__().joinpath("suite.json")
                      .read_text())["name"]  # fmt: skip
    folders = [p.name for p in (tmp_path / "bench").iterdir()]
    assert folders == [f"{name}-{datasets[0.1].name}"]
    assert (tmp_path / "bench" / folders[0] / "results.json").is_file()


def test_cli_bench_and_its_errors(tiny_suite, tmp_path, datasets, cli):
    out = tmp_path / "out"
    ok = cli(
        "bench",
        "--suite",
        str(tiny_suite),
        "--models",
        "cnn",
        "--dataset",
        str(datasets[0.1]),
        "--out",
        str(out),
    )
    assert ok.exit_code == 0, ok.output
    assert "1 cells in" in ok.output and "cnn" in ok.output
    results = (out / "results.json").read_bytes()

    def fails(args, code, text):
        result = cli("bench", *args)
        assert result.exit_code == code, result.output
        assert text in result.output and "Traceback" not in result.output
        errors = [line for line in result.output.splitlines() if line.startswith("Error")]
        assert len(errors) == 1 and text in errors[0]  # one line says it

    fails(
        ["--suite", "nope"],
        2,
        "expected one of ['paper', 'physical', 'quick', 'stream', 'stream-rain'] or a",
    )
    fails(["--suite", str(tiny_suite), "--models", "cnn,nope"], 2, "model recipe 'nope'")
    fails(
        ["--suite", str(tiny_suite), "--dataset", str(tmp_path / "missing"), "--out", str(out)],
        1,
        "expected a dataset directory",
    )
    not_schema = tmp_path / "junk"
    not_schema.mkdir()
    (not_schema / "train.h5").write_text("not hdf5")
    (not_schema / "test.h5").write_text("not hdf5")
    fails(
        ["--suite", str(tiny_suite), "--dataset", str(not_schema), "--out", str(out)],
        1,
        "cannot read as HDF5",
    )
    fails(["--suite", "quick", "--out", str(out)], 1, "belongs to suite 'tiny'")
    other = cli("bench", "--suite", "quick", "--out", str(out))
    assert "--force" not in other.output and "expected a new --out directory" in other.output
    fails(["--suite", str(tiny_suite), "--epochs", "0"], 2, "'--epochs': 0 is not in the range")
    fails(["--suite", str(tiny_suite), "--max-seconds", "-1"], 2, "'--max-seconds'")
    fails(["--suite", str(tiny_suite), "--max-seconds", "nan"], 2, "'--max-seconds'")
    other_rules = ["--models", "cnn", "--dataset", str(datasets[0.1]), "--out", str(out)]
    fails(
        ["--suite", str(tiny_suite), *other_rules, "--epochs", "2"],
        1,
        "was made with other training rules",
    )
    fails(
        ["--suite", str(tiny_suite), "--out", str(out), "--remeasure", "--epochs", "2"],
        2,
        "--remeasure re-measures the finished cells of --out as they were trained; expected "
        "no --epochs",
    )
    fails(
        ["--suite", str(tiny_suite), "--out", str(tmp_path / "none"), "--remeasure"],
        1,
        "no benchmark run to re-measure",
    )
    fails(
        ["--suite", str(tiny_suite), "--out", str(not_schema)],
        1,
        "not a benchmark output directory",
    )
    assert (out / "results.json").read_bytes() == results  # nothing touched
    assert (not_schema / "train.h5").read_text() == "not hdf5"

    def longer_args(where):
        return [
            *["--suite", str(tiny_suite), "--models", "cnn", "--dataset", str(datasets[0.1])],
            *["--out", str(where), "--epochs", "2", "--max-seconds", "inf", "--json"],
        ]

    longer = cli("bench", *longer_args(tmp_path / "e2"))
    assert longer.exit_code == 0, longer.output
    cell = json.loads(longer.stdout)["cells"][0]
    assert cell["budget"] == {"epochs": 2, "max_seconds": None}  # no time cap
    assert cell["inputs"]["rules"]["max_seconds"] is None
    assert len(cell["validation_curve"]) == cell["epochs_run"] <= 2
    written = [tmp_path / "e2" / "results.json", *(tmp_path / "e2" / "cells").iterdir()]
    for path in written:  # strict JSON, as JavaScript's parser reads it
        json.loads(
            path.read_text(), parse_constant=lambda word, p=path: pytest.fail(f"{p}: {word}")
        )
    # a cell written before, with a bare Infinity, is the same rules: kept, not refused
    (cell_file,) = (tmp_path / "e2" / "cells").iterdir()
    cell_file.write_text(
        cell_file.read_text().replace('"max_seconds": null', '"max_seconds": Infinity')
    )
    again = cli("bench", *longer_args(tmp_path / "e2"))
    assert again.exit_code == 0, again.output
    assert "Infinity" in cell_file.read_text()  # not run again


def test_a_cell_from_other_inputs_is_refused_not_reused(tiny_suite, tmp_path, datasets, catalog):
    from simlidar.errors import DatasetError
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.generate import generate

    suite = load_suite(tiny_suite)
    out = tmp_path / "out"
    recipe = tmp_path / "mycnn.toml"
    recipe.write_text(
        'model = "cnn"\n[architecture]\ndense = [8]\n[training]\n'
        'optimizer = "adam"\nlr = 1e-3\nbatch_size = 32\nepochs = 1\n'
    )
    run_suite(suite, out, [str(recipe)], datasets[0.1], progress=False)
    before = (out / "results.json").read_bytes()
    # the same directory name, other samples (another seed)
    other = generate(
        GeneratorConfig(train_size=64, test_size=32, seed=7),
        [0.1],
        catalog,
        tmp_path / "other",
        progress=False,
    )[0].path
    assert other.name == datasets[0.1].name
    with pytest.raises(DatasetError, match="was made from another dataset"):
        run_suite(suite, out, [str(recipe)], other, progress=False)
    # the recipe's own epoch cap is not what the cell ran by (the suite's budget sets it): the
    # cell is kept, not retrained
    cell = next((out / "cells").glob("*__mycnn__*.json"))
    made = cell.read_bytes()
    recipe.write_text(recipe.read_text().replace("epochs = 1", "epochs = 50"))
    run_suite(suite, out, [str(recipe)], datasets[0.1], progress=False)
    assert cell.read_bytes() == made
    # a time cap the suite leaves to the recipe is a training rule of the cell
    recipe.write_text(recipe.read_text() + "max_seconds = 5\n")
    with pytest.raises(DatasetError, match="other training rules .*max_seconds none.*"):
        run_suite(suite, out, [str(recipe)], datasets[0.1], progress=False)
    recipe.write_text(recipe.read_text().replace("max_seconds = 5\n", ""))
    recipe.write_text(recipe.read_text().replace("dense = [8]", "dense = [9]"))
    with pytest.raises(DatasetError, match="was made from another recipe"):
        run_suite(suite, out, [str(recipe)], datasets[0.1], progress=False)
    assert (out / "results.json").read_bytes() == before


def test_a_rewritten_card_keeps_the_cells(tiny_suite, tmp_path, datasets):
    """A cell is made from the split files: the card's text (which names the simlidar version)
    and so SHA256SUMS may change without the finished cells being refused or retrained."""
    import shutil

    from simlidar.release.checksums import write_sums

    data = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], data)
    suite, out = load_suite(tiny_suite), tmp_path / "out"
    recipe = tmp_path / "mycnn.toml"
    recipe.write_text(
        'model = "cnn"\n[architecture]\ndense = [8]\n[training]\n'
        'optimizer = "adam"\nlr = 1e-3\nbatch_size = 32\nepochs = 1\n'
    )
    run_suite(suite, out, [str(recipe)], data, progress=False)
    (cell,) = (out / "cells").iterdir()
    before, sums = cell.read_bytes(), (data / "SHA256SUMS").read_bytes()
    card = data / "README.md"
    card.write_text(card.read_text().replace("## Loading", "## Loading the data"))
    write_sums(data, ["README.md"])
    assert (data / "SHA256SUMS").read_bytes() != sums
    run_suite(suite, out, [str(recipe)], data, progress=False)
    assert cell.read_bytes() == before  # finished: not trained again


def test_a_suite_with_a_missing_dataset_claims_nothing(tmp_path):
    from simlidar.errors import DatasetError

    path = tmp_path / "s.toml"
    path.write_text(f'models = ["cnn"]\ndatasets = ["{tmp_path / "missing"}"]\n')
    with pytest.raises(DatasetError, match="expected a dataset directory"):
        run_suite(load_suite(path), tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_a_cell_stopped_by_the_time_cap_is_marked_in_the_report():
    from simlidar.bench.report import paper_numbers
    from simlidar.bench.tables import CAPPED, accuracy_by_noise

    def cell(seed, capped):
        return {
            "source": "simlidar-generator",
            "noise": 0.1,
            "model": "cnn",
            "seed": seed,
            "accuracy": 0.5,
            "stopped_by_time": capped,
            **PAPER_SIZED,
        }

    clean = "\n".join(accuracy_by_noise([cell(0, False), cell(1, False)], paper_numbers()))
    assert CAPPED not in clean
    marked = "\n".join(accuracy_by_noise([cell(0, False), cell(1, True)], paper_numbers()))
    assert f"50.00 ± 0.00 (2) {CAPPED}" in marked and "stopped on the suite's time cap" in marked


def test_the_paper_row_stands_beside_paper_sized_splits_only():
    """The quick suite's first report set the paper's SNN (3000 / 600 samples) as a row under
    models trained on 960 / 320: now a row only where the splits have the paper's sizes, a
    note marked not comparable otherwise; the chance level is named either way."""
    from simlidar.bench.report import paper_numbers
    from simlidar.bench.tables import accuracy_by_noise

    def cell(noise, train_size, test_size):
        return {
            "source": "simlidar-generator",
            "noise": noise,
            "model": "snn_simlidar_tuned",
            "seed": 0,
            "accuracy": 0.75,
            "classes": 32,
            "train_size": train_size,
            "test_size": test_size,
        }

    paper = paper_numbers()
    sized = "\n".join(accuracy_by_noise([cell(0.1, 3000, 600), cell(0.5, 3000, 600)], paper))
    assert "| *paper: SNN 256-400-32* | 99.83 | 68.16 |" in sized
    assert "Not comparable" not in sized and "3000 / 600 train / test samples" in sized
    assert "chance is 3.12 % (32 classes)" in sized
    small = "\n".join(accuracy_by_noise([cell(0.1, 960, 320), cell(0.5, 960, 320)], paper))
    assert "| *paper" not in small and "| snn_simlidar_tuned | 75.00 (1) | 75.00 (1) |" in small
    table, note = small.split("**Not comparable with the paper's figures.**")
    assert "99.83" not in table and "960 / 320 train / test samples" in table
    assert "hold 960 / 320 train / test samples, the paper's 3000 / 600" in note
    assert "99.83 % at noise 0.1; 68.16 % at noise 0.5" in note
    mixed = "\n".join(accuracy_by_noise([cell(0.1, 3000, 600), cell(0.5, 960, 320)], paper))
    assert "| *paper" not in mixed and "960 / 320, 3000 / 600 train / test" in mixed


def test_seeds_that_disagree_are_marked_and_training_is_tabled():
    from simlidar.bench.report import paper_numbers
    from simlidar.bench.tables import CAPPED, OPEN, SPREAD, accuracy_by_noise, training_table

    def cell(seed, accuracy, stopped="plateau", best=4, seconds=90.0):
        return {
            "source": "simlidar-generator",
            "noise": 0.1,
            "model": "cnn",
            "seed": seed,
            "accuracy": accuracy,
            "stopped_by_time": stopped == "time",
            "stopped": stopped,
            "epochs": min(best + 3, 40),
            "best_epoch": best,
            "budget": {"epochs": 40},
            "validation_size": 288,
            "seconds": seconds,
            **PAPER_SIZED,
        }

    close = [cell(0, 0.95), cell(1, 0.96), cell(2, 0.97)]  # std 1 point
    apart = [cell(0, 0.90), cell(1, 0.96), cell(2, 0.97)]  # std 3.8 points
    assert SPREAD not in "\n".join(accuracy_by_noise(close, paper_numbers()))
    marked = "\n".join(accuracy_by_noise(apart, paper_numbers()))
    assert f"94.33 ± 3.79 (3) {SPREAD}" in marked and "disagree by more than 2 points" in marked
    mixed = [cell(0, 0.9), cell(1, 0.9, "epochs", 39, 150.0), cell(2, 0.9, "time", 9, 300.0)]
    table = "\n".join(training_table(mixed))
    # 3 cells, budget 40, epochs run 7-40, kept epoch median 10 (1-based), stops 1 / 1 / 1
    assert "| cnn | 3 | 40 | 7–40 | 10 | 1 / 1 / 1 | 0 | 288 | 3.0, 5.0 | 9 |" in table
    # an epoch-cap stop whose best epoch is among the last `patience`: still improving
    for c in mixed:
        c.update(epochs_run=c["epochs"], inputs={"rules": {"patience": 5}})
    assert "| 1 / 1 / 1 | 1 | 288 |" in "\n".join(training_table(mixed))
    marked = "\n".join(accuracy_by_noise(mixed, paper_numbers()))
    assert f"(3) {CAPPED} {OPEN}" in marked and "still improving" in marked
    for c in mixed:  # a cosine schedule ends at rate 0 on its cap: converged by construction
        c["lr_schedule"] = "cosine"
    assert "| 1 / 1 / 1 | 0 | 288 |" in "\n".join(training_table(mixed))


def test_suite_json_names_a_shipped_suite_by_its_repository_path(tiny_suite):
    from simlidar.bench.outdir import suite_shown

    assert suite_shown(load_suite("quick")) == "benchmark/quick.toml"  # not the install path
    assert suite_shown(load_suite(tiny_suite)) == str(tiny_suite)


def test_a_deleted_cells_folder_is_made_again(tiny_suite, tmp_path, datasets):
    suite, out = load_suite(tiny_suite), tmp_path / "out"
    first = run_suite(suite, out, ["cnn"], datasets[0.1], progress=False)
    shutil.rmtree(out / "cells")
    again = run_suite(suite, out, ["cnn"], datasets[0.1], progress=False)
    assert [c["accuracy"] for c in again["cells"]] == [c["accuracy"] for c in first["cells"]]
    assert len(list((out / "cells").iterdir())) == 1


@pytest.mark.parametrize("blocker", ["file", "dangling link"])
def test_something_in_the_way_of_a_generated_dataset_is_named(tmp_path, blocker, cli):
    path = tmp_path / "gen.toml"
    path.write_text(GENERATED + "validation = 0\n")
    out = tmp_path / "out"
    run_suite(load_suite(path), out, progress=False)
    dataset = out / "datasets" / "simlidar-32c-noise0.2-paper-v2.0.0"
    shutil.rmtree(dataset)
    if blocker == "file":
        dataset.write_text("not a dataset")
    else:
        dataset.symlink_to(tmp_path / "nowhere")
    done = cli("bench", "--suite", str(path), "--out", str(out))
    assert done.exit_code == 1 and done.stderr.count("\n") == 1, done.output
    assert done.stderr == (
        f"Error: --out {out}: {dataset} is in the way of the suite's dataset of that name (not "
        "a folder); expected nothing there: remove it (bench replaces nothing)\n"
    )


def test_a_full_disk_while_a_cell_is_written_gets_a_line_of_its_own(tiny_suite, datasets, tmp_path):
    """A real file-size limit on a real `simlidar bench` with its progress bar: the cell's
    checkpoint (about 450 KB for the MLP) cannot be written."""
    import resource
    import subprocess
    import sys

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, resource.RLIM_INFINITY))

    args = [sys.executable, "-m", "simlidar.cli", "bench", "--suite", str(tiny_suite)]
    args += ["--models", "mlp", "--dataset", str(datasets[0.1]), "--out", str(tmp_path / "b")]
    done = subprocess.run(
        [*args, "--epochs", "1"], capture_output=True, text=True, timeout=600, preexec_fn=limit
    )
    assert done.returncode == 1, done.stderr
    lines = done.stderr.replace("\r", "\n").splitlines()
    errors = [line for line in lines if "Error" in line]
    assert len(errors) == 1 and errors[0].startswith("Error: "), done.stderr
    assert errors[0].endswith("cannot write the checkpoint (File too large)")
    assert "bench tiny" in done.stderr  # the bar was there, on lines of its own


def test_a_suite_larger_than_the_machine_is_refused_before_anything_is_allocated(
    tmp_path, limited_python
):

    path = tmp_path / "huge.toml"
    path.write_text(
        'models = ["cnn"]\n[generate]\nnoise = [0.1]\ntrain_size = 1000000000\n'
        "test_size = 1000\n[budget]\nepochs = 1\n"
    )
    out = tmp_path / "out"
    limit = 8 * 2**30
    result = limited_python(["-m", "simlidar.cli", "bench", "--suite", path, "--out", out], limit)
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith(
        f"Error: suite {path}: [generate] train_size=1000000000, test_size=1000: a cell's "
        "delays and labels: 961.1 GiB to hold in memory, "
    ), line
    assert line.endswith(
        "available; expected data that fits (a smaller split, or a machine with more memory)"
    )
    assert not out.exists()


def test_the_validation_rule_is_checked_from_the_class_counts(tmp_path):
    from simlidar.bench.run import check_validation

    path = tmp_path / "s.toml"
    path.write_text(  # 33 samples, 32 classes: class 0 has 2, the others 1
        'models = ["cnn"]\n[generate]\nnoise = [0.1]\ntrain_size = 33\n[budget]\nvalidation = 0.1\n'
    )
    with pytest.raises(ConfigError, match=r"leaves class 'tunnel/car' \(1 training sample"):
        check_validation(load_suite(path), ["cnn"], None)
    path.write_text(path.read_text().replace("train_size = 33", "train_size = 64"))
    check_validation(load_suite(path), ["cnn"], None)  # 2 a class: one to train on
    # 10^9 samples without an array of labels: test_a_suite_larger_than_the_machine_...
