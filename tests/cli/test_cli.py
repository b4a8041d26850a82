"""The command line: happy paths and every error path, with click's CliRunner.

Attack list (issue 35, item 10): numbers in other scripts' digits, which Python's ``int`` and
``float`` accept (``--noise ٠.٥``, Arabic-Indic, was read as 0.5; ``--seed ١``), and ``1_000``,
in every numeric option of every command: refused in one line (exit 2), nothing written.
"""

import json
from pathlib import Path

import pytest

from simlidar import __version__
from simlidar.cli import main

SMALL = ["--train-size", "32", "--test-size", "32"]


def test_generate_json_then_info_and_preview(cli, tmp_path):
    result = cli(
        "generate", *SMALL, "--noise", "0.1,0.33", "--out", tmp_path, "--json", "--batch-size", "20"
    )
    assert result.exit_code == 0, result.output
    record = json.loads(result.stdout)  # stdout holds only the JSON object
    assert set(record) == {"datasets", "seconds"}
    assert [d["noise"] for d in record["datasets"]] == [0.1, 0.33]
    first = record["datasets"][0]
    assert first["classes"] == 32 and first["splits"] == {"train": 32, "test": 32}
    assert "generate" in result.stderr  # the progress bar goes to stderr

    info = cli("info", first["path"], "--json")
    assert info.exit_code == 0
    assert json.loads(info.stdout)["counts"]["test"]["tunnel/none"] == 1
    text = cli("info", first["path"])
    assert "32 classes (layout x object)" in text.stdout and "tunnel/car" in text.stdout

    picture = tmp_path / "grid.png"
    shown = cli("preview", first["path"], "--out", picture)
    assert shown.exit_code == 0 and picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_generate_plain_output_and_classes(cli, tmp_path):
    result = cli("generate", *SMALL, "--classes", "8", "--out", tmp_path)
    assert result.exit_code == 0, result.output
    assert "simlidar-8c-noise0.2" in result.stdout
    assert (tmp_path / "simlidar-8c-noise0.2-paper-v2.0.0" / "preview.png").is_file()


def test_scenes_lists_and_exports(cli, tmp_path):
    listing = cli("scenes")
    assert listing.exit_code == 0
    assert "tunnel" in listing.stdout and "pedestrian" in listing.stdout
    exported = cli("scenes", "--export", tmp_path, "--format", "ply")
    assert exported.exit_code == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) == 32 and "tunnel__car.ply" in files

    import trimesh

    mesh = trimesh.load(tmp_path / "upper_bridge__truck.ply")
    assert len(mesh.faces) > 20


def test_version(cli):
    assert __version__ in cli("--version").stdout


@pytest.mark.parametrize(
    "args, code, words",
    [
        (["generate", "--classes", "5"], 2, "classes=5: expected one of [4, 8, 32]"),
        (["generate", "--noise", "1.5"], 2, "1.5: expected noise levels, each a level in [0, 1]"),
        (["generate", "--noise", "-0.1"], 2, "-0.1: expected noise levels, each a level in [0, 1]"),
        (["generate", "--noise", "0.1,abc"], 2, "'abc' is not a number"),
        (["generate", "--noise", "\u0660.\u0665"], 2, "'\u0660.\u0665' is not a number"),
        (["generate", "--seed", "\u0661"], 2, "'\u0661' is not a whole number in ASCII digits"),
        (["generate", "--train-size", "1_000"], 2, "'1_000' is not a whole number in ASCII"),
        (["generate", "--variation", "\u0660.\u0665"], 2, "is not a number in ASCII digits"),
        (["generate", "--workers", "\u0662"], 2, "'\u0662' is not a whole number"),
        (["generate", "--train-size", "0"], 2, "'--train-size': 0 is not in the range 1<=x<="),
        (["generate", "--train-size", "5"], 2, "train_size=5: expected an integer in [32, "),
        (["generate", "--train-size", str(10**20)], 2, "100000000000000000000 is not in the range"),
        (["generate", "--seed", str(2**70)], 2, "--seed"),
        (["generate", "--noise", "0.1,0.1"], 2, "repeats a level"),
        (["generate", "--shift", "1.5"], 2, "--shift"),
        (["generate", "--variation", "0"], 2, "--variation"),
        (["generate", "--variation", "1.5"], 2, "--variation"),
        (["generate", "--out", "afile"], 2, "afile"),
        (["generate", "--workers", "0"], 2, "'--workers': 0 is below 1; expected N >= 1 or auto"),
        (["generate", "--workers", "two"], 2, "'two' is not a whole number"),
        (["generate", "--test-size", "-5"], 2, "'--test-size': -5 is not in the range 1<=x<="),
        (["generate", "--train-size", "20"], 2, "at least one sample of every class"),
        (["preview", "nowhere", "--out", "x.jpg"], 2, "ending in .png"),
        (["generate", "--batch-size", "0"], 2, "--batch-size"),
        (["generate", "--width", "0"], 2, "--width"),
        (["info", "nowhere"], 1, "nowhere: expected a dataset directory"),
        (["preview", "nowhere", "--out", "x.png"], 1, "nowhere: expected a dataset directory"),
        (["scenes", "--scenes", "nowhere"], 1, "nowhere: expected a scene catalog folder"),
    ],
)
def test_bad_input_gets_one_line_and_an_exit_code(cli, tmp_path, monkeypatch, args, code, words):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("not a folder")
    result = cli(*args)
    assert result.exit_code == code, result.output
    assert words in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit)  # no traceback
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]  # nothing written


def test_an_existing_dataset_is_kept_or_needs_force(cli, tmp_path):
    """The same request again keeps the dataset (a `kept` line, exit 0, its files untouched);
    another request under the same name (another seed's file there) needs --force."""
    assert cli("generate", *SMALL, "--out", tmp_path).exit_code == 0
    target = tmp_path / "simlidar-32c-noise0.2-paper-v2.0.0" / "train.h5"
    before = target.read_bytes()
    again = cli("generate", *SMALL, "--out", tmp_path)
    assert again.exit_code == 0 and again.stdout.startswith(f"kept {target.parent} (")
    assert target.read_bytes() == before
    (target.parent / "preview.png").unlink()  # no longer the dataset the request makes
    refused = cli("generate", *SMALL, "--out", tmp_path)
    assert refused.exit_code == 1
    assert "already exists and has no preview.png: pass --force" in refused.stderr
    assert target.read_bytes() == before
    assert cli("generate", *SMALL, "--out", tmp_path, "--force").exit_code == 0


def test_an_unwritable_out_is_named(cli, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = cli("generate", *SMALL, "--out", blocker / "sub")
    assert result.exit_code == 1
    assert "--out" in result.stderr and "cannot create the folder" in result.stderr


def test_a_bad_recipe_is_named(cli, tmp_path, catalog_copy):
    recipe = catalog_copy / "objects" / "car.toml"
    recipe.write_text(recipe.read_text().replace('kind = "box"', 'kind = "blob"', 1))
    result = cli("generate", *SMALL, "--scenes", catalog_copy, "--out", tmp_path / "o")
    assert result.exit_code == 1
    assert "car.toml: primitive[0]: key 'kind'" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_preview_wants_a_png_in_an_existing_folder(cli, datasets, tmp_path):
    result = cli("preview", datasets[0.1], "--out", tmp_path / "a.jpg")
    assert result.exit_code == 2 and "ending in .png" in result.stderr
    result = cli("preview", datasets[0.1], "--out", tmp_path / "no" / "a.png")
    assert result.exit_code == 1 and "does not exist" in result.stderr


def test_file_system_errors_are_one_line(cli, tmp_path, datasets):
    # /proc refuses new files even to root: the OSError must not become a traceback
    result = cli("preview", datasets[0.1], "--out", "/proc/simlidar-preview.png")
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: ") and len(result.stderr.strip().splitlines()) == 1
    result = cli("scenes", "--export", "/proc/simlidar-meshes")
    assert result.exit_code == 1 and "Error: " in result.stderr


def test_classes_that_do_not_fit_a_custom_catalog(cli, tmp_path, catalog_copy):
    result = cli(
        "generate", *SMALL, "--scenes", catalog_copy, "--classes", "36", "--out", tmp_path / "o"
    )
    assert result.exit_code == 2
    assert "classes=36: expected one of [4, 8, 32]" in result.stderr
    assert not (tmp_path / "o").exists()


def test_an_object_that_is_never_seen_fails_cleanly(cli, tmp_path, catalog_copy):
    recipe = catalog_copy / "objects" / "truck.toml"
    recipe.write_text(
        recipe.read_text().replace("distance_m = [8.0, 25.0]", "distance_m = [-25.0, -8.0]")
    )
    result = cli("generate", *SMALL, "--scenes", catalog_copy, "--out", tmp_path / "o")
    assert result.exit_code == 1
    assert "truck): no draw in 200" in result.stderr
    assert not (tmp_path / "o").exists()  # the folder this run created is gone again


def test_shift_moves_every_return_of_a_sample(cli, tmp_path):
    import h5py
    import numpy as np

    result = cli("generate", *SMALL, "--shift", "0.05", "--out", tmp_path, "--json")
    assert result.exit_code == 0, result.output
    path = json.loads(result.stdout)["datasets"][0]["path"]
    with h5py.File(f"{path}/train.h5") as f:
        shift, clean, tof = f["shift"][:], f["clean_delays"][:], f["tof_ns"][:]
        tof_max = f.attrs["tof_max_ns"]
    assert np.abs(shift).max() <= 0.05 and np.abs(shift).min() < 0.05 and np.std(shift) > 0.01
    unshifted = tof / tof_max
    kept = ~np.isnan(unshifted) & (clean < 1.0)
    moved = clean - unshifted
    expected = np.broadcast_to(shift[:, None, None], clean.shape)
    np.testing.assert_allclose(moved[kept], expected[kept], atol=1e-6)
    # a return pushed out of the window reads as no return
    lost = ~np.isnan(unshifted) & (unshifted + expected >= 1.0)
    assert (clean[lost] == 1.0).all()


def test_variation_narrows_the_scenes_and_names_the_dataset(cli, tmp_path):
    import h5py
    import numpy as np

    spread = {}
    for variation in ("1", "0.1"):
        result = cli(
            "generate",
            "--profile",
            "physical",
            "--train-size",
            "128",
            "--test-size",
            "32",
            "--variation",
            variation,
            "--out",
            tmp_path,
            "--json",
        )
        assert result.exit_code == 0, result.output
        path = json.loads(result.stdout)["datasets"][0]["path"]
        with h5py.File(f"{path}/train.h5") as f:
            pose, labels = f["object_pose"][:], f["labels"][:]
            config = json.loads(f.attrs["config"])
        # spread of the object's distance and lateral offset within each class that has one
        spread[variation] = np.nanmean(
            [np.std(pose[labels == k, :2], axis=0) for k in np.unique(labels) if k % 4], axis=0
        )
        assert np.bincount(labels).tolist() == [4] * 32
    assert path.endswith("-physical-var0.1-v1.0.0") and config["variation"] == 0.1
    card = (Path(path) / "README.md").read_text()
    assert "--variation 0.1" in card and "config_name: noise0.2-var0.1" in card
    assert "scene variation 0.1" in card.split("---")[1]  # the card's title (pretty_name)
    assert (spread["0.1"] < 0.2 * spread["1"]).all(), spread
    command = card.split("## Regenerate")[1].split("```\n")[1].strip().split()[2:]
    again = cli("generate", *command, "--out", tmp_path / "again")
    assert again.exit_code == 0, again.output
    for name in ("train.h5", "test.h5", "README.md", "SHA256SUMS"):
        assert (tmp_path / "again" / Path(path).name / name).read_bytes() == (
            Path(path) / name
        ).read_bytes(), name


def test_debug_shows_the_traceback(cli):
    result = cli("--debug", "info", "nowhere")
    assert result.exit_code == 1
    assert result.exception is not None and "expected a dataset directory" in str(result.exception)


def test_verify_card_and_pack(cli, datasets, tmp_path):
    import shutil

    copy = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], copy)
    ok = cli("verify", copy)
    assert ok.exit_code == 0 and "OK (dataset version 1.0.0, train 96, test 64" in ok.stdout

    card = copy / "README.md"
    original = card.read_bytes()
    card.write_text("---\nbroken: [\n---\n")
    bad = cli("verify", copy)
    assert bad.exit_code == 1
    assert "README.md: sha256 does not match" in bad.stderr
    assert "README.md: malformed YAML front matter" in bad.stderr
    assert "Traceback" not in bad.output
    assert cli("card", copy).exit_code == 0
    assert card.read_bytes() == original  # rewritten from the files alone
    assert cli("verify", copy).exit_code == 0

    packed = cli("pack", copy, "--out", tmp_path / "pub")
    assert packed.exit_code == 0
    assert (tmp_path / "pub" / f"{copy.name}.tar.gz.sha256").is_file()


@pytest.mark.parametrize(
    "args, code, words",
    [
        (["verify", "nowhere"], 1, "nowhere: expected a dataset directory"),
        (["card", "nowhere"], 1, "nowhere: expected a dataset directory"),
        (["pack", "nowhere"], 1, "nowhere: expected a dataset directory"),
        (
            ["fetch", "http://127.0.0.1:9/x.tar.gz", "--sha256", "abc"],
            2,
            "expected 64 hexadecimal digits",
        ),
        (
            ["fetch", "http://127.0.0.1:9/x.tar.gz", "--sha256", "0" * 64, "--timeout", "2"],
            1,
            "fetch failed at download: http://127.0.0.1:9/x.tar.gz",
        ),
        (["fetch", "not-a-url", "--sha256", "0" * 64], 1, "fetch failed at download"),
    ],
)
def test_release_commands_fail_in_one_line(cli, tmp_path, monkeypatch, args, code, words):
    monkeypatch.chdir(tmp_path)
    result = cli(*args)
    assert result.exit_code == code, result.output
    assert words in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert list(tmp_path.iterdir()) in ([], [tmp_path / "data"])
    if (tmp_path / "data").exists():
        assert list((tmp_path / "data").iterdir()) == []  # nothing half written


def test_a_usage_error_is_one_line(cli):
    for args in (["generate", "--noise", "2"], ["generate", "--nope"], ["bogus"]):
        result = cli(*args)
        assert result.exit_code == 2
        assert result.stderr.startswith("Error: ") and len(result.stderr.splitlines()) == 1, (
            result.stderr
        )
    assert cli("--version").exit_code == 0
    bare = cli()  # no command: click's help, as before
    assert bare.exit_code == 2 and "Commands:" in bare.output


def _numeric_options():
    """(command, option) for every option of every command whose value is a number."""
    import click

    def walk(command, name):
        if isinstance(command, click.Group):
            for sub_name, sub in sorted(command.commands.items()):
                yield from walk(sub, f"{name} {sub_name}")
            return
        for param in command.params:
            types = getattr(param.type, "types", [param.type])  # a tuple option: each value
            names = {t.name for t in types}
            if names <= {"integer", "float", "integer range", "float range", "LEVELS", "N|auto"}:
                yield pytest.param(command, param, id=f"{name.strip()} {param.opts[0]}")

    return list(walk(main, ""))


@pytest.mark.parametrize("command, option", _numeric_options())
def test_every_numeric_option_takes_ascii_digits_only(command, option):
    import click

    ctx = click.Context(command)
    types = getattr(option.type, "types", [option.type])
    integer = all("integer" in t.name or t.name == "N|auto" for t in types)
    for bad in ("\u0661", "\u0660.\u0665", "1_0", "\uff11"):  # Arabic-Indic, fullwidth
        if integer or bad != "1_0":  # float("1_0") is 10.0 too
            value = tuple(bad for _ in types) if len(types) > 1 else bad
            with pytest.raises(click.BadParameter, match="is not a"):
                option.type.convert(value, option, ctx)
    taken = []  # ASCII is still taken: at least one of these is in the option's range
    for good in ("1", "0.5", "32", "100"):
        try:
            taken.append(
                option.type.convert((good,) * len(types) if len(types) > 1 else good, option, ctx)
            )
        except click.BadParameter:
            pass
    assert taken


def test_the_command_list_shows_each_commands_first_sentence_whole(cli):
    """`simlidar --help` lists every command with the first sentence of its help, wrapped,
    never cut with "..." (click cut them at one line's width)."""
    import re

    from simlidar.cli import main

    listing = cli("--help").output.split("Commands:")[1]
    flat = " ".join(listing.split())
    assert "..." not in listing
    for name, command in main.commands.items():
        first = " ".join(command.help.split("\n\n")[0].split())
        sentence = re.split(r"(?<=\.)\s", first)[0]
        assert f"{name} {sentence}" in flat, name
