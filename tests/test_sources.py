"""Every source of datasets passes one conformance test (issue 44, item 3): the generator, the
KITTI converter, the DVS barrel converter and the generator's pulse streams, each on a small
input made here (the generator twice: the paper profile, and the receiver profile `sensor`
with dual returns and fog, whose splits carry the receiver's fields). What any
dataset directory must be, whatever made it: its splits name the source and a version the
source's release notes list; it verifies; the loaders read it; its card is what
``simlidar card`` renders from its files alone, and rewriting it changes no byte; its Croissant
file and checksums name the same split files; a network trains on it through ``simlidar
bench``. A new source is refused by the first test until it has an example here."""

import json

import numpy as np
import pytest
from source_examples import write_mat

from simlidar.any_card import render_card, rewrite_card
from simlidar.convert import convert_dvs_barrel, convert_kitti
from simlidar.dataset.loaders import load_split, split_info
from simlidar.dataset.version import GENERATOR, SOURCES
from simlidar.release.checksums import read_sums
from simlidar.release.verify import verify

# source[/variant]
EXAMPLES = (GENERATOR, f"{GENERATOR}/sensor", "kitti", "dvs-barrel", "simlidar-stream")


def test_every_source_has_an_example_here():
    assert {e.split("/")[0] for e in EXAMPLES} == set(SOURCES)


@pytest.fixture(scope="module", params=EXAMPLES)
def made(request, tmp_path_factory):
    """(source, a dataset directory it made from a small input)."""
    out = tmp_path_factory.mktemp(request.param.replace("/", "-"))
    if request.param == GENERATOR:
        return request.param, request.getfixturevalue("datasets")[0.1]
    if request.param == f"{GENERATOR}/sensor":
        from simlidar.generator.config import GeneratorConfig
        from simlidar.generator.generate import generate
        from simlidar.generator.profiles import load_profile

        sensor = load_profile("sensor")
        config = GeneratorConfig.from_profile(
            sensor, train_size=64, test_size=32, return_mode="dual", fog_visibility_m=50.0
        )
        catalog = request.getfixturevalue("catalog")
        (written,) = generate(config, [0.1], catalog, out, progress=False)
        assert split_info(written.path, "train").attrs["return_mode"] == "dual"
        return GENERATOR, written.path
    if request.param == "kitti":
        kitti = request.getfixturevalue("built_kitti")
        return request.param, convert_kitti(kitti, out, progress=False)
    if request.param == "simlidar-stream":
        from simlidar.generator.stream_files import generate_streams

        catalog = request.getfixturevalue("catalog")
        return request.param, generate_streams(out, train_size=8, test_size=4, scenes=catalog,
                                               progress=False)  # fmt: skip
    mat = write_mat(out / "tiny.mat")
    return request.param, convert_dvs_barrel(mat, out / "data", progress=False)


def test_its_splits_name_the_source_and_a_released_version(made):
    source, path = made
    _, _, notes = SOURCES[source]
    for split in ("train", "test"):
        info = split_info(path, split)
        assert info.source == source
        assert info.attrs["dataset_version"] in notes


def test_it_verifies(made):
    assert verify(made[1]) == []


def test_the_loaders_read_every_split(made):
    path = made[1]
    for split in ("train", "test"):
        info = split_info(path, split)
        delays, labels = load_split(path, split)
        assert delays.shape == (info.size, info.height, info.width)
        assert delays.dtype == np.float32 and ((delays >= 0) & (delays <= 1)).all()
        classes = len(info.attrs["class_names"])
        assert labels.shape == (info.size,) and 0 <= labels.min() <= labels.max() < classes


def test_its_card_is_rendered_from_its_files_and_rewriting_it_changes_nothing(made):
    path = made[1]
    card, sums = (path / "README.md").read_bytes(), (path / "SHA256SUMS").read_bytes()
    assert render_card(path) == card.decode()
    rewrite_card(path)
    assert (path / "README.md").read_bytes() == card
    assert (path / "SHA256SUMS").read_bytes() == sums


def test_its_croissant_file_and_checksums_name_the_same_split_files(made):
    path = made[1]
    croissant = json.loads((path / "croissant.json").read_text())
    files = {d["contentUrl"]: d["sha256"] for d in croissant["distribution"]}
    sums = read_sums(path)
    splits = {p.name for s in ("train", "test") for p in split_info(path, s).files}
    assert splits <= set(files) and all(files[name] == sums[name] for name in splits)


def test_a_network_trains_on_it_through_bench(made, cli, tmp_path):
    """`simlidar bench` with the MLP, one epoch: the path runs on every source (accuracy is
    not the point)."""
    source, path = made
    mlp = tmp_path / "mlp_small.toml"
    mlp.write_text(
        'model = "mlp"\n[architecture]\ndense = [16]\n[training]\n'
        'optimizer = "adam"\nlr = 1e-3\nbatch_size = 8\nepochs = 1\n'
    )
    args = ["--models", mlp, "--dataset", path, "--out", tmp_path / "b", "--validation", "0"]
    done = cli("bench", *args, "--json")
    assert done.exit_code == 0, done.output
    (cell,) = json.loads(done.stdout)["cells"]
    assert cell["source"] == source and 0.0 <= cell["accuracy"] <= 1.0
