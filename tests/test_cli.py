"""The command line: happy paths and every error path, with click's CliRunner."""

import json

import pytest
from click.testing import CliRunner

from simlidar import __version__
from simlidar.cli import main

SMALL = ["--train-size", "32", "--test-size", "32"]


@pytest.fixture
def run():
    def invoke(*args):
        return CliRunner().invoke(main, [str(a) for a in args])

    return invoke


def test_generate_json_then_info_and_preview(run, tmp_path):
    result = run("generate", *SMALL, "--noise", "0.1,0.33", "--out", tmp_path, "--json",
                 "--batch-size", "20")  # fmt: skip
    assert result.exit_code == 0, result.output
    record = json.loads(result.stdout)  # stdout holds only the JSON object
    assert set(record) == {"datasets", "seconds"}
    assert [d["noise"] for d in record["datasets"]] == [0.1, 0.33]
    first = record["datasets"][0]
    assert first["classes"] == 32 and first["splits"] == {"train": 32, "test": 32}
    assert "generate" in result.stderr  # the progress bar goes to stderr

    info = run("info", first["path"], "--json")
    assert info.exit_code == 0
    assert json.loads(info.stdout)["counts"]["test"]["tunnel/none"] == 1
    text = run("info", first["path"])
    assert "32 classes (layout x object)" in text.stdout and "tunnel/car" in text.stdout

    picture = tmp_path / "grid.png"
    shown = run("preview", first["path"], "--out", picture)
    assert shown.exit_code == 0 and picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_generate_plain_output_and_classes(run, tmp_path):
    result = run("generate", *SMALL, "--classes", "8", "--out", tmp_path)
    assert result.exit_code == 0, result.output
    assert "simlidar-8c-noise0.2" in result.stdout
    assert (tmp_path / "simlidar-8c-noise0.2-v1.0.0" / "preview.png").is_file()


def test_scenes_lists_and_exports(run, tmp_path):
    listing = run("scenes")
    assert listing.exit_code == 0
    assert "tunnel" in listing.stdout and "pedestrian" in listing.stdout
    exported = run("scenes", "--export", tmp_path, "--format", "ply")
    assert exported.exit_code == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) == 32 and "tunnel__car.ply" in files

    import trimesh

    mesh = trimesh.load(tmp_path / "upper_bridge__truck.ply")
    assert len(mesh.faces) > 20


def test_version(run):
    assert __version__ in run("--version").stdout


@pytest.mark.parametrize(
    "args, code, words",
    [
        (["generate", "--classes", "5"], 2, "classes=5: expected one of [4, 8, 32]"),
        (["generate", "--noise", "1.5"], 2, "1.5 is outside [0, 1]"),
        (["generate", "--noise", "-0.1"], 2, "-0.1 is outside [0, 1]"),
        (["generate", "--noise", "0.1,abc"], 2, "'abc' is not a number"),
        (["generate", "--train-size", "0"], 2, "train_size=0: expected an integer >= 32"),
        (["generate", "--test-size", "-5"], 2, "test_size=-5"),
        (["generate", "--train-size", "20"], 2, "so that every class has a sample"),
        (["generate", "--batch-size", "0"], 2, "--batch-size"),
        (["generate", "--width", "0"], 2, "--width"),
        (["info", "nowhere"], 1, "nowhere: expected a dataset directory"),
        (["preview", "nowhere", "--out", "x.png"], 1, "nowhere: expected a dataset directory"),
        (["scenes", "--scenes", "nowhere"], 1, "nowhere: expected a scene catalog folder"),
    ],
)
def test_bad_input_gets_one_line_and_an_exit_code(run, tmp_path, monkeypatch, args, code, words):
    monkeypatch.chdir(tmp_path)
    result = run(*args)
    assert result.exit_code == code, result.output
    assert words in result.stderr
    assert "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_an_existing_dataset_needs_force(run, tmp_path):
    assert run("generate", *SMALL, "--out", tmp_path).exit_code == 0
    target = tmp_path / "simlidar-32c-noise0.2-v1.0.0" / "train.h5"
    before = target.read_bytes()
    again = run("generate", *SMALL, "--out", tmp_path)
    assert again.exit_code == 1
    assert "already exists: pass --force" in again.stderr
    assert target.read_bytes() == before
    assert run("generate", *SMALL, "--out", tmp_path, "--force").exit_code == 0


def test_an_unwritable_out_is_named(run, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = run("generate", *SMALL, "--out", blocker / "sub")
    assert result.exit_code == 1
    assert "--out" in result.stderr and "cannot create the folder" in result.stderr


def test_a_bad_recipe_is_named(run, tmp_path, catalog_copy):
    recipe = catalog_copy / "objects" / "car.toml"
    recipe.write_text(recipe.read_text().replace('kind = "box"', 'kind = "blob"', 1))
    result = run("generate", *SMALL, "--scenes", catalog_copy, "--out", tmp_path / "o")
    assert result.exit_code == 1
    assert "car.toml: primitive[0]: key 'kind'" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_preview_wants_a_png(run, datasets, tmp_path):
    result = run("preview", datasets[0.1], "--out", tmp_path / "a.jpg")
    assert result.exit_code == 2 and "ending in .png" in result.stderr


def test_debug_shows_the_traceback(run):
    result = run("--debug", "info", "nowhere")
    assert result.exit_code == 1
    assert result.exception is not None and "expected a dataset directory" in str(result.exception)
